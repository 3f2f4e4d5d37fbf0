//! The lattice rays (`ParallelRays::first_hits_lattice`) against the BVH's
//! `first_hit` on the meshes other programs wrote (the shared corpus's STL
//! and OBJ files): every ray of a lattice over each mesh, cast along the
//! axes and obliquely, must give the BVH's hit bit for bit. The lattices
//! include rays exactly through the meshes' own vertices (their
//! coordinates as lattice coordinates), where a shared edge or vertex must
//! be hit by one of its triangles and the test is most fragile. Without
//! the corpus the test skips.

use microcam::geometry::{P3, V3};
use microcam::mesh::bvh::{Bvh, Ray};
use microcam::mesh::parallel::{Lattice, ParallelRays};

/// At most `n` values of `v` (sorted, distinct), evenly picked.
fn pick(mut v: Vec<f64>, n: usize) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v.dedup();
    if v.len() <= n {
        return v;
    }
    (0..n).map(|k| v[k * (v.len() - 1) / (n - 1)]).collect()
}

/// `n` evenly spaced values over `[lo, hi]` widened by a tenth each side.
fn spread(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let pad = 0.1 * (hi - lo).max(1e-3);
    let (lo, hi) = (lo - pad, hi + pad);
    (0..n).map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64).collect()
}

/// Casts the lattice both ways and compares ray by ray; returns the hits.
fn compare(name: &str, bvh: &Bvh, pr: &ParallelRays, dir: V3, l: &Lattice) -> usize {
    let got = pr.first_hits_lattice(l);
    let depths = pr.first_depths_lattice(l);
    let mut hits = 0;
    for j in 0..l.vs.len() {
        for i in 0..l.us.len() {
            let k = j * l.us.len() + i;
            let want = bvh.first_hit(&Ray::new(l.origin(i, j), dir));
            assert_eq!(got[k], want, "{name}: ray ({i}, {j}) along {dir:?}");
            assert_eq!(
                depths[k].to_bits(),
                want.map_or(f64::INFINITY, |h| h.t).to_bits(),
                "{name}: depth of ray ({i}, {j}) along {dir:?}"
            );
            hits += want.is_some() as usize;
        }
    }
    hits
}

#[test]
fn lattice_rays_equal_the_bvh_on_corpus_meshes() {
    let Some(read) = microcam::mesh::read_corpus_meshes() else {
        microcam::corpus::skip("lattice_rays_equal_the_bvh_on_corpus_meshes");
        return;
    };
    let mut total_hits = 0;
    for (f, m) in &read {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let bvh = Bvh::new(m);
        let b = m.bbox();
        let (lo, hi) = (b.min, b.max);
        // Straight down: rays through every vertex's x and y (up to 60 of
        // each), and an even grid over the box.
        let dir = V3::new(0.0, 0.0, -1.0);
        let pr = ParallelRays::new(m, dir);
        let base = P3::new(0.0, 0.0, hi.z + 1.0);
        let (ex, ey) = (V3::x(), V3::y());
        for (us, vs) in [
            (
                pick(m.vertices.iter().map(|p| p.x).collect(), 60),
                pick(m.vertices.iter().map(|p| p.y).collect(), 60),
            ),
            (spread(lo.x, hi.x, 70), spread(lo.y, hi.y, 50)),
        ] {
            let l = Lattice {
                base,
                eu: ex,
                ev: ey,
                us: &us,
                vs: &vs,
            };
            total_hits += compare(&name, &bvh, &pr, dir, &l);
        }
        // Along +x, through the vertices' y and z.
        let dir = V3::new(1.0, 0.0, 0.0);
        let pr = ParallelRays::new(m, dir);
        let us = pick(m.vertices.iter().map(|p| p.y).collect(), 50);
        let vs = pick(m.vertices.iter().map(|p| p.z).collect(), 50);
        let l = Lattice {
            base: P3::new(lo.x - 1.0, 0.0, 0.0),
            eu: ey,
            ev: V3::z(),
            us: &us,
            vs: &vs,
        };
        total_hits += compare(&name, &bvh, &pr, dir, &l);
        // Obliquely, from a plane above the part, on an even grid.
        let dir = V3::new(0.3, -0.5, -0.8).normalize();
        let pr = ParallelRays::new(m, dir);
        let span = (hi - lo).norm().max(1e-3);
        let (us, vs) = (spread(-span, span, 60), spread(-span, span, 60));
        let c = P3::from((lo.coords + hi.coords) * 0.5);
        let l = Lattice {
            base: c - dir * (2.0 * span),
            eu: V3::new(1.0, 0.0, 0.0),
            ev: V3::new(0.0, 1.0, 0.0),
            us: &us,
            vs: &vs,
        };
        total_hits += compare(&name, &bvh, &pr, dir, &l);
    }
    let meshes = read.len();
    assert!(meshes >= 3, "only {meshes} corpus meshes read");
    assert!(total_hits > 0, "no ray hit any corpus mesh");
    eprintln!("{meshes} corpus meshes, {total_hits} rays hit");
    microcam::corpus::record("lattice_rays_equal_the_bvh_on_corpus_meshes", meshes);
}
