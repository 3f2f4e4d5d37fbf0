//! Waterlines against exact offsets of a block, against a sphere, and
//! their direction round islands and pockets.

use super::*;
use crate::cutter::Cutter;
use crate::dropcutter::tests::surface;
use crate::geometry::P3;
use crate::mesh::solids::{cuboid, sphere};

const TOL: f64 = 1e-7;

fn wl(sampling: f64) -> Waterline {
    Waterline {
        sampling,
        tol: TOL,
        chord_tol: None,
    }
}

/// Distance in XY from `p` to the rectangle [0, a] x [0, b].
fn to_rect(p: P2, a: f64, b: f64) -> f64 {
    let dx = (-p.x).max(p.x - a).max(0.0);
    let dy = (-p.y).max(p.y - b).max(0.0);
    dx.hypot(dy)
}

/// Twice the signed area (positive counter-clockwise) of a closed loop.
fn area2(lp: &[P2]) -> f64 {
    lp.windows(2).map(|w| w[0].x * w[1].y - w[1].x * w[0].y).sum()
}

/// Each vertex is free (the cutter there does not reach above `z`) and a
/// blocked point lies within the tolerance along one of its fibres.
fn on_the_boundary(dc: &DropCutter, lp: &[P2], z: f64) {
    for p in lp {
        assert_eq!(dc.drop_above(p.x, p.y, z), z, "{p:?} is blocked");
        let d = TOL * 1.01;
        let near = [(d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)]
            .iter()
            .any(|(dx, dy)| dc.drop_above(p.x + dx, p.y + dy, z) > z);
        assert!(near, "{p:?}: no blocked point within the tolerance");
    }
}

#[test]
fn a_block_gives_its_exact_offset_for_each_cutter() {
    let m = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(4.0, 3.0, 2.0));
    // (cutter, tip height, distance of the waterline from the block in XY)
    let cases = [
        (Cutter::Flat { radius: 0.5 }, 1.0, 0.5),
        (Cutter::Flat { radius: 0.5 }, 1.999, 0.5),
        (Cutter::Ball { radius: 0.5 }, 1.0, 0.5),
        // The ball's centre at 2.3 rests on the block's top edge.
        (Cutter::Ball { radius: 0.5 }, 1.8, (0.25f64 - 0.09).sqrt()),
        (
            Cutter::Torus {
                radius: 0.5,
                corner: 0.25,
            },
            1.0,
            0.5,
        ),
        // The tube's centre circle at 2.15: 0.25 + sqrt(0.25² - 0.15²).
        (
            Cutter::Torus {
                radius: 0.5,
                corner: 0.25,
            },
            1.9,
            0.25 + (0.0625f64 - 0.0225).sqrt(),
        ),
    ];
    for (cutter, z, d) in cases {
        let dc = DropCutter::new(&m, cutter).unwrap();
        let loops = wl(0.05).loops(&dc, z).unwrap();
        assert_eq!(loops.len(), 1, "{cutter:?} at {z}");
        let lp = &loops[0];
        assert_eq!(lp.first(), lp.last());
        assert!(lp.len() > 100);
        for p in lp {
            let e = to_rect(*p, 4.0, 3.0) - d;
            assert!(
                (-1e-12..=TOL + 1e-12).contains(&e),
                "{cutter:?} z {z}: {p:?} off by {e}"
            );
        }
        on_the_boundary(&dc, lp, z);
        // Clockwise round the island (the block on the right), with the
        // area of the offset rectangle less the corners' chord sag.
        let area = -area2(lp) / 2.0;
        let want = 12.0 + 2.0 * d * 7.0 + std::f64::consts::PI * d * d;
        assert!(
            area > 0.0 && (area - want).abs() < 1e-3 * want,
            "{cutter:?}: {area} vs {want}"
        );
    }
}

#[test]
fn nothing_above_the_model_gives_no_loop() {
    let m = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(4.0, 3.0, 2.0));
    let dc = DropCutter::new(&m, Cutter::Ball { radius: 0.5 }).unwrap();
    assert!(wl(0.1).loops(&dc, 2.0).unwrap().is_empty());
    assert!(wl(0.1).loops(&dc, 5.0).unwrap().is_empty());
}

