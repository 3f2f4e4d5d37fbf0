//! Many rays in one direction: the verification tool's rays cast down on a
//! grid over a region (Singh 2014), and any other bundle of parallel rays.
//!
//! The triangles are projected along the direction onto a plane and binned
//! into a uniform 2-D grid of cells there; a ray is a point of that plane,
//! so its candidates are the triangles of one cell. Each cell lists its
//! triangles (their corners copied in, so a cell is one contiguous read)
//! ordered by how far along the direction they begin, and a first-hit
//! query stops at the first triangle that begins beyond the hit found so
//! far: one to three triangle tests per ray on a typical part, and no tree
//! to walk.
//!
//! The answers are those of [`Bvh::first_hit`](super::bvh::Bvh::first_hit)
//! exactly (the same watertight test, the same closed-triangle rule, the
//! same tie rule: of equal `t`, the lowest triangle index), so a caller may
//! use either; `tests` checks that they agree bit for bit.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::Mesh;
use super::bvh::{Edges, Hit, Ray, Shear, intersect};
use crate::geometry::{P3, V3};

/// One triangle in one cell.
#[derive(Debug, Clone, Copy)]
struct Item {
    /// Smallest `corner · dir` over the three corners (where along the
    /// direction the triangle begins).
    key: f64,
    /// Triangle index in the mesh.
    id: u32,
    tri: [P3; 3],
}

/// A 2-D grid over the projection of a mesh along one direction, for
/// first-hit queries of rays in that direction, one at a time
/// ([`ParallelRays::first_hit`]) or from the points of a lattice
/// ([`ParallelRays::first_hits_lattice`], which rasterises the triangles
/// instead and never builds the grid).
#[derive(Debug, Clone)]
pub struct ParallelRays {
    dir: V3,
    shear: Option<Shear>,
    e1: V3,
    e2: V3,
    /// The mesh's triangles as corners, in mesh order.
    tris: Vec<[P3; 3]>,
    /// Largest corner coordinate (absolute), the scale of rounding.
    scale: f64,
    /// `dir · dir`.
    dd: f64,
    /// Margin on the early stop, far above the rounding of `t`.
    slack: f64,
    /// The per-ray index, built on first use (lattice queries need none).
    cells: OnceLock<Cells>,
    /// The triangles (index, corners) in order along `e2`, the
    /// projection's second axis (for lattices: the triangles of a band of
    /// lattice rows lie together), built on first use.
    order: OnceLock<Vec<(u32, [P3; 3])>>,
}

/// The 2-D grid of cells, each listing its triangles.
#[derive(Debug, Clone)]
struct Cells {
    lo: [f64; 2],
    inv_cell: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<Item>,
}

/// Cells per triangle of the mesh (about two triangle references per cell
/// on a closed part: its top and its bottom).
const CELLS_PER_TRIANGLE: f64 = 1.0;
/// At most this many cells, whatever the mesh.
const MAX_CELLS: f64 = 16.0e6;

