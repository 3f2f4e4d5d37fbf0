//! The rotating wire probe: its effective diameter and touch resolution
//! (Bayesteh 2013, ch. 4).
//!
//! A straight wire of length `L` bent by `beta` at the end of a spinning
//! stylus sweeps a circle of diameter `D_e = 2 L sin(beta)`; that circle is
//! the probing element. The wire touches the part once per revolution, so
//! while approaching at feed `f_p` a contact is known only to within the
//! distance travelled in one revolution, `f_p / rpm`.

use super::ProbeError;

/// A rotating wire probe and how it approaches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// Effective (swept) diameter D_e (mm).
    pub effective_diameter_mm: f64,
    /// Spindle speed (rev/min).
    pub rpm: f64,
    /// Approach feed f_p (mm/s).
    pub feed_mm_s: f64,
}

impl Probe {
    /// A probe of given effective diameter; spindle speed and approach feed
    /// must be positive.
    pub fn new(effective_diameter_mm: f64, rpm: f64, feed_mm_s: f64) -> Result<Probe, ProbeError> {
        for (name, v) in [
            ("effective diameter", effective_diameter_mm),
            ("spindle speed", rpm),
            ("approach feed", feed_mm_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(ProbeError::Param(format!("{name} must be a positive number, got {v}")));
            }
        }
        // A rotating-wire tip is tens of microns across (Bayesteh 2013: a
        // 0.102 mm wire); below a micron the touch model is meaningless and
        // the coverage sampling (a quarter of the radius) degenerates.
        if effective_diameter_mm < 1e-3 {
            return Err(ProbeError::Param(format!(
                "effective diameter must be at least 0.001 mm, got {effective_diameter_mm}"
            )));
        }
        Ok(Probe {
            effective_diameter_mm,
            rpm,
            feed_mm_s,
        })
    }

    /// D_e = 2 L sin(beta) from the wire length `l_mm` and bend angle
    /// `beta_deg` (Bayesteh 2013, eq. 4.1).
    pub fn from_wire(l_mm: f64, beta_deg: f64, rpm: f64, feed_mm_s: f64) -> Result<Probe, ProbeError> {
        if !(beta_deg.is_finite() && beta_deg > 0.0 && beta_deg <= 90.0) {
            return Err(ProbeError::Param(format!(
                "bend angle must be in (0, 90] degrees, got {beta_deg}"
            )));
        }
        Probe::new(2.0 * l_mm * beta_deg.to_radians().sin(), rpm, feed_mm_s)
    }

    /// Tip radius R_e = D_e / 2 (mm).
    pub fn radius(&self) -> f64 {
        self.effective_diameter_mm / 2.0
    }

    /// Distance travelled along the approach in one revolution (mm): the
    /// touch resolution.
    pub fn touch_resolution_mm(&self) -> f64 {
        self.feed_mm_s * 60.0 / self.rpm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effective_diameter_and_resolution() {
        let p = Probe::from_wire(1.0, 30.0, 30_000.0, 0.05).unwrap();
        assert!((p.effective_diameter_mm - 1.0).abs() < 1e-15);
        assert!((p.touch_resolution_mm() - 1e-4).abs() < 1e-18);
        assert!(Probe::new(0.0, 1.0, 1.0).is_err());
        assert!(Probe::from_wire(1.0, 120.0, 1.0, 1.0).is_err());
    }
}
