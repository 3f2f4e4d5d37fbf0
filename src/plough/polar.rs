//! The chip seen from the cutter's centre: how much of it lies along each
//! radius, in angular bins one accuracy step T_p long on the cutter circle.
//!
//! Bayesteh 2013 (Figs. 5-8 to 5-10) walks the cutter arc in steps of T_p
//! from each end of the chip and measures, along the radius, how far the
//! chip reaches inward, until that thickness passes the minimum chip
//! thickness. Here the same measure comes from the chip's area per unit
//! angle, a(θ) = ∫ t dt over the chip along the ray at θ, which for a chip
//! reaching the cutter edge gives its radial thickness
//! h = r − sqrt(r² − 2a). The ploughing area is the chip area at angles
//! where 0 < h < h_min: both ends of every chip piece, however many pieces
//! the stock outline splits the chip into, and any thin place between.

use super::dexel::Removed;
use std::f64::consts::TAU;

/// Angular bins around the cutter.
#[derive(Debug, Clone)]
pub struct Bins {
    /// Cutter radius, mm.
    pub r: f64,
    /// Bin width, rad.
    pub dtheta: f64,
    /// cos and sin of each bin's centre angle.
    pub dir: Vec<(f64, f64)>,
}

impl Bins {
    /// Bins `accuracy` mm long on a circle of radius `r`.
    pub fn new(r: f64, accuracy: f64) -> Bins {
        let n = bin_count(r, accuracy);
        let dtheta = TAU / n as f64;
        let dir = (0..n)
            .map(|k| {
                let a = (k as f64 + 0.5) * dtheta;
                (a.cos(), a.sin())
            })
            .collect();
        Bins { r, dtheta, dir }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.dir.len()
    }

    /// Always false: there are at least four bins.
    pub fn is_empty(&self) -> bool {
        self.dir.is_empty()
    }

    /// Index of the bin holding angle `a` (any real angle).
    pub fn bin_of(&self, a: f64) -> usize {
        let k = (a.rem_euclid(TAU) / self.dtheta) as usize;
        k.min(self.len() - 1)
    }

    /// Add to `acc` the chip density of the strips in `removed` (one
    /// family, `along_x` when its lines run along X) seen from (`cx`, `cy`).
    pub fn add_strips(&self, acc: &mut [f64], removed: &[Removed], spacing: f64, along_x: bool, cx: f64, cy: f64) {
        let half = 0.5 * spacing;
        for p in removed {
            // The strip as a rectangle in the cutter's frame.
            let (x0, x1, y0, y1) = if along_x {
                (p.along0 - cx, p.along1 - cx, p.across - half - cy, p.across + half - cy)
            } else {
                (p.across - half - cx, p.across + half - cx, p.along0 - cy, p.along1 - cy)
            };
            let area = (x1 - x0) * (y1 - y0);
            let (mx, my) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
            let inside = x0 <= 0.0 && 0.0 <= x1 && y0 <= 0.0 && 0.0 <= y1;
            let (k0, k1) = if inside {
                (0, self.len() as isize - 1)
            } else {
                // Angular extent, measured from the centre's direction so it
                // never wraps (the rectangle does not hold the centre).
                let base = my.atan2(mx);
                let (mut lo, mut hi) = (0.0f64, 0.0f64);
                for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
                    let d = (y.atan2(x) - base + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI;
                    lo = lo.min(d);
                    hi = hi.max(d);
                }
                let k0 = ((base + lo) / self.dtheta - 0.5).ceil() as isize;
                let k1 = ((base + hi) / self.dtheta - 0.5).floor() as isize;
                if k1 - k0 < 2 {
                    // Narrower than a few bins: its whole area goes to the
                    // bin of its centre, so no strip is lost between rays.
                    acc[self.bin_of(base)] += area / self.dtheta;
                    continue;
                }
                (k0, k1)
            };
            let n = self.len() as isize;
            for k in k0..=k1 {
                let (c, s) = self.dir[k.rem_euclid(n) as usize];
                // Not clipped at the cutter edge: a strip's corner beyond
                // the circle stands for the chip its other corner misses,
                // so the staircase keeps the chip's area.
                if let Some((t0, t1)) = ray_rect(c, s, x0, x1, y0, y1, 2.0 * self.r) {
                    acc[k.rem_euclid(n) as usize] += 0.5 * (t1 * t1 - t0 * t0);
                }
            }
        }
    }
}

