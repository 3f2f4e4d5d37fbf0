//! Tri-dexel stock: three families of parallel rays (along X, Y and Z),
//! each holding the intervals of material it crosses, cut by the volumes
//! tools sweep.
//!
//! A height field (gsim's stock) knows one top per column, so a tilted
//! tool's undercut or a steep wall is lost; three ray families keep them
//! (the multi-dexel stock of the verification literature that Singh 2014
//! reviews). Memory follows the dexels the tools touch: rays live in
//! 32 × 32 tiles allocated on first cut, and an untouched tile is the
//! stock's full interval without storage.
//!
//! Removal is exact per move: each dexel loses the interval where its ray
//! meets the swept volume ([`sweep`], solved with each family's fixed ray
//! direction worked in beforehand by [`axis`]), not a series of stamped
//! tools.
//! Moves are binned into tiles and the tiles cut in parallel with rayon;
//! removal commutes, so the result does not depend on the order.

#![warn(missing_docs)]

pub mod axis;
pub mod sweep;
pub mod tile;
pub mod tool;

use crate::geometry::P3;
use axis::AxisMove;
use rayon::prelude::*;
use thiserror::Error;
use tile::{TILE, Tile};
use tool::{LineMaterial, MoveSweep};

/// A stock that cannot be made.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum DexelError {
    /// The box is empty on some axis or has a non-finite corner.
    #[error("stock box must have min < max on every axis")]
    EmptyBox,
    /// The spacing is zero, negative or not finite.
    #[error("dexel spacing must be positive and finite")]
    BadSpacing,
    /// One family would hold more than 4·10⁹ rays (their count).
    #[error("{0} dexels in one family is too many; use a larger spacing")]
    TooMany(u64),
}

/// One family: rays along axis `dir`, laid out over the other two axes.
#[derive(Debug, Clone)]
pub struct Family {
    /// Axis the rays run along (0 = X, 1 = Y, 2 = Z).
    pub dir: usize,
    /// The first axis across the rays (the lower-numbered of the two).
    pub p: usize,
    /// The second axis across the rays.
    pub q: usize,
    /// Rays across axis `p`.
    pub np: usize,
    /// Rays across axis `q`.
    pub nq: usize,
    /// Spacing across axis `p`, mm (the box's side over `np`).
    pub hp: f64,
    /// Spacing across axis `q`, mm.
    pub hq: f64,
    p0: f64,
    q0: f64,
    /// Stock extent along the rays.
    lo: f64,
    hi: f64,
    tp: usize,
    tiles: Vec<Option<Box<Tile>>>,
}

/// Work done by a cut.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CutStats {
    /// Ray / whole-move tests.
    pub ray_tests: u64,
    /// Ray / sub-move tests (turning axes only).
    pub fine_tests: u64,
}

impl std::ops::Add for CutStats {
    type Output = CutStats;
    fn add(self, o: CutStats) -> CutStats {
        CutStats {
            ray_tests: self.ray_tests + o.ray_tests,
            fine_tests: self.fine_tests + o.fine_tests,
        }
    }
}

/// How many bytes of prepared pieces one family's cut holds at a time
/// (256 MiB: with 64 the dome sample's torus raster took 432 s against
/// 376, the last tiles of each batch running alone; docs/stlverify.md).
pub const PREPARED_BYTES: usize = 1 << 28;

/// Bytes a move's pieces take once prepared for one family's rays (what
/// [`PREPARED_BYTES`] bounds).
pub fn prepared_bytes(s: &MoveSweep) -> usize {
    let pieces = s.fine.len() + s.groups.len() + s.coarse.as_ref().map_or(0, Vec::len);
    pieces * std::mem::size_of::<axis::AxisPiece>() + std::mem::size_of::<AxisMove>()
}

/// The moves cut together: consecutive runs whose prepared pieces take at
/// most `budget` bytes (a single move may take more), in order.
fn prepare_batches(sweeps: &[MoveSweep], budget: usize) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let (mut start, mut bytes) = (0, 0);
    for (k, s) in sweeps.iter().enumerate() {
        let b = prepared_bytes(s);
        if k > start && bytes + b > budget {
            out.push(start..k);
            (start, bytes) = (k, 0);
        }
        bytes += b;
    }
    if start < sweeps.len() {
        out.push(start..sweeps.len());
    }
    out
}

