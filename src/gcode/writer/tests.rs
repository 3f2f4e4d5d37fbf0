//! Tests of the G-code writer.

use super::*;
use crate::model::toolpath::Role;

fn mv(kind: MotionKind, to: [f64; 3], feed: Option<f64>, beam: bool) -> Record {
    Record::Move(Motion {
        kind,
        to: P3::new(to[0], to[1], to[2]),
        feed,
        beam,
        beam_switch: None,
        role: None,
        chain: None,
        block: None,
        tool: Default::default(),
    })
}

fn rapid(to: [f64; 3]) -> Record {
    mv(MotionKind::Rapid, to, None, false)
}

fn line(to: [f64; 3], feed: f64, beam: bool) -> Record {
    mv(MotionKind::Line, to, Some(feed), beam)
}

fn arc(to: [f64; 3], center: [f64; 3], ccw: bool, plane: Plane, turns: u32, feed: f64, beam: bool) -> Record {
    mv(
        MotionKind::Arc(ArcData {
            center: P3::new(center[0], center[1], center[2]),
            ccw,
            plane,
            extra_turns: turns,
        }),
        to,
        Some(feed),
        beam,
    )
}

fn write(opts: WriteOptions, unit: FeedUnit, recs: &[Record]) -> String {
    write_string(opts, unit, recs).expect("writes")
}

fn opts(d: Dialect) -> WriteOptions {
    WriteOptions::for_dialect(d)
}

/// Fig. 6-38-like laser program: shutter closed on the lead-in, open on
/// the cut, closed on the corner loop, a full circle, and the counter on
/// every motion line.
fn laser_path() -> Vec<Record> {
    vec![
        rapid([1.8183, 5.0, 0.0]),
        line([1.8183, 5.455, 0.0], 2.0, false),
        line([1.8183, 6.3977, 0.0], 2.0, true),
        arc(
            [1.861, 6.355, 0.0],
            [1.861, 6.3977, 0.0],
            false,
            Plane::Xy,
            0,
            2.0,
            false,
        ),
        line([1.8183, 6.355, 0.0], 2.0, false),
        arc(
            [1.8183, 6.355, 0.0],
            [1.8183, 5.455, 0.0],
            true,
            Plane::Xy,
            0,
            2.0,
            true,
        ),
        line([1.7756, 6.355, 0.0], 2.0, false),
        arc(
            [1.8183, 6.3977, 0.0],
            [1.8183, 6.355, 0.0],
            false,
            Plane::Xy,
            0,
            2.0,
            false,
        ),
        line([1.8183, 5.455, 0.0], 2.0, true),
    ]
}

#[test]
fn pmac_laser_program_golden() {
    let text = write(opts(Dialect::Pmac), FeedUnit::MmPerS, &laser_path());
    let expected = "\
OPEN PROG 1 CLEAR
ABS
INC(R)
M33=0
RAPID X1.8183 Y5 Z0 P400=1
LINEAR Y5.455 F2 P400=2
M33==1 Y6.3977 P400=3
NORMAL K-1
M33==0 CIRCLE1 X1.861 Y6.355 I0.0427 J0 P400=4
LINEAR X1.8183 P400=5
M33==1 CIRCLE2 X1.8183 Y6.355 I0 J-0.9 P400=6
M33==0 LINEAR X1.7756 P400=7
CIRCLE1 X1.8183 Y6.3977 I0.0427 J0 P400=8
M33==1 LINEAR Y5.455 P400=9
DWELL 0
M33=0
CLOSE
";
    assert_eq!(text, expected);
}

#[test]
fn iso_laser_program_golden() {
    let mut o = opts(Dialect::Iso);
    o.line_numbers = Some(10);
    let text = write(o, FeedUnit::MmPerS, &laser_path());
    let expected = "\
N10 G21 G90 G17 G94 G91.1
N20 M5
N30 G0 X1.8183 Y5 Z0
N40 G1 Y5.455 F120
N50 M3 Y6.3977
N60 M5 G2 X1.861 Y6.355 I0.0427 J0
N70 G1 X1.8183
N80 M3 G3 X1.8183 Y6.355 I0 J-0.9
N90 M5 G1 X1.7756
N100 G2 X1.8183 Y6.3977 I0.0427 J0
N110 M3 G1 Y5.455
N120 M5
N130 M30
";
    assert_eq!(text, expected);
}

