//! Drop-cutter against analytic answers on generated meshes.

use super::adaptive::Adaptive;
use super::*;
use crate::mesh::Triangle;

/// A UV sphere of radius `rad` about the origin (upper half is enough for
/// a drop from above, but the whole sphere exercises the downward facets).
pub(crate) fn sphere(rad: f64, nu: usize, nv: usize) -> Mesh {
    let p = |i: usize, j: usize| {
        let th = std::f64::consts::PI * i as f64 / nv as f64; // from the top
        let ph = std::f64::consts::TAU * j as f64 / nu as f64;
        P3::new(rad * th.sin() * ph.cos(), rad * th.sin() * ph.sin(), rad * th.cos())
    };
    let mut tris = Vec::new();
    for i in 0..nv {
        for j in 0..nu {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            if i > 0 {
                tris.push(Triangle::new(a, b, d));
            }
            if i + 1 < nv {
                tris.push(Triangle::new(b, c, d));
            }
        }
    }
    Mesh::from_triangles(&tris)
}

/// A grid of `z = f(x, y)` over [-s, s]², n cells a side, two triangles each.
pub(crate) fn surface(s: f64, n: usize, f: impl Fn(f64, f64) -> f64) -> Mesh {
    let p = |i: usize, j: usize| {
        let (x, y) = (-s + 2.0 * s * i as f64 / n as f64, -s + 2.0 * s * j as f64 / n as f64);
        P3::new(x, y, f(x, y))
    };
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            tris.push(Triangle::new(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            tris.push(Triangle::new(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    Mesh::from_triangles(&tris)
}

#[test]
fn ball_on_a_plane_sits_at_the_plane() {
    let m = surface(5.0, 4, |x, y| 0.2 * x - 0.1 * y + 1.0);
    let dc = DropCutter::new(&m, Cutter::Ball { radius: 0.5 }).unwrap();
    let k = (1.0f64 + 0.04 + 0.01).sqrt();
    for (x, y) in [(0.0, 0.0), (1.3, -2.2), (3.9, 3.9), (-2.5, 0.0)] {
        let z = dc.drop(x, y).unwrap();
        let want = 0.2 * x - 0.1 * y + 1.0 + 0.5 * k - 0.5;
        assert!((z - want).abs() < 1e-12, "{x},{y}: {z} {want}");
    }
    // Off the mesh by more than the radius: nothing under the cutter.
    assert_eq!(dc.drop(10.0, 0.0), None);
}

#[test]
fn ball_on_a_sphere_within_the_tessellation_error() {
    // Exact sphere: tip = sqrt((R + r)² − d²) − r. The facets lie inside
    // the sphere by at most the sagitta, their vertices on it, so the drop
    // on the mesh is below the exact value by at most the sagitta.
    let (big, r) = (5.0, 0.5);
    let (nu, nv) = (256, 128);
    let m = sphere(big, nu, nv);
    let dc = DropCutter::new(&m, Cutter::Ball { radius: r }).unwrap();
    let chord = big * (std::f64::consts::PI / nv as f64).max(std::f64::consts::TAU / nu as f64);
    let sagitta = chord * chord / (8.0 * big) * 2.0;
    for k in 0..40 {
        let d = 5.2 * k as f64 / 40.0;
        let (x, y) = (d * 0.6, d * 0.8);
        let want = ((big + r) * (big + r) - d * d).sqrt() - r;
        let z = dc.drop(x, y).unwrap();
        // A normal gap of one sagitta is a vertical gap of sagitta / cos θ.
        let cos = (1.0 - (d / (big + r)).powi(2)).sqrt();
        assert!(z <= want + 1e-12 && z >= want - sagitta / cos, "d {d}: {z} vs {want}");
    }
}

#[test]
fn flat_on_a_block_edge_and_torus_on_a_slope() {
    // A roof ridge along y at x = 0: z = 1 − |x|.
    let m = surface(3.0, 6, |x, _| 1.0 - x.abs());
    let flat = DropCutter::new(&m, Cutter::Flat { radius: 0.4 }).unwrap();
    for x in [-0.3, 0.0, 0.25] {
        assert!((flat.drop(x, 0.3).unwrap() - 1.0).abs() < 1e-12);
    }
    // Beyond the radius the rim rides the slope: z = 1 − (|x| − R).
    assert!((flat.drop(1.0, 0.7).unwrap() - 0.4).abs() < 1e-12);
    let tor = DropCutter::new(
        &m,
        Cutter::Torus {
            radius: 0.4,
            corner: 0.1,
        },
    )
    .unwrap();
    // Slope 45°: the tube touches at 45°, tip = z(x) + a + rc·√2 − rc.
    let x = 1.5;
    let want = 1.0 - x + 0.3 + 0.1 * 2f64.sqrt() - 0.1;
    assert!((tor.drop(x, 0.2).unwrap() - want).abs() < 1e-12);
}

#[test]
fn the_grid_gives_what_every_triangle_gives() {
    // Drop with the index against a scan of every triangle.
    let m = surface(4.0, 13, |x, y| (x * 0.9).sin() * (y * 0.7).cos() + 0.1 * x * y);
    for c in [
        Cutter::Flat { radius: 0.3 },
        Cutter::Ball { radius: 0.7 },
        Cutter::Torus {
            radius: 0.5,
            corner: 0.2,
        },
    ] {
        let dc = DropCutter::new(&m, c).unwrap();
        let s = ContactCutter::new(c);
        let tris: Vec<Tri> = m.iter_triangles().map(|t| Tri::new(&t)).collect();
        for i in 0..30 {
            for j in 0..30 {
                let (x, y) = (-4.5 + 0.31 * i as f64, -4.5 + 0.31 * j as f64);
                let mut best = f64::NEG_INFINITY;
                for t in &tris {
                    drop_on(&s, x, y, t, &mut best);
                }
                let got = dc.drop_above(x, y, f64::NEG_INFINITY);
                assert_eq!(got, best, "{c} at {x},{y}");
            }
        }
    }
}

#[test]
fn adaptive_points_stay_within_the_chord_tolerance() {
    let m = sphere(3.0, 128, 64);
    let dc = DropCutter::new(&m, Cutter::Ball { radius: 0.5 }).unwrap();
    let xy: Vec<P2> = (0..=8).map(|i| P2::new(-4.0 + i as f64, 0.3)).collect();
    let cl = dc.drop_many(&xy, -1.0);
    let ad = Adaptive {
        chord_tol: 0.002,
        min_step: 1e-3,
    };
    let fine = ad.refine(&dc, &cl, -1.0);
    assert!(fine.len() > 40, "{}", fine.len());
    // The true CL curve, densely sampled, against the polyline.
    let mut worst: f64 = 0.0;
    for w in fine.windows(2) {
        for k in 1..20 {
            let t = k as f64 / 20.0;
            let q = w[0].xy() + (w[1].xy() - w[0].xy()) * t;
            let z = dc.drop_above(q.x, q.y, -1.0);
            let lin = w[0].z + (w[1].z - w[0].z) * t;
            let dev = (z - lin).abs() / (1.0 + ((w[1].z - w[0].z) / (w[1].xy() - w[0].xy()).norm()).powi(2)).sqrt();
            worst = worst.max(dev);
        }
    }
    assert!(worst <= 0.002, "{worst}");
}

#[test]
fn empty_and_broken_meshes_are_refused() {
    assert_eq!(
        DropCutter::new(&Mesh::default(), Cutter::Ball { radius: 1.0 }).unwrap_err(),
        DropError::EmptyMesh
    );
    let m = Mesh::from_triangles(&[Triangle::new(
        P3::origin(),
        P3::new(1.0, 0.0, f64::NAN),
        P3::new(0.0, 1.0, 0.0),
    )]);
    assert_eq!(
        DropCutter::new(&m, Cutter::Ball { radius: 1.0 }).unwrap_err(),
        DropError::NotFinite(0)
    );
}