impl Family {
    fn new(dir: usize, min: &P3, max: &P3, h: f64) -> Result<Family, DexelError> {
        let (p, q) = match dir {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        let n = |k: usize| ((max[k] - min[k]) / h).round().max(1.0) as usize;
        let (np, nq) = (n(p), n(q));
        let total = np as u64 * nq as u64;
        if total > 4_000_000_000 {
            return Err(DexelError::TooMany(total));
        }
        let (tp, tq) = (np.div_ceil(TILE), nq.div_ceil(TILE));
        let tiles = vec![None; tp * tq];
        Ok(Family {
            dir,
            p,
            q,
            np,
            nq,
            hp: (max[p] - min[p]) / np as f64,
            hq: (max[q] - min[q]) / nq as f64,
            p0: min[p],
            q0: min[q],
            lo: min[dir],
            hi: max[dir],
            tp,
            tiles,
        })
    }

    /// Across-coordinates of ray (i, j).
    pub fn ray_pos(&self, i: usize, j: usize) -> (f64, f64) {
        (
            self.p0 + (i as f64 + 0.5) * self.hp,
            self.q0 + (j as f64 + 0.5) * self.hq,
        )
    }

    /// The material intervals of ray (i, j) (absolute coordinates along the
    /// ray), in order.
    pub fn intervals(&self, i: usize, j: usize) -> Vec<[f64; 2]> {
        let t = (j / TILE) * self.tp + i / TILE;
        match &self.tiles[t] {
            None => vec![[self.lo, self.hi]],
            Some(tile) => tile
                .intervals((j % TILE) * TILE + i % TILE)
                .iter()
                .map(|iv| [iv[0] as f64, iv[1] as f64])
                .collect(),
        }
    }

    /// Ray index range `[a, b)` across axis with origin `o`, spacing `h`,
    /// count `n` whose centres lie in `[lo, hi]`.
    fn range(o: f64, h: f64, n: usize, lo: f64, hi: f64) -> (usize, usize) {
        let a = ((lo - o) / h - 0.5).ceil().max(0.0);
        let b = ((hi - o) / h - 0.5).floor() + 1.0;
        let b = b.min(n as f64);
        if a < b { (a as usize, b as usize) } else { (0, 0) }
    }

    /// Cut `sweeps`, their pieces prepared at most `budget` bytes at a
    /// time.
    fn cut(&mut self, sweeps: &[MoveSweep], budget: usize) -> CutStats {
        let mut bins: Vec<Vec<u32>> = vec![Vec::new(); self.tiles.len()];
        for (k, s) in sweeps.iter().enumerate() {
            if s.hi[self.dir] < self.lo || s.lo[self.dir] > self.hi {
                continue;
            }
            let (i0, i1) = Self::range(self.p0, self.hp, self.np, s.lo[self.p], s.hi[self.p]);
            let (j0, j1) = Self::range(self.q0, self.hq, self.nq, s.lo[self.q], s.hi[self.q]);
            if i0 >= i1 || j0 >= j1 {
                continue;
            }
            for tj in j0 / TILE..=(j1 - 1) / TILE {
                for ti in i0 / TILE..=(i1 - 1) / TILE {
                    bins[tj * self.tp + ti].push(k as u32);
                }
            }
        }
        // Progress in (tile, move) pairs: the unit of work below.
        crate::progress::add_total(bins.iter().map(|b| b.len() as u64).sum());
        // The moves' pieces prepared for this family's ray direction, a
        // batch at a time: a prepared piece is some 600 bytes, and a torus
        // move has a ring of a hundred balls, so all 80,801 moves of a
        // torus raster over the dome sample took 10.7 GB at once. Each
        // tile still meets its moves in drawing order (batch after batch),
        // so the material and the counts are those of one pass.
        let mut tiles = std::mem::take(&mut self.tiles);
        let fam = &*self;
        let (lo, hi) = (self.lo as f32, self.hi as f32);
        let mut stats = CutStats::default();
        for batch in prepare_batches(sweeps, budget) {
            let prepared: Vec<AxisMove> = sweeps[batch.clone()]
                .par_iter()
                .map(|s| AxisMove::new(s, self.dir))
                .collect();
            stats = stats
                + tiles
                    .par_iter_mut()
                    .zip(bins.par_iter())
                    .enumerate()
                    .map(|(t, (slot, bin))| {
                        // A bin lists its moves in increasing order.
                        let a = bin.partition_point(|&k| (k as usize) < batch.start);
                        let b = a + bin[a..].partition_point(|&k| (k as usize) < batch.end);
                        if a == b {
                            return CutStats::default();
                        }
                        let tile = slot.get_or_insert_with(|| Box::new(Tile::full(lo, hi)));
                        let st = fam.cut_tile(t, tile, &bin[a..b], sweeps, &prepared, batch.start);
                        crate::progress::advance((b - a) as u64);
                        st
                    })
                    .reduce(CutStats::default, |a, b| a + b);
        }
        self.tiles = tiles;
        stats
    }

    fn cut_tile(
        &self,
        t: usize,
        tile: &mut Tile,
        bin: &[u32],
        sweeps: &[MoveSweep],
        prepared: &[AxisMove],
        first: usize,
    ) -> CutStats {
        let (ti, tj) = (t % self.tp, t / self.tp);
        let mut st = CutStats::default();
        let mut scratch = Vec::new();
        for &k in bin {
            let (s, sp) = (&sweeps[k as usize], &prepared[k as usize - first]);
            let (i0, i1) = Self::range(self.p0, self.hp, self.np, s.lo[self.p], s.hi[self.p]);
            let (j0, j1) = Self::range(self.q0, self.hq, self.nq, s.lo[self.q], s.hi[self.q]);
            let (i0, i1) = (i0.max(ti * TILE), i1.min((ti + 1) * TILE));
            let (j0, j1) = (j0.max(tj * TILE), j1.min((tj + 1) * TILE));
            for j in j0..j1 {
                for i in i0..i1 {
                    let (pp, qq) = self.ray_pos(i, j);
                    st.ray_tests += 1;
                    let kk = (j % TILE) * TILE + i % TILE;
                    let mut m = TileRay { tile, k: kk };
                    st.fine_tests += sp.remove_from(pp, qq, &mut m, &mut scratch);
                }
            }
        }
        st
    }

    /// Material along all rays times the cross-section per ray, mm³.
    fn volume(&self) -> f64 {
        let full = (self.hi - self.lo) * (self.np * self.nq) as f64;
        let mut delta = 0.0;
        for (t, slot) in self.tiles.iter().enumerate() {
            let Some(tile) = slot else { continue };
            let (ti, tj) = (t % self.tp, t / self.tp);
            for j in tj * TILE..((tj + 1) * TILE).min(self.nq) {
                for i in ti * TILE..((ti + 1) * TILE).min(self.np) {
                    let m: f64 = tile
                        .intervals((j % TILE) * TILE + i % TILE)
                        .iter()
                        .map(|iv| (iv[1] - iv[0]) as f64)
                        .sum();
                    delta += m - (self.hi - self.lo);
                }
            }
        }
        (full + delta) * self.hp * self.hq
    }

    fn bytes(&self) -> usize {
        self.tiles.len() * 8 + self.tiles.iter().flatten().map(|t| t.bytes()).sum::<usize>()
    }
}

/// One dexel of a tile, as the line a move cuts.
struct TileRay<'a> {
    tile: &'a mut Tile,
    k: usize,
}