#[test]
fn a_ball_round_a_sphere_follows_the_offset_sphere() {
    // Ball of radius r round a sphere of radius R: the centre stays R + r
    // from the sphere's centre, so at tip height z the waterline is a
    // circle of radius sqrt((R + r)² - (z + r)²), less the tessellation's
    // sag R (1 - cos(pi / n)). Below the equator (centre below it) the
    // tool, coming from above, cannot reach under the bulge: the
    // waterline is the silhouette's offset, radius R + r. The mesh is
    // stored in f32: corners within 1e-6 of the sphere.
    let (rr, r) = (5.0, 1.0);
    let m = sphere(P3::origin(), rr, 128, 64);
    let dc = DropCutter::new(&m, Cutter::Ball { radius: r }).unwrap();
    let sag = rr * (1.0 - (std::f64::consts::PI / 64.0).cos());
    for z in [-3.0, 0.0, 2.5, 4.5] {
        let loops = wl(0.1).loops(&dc, z).unwrap();
        assert_eq!(loops.len(), 1, "z {z}");
        let want = if z + r < 0.0 {
            rr + r
        } else {
            ((rr + r).powi(2) - (z + r).powi(2)).sqrt()
        };
        for p in &loops[0] {
            let e = p.coords.norm() - want;
            assert!(e <= TOL + 1e-6 && e >= -2.0 * sag - 1e-6, "z {z}: {p:?} off by {e}");
        }
        on_the_boundary(&dc, &loops[0], z);
        assert!(area2(&loops[0]) < 0.0, "clockwise round the sphere");
    }
}

#[test]
fn a_pocket_wall_is_followed_counter_clockwise() {
    // A bowl z = (x² + y²) / 4 over [-3, 3]²: at z = 1 the cutter is free
    // inside the bowl (a pocket, loop counter-clockwise) and outside the
    // surface's edge (an island, clockwise).
    let m = surface(3.0, 60, |x, y| (x * x + y * y) / 4.0);
    let dc = DropCutter::new(&m, Cutter::Ball { radius: 0.25 }).unwrap();
    let loops = wl(0.05).loops(&dc, 1.0).unwrap();
    assert_eq!(loops.len(), 2);
    let mut areas: Vec<f64> = loops.iter().map(|l| area2(l) / 2.0).collect();
    areas.sort_by(f64::total_cmp);
    assert!(areas[0] < -36.0, "the outer loop is clockwise: {areas:?}");
    assert!(areas[1] > 0.0 && areas[1] < std::f64::consts::PI * 4.0, "{areas:?}");
    for lp in &loops {
        on_the_boundary(&dc, lp, 1.0);
    }
}

fn two_blocks(gap: f64) -> crate::mesh::Mesh {
    let mut tris = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(1.0, 1.0, 1.0))
        .iter_triangles()
        .collect::<Vec<_>>();
    let b = 1.0 + gap;
    tris.extend(cuboid(P3::new(b, b, 0.0), P3::new(b + 1.0, b + 1.0, 1.0)).iter_triangles());
    crate::mesh::Mesh::from_triangles(&tris)
}

#[test]
fn islands_apart_by_more_than_the_sampling_stay_apart() {
    // Two blocks meeting diagonally, their offsets (0.2 each) 0.236 apart
    // at the corners, more than a cell's diagonal: two loops.
    let dc = DropCutter::new(&two_blocks(0.45), Cutter::Flat { radius: 0.2 }).unwrap();
    let loops = wl(0.07).loops(&dc, 0.5).unwrap();
    assert_eq!(loops.len(), 2);
    for lp in &loops {
        assert!(area2(lp) < 0.0);
        on_the_boundary(&dc, lp, 0.5);
    }
}

