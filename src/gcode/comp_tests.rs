//! Tests of cutter radius compensation (comp.rs): entries, corners,
//! exits and planes against what LinuxCNC computes.

use crate::gcode::{Dialect, ReadOptions, read_str};
use crate::geometry::{P2, P3, Plane};
use crate::model::toolpath::{Motion, MotionKind, Record};
use proptest::prelude::*;

/// 'T'/'F' with (x, y, z), or 'A' with end and centre (x, y) and sense.
#[derive(Debug, Clone, PartialEq)]
enum M {
    T(f64, f64, f64),
    F(f64, f64, f64),
    A(f64, f64, f64, f64, bool),
}

fn moves(text: &str) -> Vec<M> {
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    let (_, recs) = read_str(text, &opts).unwrap_or_else(|e| panic!("{e}"));
    recs.iter()
        .filter_map(|r| match r {
            Record::Move(m) => Some(match m.kind {
                MotionKind::Rapid => M::T(m.to.x, m.to.y, m.to.z),
                MotionKind::Line => M::F(m.to.x, m.to.y, m.to.z),
                MotionKind::Arc(a) => M::A(m.to.x, m.to.y, a.center.x, a.center.y, a.ccw),
            }),
            _ => None,
        })
        .collect()
}

/// Same moves, to rs274's 4 printed decimals.
fn check(text: &str, want: &[M]) {
    let got = moves(text);
    let close = |a: f64, b: f64| (a - b).abs() <= 6e-5;
    let ok = got.len() == want.len()
        && got.iter().zip(want).all(|(g, w)| match (g, w) {
            (M::T(a, b, c), M::T(x, y, z)) | (M::F(a, b, c), M::F(x, y, z)) => {
                close(*a, *x) && close(*b, *y) && close(*c, *z)
            }
            (M::A(a, b, c, d, s), M::A(x, y, u, v, t)) => {
                close(*a, *x) && close(*b, *y) && close(*c, *u) && close(*d, *v) && s == t
            }
            _ => false,
        });
    assert!(ok, "{text}\n got {got:?}\nwant {want:?}");
}

use M::{A, F, T};

#[test]
fn the_yz_plane_compensates_as_the_xy_plane_turned_by_the_axis_cycle() {
    let xy = "G17 G0 X-5 Y-5 Z1\nG4?.1 D2 G1 X0 Y0 F10\nX10\nG3 X10 Y10 R5\nG2 X0 Y10 R5\nG1 Y0\nG40 G1 X-5 Y-5\n";
    // X->Y, Y->Z, Z->X; I->J, J->K.
    let yz = "G19 G0 Y-5 Z-5 X1\nG4?.1 D2 G1 Y0 Z0 F10\nY10\nG3 Y10 Z10 R5\nG2 Y0 Z10 R5\nG1 Z0\nG40 G1 Y-5 Z-5\n";
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    let cycle = |p: &P3| P3::new(p.z, p.x, p.y);
    for side in ["1", "2"] {
        let (_, a) = read_str(&xy.replace('?', side), &opts).unwrap();
        let (_, b) = read_str(&yz.replace('?', side), &opts).unwrap();
        let (a, b): (Vec<&Motion>, Vec<&Motion>) = (
            a.iter().filter_map(Record::motion).collect(),
            b.iter().filter_map(Record::motion).collect(),
        );
        assert_eq!(a.len(), b.len(), "G4{side}");
        assert!(a.len() >= 8, "G4{side}: {} moves", a.len());
        for (m, n) in a.iter().zip(&b) {
            assert!(
                (cycle(&m.to) - n.to).norm() < 1e-9,
                "G4{side}: {:?} vs {:?}",
                m.to,
                n.to
            );
            match (m.kind, n.kind) {
                (MotionKind::Arc(p), MotionKind::Arc(q)) => {
                    assert!((cycle(&p.center) - q.center).norm() < 1e-9, "G4{side}");
                    assert_eq!((p.ccw, q.plane), (q.ccw, Plane::Yz));
                }
                (k, l) => assert_eq!(std::mem::discriminant(&k), std::mem::discriminant(&l)),
            }
        }
    }
}

