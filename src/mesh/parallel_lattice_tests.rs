use super::*;
use crate::mesh::bvh::{Bvh, Ray};
use crate::mesh::solids;
use crate::mesh::{Mesh, Triangle};
use proptest::prelude::*;

/// Every ray of the lattice: the rasteriser's hit is the BVH's first hit,
/// bit for bit (t's bits too, apart from the sign of a zero). Returns how
/// many rays hit.
fn check(m: &Mesh, dir: V3, l: &Lattice) -> usize {
    let bvh = Bvh::new(m);
    let pr = ParallelRays::new(m, dir);
    let got = pr.first_hits_lattice(l);
    assert_eq!(got.len(), l.len());
    let depths = pr.first_depths_lattice(l);
    assert_eq!(depths.len(), l.len());
    for (h, t) in got.iter().zip(&depths) {
        assert_eq!(h.map_or(f64::INFINITY, |h| h.t).to_bits(), t.to_bits());
    }
    let mut hits = 0;
    for j in 0..l.vs.len() {
        for i in 0..l.us.len() {
            let o = l.origin(i, j);
            let want = bvh.first_hit(&Ray::new(o, dir));
            let h = got[j * l.us.len() + i];
            assert_eq!(h, want, "ray ({i}, {j}) from {o:?} along {dir:?}");
            if let (Some(a), Some(b)) = (h, want) {
                assert!(a.t.to_bits() == b.t.to_bits() || a.t == 0.0);
            }
            hits += h.is_some() as usize;
        }
    }
    hits
}

/// A small deterministic generator (xorshift), for triangle soups.
struct Rng(u64);

impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Random triangles in a box, a fifth of them degenerate: two corners the
/// same, three corners on a line, or very thin.
fn soup(seed: u64, n: usize) -> Mesh {
    let mut r = Rng(seed | 1);
    let mut m = Mesh::default();
    for k in 0..n {
        let mut p = || P3::new(r.f() * 4.0 - 2.0, r.f() * 4.0 - 2.0, r.f() * 4.0 - 2.0);
        let (a, b, c) = (p(), p(), p());
        let (b, c) = match k % 10 {
            0 => (a, c),
            1 => (b, a + (b - a) * 0.375),
            2 => (b, a + (b - a) * 0.5 + (c - a) * 1e-7),
            _ => (a + (b - a) * 0.3, a + (c - a) * 0.3),
        };
        let i = m.vertices.len() as u32;
        m.vertices.extend([a, b, c]);
        m.triangles.push([i, i + 1, i + 2]);
    }
    m
}

fn steps(x0: f64, step: f64, n: usize) -> Vec<f64> {
    (0..n).map(|k| x0 + k as f64 * step).collect()
}

#[test]
fn vertical_lattice_through_vertices_and_edges_of_a_closed_mesh() {
    // The terrain block on an h grid; lattice steps of h / 4 put rays
    // exactly through every vertex and edge midpoint, and the lattice runs
    // past the block on every side.
    let (n, h) = (16, 0.25);
    let m = crate::mesh::bvh::tests::terrain_block(n, h);
    let xs = steps(-0.5, h / 4.0, 4 * n + 5);
    let ys = steps(-0.5, h / 4.0, 4 * n + 3);
    let down = Lattice {
        base: P3::new(0.0, 0.0, 3.0),
        eu: V3::x(),
        ev: V3::y(),
        us: &xs,
        vs: &ys,
    };
    let hits = check(&m, -V3::z(), &down);
    // Watertight: every ray over the block (closed x and y ranges) hits.
    let over = |v: &f64| (0.0..=n as f64 * h).contains(v);
    assert_eq!(
        hits,
        xs.iter().filter(|v| over(v)).count() * ys.iter().filter(|v| over(v)).count()
    );
    let pr = ParallelRays::new(&m, -V3::z());
    let got = pr.first_hits_lattice(&down);
    for (j, y) in ys.iter().enumerate() {
        for (i, x) in xs.iter().enumerate() {
            if let Some(hit) = got[j * xs.len() + i] {
                let want = crate::mesh::bvh::tests::brute_top(&m, *x, *y).unwrap();
                assert_eq!(3.0 - hit.t, want, "({x}, {y})");
            }
        }
    }
    // From below, and from above on a lattice with both axes oblique in
    // the plane (still along z).
    let up = Lattice {
        base: P3::new(0.0, 0.0, -3.0),
        ..down
    };
    check(&m, V3::z() * 2.0, &up);
    let skew = Lattice {
        eu: V3::new(0.8, 0.6, 0.0),
        ev: V3::new(-0.6, 0.8, 0.1),
        base: P3::new(2.0, -0.5, 3.0),
        ..down
    };
    check(&m, -V3::z(), &skew);
}

