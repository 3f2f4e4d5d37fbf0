//! Fills checked on their output: coverage of the region, the machine's
//! limits, levels, refused inputs.

use super::*;
use crate::geometry::P3;
use crate::laser::audit::{audit, feed_elem};
use crate::laser::offset::to_polyline;
use crate::model::toolpath::{MotionKind, Role};
use cavalier_contours::core::math::Vector2;
use cavalier_contours::polyline::PlineSource;

fn poly(id: u64, pts: &[(f64, f64)], z: f64) -> Chain {
    let p: Vec<P3> = pts.iter().map(|&(x, y)| P3::new(x, y, z)).collect();
    Chain {
        id,
        closed: true,
        segments: (0..p.len())
            .map(|i| Segment::line(p[i], p[(i + 1) % p.len()]))
            .collect(),
        ..Default::default()
    }
}

fn circle(id: u64, c: (f64, f64), r: f64, z: f64, ccw: bool) -> Chain {
    let s = P3::new(c.0 + r, c.1, z);
    Chain {
        id,
        closed: true,
        segments: vec![Segment::arc_xy(s, s, P3::new(c.0, c.1, z), ccw)],
        ..Default::default()
    }
}

/// An L-shaped plate (a reflex corner) with a round hole, a triangular
/// hole, and a rounded convex corner; drawn clockwise to check that
/// orientation does not matter.
fn plate(z: f64) -> Vec<Chain> {
    let mut outer = poly(
        1,
        &[(0.0, 0.0), (0.0, 1.2), (0.6, 1.2), (0.6, 0.6), (1.4, 0.6), (1.4, 0.0)],
        z,
    );
    outer.segments.reverse();
    for s in &mut outer.segments {
        *s = s.reversed();
    }
    vec![
        outer,
        circle(2, (0.3, 0.3), 0.12, z, true),
        poly(3, &[(0.9, 0.15), (1.2, 0.15), (1.05, 0.45)], z),
    ]
}

fn setup(min_exposure_ms: f64) -> LaserSetup {
    LaserSetup {
        min_exposure_ms,
        ..LaserSetup::default().with_accel(200.0)
    }
}

/// Cut moves as exact pieces.
fn cuts(recs: &[Record]) -> Vec<Segment> {
    let mut pos = P3::origin();
    let mut out = Vec::new();
    for mv in recs.iter().filter_map(Record::motion) {
        if mv.role == Some(Role::Cut)
            && let Some(e) = feed_elem(pos, mv)
        {
            out.push(e);
        }
        pos = mv.to;
    }
    out
}

fn dist(e: &Segment, p: &P3) -> f64 {
    match e {
        Segment::Line(l) => l.distance(p),
        Segment::Arc(a) => a.distance(p).unwrap_or(f64::INFINITY),
    }
}

/// Signed distance to the region of `chains` (positive inside the outer
/// and outside the holes), exact on lines and arcs.
fn inside_distance(chains: &[Chain], p: &P3) -> f64 {
    let d = chains
        .iter()
        .flat_map(super::super::offset::chain_elems)
        .map(|e| dist(&e, p))
        .fold(f64::INFINITY, f64::min);
    let q = Vector2::new(p.x, p.y);
    let inside_outer = to_polyline(&chains[0]).winding_number(q) != 0;
    let in_hole = chains[1..].iter().any(|c| to_polyline(c).winding_number(q) != 0);
    if inside_outer && !in_hole { d } else { -d }
}

/// Largest distance from a grid point of the region to the nearest cut
/// (cuts bucketed on a grid of `cell`).
fn coverage(chains: &[Chain], cut: &[Segment], step: f64) -> f64 {
    let cell = 0.05;
    let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
    for (i, e) in cut.iter().enumerate() {
        let (a, b) = (e.start(), e.end());
        let r = if let Segment::Arc(x) = e { x.radius() } else { 0.0 };
        let (lo, hi) = (
            key(a.x.min(b.x) - r, a.y.min(b.y) - r),
            key(a.x.max(b.x) + r, a.y.max(b.y) + r),
        );
        for gx in lo.0..=hi.0 {
            for gy in lo.1..=hi.1 {
                grid.entry((gx, gy)).or_default().push(i);
            }
        }
    }
    let mut worst: f64 = 0.0;
    let n = (1.5 / step) as i64;
    for i in 0..=n {
        for j in 0..=n {
            let p = P3::new(i as f64 * step, j as f64 * step, chains[0].segments[0].start().z);
            if inside_distance(chains, &p) < 0.0 {
                continue;
            }
            let k = key(p.x, p.y);
            let mut best = f64::INFINITY;
            for gx in k.0 - 1..=k.0 + 1 {
                for gy in k.1 - 1..=k.1 + 1 {
                    for &e in grid.get(&(gx, gy)).into_iter().flatten() {
                        best = best.min(dist(&cut[e], &p));
                    }
                }
            }
            worst = worst.max(best);
        }
    }
    worst
}