#[test]
fn a_free_channel_between_grid_nodes_keeps_islands_apart() {
    // Flat R 0.23 round blocks [0, 1.02] and [1.53, 2.53] (y in [0, 1]):
    // their offsets leave a free channel 1.25 < x < 1.30, and with the
    // sampling 0.1 from -0.46 no grid node falls in it (nodes at 1.24 and
    // 1.34): only the fibres along X cross it, each between two blocked
    // nodes. The channel must be followed: two islands, not one loop
    // round both (which would leave the wall between them uncut).
    let mut tris = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(1.02, 1.0, 1.0))
        .iter_triangles()
        .collect::<Vec<_>>();
    tris.extend(cuboid(P3::new(1.53, 0.0, 0.0), P3::new(2.53, 1.0, 1.0)).iter_triangles());
    let dc = DropCutter::new(&crate::mesh::Mesh::from_triangles(&tris), Cutter::Flat { radius: 0.23 }).unwrap();
    let loops = wl(0.1).loops(&dc, 0.5).unwrap();
    assert_eq!(loops.len(), 2, "{loops:?}");
    for lp in &loops {
        assert!(area2(lp) < 0.0);
        on_the_boundary(&dc, lp, 0.5);
    }
    // The channel's walls are loop vertices on every fibre that crosses
    // it.
    let wall = |x: f64| {
        loops
            .iter()
            .flat_map(|lp| &lp[1..])
            .filter(|p| (p.x - x).abs() <= 2.0 * TOL && p.y > 0.0 && p.y < 1.0)
            .count()
    };
    assert_eq!((wall(1.25), wall(1.30)), (10, 10));
    fibre_crossings_are_vertices(&dc, &loops, 0.5, 0.1, 200, true);
}

#[test]
fn saddle_cells_give_closed_loops_that_share_no_vertex() {
    // Offsets 0.038 apart at the corners, less than the sampling: whether
    // the gap is seen depends on where the fibres fall (cells there are
    // saddles, decided at their centres), but for every placement the
    // loops are closed, clockwise, on the boundary and disjoint.
    let dc = DropCutter::new(&two_blocks(0.31), Cutter::Flat { radius: 0.2 }).unwrap();
    for sampling in [0.05, 0.061, 0.07, 0.083, 0.1] {
        let loops = wl(sampling).loops(&dc, 0.5).unwrap();
        assert!((1..=2).contains(&loops.len()), "{sampling}: {} loops", loops.len());
        let mut seen = std::collections::HashSet::new();
        for lp in &loops {
            assert_eq!(lp.first(), lp.last());
            assert!(area2(lp) < 0.0);
            on_the_boundary(&dc, lp, 0.5);
            for p in &lp[1..] {
                assert!(seen.insert((p.x.to_bits(), p.y.to_bits())), "{sampling}: {p:?} twice");
            }
        }
    }
}

#[test]
fn levels_at_once_equal_levels_one_by_one() {
    let m = sphere(P3::origin(), 5.0, 48, 24);
    let dc = DropCutter::new(
        &m,
        Cutter::Torus {
            radius: 1.0,
            corner: 0.3,
        },
    )
    .unwrap();
    let zs = [4.0, -2.0, 0.5, 3.0];
    let all = wl(0.2).levels(&dc, &zs).unwrap();
    for (z, loops) in zs.iter().zip(&all) {
        assert_eq!(&wl(0.2).loops(&dc, *z).unwrap(), loops, "z {z}");
    }
    assert!(wl(0.2).levels(&dc, &[]).unwrap().is_empty());
}

#[test]
fn bad_options_are_refused() {
    let m = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(4.0, 3.0, 2.0));
    let dc = DropCutter::new(&m, Cutter::Flat { radius: 0.5 }).unwrap();
    for w in [
        wl(0.0),
        wl(-1.0),
        wl(f64::NAN),
        Waterline {
            sampling: 0.1,
            tol: 0.0,
            chord_tol: None,
        },
        Waterline {
            chord_tol: Some(0.0),
            ..wl(0.1)
        },
        Waterline {
            chord_tol: Some(f64::NAN),
            ..wl(0.1)
        },
        wl(1e-6),
    ] {
        assert!(w.loops(&dc, 1.0).is_err(), "{w:?}");
    }
    assert!(wl(0.1).loops(&dc, f64::NAN).is_err());
}