impl ParallelRays {
    /// Index `mesh` for rays along `dir` (need not be unit; hits' `t` are
    /// in its lengths, as for [`Ray`]). A zero or non-finite direction
    /// gives an index that hits nothing.
    pub fn new(mesh: &Mesh, dir: V3) -> ParallelRays {
        let shear = Shear::new(&dir);
        let (e1, e2) = basis(&dir);
        let tris: Vec<[P3; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                [
                    mesh.vertices[t[0] as usize],
                    mesh.vertices[t[1] as usize],
                    mesh.vertices[t[2] as usize],
                ]
            })
            .collect();
        let scale = tris
            .iter()
            .flat_map(|t| t.iter())
            .map(|p| p.coords.amax())
            .fold(0.0f64, f64::max);
        ParallelRays {
            dir,
            shear,
            e1,
            e2,
            tris,
            scale,
            dd: dir.norm_squared(),
            slack: 1e-9 * scale * dir.norm() * 4.0 + 1e-300,
            cells: OnceLock::new(),
            order: OnceLock::new(),
        }
    }

    /// The cell grid, built on first use.
    fn cells_index(&self) -> &Cells {
        self.cells.get_or_init(|| self.build_cells())
    }

    fn build_cells(&self) -> Cells {
        let (e1, e2, dir) = (self.e1, self.e2, self.dir);
        let tris = &self.tris;
        let mut out = Cells {
            lo: [0.0; 2],
            inv_cell: 0.0,
            nx: 0,
            ny: 0,
            start: vec![0],
            items: Vec::new(),
        };
        if tris.is_empty() || self.shear.is_none() {
            return out;
        }
        // Projected boxes, padded so rounding in the projection never
        // leaves a triangle out of a cell a ray in it could hit.
        let pad = 1e-9 * self.scale + 1e-300;
        let boxes: Vec<[f64; 4]> = tris
            .par_iter()
            .with_min_len(4096)
            .map(|t| {
                let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
                for p in t {
                    let (x, y) = (p.coords.dot(&e1), p.coords.dot(&e2));
                    b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
                }
                [b[0] - pad, b[1] - pad, b[2] + pad, b[3] + pad]
            })
            .collect();
        let mut all = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for b in &boxes {
            all = [all[0].min(b[0]), all[1].min(b[1]), all[2].max(b[2]), all[3].max(b[3])];
        }
        let (w, h) = (all[2] - all[0], all[3] - all[1]);
        if !(w.is_finite() && h.is_finite()) {
            return out;
        }
        let cells = (tris.len() as f64 * CELLS_PER_TRIANGLE).clamp(1.0, MAX_CELLS);
        let mut cell = ((w * h) / cells).sqrt();
        if cell.is_nan() || cell <= 0.0 || w.max(h) / cell > MAX_CELLS {
            // A projection with no area (every triangle edge-on): cells
            // along its length.
            cell = w.max(h).max(pad) / cells.min(1e6);
        }
        out.lo = [all[0], all[1]];
        out.inv_cell = 1.0 / cell;
        out.nx = ((w * out.inv_cell) as usize + 1).max(1);
        out.ny = ((h * out.inv_cell) as usize + 1).max(1);
        let range = |b: &[f64; 4]| {
            let f = |v: f64, lo: f64, n: usize| (((v - lo) * out.inv_cell) as usize).min(n - 1);
            (
                f(b[0], out.lo[0], out.nx),
                f(b[2], out.lo[0], out.nx),
                f(b[1], out.lo[1], out.ny),
                f(b[3], out.lo[1], out.ny),
            )
        };
        // Counting sort of (cell, triangle) references.
        let mut count = vec![0u32; out.nx * out.ny + 1];
        for b in &boxes {
            let (x0, x1, y0, y1) = range(b);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    count[y * out.nx + x + 1] += 1;
                }
            }
        }
        for i in 1..count.len() {
            count[i] += count[i - 1];
        }
        let total = count[count.len() - 1] as usize;
        let mut fill = count.clone();
        let mut slots = vec![u32::MAX; total];
        for (i, b) in boxes.iter().enumerate() {
            let (x0, x1, y0, y1) = range(b);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y * out.nx + x;
                    slots[fill[c] as usize] = i as u32;
                    fill[c] += 1;
                }
            }
        }
        let key = |t: &[P3; 3]| t.iter().map(|p| p.coords.dot(&dir)).fold(f64::INFINITY, f64::min);
        let mut items: Vec<Item> = slots
            .par_iter()
            .with_min_len(4096)
            .map(|&i| Item {
                key: key(&tris[i as usize]),
                id: i,
                tri: tris[i as usize],
            })
            .collect();
        // Nearest-beginning first within each cell (then by index, so the
        // order is fixed by the input alone).
        let mut cuts: Vec<&mut [Item]> = Vec::with_capacity(out.nx * out.ny);
        let mut rest = items.as_mut_slice();
        for c in 0..out.nx * out.ny {
            let n = (count[c + 1] - count[c]) as usize;
            let (a, b) = rest.split_at_mut(n);
            cuts.push(a);
            rest = b;
        }
        cuts.par_iter_mut()
            .with_min_len(1024)
            .for_each(|s| s.sort_unstable_by(|a, b| a.key.total_cmp(&b.key).then(a.id.cmp(&b.id))));
        out.start = count;
        out.items = items;
        out
    }

    /// The direction the rays run along.
    pub fn dir(&self) -> V3 {
        self.dir
    }

    /// Triangle references over all cells (for benchmarks and docs;
    /// builds the cell grid).
    pub fn references(&self) -> usize {
        self.cells_index().items.len()
    }

    /// Number of cells (builds the cell grid).
    pub fn cells(&self) -> usize {
        let c = self.cells_index();
        c.nx * c.ny
    }

    /// The first hit of the ray `origin + t * dir`, `t >= 0`: the same
    /// answer as `Bvh::first_hit(&Ray::new(origin, dir))`.
    #[inline]
    pub fn first_hit(&self, origin: &P3) -> Option<Hit> {
        let sh = self.shear.as_ref()?;
        let g = self.cells_index();
        let fx = (origin.coords.dot(&self.e1) - g.lo[0]) * g.inv_cell;
        let fy = (origin.coords.dot(&self.e2) - g.lo[1]) * g.inv_cell;
        if !(fx >= 0.0 && fy >= 0.0 && fx < g.nx as f64 && fy < g.ny as f64) {
            return None;
        }
        let c = fy as usize * g.nx + fx as usize;
        let items = &g.items[g.start[c] as usize..g.start[c + 1] as usize];
        let ray = Ray::new(*origin, self.dir);
        let od = origin.coords.dot(&self.dir);
        let mut best: Option<Hit> = None;
        let mut t_max = f64::INFINITY;
        for it in items {
            // Every later triangle begins beyond the hit found so far.
            if it.key - od > t_max * self.dd + self.slack {
                break;
            }
            if let Some(h) = intersect(&it.tri, it.id, &ray, sh, t_max, Edges::Closed)
                && best.is_none_or(|b| h.t < b.t || (h.t == b.t && h.triangle < b.triangle))
            {
                t_max = h.t;
                best = Some(h);
            }
        }
        best
    }

    /// [`ParallelRays::first_hit`] for many origins, in parallel (rayon).
    pub fn first_hits(&self, origins: &[P3]) -> Vec<Option<Hit>> {
        origins
            .par_iter()
            .with_min_len(1024)
            .map(|o| self.first_hit(o))
            .collect()
    }
}

/// Two unit vectors perpendicular to `d` and to each other. Exactly the
/// other two axes for an axis direction, so the projection of a corner is
/// its coordinates, with no rounding.
fn basis(d: &V3) -> (V3, V3) {
    let zeros = [d.x == 0.0, d.y == 0.0, d.z == 0.0];
    match zeros {
        [true, true, _] => (V3::x(), V3::y()),
        [true, _, true] => (V3::z(), V3::x()),
        [_, true, true] => (V3::y(), V3::z()),
        _ => {
            let n = d.normalize();
            let a = if n.x.abs() < 0.9 { V3::x() } else { V3::y() };
            let e1 = (a - n * a.dot(&n)).normalize();
            (e1, n.cross(&e1))
        }
    }
}

#[path = "parallel_lattice.rs"]
mod lattice;
pub use lattice::Lattice;

#[cfg(test)]
#[path = "parallel_tests.rs"]
mod tests;
