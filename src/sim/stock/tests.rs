use super::*;
use std::f64::consts::PI;

fn stock(cell: f64) -> Stock {
    Stock::new(P3::new(-2.0, -2.0, -2.0), P3::new(12.0, 2.0, 0.0), cell).unwrap()
}

/// Area of the groove cross-section a cutter leaves at depth `d`
/// (integral of the depth across the groove), by the midpoint rule on
/// a million strips: independent of the grid code.
fn groove_area(c: &Cutter, d: f64) -> f64 {
    let r = c.radius();
    let n = 1_000_000;
    let w = 2.0 * r / n as f64;
    (0..n)
        .map(|k| {
            let x = -r + (k as f64 + 0.5) * w;
            c.profile(x.abs()).map_or(0.0, |h| (d - h).max(0.0)) * w
        })
        .sum()
}

/// Volume of the tool's footprint at depth `d` (a solid of revolution).
fn plunge_volume(c: &Cutter, d: f64) -> f64 {
    let r = c.radius();
    let n = 1_000_000;
    let w = r / n as f64;
    (0..n)
        .map(|k| {
            let rho = (k as f64 + 0.5) * w;
            2.0 * PI * rho * c.profile(rho).map_or(0.0, |h| (d - h).max(0.0)) * w
        })
        .sum()
}

#[test]
fn straight_slots_match_their_exact_volume_at_d_over_50() {
    // Slot of length L at depth d: groove cross-section × L plus the
    // tool's footprint (two half ends make one plunge).
    let d_tool = 2.0;
    let (len, depth) = (10.0, 0.5);
    for c in [
        Cutter::Flat { radius: 1.0 },
        Cutter::Ball { radius: 1.0 },
        Cutter::Torus {
            radius: 1.0,
            corner: 0.3,
        },
    ] {
        let exact = groove_area(&c, depth) * len + plunge_volume(&c, depth);
        let mut s = stock(d_tool / 50.0);
        let v0 = s.volume();
        // Off the grid's symmetry: a slot edge exactly on a row of cell
        // centres would count that row whole.
        let removed = s.cut_line(&P3::new(0.0, 0.0137, -depth), &P3::new(len, 0.0137, -depth), &c);
        assert!((v0 - s.volume() - removed).abs() < 1e-9 * v0, "{c:?} bookkeeping");
        let err = (removed - exact).abs() / exact;
        assert!(err < 0.005, "{c:?}: {removed} vs {exact} ({:.3} %)", err * 100.0);
    }
}

#[test]
fn every_surface_sample_is_within_a_cell_of_the_exact_surface() {
    let c = Cutter::Ball { radius: 1.0 };
    let mut s = stock(0.04);
    s.cut_line(&P3::new(0.0, 0.0, -0.5), &P3::new(10.0, 0.0, -0.5), &c);
    for j in 0..s.ny {
        for i in 0..s.nx {
            let (px, py) = (s.x0 + (i as f64 + 0.5) * s.cell, s.y0 + (j as f64 + 0.5) * s.cell);
            let rho = dist_xy_segment(px, py, &P3::new(0.0, 0.0, 0.0), &P3::new(10.0, 0.0, 0.0));
            let want = c.profile(rho).map_or(0.0, |h| (h - 0.5).min(0.0));
            assert!((s.z[j * s.nx + i] - want).abs() <= s.cell, "{px} {py}");
        }
    }
}

#[test]
fn ramps_and_arcs_cut_what_they_should() {
    // A ramp from the top down to 0.5 mm deep with a flat tool removes
    // half the level slot's groove volume along its length, plus the
    // footprint at the deep end.
    let c = Cutter::Flat { radius: 1.0 };
    let mut s = stock(0.02);
    let v = s.cut_line(&P3::new(0.0, 0.0, 0.0), &P3::new(10.0, 0.0, -0.5), &c);
    let exact = 2.0 * 0.5 * 10.0 / 2.0 + PI * 0.5;
    assert!((v - exact).abs() / exact < 0.01, "{v} vs {exact}");
    // A half circle of radius 4 at 0.2 mm deep: groove × arc length +
    // footprint.
    let mut s = Stock::new(P3::new(-6.0, -6.0, -1.0), P3::new(6.0, 6.0, 0.0), 0.02).unwrap();
    let arc = Arc3::new(
        P3::origin(),
        P3::new(4.0, 0.0, -0.2),
        P3::new(-4.0, 0.0, -0.2),
        true,
        crate::geometry::Plane::Xy,
        0,
    )
    .unwrap();
    let v = s.cut_arc(&arc, &c);
    let exact = 2.0 * 0.2 * 4.0 * PI + PI * 0.2;
    assert!((v - exact).abs() / exact < 0.005, "{v} vs {exact}");
    // Cutting the same path again removes nothing.
    assert!(s.cut_arc(&arc, &c).abs() < 1e-12);
}

