//! Material removal on a height-field stock: a grid of columns over XY,
//! each holding the height of the top of the material, cut by flat, ball
//! and torus end mills moving along the path.
//!
//! A cell is lowered to the lowest height the cutter's underside reaches
//! over its centre during a move. For a move at constant height that is
//! exact: the underside at horizontal distance ρ from the tool axis is
//! `z + h(ρ)`, and over a straight move ρ is smallest at the point of the
//! move nearest the cell. For moves that change height the underside over
//! a cell is a convex function of the position along the move, minimised by
//! golden-section search (exact to 1e-10 of the move). Arcs are cut into
//! chords whose sagitta stays under a tenth of a cell. Rows are processed
//! in parallel with rayon.
//!
//! The cutter's shape lives in [`crate::cutter`]; STL export is in
//! `sim::stl`, pictures in `sim::picture`.

use crate::cutter::Cutter;
use crate::geometry::arc::chord_angle;
use crate::geometry::{Arc3, P3};
use rayon::prelude::*;
use thiserror::Error;

/// A stock box that cannot make a height field.
#[derive(Debug, Error, PartialEq)]
pub enum StockError {
    /// The cell is not positive, the box is empty or not finite, or it
    /// would take more than 400 million cells; the text says which.
    #[error("stock box {0}")]
    Box(String),
}

/// Height-field stock over `[x0, x0 + nx·cell] × [y0, y0 + ny·cell]`.
#[derive(Debug, Clone)]
pub struct Stock {
    /// X of the grid's low edge, mm; cell `i` is centred on
    /// `x0 + (i + 0.5)·cell`.
    pub x0: f64,
    /// Y of the grid's low edge, mm; row `j` is centred on
    /// `y0 + (j + 0.5)·cell`.
    pub y0: f64,
    /// Side of a square cell, mm (> 0).
    pub cell: f64,
    /// Cells along X (>= 1).
    pub nx: usize,
    /// Rows along Y (>= 1).
    pub ny: usize,
    /// Z of the stock's bottom, mm: a cell cut lower holds no material.
    pub bottom: f64,
    /// Z of the stock's top before cutting, mm.
    pub top: f64,
    /// Row-major heights of each cell's material top, mm (`ny` rows of
    /// `nx` cells); never above `top`.
    pub z: Vec<f64>,
    /// Cells examined by the cuts so far (the work done, for benchmarks).
    pub cells_visited: u64,
}

/// Below this many cells a move runs on one thread: spawning costs more.
const PAR_CELLS: usize = 1 << 14;

