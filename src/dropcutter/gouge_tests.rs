//! The gouge check against answers found another way: a brute-force
//! search along a trough whose cross-section is known, points sampled on
//! every triangle tested against the lifted tool's solid, and a convex
//! part on which no 5-axis location can gouge.

use super::*;
use crate::cutter::Cutter;
use crate::dropcutter::fiveaxis::{FiveAxis, Location};
use crate::geometry::P2;
use crate::mesh::Mesh;

/// A trough along x: the circle of radius `rho` about (y, z) = (0, rho),
/// from -60 to +60 degrees in `m` (odd) facets, so the middle facet is
/// level; x from -4 to 4 in 8 strips.
pub(crate) fn trough(rho: f64, m: usize) -> (Mesh, Vec<(f64, f64)>) {
    assert!(m % 2 == 1);
    let th_max = 60f64.to_radians();
    let section: Vec<(f64, f64)> = (0..=m)
        .map(|k| {
            let th = -th_max + 2.0 * th_max * k as f64 / m as f64;
            (rho * th.sin(), rho * (1.0 - th.cos()))
        })
        .collect();
    let mut tris = Vec::new();
    for i in 0..8 {
        let (x0, x1) = (-4.0 + i as f64, -3.0 + i as f64);
        for w in section.windows(2) {
            let [(y0, z0), (y1, z1)] = [w[0], w[1]];
            let (a, b, c, d) = (
                P3::new(x0, y0, z0),
                P3::new(x1, y0, z0),
                P3::new(x1, y1, z1),
                P3::new(x0, y1, z1),
            );
            tris.push(Triangle::new(a, b, c));
            tris.push(Triangle::new(a, c, d));
        }
    }
    (Mesh::from_triangles(&tris), section)
}

/// Height of the cutter's underside above its tip at distance `u` from
/// the axis (written out again here, not taken from the drop code).
pub(crate) fn underside(cutter: Cutter, u: f64) -> f64 {
    let (r, rc) = (cutter.radius(), cutter.corner_radius());
    let flat = r - rc;
    if u <= flat {
        0.0
    } else {
        let w = (u - flat).min(rc);
        rc - (rc * rc - w * w).sqrt()
    }
}

/// The tessellated section's height at `y` (linear between its corners).
fn section_z(section: &[(f64, f64)], y: f64) -> f64 {
    let k = section.partition_point(|&(sy, _)| sy <= y).clamp(1, section.len() - 1);
    let ((y0, z0), (y1, z1)) = (section[k - 1], section[k]);
    z0 + (z1 - z0) * (y - y0) / (y1 - y0)
}

#[test]
fn a_vertical_tool_in_a_trough_rises_to_the_brute_force_height() {
    let (mesh, section) = trough(2.0, 121);
    let bottom = section_z(&section, 0.0);
    for cutter in [
        Cutter::Flat { radius: 1.0 },
        Cutter::Torus {
            radius: 1.0,
            corner: 0.3,
        },
        Cutter::Flat { radius: 0.3 },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let gc = GougeCheck::new(&dc);
        let lift = gc.clearance(P3::new(0.3, 0.0, bottom), V3::z(), 50.0);
        // Brute force over the section (the trough is the same along x,
        // so the deepest point is straight across the axis): every
        // corner and a fine grid between.
        let r = cutter.radius();
        let mut ys: Vec<f64> = (0..=400_000).map(|i| -r + 2.0 * r * i as f64 / 400_000.0).collect();
        ys.extend(section.iter().map(|&(y, _)| y).filter(|y| y.abs() <= r));
        let want = ys
            .iter()
            .map(|&y| section_z(&section, y) - underside(cutter, y.abs()) - bottom)
            .fold(0.0f64, f64::max);
        assert!((lift - want).abs() < 1e-7, "{cutter:?}: {lift} against {want}");
        if cutter.radius() == 1.0 && cutter.corner_radius() == 0.0 {
            // The circle itself: the rim at |y| = 1 under the true arc.
            let analytic = 2.0 - (4.0f64 - 1.0).sqrt();
            assert!((lift - analytic).abs() < 2e-4, "{lift} against {analytic}");
        }
    }
    // A tool narrow enough to fit the level facet touches and no more.
    let dc = DropCutter::new(&mesh, Cutter::Flat { radius: 0.01 }).unwrap();
    let gc = GougeCheck::new(&dc);
    assert!(gc.clearance(P3::new(0.3, 0.0, bottom), V3::z(), 50.0) <= GOUGE_TOL);
}