/// Every place where a fibre enters or leaves the blocked set, found by
/// sampling the drop densely along every fibre, has a loop vertex within
/// the sampling's 1/`per` (plus the tolerance) on that fibre; inside
/// edges blocked at both ends too when `gaps` (a gap that only one fibre
/// meets has no loop, so that check is for shapes without such gaps).
fn every_fibre_crossing_is_a_vertex(dc: &DropCutter, loops: &[Vec<P2>], z: f64, h: f64, per: usize) {
    fibre_crossings_are_vertices(dc, loops, z, h, per, false);
}

fn fibre_crossings_are_vertices(dc: &DropCutter, loops: &[Vec<P2>], z: f64, h: f64, per: usize, gaps: bool) {
    let g = Fibres::new(dc, h).unwrap();
    let blocked = |x: f64, y: f64| dc.drop_above(x, y, z) > z;
    let verts: Vec<P2> = loops.iter().flatten().copied().collect();
    let near = |p: P2| verts.iter().any(|v| (v - p).norm() <= h / per as f64 + 2.0 * TOL);
    let mut checked = 0;
    for along_x in [true, false] {
        let (n_fibres, n_nodes) = if along_x { (g.ny, g.nx) } else { (g.nx, g.ny) };
        for f in 0..n_fibres {
            let at = |k: usize, s: f64| {
                if along_x {
                    P2::new(g.x(k) + s, g.y(f))
                } else {
                    P2::new(g.x(f), g.y(k) + s)
                }
            };
            for k in 0..n_nodes - 1 {
                let (a, b) = (at(k, 0.0), at(k + 1, 0.0));
                if !gaps && blocked(a.x, a.y) && blocked(b.x, b.y) {
                    continue;
                }
                let mut prev = blocked(a.x, a.y);
                for m in 1..=per {
                    let p = at(k, h * m as f64 / per as f64);
                    let now = blocked(p.x, p.y);
                    if now != prev {
                        checked += 1;
                        assert!(
                            near(p),
                            "z {z}: the fibre crosses the boundary near {p:?} and no loop vertex is there"
                        );
                    }
                    prev = now;
                }
            }
        }
    }
    assert!(checked > 0, "no crossing was checked");
}

/// A thin wall on a table, with a tiny cube far off that fixes where the
/// fibres fall (they start two cutter radii below the mesh's box).
fn thin_wall(x: f64, y: f64) -> crate::mesh::Mesh {
    let mut tris = cuboid(P3::new(-5.0, -5.0, 0.0), P3::new(-4.99, -4.99, 0.01))
        .iter_triangles()
        .collect::<Vec<_>>();
    tris.extend(cuboid(P3::new(x, y, 0.0), P3::new(x + 0.01, y + 2.0, 1.0)).iter_triangles());
    crate::mesh::Mesh::from_triangles(&tris)
}

#[test]
fn a_boundary_crossing_one_fibre_edge_twice_is_followed() {
    // Flat R 0.5, sampling 0.7: fibres at -6 + 0.7 k. The wall's end
    // (offset: a half disc round y = 0.05) dips 0.05 below the fibre
    // y = -0.4 between its nodes x = -0.4 and 0.3, both free: that edge
    // holds two crossings and the loop must dip through both, not cut
    // straight across 0.09 above them.
    let dc = DropCutter::new(&thin_wall(-0.055, 0.05), Cutter::Flat { radius: 0.5 }).unwrap();
    let loops = wl(0.7).loops(&dc, 0.5).unwrap();
    assert_eq!(loops.len(), 1);
    on_the_boundary(&dc, &loops[0], 0.5);
    let low = loops[0][1..].iter().filter(|p| (p.y + 0.4).abs() < 1e-12).count();
    assert_eq!(low, 2, "{:?}", loops[0]);
    every_fibre_crossing_is_a_vertex(&dc, &loops, 0.5, 0.7, 400);
    // The same for ball and torus cutters, at other samplings and places.
    for (cutter, h) in [
        (Cutter::Ball { radius: 0.5 }, 0.7),
        (Cutter::Ball { radius: 0.3 }, 0.45),
        (
            Cutter::Torus {
                radius: 0.5,
                corner: 0.2,
            },
            0.66,
        ),
    ] {
        for (x, y) in [(-0.055, 0.05), (0.013, -0.021), (0.2, 0.31)] {
            let dc = DropCutter::new(&thin_wall(x, y), cutter).unwrap();
            for z in [0.3, 0.8, 0.97] {
                let loops = wl(h).loops(&dc, z).unwrap();
                for lp in &loops {
                    on_the_boundary(&dc, lp, z);
                    assert!(area2(lp) < 0.0);
                }
                every_fibre_crossing_is_a_vertex(&dc, &loops, z, h, 200);
            }
        }
    }
}

