use super::expr::VarKind;
use super::lexer::Cursor;
use super::*;
use crate::gcode::{Dialect, ProgramReader, read_str};
use crate::model::toolpath::{ArcData, Motion, MotionKind};

pub(super) fn pmac_opts() -> ReadOptions {
    ReadOptions {
        dialect: Some(Dialect::Pmac),
        ..ReadOptions::default()
    }
}

pub(super) fn read(text: &str) -> Vec<Record> {
    match read_str(text, &pmac_opts()) {
        Ok((_, recs)) => recs,
        Err(e) => panic!("unexpected error: {e}"),
    }
}

pub(super) fn read_err(text: &str) -> (u64, String) {
    match read_str(text, &pmac_opts()) {
        Ok((_, recs)) => panic!("expected an error, got {recs:?}"),
        Err(e) => (e.line(), e.to_string()),
    }
}

pub(super) fn moves(recs: &[Record]) -> Vec<&Motion> {
    recs.iter().filter_map(Record::motion).collect()
}

pub(super) fn p(x: f64, y: f64, z: f64) -> P3 {
    P3::new(x, y, z)
}

pub(super) fn assert_pt(a: &P3, b: &P3) {
    assert!((a - b).norm() < 1e-9, "{a:?} != {b:?}");
}

pub(super) fn arc(m: &Motion) -> ArcData {
    match m.kind {
        MotionKind::Arc(a) => a,
        ref k => panic!("not an arc: {k:?}"),
    }
}

#[test]
fn bare_program_in_the_style_of_the_seed() {
    let text = include_str!("../../../testdata/pmac/bare_shutter_contour.pmac");
    let (dialect, recs) = read_str(text, &ReadOptions::default()).unwrap();
    assert_eq!(dialect, Dialect::Pmac);
    // Only moves: M33 is the beam, P400 bookkeeping, M30 a no-op call.
    assert_eq!(recs.len(), 8);
    let m = moves(&recs);
    assert_eq!(m.len(), 8);
    assert_eq!(m[0].kind, MotionKind::Line);
    assert_pt(&m[0].to, &p(2.5, 4.0, 0.0));
    assert_eq!(m[0].feed, Some(2.0));
    assert_eq!(m[0].block, Some(2));
    assert_pt(&m[1].to, &p(2.5, 4.8, 0.0));
    let a = arc(m[2]);
    assert!(!a.ccw);
    assert_eq!(a.plane, Plane::Xy);
    assert_pt(&a.center, &p(2.55, 4.8, 0.0));
    assert_pt(&m[2].to, &p(2.55, 4.75, 0.0));
    assert_pt(&m[3].to, &p(2.5, 4.75, 0.0));
    // CIRCLE2 I0 J-0.75 with no end point: a full counter-clockwise circle.
    let full = arc(m[4]);
    assert!(full.ccw);
    assert_pt(&full.center, &p(2.5, 4.0, 0.0));
    assert_pt(&m[4].to, &m[3].to);
    assert_eq!(m[4].block, Some(10));
    assert_pt(&m[5].to, &p(2.45, 4.75, 0.0));
    assert_pt(&arc(m[6]).center, &p(2.45, 4.8, 0.0));
    assert_pt(&m[7].to, &p(2.5, 4.0, 0.0));
    let beams: Vec<bool> = m.iter().map(|m| m.beam).collect();
    assert_eq!(beams, [false, false, false, false, false, true, false, false]);
    assert!(
        m.iter()
            .all(|m| m.feed == Some(2.0) && m.role.is_none() && m.chain.is_none())
    );
}

#[test]
fn download_file_with_buffer_commands() {
    let text = include_str!("../../../testdata/pmac/slot_and_hole.pmac");
    let (dialect, recs) = read_str(text, &ReadOptions::default()).unwrap();
    assert_eq!(dialect, Dialect::Pmac);
    assert_eq!(recs.len(), 10, "{recs:#?}");
    assert_eq!(
        recs[0],
        Record::Accel {
            ta_ms: Some(20.0),
            ts_ms: Some(10.0),
            block: Some(7)
        }
    );
    let m = moves(&recs);
    assert_eq!(m[0].kind, MotionKind::Rapid);
    assert_eq!(m[0].feed, None);
    assert_pt(&m[0].to, &p(0.0, 0.0, 0.5));
    assert_eq!((m[1].beam, m[1].feed, m[1].block), (false, Some(2.0), Some(9)));
    assert_eq!((m[2].beam, m[2].block), (true, Some(11)));
    assert_pt(&m[2].to, &p(2.0, 0.0, 0.0));
    let slot_end = arc(m[3]);
    assert!(slot_end.ccw);
    assert_pt(&slot_end.center, &p(2.0, 0.5, 0.0));
    assert_pt(&m[4].to, &p(0.0, 1.0, 0.0));
    assert!(m[4].beam);
    assert_eq!((m[5].kind, m[5].beam, m[5].feed), (MotionKind::Rapid, false, None));
    let hole = arc(m[6]);
    assert!(!hole.ccw);
    assert_pt(&hole.center, &p(1.0, -0.75, 0.0));
    assert_pt(&m[6].to, &p(1.0, -1.0, 0.0));
    assert_eq!((m[6].feed, m[6].beam, m[6].block), (Some(1.5), true, Some(19)));
    assert_eq!(
        recs[8],
        Record::Dwell {
            seconds: 0.05,
            block: Some(21)
        }
    );
    assert_eq!(
        recs[9],
        Record::Var {
            name: "P401".into(),
            value: 12.0,
            sync: false,
            block: Some(22)
        }
    );
}