#[test]
fn a_new_entry_just_after_g40_starts_at_the_programmed_point_as_rs274() {
    // rs274: after G40 ends an offset path its current point is the
    // programmed (10, 0), not the tool's (10, 1); the entry counts from it.
    check(
        "G0 X-5 Y-5\nG41.1 D2 G1 X0 Y0 F10\nX10\nG40\nG42.1 D2 G1 X20 Y5\nX30\nG40 G1 X40\n",
        &[
            T(-5.0, -5.0, 0.0),
            F(-std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2, 0.0),
            A(0.0, 1.0, 0.0, 0.0, false),
            F(10.0, 1.0, 0.0),
            F(20.2361, 4.0, 0.0),
            F(30.0, 4.0, 0.0),
            F(40.0, 5.0, 0.0),
        ],
    );
}

#[test]
fn squares_inside_and_outside_as_rs274() {
    // Expected: LinuxCNC 2.9 rs274's canonical calls for the same text.
    let sq = "G0 X-5 Y-5\nG4?.1 D2 G1 X0 Y0 F10\nX10\nY10\nX0\nY0\nG40 G1 X-5 Y-5\n";
    check(
        &sq.replace('?', "1"),
        &[
            T(-5.0, -5.0, 0.0),
            F(-std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2, 0.0),
            A(0.0, 1.0, 0.0, 0.0, false),
            F(9.0, 1.0, 0.0),
            F(9.0, 9.0, 0.0),
            F(1.0, 9.0, 0.0),
            F(1.0, 0.0, 0.0),
            F(-5.0, -5.0, 0.0),
        ],
    );
    check(
        &sq.replace('?', "2"),
        &[
            T(-5.0, -5.0, 0.0),
            F(0.4142, -1.0, 0.0),
            F(10.0, -1.0, 0.0),
            A(11.0, 0.0, 10.0, 0.0, true),
            F(11.0, 10.0, 0.0),
            A(10.0, 11.0, 10.0, 10.0, true),
            F(0.0, 11.0, 0.0),
            A(-1.0, 10.0, 0.0, 10.0, true),
            F(-1.0, 0.0, 0.0),
            F(-5.0, -5.0, 0.0),
        ],
    );
}

#[test]
fn arcs_and_their_corners_as_rs274() {
    let prog = "G0 X-5 Y0\nG4?.1 D2 G1 X0 Y0 F10\nG2 X10 Y0 R5\nG1 Y-10\nG3 X20 Y-10 R5\nG2 X30 Y-10 R5\n";
    check(
        &format!("{}G1 X30 Y5\nG40 X40\n", prog.replace('?', "1")),
        &[
            T(-5.0, 0.0, 0.0),
            F(-0.9161, 1.0, 0.0),
            A(11.0, 0.0, 5.0, 0.0, false),
            F(11.0, -10.0, 0.0),
            A(19.0, -10.0, 15.0, -10.0, true),
            A(29.0, -5.5279, 25.0, -10.0, false),
            F(29.0, 5.0, 0.0),
            F(40.0, 5.0, 0.0),
        ],
    );
    check(
        &format!("{}G1 X30 Y5 Z-1\nZ1\nX40\nG40 X50\n", prog.replace('?', "2")),
        &[
            T(-5.0, 0.0, 0.0),
            F(0.0, -1.0, 0.0),
            A(1.0, 0.0, 0.0, 0.0, true),
            A(9.0, 0.0, 5.0, 0.0, false),
            F(9.0, -10.0, 0.0),
            A(21.0, -10.0, 15.0, -10.0, true),
            A(29.0, -10.0, 25.0, -10.0, false),
            A(31.0, -10.0, 30.0, -10.0, true),
            F(31.0, 4.0, -1.0),
            F(31.0, 4.0, 1.0),
            F(40.0, 4.0, 1.0),
            F(50.0, 5.0, 1.0),
        ],
    );
    check(
        "G0 X-5 Y0\nG41.1 D2 G2 X0 Y5 I5 J0 F10\nG1 X10\nG40 G0 X20\n",
        &[
            T(-5.0, 0.0, 0.0),
            A(0.0, 6.0, 0.0, 0.916_7, false),
            F(10.0, 6.0, 0.0),
            T(20.0, 5.0, 0.0),
        ],
    );
}

