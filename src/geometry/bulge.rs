//! DXF bulges: the arc form of LWPOLYLINE and POLYLINE vertices.
//!
//! A vertex's bulge describes the segment to the next vertex: zero is a
//! straight line, otherwise the segment is an arc in the XY plane (of the
//! entity's coordinate system) with `bulge = tan(sweep / 4)`, positive for
//! counter-clockwise. So 1 is a ccw half circle, -1 a cw half circle, and
//! |bulge| > 1 is more than half a turn. A full circle cannot be a bulge.

use super::arc::Arc3;
use super::tol::finite_p3;
use super::{EPS_LEN, P2, P3, Plane, V2};

/// The XY arc from `start` to `end` with the given bulge; `None` for a zero
/// bulge (the segment is a line), a non-finite bulge or point, or a chord
/// shorter than `EPS_LEN` (no arc fits). The centre is at the start's Z; an
/// end at another Z makes the arc a helix, as a sloped polyline would be.
///
/// ```
/// use microcam::geometry::P3;
/// use microcam::geometry::bulge::{arc_from_bulge, bulge_of};
/// // Bulge 1 is a half circle, counter-clockwise.
/// let a = arc_from_bulge(&P3::origin(), &P3::new(2.0, 0.0, 0.0), 1.0).unwrap();
/// assert!(a.ccw && (a.center - P3::new(1.0, 0.0, 0.0)).norm() < 1e-15);
/// assert!((bulge_of(&a).unwrap() - 1.0).abs() < 1e-15);
/// assert!(arc_from_bulge(&P3::origin(), &P3::new(2.0, 0.0, 0.0), 0.0).is_none());
/// ```
pub fn arc_from_bulge(start: &P3, end: &P3, bulge: f64) -> Option<Arc3> {
    if bulge == 0.0 || !bulge.is_finite() || !finite_p3(start) || !finite_p3(end) {
        return None;
    }
    let s = P2::new(start.x, start.y);
    let e = P2::new(end.x, end.y);
    let chord = e - s;
    let c = chord.norm();
    if c.is_nan() || c <= EPS_LEN {
        return None;
    }
    // Distance from the chord midpoint to the centre, positive to the left of
    // start -> end: (c/2)·cot(sweep/2) = c·(1 - b²) / (4b).
    let offset = c * (1.0 - bulge * bulge) / (4.0 * bulge);
    let left = V2::new(-chord.y, chord.x) / c;
    let center = s + chord / 2.0 + left * offset;
    Arc3::new(
        P3::new(center.x, center.y, start.z),
        *start,
        *end,
        bulge > 0.0,
        Plane::Xy,
        0,
    )
}

/// The bulge of an XY arc, `tan(sweep / 4)`: the inverse of
/// [`arc_from_bulge`]. `None` when the arc is not in the XY plane or sweeps a
/// full turn or more (no bulge can say that), or is not finite. A helical
/// rise is ignored: the bulge describes the XY projection.
pub fn bulge_of(arc: &Arc3) -> Option<f64> {
    if arc.plane != Plane::Xy {
        return None;
    }
    let sweep = arc.sweep();
    if sweep.is_nan() || sweep.abs() >= std::f64::consts::TAU {
        return None;
    }
    Some((sweep / 4.0).tan())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn p(x: f64, y: f64) -> P3 {
        P3::new(x, y, 0.0)
    }

    #[test]
    fn bulge_one_is_a_ccw_half_circle() {
        let a = arc_from_bulge(&p(0.0, 0.0), &p(2.0, 0.0), 1.0).unwrap();
        assert!((a.center - p(1.0, 0.0)).norm() < 1e-15);
        assert!(a.ccw);
        assert!((a.sweep() - PI).abs() < 1e-14);
        assert!((a.length() - PI).abs() < 1e-14);
        // ccw from (0,0) to (2,0) around (1,0) passes below: through (1,-1).
        assert!((a.point_at(0.5) - p(1.0, -1.0)).norm() < 1e-12);
        assert!((bulge_of(&a).unwrap() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn negative_and_large_bulges() {
        let a = arc_from_bulge(&p(0.0, 0.0), &p(2.0, 0.0), -1.0).unwrap();
        assert!(!a.ccw);
        assert!((a.point_at(0.5) - p(1.0, 1.0)).norm() < 1e-12);
        // tan(pi/8): a quarter circle, centre to the left of the chord.
        let q = arc_from_bulge(&p(1.0, 0.0), &p(0.0, 1.0), (PI / 8.0).tan()).unwrap();
        assert!((q.center - p(0.0, 0.0)).norm() < 1e-14);
        assert!((q.sweep() - PI / 2.0).abs() < 1e-14);
        // tan(3pi/8): three quarters of a turn, centre to the right.
        let t = arc_from_bulge(&p(1.0, 0.0), &p(0.0, -1.0), (3.0 * PI / 8.0).tan()).unwrap();
        assert!((t.center - p(0.0, 0.0)).norm() < 1e-14);
        assert!((t.sweep() - 1.5 * PI).abs() < 1e-14);
        assert!((bulge_of(&t).unwrap() - (3.0 * PI / 8.0).tan()).abs() < 1e-12);
    }

    #[test]
    fn what_has_no_bulge() {
        assert!(arc_from_bulge(&p(0.0, 0.0), &p(1.0, 0.0), 0.0).is_none());
        assert!(arc_from_bulge(&p(0.0, 0.0), &p(0.0, 0.0), 1.0).is_none());
        assert!(arc_from_bulge(&p(0.0, 0.0), &p(1.0, 0.0), f64::NAN).is_none());
        assert!(arc_from_bulge(&p(0.0, 0.0), &p(1.0, 0.0), f64::INFINITY).is_none());
        assert!(arc_from_bulge(&p(f64::NAN, 0.0), &p(1.0, 0.0), 0.5).is_none());
        let circle = Arc3::full_circle(p(0.0, 0.0), p(1.0, 0.0), true, Plane::Xy).unwrap();
        assert!(bulge_of(&circle).is_none());
        let xz = Arc3::new(
            P3::origin(),
            P3::new(1.0, 0.0, 0.0),
            P3::new(0.0, 0.0, 1.0),
            true,
            Plane::Xz,
            0,
        )
        .unwrap();
        assert!(bulge_of(&xz).is_none());
    }

    #[test]
    fn sloped_polyline_segment_is_a_helix() {
        let a = arc_from_bulge(&P3::new(0.0, 0.0, 1.0), &P3::new(2.0, 0.0, 3.0), 1.0).unwrap();
        assert_eq!(a.center.z, 1.0);
        assert!((a.rise() - 2.0).abs() < 1e-15);
        assert!((a.point_at(0.5) - P3::new(1.0, -1.0, 2.0)).norm() < 1e-12);
    }
}
