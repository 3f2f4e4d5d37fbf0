//! stlverify's library: simulate cutter locations on a tri-dexel stock
//! and compare the machined part with the design, after Singh 2014 (CL
//! data in, the machined part simulated, then rays cast on a grid over
//! the design and the simulated part, with a tolerance band).
//!
//! Singh 2014 stamped the tool at the CL points (Boolean subtraction in a
//! CAD system) and blamed the stair steps between stamps for part of the
//! over-cut it saw; here every move removes its swept volume
//! ([`crate::dexel`]), so the comparison shows the path, not the
//! simulation's sampling.
//!
//! - [`cl`]: CL data text and G-code programs to cutter locations.
//! - [`compare`]: rays on a grid, deviation statistics, profiles.
//! - [`plot`]: the deviation map (SVG, PNG) and the profile plot.
#![warn(missing_docs)]

pub mod cl;
pub mod compare;
pub mod plot;

use crate::dexel::tool::{LineMaterial, Location, MoveSweep, ToolShape};
use crate::dexel::{CutStats, DexelError, TriDexel};
use crate::geometry::{P3, V3};
use rayon::prelude::*;

/// What to simulate.
#[derive(Debug, Clone)]
pub struct VerifyJob {
    /// Lowest corner of the stock box, mm.
    pub stock_min: P3,
    /// Highest corner of the stock box, mm.
    pub stock_max: P3,
    /// The cutter, with its flute length.
    pub tool: ToolShape,
    /// Dexel spacing, mm.
    pub spacing: f64,
    /// Largest allowed distance between the true swept volume and the one
    /// cut (5-axis axis steps, torus corner ring), mm.
    pub sweep_tol: f64,
    /// A tighter bound for a torus corner's ring of balls alone, mm (it
    /// takes at most `sweep_tol / 2` in any case). The ring's error leaves
    /// material, which a verification reads as excess; a tight ring costs
    /// little (its error falls with the square of its ball count).
    pub ring_tol: Option<f64>,
    /// Tool locations in cutting order (tip and axis).
    pub locations: Vec<Location>,
}

/// The simulated part.
#[derive(Debug)]
pub struct Simulation {
    /// The machined stock.
    pub dexels: TriDexel,
    /// The volume each move swept, in order.
    pub sweeps: Vec<MoveSweep>,
    /// What the cutting did (moves, dexels touched).
    pub stats: CutStats,
    /// Largest shape error of any move's pieces, mm.
    pub shape_error_mm: f64,
    index: SweepIndex,
}

/// The sweeps of all moves (a standing tool at the first location, then
/// one per move).
pub fn sweeps(job: &VerifyJob) -> Vec<MoveSweep> {
    let locs = &job.locations;
    let mut pairs: Vec<(usize, usize)> = vec![(0, 0)];
    pairs.extend((1..locs.len()).map(|k| (k - 1, k)));
    pairs
        .par_iter()
        .map(|&(a, b)| {
            let ring_tol = job.ring_tol.unwrap_or(f64::INFINITY);
            MoveSweep::with_ring_tol(&job.tool, &locs[a], &locs[b], job.sweep_tol, ring_tol)
        })
        .collect()
}

/// Cut the job's stock.
pub fn simulate(job: &VerifyJob) -> Result<Simulation, DexelError> {
    let mut dexels = TriDexel::new(job.stock_min, job.stock_max, job.spacing)?;
    let sweeps = sweeps(job);
    let stats = dexels.cut(&sweeps);
    let shape_error_mm = sweeps.iter().map(|s| s.shape_error_mm).fold(0.0, f64::max);
    let index = SweepIndex::new(&sweeps, job.stock_min, job.stock_max);
    Ok(Simulation {
        dexels,
        sweeps,
        stats,
        shape_error_mm,
        index,
    })
}

/// Sweeps binned by their XY boxes on a coarse grid, for vertical rays at
/// any point (independent of the dexel spacing).
#[derive(Debug)]
struct SweepIndex {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    bins: Vec<Vec<u32>>,
}