impl Stock {
    /// Uncut stock filling the box `min`..`max` (mm) with cells of `cell`
    /// mm; the box's X and Y sizes are rounded to whole cells.
    pub fn new(min: P3, max: P3, cell: f64) -> Result<Stock, StockError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(StockError::Box(format!("cell {cell} mm is not positive")));
        }
        let size = max - min;
        if !(size.x > 0.0 && size.y > 0.0 && size.z > 0.0 && size.iter().all(|v| v.is_finite())) {
            return Err(StockError::Box("needs min < max on every axis".into()));
        }
        let nx = (size.x / cell).round().max(1.0) as usize;
        let ny = (size.y / cell).round().max(1.0) as usize;
        if nx.saturating_mul(ny) > 400_000_000 {
            return Err(StockError::Box(format!(
                "{nx} x {ny} cells is too many; use a larger cell"
            )));
        }
        Ok(Stock {
            x0: min.x,
            y0: min.y,
            cell,
            nx,
            ny,
            bottom: min.z,
            top: max.z,
            z: vec![max.z; nx * ny],
            cells_visited: 0,
        })
    }

    /// Material volume left, mm³.
    pub fn volume(&self) -> f64 {
        self.z.iter().map(|z| (z - self.bottom).max(0.0)).sum::<f64>() * self.cell * self.cell
    }

    /// Cut a straight move of the tool tip from `a` to `b`; returns the
    /// volume removed (mm³).
    pub fn cut_line(&mut self, a: &P3, b: &P3, cutter: &Cutter) -> f64 {
        self.cut_lines(&[(*a, *b)], cutter)[0]
    }

    /// The cells a move's tool can touch: columns `i0..i1`, rows `j0..j1`,
    /// and whether the move is level. `None` when it misses the stock.
    fn reach(&self, a: &P3, b: &P3, r: f64) -> Option<Reach> {
        let (lo_x, hi_x) = (a.x.min(b.x) - r, a.x.max(b.x) + r);
        let (lo_y, hi_y) = (a.y.min(b.y) - r, a.y.max(b.y) + r);
        let c = self.cell;
        let i0 = (((lo_x - self.x0) / c - 0.5).floor().max(0.0)) as usize;
        let j0 = (((lo_y - self.y0) / c - 0.5).floor().max(0.0)) as usize;
        let i1 = ((((hi_x - self.x0) / c - 0.5).ceil() + 1.0).max(0.0) as usize).min(self.nx);
        let j1 = ((((hi_y - self.y0) / c - 0.5).ceil() + 1.0).max(0.0) as usize).min(self.ny);
        if i0 >= i1 || j0 >= j1 || a.z.min(b.z) >= self.top {
            return None;
        }
        Some(Reach {
            i0,
            i1,
            j0,
            j1,
            level: (a.z - b.z).abs() <= 1e-12,
        })
    }

    /// Cut straight moves in order; returns the volume each removed (mm³).
    ///
    /// Large batches run in parallel by bands of rows: each band applies
    /// every move, in order, to its own rows. A cell only ever sees the
    /// moves in program order, so the stock is the same as cutting one move
    /// after the other; volumes are summed band by band in a fixed order, so
    /// they do not depend on the number of threads.
    pub fn cut_lines(&mut self, pieces: &[(P3, P3)], cutter: &Cutter) -> Vec<f64> {
        let r = cutter.radius();
        let reach: Vec<Option<Reach>> = pieces.iter().map(|(a, b)| self.reach(a, b, r)).collect();
        let work: usize = reach.iter().flatten().map(|q| (q.i1 - q.i0) * (q.j1 - q.j0)).sum();
        let g = Grid {
            x0: self.x0,
            y0: self.y0,
            c: self.cell,
            bottom: self.bottom,
        };
        let nx = self.nx;
        let band_rows = BAND_ROWS.min(self.ny).max(1);
        let band = |bi: usize, zband: &mut [f64]| -> (Vec<f64>, u64) {
            let jb0 = bi * band_rows;
            let jb1 = jb0 + zband.len() / nx;
            let mut vols = vec![0.0; pieces.len()];
            let mut visited = 0;
            let mut cache = RowCache::default();
            for (k, ((a, b), q)) in pieces.iter().zip(&reach).enumerate() {
                let Some(q) = q else { continue };
                cache.clear();
                for j in q.j0.max(jb0)..q.j1.min(jb1) {
                    let zrow = &mut zband[(j - jb0) * nx..(j - jb0 + 1) * nx];
                    let (v, n) = cut_row(&g, a, b, cutter, q, j, zrow, &mut cache);
                    vols[k] += v;
                    visited += n;
                }
            }
            (vols, visited)
        };
        if work < PAR_CELLS {
            // Small batches: straight through, no per-band bookkeeping.
            let mut vols = Vec::with_capacity(pieces.len());
            let mut cache = RowCache::default();
            for ((a, b), q) in pieces.iter().zip(&reach) {
                let mut v = 0.0;
                cache.clear();
                if let Some(q) = q {
                    for j in q.j0..q.j1 {
                        let (dv, n) = cut_row(&g, a, b, cutter, q, j, &mut self.z[j * nx..(j + 1) * nx], &mut cache);
                        v += dv;
                        self.cells_visited += n;
                    }
                }
                vols.push(v * self.cell * self.cell);
            }
            return vols;
        }
        let parts: Vec<(Vec<f64>, u64)> = self
            .z
            .par_chunks_mut(nx * band_rows)
            .enumerate()
            .map(|(bi, zb)| band(bi, zb))
            .collect();
        let mut vols = vec![0.0; pieces.len()];
        for (v, n) in parts {
            for (acc, x) in vols.iter_mut().zip(v) {
                *acc += x;
            }
            self.cells_visited += n;
        }
        let area = self.cell * self.cell;
        vols.iter_mut().for_each(|v| *v *= area);
        vols
    }

    /// Cut an arc as chords whose sagitta stays under a tenth of a cell.
    pub fn cut_arc(&mut self, arc: &Arc3, cutter: &Cutter) -> f64 {
        let pieces = self.arc_chords(arc);
        self.cut_lines(&pieces, cutter).iter().sum()
    }

    /// The chords [`Self::cut_arc`] cuts.
    pub fn arc_chords(&self, arc: &Arc3) -> Vec<(P3, P3)> {
        let r = arc.radius().max(1e-12);
        let sag = 0.1 * self.cell;
        let dphi = if sag >= r {
            std::f64::consts::FRAC_PI_2
        } else {
            chord_angle(r, sag)
        };
        let n = ((arc.sweep().abs() / dphi).ceil() as usize).clamp(1, 1 << 20);
        let mut pieces = Vec::with_capacity(n);
        let mut prev = arc.start;
        for k in 1..=n {
            let p = arc.point_at(k as f64 / n as f64);
            pieces.push((prev, p));
            prev = p;
        }
        pieces
    }
}

