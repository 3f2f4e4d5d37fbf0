//! Tests of G5.2/G5.3 (nurbs.rs): the curve evaluation against hand
//! computation and a circle, and the reader's rules and errors.

use super::*;
use crate::gcode::{Dialect, ReadOptions, read_str};

fn read(text: &str) -> Result<Vec<Motion>, GcodeError> {
    let opts = ReadOptions {
        dialect: Some(Dialect::Iso),
        ..Default::default()
    };
    read_str(text, &opts).map(|(_, r)| r.into_iter().filter_map(|r| r.motion().cloned()).collect())
}

fn cp(x: f64, y: f64, w: f64) -> ControlPoint {
    ControlPoint { p: P2::new(x, y), w }
}

#[test]
fn knot_vector_is_linuxcncs() {
    // knot_vector_creator(n = 3, k = 3) and (n = 5, k = 4).
    assert_eq!(knot_vector(3, 3), [0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 2.0]);
    assert_eq!(knot_vector(5, 4), [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 3.0, 3.0, 3.0]);
}

#[test]
fn curve_points_match_a_hand_computed_b_spline() {
    // Order 3 on knots 0 0 0 1 2 2 2: on [0, 1) the basis is (1-u)²,
    // u(1-u) + u(2-u)/2 and u²/2, so at u = 0.5: 0.25, 0.625, 0.125.
    let mut pts = [
        cp(0.0, 0.0, 1.0),
        cp(1.0, 2.0, 1.0),
        cp(3.0, 2.0, 1.0),
        cp(4.0, 0.0, 1.0),
    ];
    let knots = knot_vector(3, 3);
    let at = |pts: &[ControlPoint], u: f64| curve_point(u, 3, pts, &knots);
    assert!((at(&pts, 0.5) - P2::new(1.0, 1.5)).norm() < 1e-12);
    // On the interior knot: the midpoint of P1 P2; the ends: P0 and P3.
    assert!((at(&pts, 1.0) - P2::new(2.0, 2.0)).norm() < 1e-12);
    assert!((at(&pts, 0.0) - P2::new(0.0, 0.0)).norm() < 1e-12);
    assert!((at(&pts, 2.0) - P2::new(4.0, 0.0)).norm() < 1e-12);
    // Weight 2 on P1: (0.625·2·P1 + 0.125·P2) / (0.25 + 1.25 + 0.125).
    pts[1].w = 2.0;
    assert!((at(&pts, 0.5) - P2::new(1.0, 2.75 / 1.625)).norm() < 1e-12);
}

/// LinuxCNC's basis recursion (`Nmix`), closed intervals and all, as the
/// reference the span algorithm must reproduce.
fn nmix(i: usize, k: usize, u: f64, kv: &[f64]) -> f64 {
    if k == 1 {
        return if (kv[i]..=kv[i + 1]).contains(&u) { 1.0 } else { 0.0 };
    }
    let (a, b) = (kv[i + k - 1] - kv[i], kv[i + k] - kv[i + 1]);
    let left = if a == 0.0 {
        0.0
    } else {
        (u - kv[i]) * nmix(i, k - 1, u, kv) / a
    };
    let right = if b == 0.0 {
        0.0
    } else {
        (kv[i + k] - u) * nmix(i + 1, k - 1, u, kv) / b
    };
    left + right
}