/// Planes, helices, extra turns, dwell, spindle, accel and variables.
fn mixed_path() -> Vec<Record> {
    vec![
        rapid([0.0, 0.0, 1.0]),
        Record::Spindle {
            rpm: 30000.0,
            block: None,
        },
        Record::Accel {
            ta_ms: Some(100.0),
            ts_ms: Some(20.5),
            block: None,
        },
        // Helix, one extra turn: down 1.5 mm over 1.25 turns.
        arc([1.0, 1.0, -0.5], [0.0, 1.0, 1.0], true, Plane::Xy, 1, 60.0, true),
        Record::Dwell {
            seconds: 0.25,
            block: None,
        },
        // Half circle in ZX (G18), then a quarter in YZ (G19).
        arc([1.0, 1.0, 1.5], [1.0, 1.0, 0.5], false, Plane::Xz, 0, 60.0, true),
        arc([1.0, 0.0, 0.5], [1.0, 1.0, 0.5], true, Plane::Yz, 0, 120.0, true),
        Record::Var {
            name: "M12".into(),
            value: -3.25,
            sync: true,
            block: None,
        },
        line([0.0, 0.0, 0.5], 120.0, false),
    ]
}

#[test]
fn pmac_mixed_golden() {
    let text = write(opts(Dialect::Pmac), FeedUnit::MmPerMin, &mixed_path());
    let expected = "\
OPEN PROG 1 CLEAR
ABS
INC(R)
M33=0
RAPID X0 Y0 Z1 P400=1
; spindle S30000 rpm (not commanded by the motion program)
TA100 TS20.5
NORMAL K-1
M33==1 CIRCLE2 X0 Y0 Z-0.2 I0 J1 F1 P400=2
X1 Y1 Z-0.5 I0 J1 P400=3
DWELL 250
NORMAL J-1
CIRCLE1 Z1.5 I0 K1 P400=4
NORMAL I-1
CIRCLE2 Y0 Z0.5 J0 K-1 F2 P400=5
M12==-3.25
M33==0 LINEAR X0 P400=6
M33=0
CLOSE
";
    assert_eq!(text, expected);
}

#[test]
fn iso_mixed_golden() {
    let text = write(opts(Dialect::Iso), FeedUnit::MmPerMin, &mixed_path());
    let expected = "\
G21 G90 G17 G94 G91.1
M5
G0 X0 Y0 Z1
S30000
(TA 100 ms TS 20.5 ms)
M3 G3 X1 Y1 Z-0.5 I0 J1 P2 F60
G4 P0.25
G18 G2 Z1.5 I0 K1
G19 G3 Y0 Z0.5 J0 K-1 F120
(M12==-3.25)
M5 G1 X0
M5
M30
";
    assert_eq!(text, expected);
}

#[test]
fn output_is_byte_identical_across_runs() {
    let mut recs = laser_path();
    recs.extend(mixed_path());
    for d in [Dialect::Pmac, Dialect::Iso] {
        let a = write(opts(d), FeedUnit::MmPerS, &recs);
        let b = write(opts(d), FeedUnit::MmPerS, &recs);
        assert_eq!(a.as_bytes(), b.as_bytes());
    }
}