#[test]
fn planes_helix_and_radius_arcs() {
    let text = include_str!("../../../testdata/pmac/planes_helix_radius.pmac");
    let m_recs = read(text);
    let m = moves(&m_recs);
    assert_eq!(m.len(), 6);
    let helix = arc(m[1]);
    assert!(helix.ccw);
    assert_eq!(helix.plane, Plane::Xy);
    assert_pt(&helix.center, &p(0.0, 0.0, 0.0));
    assert_pt(&m[1].to, &p(0.0, 1.0, -0.2));
    let zx = arc(m[2]);
    assert_eq!(zx.plane, Plane::Xz);
    assert!(!zx.ccw);
    assert_pt(&zx.center, &p(0.0, 1.0, -1.2));
    assert_pt(&m[2].to, &p(1.0, 1.0, -1.2));
    let yz = arc(m[3]);
    assert_eq!(yz.plane, Plane::Yz);
    assert!(yz.ccw);
    assert_pt(&yz.center, &p(1.0, 2.0, -1.2));
    let short = arc(m[4]);
    assert_eq!(short.plane, Plane::Xy);
    assert!(short.ccw, "NORMAL K1 flips CIRCLE1");
    assert_pt(&short.center, &p(1.0, 3.0, -0.2));
    let long = arc(m[5]);
    assert!(long.ccw);
    assert_pt(&long.center, &p(2.0, 2.0, -0.2));
    assert_pt(&m[5].to, &p(3.0, 2.0, -0.2));
}

#[test]
fn arc_off_its_circle_is_an_error_on_its_line() {
    let text = include_str!("../../../testdata/pmac/arc_off_circle.pmac");
    let (line, msg) = read_err(text);
    assert_eq!(line, 3);
    assert!(msg.contains("not on the circle"), "{msg}");
}

#[test]
fn arc_rounded_to_few_decimals_runs_as_the_controller_spirals_it() {
    // A 0.2 mm arc printed with 3 decimals (what `pathgen contour
    // --decimals 3` makes of seahorse.dxf's small arcs): the rounded centre
    // lies 0.2 mm from the start and 0.2013 mm from the end. A Turbo PMAC
    // changes the radius evenly over such a move; the model's arc does the
    // same, ending exactly on the programmed end point.
    let recs = read("LINEAR X0.2 Y0 F1\nCIRCLE2 X0 Y0.2013 I-0.2 J0\n");
    let m = moves(&recs);
    let a = arc(m[1]);
    assert_pt(&a.center, &p(0.0, 0.0, 0.0));
    assert_pt(&m[1].to, &p(0.0, 0.2013, 0.0));
    let geo = a.arc(m[0].to, m[1].to).expect("a spiral arc");
    let mid = geo.point_at(0.5);
    let r_mid = (mid.x * mid.x + mid.y * mid.y).sqrt();
    assert!(
        (r_mid - 0.20065).abs() < 1e-6,
        "radius halfway is the mean, got {r_mid}"
    );
    assert_pt(&geo.point_at(1.0), &p(0.0, 0.2013, 0.0));
    // Two decimals: 10 um off on a 1 mm arc still reads.
    assert_eq!(moves(&read("LINEAR X1 Y0 F1\nCIRCLE2 X0 Y1.01 I-1 J0\n")).len(), 2);
}

#[test]
fn an_arc_that_misses_by_more_than_rounding_is_refused() {
    // 0.1 mm off on a 1 mm radius: a wrong centre, not rounding.
    let (line, msg) = read_err("LINEAR X1 Y0 F1\nCIRCLE2 X0 Y1.1 I-1 J0\n");
    assert_eq!(line, 2);
    assert!(msg.contains("not on the circle"), "{msg}");
}

