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
///
/// The moves' sweeps are not kept: they are built a run of moves at a
/// time for the cut (as many as one batch of prepared pieces holds), and
/// again for the verification rays, a bin of the plan view at a time. A
/// torus job's sweeps take some 5 KB a move (a ring of 50 balls at a
/// tight band), which on a raster of 80,000 locations was half of the
/// memory (docs/stlverify.md).
#[derive(Debug)]
pub struct Simulation {
    /// The machined stock.
    pub dexels: TriDexel,
    /// What the cutting did (moves, dexels touched).
    pub stats: CutStats,
    /// Largest shape error of any move's pieces, mm.
    pub shape_error_mm: f64,
    /// Sub-moves of all moves (5-axis moves are split where the axis
    /// turns; one per move otherwise).
    pub sub_moves: usize,
    job: VerifyJob,
    /// Each move's box (low and high corners), in order.
    boxes: Vec<([f64; 3], [f64; 3])>,
    index: SweepIndex,
}

/// The move pairs of a job: a standing tool at the first location, then
/// one move per pair of consecutive locations (none without locations).
fn move_count(job: &VerifyJob) -> usize {
    job.locations.len()
}

/// The sweep of move `k` of `job` (see [`move_count`]).
fn sweep_of(job: &VerifyJob, k: usize) -> MoveSweep {
    let locs = &job.locations;
    let (a, b) = (k.saturating_sub(1), k);
    let ring_tol = job.ring_tol.unwrap_or(f64::INFINITY);
    MoveSweep::with_ring_tol(&job.tool, &locs[a], &locs[b], job.sweep_tol, ring_tol)
}

/// The sweeps of all moves (a standing tool at the first location, then
/// one per move).
pub fn sweeps(job: &VerifyJob) -> Vec<MoveSweep> {
    (0..move_count(job)).into_par_iter().map(|k| sweep_of(job, k)).collect()
}

/// Cut the job's stock.
pub fn simulate(job: &VerifyJob) -> Result<Simulation, DexelError> {
    simulate_in_runs(job, crate::dexel::PREPARED_BYTES)
}

