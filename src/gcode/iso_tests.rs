//! Tests of the ISO reader (iso.rs and its parts).

use super::*;
use crate::gcode::{Dialect, read_str};
use crate::geometry::P2;

fn read(text: &str) -> Result<Vec<Record>, GcodeError> {
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    read_str(text, &opts).map(|(_, r)| r)
}

fn moves(text: &str) -> Vec<Motion> {
    read(text)
        .unwrap()
        .into_iter()
        .filter_map(|r| match r {
            Record::Move(m) => Some(m),
            _ => None,
        })
        .collect()
}

fn close(a: &P3, b: [f64; 3]) -> bool {
    (a - P3::new(b[0], b[1], b[2])).norm() < 1e-9
}

#[test]
fn lines_arcs_and_modes() {
    let m = moves("G21 G90 G17\nG0 X1 Y2\nG1 Z-1 F100\nX3\nG91 Y1\nG90 G2 X5 Y3 I1 J0\nG3 X3 Y3 R2\n");
    assert_eq!(m.len(), 6);
    assert!(close(&m[0].to, [1.0, 2.0, 0.0]) && m[0].kind == MotionKind::Rapid && m[0].feed.is_none());
    assert!(close(&m[1].to, [1.0, 2.0, -1.0]) && m[1].feed == Some(100.0));
    assert!(close(&m[2].to, [3.0, 2.0, -1.0]));
    assert!(close(&m[3].to, [3.0, 3.0, -1.0]));
    let MotionKind::Arc(a) = m[4].kind else {
        panic!("not an arc")
    };
    assert!(close(&a.center, [4.0, 3.0, -1.0]) && !a.ccw && a.plane == Plane::Xy);
    assert!(close(&m[4].to, [5.0, 3.0, -1.0]));
    let MotionKind::Arc(a) = m[5].kind else {
        panic!("not an arc")
    };
    assert!(a.ccw);
    assert!(((P2::new(5.0, 3.0) - Plane::Xy.project(&a.center)).norm() - 2.0).abs() < 1e-9);
    assert_eq!(m[5].block, Some(7));
}

#[test]
fn inch_programs_become_millimetres() {
    let m = moves("G20 G0 X1 Y0.5\nG1 X2 F10\n");
    assert!(close(&m[0].to, [25.4, 12.7, 0.0]));
    assert_eq!(m[1].feed, Some(254.0));
}

#[test]
fn feed_keeps_its_speed_across_unit_changes_as_in_linuxcnc() {
    // F is converted when set, before G20/G21 on the same line.
    let m = moves("G21 G1 X1 F600\nG20 X1\nG21 F300 G1 X2\n");
    let feeds: Vec<_> = m.iter().map(|m| m.feed.unwrap()).collect();
    assert!((feeds[0] - 600.0).abs() < 1e-9 && (feeds[1] - 600.0).abs() < 1e-9);
    assert!(
        (feeds[2] - 7620.0).abs() < 1e-9,
        "F300 is read in inches, before G21 applies: {feeds:?}"
    );
}

#[test]
fn named_locals_do_not_leak_through_calls() {
    let m = moves("o<f> sub\n#<depth>=[#1*10]\nG0 X#<depth>\no<f> endsub\n#<depth>=5\no<f> call [1]\nG0 X#<depth>\n");
    assert!(close(&m[0].to, [10.0, 0.0, 0.0]) && close(&m[1].to, [5.0, 0.0, 0.0]));
}