/// Whether the point `p` lies inside the tool (tip `tip`, unit axis `a`,
/// `length` long) deeper than `eps`.
pub(crate) fn inside_tool(cutter: Cutter, tip: P3, a: V3, length: f64, p: P3, eps: f64) -> bool {
    let d = p - tip;
    let h = d.dot(&a);
    let u = (d - a * h).norm();
    u < cutter.radius() - eps && h > underside(cutter, u) + eps && h < length - eps
}

/// The trough of the 5-axis tests and one pass across it at x = -1.
pub(crate) fn trough_pass() -> (Mesh, Vec<P2>) {
    let (mesh, _) = trough(2.0, 41);
    let xy = (0..=24).map(|i| P2::new(-1.0, -1.6 + 3.2 * i as f64 / 24.0)).collect();
    (mesh, xy)
}

/// Points on a barycentric grid of `n` steps a side on every triangle.
pub(crate) fn samples(mesh: &Mesh, n: usize) -> Vec<P3> {
    let mut out = Vec::new();
    for t in mesh.iter_triangles() {
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                out.push(t.a + (t.b - t.a) * u + (t.c - t.a) * v);
            }
        }
    }
    out
}

#[test]
fn lifted_locations_leave_every_sampled_point_of_the_part_outside_the_tool() {
    let (mesh, xy) = trough_pass();
    let points = samples(&mesh, 12);
    for cutter in [
        Cutter::Flat { radius: 1.0 },
        Cutter::Torus {
            radius: 0.8,
            corner: 0.2,
        },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let gc = GougeCheck::new(&dc);
        for (lead, tilt) in [(0.0f64, 0.0f64), (10.0, 0.0), (5.0, -15.0)] {
            let fa = FiveAxis {
                lead: lead.to_radians(),
                tilt: tilt.to_radians(),
                axis_length: 6.0,
            };
            let raw = fa.pass(&dc, &xy).unwrap();
            let mut lifted = raw.clone();
            let report = gc.check(&mut lifted, 6.0, GougeRule::Lift);
            let mut reported = raw.clone();
            assert_eq!(gc.check(&mut reported, 6.0, GougeRule::Report), report);
            assert_eq!(reported, raw, "Report leaves the locations");
            assert_eq!(report.checked, 25);
            assert!(report.gouging >= 10, "{cutter:?} {lead} {tilt}: {report:?}");
            let mut found_raw_gouge = false;
            for (l, r0) in lifted.iter().flatten().zip(raw.iter().flatten()) {
                let a = (l.axis_point - l.cl).normalize();
                let depth = gc.clearance(r0.cl, a, 6.0);
                for &p in &points {
                    assert!(
                        !inside_tool(cutter, l.cl, a, 6.0, p, 1e-7),
                        "{cutter:?} {lead} {tilt}: {p:?} inside the tool at {:?}",
                        l.cl
                    );
                    found_raw_gouge |= inside_tool(cutter, r0.cl, a, 6.0, p, 1e-3);
                }
                // Lifted just enough: lowered a little it cuts again.
                let rest = gc.clearance(l.cl, a, 6.0);
                assert!(rest <= GOUGE_TOL, "{rest}");
                let lower = gc.clearance(l.cl - a * 1e-3, a, 6.0);
                if depth > GOUGE_TOL {
                    assert!((lower - 1e-3).abs() < 1e-9, "{depth}: {lower}");
                } else {
                    assert!(lower <= 1e-3 + 1e-9, "{depth}: {lower}");
                }
            }
            assert!(found_raw_gouge, "the unlifted tool does cut into the trough");
        }
    }
}

#[test]
fn nothing_gouges_a_convex_part() {
    let mesh = crate::dropcutter::tests::sphere(5.0, 64, 32);
    let xy: Vec<Vec<P2>> = (0..=12)
        .map(|j| {
            (0..=40)
                .map(|i| P2::new(-3.5 + 7.0 * i as f64 / 40.0, -3.0 + 0.5 * j as f64))
                .collect()
        })
        .collect();
    for cutter in [
        Cutter::Flat { radius: 1.0 },
        Cutter::Torus {
            radius: 1.0,
            corner: 0.25,
        },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let gc = GougeCheck::new(&dc);
        for (lead, tilt) in [(0.0, 0.0), (5.0f64, -3.0f64), (20.0, 10.0)] {
            let fa = FiveAxis {
                lead: lead.to_radians(),
                tilt: tilt.to_radians(),
                axis_length: 50.0,
            };
            let mut runs = Vec::new();
            for p in &xy {
                runs.extend(fa.pass(&dc, p).unwrap());
            }
            let before = runs.clone();
            let report = gc.check(&mut runs, 50.0, GougeRule::Lift);
            assert_eq!(report.checked, 13 * 41);
            assert_eq!(report.gouging, 0, "{cutter:?} {lead} {tilt}: {report:?}");
            assert_eq!(runs, before);
        }
    }
}

