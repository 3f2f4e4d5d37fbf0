use super::*;
use crate::mesh::Mesh;
use crate::mesh::solids;
use build::{MAX_LEAF, PAR_MIN};
use proptest::prelude::*;

fn brute_first(m: &Mesh, ray: &Ray) -> Option<f64> {
    // Möller-Trumbore, for comparison away from edges.
    let mut best: Option<f64> = None;
    for t in m.iter_triangles() {
        let e1 = t.b - t.a;
        let e2 = t.c - t.a;
        let p = ray.dir.cross(&e2);
        let det = e1.dot(&p);
        if det.abs() < 1e-300 {
            continue;
        }
        let s = ray.origin - t.a;
        let u = s.dot(&p) / det;
        let q = s.cross(&e1);
        let v = ray.dir.dot(&q) / det;
        let tt = e2.dot(&q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt >= ray.t_min && tt <= ray.t_max && best.is_none_or(|b| tt < b) {
            best = Some(tt);
        }
    }
    best
}

#[test]
fn rays_hit_an_analytic_sphere_and_box() {
    let r = 2.0;
    let m = solids::sphere(P3::origin(), r, 256, 128);
    let bvh = Bvh::new(&m);
    // From outside towards the centre: first hit at distance ~ 10 - r
    // (the mesh is inscribed, so at most the chord sag further).
    let sag = r * (1.0 - (std::f64::consts::PI / 128.0).cos());
    for k in 0..50 {
        let a = k as f64 * 0.37;
        let b = k as f64 * 0.11 - 2.0;
        let d = V3::new(a.cos() * b.cos(), a.sin() * b.cos(), b.sin());
        let ray = Ray::new(P3::origin() + d * 10.0, -d);
        let h = bvh.first_hit(&ray).unwrap();
        assert!(h.t >= 10.0 - r - 1e-12 && h.t <= 10.0 - r + sag + 1e-12, "{}", h.t);
        assert!(h.front);
        let all = bvh.all_hits(&ray);
        assert_eq!(all.len(), 2);
        assert!(!all[1].front);
        assert!((all[1].t - (10.0 + r)).abs() <= sag + 1e-12);
    }
    let bx = solids::cuboid(P3::new(-1.0, -2.0, -3.0), P3::new(1.0, 2.0, 3.0));
    let bvh = Bvh::new(&bx);
    let h = bvh
        .first_hit(&Ray::new(P3::new(0.3, 0.2, 10.0), V3::new(0.0, 0.0, -2.0)))
        .unwrap();
    assert!((h.t - 3.5).abs() < 1e-15);
    assert!(bx.triangle(h.triangle as usize).normal().unwrap().z > 0.99);
    assert!(
        bvh.first_hit(&Ray::new(P3::new(1.5, 0.0, 10.0), V3::new(0.0, 0.0, -1.0)))
            .is_none()
    );
    // t range respected.
    let mut ray = Ray::new(P3::new(0.0, 0.0, 10.0), V3::new(0.0, 0.0, -1.0));
    ray.t_max = 6.0;
    assert!(bvh.first_hit(&ray).is_none());
    ray.t_max = 7.0;
    assert_eq!(bvh.first_hit(&ray).unwrap().t, 7.0);
}

#[test]
fn rays_through_edges_and_vertices_count_once() {
    // The box's faces are split along diagonals; rays straight down its
    // grid lines and diagonals pass exactly through edges and vertices.
    let bx = solids::cuboid(P3::new(0.0, 0.0, 0.0), P3::new(4.0, 4.0, 4.0));
    let bvh = Bvh::new(&bx);
    for &(x, y) in &[
        (0.0, 0.0),
        (2.0, 2.0),
        (1.0, 1.0),
        (4.0, 4.0),
        (0.0, 2.0),
        (3.0, 3.0),
        (4.0, 0.0),
        (2.0, 0.0),
    ] {
        for d in [V3::new(0.0, 0.0, -1.0), V3::new(0.0, 0.0, 1.0)] {
            let ray = Ray::new(P3::new(x, y, 2.0) - d * 10.0, d);
            let n = bvh.count_hits(&ray);
            assert!(n.is_multiple_of(2), "({x},{y}) {d:?}: {n} hits");
        }
    }
    // A fine sphere, rays aimed exactly at vertices: even counts.
    let s = solids::sphere(P3::origin(), 1.0, 32, 16);
    let bvh = Bvh::new(&s);
    for (i, v) in s.vertices.iter().enumerate() {
        let d = (v - P3::new(0.1, 0.2, 0.05)).normalize();
        let ray = Ray::new(P3::new(0.1, 0.2, 0.05) - d * 5.0, d);
        assert_eq!(bvh.count_hits(&ray) % 2, 0, "vertex {i}");
    }
    assert!(bvh.contains(&P3::new(0.1, 0.2, 0.05)));
    assert!(!bvh.contains(&P3::new(1.1, 0.2, 0.05)));
}

#[test]
fn batch_queries_match_single_ones() {
    let s = solids::torus(P3::new(0.5, 0.0, 0.0), 3.0, 1.0, 48, 24);
    let bvh = Bvh::new(&s);
    let rays: Vec<Ray> = (0..2000)
        .map(|i| {
            let a = i as f64 * 0.618;
            Ray::new(
                P3::new(a.cos() * 8.0, a.sin() * 8.0, (i % 7) as f64 * 0.3 - 0.95),
                V3::new(-a.cos(), -a.sin(), 0.01 * (i % 5) as f64),
            )
        })
        .collect();
    let b = bvh.first_hits(&rays);
    for (r, h) in rays.iter().zip(&b) {
        assert_eq!(*h, bvh.first_hit(r));
        let bf = brute_first(&s, r);
        match (h, bf) {
            (Some(h), Some(t)) => assert!((h.t - t).abs() < 1e-9, "{} vs {t}", h.t),
            (None, None) => {}
            _ => panic!("bvh {h:?} vs brute {bf:?}"),
        }
    }
    let all = bvh.all_hits_batch(&rays);
    assert!(all.iter().all(|h| h.len().is_multiple_of(2)));
    let pts: Vec<P3> = rays.iter().map(|r| r.origin).collect();
    let nb = bvh.nearest_batch(&pts);
    assert_eq!(nb[3], bvh.nearest(&pts[3]));
}

fn brute_nearest(m: &Mesh, p: &P3) -> f64 {
    m.iter_triangles()
        .map(|t| (closest_on_triangle(p, &t.a, &t.b, &t.c) - p).norm())
        .fold(f64::INFINITY, f64::min)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn segment_queries_visit_every_triangle_within_reach_once(
        x0 in -6.0f64..6.0, y0 in -6.0f64..6.0, z0 in -6.0f64..6.0,
        x1 in -6.0f64..6.0, y1 in -6.0f64..6.0, z1 in -6.0f64..6.0,
        r in 0.0f64..1.5, seed in 0u32..3,
    ) {
        let m = match seed {
            0 => solids::sphere(P3::new(0.3, 0.0, 0.0), 2.0, 24, 12),
            1 => solids::torus(P3::origin(), 3.0, 1.0, 24, 12),
            _ => solids::cylinder(P3::new(0.0, 0.0, -2.0), P3::new(1.0, 2.0, 3.0), 1.5, 20, 4),
        };
        let bvh = Bvh::new(&m);
        let (p0, p1) = (P3::new(x0, y0, z0), P3::new(x1, y1, z1));
        let mut seen = vec![0u32; m.triangles.len()];
        bvh.for_each_near_segment(p0, p1, r, |i, c| {
            seen[i as usize] += 1;
            let t = m.triangle(i as usize);
            assert_eq!(*c, [t.a, t.b, t.c]);
        });
        prop_assert!(seen.iter().all(|&n| n <= 1));
        // Points along the segment: a triangle within r of any of them is
        // within r of the segment, so it must have been visited.
        for k in 0..=200 {
            let p = p0 + (p1 - p0) * (k as f64 / 200.0);
            for (i, t) in m.iter_triangles().enumerate() {
                if (closest_on_triangle(&p, &t.a, &t.b, &t.c) - p).norm() <= r {
                    prop_assert!(seen[i] == 1, "triangle {} within {} of {:?} not visited", i, r, p);
                }
            }
        }
    }

    #[test]
    fn nearest_point_matches_brute_force(x in -6.0f64..6.0, y in -6.0f64..6.0, z in -6.0f64..6.0, seed in 0u32..4) {
        let m = match seed {
            0 => solids::sphere(P3::new(0.3, 0.0, 0.0), 2.0, 24, 12),
            1 => solids::torus(P3::origin(), 3.0, 1.0, 24, 12),
            2 => solids::cylinder(P3::new(0.0, 0.0, -2.0), P3::new(1.0, 2.0, 3.0), 1.5, 20, 4),
            _ => solids::cuboid(P3::new(-1.0, -2.0, -0.5), P3::new(1.0, 2.0, 0.5)),
        };
        let bvh = Bvh::new(&m);
        let p = P3::new(x, y, z);
        let n = bvh.nearest(&p).unwrap();
        let bf = brute_nearest(&m, &p);
        prop_assert!((n.distance - bf).abs() < 1e-12, "{} vs {}", n.distance, bf);
        prop_assert!(((n.point - p).norm() - n.distance).abs() < 1e-12);
        let t = m.triangle(n.triangle as usize);
        prop_assert!(((closest_on_triangle(&p, &t.a, &t.b, &t.c) - p).norm() - bf).abs() < 1e-12);
    }

    #[test]
    fn random_rays_agree_with_brute_force(ox in -6.0f64..6.0, oy in -6.0f64..6.0, oz in -6.0f64..6.0,
                                          dx in -1.0f64..1.0, dy in -1.0f64..1.0, dz in -1.0f64..1.0) {
        let m = solids::sphere(P3::new(0.3, 0.0, 0.0), 2.0, 24, 12);
        let bvh = Bvh::new(&m);
        prop_assume!(dx.abs() + dy.abs() + dz.abs() > 1e-3);
        let ray = Ray::new(P3::new(ox, oy, oz), V3::new(dx, dy, dz));
        let h = bvh.first_hit(&ray).map(|h| h.t);
        let b = brute_first(&m, &ray);
        match (h, b) {
            (Some(a), Some(b)) => prop_assert!((a - b).abs() < 1e-9),
            (None, None) => {}
            _ => prop_assert!(false, "{h:?} vs {b:?}"),
        }
        let inside = (P3::new(ox, oy, oz) - P3::new(0.3, 0.0, 0.0)).norm() < 1.9;
        if inside {
            prop_assert_eq!(bvh.count_hits(&ray), 1);
        }
    }
}

#[test]
fn empty_and_large_builds() {
    let bvh = Bvh::new(&Mesh::default());
    assert!(bvh.is_empty());
    assert!(bvh.first_hit(&Ray::new(P3::origin(), V3::x())).is_none());
    assert!(bvh.nearest(&P3::origin()).is_none());
    // Big enough for the parallel build path.
    let m = solids::sphere(P3::origin(), 1.0, 256, 80);
    assert!(m.triangles.len() > PAR_MIN);
    let bvh = Bvh::new(&m);
    let mut ids = bvh.ids.clone();
    ids.sort();
    assert!(ids.iter().enumerate().all(|(i, &t)| i as u32 == t));
    let ray = Ray::new(P3::new(0.0, 0.0, 5.0), V3::new(0.01, 0.02, -1.0));
    let h = bvh.first_hit(&ray).unwrap();
    let rr = ray.at(h.t).coords.norm();
    assert!(rr <= 1.0 + 1e-12 && rr >= (std::f64::consts::PI / 80.0).cos(), "{rr}");
    // Degenerate mesh: every triangle at one point.
    let p = P3::new(1.0, 1.0, 1.0);
    let d = Mesh::from_triangles(&vec![crate::mesh::Triangle::new(p, p, p); 100]);
    let bvh = Bvh::new(&d);
    assert!(bvh.first_hit(&Ray::new(P3::origin(), V3::new(1.0, 1.0, 1.0))).is_none());
    assert!((bvh.nearest(&P3::origin()).unwrap().distance - 3f64.sqrt()).abs() < 1e-12);
}

/// The terrain block as the verification tool sees a design part: written
/// to a binary STL and read back, f32 corners, three per triangle (a soup).
pub(crate) fn terrain_block(n: usize, h: f64) -> Mesh {
    let m = solids::terrain_block(n, h);
    let bytes = crate::mesh::read_stl::write_binary(&m, "terrain");
    crate::mesh::read_stl::read_stl(&bytes).unwrap().mesh
}

/// Top of the block over (x, y) by brute force over closed triangles
/// (projected point-in-triangle with inclusive edges, exact for the f32
/// corners on this grid).
pub(crate) fn brute_top(m: &Mesh, x: f64, y: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    for t in m.iter_triangles() {
        let e = |p: &P3, q: &P3| (q.x - p.x) * (y - p.y) - (q.y - p.y) * (x - p.x);
        let (u, v, w) = (e(&t.b, &t.c), e(&t.c, &t.a), e(&t.a, &t.b));
        let det = u + v + w;
        if det == 0.0 || !((u >= 0.0 && v >= 0.0 && w >= 0.0) || (u <= 0.0 && v <= 0.0 && w <= 0.0)) {
            continue;
        }
        let z = (u * t.a.z + v * t.b.z + w * t.c.z) / det;
        best = Some(best.map_or(z, |b: f64| b.max(z)));
    }
    best
}

#[test]
fn vertical_rays_through_vertices_and_edges_of_a_closed_mesh() {
    let n = 12;
    let h = 0.25;
    let m = terrain_block(n, h);
    let bvh = Bvh::new(&m);
    let mut checked = 0;
    // Every vertex, every edge midpoint (axis and diagonal) and every cell
    // centre of the grid, boundary included.
    for i2 in 0..=2 * n {
        for j2 in 0..=2 * n {
            let (x, y) = (i2 as f64 * h / 2.0, j2 as f64 * h / 2.0);
            for up in [false, true] {
                let d = if up { V3::z() } else { -V3::z() };
                let o = P3::new(x, y, if up { -5.0 } else { 5.0 });
                let ray = Ray::new(o, d);
                let want = brute_top(&m, x, y).unwrap();
                let hit = bvh.first_hit(&ray);
                let hit = hit.unwrap_or_else(|| panic!("({x}, {y}) up {up}: no hit"));
                let got = if up { 0.0 } else { ray.at(hit.t).z };
                assert_eq!(got, if up { 0.0 } else { want }, "({x}, {y}) up {up}");
                // From outside: an even number of crossings; from inside
                // (origin between bottom and top): odd.
                let n_out = bvh.count_hits(&ray);
                assert!(n_out.is_multiple_of(2), "({x}, {y}) up {up}: {n_out} crossings");
                let inside = Ray::new(P3::new(x, y, 0.5), d);
                let n_in = bvh.count_hits(&inside);
                let interior = i2 > 0 && j2 > 0 && i2 < 2 * n && j2 < 2 * n;
                if interior {
                    assert_eq!(n_in, 1, "({x}, {y}) up {up} from inside");
                    assert_eq!(bvh.all_hits(&ray).len(), 2, "({x}, {y}) up {up}");
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 2 * (2 * n + 1) * (2 * n + 1));
    // Oblique rays aimed exactly at every vertex from a point inside: odd.
    let c = P3::new(n as f64 * h * 0.5 + 0.013, n as f64 * h * 0.5 - 0.007, 0.41);
    for v in &m.vertices {
        let d = v - c;
        let n_in = bvh.count_hits(&Ray::new(c, d));
        assert_eq!(n_in % 2, 1, "vertex {v:?}");
        assert!(bvh.first_hit(&Ray::new(c, d)).is_some(), "vertex {v:?}");
    }
}

/// The batch call casts large batches in a sorted order through the 4-wide
/// tree: the same answers as one by one, and as brute force, on random
/// rays of every kind (outside and inside, axis-aligned, some with a
/// `t_max`), in parallel and on one thread.
#[test]
fn sorted_batches_of_random_rays_match_single_rays_and_brute_force() {
    let m = solids::torus(P3::new(0.2, -0.1, 0.3), 3.0, 1.0, 40, 20);
    let bvh = Bvh::new(&m);
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut rays = Vec::new();
    for i in 0..6000 {
        let o = P3::new(rnd() * 6.0, rnd() * 6.0, rnd() * 3.0);
        let mut d = V3::new(rnd(), rnd(), rnd());
        match i % 7 {
            0 => d = V3::new(0.0, 0.0, if rnd() < 0.0 { -1.0 } else { 1.0 }),
            1 => d.x = 0.0,
            2 => d = (P3::new(rnd() * 4.0, rnd() * 4.0, rnd()) - o) * 0.37,
            _ => {}
        }
        let mut r = Ray::new(o, d);
        if i % 11 == 0 {
            r.t_max = rnd().abs() * 3.0;
        }
        rays.push(r);
    }
    assert!(rays.len() >= 4096, "the sorted path needs a big batch");
    let single: Vec<Option<Hit>> = rays.iter().map(|r| bvh.first_hit(r)).collect();
    assert_eq!(bvh.first_hits(&rays), single);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    assert_eq!(pool.install(|| bvh.first_hits(&rays)), single);
    let mut hits = 0;
    for (r, h) in rays.iter().zip(&single) {
        let b = brute_first(&m, r);
        match (h, b) {
            (Some(h), Some(t)) => {
                assert!((h.t - t).abs() < 1e-9, "{r:?}: {} vs {t}", h.t);
                hits += 1;
            }
            (None, None) => {}
            _ => panic!("{r:?}: bvh {h:?} vs brute {b:?}"),
        }
        // Every crossing counted, as brute force counts them.
        if r.t_max.is_infinite() && off_axis(r) {
            assert_eq!(bvh.all_hits(r).len(), brute_count(&m, r), "{r:?}");
        }
    }
    assert!(hits > 1000, "{hits}");
}

/// Rays away from edges (brute-force Möller-Trumbore is not watertight):
/// every ray of the test is, with probability 1, except the axis-aligned
/// ones through the torus' vertex rings, which are skipped.
fn off_axis(r: &Ray) -> bool {
    r.dir.x != 0.0 && r.dir.y != 0.0
}

fn brute_count(m: &Mesh, ray: &Ray) -> usize {
    m.iter_triangles()
        .filter(|t| {
            let e1 = t.b - t.a;
            let e2 = t.c - t.a;
            let p = ray.dir.cross(&e2);
            let det = e1.dot(&p);
            if det.abs() < 1e-300 {
                return false;
            }
            let s = ray.origin - t.a;
            let u = s.dot(&p) / det;
            let q = s.cross(&e1);
            let v = ray.dir.dot(&q) / det;
            let tt = e2.dot(&q) / det;
            u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt >= ray.t_min && tt <= ray.t_max
        })
        .count()
}

/// Every node's box holds its subtree's triangles, the leaves hold at most
/// `MAX_LEAF` and together each triangle exactly once.
fn check_tree(m: &Mesh, bvh: &Bvh) {
    let mut seen = vec![0u32; m.triangles.len()];
    let mut todo = vec![0usize];
    while let Some(i) = todo.pop() {
        let nd = &bvh.nodes[i];
        let (lo, hi) = (nd.a as usize, (nd.a + nd.n) as usize);
        let tris: Vec<usize> = if nd.n > 0 {
            assert!(nd.n as usize <= MAX_LEAF, "leaf of {} triangles", nd.n);
            bvh.ids[lo..hi].iter().map(|&t| t as usize).collect()
        } else {
            todo.push(i + 1);
            todo.push(nd.a as usize);
            Vec::new()
        };
        for t in tris {
            seen[t] += 1;
            for &v in &m.triangles[t] {
                let p = m.vertices[v as usize];
                for k in 0..3 {
                    assert!(
                        nd.min[k] as f64 <= p[k] && p[k] <= nd.max[k] as f64,
                        "node {i} misses triangle {t}"
                    );
                }
            }
        }
    }
    assert!(seen.iter().all(|&c| c == 1), "triangles seen {seen:?}");
}

#[test]
fn small_nodes_split_by_the_exact_sweep_keep_every_triangle_once() {
    // 1 to 40 triangles (the exact sweep takes nodes of 3 to 16): spread
    // out, stacked on one another (equal centroids), and a mix of both.
    for n in 1..=40usize {
        for kind in 0..3 {
            let tris: Vec<_> = (0..n)
                .map(|i| {
                    let s = match kind {
                        0 => i as f64,
                        1 => 0.0,
                        _ => (i % 3) as f64,
                    };
                    let o = P3::new(s, 0.5 * s, -s);
                    crate::mesh::Triangle::new(o, o + V3::new(1.0, 0.0, 0.0), o + V3::new(0.0, 1.0, 0.2 * i as f64))
                })
                .collect();
            let m = Mesh::from_triangles(&tris);
            let bvh = Bvh::new(&m);
            check_tree(&m, &bvh);
            for i in 0..n {
                let t = m.triangle(i);
                let c = P3::from((t.a.coords + t.b.coords + t.c.coords) / 3.0);
                let ray = Ray::new(c + V3::new(0.013, 0.007, 50.0), V3::new(0.0, 0.0, -1.0));
                let (got, want) = (bvh.first_hit(&ray).map(|h| h.t), brute_first(&m, &ray));
                assert!(
                    got.is_some() && want.is_some_and(|w| (got.unwrap() - w).abs() < 1e-9),
                    "n {n} kind {kind} ray {i}: {got:?} vs {want:?}"
                );
            }
        }
    }
    let m = solids::sphere(P3::origin(), 1.0, 256, 80);
    check_tree(&m, &Bvh::new(&m));
}

#[test]
fn corpus_meshes_build_sound_trees() {
    // The trees of the meshes other programs wrote: long thin facets,
    // stacked and degenerate triangles, the exact sweep's small nodes.
    let Some(meshes) = crate::mesh::read_corpus_meshes() else {
        crate::corpus::skip("corpus_meshes_build_sound_trees");
        return;
    };
    for (_, m) in &meshes {
        check_tree(m, &Bvh::new(m));
    }
    assert!(!meshes.is_empty(), "no corpus mesh was read");
    crate::corpus::record("corpus_meshes_build_sound_trees", meshes.len());
}

#[test]
fn the_ray_order_keys_interleave_and_sort_as_written_out_again() {
    // SPREAD6 against the bit-by-bit interleave it replaces.
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    for _ in 0..2000 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let c: [u32; 6] = std::array::from_fn(|k| ((x >> (5 * k)) & 31) as u32);
        let mut slow = 0u32;
        for bit in (0..5).rev() {
            for ck in c {
                slow = (slow << 1) | ((ck >> bit) & 1);
            }
        }
        let fast = c
            .iter()
            .enumerate()
            .fold(0u32, |m, (k, &ck)| m | super::SPREAD6[ck as usize] << (5 - k));
        assert_eq!(fast, slow, "{c:?}");
    }
    // The radix sort against a stable sort of the high 32 bits, with
    // keys that leave some passes constant and some not.
    for n in [0usize, 1, 7, 5000] {
        let mut v: Vec<u64> = (0..n as u64)
            .map(|i| {
                let h = i.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40;
                ((h & 0x3ff_0f0f) << 32) | i
            })
            .collect();
        let mut expect = v.clone();
        expect.sort_by_key(|x| x >> 32);
        super::radix_sort_high32(&mut v);
        assert_eq!(v, expect, "{n}");
    }
}
