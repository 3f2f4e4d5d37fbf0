//! Where the cutter touches the bottom: the tool-tip height at (x, y) at
//! which the cutter rests on the surface without going below it anywhere
//! under its footprint (drop-cutter), and gouge-free straight moves between
//! such positions.
//!
//! Method (stated because it is numerical): the tip height is
//! `max over q in the footprint of S(q) - profile(|q - c|)`. The footprint
//! is sampled on rings (ρ = R·k/8, 6k points on ring k, 217 points), and the
//! three best samples are refined by a pattern search in the disk whose
//! step halves down to 1e-7·R. For a flat cutter the profile is 0, so this
//! is the highest surface point under the disk; for a ball or torus it is
//! the contact with the rounded end, not the surface point under the centre
//! (the Iowa State grid-pocket thesis (1999) §5.3 points out the CL/CC
//! difference on steep bottoms).

use crate::cutter::Cutter;
use crate::geometry::{P2, P3};

use super::surface::Surface;

/// Directions of the pattern search.
const DIRS: [(f64, f64); 8] = {
    use std::f64::consts::FRAC_1_SQRT_2 as H;
    [
        (1.0, 0.0),
        (-1.0, 0.0),
        (0.0, 1.0),
        (0.0, -1.0),
        (H, H),
        (-H, H),
        (H, -H),
        (-H, -H),
    ]
};

/// Rings of the footprint sampling.
const RINGS: usize = 8;

/// The surface seen through a cutter.
#[derive(Debug, Clone)]
pub struct Contact<'a> {
    /// The pocket's bottom.
    pub surface: &'a Surface,
    /// The cutter resting on it (tip heights are of its tip, in mm).
    pub cutter: Cutter,
    /// Largest dip (mm) of a straight move below the touching height.
    pub gouge_tol: f64,
    samples: Vec<(f64, f64, f64)>,
}

impl<'a> Contact<'a> {
    /// A contact model; `gouge_tol` bounds how far a straight move between
    /// touching positions may dip below the touching height in between.
    pub fn new(surface: &'a Surface, cutter: Cutter, gouge_tol: f64) -> Contact<'a> {
        let r = cutter.radius();
        let mut samples = Vec::new();
        for k in 0..=RINGS {
            let rho = r * k as f64 / RINGS as f64;
            let m = (6 * k).max(1);
            let prof = cutter.profile(rho).unwrap_or(0.0);
            for a in 0..m {
                let phi = std::f64::consts::TAU * (a as f64 + 0.5 * (k % 2) as f64) / m as f64;
                samples.push((rho * phi.cos(), rho * phi.sin(), prof));
            }
        }
        Contact {
            surface,
            cutter,
            gouge_tol,
            samples,
        }
    }

    fn value(&self, x: f64, y: f64, dx: f64, dy: f64) -> f64 {
        let rho = dx.hypot(dy);
        match self.cutter.profile(rho) {
            Some(p) => self.surface.height(x + dx, y + dy) - p,
            None => f64::NEG_INFINITY,
        }
    }

    /// Tool-tip height at which the cutter touches the surface at (x, y).
    pub fn tip_z(&self, x: f64, y: f64) -> f64 {
        if let Surface::Flat(z) = self.surface {
            return *z;
        }
        // Progress (a tool's spinner): the touching heights found are the
        // measure of a pocket's work; one relaxed add beside ~700 surface
        // evaluations costs nothing.
        crate::progress::advance(1);
        let mut best: [(f64, f64, f64); 3] = [(f64::NEG_INFINITY, 0.0, 0.0); 3];
        for &(dx, dy, prof) in &self.samples {
            let v = self.surface.height(x + dx, y + dy) - prof;
            if v > best[2].0 {
                best[2] = (v, dx, dy);
                best.sort_by(|a, b| b.0.total_cmp(&a.0));
            }
        }
        let r = self.cutter.radius();
        let mut top = best[0].0;
        for &(v0, dx0, dy0) in &best {
            if !v0.is_finite() {
                continue;
            }
            let (mut v, mut dx, mut dy) = (v0, dx0, dy0);
            let mut step = r / RINGS as f64;
            while step > 1e-7 * r {
                let mut moved = false;
                for (sx, sy) in DIRS {
                    let (nx, ny) = (dx + sx * step, dy + sy * step);
                    let w = self.value(x, y, nx, ny);
                    if w > v {
                        (v, dx, dy) = (w, nx, ny);
                        moved = true;
                    }
                }
                if !moved {
                    step *= 0.5;
                }
            }
            top = top.max(v);
        }
        top
    }

    /// Touching height at `p`, never below `floor`.
    pub fn tip_z_at(&self, p: P2) -> f64 {
        self.tip_z(p.x, p.y)
    }

    /// The straight move from `a` to `b` (both at their touching heights)
    /// as points whose chords dip at most `gouge_tol` below the touching
    /// height: a piece is halved while a sample in it dips further.
    /// Returns the points after `a`, ending with `b`.
    pub fn safe_line(&self, a: P3, b: P3, out: &mut Vec<P3>) {
        self.safe_rec(a, b, 0, out);
    }

    fn safe_rec(&self, a: P3, b: P3, depth: u32, out: &mut Vec<P3>) {
        const SAMPLES: usize = 8;
        let mut worst: f64 = 0.0;
        if depth < 14 && !matches!(self.surface, Surface::Flat(_)) {
            for k in 1..SAMPLES {
                let t = k as f64 / SAMPLES as f64;
                let p = a + (b - a) * t;
                worst = worst.max(self.tip_z(p.x, p.y) - p.z);
            }
        }
        if worst > self.gouge_tol {
            let m = a + (b - a) * 0.5;
            let mid = P3::new(m.x, m.y, self.tip_z(m.x, m.y));
            self.safe_rec(a, mid, depth + 1, out);
            self.safe_rec(mid, b, depth + 1, out);
        } else {
            out.push(b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pocket::surface::BezierPatch;

    #[test]
    fn ball_on_a_plane_touches_at_its_tip_and_on_a_slope_above_it() {
        let flat = Surface::Flat(-1.0);
        let c = Contact::new(&flat, Cutter::Ball { radius: 1.0 }, 1e-3);
        assert_eq!(c.tip_z(0.3, 0.2), -1.0);
        // Plane z = x·tan(30°): a ball of radius R touches at tip height
        // x·tan + R(1/cos - 1).
        let t = 30f64.to_radians().tan();
        let z: Vec<f64> = (0..16).map(|k| t * (k % 4) as f64).collect();
        let s = Surface::Bezier(BezierPatch::new([-10.0, 20.0], [-10.0, 20.0], &z).unwrap());
        // Control spacing 10 mm in x: slope is t per 10 mm → scale.
        let slope = t / 10.0;
        let c = Contact::new(&s, Cutter::Ball { radius: 1.0 }, 1e-3);
        let want = (2.0 + 10.0) * slope + (1.0 / slope.atan().cos() - 1.0);
        assert!(
            (c.tip_z(2.0, 3.0) - want).abs() < 1e-9,
            "{} vs {want}",
            c.tip_z(2.0, 3.0)
        );
        // A flat end mill rests on the highest point under its disk.
        let f = Contact::new(&s, Cutter::Flat { radius: 1.0 }, 1e-3);
        assert!((f.tip_z(2.0, 3.0) - 13.0 * slope).abs() < 1e-9);
    }
}