impl LineMaterial for TileRay<'_> {
    fn has(&self, t0: f64, t1: f64) -> bool {
        self.tile.has_material(self.k, t0, t1)
    }
    fn remove(&mut self, t0: f64, t1: f64) {
        self.tile.subtract(self.k, t0, t1);
    }
}

/// A box of stock as three dexel families.
#[derive(Debug, Clone)]
pub struct TriDexel {
    /// The stock box's low corner, mm.
    pub min: P3,
    /// The stock box's high corner, mm; above `min` on every axis.
    pub max: P3,
    /// Requested dexel spacing, mm (each axis divides its length evenly,
    /// so the actual spacing may differ by a fraction of it).
    pub spacing: f64,
    /// Families along X, Y and Z.
    pub families: [Family; 3],
}

/// The Z family's tops as a height grid (cell centres).
#[derive(Debug, Clone, PartialEq)]
pub struct HeightGrid {
    /// The grid's low X edge (the stock box's), mm.
    pub x0: f64,
    /// The grid's low Y edge, mm.
    pub y0: f64,
    /// Cell width along X, mm.
    pub dx: f64,
    /// Cell width along Y, mm.
    pub dy: f64,
    /// Cells along X.
    pub nx: usize,
    /// Cells along Y.
    pub ny: usize,
    /// Heights, row-major (`j * nx + i`), at `(x0 + (i + ½)·dx, y0 + (j + ½)·dy)`.
    pub z: Vec<f64>,
    /// The stock's bottom, mm: the height of a ray cut through.
    pub bottom: f64,
}

impl TriDexel {
    /// A full box of stock with rays `spacing` apart.
    pub fn new(min: P3, max: P3, spacing: f64) -> Result<TriDexel, DexelError> {
        if !(0..3).all(|k| min[k].is_finite() && max[k].is_finite() && min[k] < max[k]) {
            return Err(DexelError::EmptyBox);
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(DexelError::BadSpacing);
        }
        Ok(TriDexel {
            min,
            max,
            spacing,
            families: [
                Family::new(0, &min, &max, spacing)?,
                Family::new(1, &min, &max, spacing)?,
                Family::new(2, &min, &max, spacing)?,
            ],
        })
    }