/// [`simulate`], building the sweeps of as many moves at a time as take
/// `budget` bytes once prepared for one family (a single move may take
/// more). The part does not depend on `budget`.
fn simulate_in_runs(job: &VerifyJob, budget: usize) -> Result<Simulation, DexelError> {
    let mut dexels = TriDexel::new(job.stock_min, job.stock_max, job.spacing)?;
    let n = move_count(job);
    let mut stats = CutStats::default();
    let (mut shape_error_mm, mut sub_moves) = (0.0f64, 0usize);
    let mut boxes = Vec::with_capacity(n);
    // Built a block at a time on the pool, cut a run at a time.
    const BLOCK: usize = 256;
    let mut run: Vec<MoveSweep> = Vec::new();
    let mut run_bytes = 0usize;
    let cut_run = |run: &mut Vec<MoveSweep>, dexels: &mut TriDexel, stats: &mut CutStats| {
        *stats = *stats + dexels.cut_in_batches(run, budget);
        run.clear();
    };
    let mut k = 0;
    while k < n {
        let end = (k + BLOCK).min(n);
        let block: Vec<MoveSweep> = (k..end).into_par_iter().map(|m| sweep_of(job, m)).collect();
        for s in block {
            shape_error_mm = shape_error_mm.max(s.shape_error_mm);
            sub_moves += s.substeps;
            boxes.push((s.lo, s.hi));
            let b = crate::dexel::prepared_bytes(&s);
            if !run.is_empty() && run_bytes + b > budget {
                cut_run(&mut run, &mut dexels, &mut stats);
                run_bytes = 0;
            }
            run_bytes += b;
            run.push(s);
        }
        k = end;
    }
    if !run.is_empty() {
        cut_run(&mut run, &mut dexels, &mut stats);
    }
    let index = SweepIndex::new(&boxes, job.stock_min, job.stock_max);
    Ok(Simulation {
        dexels,
        stats,
        shape_error_mm,
        sub_moves,
        job: job.clone(),
        boxes,
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
    fn new(boxes: &[([f64; 3], [f64; 3])], min: P3, max: P3) -> SweepIndex {
        let (w, h) = (max.x - min.x, max.y - min.y);
        let cell = (w * h / 4096.0).sqrt().max(1e-6);
        let nx = ((w / cell).ceil() as usize).clamp(1, 256);
        let ny = ((h / cell).ceil() as usize).clamp(1, 256);
        let cell = (w / nx as f64).max(h / ny as f64);
        let mut bins = vec![Vec::new(); nx * ny];
        let clampi = |v: f64, n: usize| (v.floor().max(0.0) as usize).min(n - 1);
        for (k, (lo, hi)) in boxes.iter().enumerate() {
            if hi[0] < min.x || lo[0] > max.x || hi[1] < min.y || lo[1] > max.y {
                continue;
            }
            let (i0, i1) = (clampi((lo[0] - min.x) / cell, nx), clampi((hi[0] - min.x) / cell, nx));
            let (j0, j1) = (clampi((lo[1] - min.y) / cell, ny), clampi((hi[1] - min.y) / cell, ny));
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

impl SweepIndex {
    /// The bin of (x, y), a point inside the stock's plan.
    fn bin(&self, x: f64, y: f64) -> usize {
        let i = (((x - self.x0) / self.cell) as usize).min(self.nx - 1);
        let j = (((y - self.y0) / self.cell) as usize).min(self.ny - 1);
        j * self.nx + i
    }
}

impl Simulation {
    /// Top of the machined material on the vertical line through (x, y),
    /// cut exactly by every move's pieces (not read from the dexels);
    /// the stock bottom where the tool went through; `None` outside the
    /// stock. Builds the sweeps of the moves near the point: for many
    /// points, [`Simulation::tops_at`] builds them once a bin.
    pub fn top_at(&self, x: f64, y: f64) -> Option<f64> {
        self.tops_at(&[(x, y)])[0]
    }

    /// [`Simulation::top_at`] at every point, bit for bit: the points are
    /// taken a bin of the plan view at a time (in parallel), the sweeps
    /// of the bin's moves built once for all its points. Advances the
    /// progress counter by each bin's points (points outside the stock
    /// are not counted).
    pub fn tops_at(&self, points: &[(f64, f64)]) -> Vec<Option<f64>> {
        let (min, max) = (self.dexels.min, self.dexels.max);
        let inside = |&(x, y): &(f64, f64)| x >= min.x && x <= max.x && y >= min.y && y <= max.y;
        // Points by bin (a counting sort, points in order within a bin).
        let ix = &self.index;
        let n_bins = ix.nx * ix.ny;
        let bin_of: Vec<usize> = points
            .iter()
            .map(|p| if inside(p) { ix.bin(p.0, p.1) } else { n_bins })
            .collect();
        let mut start = vec![0usize; n_bins + 2];
        for &b in &bin_of {
            start[b + 1] += 1;
        }
        for b in 0..=n_bins {
            start[b + 1] += start[b];
        }
        let mut fill = start.clone();
        let mut order = vec![0usize; points.len()];
        for (k, &b) in bin_of.iter().enumerate() {
            order[fill[b]] = k;
            fill[b] += 1;
        }
        let answers: Vec<(usize, f64)> = (0..n_bins)
            .into_par_iter()
            .filter(|&b| start[b + 1] > start[b])
            .flat_map_iter(|b| {
                let mine = &order[start[b]..start[b + 1]];
                // The bin's moves whose box reaches one of its points, in
                // order, built once.
                let (mut x0, mut x1, mut y0, mut y1) =
                    (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
                for &k in mine {
                    let (x, y) = points[k];
                    (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
                }
                let moves: Vec<MoveSweep> = ix.bins[b]
                    .iter()
                    .map(|&m| m as usize)
                    .filter(|&m| {
                        let (lo, hi) = &self.boxes[m];
                        !(x1 < lo[0] || x0 > hi[0] || y1 < lo[1] || y0 > hi[1])
                    })
                    .map(|m| sweep_of(&self.job, m))
                    .collect();
                let mut scratch = Vec::new();
                let mut ivs = Vec::new();
                crate::progress::advance(mine.len() as u64);
                mine.iter()
                    .map(|&k| {
                        let (x, y) = points[k];
                        let o = P3::new(x, y, 0.0);
                        ivs.clear();
                        ivs.push([min.z, max.z]);
                        for s in &moves {
                            if x < s.lo[0] || x > s.hi[0] || y < s.lo[1] || y > s.hi[1] {
                                continue;
                            }
                            s.remove_from(&o, &V3::z(), &mut Intervals(&mut ivs), &mut scratch);
                        }
                        (k, ivs.last().map_or(min.z, |v| v[1]))
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let mut out = vec![None; points.len()];
        for (k, z) in answers {
            out[k] = Some(z);
        }
        out
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

    /// A torus raster with a turning axis at its ends: moves of one
    /// sub-move and of many, a ring of balls, boxes over several bins.
    fn raster_job() -> VerifyJob {
        let mut locations = Vec::new();
        for row in 0..6 {
            let y = 1.0 + 1.5 * row as f64;
            for k in 0..12 {
                let x = if row % 2 == 0 {
                    1.0 + 0.7 * k as f64
                } else {
                    8.7 - 0.7 * k as f64
                };
                let z = -0.4 - 0.05 * ((x * 1.3).sin() + (y * 0.7).cos());
                let tilt = if k < 2 { 0.3 * (2 - k) as f64 } else { 0.0 };
                locations.push(Location {
                    tip: P3::new(x, y, z),
                    axis: V3::new(tilt, 0.5 * tilt, 1.0).normalize(),
                });
            }
        }
        VerifyJob {
            stock_min: P3::new(0.0, 0.0, -2.0),
            stock_max: P3::new(10.0, 10.0, 0.0),
            tool: ToolShape {
                cutter: Cutter::Torus {
                    radius: 0.6,
                    corner: 0.2,
                },
                length: 4.0,
            },
            spacing: 0.08,
            sweep_tol: 0.01,
            ring_tol: Some(0.002),
            locations,
        }
    }

    #[test]
    fn runs_of_moves_cut_what_all_moves_at_once_cut() {
        let job = raster_job();
        let whole = simulate(&job).unwrap();
        // One move a run, and runs of a few moves.
        let one = simulate_in_runs(&job, 0).unwrap();
        let few = simulate_in_runs(&job, 3 * crate::dexel::prepared_bytes(&sweep_of(&job, 5))).unwrap();
        let all = sweeps(&job);
        assert_eq!(whole.sub_moves, all.iter().map(|s| s.substeps).sum::<usize>());
        assert!(whole.sub_moves > all.len(), "some moves turn the axis");
        let worst = all.iter().map(|s| s.shape_error_mm).fold(0.0, f64::max);
        assert_eq!(whole.shape_error_mm, worst);
        for sim in [&one, &few] {
            assert_eq!(sim.stats, whole.stats);
            assert_eq!(sim.dexels.volumes(), whole.dexels.volumes());
            assert!(sim.dexels.heights() == whole.dexels.heights());
            assert_eq!(
                (sim.sub_moves, sim.shape_error_mm),
                (whole.sub_moves, whole.shape_error_mm)
            );
        }
        assert!(whole.removed_volume() > 1.0);
    }

    #[test]
    fn tops_by_bin_are_every_moves_cut_point_by_point() {
        let job = raster_job();
        let sim = simulate(&job).unwrap();
        let all = sweeps(&job);
        // Points on and off the raster, on bin edges, outside the stock.
        let mut points: Vec<(f64, f64)> = Vec::new();
        for j in 0..=53 {
            for i in 0..=53 {
                points.push((-0.3 + 0.2 * i as f64, -0.3 + 0.2 * j as f64));
            }
        }
        points.push((10.0, 10.0));
        points.push((0.0, 5.0));
        let got = sim.tops_at(&points);
        let (min, max) = (job.stock_min, job.stock_max);
        let mut cut = 0;
        for (k, &(x, y)) in points.iter().enumerate() {
            let want = (x >= min.x && x <= max.x && y >= min.y && y <= max.y).then(|| {
                let mut ivs = vec![[min.z, max.z]];
                let mut scratch = Vec::new();
                for s in &all {
                    if x < s.lo[0] || x > s.hi[0] || y < s.lo[1] || y > s.hi[1] {
                        continue;
                    }
                    s.remove_from(&P3::new(x, y, 0.0), &V3::z(), &mut Intervals(&mut ivs), &mut scratch);
                }
                ivs.last().map_or(min.z, |v| v[1])
            });
            assert_eq!(got[k], want, "at ({x}, {y})");
            if want.is_some_and(|z| z < max.z) {
                cut += 1;
            }
        }
        assert!(cut > 500, "{cut} points cut");
        assert_eq!(sim.top_at(points[700].0, points[700].1), got[700]);
    }
}