#[test]
fn corpus_meshes_put_every_fibre_crossing_on_a_loop() {
    // The meshes other programs wrote, 100 fibres across, at three
    // heights, flat and ball cutters of 12 % of the part (as
    // scripts/waterline-ocl-check runs them): every loop vertex free, and
    // every place a fibre crosses the boundary (sampled 20 times per edge)
    // a vertex.
    let Some(meshes) = crate::mesh::read_corpus_meshes() else {
        crate::corpus::skip("corpus_meshes_put_every_fibre_crossing_on_a_loop");
        return;
    };
    let mut checked = 0;
    for (f, mesh) in &meshes {
        let bb = mesh.bbox();
        let size = (bb.max.x - bb.min.x).max(bb.max.y - bb.min.y);
        if size <= 0.0 || bb.max.z <= bb.min.z {
            continue;
        }
        let h = size / 100.0;
        for cutter in [
            Cutter::Flat { radius: 0.06 * size },
            Cutter::Ball { radius: 0.06 * size },
        ] {
            let Ok(dc) = DropCutter::new(mesh, cutter) else {
                continue;
            };
            for f_z in [0.2, 0.5, 0.8] {
                let z = bb.min.z + f_z * (bb.max.z - bb.min.z);
                let w = Waterline {
                    sampling: h,
                    tol: 1e-6 * h,
                    chord_tol: None,
                };
                let loops = w.loops(&dc, z).unwrap();
                for lp in &loops {
                    for p in lp {
                        assert_eq!(dc.drop_above(p.x, p.y, z), z, "{}: {p:?} is blocked", f.display());
                    }
                }
                if !loops.is_empty() {
                    every_fibre_crossing_is_a_vertex(&dc, &loops, z, h, 20);
                    checked += 1;
                }
            }
        }
    }
    crate::corpus::record("corpus_meshes_put_every_fibre_crossing_on_a_loop", checked);
    assert!(checked > 0);
}

/// The largest distance from the offset rectangle's boundary (`d` out
/// from [0, a] x [0, b]) of the loop's vertices and of points along its
/// chords (every tenth of each).
fn worst_off_offset(lp: &[P2], a: f64, b: f64, d: f64) -> f64 {
    lp.windows(2)
        .flat_map(|w| (0..10).map(move |k| w[0] + (w[1] - w[0]) * (k as f64 / 10.0)))
        .map(|p| (to_rect(p, a, b) - d).abs())
        .fold(0.0, f64::max)
}

