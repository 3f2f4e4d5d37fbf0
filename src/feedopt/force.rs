//! A mechanistic cutting-force estimate per step (the linear edge-force
//! model of Altintas, Manufacturing Automation, ch. 2): a tooth at
//! immersion angle φ cutting a chip of thickness h = f_z·sin φ over an
//! axial depth b sees a tangential force b·(K_tc·h + K_te) and a radial
//! force b·(K_rc·h + K_re).
//!
//! The simulation gives the chip cross-section A per step (volume per mm
//! of path) and the tool's depth b below the stock top; the radial width is
//! a_e = A/b and the tool engages over φ_e = acos(1 - a_e/R). Averaged over
//! a revolution with N teeth, the mean tangential force is
//! N·b/(2π)·(K_tc·f_z·(1 - cos φ_e) + K_te·φ_e), and likewise radial; the
//! figure reported is the resultant of the two means. The peak is one
//! tooth's resultant at φ = min(φ_e, π/2). This treats every cutter as a
//! flat end mill in a 2.5-D cut, and b as depth below the stock's top
//! (exact for one level; an overestimate on lower levels).

use serde::Deserialize;
use std::f64::consts::PI;
use thiserror::Error;

/// A coefficient file that does not make a model.
#[derive(Debug, Error)]
pub enum ForceError {
    /// The file (named first) is not a JSON object with exactly the four
    /// coefficient fields.
    #[error("{0}: {1}")]
    Json(String, serde_json::Error),
    /// The file (named first) cannot be read.
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    /// In the file named first, the field named second is negative or not
    /// finite.
    #[error("{0}: {1} must be a finite number >= 0")]
    Value(String, &'static str),
}

/// Cutting and edge force coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coefficients {
    /// Tangential cutting coefficient, N/mm².
    pub ktc_n_mm2: f64,
    /// Radial cutting coefficient, N/mm².
    pub krc_n_mm2: f64,
    /// Tangential edge coefficient, N/mm.
    pub kte_n_mm: f64,
    /// Radial edge coefficient, N/mm.
    pub kre_n_mm: f64,
}

impl Default for Coefficients {
    /// Aluminium-alloy figures from the worked example of Altintas,
    /// Manufacturing Automation (2nd ed., 2012, ch. 2; Al7050), standing in
    /// for Al6061, which Bayesteh 2013 cut: replace them with coefficients
    /// identified for your tool and material.
    fn default() -> Self {
        Coefficients {
            ktc_n_mm2: 796.0,
            krc_n_mm2: 168.0,
            kte_n_mm: 27.7,
            kre_n_mm: 30.8,
        }
    }
}

impl Coefficients {
    /// Read a JSON object with the four fields (`ktc_n_mm2`, `krc_n_mm2`,
    /// `kte_n_mm`, `kre_n_mm`).
    pub fn from_json(text: &str, name: &str) -> Result<Coefficients, ForceError> {
        let c: Coefficients = serde_json::from_str(text).map_err(|e| ForceError::Json(name.into(), e))?;
        for (v, f) in [
            (c.ktc_n_mm2, "ktc_n_mm2"),
            (c.krc_n_mm2, "krc_n_mm2"),
            (c.kte_n_mm, "kte_n_mm"),
            (c.kre_n_mm, "kre_n_mm"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ForceError::Value(name.into(), f));
            }
        }
        Ok(c)
    }

    /// Read a coefficient file.
    pub fn load(path: &std::path::Path) -> Result<Coefficients, ForceError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ForceError::Io(name.clone(), e))?;
        Coefficients::from_json(&text, &name)
    }
}

/// The engagement of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Engagement {
    /// Axial depth, mm.
    pub depth_mm: f64,
    /// Engagement angle, rad.
    pub phi_rad: f64,
}

impl Engagement {
    /// From the chip cross-section `area_mm2`, the depth below the stock top
    /// and the tool radius.
    pub fn new(area_mm2: f64, depth_mm: f64, radius_mm: f64) -> Engagement {
        if !(depth_mm > 1e-9 && area_mm2 > 0.0 && radius_mm > 0.0) {
            return Engagement {
                depth_mm: 0.0,
                phi_rad: 0.0,
            };
        }
        let ae = (area_mm2 / depth_mm).min(2.0 * radius_mm);
        Engagement {
            depth_mm,
            phi_rad: (1.0 - ae / radius_mm).clamp(-1.0, 1.0).acos(),
        }
    }
}