fn options(pattern: Pattern, outline: bool) -> FillOptions {
    FillOptions {
        pattern,
        beam_radius: 0.005,
        stepover: 0.01,
        angle_deg: 30.0,
        outline,
        ..Default::default()
    }
}

#[test]
fn every_point_of_the_region_is_within_a_stepover_of_a_cut() {
    let chains = plate(0.0);
    let m = setup(0.0);
    for (pattern, outline) in [(Pattern::Offset, false), (Pattern::Hatch, true)] {
        let o = options(pattern, outline);
        let job = fill(&chains, &m, &o).unwrap();
        let cut = cuts(&job.records);
        assert!(!cut.is_empty());
        let worst = coverage(&chains, &cut, 0.004);
        // The stepover, plus a quarter of it where a tight arc became
        // chords.
        assert!(worst <= 1.25 * o.stepover + 1e-9, "{pattern:?}: {worst}");
        // Every cut stays a beam radius inside (less the chords' sag):
        // the beam never leaves the region nor enters a hole.
        let mut least = f64::INFINITY;
        for e in &cut {
            for k in 0..=8 {
                let p = e.point_at_length(e.length() * k as f64 / 8.0);
                least = least.min(inside_distance(&chains, &p));
            }
        }
        assert!(least >= 0.75 * o.beam_radius - 1e-9, "{pattern:?}: {least}");
    }
}

#[test]
fn hatch_without_outline_covers_the_inside() {
    let chains = plate(0.0);
    let o = options(Pattern::Hatch, false);
    let job = fill(&chains, &setup(0.0), &o).unwrap();
    let cut = cuts(&job.records);
    // Lines only: parallel, stepover apart, each in one piece.
    for e in &cut {
        let d = e.start_tangent();
        assert!((d.y.atan2(d.x).to_degrees().rem_euclid(180.0) - 30.0).abs() < 1e-6);
    }
    assert!(coverage(&chains, &cut, 0.01) < 0.1);
}

#[test]
fn fill_output_obeys_the_machine() {
    let chains = plate(-0.02);
    for m in [
        setup(15.0),
        LaserSetup::default(),
        LaserSetup {
            controller: crate::machine::Controller::Lookahead,
            ..setup(15.0)
        },
    ] {
        for (pattern, outline) in [
            (Pattern::Offset, false),
            (Pattern::Hatch, false),
            (Pattern::Hatch, true),
        ] {
            let o = options(pattern, outline);
            let job = fill(&chains, &m, &o).unwrap();
            let a = audit(&job.records, &m, P3::origin());
            let what = format!("{pattern:?} outline {outline} {:?}", m.controller);
            assert_eq!(a.off_feed_moves, 0, "{what}");
            assert_eq!(a.corners_at_speed, 0, "{what}");
            assert_eq!(a.beam_on_rapids, 0, "{what}");
            assert!(
                a.max_accel_off_cut <= m.accel() * (1.0 + 1e-9),
                "{what}: {}",
                a.max_accel_off_cut
            );
            // The passes themselves, too: no arc tighter than V²/a.
            assert!(
                a.max_accel_cut <= m.accel() * (1.0 + 1e-9),
                "{what}: {}",
                a.max_accel_cut
            );
            let off = job.warnings.iter().any(|w| w.message.contains("shutter switch"));
            let tol = if off { m.switch_off_bound() + 1e-6 } else { 1e-6 };
            assert!(a.exposure_error < tol, "{what}: {}", a.exposure_error);
            assert!(a.min_run_before_open >= m.accel_distance() - 1e-9, "{what}");
            assert!(a.min_run_after_close >= -1e-9, "{what}");
            assert_eq!(a.stretched_moves, 0, "{what}");
            // Every move at the chains' Z, beam-on moves only on cuts'
            // paths (no rapid carries the beam).
            for mv in job.records.iter().filter_map(Record::motion) {
                assert!((mv.to.z + 0.02).abs() < 1e-12, "{what}: {mv:?}");
                if mv.kind == MotionKind::Rapid {
                    assert!(!mv.beam);
                }
            }
        }
    }
}