#[test]
fn the_checked_length_bounds_the_tool() {
    // A tall block beside a level floor: a tool standing on the floor
    // next to it, leaning over it, meets the block only above height 2.
    let mut tris = Vec::new();
    let floor = crate::mesh::solids::cuboid(P3::new(-5.0, -5.0, -1.0), P3::new(5.0, 5.0, 0.0));
    tris.extend(floor.iter_triangles());
    let block = crate::mesh::solids::cuboid(P3::new(2.0, -5.0, 2.0), P3::new(5.0, 5.0, 8.0));
    tris.extend(block.iter_triangles());
    let mesh = Mesh::from_triangles(&tris);
    let dc = DropCutter::new(&mesh, Cutter::Flat { radius: 0.5 }).unwrap();
    let gc = GougeCheck::new(&dc);
    let a = V3::new(1.0, 0.0, 1.0).normalize();
    // The tip half a radius over the floor, so the leaning bottom clears it.
    let tip = P3::new(0.0, 0.0, 0.5);
    // Up to 2 mm along the axis the tool is clear of the block.
    assert!(gc.clearance(tip, a, 2.0) <= GOUGE_TOL);
    // 10 mm long it runs into the block's underside.
    assert!(gc.clearance(tip, a, 10.0) > 1.0);
    // A roof sloping down across the axis of a vertical tool: below 1 mm
    // up the axis it stays beyond the radius, so only a longer tool meets
    // it (its triangles reach down to 0.5 mm, so they must be cut at the
    // checked height, not only rejected whole).
    let roof = |x: f64| 2.5 + 2.0 * x;
    let (p, q, r, t) = (
        P3::new(-1.0, -2.0, roof(-1.0)),
        P3::new(1.0, -2.0, roof(1.0)),
        P3::new(1.0, 2.0, roof(1.0)),
        P3::new(-1.0, 2.0, roof(-1.0)),
    );
    let mesh = Mesh::from_triangles(&[Triangle::new(p, q, r), Triangle::new(p, r, t)]);
    let dc = DropCutter::new(&mesh, Cutter::Flat { radius: 0.5 }).unwrap();
    let gc = GougeCheck::new(&dc);
    let up = V3::z();
    assert!(gc.clearance(P3::origin(), up, 1.0) <= GOUGE_TOL);
    // 2 mm long, the roof up to 2 mm lies in its disc from x = -0.5
    // (height 1.5) to x = -0.25 (height 2): 2 mm deep along the axis.
    let two = gc.clearance(P3::origin(), up, 2.0);
    assert!((two - 2.0).abs() < 1e-9, "{two}");
    // Degenerate queries are clear, not errors.
    assert_eq!(gc.clearance(tip, V3::zeros(), 10.0), 0.0);
    assert_eq!(gc.clearance(P3::new(f64::NAN, 0.0, 0.0), a, 10.0), 0.0);
    assert_eq!(gc.clearance(tip, a, 0.0), 0.0);
}

/// A floor (z = 0, 10 mm square about the origin) and a block standing on
/// it: x from 1 to 1.5, y from -3 to 3, 5 mm tall; turned by `rot` and
/// moved by `shift`.
fn floor_and_wall(rot: nalgebra::Rotation3<f64>, shift: V3) -> Mesh {
    let p = |x: f64, y: f64, z: f64| rot * P3::new(x, y, z) + shift;
    let quad = |t: &mut Vec<Triangle>, a: P3, b: P3, c: P3, d: P3| {
        t.push(Triangle::new(a, b, c));
        t.push(Triangle::new(a, c, d));
    };
    let mut t = Vec::new();
    quad(&mut t, p(-5., -5., 0.), p(5., -5., 0.), p(5., 5., 0.), p(-5., 5., 0.));
    let (x0, x1, y0, y1, h) = (1.0, 1.5, -3.0, 3.0, 5.0);
    quad(&mut t, p(x0, y0, h), p(x1, y0, h), p(x1, y1, h), p(x0, y1, h));
    quad(&mut t, p(x0, y0, 0.), p(x0, y1, 0.), p(x0, y1, h), p(x0, y0, h));
    quad(&mut t, p(x1, y0, 0.), p(x1, y1, 0.), p(x1, y1, h), p(x1, y0, h));
    quad(&mut t, p(x0, y0, 0.), p(x1, y0, 0.), p(x1, y0, h), p(x0, y0, h));
    quad(&mut t, p(x0, y1, 0.), p(x1, y1, 0.), p(x1, y1, h), p(x0, y1, h));
    Mesh::from_triangles(&t)
}

