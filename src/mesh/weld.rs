//! Vertex welding: vertices closer than a tolerance become one, so that
//! triangles read as a soup (STL stores every corner three to eight times)
//! share their edges and the topology can be read.
//!
//! A spatial hash with cells of the tolerance's size: each vertex looks in
//! the 27 cells around its own for an earlier kept vertex within the
//! tolerance, so the work is linear in the vertex count. The first vertex
//! of a cluster (in file order) is the one kept, so the result does not
//! depend on anything but the input order.

use std::collections::HashMap;

use super::Mesh;
use crate::geometry::P3;

/// What welding did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WeldReport {
    /// Vertices before.
    pub vertices_in: usize,
    /// Vertices after.
    pub vertices_out: usize,
}

/// Merge vertices within `tol` (mm; 0 = identical coordinates only) and
/// drop vertices no triangle uses. Triangles keep their order and winding.
pub fn weld(mesh: &Mesh, tol: f64) -> (Mesh, WeldReport) {
    let n = mesh.vertices.len();
    let mut remap = vec![u32::MAX; n];
    let mut used = vec![false; n];
    for t in &mesh.triangles {
        for &v in t {
            if (v as usize) < n {
                used[v as usize] = true;
            }
        }
    }
    let mut out: Vec<P3> = Vec::new();
    if tol > 0.0 && tol.is_finite() {
        let inv = 1.0 / tol;
        let cell = |p: &P3| ((p.x * inv).floor() as i64, (p.y * inv).floor() as i64, (p.z * inv).floor() as i64);
        let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::with_capacity(n / 4);
        let tol2 = tol * tol;
        for (i, p) in mesh.vertices.iter().enumerate() {
            if !used[i] {
                continue;
            }
            let (cx, cy, cz) = cell(p);
            let mut found = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(list) = grid.get(&(cx + dx, cy + dy, cz + dz)) {
                            for &k in list {
                                if (out[k as usize] - p).norm_squared() <= tol2 {
                                    found = Some(k);
                                    break 'search;
                                }
                            }
                        }
                    }
                }
            }
            remap[i] = match found {
                Some(k) => k,
                None => {
                    let k = out.len() as u32;
                    out.push(*p);
                    grid.entry((cx, cy, cz)).or_default().push(k);
                    k
                }
            };
        }
    } else {
        let mut seen: HashMap<[u64; 3], u32> = HashMap::with_capacity(n / 4);
        for (i, p) in mesh.vertices.iter().enumerate() {
            if !used[i] {
                continue;
            }
            // +0.0 and -0.0 are the same point.
            let key = [(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits(), (p.z + 0.0).to_bits()];
            remap[i] = *seen.entry(key).or_insert_with(|| {
                out.push(*p);
                (out.len() - 1) as u32
            });
        }
    }
    let triangles = mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| (v as usize) < n))
        .map(|t| [remap[t[0] as usize], remap[t[1] as usize], remap[t[2] as usize]])
        .collect();
    let rep = WeldReport {
        vertices_in: n,
        vertices_out: out.len(),
    };
    (Mesh { vertices: out, triangles }, rep)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::solids;

    #[test]
    fn soup_welds_back_to_the_indexed_mesh() {
        let m = solids::sphere(P3::new(1.0, 2.0, 3.0), 2.0, 32, 16);
        let soup = Mesh::from_triangles(&m.iter_triangles().collect::<Vec<_>>());
        let (w, r) = weld(&soup, 0.0);
        assert_eq!(r.vertices_out, m.vertices.len());
        assert_eq!(w.triangles.len(), m.triangles.len());
        // Jitter below the tolerance still welds; the result is the same mesh shape.
        let mut j = soup.clone();
        for (i, v) in j.vertices.iter_mut().enumerate() {
            v.x += 1e-7 * ((i * 7919 % 13) as f64 - 6.0) / 6.0;
        }
        let (w2, r2) = weld(&j, 1e-5);
        assert_eq!(r2.vertices_out, m.vertices.len());
        for (a, b) in w.iter_triangles().zip(w2.iter_triangles()) {
            assert!((a.a - b.a).norm() < 1e-6);
        }
    }
}