#[test]
fn planes_full_circles_helices_and_turns() {
    let m = moves("G0 X1 Y0 Z0\nG18 G2 X1 Z0 I-1 F60\nG19 G3 Y0 Z2 J0 K1\nG17 G2 X1 Y0 Z-1 I-1 P3\n");
    let MotionKind::Arc(a) = m[1].kind else { panic!() };
    assert_eq!(a.plane, Plane::Xz);
    assert!(close(&a.center, [0.0, 0.0, 0.0]) && !a.ccw);
    let MotionKind::Arc(a) = m[2].kind else { panic!() };
    assert_eq!(a.plane, Plane::Yz);
    assert!(close(&a.center, [1.0, 0.0, 1.0]));
    let MotionKind::Arc(a) = m[3].kind else { panic!() };
    assert_eq!(a.extra_turns, 2);
    assert!(close(&m[3].to, [1.0, 0.0, -1.0]));
}

#[test]
fn parameters_expressions_and_named_parameters() {
    let m = moves("#1=2\n#<z_safe>=5\nG0 X#1 Y[#1*3] Z#<z_safe>\n#1=[#1+1] G0 X#1\nG0 X#1\n");
    assert!(close(&m[0].to, [2.0, 6.0, 5.0]));
    // The assignment takes effect after the line is read.
    assert!(close(&m[1].to, [2.0, 6.0, 5.0]));
    assert!(close(&m[2].to, [3.0, 6.0, 5.0]));
}

#[test]
fn beam_follows_spindle_and_program_ends() {
    let recs = read("%\nS1000 M3\nG1 X1 F10\nM5\nG1 X2\nM30\nG1 X9\n%\n").unwrap();
    assert!(matches!(recs[0], Record::Spindle { rpm, .. } if rpm == 1000.0));
    let m: Vec<_> = recs.iter().filter_map(Record::motion).collect();
    assert_eq!(m.len(), 2, "nothing after M30 runs");
    assert!(m[0].beam && !m[1].beam);
}

/// A '%' line with text after it (Fusion 360's MPCNC post writes "% vfd
/// enable") is a remark, not the end of the program; a bare '%', after a
/// comment or not, still is.
#[test]
fn percent_with_text_is_a_remark_and_a_bare_percent_ends() {
    let m = moves("%\n(head)\nG0 X1\n% vfd enable\nG1 X2 F100\n%( *** START end ***)\nG1 X9\n");
    assert_eq!(m.len(), 2, "{m:?}");
    assert!(close(&m[1].to, [2.0, 0.0, 0.0]));
    let m = moves("%\n% LED ON\nG0 X1\n%%\nG1 X3 F100\n%\nG1 X9\n");
    assert_eq!(m.len(), 2, "{m:?}");
    assert!(close(&m[1].to, [3.0, 0.0, 0.0]));
}

#[test]
fn offsets_keep_moves_continuous() {
    let m = moves("G0 X10\nG92 X0\nG0 X5\nG92.1\nG0 X1\nG10 L2 P2 X100\nG55 G0 X1\n");
    assert!(close(&m[1].to, [15.0, 0.0, 0.0]));
    assert!(close(&m[2].to, [1.0, 0.0, 0.0]));
    assert!(close(&m[3].to, [101.0, 0.0, 0.0]));
}

#[test]
fn g52_sets_the_g92_offsets_as_linuxcnc() {
    // rs274: G52 X10 Y5 then G0 X1 Y1 is machine (11, 6); G52 X2 keeps Y.
    let m = moves("G0 X1 Y1\nG52 X10 Y5\nG0 X1 Y1\nG52 X2\nG0 X0\nG92 X0\nG0 X1\nG52 X0 Y0\nG0 X0 Y0\n");
    let to: Vec<[f64; 2]> = m.iter().map(|m| [m.to.x, m.to.y]).collect();
    assert_eq!(to, vec![[1.0, 1.0], [11.0, 6.0], [2.0, 6.0], [3.0, 6.0], [0.0, 0.0]]);
}

#[test]
fn absolute_arc_centres() {
    let m = moves("G90.1 G0 X1 Y0\nG3 X-1 Y0 I0 J0 F10\n");
    let MotionKind::Arc(a) = m[1].kind else { panic!() };
    assert!(close(&a.center, [0.0, 0.0, 0.0]));
}