#[test]
fn refined_chords_follow_the_rounded_corners_within_the_tolerance() {
    // A flat cutter round a block: the waterline is the block offset by
    // the radius, its corners quarter circles of that radius, which the
    // fibres 0.2 apart cut with chords. Refined, every point of every
    // chord is within the chord tolerance of the exact offset.
    let m = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(4.0, 3.0, 2.0));
    let dc = DropCutter::new(&m, Cutter::Flat { radius: 0.5 }).unwrap();
    let coarse = wl(0.2).loops(&dc, 1.0).unwrap();
    assert_eq!(coarse.len(), 1);
    let before = worst_off_offset(&coarse[0], 4.0, 3.0, 0.5);
    for chord_tol in [1e-2, 1e-3, 1e-4] {
        let w = Waterline {
            chord_tol: Some(chord_tol),
            ..wl(0.2)
        };
        let fine = w.loops(&dc, 1.0).unwrap();
        assert_eq!(fine.len(), 1);
        let lp = &fine[0];
        assert_eq!(lp.first(), lp.last());
        let after = worst_off_offset(lp, 4.0, 3.0, 0.5);
        println!(
            "chord tolerance {chord_tol}: worst {after:.2e} mm with {} points, {before:.2e} mm with {} unrefined",
            lp.len(),
            coarse[0].len()
        );
        assert!(after <= chord_tol + 2.0 * TOL, "{chord_tol}: {after}");
        assert!(
            before > 10.0 * chord_tol.min(1e-3),
            "the test must have sag to remove: {before}"
        );
        // Every fibre point is kept, in order; the points added are free
        // points on the offset, and only where the corners bend.
        let mut it = lp.iter();
        for p in &coarse[0] {
            assert!(it.any(|q| q == p), "{p:?} of the unrefined loop is missing");
        }
        for p in lp {
            assert_eq!(dc.drop_above(p.x, p.y, 1.0), 1.0, "{p:?} is blocked");
            assert!(
                (to_rect(*p, 4.0, 3.0) - 0.5).abs() <= 2.0 * TOL,
                "{p:?} is off the offset"
            );
        }
        // Straight sides need no point: a quarter circle of radius 0.5
        // within a tolerance t needs about (pi / 4) / acos(1 - t / 0.5)
        // chords a corner.
        let per_corner = std::f64::consts::FRAC_PI_4 / (1.0 - chord_tol / 0.5).acos();
        assert!(
            (lp.len() as f64) < coarse[0].len() as f64 + 4.0 * (2.0 * per_corner + 4.0),
            "{chord_tol}: {} points",
            lp.len()
        );
    }
}

#[test]
fn refinement_follows_a_pocket_wall_and_an_island_alike() {
    // The bowl of `a_pocket_wall_is_followed_counter_clockwise`, sampled
    // coarsely: round the pocket (counter-clockwise) the chords run through
    // the free set and the waterline lies on their right; round the island
    // (clockwise) through the blocked set, the waterline on their left.
    // Refined, the middle of every chord has the waterline within the
    // tolerance across it.
    let m = surface(3.0, 60, |x, y| (x * x + y * y) / 4.0);
    let dc = DropCutter::new(&m, Cutter::Ball { radius: 0.25 }).unwrap();
    let chord_tol = 1e-3;
    let plain = wl(0.3).loops(&dc, 1.0).unwrap();
    let w = Waterline {
        chord_tol: Some(chord_tol),
        ..wl(0.3)
    };
    let fine = w.loops(&dc, 1.0).unwrap();
    assert_eq!(plain.len(), 2);
    assert_eq!(fine.len(), 2);
    let blocked = |p: P2| dc.drop_above(p.x, p.y, 1.0) > 1.0;
    let far_chords = |lp: &[P2]| {
        lp.windows(2)
            .filter(|c| {
                let d = c[1] - c[0];
                let n = crate::geometry::V2::new(d.y, -d.x) / d.norm();
                let m = c[0] + d * 0.5;
                let t = chord_tol + 2.0 * TOL;
                blocked(m + n * t) == blocked(m - n * t)
            })
            .count()
    };
    for (p, f) in plain.iter().zip(&fine) {
        assert_eq!(f.first(), f.last());
        assert!(f.len() > p.len());
        assert_eq!(area2(p).signum(), area2(f).signum(), "same direction");
        for q in f {
            assert!(!blocked(*q), "{q:?} is blocked");
        }
        assert!(far_chords(p) > 10, "the coarse loop has chords to refine");
        assert_eq!(far_chords(f), 0, "every refined chord is within the tolerance");
    }
}

