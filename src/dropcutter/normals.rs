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
use std::collections::HashMap;

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
        let facet: Vec<V3> = tris.iter().map(|t| V3::new(t.n[0], t.n[1], t.n[2])).collect();
        // Each corner's vertex id, corners at the same coordinates sharing
        // one (+0 and -0 taken as the same).
        let mut ids: HashMap<[u64; 3], u32> = HashMap::with_capacity(tris.len());
        let vertex: Vec<[u32; 3]> = tris
            .iter()
            .map(|t| {
                t.v.map(|p| {
                    let key = p.map(|c| (c + 0.0).to_bits());
                    let next = ids.len() as u32;
                    *ids.entry(key).or_insert(next)
                })
            })
            .collect();
        // The corners at each vertex, in compressed rows.
        let n_vertices = ids.len();
        let mut start = vec![0usize; n_vertices + 1];
        for v in vertex.iter().flatten() {
            start[*v as usize + 1] += 1;
        }
        for k in 0..n_vertices {
            start[k + 1] += start[k];
        }
        let mut fill = start.clone();
        let mut at = vec![(0u32, 0u8); start[n_vertices]];
        for (t, vs) in vertex.iter().enumerate() {
            for (c, v) in vs.iter().enumerate() {
                at[fill[*v as usize]] = (t as u32, c as u8);
                fill[*v as usize] += 1;
            }
        }
        let cos_crease = crease.clamp(0.0, std::f64::consts::PI).cos();
        let corners = (0..tris.len())
            .map(|t| {
                let own = facet[t];
                std::array::from_fn(|c| {
                    if own == V3::zeros() {
                        return own;
                    }
                    let v = vertex[t][c] as usize;
                    let mut sum = V3::zeros();
                    for &(u, k) in &at[start[v]..start[v + 1]] {
                        let n = facet[u as usize];
                        // The facet itself always counts, whatever round-off
                        // makes of its dot product with itself.
                        if u as usize == t || (n != V3::zeros() && n.dot(&own) >= cos_crease) {
                            sum += n * corner_angle(&tris[u as usize], k as usize);
                        }
                    }
                    let len = sum.norm();
                    if len > 0.0 && len.is_finite() { sum / len } else { own }
                })
            })
            .collect();
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