#[test]
fn rotary_axes_are_carried_on_every_later_move() {
    let m = moves("G0 X1 Y0 Z0\nT3 M6\nG0 A90\nG91 G1 X1 B-45 C10 F100\nG90 G3 X3 Y1 I0 J1 A0\nG1 X4\nG28\n");
    assert_eq!(m[0].tool.abc, None, "before any rotary word");
    assert_eq!(m[0].tool.number, None, "no tool before M6");
    assert_eq!(m[1].tool.number, Some(3));
    assert!(close(&m[1].to, [1.0, 0.0, 0.0]) && m[1].tool.abc == Some([90.0, 0.0, 0.0]));
    assert_eq!(m[2].tool.abc, Some([90.0, -45.0, 10.0]), "G91 adds");
    assert!(matches!(m[3].kind, MotionKind::Arc(_)) && m[3].tool.abc == Some([0.0, -45.0, 10.0]));
    assert_eq!(m[4].tool.abc, Some([0.0, -45.0, 10.0]), "unchanged axes are carried");
    assert_eq!(
        m.last().unwrap().tool.abc,
        Some([0.0; 3]),
        "G28 homes the rotary axes too"
    );
    // Degrees stay degrees in an inch program.
    let m = moves("G20 G0 X1 A30\n");
    assert!(close(&m[0].to, [25.4, 0.0, 0.0]) && m[0].tool.abc == Some([30.0, 0.0, 0.0]));
}

#[test]
fn feed_modes_as_linuxcnc() {
    // G93: the feed that makes the move take 1/F minutes; a rotary-only
    // move counts its degrees; F is no length and ignores G20.
    let m = moves("G0 X0 Y0\nG93 G1 X10 F2\nG2 X20 Y0 I5 J0 F4\nG1 A90 F1\nG20 G1 X1 F3\nG21 G94 G1 X0 F50\n");
    let feeds: Vec<f64> = m.iter().skip(1).map(|m| m.feed.unwrap()).collect();
    // F on the G21 line is read in inches, as LinuxCNC does.
    let want = [
        20.0,
        4.0 * 5.0 * std::f64::consts::PI,
        90.0,
        (25.4 - 20.0) * 3.0,
        50.0 * 25.4,
    ];
    for (f, w) in feeds.iter().zip(want) {
        assert!((f - w).abs() < 1e-9, "{feeds:?}");
    }
    // G95: F per revolution times the spindle speed in force.
    let m = moves("S2000 M3\nG95 G1 X1 F0.01\nS500\nG1 X2\nG20\nG1 X1 F0.001\n");
    let feeds: Vec<f64> = m.iter().map(|m| m.feed.unwrap()).collect();
    assert_eq!(feeds.len(), 3);
    assert!(
        (feeds[0] - 20.0).abs() < 1e-9 && (feeds[1] - 5.0).abs() < 1e-9,
        "{feeds:?}"
    );
    assert!((feeds[2] - 0.001 * 25.4 * 500.0).abs() < 1e-9, "{feeds:?}");
}

