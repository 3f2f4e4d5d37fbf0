//! Geometry kernel: points, planes, tolerances and the exact primitives
//! (lines, circular and helical arcs) every tool works with.
//!
//! Everything is in millimetres and radians. Points are `nalgebra` points so
//! the usual vector algebra is available; the plane-local helpers here keep
//! the arc maths in one place so the G-code readers, the writers and the
//! toolpath generators all agree on what an arc is.
//!
//! - [`line`](mod@line): [`Line3`], straight segments.
//! - [`arc`]: [`Arc3`], circular and helical arcs in a principal [`Plane`].
//! - [`bulge`]: DXF polyline bulges to and from arcs.
//! - [`bbox`]: [`BBox3`], axis-aligned boxes.
//! - [`intersect`]: where lines and arcs meet in XY, at a tolerance.
//! - [`tol`]: tolerant comparisons and angle normalisation.
//! - [`planar`]: sweep and radius-form centre helpers for the G-code readers.
//! - [`segment`]: [`Segment`], a line or an arc: the one type chains,
//!   planned paths and toolpath moves carry.

#![warn(missing_docs)]

pub mod arc;
pub mod bbox;
pub mod bulge;
pub mod intersect;
pub mod line;
pub mod planar;
#[cfg(test)]
mod proptests;
pub mod segment;
#[cfg(test)]
pub(crate) mod test_rng;
pub mod tol;

pub use arc::Arc3;
pub use bbox::BBox3;
pub use line::Line3;
pub use segment::Segment;

use serde::{Deserialize, Serialize};

/// A point in machine space (mm).
pub type P3 = nalgebra::Point3<f64>;
/// A vector in machine space (mm).
pub type V3 = nalgebra::Vector3<f64>;
/// A point in a plane (mm): the plane's first and second axis.
pub type P2 = nalgebra::Point2<f64>;
/// A vector in a plane (mm).
pub type V2 = nalgebra::Vector2<f64>;

/// Default length tolerance (mm) for "these two points are the same".
pub const EPS_LEN: f64 = 1e-9;

/// The plane an arc lies in. The arc's sense (`ccw`) is counter-clockwise
/// seen from the positive end of the plane normal, i.e. a positive rotation
/// about the normal by the right-hand rule. This is the RS274 convention:
/// G17 = XY (normal +Z), G18 = ZX (normal +Y), G19 = YZ (normal +X).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Plane {
    /// G17: the XY plane, normal +Z.
    #[default]
    Xy,
    /// G18: the ZX plane, normal +Y (first axis Z, second X).
    Xz,
    /// G19: the YZ plane, normal +X.
    Yz,
}

impl Plane {
    /// Indices (into x, y, z) of the plane's first axis, second axis and normal,
    /// ordered so that first × second = +normal.
    pub fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::Xy => (0, 1, 2),
            Plane::Xz => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        }
    }

    /// Project a 3-D point onto the plane's (first, second) coordinates.
    pub fn project(self, p: &P3) -> P2 {
        let (a, b, _) = self.axes();
        P2::new(p[a], p[b])
    }

    /// The coordinate along the plane normal.
    pub fn normal_coord(self, p: &P3) -> f64 {
        p[self.axes().2]
    }

    /// Build a 3-D point from in-plane coordinates and a normal coordinate.
    pub fn lift(self, q: &P2, normal: f64) -> P3 {
        let (a, b, n) = self.axes();
        let mut p = P3::origin();
        p[a] = q.x;
        p[b] = q.y;
        p[n] = normal;
        p
    }

    /// The name used in the pipe formats ("xy", "xz", "yz").
    pub fn name(self) -> &'static str {
        match self {
            Plane::Xy => "xy",
            Plane::Xz => "xz",
            Plane::Yz => "yz",
        }
    }
}

/// True when two points are within `tol` of each other.
pub fn same_point(a: &P3, b: &P3, tol: f64) -> bool {
    (a - b).norm() <= tol
}

/// `v.floor() as i64` (saturating, NaN to 0) without the libm call that
/// `floor` is on x86_64's baseline instruction set (no SSE4.1 `roundsd`):
/// the spatial hashes of the chaining take a floor per point, and the call
/// was a tenth of the node clustering's time.
#[inline]
pub fn floor_i64(v: f64) -> i64 {
    // The cast truncates towards zero and saturates; below zero a value
    // with a fraction is one more than its floor. Saturated values are
    // whole numbers as doubles, so they never take the step (except below
    // i64::MIN, where the floor saturates too).
    let t = v as i64;
    if (t as f64) > v { t.saturating_sub(1) } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn floor_i64_is_floor_then_cast(bits in any::<u64>(), small in -1e6f64..1e6) {
            for v in [f64::from_bits(bits), small, small.trunc(), -small.trunc(), small * 1e-300] {
                prop_assert_eq!(floor_i64(v), v.floor() as i64, "{:e}", v);
            }
        }
    }

    #[test]
    fn floor_i64_edges() {
        for v in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            1.0,
            -1.0 - f64::EPSILON,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            i64::MAX as f64,
            i64::MIN as f64,
            -9.223372036854778e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            4503599627370495.5,
            -4503599627370495.5,
        ] {
            assert_eq!(floor_i64(v), v.floor() as i64, "{v:e}");
        }
    }

    #[test]
    fn plane_axes_are_right_handed_and_lift_inverts_project() {
        for plane in [Plane::Xy, Plane::Xz, Plane::Yz] {
            let (a, b, n) = plane.axes();
            let (mut ea, mut eb, mut en) = (V3::zeros(), V3::zeros(), V3::zeros());
            ea[a] = 1.0;
            eb[b] = 1.0;
            en[n] = 1.0;
            assert_eq!(ea.cross(&eb), en, "{plane:?}");
            let p = P3::new(1.0, 2.0, 3.0);
            assert_eq!(plane.lift(&plane.project(&p), plane.normal_coord(&p)), p);
        }
        assert_eq!(Plane::Xz.project(&P3::new(1.0, 2.0, 3.0)), P2::new(3.0, 1.0));
        assert_eq!(Plane::Yz.normal_coord(&P3::new(1.0, 2.0, 3.0)), 1.0);
        assert!(same_point(&P3::origin(), &P3::new(0.0, 0.0, 1e-10), EPS_LEN));
    }
}