/// Lowest height the underside of `cutter` reaches over (px, py) while the
/// tip moves from `a` to `b` (changing height), or `None` if the tool never
/// covers the point. The tool covers it for t in an interval (a quadratic
/// in t); there the underside height `z(t) + h(ρ(t))` is convex for all
/// three cutters (ρ(t) is the norm of an affine map, h is convex and
/// non-decreasing in ρ, z is linear), so a golden-section search finds the
/// minimum.
fn lowest_on_move(px: f64, py: f64, a: &P3, b: &P3, cutter: &Cutter) -> Option<f64> {
    let r = cutter.radius();
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let (wx, wy) = (px - a.x, py - a.y);
    let aa = dx * dx + dy * dy;
    let bb = wx * dx + wy * dy;
    let cc = wx * wx + wy * wy;
    let (t0, t1) = if aa <= 0.0 {
        // A plunge: the tool covers the point all along or never.
        if cc > r * r {
            return None;
        }
        (0.0, 1.0)
    } else {
        let disc = bb * bb - aa * (cc - r * r);
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        (((bb - s) / aa).max(0.0), ((bb + s) / aa).min(1.0))
    };
    if t0 > t1 {
        return None;
    }
    let g = |t: f64| -> f64 {
        let (qx, qy) = (a.x + dx * t, a.y + dy * t);
        let rho = ((px - qx).powi(2) + (py - qy).powi(2)).sqrt().min(r);
        a.z + (b.z - a.z) * t + cutter.profile(rho).unwrap_or(0.0)
    };
    const INV_PHI: f64 = 0.618_033_988_749_895;
    let (mut lo, mut hi) = (t0, t1);
    let mut x1 = hi - INV_PHI * (hi - lo);
    let mut x2 = lo + INV_PHI * (hi - lo);
    let (mut f1, mut f2) = (g(x1), g(x2));
    // 0.618^48 < 1e-10 of the interval: far below any cell.
    for _ in 0..48 {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - INV_PHI * (hi - lo);
            f1 = g(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + INV_PHI * (hi - lo);
            f2 = g(x2);
        }
    }
    Some(g(t0).min(g(t1)).min(f1).min(f2))
}

/// Rows per band when a batch is cut in parallel.
const BAND_ROWS: usize = 32;

/// The cells a move can touch (see [`Stock::cut_lines`]).
#[derive(Debug, Clone, Copy)]
struct Reach {
    i0: usize,
    i1: usize,
    j0: usize,
    j1: usize,
    level: bool,
}

/// Grid placement, copied out so bands can borrow rows mutably.
struct Grid {
    x0: f64,
    y0: f64,
    c: f64,
    bottom: f64,
}