#[test]
fn oblique_directions_and_lattices_match_the_bvh() {
    let meshes = [
        solids::sphere(P3::new(0.3, -0.2, 0.1), 2.0, 48, 24),
        solids::torus(P3::origin(), 3.0, 1.0, 48, 24),
        solids::cuboid(P3::new(-1.0, -2.0, -0.5), P3::new(1.0, 2.0, 0.5)),
    ];
    let us = steps(-3.3, 0.11, 61);
    let vs = steps(-3.4, 0.13, 53);
    for m in &meshes {
        for d in [
            V3::new(0.3, -0.2, -1.0),
            V3::new(1.0, 0.0, 0.0),
            V3::new(0.0, -0.5, 0.0),
            V3::new(-0.7, 0.7, 0.1),
        ] {
            // The lattice plane across the direction, behind the mesh, and
            // one through the mesh (origins inside: t >= 0 cuts the rest).
            let (e1, e2) = super::super::basis(&d);
            for back in [8.0, 0.0] {
                let l = Lattice {
                    base: P3::origin() - d.normalize() * back,
                    eu: e1,
                    ev: e2,
                    us: &us,
                    vs: &vs,
                };
                let hits = check(m, d, &l);
                assert!(hits > 100, "{hits}");
            }
            // A lattice plane not across the direction.
            let l = Lattice {
                base: P3::new(-5.0, 4.0, 6.0),
                eu: (e1 + d * 0.3).normalize(),
                ev: e2 - d * 0.2,
                us: &us,
                vs: &vs,
            };
            check(m, d, &l);
        }
        // Rays aimed exactly at every vertex: the vertices' own coordinates
        // as the lattice's.
        let xs: Vec<f64> = m.vertices.iter().map(|v| v.x).collect();
        let ys: Vec<f64> = m.vertices.iter().take(40).map(|v| v.y).collect();
        let l = Lattice {
            base: P3::new(0.0, 0.0, 10.0),
            eu: V3::x(),
            ev: V3::y(),
            us: &xs,
            vs: &ys,
        };
        check(m, -V3::z(), &l);
    }
}

#[test]
fn degenerate_triangles_and_unusual_lattices() {
    for seed in 1..4u64 {
        let m = soup(seed * 0x9e37_79b9_7f4a_7c15, 300);
        let us = steps(-2.5, 0.05, 101);
        let vs = steps(-2.5, 0.07, 72);
        for d in [-V3::z(), V3::new(0.2, 0.1, -1.0), V3::new(1.0, 0.4, -0.3)] {
            let (e1, e2) = super::super::basis(&d);
            let l = Lattice {
                base: P3::origin() - d.normalize() * 5.0,
                eu: e1,
                ev: e2,
                us: &us,
                vs: &vs,
            };
            assert!(check(&m, d, &l) > 100);
        }
        // Unsorted, repeated and non-finite coordinates.
        let mut us2 = us.clone();
        us2.reverse();
        us2.extend([0.3, 0.3, f64::NAN, f64::INFINITY, -0.0]);
        let vs2 = [1.0, -1.0, 0.0, f64::NAN, 1.0, 0.5];
        let l = Lattice {
            base: P3::new(0.0, 0.0, 5.0),
            eu: V3::x(),
            ev: V3::y(),
            us: &us2,
            vs: &vs2,
        };
        check(&m, -V3::z(), &l);
        // Axes in the plane of the direction: one ray at a time.
        let l = Lattice {
            base: P3::new(0.0, 0.0, 5.0),
            eu: V3::x(),
            ev: V3::z(),
            us: &us,
            vs: &vs,
        };
        check(&m, -V3::z(), &l);
    }
    // Nothing to hit, no rays, no direction.
    let cube = solids::cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
    let one = [0.5];
    let l = Lattice {
        base: P3::new(0.0, 0.0, 2.0),
        eu: V3::x(),
        ev: V3::y(),
        us: &one,
        vs: &one,
    };
    assert!(ParallelRays::new(&Mesh::default(), -V3::z()).first_hits_lattice(&l)[0].is_none());
    assert!(ParallelRays::new(&cube, V3::zeros()).first_hits_lattice(&l)[0].is_none());
    assert_eq!(
        ParallelRays::new(&cube, -V3::z()).first_hits_lattice(&l)[0].unwrap().t,
        1.0
    );
    assert!(
        ParallelRays::new(&cube, -V3::z())
            .first_hits_lattice(&Lattice { us: &[], ..l })
            .is_empty()
    );
}

