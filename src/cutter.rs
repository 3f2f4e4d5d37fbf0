//! End mills: the shape of the cutting end, shared by every milling tool
//! (material removal, drop-cutter, pocketing, feed scheduling, verification,
//! ploughing).
//!
//! A cutter is described the way OpenCAMLib and most CAM systems do it: a
//! solid of revolution about the tool axis whose underside, at horizontal
//! distance ρ from the axis, sits `profile(ρ)` above the tool tip. The
//! algorithms that use it (drop-cutter, removal) ask only for that profile
//! and the radii, so a new shape needs a variant here and nothing else.
#![warn(missing_docs)]

use std::fmt;
use thiserror::Error;

/// A cutter description that does not make a tool.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CutterError {
    /// Not `flat:D`, `ball:D` or `torus:D:RC` with positive numbers.
    #[error("cutter '{0}': expected flat:D, ball:D or torus:D:RC in mm")]
    Syntax(String),
    /// A torus whose corner radius exceeds the tool radius.
    #[error("cutter '{0}': the corner radius is above the tool radius")]
    CornerTooLarge(String),
}

/// The cutting end of an end mill, dimensions in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cutter {
    /// Flat end mill (cylinder) of radius `radius`.
    Flat {
        /// Tool radius, mm.
        radius: f64,
    },
    /// Ball-nose end mill: a hemisphere of radius `radius`.
    Ball {
        /// Tool (and ball) radius, mm.
        radius: f64,
    },
    /// Bull nose (torus): flat bottom out to `radius - corner`, then a
    /// quarter circle of radius `corner` (0 < corner <= radius).
    Torus {
        /// Tool radius, mm.
        radius: f64,
        /// Corner radius, mm.
        corner: f64,
    },
}

impl Cutter {
    /// `flat:D`, `ball:D` or `torus:D:RC` (diameter and corner radius, mm).
    ///
    /// ```
    /// use microcam::cutter::Cutter;
    /// assert_eq!(Cutter::parse("ball:2").unwrap(), Cutter::Ball { radius: 1.0 });
    /// assert!(Cutter::parse("torus:2:1.5").is_err());
    /// ```
    pub fn parse(s: &str) -> Result<Cutter, CutterError> {
        let parts: Vec<&str> = s.split(':').collect();
        let num = |i: usize| -> Result<f64, CutterError> {
            parts
                .get(i)
                .and_then(|x| x.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite() && *v > 0.0 && *v < 1e6)
                .ok_or_else(|| CutterError::Syntax(s.to_string()))
        };
        let c = match (parts[0].trim(), parts.len()) {
            ("flat", 2) => Cutter::Flat { radius: num(1)? / 2.0 },
            ("ball", 2) => Cutter::Ball { radius: num(1)? / 2.0 },
            ("torus", 3) => Cutter::Torus {
                radius: num(1)? / 2.0,
                corner: num(2)?,
            },
            _ => return Err(CutterError::Syntax(s.to_string())),
        };
        if let Cutter::Torus { radius, corner } = c
            && corner > radius
        {
            return Err(CutterError::CornerTooLarge(s.to_string()));
        }
        Ok(c)
    }

    /// The cutter of diameter `d` and corner radius `cr` (mm), as tool
    /// tables and CAM tool comments give them: flat when `cr` is 0, ball
    /// when it is half the diameter, torus between; `None` unless
    /// `d > 0` and `0 <= cr <= d/2`.
    ///
    /// ```
    /// use microcam::cutter::Cutter;
    /// assert_eq!(Cutter::from_diameter_corner(2.0, 1.0), Some(Cutter::Ball { radius: 1.0 }));
    /// assert_eq!(Cutter::from_diameter_corner(2.0, 0.0), Some(Cutter::Flat { radius: 1.0 }));
    /// ```
    pub fn from_diameter_corner(d: f64, cr: f64) -> Option<Cutter> {
        if !(d.is_finite() && d > 0.0 && cr.is_finite() && cr >= 0.0 && cr <= d / 2.0 + 1e-12) {
            return None;
        }
        let radius = d / 2.0;
        Some(if cr == 0.0 {
            Cutter::Flat { radius }
        } else if (cr - radius).abs() <= 1e-9 * radius {
            Cutter::Ball { radius }
        } else {
            Cutter::Torus { radius, corner: cr }
        })
    }