/// Cut one row `j` with the move a-b; returns the height removed (sum over
/// cells, mm) and the cells examined.
///
/// On x86-64 processors with AVX2 the same code runs compiled for AVX2
/// (four lanes instead of SSE2's two): the ball's and torus' heights beside
/// a slanted pass take one square root per cell, and `vsqrtpd` on four
/// lanes is what lifts them towards the flat tool's rate. The answers are
/// bit for bit the same: square roots, min and max are exact in both, and
/// Rust never fuses a multiply and an add into an FMA on its own.
#[allow(clippy::too_many_arguments)]
#[inline]
fn cut_row(
    g: &Grid,
    a: &P3,
    b: &P3,
    cutter: &Cutter,
    q: &Reach,
    j: usize,
    zrow: &mut [f64],
    cache: &mut RowCache,
) -> (f64, u64) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has just been found to support AVX2, the
        // only requirement of `cut_row_avx2`.
        return unsafe { cut_row_avx2(g, a, b, cutter, q, j, zrow, cache) };
    }
    cut_row_body(g, a, b, cutter, q, j, zrow, cache)
}

/// [`cut_row`] compiled for AVX2 (see there).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
fn cut_row_avx2(
    g: &Grid,
    a: &P3,
    b: &P3,
    cutter: &Cutter,
    q: &Reach,
    j: usize,
    zrow: &mut [f64],
    cache: &mut RowCache,
) -> (f64, u64) {
    cut_row_body(g, a, b, cutter, q, j, zrow, cache)
}

/// The body of [`cut_row`], inlined into each build of it.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn cut_row_body(
    g: &Grid,
    a: &P3,
    b: &P3,
    cutter: &Cutter,
    q: &Reach,
    j: usize,
    zrow: &mut [f64],
    cache: &mut RowCache,
) -> (f64, u64) {
    let (x0, c, r) = (g.x0, g.c, cutter.radius());
    let py = g.y0 + (j as f64 + 0.5) * c;
    let mut removed = 0.0;
    // A level move touches one run of cells per row: the row's chord
    // through the stadium (the move's XY segment grown by r).
    let (ia, ib) = if q.level {
        match stadium_chord(a, b, r, py) {
            Some((xl, xr)) => {
                // Both ends within the move's reach: on a stock a few
                // cells wide the chord's rounded start can pass the row's
                // end (the start index then lay beyond the slice).
                let ia = ((xl - x0) / c - 0.5).ceil().max(q.i0 as f64).min(q.i1 as f64) as usize;
                let ib = (((xr - x0) / c - 0.5).floor() + 1.0).clamp(0.0, q.i1 as f64) as usize;
                (ia, ib.max(ia))
            }
            None => (q.i0, q.i0),
        }
    } else {
        (q.i0, q.i1)
    };
    if q.level
        && let Cutter::Flat { .. } = cutter
    {
        // Flat bottom: one height for the whole run, a branch-free loop
        // the compiler vectorises.
        let h = a.z.max(g.bottom);
        for zc in &mut zrow[ia..ib] {
            let cut = (*zc - h).max(0.0);
            removed += cut;
            *zc -= cut;
        }
        return (removed, (ib - ia) as u64);
    }
    if q.level {
        // Ball and torus on a level move: the underside over a cell is a
        // function of its distance from the move's XY segment (see
        // `level_run`).
        let removed = match *cutter {
            Cutter::Ball { radius } => {
                let r2 = radius * radius;
                let p = Profile {
                    of_rho2: |rho2: f64| radius - (r2 - rho2).max(0.0).sqrt(),
                    of_d: |d: f64| radius - (r2 - d * d).max(0.0).sqrt(),
                    flat: 0.0,
                };
                level_run(g, a, b, py, &mut zrow[ia..ib], ia, &p, cache)
            }
            Cutter::Torus { radius, corner } => {
                let flat = radius - corner;
                let c2 = corner * corner;
                let p = Profile {
                    of_rho2: |rho2: f64| {
                        let u = (rho2.sqrt() - flat).max(0.0);
                        corner - (c2 - u * u).max(0.0).sqrt()
                    },
                    of_d: |d: f64| {
                        let u = (d.abs() - flat).max(0.0);
                        corner - (c2 - u * u).max(0.0).sqrt()
                    },
                    flat,
                };
                level_run(g, a, b, py, &mut zrow[ia..ib], ia, &p, cache)
            }
            Cutter::Flat { .. } => 0.0,
        };
        return (removed, (ib - ia) as u64);
    }
    for (i, zc) in zrow.iter_mut().enumerate().take(ib).skip(ia) {
        let px = x0 + (i as f64 + 0.5) * c;
        if let Some(h) = lowest_on_move(px, py, a, b, cutter) {
            let h = h.max(g.bottom);
            // Rounding in the move's height (a + (b - a)·1 is not always b)
            // must not count as a cut.
            if h < *zc - 1e-12 {
                removed += *zc - h;
                *zc = h;
            }
        }
    }
    (removed, (ib - ia) as u64)
}