#[test]
fn a_holder_rises_above_a_wall_its_cutter_clears() {
    let cutter = Cutter::Flat { radius: 0.5 };
    let holder = |radius: f64, height: f64| Holder { radius, height };
    // The same scene in place and turned and moved: the answers must not
    // depend on the frame.
    let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 1.1);
    let shift = V3::new(3.0, -2.0, 7.0);
    for (r, s) in [(nalgebra::Rotation3::identity(), V3::zeros()), (rot, shift)] {
        let mesh = floor_and_wall(r, s);
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let tip = r * P3::origin() + s;
        let up = r * V3::z();
        let depth = |h: Option<Holder>, axis: V3, length: f64| {
            let gc = GougeCheck::new(&dc);
            let gc = match h {
                Some(h) => gc.with_holder(h).unwrap(),
                None => gc,
            };
            gc.clearance(tip, axis, length)
        };
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
        // The cutter stands on the floor a millimetre from the wall.
        assert!(close(depth(None, up, 10.0), 0.0));
        // A holder reaching the wall from 2 mm up: it rises until its face
        // is level with the wall's top (5 mm).
        assert!(close(depth(Some(holder(1.5, 2.0)), up, 10.0), 3.0));
        // The wall's top cut at the checked length (4 mm).
        assert!(close(depth(Some(holder(1.5, 2.0)), up, 4.0), 2.0));
        // A face above the wall, a holder that does not reach it, a
        // holder beyond the checked length: clear.
        assert!(close(depth(Some(holder(1.5, 6.0)), up, 10.0), 0.0));
        assert!(close(depth(Some(holder(0.99, 2.0)), up, 10.0), 0.0));
        assert!(close(depth(Some(holder(1.5, 12.0)), up, 10.0), 0.0));
        // Tilted 20 degrees away from the wall the holder clears it: the
        // depth is the cutter's alone (its rim in the floor, r tan 20
        // deg); towards the wall the holder goes deeper than upright.
        let (sin, cos) = 20f64.to_radians().sin_cos();
        let away = r * V3::new(-sin, 0.0, cos);
        let towards = r * V3::new(sin, 0.0, cos);
        let rim = 0.5 * sin / cos;
        assert!(close(depth(None, away, 10.0), rim));
        assert!(close(depth(Some(holder(1.5, 2.0)), away, 10.0), rim));
        assert!(depth(Some(holder(1.5, 2.0)), towards, 10.0) > 3.0);
    }
    // A stepped holder: a collet nut that does not reach the wall (0.9
    // mm from 2 mm up) under a body that does (1.5 mm from 4 mm up): the
    // body's face rises to the wall's top; each cylinder alone gives what
    // it gives, and the union the worst of them, whatever the order.
    let mesh = floor_and_wall(nalgebra::Rotation3::identity(), V3::zeros());
    let dc = DropCutter::new(&mesh, cutter).unwrap();
    let stepped = |hs: &[Holder]| {
        hs.iter()
            .fold(GougeCheck::new(&dc), |c, &h| c.with_holder(h).unwrap())
            .clearance(P3::origin(), V3::z(), 10.0)
    };
    let (nut, body) = (holder(0.9, 2.0), holder(1.5, 4.0));
    assert_eq!(stepped(&[nut]), 0.0);
    assert!((stepped(&[body]) - 1.0).abs() < 1e-9);
    assert!((stepped(&[nut, body]) - 1.0).abs() < 1e-9);
    assert!((stepped(&[body, nut]) - 1.0).abs() < 1e-9);
    // A nose wider still, lower than the wall's top: the deepest wins.
    let nose = holder(2.0, 3.0);
    assert!((stepped(&[nut, body, nose]) - 2.0).abs() < 1e-9);
    // A holder narrower than the cutter, or at the tip, is refused.
    let mesh = floor_and_wall(nalgebra::Rotation3::identity(), V3::zeros());
    let dc = DropCutter::new(&mesh, cutter).unwrap();
    for h in [
        holder(0.4, 2.0),
        holder(1.0, 0.0),
        holder(f64::NAN, 2.0),
        holder(1.0, -1.0),
    ] {
        assert!(GougeCheck::new(&dc).with_holder(h).is_err(), "{h:?}");
    }
}