impl SweepIndex {
    fn new(sweeps: &[MoveSweep], min: P3, max: P3) -> SweepIndex {
        let (w, h) = (max.x - min.x, max.y - min.y);
        let cell = (w * h / 4096.0).sqrt().max(1e-6);
        let nx = ((w / cell).ceil() as usize).clamp(1, 256);
        let ny = ((h / cell).ceil() as usize).clamp(1, 256);
        let cell = (w / nx as f64).max(h / ny as f64);
        let mut bins = vec![Vec::new(); nx * ny];
        let clampi = |v: f64, n: usize| (v.floor().max(0.0) as usize).min(n - 1);
        for (k, s) in sweeps.iter().enumerate() {
            if s.hi[0] < min.x || s.lo[0] > max.x || s.hi[1] < min.y || s.lo[1] > max.y {
                continue;
            }
            let (i0, i1) = (
                clampi((s.lo[0] - min.x) / cell, nx),
                clampi((s.hi[0] - min.x) / cell, nx),
            );
            let (j0, j1) = (
                clampi((s.lo[1] - min.y) / cell, ny),
                clampi((s.hi[1] - min.y) / cell, ny),
            );
            for j in j0..=j1 {
                for i in i0..=i1 {
                    bins[j * nx + i].push(k as u32);
                }
            }
        }
        SweepIndex {
            x0: min.x,
            y0: min.y,
            cell,
            nx,
            ny,
            bins,
        }
    }
}

impl Simulation {
    /// Top of the machined material on the vertical line through (x, y),
    /// cut exactly by every move's pieces (not read from the dexels);
    /// the stock bottom where the tool went through; `None` outside the
    /// stock.
    pub fn top_at(&self, x: f64, y: f64) -> Option<f64> {
        let (min, max) = (self.dexels.min, self.dexels.max);
        if x < min.x || x > max.x || y < min.y || y > max.y {
            return None;
        }
        let ix = &self.index;
        let i = (((x - ix.x0) / ix.cell) as usize).min(ix.nx - 1);
        let j = (((y - ix.y0) / ix.cell) as usize).min(ix.ny - 1);
        let o = P3::new(x, y, 0.0);
        let e = V3::z();
        let mut ivs = vec![[min.z, max.z]];
        let mut scratch = Vec::new();
        for &k in &ix.bins[j * ix.nx + i] {
            let s = &self.sweeps[k as usize];
            if x < s.lo[0] || x > s.hi[0] || y < s.lo[1] || y > s.hi[1] {
                continue;
            }
            s.remove_from(&o, &e, &mut Intervals(&mut ivs), &mut scratch);
        }
        Some(ivs.last().map_or(min.z, |v| v[1]))
    }

    /// Volume removed from the stock, mm³, by the Z dexels.
    pub fn removed_volume(&self) -> f64 {
        self.dexels.box_volume() - self.dexels.volumes()[2]
    }
}

/// Sorted disjoint intervals along a vertical line.
struct Intervals<'a>(&'a mut Vec<[f64; 2]>);

impl LineMaterial for Intervals<'_> {
    fn has(&self, t0: f64, t1: f64) -> bool {
        self.0.iter().any(|iv| iv[0] < t1 && iv[1] > t0)
    }
    fn remove(&mut self, t0: f64, t1: f64) {
        subtract(self.0, t0, t1);
    }
}

/// Remove (t0, t1) from sorted disjoint intervals.
fn subtract(ivs: &mut Vec<[f64; 2]>, t0: f64, t1: f64) {
    let mut out = Vec::with_capacity(ivs.len() + 1);
    for &iv in ivs.iter() {
        if t1 <= iv[0] || t0 >= iv[1] {
            out.push(iv);
            continue;
        }
        if t0 > iv[0] {
            out.push([iv[0], t0]);
        }
        if t1 < iv[1] {
            out.push([t1, iv[1]]);
        }
    }
    *ivs = out;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;

    #[test]
    fn exact_top_agrees_with_dexel_heights() {
        let loc = |x: f64, y: f64, z: f64| Location {
            tip: P3::new(x, y, z),
            axis: V3::new(0.2, 0.1, 1.0).normalize(),
        };
        let job = VerifyJob {
            stock_min: P3::new(0.0, 0.0, -3.0),
            stock_max: P3::new(10.0, 10.0, 0.0),
            tool: ToolShape {
                cutter: Cutter::Ball { radius: 1.0 },
                length: 5.0,
            },
            spacing: 0.1,
            sweep_tol: 0.01,
            ring_tol: None,
            locations: vec![loc(2.0, 2.0, -1.0), loc(8.0, 5.0, -1.5), loc(3.0, 8.0, -0.5)],
        };
        let sim = simulate(&job).unwrap();
        let h = sim.dexels.heights();
        let mut worst: f64 = 0.0;
        for j in 0..h.ny {
            for i in 0..h.nx {
                let (x, y) = (h.x0 + (i as f64 + 0.5) * h.dx, h.y0 + (j as f64 + 0.5) * h.dy);
                worst = worst.max((sim.top_at(x, y).unwrap() - h.z[j * h.nx + i]).abs());
            }
        }
        assert!(worst < 1e-5, "{worst}");
        assert!(sim.removed_volume() > 0.0);
        assert!(sim.top_at(-1.0, 0.0).is_none());
    }
}