/// A cutter's underside height above its tip, `h`, for a level move: as a
/// function of the squared distance ρ² from the tool axis (the end caps,
/// where the nearest point of the move is an end), and of the signed
/// distance `d` across the move (beside the segment, where ρ = |d| needs no
/// square root). Inside `|d| <= flat` the underside is the tip's plane.
struct Profile<F: Fn(f64) -> f64, G: Fn(f64) -> f64> {
    of_rho2: F,
    of_d: G,
    flat: f64,
}

/// Heights one move leaves beside its segment, kept across the rows of a
/// band: for a move along Y every row beside the segment gets the same
/// heights (the distance from the segment is the column's), so they are
/// computed once per move and band instead of once per cell.
#[derive(Default)]
struct RowCache {
    /// Column range the heights are for (empty: nothing cached).
    i0: usize,
    i1: usize,
    hz: Vec<f64>,
}

impl RowCache {
    fn clear(&mut self) {
        self.i0 = 0;
        self.i1 = 0;
        self.hz.clear();
    }
}

/// Lower the run of cells `zrun` (starting at column `i0`) of row `py` to
/// the underside `a.z + h` of a level move a-b; returns the height removed
/// (sum, mm). Every cell of the run lies in the move's stadium, so ρ ≤ R up
/// to rounding and `h` needs no test for "outside the tool".
///
/// The run splits into the cells whose nearest point of the segment is an
/// end (the caps: [`level_cells`], the distance to that end) and those
/// beside the segment, one span per row found from the segment's
/// direction. Beside the segment the distance is linear along the row, so
/// no square root gives it, and:
/// - a move along X has one height there (the flat tool's loop);
/// - a move along Y has the same heights in every row beside it: computed
///   once per move and band ([`RowCache`]) and applied like the flat
///   tool's;
/// - any other direction computes `h(d)` per cell (one square root for the
///   ball and the torus; none where the torus' flat bottom is, a span of
///   its own).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn level_run<F: Fn(f64) -> f64, G: Fn(f64) -> f64>(
    g: &Grid,
    a: &P3,
    b: &P3,
    py: f64,
    zrun: &mut [f64],
    i0: usize,
    p: &Profile<F, G>,
    cache: &mut RowCache,
) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let l2 = dx * dx + dy * dy;
    let n = zrun.len();
    if l2 <= 0.0 || n == 0 {
        return level_cells(g, a, b, py, zrun, i0, &p.of_rho2);
    }
    let wy = py - a.y;
    let c = g.c;
    let xs = g.x0 + 0.5 * c - a.x;
    let nf = n as f64;
    // Columns k (of the run) whose projection on the segment lies inside
    // it: 0 <= (wx·dx + wy·dy)/l2 <= 1, wx = xs + (i0 + k)·c.
    let (ka, kb) = if dx == 0.0 {
        let t = wy * dy / l2;
        if (0.0..=1.0).contains(&t) { (0, n) } else { (0, 0) }
    } else {
        let (e0, e1) = (-wy * dy / dx, (l2 - wy * dy) / dx);
        let (lo, hi) = (e0.min(e1), e0.max(e1));
        let ka = ((lo - xs) / c - i0 as f64).ceil().clamp(0.0, nf);
        let kb = (((hi - xs) / c - i0 as f64).floor() + 1.0).clamp(ka, nf);
        (ka as usize, kb as usize)
    };
    let (head, rest) = zrun.split_at_mut(ka);
    let (mid, tail) = rest.split_at_mut(kb - ka);
    let mut removed = level_cells(g, a, b, py, head, i0, &p.of_rho2);
    removed += level_tail(g, a, b, py, tail, i0 + kb, &p.of_rho2);
    let (z, bottom) = (a.z, g.bottom);
    if mid.is_empty() {
        return removed;
    }
    let l = l2.sqrt();
    if dy == 0.0 {
        // Along X: one distance, |wy|, beside the segment.
        let hz = (z + (p.of_d)(wy)).max(bottom);
        return removed + lower_to(mid, hz);
    }
    let mi0 = i0 + ka;
    if dx == 0.0 {
        // Along Y: the distance is the column's, the same in every row.
        let mi1 = mi0 + mid.len();
        if cache.i0 != mi0 || cache.i1 != mi1 || cache.hz.len() != mid.len() {
            cache.i0 = mi0;
            cache.i1 = mi1;
            cache.hz.clear();
            cache
                .hz
                .extend((mi0..mi1).map(|i| (z + (p.of_d)(xs + i as f64 * c)).max(bottom)));
        }
        return removed + lower_to_each(mid, &cache.hz);
    }
    // Any other direction: d = wx·dy/l - wy·dx/l, linear in the column.
    let (sy, wyx) = (dy / l, wy * dx / l);
    // The torus' flat bottom: |d| <= flat, a span of columns of its own.
    let (fa, fb) = if p.flat > 0.0 {
        let (e0, e1) = ((wyx - p.flat) / sy, (wyx + p.flat) / sy);
        let (lo, hi) = (e0.min(e1), e0.max(e1));
        let m = mid.len() as f64;
        let fa = ((lo - xs) / c - mi0 as f64).ceil().clamp(0.0, m);
        let fb = (((hi - xs) / c - mi0 as f64).floor() + 1.0).clamp(fa, m);
        (fa as usize, fb as usize)
    } else {
        (0, 0)
    };
    let (m0, rest) = mid.split_at_mut(fa);
    let (m1, m2) = rest.split_at_mut(fb - fa);
    removed += beside_cells(m0, mi0, xs, c, sy, wyx, z, bottom, &p.of_d);
    removed += lower_to(m1, (z + (p.of_d)(0.0)).max(bottom));
    removed + beside_cells(m2, mi0 + fb, xs, c, sy, wyx, z, bottom, &p.of_d)
}

