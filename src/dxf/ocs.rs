//! Affine transforms and the DXF Object Coordinate System.
//!
//! Planar entities (ARC, CIRCLE, LWPOLYLINE, 2-D POLYLINE, INSERT) store
//! their coordinates in an OCS derived from the extrusion direction by the
//! "arbitrary axis algorithm". Extrusion (0,0,-1) gives an OCS whose X axis
//! is the world's -X: a counter-clockwise arc in the OCS is a clockwise,
//! mirrored arc in the world. Everything here is one 3-D affine map so the
//! OCS, block insertion, the unit scale and the user's transforms compose.

use crate::geometry::{P3, V3};
use nalgebra::Matrix3;

/// `p -> m * p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// The linear part (rotation, scale, mirror, shear).
    pub m: Matrix3<f64>,
    /// The translation, added after `m`.
    pub t: V3,
}

impl Affine {
    /// The map that leaves every point where it is.
    pub fn identity() -> Affine {
        Affine {
            m: Matrix3::identity(),
            t: V3::zeros(),
        }
    }

    /// A shift by `t`.
    pub fn translate(t: V3) -> Affine {
        Affine {
            m: Matrix3::identity(),
            t,
        }
    }

    /// A scale about the origin by `sx`, `sy`, `sz` along the axes (a
    /// negative factor mirrors).
    pub fn scale(sx: f64, sy: f64, sz: f64) -> Affine {
        Affine {
            m: Matrix3::from_diagonal(&V3::new(sx, sy, sz)),
            t: V3::zeros(),
        }
    }

    /// Rotation about +Z by `a` radians (counter-clockwise seen from +Z).
    pub fn rotate_z(a: f64) -> Affine {
        let (s, c) = a.sin_cos();
        Affine {
            m: Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
            t: V3::zeros(),
        }
    }

    /// The OCS-to-world map for an extrusion direction.
    pub fn ocs(extrusion: V3) -> Affine {
        let (ax, ay, az) = ocs_axes(extrusion);
        Affine {
            m: Matrix3::from_columns(&[ax, ay, az]),
            t: V3::zeros(),
        }
    }

    /// `self ∘ other`: apply `other` first.
    pub fn then_after(&self, other: &Affine) -> Affine {
        Affine {
            m: self.m * other.m,
            t: self.m * other.t + self.t,
        }
    }

    /// `self ∘ ocs(extrusion)`: an entity's own coordinates to the world.
    /// Nearly every entity has the default extrusion (0, 0, 1), whose OCS
    /// is the identity: then `self` as it is, without building the axes
    /// and multiplying by them (a tenth of the placer's time on the mix
    /// benchmark). The product with the identity differs from `self` at
    /// most in the sign of a zero entry.
    pub fn with_ocs(&self, extrusion: &V3) -> Affine {
        if *extrusion == V3::z() {
            *self
        } else {
            self.then_after(&Affine::ocs(*extrusion))
        }
    }

    /// The image of point `p`.
    pub fn apply(&self, p: &P3) -> P3 {
        P3::from(self.m * p.coords + self.t)
    }

    /// The image of direction or offset `v` (no translation).
    pub fn apply_vec(&self, v: &V3) -> V3 {
        self.m * v
    }

    /// True when no entry is NaN or infinite (a scale of 1e300 times 1e300
    /// in nested inserts is not).
    pub fn is_finite(&self) -> bool {
        self.m.iter().all(|x| x.is_finite()) && self.t.iter().all(|x| x.is_finite())
    }
}

/// The arbitrary axis algorithm (DXF reference, "Arbitrary Axis
/// Algorithm"): OCS X, Y and Z axes in world coordinates.
pub fn ocs_axes(extrusion: V3) -> (V3, V3, V3) {
    let n = extrusion.try_normalize(1e-12).unwrap_or(V3::z());
    // Exactly the common cases, so that (0,0,1) is the identity with no
    // round-off and (0,0,-1) is an exact mirror.
    if n == V3::z() {
        return (V3::x(), V3::y(), V3::z());
    }
    let limit = 1.0 / 64.0;
    let ax = if n.x.abs() < limit && n.y.abs() < limit {
        V3::y().cross(&n)
    } else {
        V3::z().cross(&n)
    }
    .normalize();
    let ay = n.cross(&ax).normalize();
    (ax, ay, n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn negative_z_extrusion_mirrors_x() {
        let a = Affine::ocs(V3::new(0.0, 0.0, -1.0));
        let p = a.apply(&P3::new(2.0, 3.0, 4.0));
        assert_eq!(p, P3::new(-2.0, 3.0, -4.0));
        assert!(a.m.determinant() > 0.0, "a proper rotation in 3-D");
    }

    #[test]
    fn compose_applies_right_first() {
        let a = Affine::translate(V3::new(1.0, 0.0, 0.0)).then_after(&Affine::scale(2.0, 2.0, 1.0));
        assert_eq!(a.apply(&P3::new(1.0, 1.0, 0.0)), P3::new(3.0, 2.0, 0.0));
    }

    #[test]
    fn ocs_axes_are_orthonormal_right_handed() {
        for n in [
            V3::new(1.0, 2.0, 3.0),
            V3::new(0.001, 0.0, -1.0),
            V3::new(1.0, 0.0, 0.0),
        ] {
            let (x, y, z) = ocs_axes(n);
            assert!((x.cross(&y) - z).norm() < 1e-12);
            assert!(x.dot(&y).abs() < 1e-12);
        }
    }
}
