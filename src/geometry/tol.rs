//! Tolerance-aware comparisons and angle normalisation.
//!
//! Exact equality is meaningless for coordinates that went through DXF text,
//! unit conversion and trigonometry, so every "is this the same?" question in
//! the kernel goes through these helpers with an explicit tolerance. They are
//! written so that a NaN anywhere answers `false` (never "equal by accident")
//! and never panic.

use super::{P2, P3};
use std::f64::consts::{PI, TAU};

/// True when `|a - b| <= tol`. NaN in any argument gives `false`.
///
/// ```
/// use microcam::geometry::tol::approx_eq;
/// assert!(approx_eq(1.0, 1.0 + 1e-10, 1e-9));
/// assert!(!approx_eq(f64::NAN, f64::NAN, 1.0));
/// ```
pub fn approx_eq(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// True when two plane points are within `tol` (Euclidean distance).
pub fn approx_eq_p2(a: &P2, b: &P2, tol: f64) -> bool {
    (a - b).norm() <= tol
}

/// True when two space points are within `tol` (Euclidean distance).
pub fn approx_eq_p3(a: &P3, b: &P3, tol: f64) -> bool {
    (a - b).norm() <= tol
}

/// An angle brought into `[0, 2π)`. Needed because `atan2` answers in
/// `(-π, π]` while sweeps are measured from a start angle. Non-finite input
/// comes back as NaN.
///
/// ```
/// use microcam::geometry::tol::{angles_approx_eq, normalize_angle};
/// use std::f64::consts::PI;
/// assert!((normalize_angle(-PI / 2.0) - 1.5 * PI).abs() < 1e-15);
/// assert_eq!(normalize_angle(-1e-300), 0.0);
/// assert!(angles_approx_eq(-PI, PI, 1e-12));
/// ```
pub fn normalize_angle(a: f64) -> f64 {
    if !a.is_finite() {
        return f64::NAN;
    }
    let r = a.rem_euclid(TAU);
    // rem_euclid of a tiny negative number rounds up to exactly TAU.
    if r >= TAU { 0.0 } else { r }
}

/// `x.rem_euclid(2π)`, bit for bit, without the `fmod` call when `x` lies
/// within `(-2π, 4π)` (every difference of two `atan2` results and the
/// quarter directions): there the remainder is `x`, `x + 2π` or `x - 2π`,
/// and the last is exact (Sterbenz). `fmod` was most of the cost of an
/// arc's box in the DXF import's orientation step (four tests per arc).
///
/// ```
/// use microcam::geometry::tol::rem_tau;
/// use std::f64::consts::TAU;
/// for x in [-1.0, 0.5, 7.0, -1e-300, 3.0 * TAU + 0.1, f64::NAN] {
///     assert_eq!(rem_tau(x).to_bits(), x.rem_euclid(TAU).to_bits());
/// }
/// ```
#[inline]
pub fn rem_tau(x: f64) -> f64 {
    if (0.0..TAU).contains(&x) {
        x
    } else if x < 0.0 && x > -TAU {
        x + TAU
    } else if (TAU..2.0 * TAU).contains(&x) {
        x - TAU
    } else {
        x.rem_euclid(TAU)
    }
}

/// An angle brought into `(-π, π]`, the range of `atan2`: the signed
/// difference between two directions. Non-finite input comes back as NaN.
pub fn normalize_angle_signed(a: f64) -> f64 {
    let r = normalize_angle(a);
    if r > PI { r - TAU } else { r }
}

/// True when two angles name the same direction within `tol` radians,
/// whatever whole turns separate them (so `-π` equals `π`).
pub fn angles_approx_eq(a: f64, b: f64, tol: f64) -> bool {
    normalize_angle_signed(a - b).abs() <= tol
}

/// True when every coordinate of the point is finite (no NaN, no infinity).
pub fn finite_p3(p: &P3) -> bool {
    p.iter().all(|c| c.is_finite())
}

/// True when every coordinate of the point is finite (no NaN, no infinity).
pub fn finite_p2(p: &P2) -> bool {
    p.iter().all(|c| c.is_finite())
}

/// True when `x` is a finite number above zero: the test every length or
/// sweep must pass before it is divided by. NaN answers `false`.
pub fn positive_finite(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

/// True when `tol` is usable as a tolerance: finite and not negative.
pub fn valid_tol(tol: f64) -> bool {
    tol.is_finite() && tol >= 0.0
}

#[cfg(test)]
mod tests {
    #[test]
    fn rem_tau_is_rem_euclid_bit_for_bit() {
        let mut rnd = crate::geometry::test_rng::unit_rng(0x9e37_79b9_7f4a_7c15);
        let mut v: Vec<f64> = vec![
            0.0,
            -0.0,
            TAU,
            -TAU,
            2.0 * TAU,
            -1e-300,
            1e-300,
            4.0 * TAU,
            f64::INFINITY,
            f64::NAN,
        ];
        for k in -3..=5 {
            let e = k as f64 * TAU;
            v.extend([
                e,
                f64::from_bits(e.to_bits() + 1),
                f64::from_bits(e.to_bits().wrapping_sub(1)),
            ]);
        }
        for _ in 0..100_000 {
            v.push((rnd() - 0.4) * 10.0 * TAU);
            v.push((rnd() - 0.5) * 1e-12);
        }
        for x in v {
            assert_eq!(rem_tau(x).to_bits(), x.rem_euclid(TAU).to_bits(), "{x:e}");
        }
    }

    use super::*;

    #[test]
    fn approx_eq_respects_tolerance_and_nan() {
        assert!(approx_eq(1.0, 1.0 + 1e-10, 1e-9));
        assert!(!approx_eq(1.0, 1.0 + 1e-8, 1e-9));
        assert!(!approx_eq(f64::NAN, f64::NAN, 1.0));
        assert!(!approx_eq(1.0, 1.0, f64::NAN));
        assert!(approx_eq_p3(
            &P3::new(1.0, 2.0, 3.0),
            &P3::new(1.0, 2.0, 3.0 + 5e-10),
            1e-9
        ));
        assert!(!approx_eq_p2(&P2::new(0.0, 0.0), &P2::new(3.0, 4.0), 4.9));
        assert!(approx_eq_p2(&P2::new(0.0, 0.0), &P2::new(3.0, 4.0), 5.0));
    }

    #[test]
    fn angles_normalise_into_their_ranges() {
        assert_eq!(normalize_angle(-1e-300), 0.0);
        assert!((normalize_angle(-PI / 2.0) - 1.5 * PI).abs() < 1e-15);
        assert!((normalize_angle(5.0 * TAU + 1.0) - 1.0).abs() < 1e-12);
        assert!((normalize_angle_signed(1.5 * PI) + PI / 2.0).abs() < 1e-15);
        assert!((normalize_angle_signed(-PI) - PI).abs() < 1e-15);
        assert!(normalize_angle(f64::INFINITY).is_nan());
        assert!(angles_approx_eq(-PI, PI, 1e-12));
        assert!(angles_approx_eq(0.0, TAU - 1e-13, 1e-12));
        assert!(!angles_approx_eq(0.0, 0.1, 0.05));
    }

    #[test]
    fn finiteness_checks() {
        assert!(finite_p3(&P3::new(1.0, 2.0, 3.0)));
        assert!(!finite_p3(&P3::new(1.0, f64::NAN, 3.0)));
        assert!(!finite_p2(&P2::new(f64::INFINITY, 0.0)));
        assert!(positive_finite(1e-300));
        assert!(!positive_finite(0.0));
        assert!(!positive_finite(f64::NAN));
        assert!(!positive_finite(f64::INFINITY));
        assert!(valid_tol(0.0));
        assert!(!valid_tol(-1e-9));
        assert!(!valid_tol(f64::NAN));
    }
}
