use super::*;
use crate::mesh::bvh::Bvh;
use crate::mesh::solids;

/// Both paths give the same hit, bit for bit.
fn same(bvh: &Bvh, pr: &ParallelRays, o: &P3) {
    let want = bvh.first_hit(&Ray::new(*o, pr.dir()));
    let got = pr.first_hit(o);
    assert_eq!(got, want, "origin {o:?} dir {:?}", pr.dir());
}

#[test]
fn grid_rays_through_vertices_and_edges_match_the_bvh() {
    let n = 16;
    let h = 0.25;
    let m = crate::mesh::bvh::tests::terrain_block(n, h);
    let bvh = Bvh::new(&m);
    let down = ParallelRays::new(&m, -V3::z());
    let up = ParallelRays::new(&m, V3::z() * 2.0);
    assert!(down.cells() > 100 && down.references() >= m.triangles.len());
    // Every vertex, edge midpoint and cell centre, the rim included, and
    // points just outside: the same hit from both paths, and the top of
    // the block (by brute force) wherever the point is over it.
    for i4 in -2..=4 * n as i64 + 2 {
        for j4 in -2..=4 * n as i64 + 2 {
            let (x, y) = (i4 as f64 * h / 4.0, j4 as f64 * h / 4.0);
            let o = P3::new(x, y, 3.0);
            same(&bvh, &down, &o);
            same(&bvh, &up, &P3::new(x, y, -3.0));
            let over = (0..=4 * n as i64).contains(&i4) && (0..=4 * n as i64).contains(&j4);
            let hit = down.first_hit(&o);
            assert_eq!(hit.is_some(), over, "({x}, {y})");
            if over {
                let want = crate::mesh::bvh::tests::brute_top(&m, x, y).unwrap();
                assert_eq!(3.0 - hit.unwrap().t, want, "({x}, {y})");
                assert_eq!(up.first_hit(&P3::new(x, y, -3.0)).unwrap().t, 1.5);
            }
        }
    }
    let all: Vec<P3> = (0..500)
        .map(|k| P3::new(k as f64 * 0.0091, k as f64 * 0.0077, 2.0))
        .collect();
    let batch = down.first_hits(&all);
    for (o, h) in all.iter().zip(&batch) {
        assert_eq!(*h, down.first_hit(o));
    }
}

#[test]
fn oblique_directions_match_the_bvh() {
    let meshes = [
        solids::sphere(P3::new(0.3, -0.2, 0.1), 2.0, 48, 24),
        solids::torus(P3::origin(), 3.0, 1.0, 48, 24),
        solids::cuboid(P3::new(-1.0, -2.0, -0.5), P3::new(1.0, 2.0, 0.5)),
    ];
    for m in &meshes {
        let bvh = Bvh::new(m);
        for d in [
            V3::new(0.3, -0.2, -1.0),
            V3::new(1.0, 0.0, 0.0),
            V3::new(0.0, -0.5, 0.0),
            V3::new(-0.7, 0.7, 0.1),
        ] {
            let pr = ParallelRays::new(m, d);
            let (e1, e2) = basis(&d);
            assert!(e1.dot(&d).abs() < 1e-12 && e2.dot(&d).abs() < 1e-12 && e1.dot(&e2).abs() < 1e-12);
            let mut hits = 0;
            for k in 0..2000 {
                let (a, b) = ((k % 50) as f64 * 0.13 - 3.2, (k / 50) as f64 * 0.17 - 3.4);
                let o = P3::origin() - d.normalize() * 8.0 + e1 * a + e2 * b;
                same(&bvh, &pr, &o);
                hits += pr.first_hit(&o).is_some() as usize;
                // Origins inside the mesh too (t_min = 0 cuts the rest).
                same(&bvh, &pr, &(P3::origin() + e1 * a * 0.3 + e2 * b * 0.3));
            }
            assert!(hits > 50, "{hits}");
        }
        // Rays aimed exactly at every vertex.
        let pr = ParallelRays::new(m, V3::new(0.0, 0.0, -1.0));
        for v in &m.vertices {
            same(&bvh, &pr, &P3::new(v.x, v.y, 10.0));
        }
    }
}

#[test]
fn empty_and_degenerate_inputs() {
    let e = ParallelRays::new(&Mesh::default(), -V3::z());
    assert!(e.first_hit(&P3::origin()).is_none());
    let m = solids::cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
    assert!(
        ParallelRays::new(&m, V3::zeros())
            .first_hit(&P3::new(0.5, 0.5, 2.0))
            .is_none()
    );
    assert!(
        ParallelRays::new(&m, V3::new(f64::NAN, 0.0, 1.0))
            .first_hit(&P3::new(0.5, 0.5, 2.0))
            .is_none()
    );
    let pr = ParallelRays::new(&m, -V3::z());
    assert!(pr.first_hit(&P3::new(f64::NAN, 0.5, 2.0)).is_none());
    assert!(pr.first_hit(&P3::new(0.5, 0.5, -2.0)).is_none());
    // Every triangle edge-on to the rays: a flat square seen along its plane.
    let sq = Mesh {
        vertices: vec![
            P3::origin(),
            P3::new(1.0, 0.0, 0.0),
            P3::new(1.0, 1.0, 0.0),
            P3::new(0.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    let bvh = Bvh::new(&sq);
    let side = ParallelRays::new(&sq, V3::x());
    for k in 0..20 {
        same(&bvh, &side, &P3::new(-1.0, k as f64 * 0.06, 0.0));
    }
}