#[test]
fn a_lifted_tool_with_its_holder_leaves_every_sampled_point_outside() {
    // Tools around the wall at many tilts: lifted by the clearance found,
    // no sampled point of the part is inside the cutter or the holder;
    // lowered by 1e-3 mm, the tool is 1e-3 mm deep again (the lift is no
    // larger than needed).
    let mesh = floor_and_wall(nalgebra::Rotation3::identity(), V3::zeros());
    let points = samples(&mesh, 40);
    let cutter = Cutter::Flat { radius: 0.5 };
    let h = Holder {
        radius: 1.25,
        height: 1.5,
    };
    let dc = DropCutter::new(&mesh, cutter).unwrap();
    let gc = GougeCheck::new(&dc).with_holder(h).unwrap();
    let bare = GougeCheck::new(&dc);
    let length = 8.0;
    let mut by_holder = 0;
    let inside = |tip: P3, a: V3, p: P3, eps: f64| {
        let d = p - tip;
        let along = d.dot(&a);
        let u = (d - a * along).norm();
        let in_holder = u < h.radius - eps && along > h.height + eps && along < length - eps;
        in_holder || inside_tool(cutter, tip, a, length, p, eps)
    };
    let mut binding = 0;
    for i in 0..12 {
        for j in 0..5 {
            let tip = P3::new(-0.2 + 0.08 * i as f64, 0.3 * j as f64 - 0.6, 0.0);
            let (th, ph) = (0.35 * (j as f64 - 2.0), 0.7 * i as f64);
            let a = V3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            let d = gc.clearance(tip, a, length);
            let lifted = tip + a * d;
            for &p in &points {
                assert!(!inside(lifted, a, p, 1e-7), "tip {tip:?} axis {a:?}: {p:?} inside");
            }
            if d > 1e-3 {
                let again = gc.clearance(lifted - a * 1e-3, a, length);
                assert!((again - 1e-3).abs() < 1e-9, "tip {tip:?} axis {a:?}: {again}");
                binding += 1;
            }
            by_holder += (d > bare.clearance(tip, a, length) + 1e-6) as usize;
        }
    }
    assert!(binding > 10, "{binding}");
    assert!(by_holder > 5, "{by_holder}");
}

/// Contacts along `xy` on `dc` with smoothed normals, and the locations
/// made from them, as pathgen makes them before setting them down.
pub(crate) fn smooth_pass(
    dc: &DropCutter,
    fa: &FiveAxis,
    xy: &[P2],
) -> (Vec<Vec<crate::dropcutter::fiveaxis::Contact>>, Vec<Vec<Location>>) {
    let (r, rc) = FiveAxis::radii(dc).unwrap();
    let normals = dc.smooth_normals(crate::dropcutter::normals::DEFAULT_CREASE_DEG.to_radians());
    let contacts = FiveAxis::contacts_with(dc, xy, Some(&normals));
    let runs = contacts
        .iter()
        .map(|run| run.iter().map(|c| fa.location(c.cc, c.normal, c.feed, r, rc)).collect())
        .collect();
    (contacts, runs)
}