    /// Remove every move's swept volume.
    pub fn cut(&mut self, sweeps: &[MoveSweep]) -> CutStats {
        self.cut_in_batches(sweeps, PREPARED_BYTES)
    }

    /// Remove every move's swept volume, preparing each family's pieces
    /// at most `budget` bytes at a time (a single move may take more; 0 is
    /// one move a batch). The material left does not depend on `budget`:
    /// each tile meets its moves in the same order, batch after batch.
    /// [`TriDexel::cut`] takes 256 MiB.
    pub fn cut_in_batches(&mut self, sweeps: &[MoveSweep], budget: usize) -> CutStats {
        let mut st = CutStats::default();
        for f in self.families.iter_mut() {
            st = st + f.cut(sweeps, budget);
        }
        st
    }

    /// Remaining volume by each family (X, Y, Z), mm³; they agree to the
    /// resolution.
    pub fn volumes(&self) -> [f64; 3] {
        [
            self.families[0].volume(),
            self.families[1].volume(),
            self.families[2].volume(),
        ]
    }

    /// Volume of the stock box, mm³.
    pub fn box_volume(&self) -> f64 {
        (self.max - self.min).iter().product()
    }

    /// Bytes of dexel storage.
    pub fn bytes(&self) -> usize {
        self.families.iter().map(|f| f.bytes()).sum()
    }

    /// Dexels in all families.
    pub fn dexel_count(&self) -> u64 {
        self.families.iter().map(|f| (f.np * f.nq) as u64).sum()
    }