#[test]
fn numbers_are_fixed_point_trimmed_and_never_minus_zero() {
    let mut b = String::new();
    for (v, dec, pt, want) in [
        (0i64, 4, false, "0"),
        (0, 4, true, "0."),
        (15000, 4, false, "1.5"),
        (-15000, 4, false, "-1.5"),
        (-5, 4, false, "-0.0005"),
        (12345, 4, false, "1.2345"),
        (10000, 4, true, "1."),
        (-120, 0, false, "-120"),
        (i64::MIN, 9, false, "-9223372036.854775808"),
        (1, 9, false, "0.000000001"),
    ] {
        b.clear();
        push_fixed(&mut b, v, dec, pt);
        assert_eq!(b, want, "{v} with {dec} decimals");
    }
    // Rounding to the output precision: -0.00004 is 0, not -0.
    let text = write(
        opts(Dialect::Iso),
        FeedUnit::MmPerMin,
        &[rapid([-0.00004, 2.00004, -1.99996])],
    );
    assert!(text.contains("G0 X0 Y2 Z-2\n"), "{text}");
}

#[test]
fn feeds_convert_and_stay_modal() {
    let recs = [
        line([1.0, 0.0, 0.0], 2.5, false),
        line([2.0, 0.0, 0.0], 2.5, false),
        rapid([3.0, 0.0, 0.0]),
        line([4.0, 0.0, 0.0], 2.5, false),
        line([5.0, 0.0, 0.0], 1.0 / 3.0, false),
    ];
    let iso = write(opts(Dialect::Iso), FeedUnit::MmPerS, &recs);
    assert!(iso.contains("G1 X1 Y0 Z0 F150\nX2\nG0 X3\nG1 X4\nX5 F20\n"), "{iso}");
    let pmac = write(opts(Dialect::Pmac), FeedUnit::MmPerMin, &recs);
    assert!(
        pmac.contains(
            "LINEAR X1 Y0 Z0 F0.0417 P400=1\nX2 P400=2\nRAPID X3 P400=3\nLINEAR X4 P400=4\nX5 F0.0056 P400=5\n"
        ),
        "{pmac}"
    );
    // Output unit chosen explicitly.
    let mut o = opts(Dialect::Iso);
    o.feed_unit = FeedUnit::MmPerS;
    assert!(write(o, FeedUnit::MmPerMin, &recs[..1]).contains("F0.0417"));
}

#[test]
fn options_change_the_words() {
    let recs = [
        line([1.0, 0.0, 0.0], 2.0, true),
        line([2.0, 0.0, 0.0], 2.0, true),
        line([3.0, 0.0, 0.0], 2.0, false),
    ];
    let mut o = opts(Dialect::Pmac);
    o.shutter_sync = false;
    o.shutter_var = "M1".into();
    o.line_counter = None;
    o.repeat_motion = true;
    o.decimal_point = true;
    o.header = Some(vec!["OPEN PROG 7 CLEAR".into()]);
    o.trailer = Some(vec!["CLOSE".into()]);
    let text = write(o, FeedUnit::MmPerS, &recs);
    assert_eq!(
        text,
        "OPEN PROG 7 CLEAR\nM1=1 LINEAR X1. Y0. Z0. F2.\nLINEAR X2.\nM1=0 LINEAR X3.\nCLOSE\n"
    );

    // A custom ISO header leaves beam and plane unknown: the first move
    // and the first arc say them; other M-codes for the beam.
    let mut o = opts(Dialect::Iso);
    o.header = Some(vec!["%".into(), "(part 1)".into(), "G21 G90".into()]);
    o.trailer = Some(vec!["M30".into(), "%".into()]);
    o.beam_on = "M62 P0".into();
    o.beam_off = "M63 P0".into();
    o.line_numbers = Some(5);
    o.absolute_centers = true;
    let recs = [
        line([1.0, 0.0, 0.0], 1.0, false),
        arc([1.0, 2.0, 0.0], [1.0, 1.0, 0.0], true, Plane::Xy, 0, 1.0, true),
    ];
    let text = write(o, FeedUnit::MmPerMin, &recs);
    assert_eq!(
        text,
        "%\n(part 1)\nN5 G21 G90\nN10 M63 P0 G1 X1 Y0 Z0 F1\nN15 G17 M62 P0 G3 Y2 I1 J1\nN20 M30\n%\n"
    );
}