#[test]
fn what_we_cannot_honour_is_an_error_naming_the_line() {
    let cases = [
        ("G1 X1 F10\nG41 D1\n", 2, "cutter radius compensation"),
        ("G81 X1 Y1 Z-1 R1\n", 1, "no feed rate"),
        ("O100 call\n", 1, "before its definition"),
        ("o1 while [1]\no1 endwhile\n", 1, "endless"),
        ("o1 if [1]\nG0 X1\n", 2, "ends inside o1 if"),
        ("o1 endif\n", 1, "without its opening line"),
        ("G0 W10\n", 1, "W is not supported"),
        ("G92 A10\n", 1, "no rotary offsets"),
        ("G1 X1 F10\nG81 X1 Z-1 R1 A10\n", 2, "G0, G1, G2 and G3 moves only"),
        ("G0 X0\nG41.1 D1\nG1 X5 F10\nG1 X10 A5\n", 4, "compensation on"),
        ("G93 G1 X1 F2\nG1 X2\n", 2, "F word missing"),
        ("G93 G1 X1 F2\nG81 X1 Z-1 R1 F3\n", 2, "inverse time"),
        ("G95 G1 X1 F0.1\n", 1, "no spindle speed"),
        ("G1 X1 F10\nG94\nG1 X2\n", 3, "no feed rate"),
        ("G1 X1\n", 1, "no feed rate"),
        ("G0 X0 Y0\nG2 X2 Y0 I0.5 F10\n", 2, "not on the circle"),
        ("G2 X0 Y1 R0.1 F1\n", 1, "too small"),
        ("G0 G1 X1\n", 1, "modal group 1"),
        ("G0 X1 X2\n", 1, "repeated"),
        ("G0 X[1+\n", 1, "X word"),
        ("G0 X1 (unclosed\n", 1, "not closed"),
        ("G80\nX1\n", 2, "no motion mode"),
        ("G12\n", 1, "unknown G code G12"),
        ("G10 L2 P0.5 X1\n", 1, "G10 P must be"),
        ("G10 L2 P-1 X1\n", 1, "G10 P must be"),
        ("G2 X1 F1\n", 1, "needs R or"),
    ];
    for (text, line, needle) in cases {
        let e = read(text).unwrap_err();
        assert_eq!(e.line(), line, "{text:?}: {e}");
        assert!(e.to_string().contains(needle), "{text:?}: {e}");
    }
}

#[test]
fn stray_bytes_in_comments_are_harmless_and_elsewhere_named() {
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    let ok: &[u8] = b"G0 X1 (caf\xe9 \xff)\nG0 X2 ; \xfe\n";
    let recs: Vec<_> = crate::gcode::ProgramReader::new(ok, &opts).unwrap().collect();
    assert_eq!(recs.len(), 2);
    assert!(recs.iter().all(|r| r.is_ok()));
    let bad: &[u8] = b"G0 X1\nG0 X\xe92\n";
    let e = crate::gcode::ProgramReader::new(bad, &opts)
        .unwrap()
        .find_map(|r| r.err())
        .unwrap();
    assert_eq!(e.line(), 2);
    assert!(e.to_string().contains("0xe9"), "{e}");
}

#[test]
fn subroutines_loops_and_conditions() {
    let text = "o<side> sub\n  G1 X[#1] Y[#2] F100\no<side> endsub\n\
                #1=99\n#<i>=0\n\
                o10 while [#<i> LT 3]\n  o<side> call [#<i>] [#<i>*2]\n\
                o11 if [#<i> EQ 1]\n G0 Z1\n o11 elseif [#<i> EQ 2]\n G0 Z2\n o11 else\n G0 Z9\n o11 endif\n\
                #<i>=[#<i>+1]\no10 endwhile\n\
                o20 repeat [2]\n G0 X-1\no20 endrepeat\n\
                o30 do\n #<i>=[#<i>-1]\n o31 if [#<i> EQ 1]\n  o30 break\n o31 endif\no30 while [#<i> GT 0]\n\
                G0 X#1 Y#<i>\n";
    let m = moves(text);
    let to: Vec<[f64; 3]> = m.iter().map(|m| [m.to.x, m.to.y, m.to.z]).collect();
    assert_eq!(
        to,
        vec![
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 9.0],
            [1.0, 2.0, 9.0],
            [1.0, 2.0, 1.0],
            [2.0, 4.0, 1.0],
            [2.0, 4.0, 2.0],
            [-1.0, 4.0, 2.0],
            [-1.0, 4.0, 2.0],
            [99.0, 1.0, 2.0],
        ]
    );
}

