//! Physics of generated drawings, checked on the output moves with
//! [`super::audit`]: constant speed, acceleration within the limit
//! everywhere off the drawing, the shutter fully open exactly over the
//! cuts, every chain cut once per pass, offsets at the right distance.

use super::audit::{Audit, audit};
use super::contour::{ContourOptions, contour, cut_paths};
use super::offset::{Side, chain_elems};
use super::setup::LaserSetup;
use crate::formats::chains::ChainsReader;
use crate::geometry::{P3, V3};
use crate::model::chain::{Chain, Segment};
use crate::model::toolpath::{MotionKind, Record, Role};

fn plate() -> Vec<Chain> {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/chains/plate.chains")).unwrap();
    ChainsReader::new(text.as_bytes())
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap()
}

/// Random closed polygons (sharp and shallow corners, some arcs) and open
/// polylines, from a fixed xorshift seed.
pub(crate) fn random_drawing(n: usize, seed: u64) -> Vec<Chain> {
    let mut s = seed.max(1);
    let mut r = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(n);
    for id in 0..n {
        let c = P3::new(100.0 * r(), 100.0 * r(), 0.0);
        let k = 3 + (r() * 6.0) as usize;
        let rad = 0.5 + 2.0 * r();
        // A star-shaped polygon: sorted angles, random radii.
        let mut angs: Vec<f64> = (0..k).map(|_| r() * std::f64::consts::TAU).collect();
        angs.sort_by(f64::total_cmp);
        let pts: Vec<P3> = angs
            .iter()
            .map(|&a| c + V3::new(a.cos(), a.sin(), 0.0) * rad * (0.5 + 0.5 * r()))
            .collect();
        let closed = id % 5 != 4;
        let m = if closed { k } else { k - 1 };
        let segments = (0..m)
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % k]);
                if i % 3 == 1 {
                    // A shallow arc bulging outwards: centre left of the
                    // chord (the polygon runs counter-clockwise).
                    let d = b - a;
                    let ctr = nalgebra::center(&a, &b) + V3::new(-d.y, d.x, 0.0) * 0.4;
                    Segment::arc_xy(a, b, ctr, true)
                } else {
                    Segment::line(a, b)
                }
            })
            .collect();
        out.push(Chain {
            id: id as u64 + 1,
            closed,
            segments,
            ..Default::default()
        });
    }
    out
}

/// `exposure_tol`: how far (mm) the shutter may act off a cut end. Exact
/// (1e-6) unless the drawing has pieces shorter than 1 ms at V beside a
/// switch point, where pathgen reports the offset (at most V·1 ms).
fn check_physics(a: &Audit, m: &LaserSetup, exposure_tol: f64) {
    assert_eq!(a.off_feed_moves, 0, "every feed move at V");
    assert_eq!(a.corners_at_speed, 0, "no corner taken at speed");
    assert!(
        a.max_accel_off_cut <= m.accel() * (1.0 + 1e-9),
        "loops and leads ask {} > {} mm/s²",
        a.max_accel_off_cut,
        m.accel()
    );
    assert_eq!(a.beam_on_rapids, 0);
    assert!(
        a.exposure_error < exposure_tol,
        "shutter open off the cuts by {} mm",
        a.exposure_error
    );
    assert!(
        a.min_run_before_open >= m.accel_distance() - 1e-9,
        "shutter commanded after only {} mm of lead-in",
        a.min_run_before_open
    );
    assert!(
        a.min_run_after_close >= -1e-9,
        "the stage slows {} mm before the shutter is closed",
        -a.min_run_after_close
    );
}

/// Moves a Turbo PMAC would stretch: each must be a cut piece of the
/// drawing itself shorter than 1 ms at V (never a lead, a loop or a piece
/// pathgen split).
fn only_short_drawing_pieces_stretched(recs: &[Record], m: &LaserSetup, drawing: &[Segment]) {
    let short: Vec<f64> = drawing
        .iter()
        .map(Segment::length)
        .filter(|&l| l < m.min_block())
        .collect();
    let mut ta = super::audit::PmacTa::new(m);
    let mut pos = P3::origin();
    let mut n = 0;
    for r in recs {
        if ta.read(r) {
            continue;
        }
        let Record::Move(mv) = r else { continue };
        if let Some(e) = super::audit::feed_elem(pos, mv) {
            let len = e.length();
            if m.controller == crate::machine::Controller::Pmac && ta.stretches(len, m.feed) {
                n += 1;
                assert_eq!(mv.role, Some(Role::Cut), "a stretched {len} mm {:?} move", mv.role);
                assert!(
                    short.iter().any(|&l| (l - len).abs() < 1e-9),
                    "a stretched {len} mm cut piece that is not a whole drawing piece"
                );
            }
        }
        pos = mv.to;
    }
    let a = audit(recs, m, P3::origin());
    assert_eq!(a.stretched_moves, n);
}

