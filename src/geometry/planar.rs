//! Plane-local arc helpers shared by the G-code readers and writers.

use super::{P2, V2};
use std::f64::consts::TAU;

/// Signed sweep angle (radians) of an arc around `center` from `start` to
/// `end`, positive for counter-clockwise. A start equal to the end (within
/// `tol` of the radius) is a full turn. `extra_turns` adds whole turns
/// (RS274 `P` words: P2 is one extra turn).
///
/// ```
/// use microcam::geometry::P2;
/// use microcam::geometry::planar::sweep_angle;
/// let (c, s, e) = (P2::origin(), P2::new(1.0, 0.0), P2::new(0.0, 1.0));
/// assert!((sweep_angle(&c, &s, &e, true, 0, 1e-9) - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// assert!((sweep_angle(&c, &s, &s, false, 0, 1e-9) + std::f64::consts::TAU).abs() < 1e-15);
/// ```
pub fn sweep_angle(center: &P2, start: &P2, end: &P2, ccw: bool, extra_turns: u32, tol: f64) -> f64 {
    let a0 = (start - center).y.atan2((start - center).x);
    sweep_from_start_angle(a0, center, start, end, ccw, extra_turns, tol)
}

/// The rule of [`sweep_angle`] for a full turn: start and end of an arc of
/// radius `r` within `tol`, or within a millionth of a millionth of the
/// radius (a large circle's ends that differ by rounding only).
pub(crate) fn ends_close_full_turn(start: &P2, end: &P2, r: f64, tol: f64) -> bool {
    (end - start).norm() <= tol.max(r * 1e-12)
}

/// [`sweep_angle`] for a caller that has the start's direction `a0`
/// (`atan2` of start minus centre) already: the same arithmetic, one
/// `atan2` fewer.
pub(crate) fn sweep_from_start_angle(
    a0: f64,
    center: &P2,
    start: &P2,
    end: &P2,
    ccw: bool,
    extra_turns: u32,
    tol: f64,
) -> f64 {
    let a1 = (end - center).y.atan2((end - center).x);
    let r = (start - center).norm();
    let mut d = a1 - a0;
    if ccw {
        while d <= 0.0 {
            d += TAU;
        }
        while d > TAU {
            d -= TAU;
        }
    } else {
        while d >= 0.0 {
            d -= TAU;
        }
        while d < -TAU {
            d += TAU;
        }
    }
    // Start and end coincide: a full circle, whatever rounding says.
    if ends_close_full_turn(start, end, r, tol) {
        d = if ccw { TAU } else { -TAU };
    }
    let extra = extra_turns as f64 * TAU;
    if ccw { d + extra } else { d - extra }
}

/// Centre of the arc of radius `|r|` from `start` to `end`, turning
/// counter-clockwise when `ccw`. A negative `r` asks for the long way round
/// (more than half a turn), as in RS274 and PMAC `R` words. `None` when the
/// chord is longer than the diameter (beyond a relative slack of 1e-9 for
/// rounding, in which case the centre is the chord midpoint) or zero.
///
/// ```
/// use microcam::geometry::P2;
/// use microcam::geometry::planar::center_from_radius;
/// let (s, e) = (P2::new(1.0, 0.0), P2::new(0.0, 1.0));
/// assert!((center_from_radius(&s, &e, 1.0, true).unwrap() - P2::origin()).norm() < 1e-12);
/// assert!((center_from_radius(&s, &e, -1.0, true).unwrap() - P2::new(1.0, 1.0)).norm() < 1e-12);
/// assert!(center_from_radius(&s, &e, 0.5, true).is_none());
/// ```
pub fn center_from_radius(start: &P2, end: &P2, r: f64, ccw: bool) -> Option<P2> {
    let chord = end - start;
    let c = chord.norm();
    let rad = r.abs();
    if c == 0.0 || rad == 0.0 || !c.is_finite() || !rad.is_finite() {
        return None;
    }
    let half = c / 2.0;
    let h2 = rad * rad - half * half;
    let h = if h2 >= 0.0 {
        h2.sqrt()
    } else if half - rad <= rad * 1e-9 {
        0.0
    } else {
        return None;
    };
    let mid = start + chord / 2.0;
    // Unit normal to the chord, to the left of start->end.
    let left = V2::new(-chord.y, chord.x) / c;
    // A short counter-clockwise arc has its centre on the left of the chord.
    let short = r > 0.0;
    let on_left = ccw == short;
    Some(if on_left { mid + left * h } else { mid - left * h })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn quarter_arcs_have_the_right_sweep() {
        let c = P2::new(0.0, 0.0);
        let s = P2::new(1.0, 0.0);
        let e = P2::new(0.0, 1.0);
        assert!((sweep_angle(&c, &s, &e, true, 0, 1e-9) - PI / 2.0).abs() < 1e-12);
        assert!((sweep_angle(&c, &s, &e, false, 0, 1e-9) + 1.5 * PI).abs() < 1e-12);
        assert!((sweep_angle(&c, &s, &s, true, 1, 1e-9) - 2.0 * TAU).abs() < 1e-12);
    }

    #[test]
    fn radius_form_picks_short_and_long_arcs() {
        let s = P2::new(1.0, 0.0);
        let e = P2::new(0.0, 1.0);
        let short = center_from_radius(&s, &e, 1.0, true).unwrap();
        assert!((short - P2::new(0.0, 0.0)).norm() < 1e-12);
        let long = center_from_radius(&s, &e, -1.0, true).unwrap();
        assert!((long - P2::new(1.0, 1.0)).norm() < 1e-12);
        let cw_short = center_from_radius(&s, &e, 1.0, false).unwrap();
        assert!((cw_short - P2::new(1.0, 1.0)).norm() < 1e-12);
        assert!(center_from_radius(&s, &e, 0.5, true).is_none());
    }
}
