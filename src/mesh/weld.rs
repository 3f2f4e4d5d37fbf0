//! Vertex welding: vertices closer than a tolerance become one, so that
//! triangles read as a soup (STL stores every corner three to eight times)
//! share their edges and the topology can be read.
//!
//! A hash on the exact coordinates first (an STL soup repeats each corner
//! three to eight times), then a spatial hash with cells eight times the
//! tolerance for the distinct positions: each looks in the cells its
//! tolerance ball can reach (about two). Linear work, mostly in parallel,
//! and a result that depends on the input order alone (see [`weld`]).

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hash, Hasher};
use std::sync::atomic::{AtomicU32, Ordering};

use super::Mesh;
use crate::geometry::P3;

/// What welding did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct WeldReport {
    /// Vertices before.
    pub vertices_in: usize,
    /// Vertices after.
    pub vertices_out: usize,
}

/// A multiply-rotate hash with a final avalanche (the keys are float bits
/// whose low 29 bits are zero for f32 data, so the mixing must reach the
/// low bits the table indexes by). Fixed, so runs are reproducible.
#[derive(Default)]
struct Fast(u64);

impl Hasher for Fast {
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(*b as u64);
        }
    }
    #[inline]
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(26) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
    #[inline]
    fn finish(&self) -> u64 {
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
        h ^= h >> 33;
        h
    }
}

type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<Fast>>;

/// Three words hashed as three words.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Key([u64; 3]);

impl Hash for Key {
    #[inline]
    fn hash<H: Hasher>(&self, h: &mut H) {
        h.write_u64(self.0[0]);
        h.write_u64(self.0[1]);
        h.write_u64(self.0[2]);
    }
}