fn offset_length(c: &Chain, side: Side, d: f64) -> f64 {
    super::offset::offset_chain(c, side, d)
        .iter()
        .map(|p| p.iter().map(Segment::length).sum::<f64>())
        .sum()
}

#[test]
fn plate_outside_two_levels_two_copies() {
    let m = LaserSetup::default();
    let chains = plate();
    let o = ContourOptions {
        side: Side::Outside,
        distance: 0.005,
        levels: 2,
        level_step: -0.01,
        array: (2, 1),
        pitch: (10.0, 0.0),
        ..Default::default()
    };
    let job = contour(&chains, &m, &o);
    let a = audit(&job.records, &m, P3::origin());
    check_physics(&a, &m, 1e-6);
    assert_eq!(a.stretched_moves, 0);
    // Every chain is cut once per pass: 4 passes of each (holes swap to
    // inside); the plate has no piece shorter than the least block, so the
    // cleanup leaves the offsets as they are.
    assert_eq!(job.cleanup.short, 0);
    for c in &chains {
        let hole = c.id == 2 || c.id == 3;
        let side = match (c.closed, hole) {
            (false, _) => Side::On,
            (true, true) => Side::Inside,
            (true, false) => Side::Outside,
        };
        let want = 4.0 * offset_length(c, side, 0.005);
        let got = a.cut_length[&c.id];
        assert!((got - want).abs() < 1e-9, "chain {}: cut {got} mm, want {want}", c.id);
        let lead_ins = job
            .records
            .iter()
            .filter_map(Record::motion)
            .filter(|mv| mv.chain == Some(c.id) && mv.role == Some(Role::LeadIn) && !mv.beam)
            .count();
        assert_eq!(lead_ins, 4, "chain {}", c.id);
    }
    // Holes before the contour around them, in every copy and level.
    let seq: Vec<u64> = job
        .records
        .iter()
        .filter_map(Record::motion)
        .filter(|mv| mv.kind == MotionKind::Rapid)
        .filter_map(|mv| mv.chain)
        .collect();
    for pass in seq.chunks(4) {
        let at = |id: u64| pass.iter().position(|&x| x == id).unwrap();
        assert!(at(2) < at(1) && at(3) < at(1), "{pass:?}");
    }
    // Levels step down in Z.
    let zs: std::collections::BTreeSet<i64> = job
        .records
        .iter()
        .filter_map(Record::motion)
        .map(|mv| (mv.to.z * 1e6).round() as i64)
        .collect();
    assert_eq!(zs.into_iter().collect::<Vec<_>>(), vec![-10_000, 0]);
}

