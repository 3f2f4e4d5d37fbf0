//! Smooth surface normals for 5-axis orientation: the tool axis follows
//! the surface the mesh approximates, not each facet of it.
//!
//! A 5-axis location oriented by its facet's normal turns the tool axis in
//! a step at every facet edge: on a 100,000-triangle freeform part the
//! rotary axes jerk a degree or more between CL points a few hundredths of
//! a millimetre apart, and a trunnion follows that only by slowing the
//! feed (the gouge bench counts the steps). Here each triangle corner gets
//! a vertex normal, the facet normals around the vertex weighted by the
//! corner angles they meet it with (Thürmer and Wüthrich's angle
//! weighting: independent of how a face is split into triangles), and
//! the normal at a contact is those three interpolated across the facet
//! (Phong's normal). Two facets meeting at more than a crease angle are
//! not averaged together, so the flat top of a block keeps an upright
//! normal right up to its edges, and the wall below it its own.
//!
//! Corners are joined by exact position (the mesh as read is not welded;
//! a CAD export writes a shared vertex with the same coordinates each
//! time). Normals are those of [`Tri`], turned upward (nz >= 0), as the
//! drop from above sees the surface: the lower sheet of a closed part
//! folds back under the upper one there, more than any crease from it,
//! so the two are never averaged.

use super::cutter_vs_triangle::Tri;
use crate::geometry::{P3, V3};
use rayon::prelude::*;

/// The default crease angle (degrees): facets meeting at more than this
/// keep their own normals along the shared edge.
pub const DEFAULT_CREASE_DEG: f64 = 30.0;

/// Interpolated normals over a drop-cutter's triangles.
#[derive(Debug, Clone)]
pub struct SmoothNormals {
    /// Unit upward normal at each corner of each triangle (in the
    /// triangles' order); the facet's own where it has no neighbour
    /// within the crease, zeros for a degenerate triangle.
    corners: Vec<[V3; 3]>,
    /// The crease angle (radians).
    crease: f64,
}

