//! Generated closed solids (welded, outward-oriented): the project's own
//! test, benchmark and fuzz-seed meshes, with known volumes and sections.

use super::Mesh;
use crate::geometry::{P3, V3};
use std::f64::consts::TAU;

/// A UV sphere of radius `r` about `c`: `n_lon` segments around Z,
/// `n_lat` rings from pole to pole (vertex rings at
/// z = c.z - r cos(π i / n_lat)).
pub fn sphere(c: P3, r: f64, n_lon: usize, n_lat: usize) -> Mesh {
    let n_lon = n_lon.max(3);
    let n_lat = n_lat.max(2);
    let mut m = Mesh::default();
    m.vertices.push(c + V3::new(0.0, 0.0, -r));
    for i in 1..n_lat {
        let th = std::f64::consts::PI * i as f64 / n_lat as f64;
        let (z, rr) = (-r * th.cos(), r * th.sin());
        for j in 0..n_lon {
            let ph = TAU * j as f64 / n_lon as f64;
            m.vertices.push(c + V3::new(rr * ph.cos(), rr * ph.sin(), z));
        }
    }
    m.vertices.push(c + V3::new(0.0, 0.0, r));
    let ring = |i: usize, j: usize| (1 + (i - 1) * n_lon + j % n_lon) as u32;
    let top = (m.vertices.len() - 1) as u32;
    for j in 0..n_lon {
        m.triangles.push([0, ring(1, j + 1), ring(1, j)]);
        m.triangles.push([top, ring(n_lat - 1, j), ring(n_lat - 1, j + 1)]);
    }
    for i in 1..n_lat - 1 {
        for j in 0..n_lon {
            let (a, b, cc, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
            m.triangles.push([a, b, cc]);
            m.triangles.push([a, cc, d]);
        }
    }
    m
}

/// A torus about the Z axis through `c`: tube centre radius `big_r`, tube
/// radius `r`; `n_u` segments around Z, `n_v` around the tube (vertex rings
/// at z = c.z + r sin(2π k / n_v)).
pub fn torus(c: P3, big_r: f64, r: f64, n_u: usize, n_v: usize) -> Mesh {
    let (n_u, n_v) = (n_u.max(3), n_v.max(3));
    let mut m = Mesh::default();
    for i in 0..n_u {
        let u = TAU * i as f64 / n_u as f64;
        for k in 0..n_v {
            let v = TAU * k as f64 / n_v as f64;
            let rr = big_r + r * v.cos();
            m.vertices.push(c + V3::new(rr * u.cos(), rr * u.sin(), r * v.sin()));
        }
    }
    let id = |i: usize, k: usize| ((i % n_u) * n_v + k % n_v) as u32;
    for i in 0..n_u {
        for k in 0..n_v {
            let (a, b, cc, d) = (id(i, k), id(i + 1, k), id(i + 1, k + 1), id(i, k + 1));
            m.triangles.push([a, b, cc]);
            m.triangles.push([a, cc, d]);
        }
    }
    m
}

/// A closed cylinder of radius `r` from `a` to `b` (any direction):
/// `n` segments around, `n_len` along, flat capped ends.
pub fn cylinder(a: P3, b: P3, r: f64, n: usize, n_len: usize) -> Mesh {
    let n = n.max(3);
    let n_len = n_len.max(1);
    let axis = (b - a).normalize();
    let helper = if axis.x.abs() < 0.9 { V3::x() } else { V3::y() };
    let e1 = axis.cross(&helper).normalize();
    let e2 = axis.cross(&e1);
    let mut m = Mesh::default();
    for s in 0..=n_len {
        let o = a + (b - a) * (s as f64 / n_len as f64);
        for j in 0..n {
            let ph = TAU * j as f64 / n as f64;
            m.vertices.push(o + (e1 * ph.cos() + e2 * ph.sin()) * r);
        }
    }
    let ca = m.vertices.len() as u32;
    m.vertices.push(a);
    let cb = ca + 1;
    m.vertices.push(b);
    let id = |s: usize, j: usize| (s * n + j % n) as u32;
    for s in 0..n_len {
        for j in 0..n {
            let (p, q, rr, t) = (id(s, j), id(s, j + 1), id(s + 1, j + 1), id(s + 1, j));
            m.triangles.push([p, q, rr]);
            m.triangles.push([p, rr, t]);
        }
    }
    for j in 0..n {
        m.triangles.push([ca, id(0, j + 1), id(0, j)]);
        m.triangles.push([cb, id(n_len, j), id(n_len, j + 1)]);
    }
    m
}

/// An axis-aligned box from `lo` to `hi`, 12 triangles, outward.
pub fn cuboid(lo: P3, hi: P3) -> Mesh {
    let v = |i: usize| {
        P3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let vertices = (0..8).map(v).collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut triangles = Vec::new();
    for q in quads {
        triangles.push([q[0], q[1], q[2]]);
        triangles.push([q[0], q[2], q[3]]);
    }
    Mesh { vertices, triangles }
}

/// A closed block over `[0, n h]²`: its top a bumpy height field on an
/// `n` x `n` grid of spacing `h` (z = 1 + 0.3 sin(0.7 i) cos(0.45 j), the
/// cells' diagonals alternating so vertices have fans of four and eight
/// triangles), vertical sides and a flat bottom at z = 0, all on the same
/// grid, so every face shares its edges. Rays on the grid's lines pass
/// exactly through its vertices and edges.
pub fn terrain_block(n: usize, h: f64) -> Mesh {
    let z = |i: usize, j: usize| 1.0 + 0.3 * ((i as f64) * 0.7).sin() * ((j as f64) * 0.45).cos();
    let m1 = n + 1;
    let id = |i: usize, j: usize, top: bool| (usize::from(top) * m1 * m1 + j * m1 + i) as u32;
    let mut vertices = Vec::with_capacity(2 * m1 * m1);
    for top in [false, true] {
        for j in 0..=n {
            for i in 0..=n {
                vertices.push(P3::new(i as f64 * h, j as f64 * h, if top { z(i, j) } else { 0.0 }));
            }
        }
    }
    let mut triangles = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let q = |top| {
                [
                    id(i, j, top),
                    id(i + 1, j, top),
                    id(i + 1, j + 1, top),
                    id(i, j + 1, top),
                ]
            };
            let ([a, b, c, d], [ab, bb, cb, db]) = (q(true), q(false));
            if (i + j) % 2 == 0 {
                triangles.extend([[a, b, c], [a, c, d], [ab, cb, bb], [ab, db, cb]]);
            } else {
                triangles.extend([[a, b, d], [b, c, d], [ab, db, bb], [bb, db, cb]]);
            }
        }
    }
    for k in 0..n {
        // Sides, outward: y = 0, x = n, y = n, x = 0.
        for ((i0, j0), (i1, j1)) in [
            ((k, 0), (k + 1, 0)),
            ((n, k), (n, k + 1)),
            ((k + 1, n), (k, n)),
            ((0, k + 1), (0, k)),
        ] {
            let (a, b) = (id(i0, j0, false), id(i1, j1, false));
            let (c, d) = (id(i1, j1, true), id(i0, j0, true));
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    Mesh { vertices, triangles }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signed_volume(m: &Mesh) -> f64 {
        m.iter_triangles()
            .map(|t| t.a.coords.dot(&t.b.coords.cross(&t.c.coords)) / 6.0)
            .sum()
    }

    #[test]
    fn generated_solids_are_outward() {
        let b = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(1.0, 2.0, 3.0));
        assert!((signed_volume(&b) - 6.0).abs() < 1e-12);
        let s = sphere(P3::new(1.0, 2.0, 3.0), 2.0, 64, 32);
        let v = signed_volume(&s);
        assert!(v > 0.98 * 32.0 / 3.0 * std::f64::consts::PI && v < 32.0 / 3.0 * std::f64::consts::PI);
        let t = torus(P3::origin(), 3.0, 1.0, 64, 32);
        let tv = 2.0 * std::f64::consts::PI.powi(2) * 3.0;
        assert!((signed_volume(&t) / tv - 1.0).abs() < 0.01);
        let c = cylinder(P3::new(0.0, 0.0, 0.0), P3::new(1.0, 1.0, 5.0), 1.0, 64, 3);
        let cv = std::f64::consts::PI * (27.0f64).sqrt();
        assert!((signed_volume(&c) / cv - 1.0).abs() < 0.01);
        let t = terrain_block(8, 0.5);
        let v = signed_volume(&t);
        assert!(v > 0.7 * 16.0 && v < 1.3 * 16.0, "{v}");
        let r = crate::mesh::topology::report(&t);
        assert!(r.watertight && r.components == 1, "{r:?}");
    }
}