#[test]
fn subroutines_come_from_files_on_the_subroutine_path() {
    let dir = std::env::temp_dir().join(format!("microcam-subpath-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("side.ngc"), "o<side> sub\nG1 X#1 F10\no<side> endsub\n").unwrap();
    let mut opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    let text = "o<side> call [3]\no<side> call [4]\n";
    let e = read_str(text, &opts).unwrap_err();
    assert!(e.to_string().contains("--subroutine-path") && e.line() == 1, "{e}");
    opts.subroutine_path = vec![dir.join("missing"), dir.clone()];
    let (_, recs) = read_str(text, &opts).unwrap();
    let xs: Vec<f64> = recs.iter().filter_map(Record::motion).map(|m| m.to.x).collect();
    assert_eq!(xs, vec![3.0, 4.0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_badge_sample_reads_in_every_plane() {
    let text = include_str!("../../testdata/gcode/badge.ngc");
    let recs = read(text).unwrap();
    let arcs = recs
        .iter()
        .filter(|r| {
            matches!(
                r,
                Record::Move(Motion {
                    kind: MotionKind::Arc(_),
                    ..
                })
            )
        })
        .count();
    assert_eq!(arcs, 8, "{arcs} arcs");
}

#[test]
fn the_spindle_starts_empty_as_in_linuxcnc() {
    // LinuxCNC starts with tool 0 (no tool) in the spindle: G43 before any
    // M6 takes its zero offset, M6 without a T loads tool 0, and moves carry
    // no tool number until a real tool is loaded; T0 M6 empties it again.
    let table = crate::gcode::tooltable::ToolTable::parse("T1 P1 D3\nT2 P2 Z10 D6\n", false).unwrap();
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        tool_table: Some(std::sync::Arc::new(table)),
        ..Default::default()
    };
    let read_t = |text: &str| read_str(text, &opts).map(|(_, r)| r);
    let tools = |text: &str| -> Vec<Option<u32>> {
        read_t(text)
            .unwrap()
            .iter()
            .filter_map(Record::motion)
            .map(|m| m.tool.number)
            .collect()
    };
    assert_eq!(
        tools("G43\nG0 X1\nM6\nG0 X2\nG43 H2\nG0 X3\nT2 M6\nG0 X4\nT0 M6\nG0 X5\nM61 Q1\nG0 X6\n"),
        [None, None, None, Some(2), None, Some(1)]
    );
    // H names any tool of the table, loaded or not; rs274 refuses others
    // ("Requested tool 5 not found in the tool table") and a fraction.
    for (text, needle) in [
        ("G0 X1\nG43 H5\n", "not in the tool table"),
        ("G0 X1\nG43.2 H-1\n", "not in the tool table"),
        ("G0 X1\nG43 H1.5\n", "whole number"),
    ] {
        let e = read_t(text).unwrap_err();
        assert_eq!(e.line(), 2, "{text}: {e}");
        assert!(e.to_string().contains(needle), "{text}: {e}");
    }
    // Without a table nothing is known of the tools: any H >= 0 passes.
    assert!(read("G43 H5\nG0 X1\n").is_ok());
}

#[test]
fn the_loop_bound_is_the_callers_to_set() {
    // 5 iterations of a loop that moves each time: fine under a bound of
    // 5, an error naming the `while` line under a bound of 4.
    let text = "#1=0\no1 while [#1 LT 5]\nG1 X[#1] F10\n#1=[#1+1]\no1 endwhile\n";
    let opts = |n| ReadOptions {
        dialect: Some(Dialect::Iso),
        max_loop_iterations: n,
        ..ReadOptions::default()
    };
    let (_, records) = read_str(text, &opts(5)).unwrap();
    assert_eq!(records.iter().filter(|r| matches!(r, Record::Move(_))).count(), 5);
    let e = read_str(text, &opts(4)).unwrap_err();
    assert!(e.to_string().contains("more than 4 loop iterations"), "{e}");
    assert_eq!(ReadOptions::default().max_loop_iterations, 1_000_000);
}