#[test]
fn move_modes_are_modal_and_map_to_the_model() {
    let recs = read("RAPID X1 Y1\nX2\nLINEAR X3 F4\nY5\nCIRCLE1 X4 Y6 I1\nX5 Y5 I1 J0\nCIRCLE2 X7 Y5 R1\n");
    let m = moves(&recs);
    assert_eq!(m.len(), 7);
    assert_eq!((m[0].kind, m[0].feed), (MotionKind::Rapid, None));
    assert_eq!((m[1].kind, m[1].feed), (MotionKind::Rapid, None));
    assert_pt(&m[1].to, &p(2.0, 1.0, 0.0));
    assert_eq!((m[2].kind, m[2].feed), (MotionKind::Line, Some(4.0)));
    assert_eq!(m[3].kind, MotionKind::Line);
    assert_pt(&m[3].to, &p(3.0, 5.0, 0.0));
    // CIRCLE1 under the default NORMAL K-1 is G2 in G17.
    let a = arc(m[4]);
    assert!(!a.ccw);
    assert_eq!(a.plane, Plane::Xy);
    assert_pt(&a.center, &p(4.0, 5.0, 0.0));
    assert_eq!(m[4].feed, Some(4.0));
    let b = arc(m[5]);
    assert!(!b.ccw, "CIRCLE1 stays modal");
    assert_pt(&b.center, &p(5.0, 6.0, 0.0));
    let c = arc(m[6]);
    assert!(c.ccw);
    assert_pt(&c.center, &p(6.0, 5.0, 0.0));
}

#[test]
fn compact_and_lower_case_text() {
    let recs = read("linearx1y2f3\nCIR2X0Y3I-1J0 m33=1\nRPDZ1\nLIN X 4 Y 4 Z 0");
    let m = moves(&recs);
    assert_eq!(m.len(), 4);
    assert_pt(&m[0].to, &p(1.0, 2.0, 0.0));
    assert_eq!(m[0].feed, Some(3.0));
    assert!(arc(m[1]).ccw);
    assert_pt(&arc(m[1]).center, &p(0.0, 2.0, 0.0));
    assert_eq!((m[2].kind, m[2].beam), (MotionKind::Rapid, true));
    assert_pt(&m[3].to, &p(4.0, 4.0, 0.0));
}

#[test]
fn abs_inc_and_axis_lists() {
    let recs = read("LINEAR F1\nX1 Y1 Z1\nINC\nX1 Y-2\nABS(X)\nX0 Y1 Z-1\nABS\nINC(Y,Z)\nX5 Y1\n");
    let m = moves(&recs);
    assert_pt(&m[0].to, &p(1.0, 1.0, 1.0));
    assert_pt(&m[1].to, &p(2.0, -1.0, 1.0));
    assert_pt(&m[2].to, &p(0.0, 0.0, 0.0));
    assert_pt(&m[3].to, &p(5.0, 1.0, 0.0));
}

#[test]
fn centre_vector_incremental_and_absolute() {
    // Default INC(R): centre relative to the start point.
    let recs = read("LINEAR F1 X10 Y10\nCIRCLE2 X12 Y12 I2 J0\nABS(R)\nX10 Y10 I12 J10\nINC(R)\nX12 Y12 J2");
    let m = moves(&recs);
    assert_pt(&arc(m[1]).center, &p(12.0, 10.0, 0.0));
    assert_pt(&arc(m[2]).center, &p(12.0, 10.0, 0.0));
    assert_pt(&arc(m[3]).center, &p(10.0, 12.0, 0.0));
    assert!(arc(m[3]).ccw);
}

#[test]
fn radius_arcs_short_and_long_in_both_senses() {
    // From (1,0) to (0,1) with radius 1.
    let cases = [
        ("CIRCLE2 X0 Y1 R1", true, (0.0, 0.0)),
        ("CIRCLE2 X0 Y1 R-1", true, (1.0, 1.0)),
        ("CIRCLE1 X0 Y1 R1", false, (1.0, 1.0)),
        ("CIRCLE1 X0 Y1 R-1", false, (0.0, 0.0)),
    ];
    for (line, ccw, (cx, cy)) in cases {
        let recs = read(&format!("LINEAR X1 Y0 F1\n{line}"));
        let a = arc(moves(&recs)[1]);
        assert_eq!(a.ccw, ccw, "{line}");
        assert_pt(&a.center, &p(cx, cy, 0.0));
    }
    // Rounded half circle: the chord exceeds the diameter by 0.00005.
    let recs = read("LINEAR F1\nCIRCLE2 X1.00005 Y0 R0.5");
    let half = arc(moves(&recs)[0]);
    assert_pt(&half.center, &p(0.500025, 0.0, 0.0));
    let (line, msg) = read_err("LINEAR F1\nCIRCLE1 X1 Y0 R0.4");
    assert_eq!(line, 2);
    assert!(msg.contains("cannot reach"), "{msg}");
    let (line, msg) = read_err("LINEAR F1 X1\nCIRCLE1 X1 Y0 R0.5");
    assert_eq!(line, 2);
    assert!(msg.contains("full circle"), "{msg}");
}