    /// Tool radius (half the diameter).
    pub fn radius(&self) -> f64 {
        match *self {
            Cutter::Flat { radius } | Cutter::Ball { radius } | Cutter::Torus { radius, .. } => radius,
        }
    }

    /// Tool diameter.
    pub fn diameter(&self) -> f64 {
        2.0 * self.radius()
    }

    /// Radius of the rounded edge: 0 for a flat end mill, the tool radius
    /// for a ball.
    pub fn corner_radius(&self) -> f64 {
        match *self {
            Cutter::Flat { .. } => 0.0,
            Cutter::Ball { radius } => radius,
            Cutter::Torus { corner, .. } => corner,
        }
    }

    /// Height of the underside above the tool tip at distance `rho` from
    /// the axis; `None` outside the tool.
    ///
    /// ```
    /// use microcam::cutter::Cutter;
    /// let ball = Cutter::Ball { radius: 1.0 };
    /// assert_eq!(ball.profile(0.0), Some(0.0));
    /// assert_eq!(ball.profile(1.0), Some(1.0));
    /// assert_eq!(ball.profile(1.5), None);
    /// ```
    #[inline]
    pub fn profile(&self, rho: f64) -> Option<f64> {
        match *self {
            Cutter::Flat { radius } => (rho <= radius).then_some(0.0),
            Cutter::Ball { radius } => (rho <= radius).then(|| radius - (radius * radius - rho * rho).max(0.0).sqrt()),
            Cutter::Torus { radius, corner } => {
                if rho > radius {
                    None
                } else {
                    let flat = radius - corner;
                    if rho <= flat {
                        Some(0.0)
                    } else {
                        let u = rho - flat;
                        Some(corner - (corner * corner - u * u).max(0.0).sqrt())
                    }
                }
            }
        }
    }
}

/// Written back in the form [`Cutter::parse`] reads.
impl fmt::Display for Cutter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Cutter::Flat { radius } => write!(f, "flat:{}", 2.0 * radius),
            Cutter::Ball { radius } => write!(f, "ball:{}", 2.0 * radius),
            Cutter::Torus { radius, corner } => write!(f, "torus:{}:{}", 2.0 * radius, corner),
        }
    }
}

/// A cutter with what a milling schedule needs to know about it besides
/// its shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tool {
    /// The shape.
    pub cutter: Cutter,
    /// Cutting edges; feed per tooth = feed / (rpm/60 · flutes).
    pub flutes: u32,
    /// Length of the cutting part above the tip (mm); material above it is
    /// hit by the shank. `None`: unlimited.
    pub flute_length: Option<f64>,
}

impl Tool {
    /// A tool with `flutes` flutes and no flute length limit.
    pub fn new(cutter: Cutter, flutes: u32) -> Tool {
        Tool {
            cutter,
            flutes,
            flute_length: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_display_round_trip() {
        for s in ["flat:2", "ball:0.794", "torus:6:0.5"] {
            let c = Cutter::parse(s).unwrap();
            assert_eq!(c.to_string(), s);
            assert_eq!(Cutter::parse(&c.to_string()).unwrap(), c);
        }
        assert_eq!(Cutter::parse("flat:2").unwrap(), Cutter::Flat { radius: 1.0 });
        assert!(matches!(
            Cutter::parse("torus:2:1.5"),
            Err(CutterError::CornerTooLarge(_))
        ));
        assert!(Cutter::parse("ball:-1").is_err());
        assert!(Cutter::parse("ball:nan").is_err());
        assert!(Cutter::parse("drill:1").is_err());
        assert!(Cutter::parse("").is_err());
    }

    #[test]
    fn torus_profile_meets_flat_and_ball_at_its_limits() {
        let t = Cutter::Torus {
            radius: 1.0,
            corner: 1.0,
        };
        let b = Cutter::Ball { radius: 1.0 };
        for i in 0..=20 {
            let rho = i as f64 / 20.0;
            assert!((t.profile(rho).unwrap() - b.profile(rho).unwrap()).abs() < 1e-12);
        }
        let t = Cutter::Torus {
            radius: 1.0,
            corner: 0.25,
        };
        assert_eq!(t.profile(0.75), Some(0.0));
        assert!((t.profile(1.0).unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(t.corner_radius(), 0.25);
    }
}
