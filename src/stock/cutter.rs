//! Cutters as height profiles: how far above its tip the cutter's surface
//! is at a radial distance from its axis.

use thiserror::Error;

/// A rotating end mill, dimensions in mm. Constructed through
/// [`Cutter::flat`], [`Cutter::ball`] or [`Cutter::torus`], which check
/// the dimensions, so a cutter in hand is always a real one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cutter {
    /// Flat end mill of radius `radius`.
    Flat { radius: f64 },
    /// Ball end mill of radius `radius`.
    Ball { radius: f64 },
    /// Bull-nose (torus) end mill: `radius` overall, `corner` the corner
    /// radius (0 < corner < radius).
    Torus { radius: f64, corner: f64 },
}

#[derive(Debug, Error, PartialEq)]
pub enum CutterError {
    #[error("cutter radius must be positive and finite, got {0} mm")]
    Radius(f64),
    #[error("torus corner radius must be between 0 and the cutter radius {radius} mm, got {corner} mm")]
    Corner { radius: f64, corner: f64 },
}

impl Cutter {
    pub fn flat(radius: f64) -> Result<Cutter, CutterError> {
        check_radius(radius)?;
        Ok(Cutter::Flat { radius })
    }

    pub fn ball(radius: f64) -> Result<Cutter, CutterError> {
        check_radius(radius)?;
        Ok(Cutter::Ball { radius })
    }

    pub fn torus(radius: f64, corner: f64) -> Result<Cutter, CutterError> {
        check_radius(radius)?;
        if !(corner > 0.0 && corner < radius) {
            return Err(CutterError::Corner { radius, corner });
        }
        Ok(Cutter::Torus { radius, corner })
    }

    /// The cutter's radius (mm).
    pub fn radius(&self) -> f64 {
        match *self {
            Cutter::Flat { radius } | Cutter::Ball { radius } | Cutter::Torus { radius, .. } => radius,
        }
    }

    /// Height of the cutter's surface above its tip at squared radial
    /// distance `d2` (mm^2), for `d2 <= radius^2`. Taking the square keeps a
    /// square root off the flat cutter's hot path.
    #[inline]
    pub fn profile(&self, d2: f64) -> f64 {
        match *self {
            Cutter::Flat { .. } => 0.0,
            Cutter::Ball { radius } => radius - (radius * radius - d2).max(0.0).sqrt(),
            Cutter::Torus { radius, corner } => {
                let flat = radius - corner;
                let d = d2.sqrt();
                if d <= flat {
                    0.0
                } else {
                    let e = d - flat;
                    corner - (corner * corner - e * e).max(0.0).sqrt()
                }
            }
        }
    }
}

fn check_radius(r: f64) -> Result<(), CutterError> {
    if r > 0.0 && r.is_finite() {
        Ok(())
    } else {
        Err(CutterError::Radius(r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles_have_the_right_shape() {
        let b = Cutter::ball(1.0).unwrap();
        assert_eq!(b.profile(0.0), 0.0);
        assert!((b.profile(1.0) - 1.0).abs() < 1e-12);
        assert!((b.profile(0.25) - (1.0 - 0.75f64.sqrt())).abs() < 1e-12);
        let t = Cutter::torus(1.0, 0.25).unwrap();
        assert_eq!(t.profile(0.75 * 0.75), 0.0);
        assert!((t.profile(1.0) - 0.25).abs() < 1e-12);
        assert_eq!(Cutter::flat(1.0).unwrap().profile(1.0), 0.0);
        assert!(Cutter::torus(1.0, 1.0).is_err());
        assert!(Cutter::flat(f64::NAN).is_err());
        assert!(Cutter::ball(-1.0).is_err());
    }
}