    /// Top of the material along each Z ray (the stock bottom where a ray
    /// was cut through).
    pub fn heights(&self) -> HeightGrid {
        let f = &self.families[2];
        let mut z = vec![self.max.z; f.np * f.nq];
        for (t, slot) in f.tiles.iter().enumerate() {
            let Some(tile) = slot else { continue };
            let (ti, tj) = (t % f.tp, t / f.tp);
            for j in tj * TILE..((tj + 1) * TILE).min(f.nq) {
                for i in ti * TILE..((ti + 1) * TILE).min(f.np) {
                    let iv = tile.intervals((j % TILE) * TILE + i % TILE);
                    z[j * f.np + i] = iv.last().map_or(self.min.z, |v| v[1] as f64);
                }
            }
        }
        HeightGrid {
            x0: self.min.x,
            y0: self.min.y,
            dx: f.hp,
            dy: f.hq,
            nx: f.np,
            ny: f.nq,
            z,
            bottom: self.min.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;
    use crate::geometry::V3;
    use tool::{Location, ToolShape};

    /// Every ray's material in every family.
    fn all_intervals(d: &TriDexel) -> Vec<Vec<[f64; 2]>> {
        d.families
            .iter()
            .flat_map(|f| (0..f.nq).flat_map(move |j| (0..f.np).map(move |i| f.intervals(i, j))))
            .collect()
    }

    #[test]
    fn moves_cut_in_batches_leave_what_one_pass_leaves() {
        // A torus (a ring of balls a move) on a zigzag whose axis turns
        // (sub-moves, groups), cut with every move prepared at once, one
        // move a batch, and batches of a few moves.
        let tool = ToolShape {
            cutter: Cutter::Torus {
                radius: 0.5,
                corner: 0.2,
            },
            length: 3.0,
        };
        let locs: Vec<Location> = (0..36)
            .map(|k| {
                let (row, col) = (k / 12, k % 12);
                let x = if row % 2 == 0 { col } else { 11 - col } as f64 * 0.3 - 1.6;
                let tilt = 0.05 * ((k as f64) * 0.7).sin();
                Location {
                    tip: P3::new(x, row as f64 * 0.35 - 0.7, -0.3 - 0.05 * row as f64),
                    axis: V3::new(tilt.sin(), 0.0, tilt.cos()),
                }
            })
            .collect();
        let sweeps: Vec<MoveSweep> = std::iter::once((0, 0))
            .chain((1..locs.len()).map(|k| (k - 1, k)))
            .map(|(a, b)| MoveSweep::new(&tool, &locs[a], &locs[b], 0.02))
            .collect();
        assert!(sweeps.iter().any(|s| s.substeps > 1), "some axis must turn");
        let cut = |budget: usize| {
            let mut d = TriDexel::new(P3::new(-2.5, -1.5, -1.5), P3::new(2.5, 1.5, 0.0), 0.05).unwrap();
            let st = d.cut_in_batches(&sweeps, budget);
            (st, all_intervals(&d), d.volumes())
        };
        let one_pass = cut(usize::MAX);
        let move_size = prepare_batches(&sweeps[1..2], usize::MAX).len();
        assert_eq!(move_size, 1);
        assert_eq!(prepare_batches(&sweeps, 0).len(), sweeps.len());
        let few = std::mem::size_of::<axis::AxisPiece>() * sweeps[1].fine.len() * 5;
        assert!(prepare_batches(&sweeps, few).len() > 5);
        for budget in [0, few] {
            let batched = cut(budget);
            assert_eq!(batched.0, one_pass.0, "budget {budget}");
            assert_eq!(batched.2, one_pass.2, "budget {budget}");
            assert!(batched.1 == one_pass.1, "budget {budget}: the material differs");
        }
        // Something was cut.
        assert!(one_pass.2[2] < 5.0 * 3.0 * 1.5 - 0.5);
    }

    #[test]
    fn prepare_batches_cover_the_moves_in_order_within_the_budget() {
        let tool = ToolShape {
            cutter: Cutter::Torus {
                radius: 0.5,
                corner: 0.2,
            },
            length: 3.0,
        };
        let at = |x: f64| Location {
            tip: P3::new(x, 0.0, 0.0),
            axis: V3::z(),
        };
        let sweeps: Vec<MoveSweep> = (0..10)
            .map(|k| MoveSweep::new(&tool, &at(k as f64), &at(k as f64 + 1.0), 0.01))
            .collect();
        let per = std::mem::size_of::<axis::AxisPiece>() * sweeps[0].fine.len() + std::mem::size_of::<AxisMove>();
        assert!(sweeps.iter().all(|s| s.coarse.is_none() && s.groups.is_empty()));
        for (budget, want) in [
            (usize::MAX, std::iter::once(0..10).collect()),
            (3 * per, vec![0..3, 3..6, 6..9, 9..10]),
            (per - 1, (0..10).map(|k| k..k + 1).collect()),
        ] {
            assert_eq!(prepare_batches(&sweeps, budget), want, "budget {budget}");
        }
        assert!(prepare_batches(&[], 1).is_empty());
    }

    #[test]
    fn straight_slot_removes_the_stadium_volume_in_every_family() {
        let mut d = TriDexel::new(P3::new(0.0, 0.0, -4.0), P3::new(20.0, 10.0, 0.0), 0.05).unwrap();
        let tool = ToolShape {
            cutter: Cutter::Flat { radius: 2.0 },
            length: 10.0,
        };
        let a = Location {
            tip: P3::new(5.0, 5.0, -1.0),
            axis: V3::z(),
        };
        let b = Location {
            tip: P3::new(15.0, 5.0, -1.0),
            axis: V3::z(),
        };
        let s = MoveSweep::new(&tool, &a, &b, 0.01);
        d.cut(&[s]);
        let removed = (10.0 * 4.0 + std::f64::consts::PI * 4.0) * 1.0;
        for v in d.volumes() {
            let got = d.box_volume() - v;
            assert!((got - removed).abs() < 0.01 * removed, "{got} vs {removed}");
        }
        let h = d.heights();
        assert_eq!(h.z[h.nx * 100 + 200], -1.0);
        assert_eq!(h.z[0], 0.0);
        assert!(d.bytes() < 3 * 8 * 400 * 200);
    }

    #[test]
    fn tilted_tool_leaves_an_undercut_the_x_family_sees() {
        // A flat tool tilted 45° about Y, pushed in along Y below the top:
        // a Z ray above the cut keeps material on both sides.
        let mut d = TriDexel::new(P3::new(-5.0, -5.0, -5.0), P3::new(5.0, 5.0, 0.0), 0.1).unwrap();
        let tool = ToolShape {
            cutter: Cutter::Flat { radius: 0.5 },
            length: 3.0,
        };
        let axis = V3::new(1.0, 0.0, 1.0).normalize();
        let a = Location {
            tip: P3::new(-1.0, -6.0, -3.0),
            axis,
        };
        let b = Location {
            tip: P3::new(-1.0, 6.0, -3.0),
            axis,
        };
        d.cut(&[MoveSweep::new(&tool, &a, &b, 0.01)]);
        let z = &d.families[2];
        let (i, j) = (((0.0 - -5.0) / z.hp) as usize, 50);
        let iv = z.intervals(i, j);
        assert!(iv.len() >= 2, "{iv:?}");
        assert_eq!(iv.last().unwrap()[1], 0.0);
    }
}