#[test]
fn levels_are_kept_apart_and_in_input_order() {
    let mut chains = plate(0.0);
    let mut lower = plate(-0.5);
    for (i, c) in lower.iter_mut().enumerate() {
        c.id = 10 + i as u64;
    }
    chains.extend(lower);
    let o = options(Pattern::Offset, false);
    let p = prepare(&chains, &o).unwrap();
    assert_eq!(p.regions.len(), 2);
    assert_eq!((p.regions[0].z, p.regions[1].z), (0.0, -0.5));
    assert_eq!((p.regions[0].holes, p.regions[1].holes), (2, 2));
    let job = fill(&chains, &setup(15.0), &o).unwrap();
    let zs: Vec<f64> = job.records.iter().filter_map(Record::motion).map(|m| m.to.z).collect();
    let first_low = zs.iter().position(|&z| z == -0.5).unwrap();
    assert!(zs[..first_low].iter().all(|&z| z == 0.0));
    assert!(zs[first_low..].iter().all(|&z| z == -0.5));
    assert_eq!(fill(&chains, &setup(15.0), &o).unwrap().records, job.records);
}

#[test]
fn bad_inputs_are_refused() {
    let o = FillOptions::default();
    let mut open = poly(1, &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 0.0);
    open.closed = false;
    assert_eq!(prepare(&[open], &o).unwrap_err(), FillError::NoClosed(1));
    assert_eq!(prepare(&[], &o).unwrap_err(), FillError::NoClosed(0));
    let flat = poly(2, &[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)], 0.0);
    assert_eq!(prepare(&[flat], &o).unwrap_err(), FillError::Empty);
    let mut nan = poly(3, &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 0.0);
    nan.segments[1] = Segment::line(P3::new(1.0, 0.0, 0.0), P3::new(f64::NAN, 1.0, 0.0));
    assert_eq!(prepare(&[nan], &o).unwrap_err(), FillError::NotFinite(3));
    let sq = poly(4, &[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)], 0.0);
    let tiny = FillOptions {
        stepover: 1e-9,
        ..FillOptions::default()
    };
    match prepare(std::slice::from_ref(&sq), &tiny).unwrap_err() {
        FillError::TooBig { passes, moves, .. } => assert!(passes > 1_000_000_000 && moves > passes),
        e => panic!("{e}"),
    }
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let o = FillOptions {
            stepover: bad,
            ..FillOptions::default()
        };
        assert!(matches!(
            prepare(std::slice::from_ref(&sq), &o),
            Err(FillError::NotPositive(..))
        ));
    }
}

#[test]
fn a_region_narrower_than_the_beam_makes_nothing_and_says_so() {
    let thin = poly(5, &[(0.0, 0.0), (1.0, 0.0), (1.0, 0.004), (0.0, 0.004)], 0.0);
    let job = fill(&[thin], &setup(15.0), &FillOptions::default()).unwrap();
    assert!(cuts(&job.records).is_empty());
    assert!(
        job.warnings
            .iter()
            .any(|w| w.message.contains("narrower than the beam"))
    );
}

#[test]
fn a_boundary_crossing_itself_is_named_and_its_cuts_stay_inside() {
    // A bow tie: two triangles wound against each other, no net area. The
    // error names the crossing instead of saying there is no area.
    let bow = poly(7, &[(0.0, 0.0), (2.0, 0.0), (0.0, 2.0), (2.0, 2.0)], 0.0);
    match prepare(&[bow], &FillOptions::default()).unwrap_err() {
        FillError::Crosses { chain, x, y } => {
            assert_eq!(chain, 7);
            assert!((x - 1.0).abs() < 1e-9 && (y - 1.0).abs() < 1e-9, "({x}, {y})");
        }
        e => panic!("{e}"),
    }
    // Unequal lobes: filled with a warning naming the crossing, and every
    // cut point lies inside one of the two triangles by the beam radius.
    let eight = poly(8, &[(0.0, 0.0), (2.0, 0.0), (0.0, 1.0), (1.0, 1.0)], 0.0);
    let o = FillOptions {
        beam_radius: 0.025,
        stepover: 0.05,
        ..FillOptions::default()
    };
    let job = fill(std::slice::from_ref(&eight), &setup(15.0), &o).unwrap();
    assert!(
        job.warnings
            .iter()
            .any(|w| w.chain == 8 && w.message.contains("crosses or touches itself at (0.666667, 0.666667)")),
        "{:?}",
        job.warnings
    );
    let x = 2.0 / 3.0;
    let lobes = [
        poly(1, &[(0.0, 0.0), (2.0, 0.0), (x, x)], 0.0),
        poly(2, &[(x, x), (1.0, 1.0), (0.0, 1.0)], 0.0),
    ];
    let cut = cuts(&job.records);
    assert!(!cut.is_empty());
    for e in &cut {
        for k in 0..=8 {
            let p = e.point_at_length(e.length() * k as f64 / 8.0);
            let d = lobes
                .iter()
                .map(|l| inside_distance(std::slice::from_ref(l), &p))
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(d >= 0.75 * o.beam_radius, "{p:?} is {d} mm inside");
        }
    }
}