#[test]
fn settled_tools_touch_the_part_and_are_nowhere_in_it() {
    // A coarse sphere: the smoothed tangent planes are well off the
    // facets, so unsettled tools sit in the part or above it.
    let mesh = crate::dropcutter::tests::sphere(5.0, 24, 12);
    let points = samples(&mesh, 8);
    let xy: Vec<P2> = (0..=30).map(|i| P2::new(-3.0 + 6.0 * i as f64 / 30.0, 0.7)).collect();
    for cutter in [
        Cutter::Flat { radius: 1.0 },
        Cutter::Torus {
            radius: 1.0,
            corner: 0.3,
        },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let gc = GougeCheck::new(&dc);
        for (lead, tilt) in [(0.0f64, 0.0f64), (8.0, -4.0)] {
            let fa = FiveAxis {
                lead: lead.to_radians(),
                tilt: tilt.to_radians(),
                axis_length: 20.0,
            };
            let (contacts, raw) = smooth_pass(&dc, &fa, &xy);
            let mut runs = raw.clone();
            let (gouges, report) = gc.check_settling(&contacts, &mut runs, fa.axis_length, GougeRule::Lift);
            // A convex part: nothing rose beyond its own facet's plane.
            assert_eq!(gouges.gouging, 0, "{cutter:?} {lead}: {gouges:?}");
            assert_eq!(report.settled, 31, "{report:?}");
            assert_eq!(report.nothing_below, 0);
            // A tool touches its own contact point, so it never comes
            // down; it rises out of the facets around it.
            assert!(
                report.raised > 10 && report.highest > 1e-4,
                "{cutter:?} {lead}: {report:?}"
            );
            let mut was_in = false;
            for (l, r0) in runs.iter().flatten().zip(raw.iter().flatten()) {
                let a = (l.axis_point - l.cl).normalize();
                // Moved along its own axis only.
                let shift = l.cl - r0.cl;
                assert!((shift - a * shift.dot(&a)).norm() < 1e-12);
                assert!(shift.dot(&a) > -1e-9, "{shift:?}");
                // Touching: clear where it is, 1e-4 into the part lowered by 1e-4.
                assert!(gc.clearance(l.cl, a, fa.axis_length) <= GOUGE_TOL);
                let lower = gc.clearance(l.cl - a * 1e-4, a, fa.axis_length);
                assert!((lower - 1e-4).abs() < 1e-9, "{cutter:?} {lead}: {lower}");
                for &p in &points {
                    assert!(
                        !inside_tool(cutter, l.cl, a, fa.axis_length, p, 1e-7),
                        "{p:?} in the tool at {l:?}"
                    );
                    was_in |= inside_tool(cutter, r0.cl, a, fa.axis_length, p, 1e-4);
                }
            }
            assert!(was_in, "{cutter:?} {lead}: the unsettled tools cut into the facets");
        }
    }
}

#[test]
fn a_tool_with_no_part_within_reach_is_left_where_it_is() {
    let mesh = crate::dropcutter::tests::sphere(5.0, 24, 12);
    let dc = DropCutter::new(&mesh, Cutter::Flat { radius: 1.0 }).unwrap();
    let gc = GougeCheck::new(&dc);
    // Beside the sphere, pointing up: nothing below within the radius.
    assert_eq!(gc.rest_height(P3::new(9.0, 0.0, 0.0), V3::z(), 10.0, 1.0), None);
    // Above the top: comes down by the gap (searched from far enough).
    let h = gc.rest_height(P3::new(0.0, 0.0, 5.5), V3::z(), 10.0, 1.0).unwrap();
    assert!(h < -0.4 && h > -0.6, "{h}");
    // Farther above than the search reaches (the radius below the
    // searched stretch): nothing.
    assert_eq!(gc.rest_height(P3::new(0.0, 0.0, 8.5), V3::z(), 10.0, 1.0), None);
    for bad in [f64::NAN, -1.0] {
        assert_eq!(gc.rest_height(P3::new(0.0, 0.0, 5.5), V3::z(), 10.0, bad), None);
    }
    let mut runs = vec![vec![Location {
        cl: P3::new(9.0, 0.0, 0.0),
        axis_point: P3::new(9.0, 0.0, 10.0),
    }]];
    let contacts = vec![vec![crate::dropcutter::fiveaxis::Contact {
        cc: P3::new(9.0, 0.0, 0.0),
        normal: V3::z(),
        facet: V3::z(),
        feed: V3::x(),
    }]];
    let before = runs.clone();
    let (_, r) = gc.check_settling(&contacts, &mut runs, 10.0, GougeRule::Lift);
    assert_eq!((r.settled, r.nothing_below), (0, 1));
    assert_eq!(runs, before);
}