#[test]
fn comments_mark_chain_and_role_changes() {
    let mut recs = laser_path();
    for (i, r) in recs.iter_mut().enumerate() {
        if let Record::Move(m) = r {
            m.chain = (i > 0).then_some(7);
            m.role = Some(if m.beam { Role::Cut } else { Role::Loop });
        }
    }
    let mut o = opts(Dialect::Pmac);
    o.comments = true;
    let text = write(o.clone(), FeedUnit::MmPerS, &recs[..4]);
    assert!(text.contains("; loop\nRAPID"), "{text}");
    assert!(text.contains("; chain 7 loop\nLINEAR Y5.455"), "{text}");
    assert!(text.contains("; chain 7 cut\nM33==1 Y6.3977"), "{text}");
    o.dialect = Dialect::Iso;
    let text = write(o, FeedUnit::MmPerS, &recs[..3]);
    assert!(text.contains("(chain 7 cut)\nM3 Y6.3977"), "{text}");
}

#[test]
fn rotary_axes_and_tools_are_written_in_both_dialects() {
    let with = |r: Record, abc: [f64; 3], tool: Option<u32>| match r {
        Record::Move(mut m) => {
            m.tool.abc = Some(abc);
            m.tool.number = tool;
            Record::Move(m)
        }
        r => r,
    };
    let recs = [
        with(rapid([0.0, 0.0, 5.0]), [0.0, 0.0, 0.0], Some(2)),
        with(rapid([0.0, 0.0, 5.0]), [90.0, 0.0, 0.0], Some(2)),
        with(line([1.0, 0.0, 5.0], 1.0, true), [90.0, 45.5, 0.0], Some(2)),
        with(line([2.0, 0.0, 5.0], 1.0, true), [90.0, 45.5, 0.0], Some(5)),
    ];
    let iso = write(opts(Dialect::Iso), FeedUnit::MmPerMin, &recs);
    assert!(
        iso.contains("T2 M6\nG0 X0 Y0 Z5 A0 B0 C0\nA90\n") && iso.contains("G1 X1 B45.5 F1\nT5 M6\nX2\n"),
        "{iso}"
    );
    let pmac = write(opts(Dialect::Pmac), FeedUnit::MmPerS, &recs);
    assert!(pmac.contains("RAPID X0 Y0 Z5 A0 B0 C0 P400=1\nA90 P400=2\n"), "{pmac}");
    assert!(!pmac.contains("M6"), "{pmac}");
    // Read back: the same rotary positions and tools.
    let (_, back) = crate::gcode::read_str(
        &iso,
        &crate::gcode::ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        },
    )
    .unwrap();
    let m: Vec<&Motion> = back.iter().filter_map(Record::motion).collect();
    assert_eq!(m.len(), 4);
    for (a, b) in m.iter().zip(&recs) {
        let b = b.motion().unwrap();
        assert_eq!((a.tool.abc, a.tool.number), (b.tool.abc, b.tool.number), "{iso}");
    }
}

#[test]
fn zero_length_moves_stay_moves() {
    let recs = [line([1.0, 2.0, 3.0], 1.0, false), line([1.0, 2.0, 3.00001], 1.0, false)];
    let text = write(opts(Dialect::Pmac), FeedUnit::MmPerS, &recs);
    assert!(text.contains("P400=1\nX1 P400=2\n"), "{text}");
}

#[test]
fn empty_program_is_header_and_trailer() {
    assert_eq!(
        write(opts(Dialect::Pmac), FeedUnit::MmPerS, &[]),
        "OPEN PROG 1 CLEAR\nABS\nINC(R)\nM33=0\nM33=0\nCLOSE\n"
    );
    assert_eq!(
        write(opts(Dialect::Iso), FeedUnit::MmPerS, &[]),
        "G21 G90 G17 G94 G91.1\nM5\nM5\nM30\n"
    );
}