/// Distance from `p` to the nearest point of chain `c`.
fn dist_to_chain(p: &P3, c: &Chain) -> f64 {
    chain_elems(c)
        .iter()
        .map(|e| match e {
            Segment::Line(l) => l.distance(p),
            Segment::Arc(a) => a.distance(p).unwrap_or(f64::INFINITY),
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn cuts_run_at_the_offset_distance() {
    let m = LaserSetup::default();
    let chains = plate();
    for (side, d) in [(Side::Outside, 0.005), (Side::Inside, 0.05), (Side::On, 0.0)] {
        let job = contour(
            &chains,
            &m,
            &ContourOptions {
                side,
                distance: d,
                ..Default::default()
            },
        );
        let mut pos = P3::origin();
        let (mut exact, mut total) = (0.0, 0.0);
        for mv in job.records.iter().filter_map(Record::motion) {
            if mv.role == Some(Role::Cut) {
                let c = chains.iter().find(|c| Some(c.id) == mv.chain).unwrap();
                let e = match mv.kind {
                    MotionKind::Arc(ad) => Segment::Arc(
                        crate::geometry::arc::Arc3::new(ad.center, pos, mv.to, ad.ccw, ad.plane, 0).unwrap(),
                    ),
                    _ => Segment::line(pos, mv.to),
                };
                // Weighted by length: miter pieces are short.
                for k in 0..=10 {
                    let p = e.point_at_length(e.length() * k as f64 / 10.0);
                    let dd = dist_to_chain(&p, c);
                    // On the offset: exactly d. Open chains are cut on the line.
                    let want = if c.closed { d } else { 0.0 };
                    // Mitred corners reach out to d / cos(75°) at most.
                    assert!(dd >= want - 1e-9 && dd <= want * 3.87 + 1e-9, "{side:?}: {p:?} at {dd}");
                    total += e.length();
                    if (dd - want).abs() < 1e-9 {
                        exact += e.length();
                    }
                }
            }
            pos = mv.to;
        }
        assert!(
            exact >= 0.9 * total,
            "{side:?}: {exact}/{total} of the cut length at the offset"
        );
    }
}

#[test]
fn random_drawings_obey_the_machine() {
    for (seed, m) in [
        (3u64, LaserSetup::default()),
        (11, LaserSetup::default().with_accel(500.0)),
        (
            17,
            LaserSetup {
                feed: 5.0,
                ts_ms: 60.0,
                ..LaserSetup::default()
            },
        ),
        (
            23,
            LaserSetup {
                cut_ta_ms: 25.0,
                ..LaserSetup::default()
            },
        ),
        (
            31,
            LaserSetup {
                controller: crate::machine::Controller::Lookahead,
                ..LaserSetup::default()
            },
        ),
    ] {
        let chains = random_drawing(60, seed);
        for side in [Side::On, Side::Outside, Side::Inside] {
            let job = contour(
                &chains,
                &m,
                &ContourOptions {
                    side,
                    distance: 0.02,
                    ..Default::default()
                },
            );
            let a = audit(&job.records, &m, P3::origin());
            let o = ContourOptions {
                side,
                distance: 0.02,
                ..Default::default()
            };
            let paths = cut_paths(&chains, &m, &o);
            let drawing: Vec<Segment> = paths.iter().flat_map(|(p, _)| p.iter().flatten().copied()).collect();
            only_short_drawing_pieces_stretched(&job.records, &m, &drawing);
            // Whatever the cleanup could not remove is all that is stretched.
            let left: usize = paths.iter().map(|(_, st)| st.left).sum();
            assert!(
                a.stretched_moves <= left,
                "seed {seed} {side:?}: {} stretched",
                a.stretched_moves
            );
            // Switches next to drawing pieces only a few ms long at V may
            // act off by up to V·1 ms (a least block on a look-ahead
            // control); pathgen says so.
            let off = job.warnings.iter().any(|w| w.message.contains("shutter switch"));
            check_physics(&a, &m, if off { m.switch_off_bound() + 1e-6 } else { 1e-6 });
            for (c, (p, _)) in chains.iter().zip(&paths) {
                let want: f64 = p.iter().flatten().map(Segment::length).sum();
                let got = a.cut_length.get(&c.id).copied().unwrap_or(0.0);
                assert!(
                    (got - want).abs() < 1e-9,
                    "seed {seed} {side:?} chain {}: {got} vs {want}",
                    c.id
                );
            }
        }
    }
}

#[test]
fn planning_is_deterministic() {
    let m = LaserSetup::default();
    let chains = random_drawing(200, 5);
    let o = ContourOptions {
        side: Side::Outside,
        distance: 0.01,
        ..Default::default()
    };
    assert_eq!(contour(&chains, &m, &o).records, contour(&chains, &m, &o).records);
}

#[test]
fn patterns_obey_the_machine() {
    use super::constant_velocity::{all_cut, plan_paths};
    use super::patterns::*;
    use crate::geometry::Plane;
    let m = LaserSetup::default().with_accel(200.0);
    let c = P3::new(1.0, 1.0, 0.0);
    let zz = |plane, along_second, width, step, corner_radius| Zigzag {
        origin: c,
        plane,
        along_second,
        length: 1.0,
        width,
        step,
        corner_radius,
    };
    let cases: Vec<(&str, Vec<super::constant_velocity::Tagged>)> = vec![
        ("helix", vec![all_cut(helix(c, 0.3, -0.01, 4, true))]),
        ("square", vec![all_cut(square_spiral(c, 0.05, 0.5, false))]),
        ("square in", vec![all_cut(square_spiral(c, 0.05, 0.5, true))]),
        (
            "archimedean",
            vec![all_cut(archimedean(c, 0.1, 0.02, 0.4, false, 1e-5))],
        ),
        (
            "archimedean in",
            vec![all_cut(archimedean(c, 0.1, 0.02, 0.4, true, 1e-5))],
        ),
        ("zigzag xy", vec![zigzag(&zz(Plane::Xy, false, 0.3, 0.02, 0.0), &m)]),
        ("zigzag xz", vec![zigzag(&zz(Plane::Xz, true, 0.1, 0.01, 0.05), &m)]),
        (
            "cone",
            cone_levels(0.0, 1.0, 0.4, 0.3, 3)
                .into_iter()
                .map(|(z, d)| all_cut(archimedean(P3::new(1.0, 1.0, z), 0.02, 0.02, 0.5 * d, false, 1e-5)))
                .collect(),
        ),
    ];
    for (name, paths) in cases {
        let want: f64 = paths
            .iter()
            .flatten()
            .filter(|p| p.1 == Role::Cut)
            .map(|p| p.0.length())
            .sum();
        let (recs, _notes) = plan_paths(&paths, &m, Some(7));
        let a = audit(&recs, &m, P3::origin());
        assert_eq!(a.off_feed_moves, 0, "{name}");
        assert_eq!(a.corners_at_speed, 0, "{name}");
        assert!(
            a.max_accel_off_cut <= m.accel() * (1.0 + 1e-9),
            "{name}: {}",
            a.max_accel_off_cut
        );
        assert!(a.exposure_error < 1e-6, "{name}: {}", a.exposure_error);
        assert_eq!(a.stretched_moves, 0, "{name}");
        assert!(a.min_run_after_close >= -1e-9, "{name}");
        assert!((a.cut_length[&7] - want).abs() < 1e-9, "{name}");
        // Roles on every move.
        assert!(
            recs.iter().filter_map(Record::motion).all(|mv| mv.role.is_some()),
            "{name}"
        );
    }
}

#[test]
fn degenerate_chains_are_dropped_not_panicked_on() {
    let m = LaserSetup::default();
    let z = P3::origin();
    let chains = vec![
        Chain {
            id: 1,
            ..Default::default()
        },
        Chain {
            id: 2,
            closed: true,
            segments: vec![Segment::line(z, z)],
            ..Default::default()
        },
        Chain {
            id: 3,
            segments: vec![Segment::line(z, P3::new(1.0, 0.0, 0.0))],
            ..Default::default()
        },
    ];
    for side in [Side::On, Side::Outside, Side::Inside, Side::Left] {
        let job = contour(
            &chains,
            &m,
            &ContourOptions {
                side,
                distance: 0.01,
                ..Default::default()
            },
        );
        let a = audit(&job.records, &m, P3::origin());
        check_physics(&a, &m, 1e-6);
        assert_eq!(a.cut_length.keys().copied().collect::<Vec<_>>(), vec![3], "{side:?}");
    }
}

/// Nesting depth of chain `i`, brute force and independent of the
/// planner's grid: the closed chains whose winding number is non-zero at
/// up to 16 of chain `i`'s vertices. `None` when some other closed chain
/// has some of those vertices inside and some outside (the two cross:
/// neither is inside the other, and which side is "outside" is moot).
fn depth_brute(
    chains: &[Chain],
    plines: &[Option<cavalier_contours::polyline::Polyline<f64>>],
    i: usize,
) -> Option<usize> {
    use cavalier_contours::polyline::PlineSource;
    let segs = &chains[i].segments;
    let stride = segs.len().div_ceil(16).max(1);
    let pts: Vec<P3> = segs.iter().step_by(stride).map(|s| s.start()).collect();
    let mut depth = 0;
    for (j, p) in plines.iter().enumerate() {
        let Some(p) = p else { continue };
        if j == i {
            continue;
        }
        let inside = pts
            .iter()
            .filter(|q| p.winding_number(cavalier_contours::core::math::Vector2::new(q.x, q.y)) != 0)
            .count();
        if inside == pts.len() {
            depth += 1;
        } else if inside > 0 {
            return None;
        }
    }
    Some(depth)
}

/// The corpus drawings as dxf2chains makes them (joined within 0.001 mm):
/// each one's file name, its chains, and whether it is planar (every
/// chain at one Z: chains in 3-D get no corner loops out of the XY plane,
/// so the physics hold on planar drawings only). Drawings that do not
/// import or give no chain are left out; `None` without the corpus.
fn corpus_drawings() -> Option<Vec<(String, Vec<Chain>, bool)>> {
    use crate::dxf::{ImportOptions, chain, import};
    let files = crate::corpus::files("dxf", &[".dxf"]);
    if files.is_empty() {
        return None;
    }
    let mut out = Vec::new();
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let f = std::fs::File::open(path).unwrap();
        let Ok(mut imp) = import(Box::new(std::io::BufReader::new(f)), &ImportOptions::default()) else {
            continue;
        };
        let segs = std::mem::take(&mut imp.sink.segments);
        let (built, _) = chain::build(segs, &imp.sink.points, &imp.sink.layers, 0.001);
        let chains: Vec<Chain> = built.iter().collect();
        if chains.is_empty() {
            continue;
        }
        let planar = chains.iter().all(|c| {
            let z = c.segments.first().map_or(0.0, |s| s.start().z);
            c.segments.iter().all(|s| s.start().z == z && s.end().z == z)
        });
        out.push((name, chains, planar));
    }
    Some(out)
}

/// The corpus drawings (as dxf2chains makes them), planned on every side
/// with the default machine and a 5 µm offset: the physics hold, no block
/// is stretched, every chain is cut exactly as [`cut_paths`] says, and a
/// hole (a chain inside an odd number of others) is offset to the other
/// side: an outside cut encloses more than the part's contour and less
/// than a hole, an inside cut the reverse.
#[test]
fn corpus_drawings_obey_the_machine_on_every_side() {
    let Some(drawings) = corpus_drawings() else {
        crate::corpus::skip("corpus_drawings_obey_the_machine_on_every_side");
        return;
    };
    let pmac = LaserSetup::default();
    // The same stage on a look-ahead control, which switches the shutter
    // at block boundaries (no block under 1 ms at V there either).
    let lookahead = LaserSetup {
        controller: crate::machine::Controller::Lookahead,
        ..LaserSetup::default()
    };
    let mut cases = 0;
    let mut failures: Vec<String> = Vec::new();
    let mut holes = 0;
    let mut planar_drawings = 0;
    for ((name, chains, planar), m) in drawings.iter().flat_map(|d| [(d, &pmac), (d, &lookahead)]) {
        let name = format!("{name} ({:?})", m.controller);
        let (chains, planar) = (chains.as_slice(), *planar);
        let plines: Vec<_> = chains
            .iter()
            .map(|c| c.closed.then(|| super::offset::to_polyline(c)))
            .collect();
        let depth: Vec<Option<usize>> = (0..chains.len()).map(|i| depth_brute(chains, &plines, i)).collect();
        // A chain crossing itself has no inside to offset from.
        let crosses: Vec<bool> = plines
            .iter()
            .map(|p| {
                use cavalier_contours::polyline::PlineSource;
                p.as_ref().is_some_and(|p| p.scan_for_self_intersect())
            })
            .collect();
        planar_drawings += usize::from(planar);
        for side in [Side::On, Side::Outside, Side::Inside] {
            let o = ContourOptions {
                side,
                distance: 0.005,
                ..Default::default()
            };
            let job = contour(chains, m, &o);
            let a = audit(&job.records, m, P3::origin());
            let off = job.warnings.iter().any(|w| w.message.contains("shutter switch"));
            let physics = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                check_physics(&a, m, if off { m.switch_off_bound() + 1e-6 } else { 1e-6 })
            }));
            if planar && physics.is_err() {
                failures.push(format!("{name} {side:?}: physics"));
            }
            if a.stretched_moves != 0 || job.cleanup.left != 0 || job.cleanup.max_dev > o.cleanup_tol {
                failures.push(format!(
                    "{name} {side:?}: {} stretched blocks, {} short pieces left, deviation {}",
                    a.stretched_moves, job.cleanup.left, job.cleanup.max_dev
                ));
            }
            let paths = cut_paths(chains, m, &o);
            for (i, (c, (p, _))) in chains.iter().zip(&paths).enumerate() {
                let want: f64 = p.iter().flatten().map(Segment::length).sum();
                let got = a.cut_length.get(&c.id).copied().unwrap_or(0.0);
                if (got - want).abs() > 1e-6 {
                    failures.push(format!("{name} {side:?} chain {}: cut {got} mm, want {want}", c.id));
                }
                let Some(d) = depth[i] else { continue };
                if side == Side::On || !c.closed || p.len() != 1 || crosses[i] {
                    continue;
                }
                let drawn = super::contour::signed_area(&chain_elems(c)).abs();
                let cut = super::contour::signed_area(&p[0]).abs();
                let hole = d % 2 == 1;
                holes += usize::from(hole);
                let grows = (side == Side::Outside) != hole;
                if (cut > drawn) != grows {
                    failures.push(format!(
                        "{name} {side:?} chain {} (depth {d}): cut encloses {cut} mm², drawn {drawn} mm²",
                        c.id
                    ));
                }
            }
            cases += 1;
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The corpus has nested drawings: holes were checked.
    assert!(holes > 10, "{holes} holes checked");
    assert!(planar_drawings >= 20, "{planar_drawings} planar drawings");
    crate::corpus::record("corpus_drawings_obey_the_machine_on_every_side", cases);
}

/// The corpus drawings planned for 4 and for 3 decimals (`pathgen contour
/// --gcode pmac --decimals N`), written as PMAC programs and read back as
/// gsim, pmac-send and the emulator read them: every program reads (at 3
/// decimals a small arc's rounded centre can miss its rounded end by a
/// micrometre or more, which the controller runs as a spiral and the reader
/// must accept), no block of what was read is stretched, and on the planar
/// drawings the program passes `pathgen audit` at the printing precision
/// (direction jumps that rounding explains are no corners; without roles
/// the beam-on moves are the cuts).
#[test]
fn corpus_programs_read_back_unstretched_and_pass_the_audit() {
    use super::audit::audit_at;
    use crate::gcode::writer::{WriteOptions, write_string};
    use crate::gcode::{Dialect, ReadOptions, read_str};
    use crate::model::toolpath::FeedUnit;
    let Some(drawings) = corpus_drawings() else {
        crate::corpus::skip("corpus_programs_read_back_unstretched_and_pass_the_audit");
        return;
    };
    let ropts = ReadOptions {
        dialect: Some(Dialect::Pmac),
        ..Default::default()
    };
    let (mut cases, mut arcs, mut audited) = (0, 0, 0);
    let mut failures: Vec<String> = Vec::new();
    for (name, chains, planar) in &drawings {
        let planar = *planar;
        for (decimals, precision) in [(4u8, 1e-4), (3, 1e-3)] {
            let m = LaserSetup {
                decimals,
                ..Default::default()
            };
            let mut wopts = WriteOptions::for_dialect(Dialect::Pmac);
            wopts.decimals = decimals;
            for side in [Side::On, Side::Outside, Side::Inside] {
                let o = ContourOptions {
                    side,
                    distance: 0.005,
                    ..Default::default()
                };
                let job = contour(chains, &m, &o);
                let case = format!("{name} {side:?} {decimals} decimals");
                let text = match write_string(wopts.clone(), FeedUnit::MmPerS, &job.records) {
                    Ok(t) => t,
                    Err(e) => {
                        failures.push(format!("{case}: not written: {e}"));
                        continue;
                    }
                };
                match read_str(&text, &ropts) {
                    Ok((_, records)) => {
                        arcs += records
                            .iter()
                            .filter(|r| matches!(r, Record::Move(mv) if matches!(mv.kind, MotionKind::Arc(_))))
                            .count();
                        let a = audit_at(&records, &m, P3::origin(), precision);
                        if a.stretched_moves != 0 {
                            failures.push(format!("{case}: {} stretched blocks", a.stretched_moves));
                        }
                        if planar && !a.passes(&m, precision) {
                            failures.push(format!("{case}: audit fails: {}", a.report_json(&m, precision)));
                        }
                        audited += usize::from(planar);
                    }
                    Err(e) => failures.push(format!("{case}: read back: {e}")),
                }
                cases += 1;
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(arcs > 10_000, "{arcs} arcs read back");
    assert!(audited >= 120, "{audited} programs audited");
    crate::corpus::record("corpus_programs_read_back_unstretched_and_pass_the_audit", cases);
}