/// The hidden-face cull (`row_hidden`) skips a triangle only when every
/// ray finds it behind a nearer hit: layers of squares one behind the
/// other, some at exactly the same depth, some a hair (1e-12 mm) behind or
/// in front, listed far layers first and near first, cast at from both
/// sides and obliquely. (Ties between triangles that share an edge, where
/// the lower index must win, are in the closed-mesh tests above: a cull
/// that skipped equal depths fails those.)
#[test]
fn hidden_layers_and_ties_match_the_bvh() {
    let square = |z: f64, tilt: f64| {
        let c = |x: f64, y: f64| P3::new(x, y, z + tilt * x);
        [
            Triangle {
                a: c(-1.0, -1.0),
                b: c(1.0, -1.0),
                c: c(1.0, 1.0),
            },
            Triangle {
                a: c(-1.0, -1.0),
                b: c(1.0, 1.0),
                c: c(-1.0, 1.0),
            },
        ]
    };
    let depths = [0.0, 0.0, 1e-12, -1e-12, 0.5, 0.5, -3.0, 2.0];
    for reversed in [false, true] {
        let mut tris: Vec<Triangle> = Vec::new();
        for (k, &z) in depths.iter().enumerate() {
            tris.extend(square(z, 0.01 * (k % 3) as f64));
        }
        if reversed {
            tris.reverse();
        }
        let m = Mesh::from_triangles(&tris);
        let us = steps(-1.3, 0.1, 27);
        for (dir, z0) in [(-V3::z(), 10.0), (V3::z(), -10.0)] {
            let l = Lattice {
                base: P3::new(0.0, 0.0, z0),
                eu: V3::x(),
                ev: V3::y(),
                us: &us,
                vs: &us,
            };
            assert!(check(&m, dir, &l) > 0);
        }
        let dir = V3::new(0.2, -0.1, -1.0).normalize();
        let l = Lattice {
            base: P3::new(0.0, 0.0, 10.0),
            eu: V3::x(),
            ev: V3::y(),
            us: &us,
            vs: &us,
        };
        assert!(check(&m, dir, &l) > 0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Random meshes, directions and lattices (steps, offsets, extents past
    /// the mesh): the BVH's answers.
    #[test]
    fn random_lattices_match_the_bvh(
        seed in 0u64..1_000_000,
        kind in 0u32..4,
        dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0,
        axis in 0usize..4,
        su in 0.01f64..0.4, sv in 0.01f64..0.4,
        ou in -4.0f64..0.0, ov in -4.0f64..0.0,
        nu in 1usize..40, nv in 1usize..40,
    ) {
        let m = match kind {
            0 => solids::sphere(P3::new(0.1, 0.2, -0.3), 1.5, 20, 10),
            1 => solids::torus(P3::origin(), 2.0, 0.7, 24, 12),
            2 => crate::mesh::bvh::tests::terrain_block(6, 0.5),
            _ => soup(seed, 120),
        };
        let d = match axis {
            0 => V3::new(dx, dy, dz),
            1 => V3::new(0.0, 0.0, if dz < 0.0 { -1.0 } else { 1.0 }),
            2 => V3::new(dx, 0.0, 0.0),
            _ => V3::new(0.0, dy, dz),
        };
        prop_assume!(d.norm() > 1e-3);
        let (e1, e2) = super::super::basis(&d);
        let us = steps(ou, su, nu);
        let vs = steps(ov, sv, nv);
        let l = Lattice { base: P3::origin() - d.normalize() * 6.0, eu: e1, ev: e2, us: &us, vs: &vs };
        check(&m, d, &l);
    }
}