#[test]
fn the_rise_out_of_a_facets_plane_is_exact() {
    // A tilted plane; tools touching it (made by the facet-normal rule at
    // several leads and tilts) rise 0 out of it, and the same tools
    // lowered by 0.3 mm along their axes rise 0.3.
    let n = V3::new(0.2, -0.3, 1.0).normalize();
    let plane = |x: f64, y: f64| (0.0 - n.x * x - n.y * y) / n.z;
    let mesh = crate::dropcutter::tests::surface(4.0, 4, plane);
    for cutter in [
        Cutter::Flat { radius: 1.0 },
        Cutter::Torus {
            radius: 1.0,
            corner: 0.4,
        },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let gc = GougeCheck::new(&dc);
        let (r, rc) = FiveAxis::radii(&dc).unwrap();
        for (lead, tilt) in [(0.0f64, 0.0f64), (10.0, 0.0), (5.0, -20.0), (-30.0, 15.0)] {
            let fa = FiveAxis {
                lead: lead.to_radians(),
                tilt: tilt.to_radians(),
                axis_length: 10.0,
            };
            let cc = P3::new(0.3, -0.2, plane(0.3, -0.2));
            let l = fa.location(cc, n, V3::new(1.0, 0.4, 0.0), r, rc);
            let rise = gc.plane_rise(&l, cc, n);
            assert!(rise.abs() < 1e-12, "{cutter:?} {lead} {tilt}: {rise}");
            // On the plane itself the drop agrees.
            let a = (l.axis_point - l.cl).normalize();
            assert!(gc.clearance(l.cl, a, 10.0) <= GOUGE_TOL);
            let low = lifted(&l, -0.3);
            let rise = gc.plane_rise(&low, cc, n);
            assert!((rise - 0.3).abs() < 1e-12, "{cutter:?} {lead} {tilt}: {rise}");
            assert!((gc.clearance(low.cl, a, 10.0) - 0.3).abs() < 1e-9);
        }
    }
}

#[test]
fn smoothed_locations_in_a_trough_are_turned_or_lifted_clear() {
    // The trough is tighter than the tool: set down, many locations rise
    // beyond their facets (gouges); the tilt search turns them clear.
    let (mesh, xy) = trough_pass();
    let points = samples(&mesh, 12);
    let cutter = Cutter::Flat { radius: 1.0 };
    let dc = DropCutter::new(&mesh, cutter).unwrap();
    let gc = GougeCheck::new(&dc);
    let fa = FiveAxis {
        lead: 0.0,
        tilt: 0.0,
        axis_length: 6.0,
    };
    let (contacts, raw) = smooth_pass(&dc, &fa, &xy);
    let mut lifted_runs = raw.clone();
    let (lift, _) = gc.check_settling(&contacts, &mut lifted_runs, 6.0, GougeRule::Lift);
    assert!(lift.gouging >= 10, "{lift:?}");
    let mut turned = raw.clone();
    let search = crate::dropcutter::tilt::TiltSearch {
        max: 30f64.to_radians(),
        step: 5f64.to_radians(),
        ramp: 2.0,
        both: true,
    };
    let (report, tilt, settling) = gc
        .check_tilting(&fa, &contacts, &mut turned, &search, Placement::SetDown)
        .unwrap();
    assert_eq!(report.gouging, lift.gouging);
    assert_eq!(settling.settled, 25);
    assert!(tilt.tilted > 0, "{tilt:?}");
    for l in turned.iter().flatten().chain(lifted_runs.iter().flatten()) {
        let a = (l.axis_point - l.cl).normalize();
        assert!(gc.clearance(l.cl, a, 6.0) <= GOUGE_TOL, "{l:?}");
        for &p in &points {
            assert!(
                !inside_tool(cutter, l.cl, a, 6.0, p, 1e-7),
                "{p:?} in the tool at {l:?}"
            );
        }
    }
    // Turned tools stay on the part: lowered 1e-4 they are in it.
    for l in turned.iter().flatten() {
        let a = (l.axis_point - l.cl).normalize();
        assert!(gc.clearance(l.cl - a * 1e-4, a, 6.0) > 0.5e-4, "{l:?}");
    }
}

/// The 5-axis job the corpus tests run on every corpus mesh (other
/// programs' files: open, non-manifold, degenerate triangles, vertices
/// written more than once): a torus of 5 % of the part, lead 5 and tilt -3
/// degrees, twice the part's size plus its height of tool checked, passes
/// along X at 30, 50 and 70 % of its depth, 41 points each. `pass` gets the
/// mesh's file, its gouge check, the part's size, the orientation and the
/// pass's points. `None` when the corpus is absent.
pub(crate) fn on_corpus_passes(
    mut pass: impl FnMut(&std::path::Path, &GougeCheck, f64, &FiveAxis, &[P2]),
) -> Option<()> {
    let meshes = crate::mesh::read_corpus_meshes()?;
    for (f, mesh) in &meshes {
        let bb = mesh.bbox();
        let size = (bb.max.x - bb.min.x).max(bb.max.y - bb.min.y);
        if size <= 0.0 || !size.is_finite() {
            continue;
        }
        let cutter = Cutter::Torus {
            radius: 0.05 * size,
            corner: 0.01 * size,
        };
        let Ok(dc) = DropCutter::new(mesh, cutter) else {
            continue;
        };
        let gc = GougeCheck::new(&dc);
        let fa = FiveAxis {
            lead: 5f64.to_radians(),
            tilt: -3f64.to_radians(),
            axis_length: 2.0 * size + (bb.max.z - bb.min.z),
        };
        for frac in [0.3, 0.5, 0.7] {
            let y = bb.min.y + frac * (bb.max.y - bb.min.y);
            let xy: Vec<P2> = (0..=40)
                .map(|i| P2::new(bb.min.x + (bb.max.x - bb.min.x) * i as f64 / 40.0, y))
                .collect();
            pass(f, &gc, size, &fa, &xy);
        }
    }
    Some(())
}