/// The tail cap: [`level_cells`] (a separate name keeps both calls inlined
/// with their own code).
#[inline(always)]
fn level_tail(g: &Grid, a: &P3, b: &P3, py: f64, zrun: &mut [f64], i0: usize, h: &impl Fn(f64) -> f64) -> f64 {
    level_cells(g, a, b, py, zrun, i0, h)
}

/// Cells per block of the height loops below.
const BLOCK: usize = 32;

/// The column offsets within a block as floats, read from a table: no
/// integer conversion per cell (u64 → f64 has no SSE2 or AVX2 vector form)
/// and no float counter carried from cell to cell, either of which keeps a
/// loop from being vectorised. The same values as counting 0.0, 1.0, ...
const OFFSETS: [f64; BLOCK] = {
    let mut o = [0.0; BLOCK];
    let mut k = 0;
    while k < BLOCK {
        o[k] = k as f64;
        k += 1;
    }
    o
};

/// Lower every cell to `hz`; the height removed.
#[inline(always)]
fn lower_to(zrun: &mut [f64], hz: f64) -> f64 {
    let mut removed = 0.0;
    for zc in zrun.iter_mut() {
        let cut = (*zc - hz).max(0.0);
        removed += cut;
        *zc -= cut;
    }
    removed
}

/// Lower each cell to its own height; the height removed.
#[inline(always)]
fn lower_to_each(zrun: &mut [f64], hz: &[f64]) -> f64 {
    let mut removed = 0.0;
    for (zc, &h) in zrun.iter_mut().zip(hz) {
        // Rounding in the move's height must not count as a cut.
        let cut = if h < *zc - 1e-12 { *zc - h } else { 0.0 };
        removed += cut;
        *zc = if h < *zc - 1e-12 { h } else { *zc };
    }
    removed
}

