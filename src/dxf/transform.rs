//! The drawing transforms of the CAD panel of Bayesteh (2013): move, rotate, scale,
//! mirror, and linear and polar patterns, as the list of affine maps (one
//! per copy) that [`super::ImportOptions::copies`] takes.
//!
//! Order for each copy: scale, mirror, rotate (about the origin),
//! translate; then the copy's array offset and polar rotation.

use super::ocs::Affine;
use crate::geometry::V3;

/// `--mirror`: which coordinate changes sign.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mirror {
    /// x -> -x (mirror about the Y axis).
    X,
    /// y -> -y (mirror about the X axis).
    Y,
}

/// The user's transforms of the drawing (dxf2chains flags), applied in
/// millimetres after the drawing's units; `None` leaves a step out.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Transforms {
    /// `--translate`: shift (dx, dy) in mm.
    pub translate: Option<(f64, f64)>,
    /// `--rotate`: about the origin, degrees counter-clockwise.
    pub rotate_deg: Option<f64>,
    /// `--scale`: uniform factor about the origin.
    pub scale: Option<f64>,
    /// `--mirror`: which axis flips.
    pub mirror: Option<Mirror>,
    /// `--array`: nx columns, ny rows, spaced dx, dy (mm).
    pub array: Option<(u32, u32, f64, f64)>,
    /// `--polar`: n copies, step angle (degrees), centre x, centre y (mm).
    pub polar: Option<(u32, f64, f64, f64)>,
}

impl Transforms {
    /// True when no transform was asked for: one copy of the drawing as is.
    pub fn is_identity(&self) -> bool {
        *self == Transforms::default()
    }

    /// One affine map per copy, in a fixed order (array rows, then columns,
    /// then polar copies).
    pub fn copies(&self) -> Vec<Affine> {
        let mut base = Affine::identity();
        if let Some(s) = self.scale {
            base = Affine::scale(s, s, s).then_after(&base);
        }
        match self.mirror {
            Some(Mirror::X) => base = Affine::scale(-1.0, 1.0, 1.0).then_after(&base),
            Some(Mirror::Y) => base = Affine::scale(1.0, -1.0, 1.0).then_after(&base),
            None => {}
        }
        if let Some(r) = self.rotate_deg {
            base = Affine::rotate_z(r.to_radians()).then_after(&base);
        }
        if let Some((dx, dy)) = self.translate {
            base = Affine::translate(V3::new(dx, dy, 0.0)).then_after(&base);
        }
        let mut out = Vec::new();
        let (nx, ny, dx, dy) = self.array.unwrap_or((1, 1, 0.0, 0.0));
        for j in 0..ny {
            for i in 0..nx {
                let a = Affine::translate(V3::new(i as f64 * dx, j as f64 * dy, 0.0)).then_after(&base);
                match self.polar {
                    None => out.push(a),
                    Some((n, step, cx, cy)) => {
                        for k in 0..n {
                            let c = V3::new(cx, cy, 0.0);
                            let rot = Affine::translate(c)
                                .then_after(&Affine::rotate_z((k as f64 * step).to_radians()))
                                .then_after(&Affine::translate(-c));
                            out.push(rot.then_after(&a));
                        }
                    }
                }
            }
        }
        out
    }
}

/// A transform flag's value that cannot be used; the message names the
/// flag.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransformArgError {
    /// A comma-separated item is not a number.
    #[error("{flag}: '{item}' is not a number")]
    NotANumber {
        /// The flag, e.g. `--array`.
        flag: String,
        /// The item as given.
        item: String,
    },
    /// Not exactly the expected count of finite numbers.
    #[error("{flag}: expected {want} finite numbers separated by commas, got '{text}'")]
    Arity {
        /// The flag.
        flag: String,
        /// How many numbers it takes.
        want: usize,
        /// The value as given.
        text: String,
    },
    /// A copy count that is not a whole number from 1 to 10,000.
    #[error("{flag}: copy counts must be whole numbers from 1 to 10000, got {got}")]
    Count {
        /// The flag.
        flag: String,
        /// The number given.
        got: f64,
    },
}

/// Parse `a,b,...` into exactly `n` finite numbers.
pub fn parse_numbers(s: &str, n: usize, what: &str) -> Result<Vec<f64>, TransformArgError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| {
            t.trim().parse::<f64>().map_err(|_| TransformArgError::NotANumber {
                flag: what.to_string(),
                item: t.to_string(),
            })
        })
        .collect::<Result<_, _>>()?;
    if v.len() != n || v.iter().any(|x| !x.is_finite()) {
        return Err(TransformArgError::Arity {
            flag: what.to_string(),
            want: n,
            text: s.to_string(),
        });
    }
    Ok(v)
}

/// A copy count from the command line: a whole number from 1 to 10,000.
pub fn count(x: f64, what: &str) -> Result<u32, TransformArgError> {
    if x.fract() == 0.0 && (1.0..=10_000.0).contains(&x) {
        Ok(x as u32)
    } else {
        Err(TransformArgError::Count {
            flag: what.to_string(),
            got: x,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P3;

    #[test]
    fn order_is_scale_mirror_rotate_translate() {
        let t = Transforms {
            translate: Some((10.0, 0.0)),
            rotate_deg: Some(90.0),
            scale: Some(2.0),
            mirror: Some(Mirror::X),
            ..Default::default()
        };
        let c = t.copies();
        assert_eq!(c.len(), 1);
        // (1,0) -> (2,0) -> (-2,0) -> (0,-2) -> (10,-2)
        let p = c[0].apply(&P3::new(1.0, 0.0, 0.0));
        assert!((p - P3::new(10.0, -2.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn array_and_polar_counts() {
        let t = Transforms {
            array: Some((3, 2, 5.0, 7.0)),
            polar: Some((4, 90.0, 0.0, 0.0)),
            ..Default::default()
        };
        let c = t.copies();
        assert_eq!(c.len(), 24);
        let p = c[1].apply(&P3::new(1.0, 0.0, 0.0));
        assert!((p - P3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn number_lists() {
        assert_eq!(parse_numbers("1, 2", 2, "x").unwrap(), vec![1.0, 2.0]);
        assert!(parse_numbers("1", 2, "x").is_err());
        assert!(parse_numbers("1,a", 2, "x").is_err());
        assert!(count(2.5, "x").is_err());
    }
}
