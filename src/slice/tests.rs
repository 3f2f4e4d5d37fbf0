use super::*;
use crate::mesh::{Mesh, solids};
use std::f64::consts::{PI, TAU};

fn total_area(s: &Section) -> f64 {
    s.loops.iter().map(|l| l.area()).sum()
}

fn poly_factor(n: usize) -> f64 {
    (TAU / n as f64).sin() / (TAU / n as f64)
}

#[test]
fn sphere_sections_match_the_circle() {
    let r = 2.0;
    let (n_lon, n_lat) = (1024, 384);
    let m = solids::sphere(P3::origin(), r, n_lon, n_lat);
    let opts = SliceOptions::default();
    // Through a vertex ring (exactly a regular polygon) and between rings.
    let ring_z = -r * (PI * 100.0 / n_lat as f64).cos();
    for z in [ring_z, -0.7 * r, -0.3 * r, 0.1 * r, 0.55 * r] {
        let s = section(&m, z, &opts);
        assert_eq!(s.loops.len(), 1, "z {z}");
        assert!(s.warnings.is_empty());
        let exact = PI * (r * r - z * z);
        let rel = (total_area(&s) / exact - 1.0).abs();
        assert!(rel < 1e-4, "z {z}: rel {rel}");
        if z == ring_z {
            assert_eq!(s.loops[0].points.len(), n_lon);
            assert!((total_area(&s) / exact - poly_factor(n_lon)).abs() < 1e-12);
        }
    }
    // At a pole: a single point, no loop.
    assert!(section(&m, -r, &opts).loops.is_empty());
    // Arcs fitted: fewer pieces, same area.
    let s = section(&m, 0.1 * r, &opts);
    let chains = to_chains(&[s], Some(1e-4), 1);
    assert_eq!(chains.len(), 1);
    assert!(chains[0].segments.len() < 100, "{}", chains[0].segments.len());
    let exact = PI * (r * r - 0.01 * r * r);
    assert!((chain_area(&chains[0]) / exact - 1.0).abs() < 1e-4);
    assert!(chains[0].segments.iter().all(|s| s.start().z == 0.1 * r));
}

#[test]
fn tilted_cylinder_section_is_an_ellipse() {
    let (r, n) = (1.5, 1024);
    for alpha in [0.3f64, 0.9] {
        let b = P3::new(10.0 * alpha.sin(), 0.0, 10.0 * alpha.cos());
        let m = solids::cylinder(P3::origin(), b, r, n, 3);
        let s = section(&m, 0.5 * b.z, &SliceOptions::default());
        assert_eq!(s.loops.len(), 1);
        let exact = PI * r * r / alpha.cos();
        let rel = (total_area(&s) / exact - 1.0).abs();
        assert!(rel < 1e-4, "alpha {alpha}: {rel}");
        assert!(s.loops[0].area() > 0.0);
    }
}

#[test]
fn torus_section_is_an_annulus_with_a_hole() {
    let (big_r, r, n_u, n_v) = (3.0, 1.0, 1024, 64);
    let m = solids::torus(P3::origin(), big_r, r, n_u, n_v);
    let h = r * (TAU * 5.0 / n_v as f64).sin();
    let s = section(&m, h, &SliceOptions::default());
    assert_eq!(s.loops.len(), 2);
    let outer = s.loops.iter().find(|l| l.depth == 0).unwrap();
    let hole = s.loops.iter().find(|l| l.depth == 1).unwrap();
    assert!(outer.area() > 0.0 && hole.area() < 0.0);
    let sq = (r * r - h * h).sqrt();
    let exact = 4.0 * PI * big_r * sq;
    let rel = (total_area(&s) / exact - 1.0).abs();
    assert!(rel < 1e-4, "{rel}");
    let chains = to_chains(&[s], None, 7);
    assert_eq!(chains[0].id, 7);
    assert_eq!(chains.iter().filter(|c| c.layer.as_deref() == Some("hole")).count(), 1);
}

#[test]
fn box_sections_through_vertices_and_facets_have_no_spurious_pieces() {
    let m = solids::cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
    let o = SliceOptions::default();
    for (z, n) in [(0.0, 1), (1.5, 1), (3.0, 0), (-1.0, 0)] {
        let s = section(&m, z, &o);
        assert_eq!(s.loops.len(), n, "z {z}");
        if n == 1 {
            assert_eq!(s.loops[0].points.len(), 4, "z {z}: {:?}", s.loops[0].points);
            assert!((s.loops[0].area() - 2.0).abs() < 1e-15);
        }
    }
}