#[test]
fn full_circles_and_helices() {
    let recs = read("LINEAR X1 F2\nCIRCLE1 I-1\nCIRCLE2 X1 Y0 Z-0.5 I-1 J0\nINC\nCIRCLE2 Z-0.5 I-1");
    let m = moves(&recs);
    assert_pt(&m[1].to, &p(1.0, 0.0, 0.0));
    assert_pt(&arc(m[1]).center, &p(0.0, 0.0, 0.0));
    assert!(!arc(m[1]).ccw);
    // Full-turn helix: the end equals the start in the plane only.
    assert_pt(&m[2].to, &p(1.0, 0.0, -0.5));
    assert_pt(&arc(m[2]).center, &p(0.0, 0.0, 0.0));
    assert_pt(&m[3].to, &p(1.0, 0.0, -1.0));
    assert_pt(&arc(m[3]).center, &p(0.0, 0.0, -0.5));
}

#[test]
fn normal_vectors_choose_plane_and_sense() {
    let cases = [
        ("NORMAL K-1", Plane::Xy, false),
        ("NORMAL K1", Plane::Xy, true),
        ("NORMAL J-1", Plane::Xz, false),
        ("NORMAL J1", Plane::Xz, true),
        ("NORMAL I-1", Plane::Yz, false),
        ("NRM I0 J0 K-2", Plane::Xy, false),
        ("NORMAL I1", Plane::Yz, true),
    ];
    for (normal, plane, ccw) in cases {
        let recs = read(&format!("{normal}\nCIRCLE1 F1 I1 J1 K1"));
        let a = arc(moves(&recs)[0]);
        assert_eq!((a.plane, a.ccw), (plane, ccw), "{normal}");
    }
    let (line, msg) = read_err("LINEAR F1\nNORMAL I0.7 J0.7");
    assert_eq!(line, 2);
    assert!(msg.contains("NORMAL"), "{msg}");
    assert_eq!(read_err("NORMAL").0, 1);
}

#[test]
fn shutter_states_with_immediate_and_synchronous_assignment() {
    let recs = read("LINEAR F1\nX1\nM33=1\nX2\nX3 M33==0\nM33 == 1\nX4 M33=0\nX5\nM33=(P1+2)\nX6\nM33=0 X7");
    let beams: Vec<bool> = moves(&recs).iter().map(|m| m.beam).collect();
    // `X3` comes before `M33==0` on its line: still open for it; `X7`
    // comes after `M33=0`: closed.
    assert_eq!(beams, [false, true, true, true, false, true, false]);
    assert_eq!(recs.len(), 7, "shutter assignments make no records");
    // Each move whose beam differs from the one before carries how the
    // switch was written.
    use ShutterSwitch::{Immediate, Sync};
    let switches: Vec<Option<ShutterSwitch>> = moves(&recs).iter().map(|m| m.beam_switch).collect();
    assert_eq!(
        switches,
        [
            None,
            Some(Immediate),
            None,
            None,
            Some(Immediate),
            Some(Immediate),
            Some(Immediate)
        ]
    );
    let recs = read("LINEAR F1\nM33==1 X1\nX2\nM33==0 X3\n");
    let switches: Vec<Option<ShutterSwitch>> = moves(&recs).iter().map(|m| m.beam_switch).collect();
    assert_eq!(switches, [Some(Sync), None, Some(Sync)]);
    // A configured shutter variable.
    let opts = ReadOptions {
        shutter_var: "m7".into(),
        ..pmac_opts()
    };
    let (_, recs) = read_str("LINEAR F1\nM7=1 X1\nM33=1", &opts).unwrap();
    assert!(recs[0].motion().unwrap().beam);
    assert_eq!(
        recs[1],
        Record::Var {
            name: "M33".into(),
            value: 1.0,
            sync: false,
            block: Some(3)
        }
    );
}

#[test]
fn variables_are_recorded_except_shutter_and_counter() {
    let recs = read("P400=1 P12=3.5 Q3=-2\nM40==1 I5193=$2000\nm41=0 p400=P400+1");
    let vars: Vec<(String, f64, bool, Option<u64>)> = recs
        .iter()
        .map(|r| match r {
            Record::Var {
                name,
                value,
                sync,
                block,
            } => (name.clone(), *value, *sync, *block),
            other => panic!("not a var: {other:?}"),
        })
        .collect();
    assert_eq!(
        vars,
        [
            ("P12".to_string(), 3.5, false, Some(1)),
            ("Q3".to_string(), -2.0, false, Some(1)),
            ("M40".to_string(), 1.0, true, Some(2)),
            ("I5193".to_string(), 8192.0, false, Some(2)),
            ("M41".to_string(), 0.0, false, Some(3)),
        ]
    );
    let (line, msg) = read_err("P1==2");
    assert_eq!(line, 1);
    assert!(msg.contains("M-variables only"), "{msg}");
    assert!(read_err("P9000=1").1.contains("out of range"));
    assert!(read_err("LINEAR X1 F1\nP12").1.contains("not an assignment"));
    assert!(read_err("P(P1+1) = 2").1.contains("indirect"));
}

fn value_of(expr: &str) -> f64 {
    let recs = read(&format!("P1=2 Q0=-1 M5=3\nP2={expr}"));
    match recs.last() {
        Some(Record::Var { name, value, .. }) if name == "P2" => *value,
        other => panic!("{other:?}"),
    }
}

