//! How a real touch differs from the exact one, and what that does to a
//! measured point.
//!
//! Three effects, each optional: the wire touches only once per revolution
//! (the centre has moved on by a uniform fraction of `f_p / rpm` when it
//! does), the sensor and controller react late (a fixed over-travel
//! `f_p * delay`), and the burst threshold scatters (normal, sigma). All act
//! along the approach. Their mean (`delay * f_p + resolution / 2`) is what a
//! calibrated D_e absorbs, so it is taken off every reported contact; what
//! remains has standard deviation `sqrt(sigma^2 + resolution^2 / 12)`.

use super::ProbeError;
use super::tip::Probe;

/// The touch noise model.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NoiseModel {
    /// Standard deviation of the touch scatter (mm).
    pub sigma_mm: f64,
    /// Trigger delay (s).
    pub delay_s: f64,
    /// Touch only once per revolution.
    pub quantise: bool,
}

impl NoiseModel {
    /// Refuse negative or non-finite figures.
    pub fn check(&self) -> Result<(), ProbeError> {
        for (name, v) in [("touch noise", self.sigma_mm), ("trigger delay", self.delay_s)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ProbeError::Param(format!(
                    "{name} must be a non-negative number, got {v}"
                )));
            }
        }
        Ok(())
    }

    /// True when touches are exact.
    pub fn is_exact(&self) -> bool {
        self.sigma_mm == 0.0 && self.delay_s == 0.0 && !self.quantise
    }

    fn resolution(&self, probe: &Probe) -> f64 {
        if self.quantise {
            probe.touch_resolution_mm()
        } else {
            0.0
        }
    }

    /// Mean over-travel along the approach (mm), removed from every contact.
    pub fn bias_mm(&self, probe: &Probe) -> f64 {
        self.delay_s * probe.feed_mm_s + self.resolution(probe) / 2.0
    }

    /// Standard uncertainty of one contact along its approach (mm).
    pub fn point_sigma_mm(&self, probe: &Probe) -> f64 {
        let q = self.resolution(probe);
        (self.sigma_mm * self.sigma_mm + q * q / 12.0).sqrt()
    }

    /// The error of one touch along the approach, after the mean is taken
    /// off (mm).
    pub fn draw(&self, probe: &Probe, rng: &mut Rng) -> f64 {
        if self.is_exact() {
            return 0.0;
        }
        let mut e = self.delay_s * probe.feed_mm_s;
        if self.quantise {
            e += rng.uniform() * probe.touch_resolution_mm();
        }
        if self.sigma_mm > 0.0 {
            e += self.sigma_mm * rng.normal();
        }
        e - self.bias_mm(probe)
    }
}

/// A small seeded generator (SplitMix64), so a seed gives the same run on
/// every machine.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_have_zero_mean_and_the_predicted_spread() {
        let probe = Probe::new(0.1, 30_000.0, 0.5).unwrap();
        let m = NoiseModel {
            sigma_mm: 0.0005,
            delay_s: 0.001,
            quantise: true,
        };
        let mut rng = Rng::new(7);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| m.draw(&probe, &mut rng)).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        let s = m.point_sigma_mm(&probe);
        assert!(mean.abs() < 5.0 * s / (n as f64).sqrt(), "mean {mean}");
        assert!((var.sqrt() / s - 1.0).abs() < 0.01, "sd {} vs {s}", var.sqrt());
        assert_eq!(NoiseModel::default().draw(&probe, &mut rng), 0.0);
    }
}