#[test]
fn curve_points_match_linuxcncs_recursion_on_and_between_knots() {
    // A fixed pseudo-random sequence: orders 3..=6, up to 5 spare points,
    // weights 0.2..3, every step of NURBS_FEED's parameter grid.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let k = 3 + (rnd() * 4.0) as usize;
        let count = k + (rnd() * 6.0) as usize;
        let pts: Vec<ControlPoint> = (0..count)
            .map(|_| cp(rnd() * 20.0 - 10.0, rnd() * 20.0 - 10.0, 0.2 + rnd() * 2.8))
            .collect();
        let n = count - 1;
        let knots = knot_vector(n, k);
        let umax = (n + 2 - k) as f64;
        for step in 0..=4 * count {
            let u = umax * step as f64 / (4 * count) as f64;
            let basis: Vec<f64> = (0..count).map(|i| nmix(i, k, u, &knots)).collect();
            let den: f64 = basis.iter().zip(&pts).map(|(b, p)| b * p.w).sum();
            let want = pts
                .iter()
                .zip(&basis)
                .fold(V2::zeros(), |acc, (p, b)| acc + p.p.coords * (b * p.w / den));
            worst = worst.max((curve_point(u, k, &pts, &knots).coords - want).norm());
        }
    }
    assert!(worst < 1e-12, "largest difference {worst}");
}

/// Points along every move of `m`, from `start` (mm, XY).
fn samples(start: P3, m: &[Motion]) -> Vec<P2> {
    let mut out = Vec::new();
    let mut from = start;
    for mv in m {
        for k in 0..=20 {
            let t = f64::from(k) / 20.0;
            let p = match mv.kind {
                MotionKind::Arc(a) => a.arc(from, mv.to).expect("an arc").point_at(t),
                _ => from + (mv.to - from) * t,
            };
            out.push(P2::new(p.x, p.y));
        }
        from = mv.to;
    }
    out
}

#[test]
fn a_rational_quadratic_with_weight_half_root_two_cuts_a_quarter_circle() {
    let r = 10.0;
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let text = format!("G0 X{r} Y0 Z-1\nG1 F100\nG5.2 X{r} Y{r} P{w:.17} L3\nX0 Y{r} P1\nG5.3\nG1 X-1\n");
    let m = read(&text).unwrap();
    let curve: Vec<&Motion> = m.iter().filter(|m| m.block == Some(5)).collect();
    // 4 (n + 1) = 12 parameter steps, each a biarc of two moves.
    assert_eq!(curve.len(), 24);
    assert!(curve.iter().all(|m| m.feed == Some(100.0) && m.to.z == -1.0));
    assert!(curve.iter().any(|m| matches!(m.kind, MotionKind::Arc(_))));
    // Every step ends on the curve: exactly on the circle.
    for m in curve.iter().skip(1).step_by(2) {
        let d = (m.to.x.hypot(m.to.y) - r).abs();
        assert!(d < 1e-9, "{:?} is {d} mm off the circle", m.to);
    }
    assert!((curve[23].to - P3::new(0.0, r, -1.0)).norm() < 1e-12);
    // Between them the biarcs follow the circle to within what the
    // finite-difference tangents allow: 1.4e-7 of the radius with
    // LinuxCNC's own evaluation (a Python transcription of it).
    let owned: Vec<Motion> = curve.iter().map(|m| (*m).clone()).collect();
    let worst = samples(P3::new(r, 0.0, -1.0), &owned)
        .iter()
        .map(|p| (p.coords.norm() - r).abs())
        .fold(0.0, f64::max);
    assert!(worst < 5e-7 * r, "worst deviation {worst} mm");
    // The next move starts from the last control point.
    assert!((m.last().unwrap().to - P3::new(-1.0, r, -1.0)).norm() < 1e-12);
}

#[test]
fn a_straight_curve_is_cut_in_lines() {
    // Parallel tangents: LinuxCNC's biarc has no finite root (NaN there);
    // each step is one line along the curve.
    let m = read("F10\nG5.2 X1 Y0 P1\nX2 Y0 P1\nG5.3\n").unwrap();
    assert_eq!(m.len(), 12);
    assert!(m.iter().all(|m| m.kind == MotionKind::Line && m.to.y.abs() < 1e-12));
    assert!((m[11].to.x - 2.0).abs() < 1e-12 && m.windows(2).all(|w| w[1].to.x > w[0].to.x));
}