/// Merge vertices within `tol` (mm; 0 = identical coordinates only) and
/// drop vertices no triangle uses. Triangles keep their order and winding.
///
/// The rule, in file order: identical coordinates always become one vertex
/// (an STL soup stores each corner three to eight times); a new position
/// joins the earliest kept vertex within `tol`, else it is kept. Kept
/// vertices are numbered in the order they first occur, so the result
/// depends on the input alone.
///
/// The work, mostly in parallel (rayon): identical coordinates are found
/// by hashing their bits in shards; the distinct positions are put in a
/// spatial hash of cells `8 tol` wide (the ball of radius `tol` reaches
/// one to eight of them, about two on average), and each finds out
/// whether any other lies within `tol`. Only those that have such a
/// neighbour (none on a clean mesh) go through the rule above one by one.
pub fn weld(mesh: &Mesh, tol: f64) -> (Mesh, WeldReport) {
    use rayon::prelude::*;
    let n = mesh.vertices.len();
    let mut used = vec![false; n];
    for t in &mesh.triangles {
        for &v in t {
            if (v as usize) < n {
                used[v as usize] = true;
            }
        }
    }
    // +0.0 and -0.0 are the same point.
    let key_of = |p: &P3| Key([(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits(), (p.z + 0.0).to_bits()]);
    let hash_of = |k: &Key| {
        let mut h = Fast::default();
        k.hash(&mut h);
        h.finish()
    };
    // Identical coordinates by shards of their hash, two per thread, each
    // with its own table. A shard goes through the vertices in file order
    // and takes its own, so its table gives each the first vertex with the
    // same coordinates (whatever the number of shards), and it reads the
    // vertex array in order. Until 29 November 2026 the vertices were
    // first sorted into 64 shards, on one thread, and each shard read its
    // own at random, a cache miss a vertex: 150-225 ms on a 1 M-triangle
    // STL on two cores, now 100-120 (8, 16 and 32 shards: 135-160,
    // 155-205 and 240-250 ms; each shard's pass over all the vertices
    // costs more than its table's cache misses save).
    let shards = (2 * rayon::current_num_threads()).clamp(1, 64) as u64;
    let shard: Vec<u8> = mesh
        .vertices
        .par_iter()
        .with_min_len(8192)
        .map(|p| (hash_of(&key_of(p)) % shards) as u8)
        .collect();
    // first[i]: the first vertex (file order) with i's coordinates; each
    // index is stored by the one shard that owns it (relaxed atomic stores
    // are plain stores on x86).
    let first: Vec<AtomicU32> = (0..n).map(|_| AtomicU32::new(u32::MAX)).collect();
    (0..shards as u8).into_par_iter().for_each(|s| {
        let mut map: FastMap<Key, u32> = FastMap::default();
        map.reserve(n / shards as usize / 4);
        for i in 0..n {
            if shard[i] == s && used[i] {
                let f = *map.entry(key_of(&mesh.vertices[i])).or_insert(i as u32);
                first[i].store(f, Ordering::Relaxed);
            }
        }
    });
    let first: Vec<u32> = first.into_iter().map(AtomicU32::into_inner).collect();
    // Distinct positions in file order.
    let uniq: Vec<u32> = (0..n as u32).filter(|&i| first[i as usize] == i).collect();
    let near = tol > 0.0 && tol.is_finite();
    // Cells eight tolerances wide: the ball of radius tol around a point
    // reaches a neighbouring cell along an axis only when the point lies
    // within tol of that side, so a point looks in about two cells, not
    // the eight that cells of 2 tol always gave. On a 1 M-triangle STL
    // the search below went only from 120-135 to 100-115 ms: each lookup
    // is a cache miss, and the eight of a point overlapped.
    let inv = 0.125 / tol;
    let tol2 = tol * tol;
    // `floor_i64`, not `floor`: a libm call on baseline x86_64.
    let cell_of = |p: &P3| [p.x, p.y, p.z].map(|v| crate::geometry::floor_i64(v * inv));
    // The cells the ball of radius tol around p can reach: on each axis
    // its own, and a neighbour when p is within an eighth of the cell (plus
    // a margin for the round-off of v * inv) of that side.
    const NEAR_SIDE: f64 = 0.125 + 1e-3;
    let reach = |p: &P3| {
        let c = cell_of(p);
        let span = |v: f64, c: i64| {
            let f = v * inv - c as f64;
            let lo = if f < NEAR_SIDE { c.saturating_sub(1) } else { c };
            let hi = if f > 1.0 - NEAR_SIDE { c.saturating_add(1) } else { c };
            (lo, hi)
        };
        let (x, y, z) = (span(p.x, c[0]), span(p.y, c[1]), span(p.z, c[2]));
        (x.0..=x.1).flat_map(move |cx| {
            (y.0..=y.1).flat_map(move |cy| (z.0..=z.1).map(move |cz| Key([cx as u64, cy as u64, cz as u64])))
        })
    };
    // Cell -> the last distinct position (in file order) in it; `next`
    // chains the others, in decreasing file order.
    let mut cells: FastMap<Key, u32> = FastMap::default();
    let mut next = vec![u32::MAX; if near { uniq.len() } else { 0 }];
    let mut crowded = vec![false; if near { uniq.len() } else { 0 }];
    if near {
        cells.reserve(uniq.len());
        for (j, &i) in uniq.iter().enumerate() {
            let c = cell_of(&mesh.vertices[i as usize]).map(|v| v as u64);
            let head = cells.entry(Key(c)).or_insert(u32::MAX);
            next[j] = *head;
            *head = j as u32;
        }
        crowded = uniq
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(j, &i)| {
                let p = &mesh.vertices[i as usize];
                reach(p).any(|key| {
                    let mut k = cells.get(&key).copied().unwrap_or(u32::MAX);
                    while k != u32::MAX {
                        if k as usize != j && (mesh.vertices[uniq[k as usize] as usize] - p).norm_squared() <= tol2 {
                            return true;
                        }
                        k = next[k as usize];
                    }
                    false
                })
            })
            .collect();
    }
    // The rule, in file order; out_of[j]: output index of distinct position j.
    let mut out: Vec<P3> = Vec::with_capacity(uniq.len());
    let mut out_of = vec![u32::MAX; uniq.len()];
    let mut kept = vec![false; uniq.len()];
    for (j, &i) in uniq.iter().enumerate() {
        let p = &mesh.vertices[i as usize];
        let mut found = u32::MAX;
        if near && crowded[j] {
            for key in reach(p) {
                let mut k = cells.get(&key).copied().unwrap_or(u32::MAX);
                while k != u32::MAX {
                    // Earlier, kept, within tol; the earliest such.
                    let o = out_of[k as usize];
                    if (k as usize) < j && kept[k as usize] && o < found && (out[o as usize] - p).norm_squared() <= tol2
                    {
                        found = o;
                    }
                    k = next[k as usize];
                }
            }
        }
        out_of[j] = if found != u32::MAX {
            found
        } else {
            kept[j] = true;
            out.push(*p);
            (out.len() - 1) as u32
        };
    }
    // Map every vertex through its first occurrence.
    let mut pos_of = vec![u32::MAX; n];
    for (j, &i) in uniq.iter().enumerate() {
        pos_of[i as usize] = out_of[j];
    }
    let remap: Vec<u32> = (0..n)
        .into_par_iter()
        .with_min_len(8192)
        .map(|i| if used[i] { pos_of[first[i] as usize] } else { u32::MAX })
        .collect();
    let triangles = mesh
        .triangles
        .par_iter()
        .with_min_len(8192)
        .filter(|t| t.iter().all(|&v| (v as usize) < n))
        .map(|t| [remap[t[0] as usize], remap[t[1] as usize], remap[t[2] as usize]])
        .collect();
    let rep = WeldReport {
        vertices_in: n,
        vertices_out: out.len(),
    };
    (
        Mesh {
            vertices: out,
            triangles,
        },
        rep,
    )
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

    /// The rule of [`weld`], one vertex at a time by brute force.
    fn reference(mesh: &Mesh, tol: f64) -> Mesh {
        let mut out: Vec<P3> = Vec::new();
        let mut seen: Vec<(P3, u32)> = Vec::new();
        let mut remap = vec![u32::MAX; mesh.vertices.len()];
        let used: std::collections::BTreeSet<u32> = mesh.triangles.iter().flatten().copied().collect();
        for &i in &used {
            let p = mesh.vertices[i as usize];
            let same = |q: &P3| q.x == p.x && q.y == p.y && q.z == p.z;
            remap[i as usize] = if let Some(&(_, k)) = seen.iter().find(|(q, _)| same(q)) {
                k
            } else {
                let k = match out
                    .iter()
                    .position(|q| tol > 0.0 && (q - p).norm_squared() <= tol * tol)
                {
                    Some(k) => k as u32,
                    None => {
                        out.push(p);
                        (out.len() - 1) as u32
                    }
                };
                seen.push((p, k));
                k
            };
        }
        let triangles = mesh.triangles.iter().map(|t| t.map(|v| remap[v as usize])).collect();
        Mesh {
            vertices: out,
            triangles,
        }
    }

    #[test]
    fn clusters_and_chains_weld_by_the_rule() {
        // Points in tight clusters and chains (each within tol of the
        // next, not of the first), with exact repeats and -0.0.
        let mut s = 12345u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 10_000) as f64 / 10_000.0
        };
        let mut v = Vec::new();
        for c in 0..300 {
            let base = P3::new((c % 7) as f64 * 0.01, (c / 7 % 5) as f64 * 0.01, 0.0);
            for _ in 0..4 {
                v.push(base + crate::geometry::V3::new(rnd(), rnd(), rnd()) * 3e-3);
            }
            if c % 3 == 0 {
                v.push(v[v.len() - 2]);
            }
        }
        v.push(P3::new(-0.0, 0.0, 0.0));
        v.push(P3::new(0.0, -0.0, 0.0));
        let n = v.len() as u32;
        let triangles: Vec<[u32; 3]> = (0..n).map(|i| [i, (i * 7 + 1) % n, (i * 13 + 2) % n]).collect();
        let m = Mesh { vertices: v, triangles };
        for tol in [0.0, 1e-4, 1e-3, 2e-3, 5e-3, 0.02] {
            let (w, r) = weld(&m, tol);
            assert_eq!(w, reference(&m, tol), "tol {tol}");
            assert_eq!(r.vertices_out, w.vertices.len());
        }
    }

    #[test]
    fn pairs_across_cell_sides_weld_by_the_rule() {
        // Cells are 8 tol wide: pairs of points either side of a cell's
        // side (and of its corners), just within and just beyond tol of
        // each other, on every axis and at negative coordinates.
        let tol = 1e-3;
        let w = 8.0 * tol;
        let mut v = Vec::new();
        for k in -3i32..3 {
            let side = k as f64 * w;
            for d in [0.4999, 0.5, 0.5001, 0.9999, 1.0001] {
                let (a, b) = (side - d * tol, side + (1.0 - d) * tol);
                for axis in 0..3 {
                    let mut p = [0.3 * w, 0.6 * w, 0.1 * w];
                    let mut q = p;
                    p[axis] = a;
                    q[axis] = b;
                    // Both orders: the later point is the one that looks.
                    let (p, q) = (P3::new(p[0], p[1], p[2]), P3::new(q[0], q[1], q[2]));
                    let shift = crate::geometry::V3::new(0.0, 0.0, 40.0 * w);
                    v.extend([p, q, q + shift, p + shift]);
                }
                // Across a corner: both x and y change sides.
                let e = tol * 0.7 * d;
                v.push(P3::new(side - e, side - e, 0.0));
                v.push(P3::new(side + e * 0.4, side + e * 0.4, 0.0));
            }
        }
        let n = v.len() as u32;
        let triangles: Vec<[u32; 3]> = (0..n).map(|i| [i, (i + 1) % n, (i + 2) % n]).collect();
        let m = Mesh { vertices: v, triangles };
        for tol in [tol, 0.999 * tol, 1.001 * tol] {
            assert_eq!(weld(&m, tol).0, reference(&m, tol), "tol {tol}");
        }
    }
}