#[test]
fn expressions_follow_pmac_precedence_and_functions() {
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    assert_eq!(value_of("1+2*3"), 7.0);
    assert_eq!(value_of("(1+2)*3"), 9.0);
    assert_eq!(value_of("P1*M5-P99"), 6.0);
    assert_eq!(value_of("-P1--3"), 1.0);
    assert_eq!(value_of("10/4"), 2.5);
    assert_eq!(value_of("7%3"), 1.0);
    assert_eq!(value_of("-7%3"), 2.0);
    assert!(close(value_of("SIN(30)"), 0.5));
    assert!(close(value_of("COS(60)+TAN(45)"), 1.5));
    assert!(close(value_of("ASIN(1)"), 90.0));
    assert!(close(value_of("ACOS(0)+ATAN(1)"), 135.0));
    // ATAN2 takes its cosine argument from Q0 (-1 here).
    assert!(close(value_of("ATAN2(1)"), 135.0));
    assert_eq!(value_of("SQRT(16)+ABS(-2)"), 6.0);
    assert_eq!(value_of("INT(2.7)"), 2.0);
    assert_eq!(value_of("INT(-2.5)"), -3.0);
    assert!(close(value_of("LN(EXP(2))"), 2.0));
    assert_eq!(value_of("$FF"), 255.0);
    assert_eq!(value_of("$AA^$55"), 255.0);
    assert_eq!(value_of("3^-3"), -2.0);
    assert_eq!(value_of("0.5^0.875"), 0.375);
    assert_eq!(value_of("6&3|8"), 10.0);
    assert_eq!(value_of("P(P1-1)+1"), 3.0);
    assert_eq!(value_of(" ( P1 + 1 ) * 2 "), 6.0);
    // Unassigned variables read as zero.
    assert_eq!(value_of("Q77+M8000"), 0.0);
    // Axis values may be expressions too.
    let recs = read("P1=2\nLINEAR F(P1*3) X(P1+2) Y-(P1) Z(SIN(90))");
    let m = moves(&recs)[0];
    assert_pt(&m.to, &p(4.0, -2.0, 1.0));
    assert_eq!(m.feed, Some(6.0));
}

#[test]
fn bad_expressions_are_errors() {
    assert!(read_err("P1=1/0").1.contains("not a finite number"));
    assert!(read_err("P1=SQRT(-1)").1.contains("not a finite number"));
    assert!(read_err("P1=(1+2").1.contains("closing"));
    assert!(read_err("P1=FOO(2)").1.contains("unknown function"));
    assert!(read_err("P1=SIN 30").1.contains("parentheses"));
    assert!(read_err("P1=").1.contains("value is expected"));
    let deep = format!("P1={}1{}", "(".repeat(500), ")".repeat(500));
    assert!(read_err(&deep).1.contains("too deeply"));
    let minus = format!("P1={}1", "-".repeat(500));
    assert!(read_err(&minus).1.contains("too deeply"));
    let huge = format!("LINEAR F1 X{}", "9".repeat(400));
    assert!(read_err(&huge).1.contains("not a finite number"));
}