#[test]
fn gaps_are_joined_with_a_warning() {
    let mut m = solids::cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
    // One triangle uses a copy of a top vertex, 1 µm off: a crack.
    let v = m.vertices[7] + crate::geometry::V3::new(1e-6, 0.0, 0.0);
    m.vertices.push(v);
    let k = m
        .triangles
        .iter()
        .position(|t| t.contains(&7) && !t.iter().all(|&i| m.vertices[i as usize].z == 3.0))
        .unwrap();
    for i in m.triangles[k].iter_mut() {
        if *i == 7 {
            *i = 8;
        }
    }
    let s = section(&m, 1.5, &SliceOptions::default());
    assert_eq!(s.loops.len(), 1);
    assert!(s.loops[0].closed);
    assert!(s.warnings[0].contains("joined"), "{:?}", s.warnings);
    assert!((s.loops[0].area() - 2.0).abs() < 1e-5);
    // With a tolerance below the crack it stays open and says so.
    let s = section(
        &m,
        1.5,
        &SliceOptions {
            join_tol: 1e-9,
            ..Default::default()
        },
    );
    assert!(s.warnings.iter().any(|w| w.contains("stay open")), "{:?}", s.warnings);
    let _ = Mesh::default();
}

#[test]
fn levels_by_step() {
    assert_eq!(step_levels(0.0, 1.0, 0.25, true), vec![0.75, 0.5, 0.25, 0.0]);
    assert_eq!(step_levels(0.0, 1.0, 0.25, false), vec![0.0, 0.25, 0.5, 0.75]);
    assert!(step_levels(0.0, 1.0, 0.0, false).is_empty());
}

/// A square loop, clockwise or not.
fn square_loop(x: f64, y: f64, s: f64, cw: bool, closed: bool) -> Loop {
    let mut points = vec![
        P2::new(x, y),
        P2::new(x + s, y),
        P2::new(x + s, y + s),
        P2::new(x, y + s),
    ];
    if cw {
        points.reverse();
    }
    Loop {
        points,
        depth: 0,
        closed,
    }
}

#[test]
fn many_loops_nest_by_the_grid_as_by_every_pair() {
    // A frame round 12 x 12 squares; in every second square a hole, in
    // every third hole an island; a strip of touching squares; open
    // loops over them; and a second frame the same as the first (each
    // counts the other). Orientations at random.
    let mut loops = Vec::new();
    let mut want = Vec::new();
    let mut flip = 0u32;
    let mut cw = || {
        flip = flip.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        flip >> 16 & 1 == 1
    };
    for _ in 0..2 {
        loops.push(square_loop(-1.0, -1.0, 40.0, cw(), true));
        want.push(1);
    }
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (3.0 * i as f64, 3.0 * j as f64);
            loops.push(square_loop(x, y, 2.5, cw(), true));
            want.push(2);
            if (i + j) % 2 == 0 {
                loops.push(square_loop(x + 0.5, y + 0.5, 1.5, cw(), true));
                want.push(3);
                if (i + j) % 3 == 0 {
                    loops.push(square_loop(x + 1.0, y + 1.0, 0.5, cw(), true));
                    want.push(4);
                }
            }
        }
    }
    for k in 0..10 {
        loops.push(square_loop(36.5 + 0.25 * k as f64, 0.0, 0.25, cw(), true));
        want.push(2);
        loops.push(square_loop(0.3 * k as f64, 37.0, 0.2, cw(), false));
        want.push(0);
    }
    assert!(loops.len() > 200);
    let mut by_grid = loops.clone();
    nest(&mut by_grid);
    let boxes: Vec<(P2, P2)> = loops.iter().map(|l| bbox(&l.points)).collect();
    assert!(BoxGrid::new(&loops, &boxes).is_some(), "the grid is what is tested");
    for (i, l) in by_grid.iter().enumerate() {
        // Every pair, as nest did before the grid.
        let reference = if loops[i].closed {
            let p = probe(&loops[i].points);
            (0..loops.len())
                .filter(|&j| {
                    let (lo, hi) = boxes[j];
                    j != i
                        && loops[j].closed
                        && p.x >= lo.x
                        && p.x <= hi.x
                        && p.y >= lo.y
                        && p.y <= hi.y
                        && inside(&p, &loops[j].points)
                })
                .count()
        } else {
            0
        };
        assert_eq!(l.depth, reference, "loop {i}");
        // The frames hold each other, so depths count from 1 inside them.
        assert_eq!(l.depth, want[i], "loop {i}");
        if l.closed {
            assert_eq!(
                l.area() > 0.0,
                l.depth % 2 == 0,
                "loop {i}: outer counter-clockwise, holes clockwise"
            );
        }
    }
}