#[test]
fn on_every_corpus_mesh_set_down_tools_touch_it_and_are_nowhere_in_it() {
    // Smoothed-normal locations on passes across each corpus mesh, set
    // down. Each one clears the part, and each one that found the part
    // below touches it (lowered a little, it is in it).
    let mut checked = 0;
    let ran = on_corpus_passes(|f, gc, size, fa, xy| {
        let length = fa.axis_length;
        let eps = 1e-4 * size;
        let (contacts, runs) = smooth_pass(gc.drop_cutter(), fa, xy);
        for (run, settled) in runs.iter().zip(gc.settle_all(&contacts, &runs, length)) {
            for (l, s) in run.iter().zip(settled) {
                let a = (l.axis_point - l.cl).normalize();
                let at = s.location;
                assert!(
                    gc.clearance(at.cl, a, length) <= GOUGE_TOL * size.max(1.0),
                    "{f:?}: {at:?}"
                );
                if s.raise.is_some() {
                    let lower = gc.clearance(at.cl - a * eps, a, length);
                    assert!(lower > 0.5 * eps, "{f:?}: {at:?} lowered {eps} is {lower} in the part");
                }
                checked += 1;
            }
        }
    });
    if ran.is_none() {
        crate::corpus::skip("corpus_meshes_set_down_tools_touch_them");
        return;
    }
    crate::corpus::record("corpus_meshes_set_down_tools_touch_them", checked);
    assert!(checked > 100, "{checked}");
}

/// `clears` is `clearance <= tol` found sooner: the same answer for tools
/// with and without a holder, at tolerances either side of each depth.
#[test]
fn clears_answers_as_clearance_does() {
    let mesh = floor_and_wall(nalgebra::Rotation3::identity(), V3::zeros());
    for cutter in [
        Cutter::Flat { radius: 0.5 },
        Cutter::Torus {
            radius: 0.5,
            corner: 0.2,
        },
    ] {
        let dc = DropCutter::new(&mesh, cutter).unwrap();
        let holder = Holder {
            radius: 1.25,
            height: 1.5,
        };
        let checks = [
            GougeCheck::new(&dc),
            GougeCheck::new(&dc).with_holder(holder).unwrap(),
            GougeCheck::new(&dc)
                .with_holder(holder)
                .unwrap()
                .with_holder(Holder {
                    radius: 2.0,
                    height: 3.0,
                })
                .unwrap(),
        ];
        let (mut clear, mut cut) = (0, 0);
        for gc in &checks {
            for i in 0..12 {
                for j in 0..5 {
                    let tip = P3::new(
                        -0.2 + 0.08 * i as f64,
                        0.3 * j as f64 - 0.6,
                        0.25 * (i % 4) as f64 - 0.02,
                    );
                    let (th, ph) = (0.35 * (j as f64 - 2.0), 0.7 * i as f64);
                    let a = V3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                    let d = gc.clearance(tip, a, 8.0);
                    for tol in [GOUGE_TOL, 0.5 * d, d, d * (1.0 + 1e-9) + 1e-12, 2.0 * d + 0.01] {
                        assert_eq!(
                            gc.clears(tip, a, 8.0, tol),
                            d <= tol,
                            "tip {tip:?} axis {a:?} depth {d} tol {tol}"
                        );
                    }
                    if d <= GOUGE_TOL {
                        clear += 1;
                    } else {
                        cut += 1;
                    }
                }
            }
        }
        assert!(clear > 10 && cut > 10, "{cutter:?}: {clear} clear, {cut} cut");
    }
}