#[test]
fn accel_times_and_dwells() {
    let recs = read("TA10\nTS5 TA(2*10)\nLINEAR X1 F1 TA30\nDWELL100\nDELAY 2.5\nDWE(P1+1) DLY0");
    assert_eq!(
        recs[..4],
        [
            Record::Accel {
                ta_ms: Some(10.0),
                ts_ms: None,
                block: Some(1)
            },
            Record::Accel {
                ta_ms: Some(20.0),
                ts_ms: Some(5.0),
                block: Some(2)
            },
            // TA on a move's line applies to that move: it comes first.
            Record::Accel {
                ta_ms: Some(30.0),
                ts_ms: None,
                block: Some(3)
            },
            recs[3].clone(),
        ]
    );
    assert_eq!(recs[3].motion().unwrap().block, Some(3));
    let dwells: Vec<(f64, Option<u64>)> = recs[4..]
        .iter()
        .map(|r| match r {
            Record::Dwell { seconds, block } => (*seconds, *block),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        dwells,
        [(0.1, Some(4)), (0.0025, Some(5)), (0.001, Some(6)), (0.0, Some(6))]
    );
    assert!(read_err("DWELL -5").1.contains("negative"));
    assert!(read_err("TA-1").1.contains("negative"));
    assert!(read_err("TM-1").1.contains("negative"));
}

#[test]
fn calls_labels_and_delimiters_do_nothing() {
    let recs = read("%\nN10 G90 G54 T1 D0\nLINEAR X1 F2 M3\nM30\nO20 X2\nM(P1+5)\n%100\n");
    let m = moves(&recs);
    assert_eq!(recs.len(), 2);
    assert_pt(&m[1].to, &p(2.0, 0.0, 0.0));
    assert_eq!(m[1].block, Some(5));
}

#[test]
fn error_cases_name_their_line() {
    let cases: [(&str, u64, &str); 15] = [
        ("LINEAR X1", 1, "no feed rate"),
        ("RAPID X1\nCIRCLE1 X2", 2, "no feed rate"),
        ("LINEAR F1\nX1\nFOO3", 3, "unknown word 'FOO3'"),
        ("LINEAR F1\nX1 U2", 2, "axis U"),
        ("F1\nCIRCLE1 X1 Y1", 2, "without a centre"),
        ("F1\nLINEAR X1 I1", 2, "CIRCLE1 or CIRCLE2"),
        ("F1\nCIRCLE1 X1 R1 I1", 2, "not both"),
        ("F1 X1 X2", 1, "twice"),
        ("P1=1\nWHILE(P1<2)", 2, "flow control"),
        ("GOTO 10", 1, "flow control"),
        ("LINEAR F1 (comment)", 1, "comments start with ';'"),
        ("CIRCLE3 X1", 1, "CIRCLE1 or CIRCLE2"),
        ("F0", 1, "positive"),
        ("X1 @", 1, "unexpected character '@'"),
        ("X1 5", 1, "without a word"),
    ];
    for (text, line, needle) in cases {
        let (l, msg) = read_err(text);
        assert_eq!(l, line, "{text}: {msg}");
        assert!(msg.contains(needle), "{text}: {msg}");
    }
}

#[test]
fn buffer_structure() {
    // On-line commands outside buffers are noted, the first motion buffer
    // read (or the one chosen), a PLC skipped, and RETURN ends a program.
    let text = "&1 #1J/ I5=2\nCLOSE DELETE GATHER DEFINE ROT 100 OPEN PROG 5 CLEAR LINEAR X1 F1\nCLOSE\n\
                I6=1 X9 garbage\nOPEN PLC 1 CLEAR\nIF (M1=1) CMD\"CLOSE\" ENDIF\nCLOSE\nOPEN ROT\nLINEAR X2 F1\nRETURN\n\
                N100 WHILE(1) ENDWHILE\nCLOSE &1B0R\n";
    let opts = pmac_opts();
    let (_, recs) = read_str(text, &opts).unwrap();
    let m = moves(&recs);
    assert_eq!(recs.len(), 1, "{recs:?}");
    assert_eq!(m[0].block, Some(2));
    let notes = opts.notes.take();
    let lines: Vec<u64> = notes.iter().map(|n| n.0).collect();
    assert_eq!(lines, [1, 1, 4, 4, 4, 5, 8], "{notes:?}");
    assert!(notes[0].1.starts_with("#1J/: motor command"), "{notes:?}");
    assert!(notes[1].1.contains("I5 = 2 stored"), "{notes:?}");
    assert!(notes[5].1.contains("PLC program skipped"), "{notes:?}");
    assert!(notes[6].1.contains("rotary buffer (OPEN ROT) skipped"), "{notes:?}");
    // The rotary buffer chosen instead: PROG 5 is the first, so only
    // --program picks another; a rotary buffer has no number.
    let opts = ReadOptions {
        pmac_program: Some(5),
        ..pmac_opts()
    };
    assert_eq!(moves(&read_str(text, &opts).unwrap().1)[0].block, Some(2));
    let two = "OPEN PROG 1 CLEAR\nLINEAR X1 F1\nCLOSE\nOPEN PROG 2 CLEAR\nLINEAR X2 F1\nCLOSE\n";
    let opts = ReadOptions {
        pmac_program: Some(2),
        ..pmac_opts()
    };
    let (_, recs) = read_str(two, &opts).unwrap();
    assert_eq!((moves(&recs).len(), moves(&recs)[0].block), (1, Some(5)));
    assert!(opts.notes.take()[0].1.contains("PROG 1 skipped: --program 2"));
    let opts = ReadOptions {
        pmac_program: Some(3),
        ..pmac_opts()
    };
    let e = read_str(two, &opts).unwrap_err();
    assert_eq!(e.line(), 6);
    assert!(
        e.to_string()
            .contains("no OPEN PROG 3 (motion programs in it: PROG 1, PROG 2)"),
        "{e}"
    );
    // Unclosed buffers, nested OPEN, CLEAR after records, on-line text inside.
    let (line, msg) = read_err("OPEN PROG 1\nLINEAR X1 F1\n");
    assert_eq!(line, 2);
    assert!(msg.contains("opened at line 1"), "{msg}");
    assert_eq!(read_err("OPEN PROG 1\nOPEN PROG 2").0, 2);
    assert!(read_err("OPEN PROG 1\nLINEAR X1 F1\nCLEAR").1.contains("CLEAR"));
    assert!(read_err("OPEN PROG 1\n&1B1R").1.contains("on-line command"));
    assert!(read_err("OPEN PROG\nCLOSE").1.contains("program number"));
    assert!(read_err("OPEN GATHER").1.contains("OPEN PROG"));
    // The download preamble alone does not hide a bare program ...
    let recs = read("CLOSE\nDELETE GATHER\nLINEAR X1 F1\n");
    assert_eq!(moves(&recs)[0].block, Some(3));
    // ... but motion after a buffer's CLOSE is outside the program.
    let (line, msg) = read_err("OPEN PROG 1\nLINEAR X1 F1\nCLOSE\n&1B1R\nLINEAR X2\n");
    assert_eq!(line, 5);
    assert!(msg.contains("outside a program buffer"), "{msg}");
    // A bare program: &-lines ignored, RETURN ends reading.
    let recs = read("&1\nLINEAR X1 F1\nRETURN\nthis is never read");
    assert_eq!(recs.len(), 1);
}

#[test]
fn dialect_detection_sees_typical_programs_as_pmac() {
    for text in [
        "OPEN PROG 1 CLEAR\nG54 G90\nLINEAR X1 F1\nCLOSE\n",
        "CLOSE\nDELETE GATHER\nOPEN PROG 1 CLEAR\nRAPID X0\nCLOSE\n",
        "; generated\nLINEAR X1.8 Y5.4 Z0 F2\nM33=0 P400=1\n",
        "M33=0\nF1 X1\n",
        "CIRCLE2 I0 J-0.9 F1\n",
    ] {
        let (d, recs) = read_str(text, &ReadOptions::default()).unwrap();
        assert_eq!(d, Dialect::Pmac, "{text}");
        assert!(!recs.is_empty(), "{text}");
    }
}

#[test]
fn bad_options_are_reported() {
    let opts = ReadOptions {
        shutter_var: "shutter".into(),
        ..pmac_opts()
    };
    let e = read_str("X1", &opts).unwrap_err();
    assert!(e.to_string().contains("shutter variable 'shutter'"), "{e}");
    assert_eq!(
        Var::parse(" p400 "),
        Some(Var {
            kind: VarKind::P,
            index: 400
        })
    );
    assert_eq!(Var::parse("M8192"), None);
    assert_eq!(Var::parse("M"), None);
}

#[test]
fn start_position_and_streaming_reader() {
    let mut text = String::from("OPEN PROG 1 CLEAR\nLINEAR F10 INC\n");
    for i in 0..5000 {
        text.push_str(&format!("X0.1 M33={} P400={i}\n", i % 2));
    }
    text.push_str("CLOSE\n");
    let opts = ReadOptions {
        start: p(1.0, 2.0, 3.0),
        ..ReadOptions::default()
    };
    let reader = ProgramReader::new(text.as_bytes(), &opts).unwrap();
    assert_eq!(reader.dialect(), Dialect::Pmac);
    let recs: Vec<Record> = reader.collect::<Result<_, _>>().unwrap();
    assert_eq!(recs.len(), 5000);
    let last = recs[4999].motion().unwrap();
    assert!((last.to.x - 501.0).abs() < 1e-6);
    assert_eq!((last.to.y, last.to.z), (2.0, 3.0));
    assert_eq!(last.block, Some(5002));
    // M33 is set after the move on each line: move i sees line i-1's value.
    assert!(!recs[0].motion().unwrap().beam);
    assert!(!recs[1].motion().unwrap().beam);
    assert!(recs[2].motion().unwrap().beam);
}

proptest::proptest! {
    /// Any text gives records or an error, never a panic or a hang.
    #[test]
    fn arbitrary_text_never_panics(lines in proptest::collection::vec(
        proptest::prop_oneof![
            "[A-Z0-9=().;+*/%&|^$ ,#@\"-]{0,60}",
            "(LINEAR|RAPID|CIRCLE[12]|X|Y|Z|I|J|K|R|F|TA|TS|M33=|M33==|P400=|P1=|ABS|INC|NORMAL|OPEN PROG 1|CLOSE|DWELL|\\(|\\)|-|[0-9.]{1,8}| ){0,24}",
            proptest::prelude::any::<String>(),
        ],
        0..12,
    )) {
        let text = lines.join("\n");
        let _ = read_str(&text, &pmac_opts());
        let _ = read_str(&text, &ReadOptions::default());
    }
}

/// Throughput check: `cargo test --release --lib pmac::tests::throughput
/// -- --ignored --nocapture` prints lines per second (the target is
/// millions in release builds).
#[test]
#[ignore]
fn throughput() {
    let mut text = String::from("OPEN PROG 1 CLEAR\nLINEAR F2\n");
    for i in 0..200_000u32 {
        let x = f64::from((i / 4) % 1000) * 0.0013;
        match i % 4 {
            0 => text.push_str(&format!("LINEAR X{x:.4} Y5.455 Z0 F2\n")),
            1 => text.push_str(&format!("M33=1 P400={i}\n")),
            2 => text.push_str(&format!("CIRCLE1 X{:.4} Y5.455 I0.05 J0\n", x + 0.1)),
            _ => text.push_str(&format!("M33=0 P400={i}\n")),
        }
    }
    text.push_str("CLOSE\n");
    let lines = text.lines().count();
    let t = std::time::Instant::now();
    let reader = ProgramReader::new(text.as_bytes(), &ReadOptions::default()).unwrap();
    let n = reader.collect::<Result<Vec<_>, _>>().unwrap().len();
    let s = t.elapsed().as_secs_f64();
    assert_eq!(n, 100_000);
    println!("{lines} lines in {s:.3} s: {:.0} lines/s", lines as f64 / s);
}

#[test]
fn numbers_parse_exactly() {
    let mut c = Cursor::new("1.8183 .5 5. 12345678901234567.25 0.1");
    let mut got = Vec::new();
    while c.peek().is_some() {
        c.skip_ws();
        got.push(c.number().unwrap());
    }
    assert_eq!(got, [1.8183, 0.5, 5.0, 12345678901234567.25, 0.1]);
    assert_eq!(Cursor::new("x").number(), None);
    assert_eq!(Cursor::new("FFFFFFFFFFFFFFFFF").hex(), None);
}

#[test]
fn move_time_frax_and_axes_that_stay_put() {
    // TM gives the move its time: feed = length / time; F returns to feeds.
    let recs = read("LINEAR TM500 X1 Y1\nX2 Y1 F3\nTM(250)\nCIRCLE1 X3 Y0 I0 J-1\n");
    let m = moves(&recs);
    assert!((m[0].feed.unwrap() - 2f64.sqrt() / 0.5).abs() < 1e-12);
    assert_eq!(m[1].feed, Some(3.0));
    assert!((m[2].feed.unwrap() - std::f64::consts::FRAC_PI_2 / 0.25).abs() < 1e-9);
    // A move of no length in TM mode is its time in place; TM0 with length is refused.
    let recs = read("LINEAR TM(Q70) X0 Y0 A(Q71) W0\nDWELL0\n");
    assert_eq!(
        recs,
        [
            Record::Dwell {
                seconds: 0.0,
                block: Some(1)
            },
            Record::Dwell {
                seconds: 0.0,
                block: Some(2)
            }
        ]
    );
    assert!(read_err("LINEAR TM0 X1").1.contains("in no time"));
    // FRAX(X,Y): F is the XY speed; Z rides along, so the path is faster.
    let m = read("FRAX(X,Y) LINEAR X3 Z4 F3\nX6 F3\n");
    assert_eq!(moves(&m)[0].feed, Some(5.0));
    assert_eq!(moves(&m)[1].feed, Some(3.0));
    assert!(read_err("FRAX(X,Y) LINEAR Z1 F1").1.contains("no FRAX axis"));
    assert_eq!(moves(&read("FRAX(A,B,C,U,V,W,X,Y,Z) LINEAR X1 F1"))[0].feed, Some(1.0));
    // U, V, W are read where they stay put, and refused where they move.
    let (line, msg) = read_err("LINEAR F1 X1 U0\nINC U0 V0\nABS X2 W1\n");
    assert_eq!(line, 3);
    assert!(msg.contains("axis W moves (from 0 to 1)"), "{msg}");
    assert!(read_err("INC LINEAR F1 X1 U0.5").1.contains("axis U moves"));
}

#[test]
fn rotary_axes_a_b_c_are_carried_on_every_later_move() {
    let recs = read("LINEAR F1 X1\nX2 A0\nABS X3 B1\nINC X1 C-5\nX1\n");
    let m = moves(&recs);
    assert_eq!(m.len(), 5);
    assert_eq!(m[0].tool.abc, None, "no rotary word yet");
    assert_eq!(m[1].tool.abc, Some([0.0, 0.0, 0.0]));
    assert_eq!(m[2].tool.abc, Some([0.0, 1.0, 0.0]));
    assert_eq!(m[3].tool.abc, Some([0.0, 1.0, -5.0]), "INC: C is an increment");
    assert_eq!(m[4].tool.abc, Some([0.0, 1.0, -5.0]));
    assert_eq!(m[4].to, p(5.0, 0.0, 0.0));
    // F is the speed of X, Y, Z (the default FRAX): A rides along.
    assert_eq!(m[1].feed, Some(1.0));
    // A rotary-only move with a time: degrees per second.
    let recs = read("LINEAR TM500 A90\n");
    assert_eq!(moves(&recs)[0].feed, Some(180.0));
    assert_eq!(moves(&recs)[0].tool.abc, Some([90.0, 0.0, 0.0]));
    // What a controller times by Isx86, or with A in FRAX, is not modelled.
    let (line, msg) = read_err("LINEAR F1 X1\nA90\n");
    assert_eq!(line, 2);
    assert!(msg.contains("rotary axes only"), "{msg}");
    assert!(
        read_err("FRAX(X,Y,Z,A) LINEAR F1 X1 A5")
            .1
            .contains("rotary axis in FRAX")
    );
    assert_eq!(moves(&read("FRAX(X,Y,Z,A) LINEAR F1 X1 A0"))[0].feed, Some(1.0));
}