/// The model for a tool with `flutes` teeth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceModel {
    /// The material's and tool's force coefficients.
    pub k: Coefficients,
    /// Teeth of the tool (the mean force scales with them).
    pub flutes: u32,
}

impl ForceModel {
    /// Mean resultant force over a revolution at feed per tooth `fz` mm, N.
    pub fn mean_n(&self, e: &Engagement, fz: f64) -> f64 {
        if e.depth_mm <= 0.0 {
            return 0.0;
        }
        let c = self.flutes as f64 * e.depth_mm / (2.0 * PI);
        let w = 1.0 - e.phi_rad.cos();
        let ft = c * (self.k.ktc_n_mm2 * fz * w + self.k.kte_n_mm * e.phi_rad);
        let fr = c * (self.k.krc_n_mm2 * fz * w + self.k.kre_n_mm * e.phi_rad);
        ft.hypot(fr)
    }

    /// Peak force on one tooth, N.
    pub fn peak_n(&self, e: &Engagement, fz: f64) -> f64 {
        if e.depth_mm <= 0.0 {
            return 0.0;
        }
        let h = fz * e.phi_rad.min(PI / 2.0).sin();
        let ft = e.depth_mm * (self.k.ktc_n_mm2 * h + self.k.kte_n_mm);
        let fr = e.depth_mm * (self.k.krc_n_mm2 * h + self.k.kre_n_mm);
        ft.hypot(fr)
    }

    /// The feed per tooth in `[lo, hi]` at which the mean force is `target`
    /// (the mean force rises with the feed): `hi` when even `hi` stays
    /// below, `lo` when even `lo` is above.
    pub fn feed_for(&self, e: &Engagement, target: f64, lo: f64, hi: f64) -> f64 {
        if self.mean_n(e, hi) <= target {
            return hi;
        }
        if self.mean_n(e, lo) >= target {
            return lo;
        }
        let (mut a, mut b) = (lo, hi);
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            if self.mean_n(e, m) <= target {
                a = m;
            } else {
                b = m;
            }
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_force_matches_the_power_balance_without_edge_forces() {
        // Without edge terms the mean tangential force times the surface
        // speed is the cutting power K_tc · MRR.
        let k = Coefficients {
            ktc_n_mm2: 800.0,
            krc_n_mm2: 0.0,
            kte_n_mm: 0.0,
            kre_n_mm: 0.0,
        };
        let m = ForceModel { k, flutes: 2 };
        let (r, b, ae, fz) = (0.397, 0.1, 0.2, 0.001);
        let e = Engagement::new(ae * b, b, r);
        let n_rev_s = 1000.0;
        let power = m.mean_n(&e, fz) * 2.0 * PI * r * n_rev_s;
        let mrr = ae * b * fz * 2.0 * n_rev_s;
        assert!((power - 800.0 * mrr).abs() < 1e-9 * power, "{power} vs {}", 800.0 * mrr);
    }

    #[test]
    fn feed_for_inverts_the_mean_force() {
        let m = ForceModel {
            k: Coefficients::default(),
            flutes: 2,
        };
        let e = Engagement::new(0.03, 0.1, 0.397);
        let f = m.feed_for(&e, m.mean_n(&e, 0.0012), 0.001, 0.0015);
        assert!((f - 0.0012).abs() < 1e-9);
        assert_eq!(m.feed_for(&e, 1e9, 0.001, 0.0015), 0.0015);
        assert!(m.peak_n(&e, 0.001) > m.mean_n(&e, 0.001) * 0.5);
        assert!(
            Coefficients::from_json(r#"{"ktc_n_mm2":1,"krc_n_mm2":1,"kte_n_mm":1,"kre_n_mm":-1}"#, "k.json").is_err()
        );
    }

    #[test]
    fn the_force_never_falls_as_the_feed_rises() {
        // Why the model cannot predict a lower mean force after feedopt,
        // whose feeds are never below the nominal f_min (docs/feedopt.md).
        let m = ForceModel {
            k: Coefficients::default(),
            flutes: 2,
        };
        for ae in [0.01, 0.1, 0.397, 0.794] {
            for b in [0.01, 0.1] {
                let e = Engagement::new(ae * b, b, 0.397);
                let mut last = (0.0, 0.0);
                for k in 0..=50 {
                    let fz = 0.001 + 0.0005 * k as f64 / 50.0;
                    let now = (m.mean_n(&e, fz), m.peak_n(&e, fz));
                    assert!(now.0 >= last.0 && now.1 >= last.1, "ae {ae} b {b} fz {fz}");
                    last = now;
                }
            }
        }
    }
}
