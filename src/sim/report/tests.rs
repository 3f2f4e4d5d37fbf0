use super::*;
use crate::gcode::{ReadOptions, read_str};
use crate::model::toolpath::{FeedUnit, Motion};

type Finished = (GsimReport, [Option<Vec<u8>>; 3]);

fn sim(text: &str, machine: Machine) -> Result<Finished, SimError> {
    let (d, recs) = read_str(text, &ReadOptions::default()).unwrap();
    let header = Header {
        feed_unit: d.feed_unit(),
        source: None,
    };
    let mut s = Simulator::new(&header, machine, CommandTiming::Sync, P3::origin(), Some(Vec::new()));
    for r in &recs {
        s.add(r)?;
    }
    s.finish()
}

#[test]
fn times_add_up_and_the_series_has_a_row_per_block() {
    let mut m = Machine::builtin("lookahead");
    m.accel_mm_s2 = 100.0;
    m.block_rate_hz = 0.0;
    // 10 mm at 600 mm/min = 10 mm/s: 1.1 s; G4 P0.5; rapid back.
    let (r, [csv, ..]) = sim("G1 X10 F600\nG4 P0.5\nG0 X0\n", m).unwrap();
    assert!((r.time.cutting_time_s - 1.1).abs() < 1e-12);
    assert_eq!(r.time.dwell_time_s, 0.5);
    let total = r.time.cutting_time_s + r.time.dwell_time_s + r.time.rapid_time_s;
    assert!((r.time.cycle_time_s - total).abs() < 1e-12);
    assert!((r.time.ideal_cutting_time_s - 1.0).abs() < 1e-12);
    let csv = String::from_utf8(csv.unwrap()).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], BLOCKS_HEADER.trim_end());
    assert_eq!(rows[1], "1,line,10,10,10,1.1,");
    assert_eq!(rows[2], "2,dwell,0,,,0.5,");
    assert!(rows[3].starts_with("3,rapid,10,100,"));
    assert_eq!(rows.len(), 4);
}

#[test]
fn bad_programs_name_their_line() {
    let mut m = Machine::builtin("lookahead");
    m.limits_min_mm = Some([0.0, 0.0, -5.0]);
    m.limits_max_mm = Some([10.0, 10.0, 5.0]);
    // The arc's end is inside but its extent is not.
    let e = sim("G1 X5 Y5 F100\nG2 X5 Y5 I3 J0\n", m.clone()).err().unwrap();
    assert!(e.to_string().starts_with("line 2: move reaches X11"), "{e}");
    let e = sim("G1 X5 F100\nG0 Z6\n", m).err().unwrap();
    assert!(e.to_string().starts_with("line 2:"), "{e}");
    // A toolpath record with no feed on a feed move.
    let h = Header {
        feed_unit: FeedUnit::MmPerS,
        source: None,
    };
    let mut s: Simulator<Vec<u8>> = Simulator::new(
        &h,
        Machine::builtin("laser-stage"),
        CommandTiming::Sync,
        P3::origin(),
        None,
    );
    let rec = Record::Move(Motion::bare(MotionKind::Line, P3::new(1.0, 0.0, 0.0), Some(0.0)));
    let e = s.add(&rec).unwrap_err().to_string();
    assert_eq!(e, "record 1: feed move with feed 0");
}

#[test]
fn steps_split_blocks_by_feed_per_tooth_and_add_up() {
    // 2 mm/s at 60,000 rpm with 2 flutes: 1 µm per tooth, steps of 10 µm.
    let text = "G0 Z1\nS60000\nG1 Z-0.1 F120\nG1 X0.5\n";
    let (d, recs) = read_str(text, &ReadOptions::default()).unwrap();
    let header = Header {
        feed_unit: d.feed_unit(),
        source: None,
    };
    let stock = Stock::new(P3::new(-1.0, -1.0, -1.0), P3::new(2.0, 1.0, 0.0), 0.01).unwrap();
    let mut s = Simulator::new(
        &header,
        Machine::builtin("lookahead"),
        CommandTiming::Sync,
        P3::origin(),
        None,
    )
    .with_removal(stock, Cutter::Flat { radius: 0.397 }, Some(Vec::new()))
    .with_steps(
        StepPlan {
            flutes: 2,
            scale: 10.0,
            rpm: None,
        },
        Some(Vec::new()),
    );
    for r in &recs {
        s.add(r).unwrap();
    }
    let (r, [_, removal, steps]) = s.finish().unwrap();
    let steps = String::from_utf8(steps.unwrap()).unwrap();
    let of_line = |l: &str| -> Vec<f64> {
        steps
            .lines()
            .skip(1)
            .filter(|row| row.split(',').next() == Some(l))
            .map(|row| row.rsplit(',').next().unwrap().parse().unwrap())
            .collect()
    };
    // 0.5 mm in 10 µm steps.
    let v4 = of_line("4");
    assert_eq!(v4.len(), 50);
    let removal = String::from_utf8(removal.unwrap()).unwrap();
    let row4: Vec<&str> = removal
        .lines()
        .find(|l| l.starts_with("4,"))
        .unwrap()
        .split(',')
        .collect();
    let block: f64 = row4[3].parse().unwrap();
    assert!(
        (v4.iter().sum::<f64>() - block).abs() < 1e-8,
        "steps add up to the block"
    );
    assert_eq!(row4[5], "50");
    // In the steady part of the slot each step removes width × depth × step.
    let mid = v4[25];
    assert!((mid - 0.794 * 0.1 * 0.01).abs() < 0.05 * mid, "{mid}");
    let (stats, stock) = r.removal.as_ref().unwrap();
    assert!((stats.removed_volume_mm3 - (6.0 - stock.volume())).abs() < 1e-9);
}