impl SmoothNormals {
    /// Corner normals of `tris` with facets averaged within `crease`
    /// radians of one another (0 gives each facet its own normal).
    pub fn new(tris: &[Tri], crease: f64) -> SmoothNormals {
        let facet: Vec<V3> = tris.par_iter().map(|t| V3::new(t.n[0], t.n[1], t.n[2])).collect();
        // Each corner's weight: its interior angle.
        let angle: Vec<[f64; 3]> = tris
            .par_iter()
            .map(|t| std::array::from_fn(|k| corner_angle(t, k)))
            .collect();
        // The corners (3 t + c) grouped by position, +0 and -0 the same:
        // sorted, so a vertex's corners are one run (a sort, where a hash
        // map of positions took most of the time on a million triangles).
        let key = |i: u32| tris[i as usize / 3].v[i as usize % 3].map(|x| (x + 0.0).to_bits());
        // Sorted by a Morton code of the position in the mesh's box (21
        // bits an axis): equal positions fall together, and neighbouring
        // runs are neighbouring vertices, whose triangles a mesh file
        // mostly holds near one another, so the reads below stay in cache
        // (a hash of the position scattered them: three times the time on
        // a million triangles). Different positions in one cell are told
        // apart below.
        let (lo, hi) = tris
            .iter()
            .fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(mut lo, mut hi), t| {
                for p in &t.v {
                    for k in 0..3 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                }
                (lo, hi)
            });
        let scale: [f64; 3] = std::array::from_fn(|k| {
            let ext = hi[k] - lo[k];
            if ext > 0.0 && ext.is_finite() {
                ((1u64 << 21) - 1) as f64 / ext
            } else {
                0.0
            }
        });
        let spread = |x: u64| {
            // Bit b of x to bit 3 b.
            let mut x = x & 0x1f_ffff;
            x = (x | x << 32) & 0x1f_0000_0000_ffff;
            x = (x | x << 16) & 0x1f_0000_ff00_00ff;
            x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
            x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
            (x | x << 2) & 0x1249_2492_4924_9249
        };
        let morton = |i: u32| {
            let p = tris[i as usize / 3].v[i as usize % 3];
            (0..3).fold(0u64, |m, k| {
                let q = ((p[k] - lo[k]) * scale[k]).clamp(0.0, ((1u64 << 21) - 1) as f64) as u64;
                m | spread(q) << k
            })
        };
        let n = tris.len() * 3;
        let mut sorted: Vec<(u64, u32)> = (0..n as u32).into_par_iter().map(|i| (morton(i), i)).collect();
        sorted.par_sort_unstable();
        // Run starts, and where each corner sits in `sorted`.
        let mut starts: Vec<u32> = (0..n as u32)
            .into_par_iter()
            .filter(|&k| k == 0 || sorted[k as usize].0 != sorted[k as usize - 1].0)
            .collect();
        starts.push(n as u32);
        let cos_crease = crease.clamp(0.0, std::f64::consts::PI).cos();
        // Each run's corners' normals, in the sorted order: a run's
        // facets (normal, weighted normal, position) read once into a
        // buffer, then each corner sums those within the crease of its own
        // facet. Runs in chunks, one buffer per chunk.
        let runs: Vec<u32> = (0..starts.len() as u32 - 1).collect();
        let by_sorted: Vec<V3> = runs
            .par_chunks(4096)
            .flat_map_iter(|chunk| {
                let mut out = Vec::new();
                let mut here: Vec<(V3, V3, [u64; 3], usize)> = Vec::new();
                for &r in chunk {
                    let run = &sorted[starts[r as usize] as usize..starts[r as usize + 1] as usize];
                    here.clear();
                    here.extend(run.iter().map(|&(_, j)| {
                        let (u, k) = (j as usize / 3, j as usize % 3);
                        (facet[u], facet[u] * angle[u][k], key(j), u)
                    }));
                    for &(own, _, pos, t) in &here {
                        if own == V3::zeros() {
                            out.push(own);
                            continue;
                        }
                        let mut sum = V3::zeros();
                        for &(n, weighted, p, u) in &here {
                            // Another position in the run (in the same
                            // cell of the code) is another vertex. The facet itself
                            // always counts, whatever round-off makes of
                            // its dot product with itself.
                            if p == pos && (u == t || (n != V3::zeros() && n.dot(&own) >= cos_crease)) {
                                sum += weighted;
                            }
                        }
                        let len = sum.norm();
                        out.push(if len > 0.0 && len.is_finite() { sum / len } else { own });
                    }
                }
                out
            })
            .collect();
        // Back in triangle order.
        let mut corners = vec![[V3::zeros(); 3]; tris.len()];
        for (k, &(_, i)) in sorted.iter().enumerate() {
            corners[i as usize / 3][i as usize % 3] = by_sorted[k];
        }
        crate::progress::lap("smooth normals");
        SmoothNormals { corners, crease }
    }

    /// The crease angle the normals were made with (radians).
    pub fn crease(&self) -> f64 {
        self.crease
    }

    /// The normal at `p` on triangle `t` of `tris` (the triangles these
    /// normals were made from): the corner normals weighted by `p`'s
    /// barycentric coordinates in the triangle's XY projection (the
    /// contact is straight below a sample), unit length; the facet's own
    /// normal where that fails (a degenerate projection).
    pub fn at(&self, tris: &[Tri], t: usize, p: P3) -> V3 {
        let tri = &tris[t];
        let own = V3::new(tri.n[0], tri.n[1], tri.n[2]);
        let [a, b, c] = tri.v;
        let area =
            |p: [f64; 2], q: [f64; 2], r: [f64; 2]| (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
        let (a, b, c, q) = ([a[0], a[1]], [b[0], b[1]], [c[0], c[1]], [p.x, p.y]);
        let whole = area(a, b, c);
        if whole.abs() <= f64::MIN_POSITIVE || !whole.is_finite() {
            return own;
        }
        // Clamped into the triangle: a contact on its edge may sit a
        // round-off outside.
        let w = [area(q, b, c) / whole, area(a, q, c) / whole, area(a, b, q) / whole].map(|x| x.clamp(0.0, 1.0));
        let [na, nb, nc] = self.corners[t];
        let n = na * w[0] + nb * w[1] + nc * w[2];
        let len = n.norm();
        if len > 1e-12 && len.is_finite() { n / len } else { own }
    }
}

/// The interior angle of triangle `t` at its corner `k` (0 for a
/// degenerate corner).
fn corner_angle(t: &Tri, k: usize) -> f64 {
    let p = |i: usize| {
        let v = t.v[i % 3];
        V3::new(v[0], v[1], v[2])
    };
    let (o, u, w) = (p(k), p(k + 1), p(k + 2));
    let (e1, e2) = (u - o, w - o);
    let cross = e1.cross(&e2).norm();
    let angle = cross.atan2(e1.dot(&e2));
    if angle.is_finite() { angle } else { 0.0 }
}

#[cfg(test)]
#[path = "normals_tests.rs"]
mod tests;