/// Bins of about `accuracy` mm on a circle of radius `r` (at least 4).
pub fn bin_count(r: f64, accuracy: f64) -> usize {
    ((TAU * r / accuracy).round() as usize).max(4)
}

/// Where the ray from the origin along (`c`, `s`) is inside the rectangle,
/// within `[0, tmax]`.
pub fn ray_rect(c: f64, s: f64, x0: f64, x1: f64, y0: f64, y1: f64, tmax: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0f64, tmax);
    for (d, a, b) in [(c, x0, x1), (s, y0, y1)] {
        if d.abs() < 1e-300 {
            if a > 0.0 || b < 0.0 {
                return None;
            }
        } else {
            let (ta, tb) = (a / d, b / d);
            let (ta, tb) = if ta < tb { (ta, tb) } else { (tb, ta) };
            lo = lo.max(ta);
            hi = hi.min(tb);
        }
    }
    (hi > lo).then_some((lo, hi))
}

/// Circular moving average of `a` over `w` bins (odd), into `out`.
pub fn smooth(a: &[f64], w: usize, out: &mut Vec<f64>) {
    let n = a.len();
    out.clear();
    let w = w.min(n - (1 - n % 2)).max(1) | 1;
    if w == 1 {
        out.extend_from_slice(a);
        return;
    }
    let h = w / 2;
    let mut sum: f64 = (0..w).map(|i| a[(i + n - h) % n]).sum();
    for k in 0..n {
        out.push(sum / w as f64);
        sum += a[(k + h + 1) % n] - a[(k + n - h) % n];
    }
}

/// Radial thickness of a chip with area density `a` (mm²/rad) reaching the
/// edge of a cutter of radius `r`.
pub fn thickness(a: f64, r: f64) -> f64 {
    let inner2 = r * r - 2.0 * a;
    if inner2 <= 0.0 { r } else { r - inner2.sqrt() }
}

/// Chip area and ploughing area (mm²) from density per bin, thickness per
/// bin and the minimum chip thickness.
pub fn split(density: &[f64], thick: impl Fn(usize) -> f64, h_min: f64, dtheta: f64) -> (f64, f64) {
    let (mut chip, mut plough) = (0.0, 0.0);
    // Rounding in a running sum leaves crumbs of 1e-18 where there is no
    // chip: below a billionth of the peak is nothing.
    let floor = 1e-9 * density.iter().fold(0.0f64, |m, &a| m.max(a));
    for (k, &a) in density.iter().enumerate() {
        if a <= floor {
            continue;
        }
        chip += a;
        let h = thick(k);
        if h > 0.0 && h < h_min {
            plough += a;
        }
    }
    (chip * dtheta, plough * dtheta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_through_rectangle() {
        assert_eq!(ray_rect(1.0, 0.0, 1.0, 2.0, -1.0, 1.0, 10.0), Some((1.0, 2.0)));
        assert_eq!(ray_rect(1.0, 0.0, 1.0, 2.0, -1.0, 1.0, 1.5), Some((1.0, 1.5)));
        assert_eq!(ray_rect(-1.0, 0.0, 1.0, 2.0, -1.0, 1.0, 10.0), None);
        assert_eq!(ray_rect(0.0, 1.0, 1.0, 2.0, -1.0, 1.0, 10.0), None);
    }

    #[test]
    fn smoothing_keeps_the_total() {
        let mut a = vec![0.0; 50];
        a[0] = 7.0;
        a[20] = 3.0;
        let mut out = Vec::new();
        smooth(&a, 5, &mut out);
        assert!((out.iter().sum::<f64>() - 10.0).abs() < 1e-12);
        assert!((out[49] - 1.4).abs() < 1e-12 && (out[2] - 1.4).abs() < 1e-12 && out[3] == 0.0);
    }

    #[test]
    fn strips_spread_their_area_over_angle() {
        // A thin ring of strips around the centre keeps its area.
        let b = Bins::new(1.0, 0.01);
        let mut acc = vec![0.0; b.len()];
        let strip = Removed {
            along0: 0.9,
            along1: 1.0,
            across: 0.0,
        };
        b.add_strips(&mut acc, &[strip], 0.2, true, 0.0, 0.0);
        let total: f64 = acc.iter().sum::<f64>() * b.dtheta;
        // The rectangle [0.9,1]×[-0.1,0.1] clipped by the unit disc.
        assert!((total - 0.02).abs() < 1.5e-3, "{total}");
        assert!(thickness(0.5 * (1.0 - 0.81), 1.0) - 0.1 < 1e-12);
    }
}