/// Cells beside a segment that is neither along X nor along Y: signed
/// distance `d = wx·sy - wyx` across it (linear along the row: no square
/// root for ρ), heights `z + h(d)` computed in blocks (a loop without a
/// reduction, so the square root of the profile vectorises) and applied
/// like the flat tool's.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn beside_cells(
    zrun: &mut [f64],
    i0: usize,
    xs: f64,
    c: f64,
    sy: f64,
    wyx: f64,
    z: f64,
    bottom: f64,
    h: &impl Fn(f64) -> f64,
) -> f64 {
    let mut removed = 0.0;
    let mut buf = [0.0f64; BLOCK];
    let dd = c * sy;
    for (bi, block) in zrun.chunks_mut(BLOCK).enumerate() {
        let n = block.len();
        let d0 = (xs + (i0 + bi * BLOCK) as f64 * c) * sy - wyx;
        for (hv, &k) in buf[..n].iter_mut().zip(&OFFSETS[..n]) {
            *hv = (z + h(d0 + k * dd)).max(bottom);
        }
        removed += lower_to_each(block, &buf[..n]);
    }
    removed
}

/// [`level_run`]'s general case: every cell's own distance.
#[inline(always)]
fn level_cells(g: &Grid, a: &P3, b: &P3, py: f64, zrun: &mut [f64], i0: usize, h: &impl Fn(f64) -> f64) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let l2 = dx * dx + dy * dy;
    let inv = if l2 > 0.0 { 1.0 / l2 } else { 0.0 };
    let wy = py - a.y;
    let wyd = wy * dy;
    let (c, xs) = (g.c, g.x0 + 0.5 * g.c - a.x);
    let (z, bottom) = (a.z, g.bottom);
    let mut removed = 0.0;
    let mut buf = [0.0f64; BLOCK];
    for (bi, block) in zrun.chunks_mut(BLOCK).enumerate() {
        let base = (i0 + bi * BLOCK) as f64;
        let hb = &mut buf[..block.len()];
        for (hv, &k) in hb.iter_mut().zip(&OFFSETS) {
            // base + k: the same whole number as (i0 + bi·BLOCK + k) as f64.
            let wx = xs + (base + k) * c;
            let t = ((wx * dx + wyd) * inv).clamp(0.0, 1.0);
            let (ex, ey) = (wx - t * dx, wy - t * dy);
            *hv = (z + h(ex * ex + ey * ey)).max(bottom);
        }
        for (zc, &hz) in block.iter_mut().zip(hb.iter()) {
            // Rounding in the move's height must not count as a cut.
            let cut = if hz < *zc - 1e-12 { *zc - hz } else { 0.0 };
            removed += cut;
            *zc = if hz < *zc - 1e-12 { hz } else { *zc };
        }
    }
    removed
}

/// Where the horizontal line y = `py` crosses the stadium of the XY
/// segment a-b grown by `r` (the points within `r` of the segment): an
/// interval, since the stadium is convex; `None` if it misses.
fn stadium_chord(a: &P3, b: &P3, r: f64, py: f64) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    // The two end discs.
    for e in [a, b] {
        let dy = py - e.y;
        if dy.abs() <= r {
            let w = (r * r - dy * dy).sqrt();
            lo = lo.min(e.x - w);
            hi = hi.max(e.x + w);
        }
    }
    // The band of points whose projection falls inside the segment.
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let l = (dx * dx + dy * dy).sqrt();
    if l > 0.0 {
        let (ux, uy) = (dx / l, dy / l);
        let (nx, ny) = (-uy, ux);
        let wy = py - a.y;
        // Constraints linear in x: 0 <= (x-ax)·ux + wy·uy <= l and
        // -r <= (x-ax)·nx + wy·ny <= r.
        let mut blo = f64::NEG_INFINITY;
        let mut bhi = f64::INFINITY;
        let mut ok = true;
        for (k, c0, c1) in [(ux, -wy * uy, l - wy * uy), (nx, -r - wy * ny, r - wy * ny)] {
            if k.abs() < 1e-15 {
                ok &= c0 <= 0.0 && 0.0 <= c1;
            } else {
                let (p, q) = (c0 / k, c1 / k);
                blo = blo.max(p.min(q));
                bhi = bhi.min(p.max(q));
            }
        }
        if ok && blo <= bhi {
            lo = lo.min(a.x + blo);
            hi = hi.max(a.x + bhi);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests;