#[test]
fn refinement_traces_a_pin_that_meets_one_fibre_only() {
    // A block and a pin 0.1 mm square beside it; flat cutter of radius
    // 0.05, fibres 0.5 apart from x, y = -0.1: the pin's blocked set,
    // x 5.25..5.45 and y 0.95..1.15, meets the fibre x = 5.4 and no other.
    // Plain, the pin has no loop (a stretch on one fibre); refined, a loop
    // round it at the cutter's radius, clockwise, within the tolerance.
    let mut tris: Vec<_> = cuboid(P3::new(0.0, 0.0, 0.0), P3::new(4.0, 3.0, 2.0))
        .iter_triangles()
        .collect();
    tris.extend(cuboid(P3::new(5.3, 1.0, 0.0), P3::new(5.4, 1.1, 2.0)).iter_triangles());
    let m = crate::mesh::Mesh::from_triangles(&tris);
    let dc = DropCutter::new(&m, Cutter::Flat { radius: 0.05 }).unwrap();
    assert_eq!(wl(0.5).loops(&dc, 1.0).unwrap().len(), 1, "the block's loop only");
    let chord_tol = 1e-3;
    let w = Waterline {
        chord_tol: Some(chord_tol),
        ..wl(0.5)
    };
    let loops = w.loops(&dc, 1.0).unwrap();
    assert_eq!(loops.len(), 2, "the block's loop and the pin's");
    let pin = loops.iter().find(|l| l[0].x > 5.0).expect("a loop round the pin");
    assert_eq!(pin.first(), pin.last());
    assert!(area2(pin) < 0.0, "clockwise round the pin");
    let off = |p: P2| to_rect(P2::new(p.x - 5.3, p.y - 1.0), 0.1, 0.1) - 0.05;
    for p in pin {
        assert!(off(*p).abs() <= 2.0 * TOL, "{p:?} off the pin's offset by {}", off(*p));
    }
    let worst = worst_off_offset(
        &pin.iter().map(|p| P2::new(p.x - 5.3, p.y - 1.0)).collect::<Vec<_>>(),
        0.1,
        0.1,
        0.05,
    );
    assert!(worst <= chord_tol + 2.0 * TOL, "{worst}");
    // It goes round: points on all four sides of the pin.
    assert!(pin.iter().any(|p| p.x < 5.3) && pin.iter().any(|p| p.x > 5.4));
    assert!(pin.iter().any(|p| p.y < 1.0) && pin.iter().any(|p| p.y > 1.1));
}

#[test]
fn refinement_traces_a_hole_that_meets_one_fibre_only() {
    // A frame of four blocks round a square hole 0.3 mm wide; flat cutter
    // of radius 0.05, fibres 0.5 apart from x, y = -0.1: the free square
    // inside the hole, x 1.3..1.5 and y 1.1..1.3, meets the fibre x = 1.4
    // and no other. Plain, only the frame's outer loop; refined, a pocket
    // loop round the free square too, counter-clockwise, on its edges.
    let mut tris = Vec::new();
    for (lo, hi) in [
        ((0.0, 0.0), (1.25, 3.0)),
        ((1.55, 0.0), (3.0, 3.0)),
        ((1.25, 0.0), (1.55, 1.05)),
        ((1.25, 1.35), (1.55, 3.0)),
    ] {
        tris.extend(cuboid(P3::new(lo.0, lo.1, 0.0), P3::new(hi.0, hi.1, 2.0)).iter_triangles());
    }
    let m = crate::mesh::Mesh::from_triangles(&tris);
    let dc = DropCutter::new(&m, Cutter::Flat { radius: 0.05 }).unwrap();
    assert_eq!(wl(0.5).loops(&dc, 1.0).unwrap().len(), 1, "the outer loop only");
    let w = Waterline {
        chord_tol: Some(1e-3),
        ..wl(0.5)
    };
    let loops = w.loops(&dc, 1.0).unwrap();
    assert_eq!(loops.len(), 2, "the outer loop and the hole's");
    let hole = loops
        .iter()
        .find(|l| l.iter().all(|p| p.x > 1.0 && p.x < 2.0 && p.y > 1.0 && p.y < 1.5))
        .expect("a loop in the hole");
    assert_eq!(hole.first(), hole.last());
    assert!(area2(hole) > 0.0, "counter-clockwise round a pocket");
    for p in hole {
        let to_edge = (p.x - 1.3).min(1.5 - p.x).min(p.y - 1.1).min(1.3 - p.y);
        assert!(
            (-1e-12..=2.0 * TOL).contains(&to_edge),
            "{p:?}: {to_edge} from the edge"
        );
    }
    assert!(hole.iter().any(|p| p.x < 1.31) && hole.iter().any(|p| p.x > 1.49));
    assert!(hole.iter().any(|p| p.y < 1.11) && hole.iter().any(|p| p.y > 1.29));
}
