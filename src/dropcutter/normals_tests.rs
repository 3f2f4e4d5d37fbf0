//! Smooth normals against analytic surfaces.

use super::*;
use crate::cutter::Cutter;
use crate::dropcutter::DropCutter;
use crate::dropcutter::tests::surface;
use crate::mesh::Mesh;
use crate::mesh::solids::{cuboid, sphere};

/// Points spread over the disc of radius `r` about the origin (a
/// deterministic sunflower pattern).
fn disc_points(n: usize, r: f64) -> Vec<(f64, f64)> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let rho = r * ((i as f64 + 0.5) / n as f64).sqrt();
            let th = golden * i as f64;
            (rho * th.cos(), rho * th.sin())
        })
        .collect()
}

/// Angles (degrees) between the facet normal, and the smoothed one, and
/// the true normal `truth(p)`, at the contact straight below each point.
fn errors(mesh: &Mesh, pts: &[(f64, f64)], crease: f64, truth: impl Fn(P3) -> V3) -> (Vec<f64>, Vec<f64>) {
    let dc = DropCutter::new(mesh, Cutter::Flat { radius: 1.0 }).unwrap();
    let smooth = dc.smooth_normals(crease);
    let (mut facet, mut smoothed) = (Vec::new(), Vec::new());
    for &(x, y) in pts {
        let (z, t) = dc.surface_contact(x, y).expect("on the mesh");
        let p = P3::new(x, y, z);
        let n = dc.tris[t].n;
        let want = truth(p);
        let deg = |v: V3| v.normalize().dot(&want).clamp(-1.0, 1.0).acos().to_degrees();
        facet.push(deg(V3::new(n[0], n[1], n[2])));
        smoothed.push(deg(dc.smooth_normal_at(&smooth, t, p)));
    }
    (facet, smoothed)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(0.0, f64::max)
}

#[test]
fn smoothed_normals_follow_a_sphere_far_closer_than_its_facets() {
    let mesh = sphere(P3::origin(), 10.0, 96, 48);
    let pts = disc_points(4000, 8.0);
    let (facet, smooth) = errors(&mesh, &pts, DEFAULT_CREASE_DEG.to_radians(), |p| p.coords.normalize());
    let (fm, sm) = (median(facet.clone()), median(smooth.clone()));
    // Facets 3.75 degrees apart: the facet's normal is off by up to about
    // half that; the interpolated one by a small fraction of it.
    assert!(fm > 0.5, "facet median {fm}");
    assert!(sm < fm / 8.0, "smooth median {sm} against facet {fm}");
    assert!(
        max(&smooth) < max(&facet) / 4.0,
        "{} against {}",
        max(&smooth),
        max(&facet)
    );
    // A crease of 0 keeps every facet's own normal.
    let (_, flat) = errors(&mesh, &pts, 0.0, |p| p.coords.normalize());
    for (f, s) in facet.iter().zip(&flat) {
        assert!((f - s).abs() < 1e-6, "{f} {s}");
    }
}

#[test]
fn a_crease_keeps_a_blocks_top_upright_up_to_its_edges() {
    let mesh = cuboid(P3::new(-2.0, -2.0, 0.0), P3::new(2.0, 2.0, 1.0));
    let dc = DropCutter::new(&mesh, Cutter::Flat { radius: 0.5 }).unwrap();
    let kept = dc.smooth_normals(DEFAULT_CREASE_DEG.to_radians());
    let rounded = dc.smooth_normals(std::f64::consts::PI);
    let mut tipped = 0;
    for &(x, y) in &[(0.0, 0.0), (1.999, 0.3), (-1.999, -1.999), (0.5, 2.0), (2.0, 2.0)] {
        let (z, t) = dc.surface_contact(x, y).unwrap();
        assert_eq!(z, 1.0);
        let p = P3::new(x, y, z);
        let n = dc.smooth_normal_at(&kept, t, p);
        assert!((n - V3::z()).norm() < 1e-12, "({x}, {y}): {n:?}");
        // Without the crease the walls' normals lean the top's at its rim.
        tipped += ((dc.smooth_normal_at(&rounded, t, p) - V3::z()).norm() > 1e-3) as usize;
    }
    assert!(tipped >= 3, "{tipped}");
}