#[test]
fn compensation_errors_name_the_line() {
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    for (text, line, needle) in [
        ("G41 D1\nG1 X1 F1\n", 1, "--tool-table"),
        ("G41.1 D1\nG41.1 D1\n", 2, "already on"),
        ("G41.1\n", 1, "needs a D"),
        ("G41.1 D4\nG1 X1 F1\n", 2, "entry move"),
        ("G41.1 D2\nG1 X10 F1\nG18\n", 3, "planes"),
        ("G41.1 D2\nG1 X10 F1\nT1 M6\n", 3, "change tools"),
        ("G41.1 D2\nG1 X10 F1\nG81 X1 R1 Z-1\n", 3, "canned cycles"),
        ("G41.1 D2\nG1 X10 F1\nY5\nX9.9\nY-5\n", 5, "concave corner"),
        // LinuxCNC: a new G41/G42 after G40 does not allow the arc.
        (
            "G0 X-5\nG41.1 D2\nG1 X0 F1\nX10\nG40\nG42.1 D2\nG3 X0 Y0 I-5\n",
            7,
            "cannot be an arc",
        ),
    ] {
        let e = read_str(text, &opts).unwrap_err();
        assert_eq!(e.line(), line, "{text:?}: {e}");
        assert!(e.to_string().contains(needle), "{text:?}: {e}");
    }
}

/// Distance from `q` to the segment a-b.
fn seg_dist(q: P2, a: P2, b: P2) -> f64 {
    crate::geometry::line::point_segment_distance(&q, &a, &b)
}

proptest! {
    /// Random convex polygons (lines and convex corners, both sides):
    /// every compensated point lies exactly one tool radius from the
    /// programmed outline, and every corner arc is centred on a
    /// programmed corner with the tool radius.
    #[test]
    fn compensated_outlines_are_at_the_tool_radius(
        n in 3usize..9,
        jitter in proptest::collection::vec(0.0..1.0f64, 9),
        radius in 20.0..40.0f64,
        d in 0.5..6.0f64,
        left: bool,
        ccw: bool,
    ) {
        let pts: Vec<P2> = (0..n)
            .map(|k| {
                let a = (k as f64 + 0.8 * jitter[k]) / n as f64 * std::f64::consts::TAU;
                let a = if ccw { a } else { -a };
                // On a circle, so the outline is convex.
                P2::new(radius * a.cos(), radius * a.sin())
            })
            .collect();
        // Inside a convex outline the corners are concave: keep the
        // tool small against the shortest side then.
        let inside = left == ccw;
        let shortest = (0..n).map(|k| (pts[(k + 1) % n] - pts[k]).norm()).fold(f64::MAX, f64::min);
        prop_assume!(!inside || d < shortest / 4.0);
        let mut text = format!(
            "G0 X{} Y{}\nG4{}.1 D{d} G1 X{} Y{} F100\n",
            pts[0].x * 2.0, pts[0].y * 2.0, if left { 1 } else { 2 }, pts[0].x, pts[0].y
        );
        // Round the outline and along its first side again, so that
        // every corner is turned.
        for k in 1..=n + 1 {
            let p = pts[k % n];
            text += &format!("X{} Y{}\n", p.x, p.y);
        }
        text += &format!("G40 G0 X{} Y{}\n", pts[0].x * 2.0, pts[0].y * 2.0);
        let opts = ReadOptions { dialect: Some(Dialect::Iso), ..Default::default() };
        let (_, recs) = read_str(&text, &opts).map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        let ms: Vec<_> = recs.iter().filter_map(Record::motion).collect();
        let r = d / 2.0;
        let outline_dist = |q: P2| (0..n).map(|k| seg_dist(q, pts[k], pts[(k + 1) % n])).fold(f64::MAX, f64::min);
        // Lines 4 to n + 2 turn the corners of the outline; before them
        // come the rapid, the entry and the first side (which may round
        // the entry's own corner), after them the last side (whose end
        // is no corner) and the exit.
        for m in ms.iter().filter(|m| m.block.is_some_and(|b| (4..=n as u64 + 2).contains(&b))) {
            let q = Plane::Xy.project(&m.to);
            prop_assert!((outline_dist(q) - r).abs() < 1e-9, "{text}\npoint {q:?} at {} from the outline, radius {r}", outline_dist(q));
            if let MotionKind::Arc(a) = m.kind {
                let c = Plane::Xy.project(&a.center);
                prop_assert!(pts.iter().any(|p| (p - c).norm() < 1e-9), "corner arc centre {c:?} is no corner");
                prop_assert!(((q - c).norm() - r).abs() < 1e-9);
            }
        }
    }
}