#[test]
fn bad_records_are_errors_and_change_nothing() {
    let bad: Vec<Record> = vec![
        rapid([f64::NAN, 0.0, 0.0]),
        rapid([f64::INFINITY, 0.0, 0.0]),
        rapid([1e300, 0.0, 0.0]),
        line([1.0, 0.0, 0.0], f64::NAN, true),
        line([1.0, 0.0, 0.0], -1.0, true),
        line([1.0, 0.0, 0.0], 1e-9, true),
        arc([1.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], true, Plane::Xy, 0, 1.0, true),
        // centre on the start point
        arc([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], true, Plane::Xy, 0, 1.0, true),
        // end not on the circle
        arc([3.0, 0.0, 0.0], [1.0, 0.0, 0.0], true, Plane::Xy, 0, 1.0, true),
        arc([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], true, Plane::Xy, u32::MAX, 1.0, true),
        Record::Dwell {
            seconds: -1.0,
            block: Some(9),
        },
        Record::Dwell {
            seconds: f64::NAN,
            block: None,
        },
        Record::Spindle {
            rpm: f64::NAN,
            block: None,
        },
        Record::Accel {
            ta_ms: Some(-1.0),
            ts_ms: None,
            block: None,
        },
        Record::Var {
            name: "P1\nCLOSE".into(),
            value: 1.0,
            sync: false,
            block: None,
        },
        Record::Var {
            name: "m33".into(),
            value: 1.0,
            sync: false,
            block: None,
        },
        Record::Var {
            name: "P400".into(),
            value: 1.0,
            sync: false,
            block: None,
        },
        Record::Var {
            name: "P1".into(),
            value: f64::NAN,
            sync: false,
            block: None,
        },
    ];
    for d in [Dialect::Pmac, Dialect::Iso] {
        let mut w = GcodeWriter::new(Vec::new(), opts(d), FeedUnit::MmPerS);
        w.record(&rapid([0.0, 0.0, 0.0])).unwrap();
        let mut refused = 0;
        for r in &bad {
            let before = w.out.len();
            if let Err(e) = w.record(r) {
                assert!(matches!(e, WriteError::Invalid { .. }), "{e}");
                assert_eq!(w.out.len(), before, "nothing of a refused record is written: {e}");
                refused += 1;
            }
        }
        // ISO comments PMAC variables instead of refusing the reserved
        // ones, and has a turn count for any number of turns.
        let expect = if d == Dialect::Pmac { bad.len() } else { bad.len() - 3 };
        assert_eq!(refused, expect, "{d:?}");
        // Still consistent: the next good record follows the last good one.
        w.record(&line([1.0, 0.0, 0.0], 1.0, false)).unwrap();
        let text = String::from_utf8(w.finish().unwrap()).unwrap();
        assert!(
            text.contains(if d == Dialect::Pmac {
                "LINEAR X1 F1 P400=2\n"
            } else {
                "M5 G1 X1\n"
            }),
            "{text}"
        );
    }
    let e = GcodeWriter::new(Vec::new(), opts(Dialect::Pmac), FeedUnit::MmPerS)
        .record(&Record::Dwell {
            seconds: -1.0,
            block: Some(9),
        })
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "toolpath record 1 (source line 9): dwell must be zero or more seconds, not -1"
    );
    let mut o = opts(Dialect::Iso);
    o.start = P3::new(f64::NAN, 0.0, 0.0);
    assert!(write_string(o, FeedUnit::MmPerS, &[]).is_err());
}

#[test]
fn iso_variables() {
    let var = |name: &str| Record::Var {
        name: name.into(),
        value: 2.5,
        sync: false,
        block: None,
    };
    let text = write(
        opts(Dialect::Iso),
        FeedUnit::MmPerS,
        &[var("#100"), var("#<depth>"), var("M5")],
    );
    assert!(text.contains("\n#100=2.5\n#<depth>=2.5\n(M5=2.5)\n"), "{text}");
    assert!(write_string(opts(Dialect::Iso), FeedUnit::MmPerS, &[var("#<a)>")]).is_err());
}