#[test]
fn the_smoothed_normal_is_the_same_from_both_sides_of_an_edge() {
    // A wavy height field: every interior edge is shared by two facets.
    let mesh = surface(3.0, 12, |x, y| 0.4 * (0.9 * x).sin() * (0.7 * y).cos());
    let dc = DropCutter::new(&mesh, Cutter::Flat { radius: 0.5 }).unwrap();
    let smooth = dc.smooth_normals(DEFAULT_CREASE_DEG.to_radians());
    let mut edges: std::collections::HashMap<[u64; 6], Vec<usize>> = std::collections::HashMap::new();
    for (t, tri) in dc.tris.iter().enumerate() {
        for k in 0..3 {
            let (mut a, mut b) = (tri.v[k], tri.v[(k + 1) % 3]);
            if (a[0], a[1]) > (b[0], b[1]) {
                std::mem::swap(&mut a, &mut b);
            }
            let key = [a[0], a[1], a[2], b[0], b[1], b[2]].map(f64::to_bits);
            edges.entry(key).or_default().push(t);
        }
    }
    let mut shared = 0;
    for (key, ts) in &edges {
        if ts.len() != 2 {
            continue;
        }
        let c = key.map(f64::from_bits);
        for s in [0.25, 0.5, 0.8] {
            let p = P3::new(
                c[0] + s * (c[3] - c[0]),
                c[1] + s * (c[4] - c[1]),
                c[2] + s * (c[5] - c[2]),
            );
            let (n0, n1) = (
                dc.smooth_normal_at(&smooth, ts[0], p),
                dc.smooth_normal_at(&smooth, ts[1], p),
            );
            assert!((n0 - n1).norm() < 1e-12, "{p:?}: {n0:?} {n1:?}");
        }
        shared += 1;
    }
    assert!(shared > 300, "{shared}");
}

#[test]
fn a_degenerate_facet_and_its_neighbours_get_finite_unit_normals() {
    let a = P3::new(0.0, 0.0, 0.0);
    let b = P3::new(1.0, 0.0, 0.1);
    let c = P3::new(0.0, 1.0, 0.2);
    let tris = [
        crate::mesh::Triangle::new(a, b, c),
        crate::mesh::Triangle::new(a, b, P3::new(2.0, 0.0, 0.2)), // collinear: no normal
        crate::mesh::Triangle::new(b, P3::new(1.0, 1.0, 0.3), c),
    ];
    let dc = DropCutter::new(&Mesh::from_triangles(&tris), Cutter::Flat { radius: 0.5 }).unwrap();
    let smooth = dc.smooth_normals(DEFAULT_CREASE_DEG.to_radians());
    for (t, p) in [(0, P3::new(0.2, 0.2, 0.0)), (2, P3::new(0.7, 0.7, 0.0))] {
        let n = dc.smooth_normal_at(&smooth, t, p);
        assert!((n.norm() - 1.0).abs() < 1e-12 && n.z > 0.0, "{n:?}");
    }
    let n = dc.smooth_normal_at(&smooth, 1, P3::new(1.0, 0.0, 0.0));
    assert!(n.iter().all(|c| c.is_finite()), "{n:?}");
}

#[test]
fn corners_a_hair_apart_are_not_one_vertex() {
    // Two facets leaning different ways whose nearest corners are 1e-9
    // apart (one cell of the sort's code on a 10 mm mesh) but not equal:
    // each keeps its own normal there; with the corners equal they share.
    let mesh_with = |gap: f64| {
        let a = crate::mesh::Triangle::new(P3::new(0.0, 0.0, 0.0), P3::new(5.0, 0.0, 1.0), P3::new(0.0, 5.0, 0.0));
        let b = crate::mesh::Triangle::new(P3::new(gap, 0.0, 0.0), P3::new(0.0, -5.0, 0.5), P3::new(5.0, -5.0, 1.5));
        Mesh::from_triangles(&[
            a,
            b,
            crate::mesh::Triangle::new(
                P3::new(10.0, 10.0, 0.0),
                P3::new(9.0, 10.0, 0.0),
                P3::new(10.0, 9.0, 0.0),
            ),
        ])
    };
    for (gap, shared) in [(1e-9, false), (0.0, true)] {
        let dc = DropCutter::new(&mesh_with(gap), Cutter::Flat { radius: 0.5 }).unwrap();
        let smooth = dc.smooth_normals(std::f64::consts::PI);
        let n0 = dc.smooth_normal_at(&smooth, 0, P3::new(0.0, 0.0, 0.0));
        let own = V3::new(dc.tris[0].n[0], dc.tris[0].n[1], dc.tris[0].n[2]);
        assert_eq!((n0 - own).norm() > 1e-6, shared, "gap {gap}: {n0:?} {own:?}");
    }
}