#[test]
fn the_block_reads_as_linuxcnc_reads_it() {
    // The example of LinuxCNC's manual, in G91 after an offset: control
    // points count from the block's start, the curve ends on the last one.
    let text = "G10 L2 P1 X5 Y5\nG0 X0 Y0\nF10\nG91 G5.2 X0 Y1 P1 L3\nX2 Y2 P1\nX2 Y0 P1\nX0 Y0 P2\nG5.3\nG90 G1 X0\n";
    let m = read(text).unwrap();
    let curve: Vec<&Motion> = m.iter().filter(|m| m.block == Some(8)).collect();
    assert_eq!(curve.len(), 8 * 5, "4 (n + 1) steps of two moves, n + 1 = 5");
    assert!((curve.last().unwrap().to - P3::new(5.0, 5.0, 0.0)).norm() < 1e-12);
    // The fourth step ends at u = 4/20 · 3, on the hand-computed curve.
    let pts = [
        cp(0.0, 0.0, 1.0),
        cp(0.0, 1.0, 1.0),
        cp(2.0, 2.0, 1.0),
        cp(2.0, 0.0, 1.0),
        cp(0.0, 0.0, 2.0),
    ];
    let want = curve_point(0.6, 3, &pts, &knot_vector(4, 3));
    assert!((curve[7].to - P3::new(want.x + 5.0, want.y + 5.0, 0.0)).norm() < 1e-12);
    // P without X and Y on the first line weighs the start point; L above
    // 3 sets the order (then 4 points are needed, 5 given).
    let m = read("F10\nG5.2 P3 L4\nX1 Y1 P1\nX2 Y0 P1\nX3 Y1 P1\nX4 Y0 P1\nG5.3\n").unwrap();
    assert_eq!(m.len(), 8 * 5);
    // G5.3 and a new G5.2 on one line: LinuxCNC closes first.
    let m = read("F10\nG5.2 X1 Y1 P1\nX2 Y0 P1\nG5.3 G5.2 P1\nX3 Y1 P1\nX4 Y0 P1\nG5.3\n").unwrap();
    assert_eq!(m.len(), 8 * 3 * 2);
}

#[test]
fn nurbs_errors_name_the_line() {
    let cases: [(&str, u64, &str); 12] = [
        ("F10\nG5.3\n", 2, "G5.3 without G5.2"),
        ("F10\nG5.2 X1 Y1 L3\n", 2, "positive weight"),
        ("F10\nG5.2 X1 Y1 P1\nX2 Y2\nG5.3\n", 3, "positive weight"),
        ("F10\nG5.2 X1 Y1 P1\nX2 Y2 P0\nG5.3\n", 3, "positive weight"),
        ("F10\nG5.2 X1 P1\n", 2, "both X and Y"),
        ("F10\nG5.2 X1 Y1 P1\nG5.2 P2\n", 3, "first line"),
        ("F10\nG18 G5.2 X1 Y1 P1\n", 2, "XY plane"),
        ("F10\nG5.2 X1 Y1 P1 L4\nX2 Y0 P1\nG5.3\n", 4, "order L = 4"),
        ("F10\nG5.2 X1 Y1 P1\nG1 X2 Y0\n", 3, "opened on line 2"),
        ("F10\nG5.2 X1 Y1 P1\nX2 Y0 P1\nM2\n", 4, "program end"),
        ("F10\nG5.2 X1 Y1 P1\nX2 Y0 P1\n", 3, "no G5.3"),
        ("G5.2 X1 Y1 P1\n", 1, "no feed rate"),
    ];
    for (text, line, needle) in cases {
        let e = read(text).unwrap_err();
        assert_eq!(e.line(), line, "{text}: {e}");
        assert!(e.to_string().contains(needle), "{text}: {e}");
    }
    // Z, A and polar words on a control point, an order beyond the cap.
    for text in [
        "F10\nG5.2 X1 Y1 Z1 P1\n",
        "F10\nG5.2 @1 ^2 P1\n",
        "F10\nG5.2 X1 Y1 P1 L21\n",
    ] {
        assert_eq!(read(text).unwrap_err().line(), 2, "{text}");
    }
}