#[test]
fn level_moves_agree_with_the_general_search() {
    // The fast path (stadium chord, closed-form depth, branch-free flat
    // loop) against the golden-section search on the same moves.
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for c in [
        Cutter::Flat { radius: 0.7 },
        Cutter::Ball { radius: 0.7 },
        Cutter::Torus {
            radius: 0.7,
            corner: 0.2,
        },
    ] {
        let mut fast = Stock::new(P3::new(-3.0, -3.0, -2.0), P3::new(3.0, 3.0, 0.0), 0.05).unwrap();
        let mut slow = fast.clone();
        for _ in 0..12 {
            let z = -rnd();
            let a = P3::new(6.0 * rnd() - 3.0, 6.0 * rnd() - 3.0, z);
            // Some moves axis-parallel, some a point.
            let b = match (rnd() * 4.0) as u32 {
                0 => P3::new(a.x, 6.0 * rnd() - 3.0, z),
                1 => P3::new(6.0 * rnd() - 3.0, a.y, z),
                2 => a,
                _ => P3::new(6.0 * rnd() - 3.0, 6.0 * rnd() - 3.0, z),
            };
            let vf = fast.cut_line(&a, &b, &c);
            let mut vs = 0.0;
            for j in 0..slow.ny {
                for i in 0..slow.nx {
                    let (px, py) = (
                        slow.x0 + (i as f64 + 0.5) * slow.cell,
                        slow.y0 + (j as f64 + 0.5) * slow.cell,
                    );
                    let zc = &mut slow.z[j * slow.nx + i];
                    // A tiny tilt sends the general path through the search.
                    if let Some(h) = lowest_on_move(px, py, &a, &P3::new(b.x, b.y, b.z + 1e-13), &c)
                        && h < *zc - 1e-9
                    {
                        vs += (*zc - h) * slow.cell * slow.cell;
                        *zc = h;
                    }
                }
            }
            assert!((vf - vs).abs() < 1e-6, "{c:?}: {vf} vs {vs}");
        }
        for (f, s) in fast.z.iter().zip(&slow.z) {
            assert!((f - s).abs() < 1e-9);
        }
    }
}

#[test]
fn rasters_along_y_and_diagonals_in_parallel_bands_agree_with_the_search() {
    // Level passes along Y (the per-band height cache), at 45° and at
    // an odd angle (per-cell heights beside the segment, the torus'
    // flat span), cut as one parallel batch, against the golden-section
    // search cell by cell.
    // The passes are placed off the 0.02 mm grid's decimal steps: a
    // column of cell centres exactly R from a pass (0.3 + 0.55·k + 0.6
    // is on the grid) is a tie, in or out of the tool by one rounding
    // of the distance. The torus' rim is a vertical wall `corner` above
    // its tip, so such a column is cut `corner` deep or not at all (6e-6
    // of the volume here); the ball's rim lies above the stock.
    for c in [
        Cutter::Ball { radius: 0.6 },
        Cutter::Torus {
            radius: 0.6,
            corner: 0.25,
        },
    ] {
        let mut fast = Stock::new(P3::new(0.0, 0.0, -2.0), P3::new(5.0, 5.0, 0.0), 0.02).unwrap();
        let mut slow = fast.clone();
        let mut pieces = Vec::new();
        for k in 0..8 {
            let x = 0.3013 + 0.55 * k as f64;
            let z = -0.2 - 0.03 * k as f64;
            pieces.push((P3::new(x, -0.5, z), P3::new(x, 5.5, z)));
            let y = 0.2017 + 0.6 * k as f64;
            pieces.push((P3::new(-0.3, y - 0.5, z), P3::new(2.9, y + 2.7, z)));
            pieces.push((P3::new(4.6, y, z - 0.1), P3::new(0.7, y + 1.3, z - 0.1)));
        }
        let vf: f64 = fast.cut_lines(&pieces, &c).iter().sum();
        let mut vs = 0.0;
        for (a, b) in &pieces {
            for j in 0..slow.ny {
                for i in 0..slow.nx {
                    let (px, py) = (
                        slow.x0 + (i as f64 + 0.5) * slow.cell,
                        slow.y0 + (j as f64 + 0.5) * slow.cell,
                    );
                    let zc = &mut slow.z[j * slow.nx + i];
                    if let Some(h) = lowest_on_move(px, py, a, &P3::new(b.x, b.y, b.z + 1e-13), &c)
                        && h < *zc - 1e-9
                    {
                        vs += (*zc - h) * slow.cell * slow.cell;
                        *zc = h;
                    }
                }
            }
        }
        assert!((vf - vs).abs() < 1e-6 * vs.max(1.0), "{c:?}: {vf} vs {vs}");
        let worst = fast
            .z
            .iter()
            .zip(&slow.z)
            .map(|(f, s)| (f - s).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{c:?}: {worst}");
    }
}

#[test]
fn a_parallel_batch_cuts_like_one_move_after_another() {
    let c = Cutter::Torus {
        radius: 0.5,
        corner: 0.2,
    };
    let mut one = Stock::new(P3::new(0.0, 0.0, -2.0), P3::new(10.0, 10.0, 0.0), 0.02).unwrap();
    let mut batch = one.clone();
    // Overlapping moves, level and ramping, so order matters per cell.
    let pieces: Vec<(P3, P3)> = (0..40)
        .map(|k| {
            let t = k as f64 * 0.37;
            let a = P3::new(5.0 + 4.0 * t.cos(), 5.0 + 4.0 * t.sin(), -0.2 - 0.01 * k as f64);
            let b = P3::new(
                5.0 + 3.0 * (t + 2.0).cos(),
                5.0 + 3.0 * (t + 2.0).sin(),
                if k % 2 == 0 { a.z } else { -0.9 },
            );
            (a, b)
        })
        .collect();
    let v1: Vec<f64> = pieces.iter().map(|(a, b)| one.cut_line(a, b, &c)).collect();
    let vb = batch.cut_lines(&pieces, &c);
    for (x, y) in v1.iter().zip(&vb) {
        assert!((x - y).abs() < 1e-9, "{x} vs {y}");
    }
    assert_eq!(one.z, batch.z);
    assert_eq!(one.cells_visited, batch.cells_visited);
}

/// Distance in XY from (px, py) to the segment a-b.
fn dist_xy_segment(px: f64, py: f64, a: &P3, b: &P3) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let (wx, wy) = (px - a.x, py - a.y);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        ((wx * dx + wy * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((wx - t * dx).powi(2) + (wy - t * dy).powi(2)).sqrt()
}
