//! Property tests across the geometry kernel: random arcs and lines must
//! survive every change of representation and every query must agree with
//! brute-force sampling. Unit tests with closed-form answers live beside each
//! module; these look for the cases nobody thought of.

use super::arc::Arc3;
use super::bulge::{arc_from_bulge, bulge_of};
use super::intersect::{Intersection, arc_arc, line_arc, line_line};
use super::line::Line3;
use super::segment::Segment;
use super::{P2, P3, Plane, V2};
use proptest::prelude::*;
use std::f64::consts::{PI, TAU};

fn plane() -> impl Strategy<Value = Plane> {
    prop_oneof![Just(Plane::Xy), Just(Plane::Xz), Just(Plane::Yz)]
}

/// An arc from its defining numbers: centre (in-plane) and height, radius,
/// start angle, signed sweep of the base turn, rise and extra turns.
#[allow(clippy::too_many_arguments)]
fn build(plane: Plane, c: P2, h: f64, r: f64, a0: f64, sw: f64, rise: f64, extra: u32) -> Arc3 {
    let at = |a: f64| c + V2::new(a.cos(), a.sin()) * r;
    Arc3::new(
        plane.lift(&c, h),
        plane.lift(&at(a0), h),
        plane.lift(&at(a0 + sw), h + rise),
        sw > 0.0,
        plane,
        extra,
    )
    .expect("strategy builds valid arcs")
}

/// An arc of less than a full turn (so start and end differ), any plane,
/// optionally helical, with its expected signed sweep.
fn arc_with_sweep(
    planes: impl Strategy<Value = Plane>,
    helical: bool,
    max_extra: u32,
) -> impl Strategy<Value = (Arc3, f64)> {
    (
        planes,
        -50.0..50.0f64,
        -50.0..50.0f64,
        -10.0..10.0f64,
        0.01..50.0f64,
        -PI..PI,
        0.05..(TAU - 0.05),
        any::<bool>(),
        if helical {
            prop_oneof![Just(0.0), -5.0..5.0f64].boxed()
        } else {
            Just(0.0).boxed()
        },
        0..=max_extra,
    )
        .prop_map(|(pl, cx, cy, h, r, a0, sw, ccw, rise, extra)| {
            let sw = if ccw { sw } else { -sw };
            let arc = build(pl, P2::new(cx, cy), h, r, a0, sw, rise, extra);
            (arc, sw + sw.signum() * extra as f64 * TAU)
        })
}

fn planar_arc() -> impl Strategy<Value = Arc3> {
    arc_with_sweep(plane(), false, 0).prop_map(|(a, _)| a)
}

fn any_arc() -> impl Strategy<Value = Arc3> {
    arc_with_sweep(plane(), true, 3).prop_map(|(a, _)| a)
}

fn xy_arc() -> impl Strategy<Value = Arc3> {
    (
        -3.0..3.0f64,
        -3.0..3.0f64,
        0.5..4.0f64,
        -PI..PI,
        prop_oneof![0.05..(TAU - 0.05), Just(0.0)],
        any::<bool>(),
    )
        .prop_map(|(cx, cy, r, a0, sw, ccw)| {
            let sw = if ccw { sw } else { -sw };
            let mut a = build(Plane::Xy, P2::new(cx, cy), 0.0, r, a0, sw, 0.0, 0);
            a.ccw = ccw;
            a
        })
}

fn xy_line() -> impl Strategy<Value = Line3> {
    (-6.0..6.0f64, -6.0..6.0f64, -6.0..6.0f64, -6.0..6.0f64)
        .prop_map(|(a, b, c, d)| Line3::new(P3::new(a, b, 0.0), P3::new(c, d, 0.0)))
}

fn close3(a: &P3, b: &P3, tol: f64) -> bool {
    (a - b).norm() <= tol
}

fn xy(p: &P3) -> P2 {
    P2::new(p.x, p.y)
}

fn on_line(l: &Line3, p: &P2) -> f64 {
    l.distance(&P3::new(p.x, p.y, 0.0))
}

fn on_arc(a: &Arc3, p: &P2) -> f64 {
    a.distance(&P3::new(p.x, p.y, 0.0)).unwrap_or(f64::INFINITY)
}

fn line_xy(l: &Line3, t: f64) -> P2 {
    xy(&l.point_at(t))
}

fn arc_xy(a: &Arc3, t: f64) -> P2 {
    xy(&a.point_at(t))
}

/// Every hit lies on both primitives within `tol`, and its parameters name it.
fn check_hits(
    hits: &[Intersection],
    on_a: impl Fn(&P2) -> f64,
    on_b: impl Fn(&P2) -> f64,
    at_a: impl Fn(f64) -> P2,
    at_b: impl Fn(f64) -> P2,
    tol: f64,
) -> Result<(), TestCaseError> {
    for i in hits {
        for h in i.hits() {
            prop_assert!((0.0..=1.0).contains(&h.t1) && (0.0..=1.0).contains(&h.t2), "{i:?}");
            prop_assert!(on_a(&h.point) <= tol + 1e-9, "off first by {}: {i:?}", on_a(&h.point));
            prop_assert!(on_b(&h.point) <= tol + 1e-9, "off second by {}: {i:?}", on_b(&h.point));
            prop_assert!((at_a(h.t1) - h.point).norm() <= 2.0 * tol + 1e-9, "t1 wrong: {i:?}");
            prop_assert!((at_b(h.t2) - h.point).norm() <= 2.0 * tol + 1e-9, "t2 wrong: {i:?}");
        }
    }
    Ok(())
}

/// Where the sampled first primitive clearly crosses the second one inside
/// both (away from ends), some reported hit must be nearby.
fn check_complete(
    hits: &[Intersection],
    at_a: impl Fn(f64) -> P2,
    side_b: impl Fn(&P2) -> f64,
    inside_b: impl Fn(&P2) -> bool,
) -> Result<(), TestCaseError> {
    const N: usize = 1000;
    let mut prev = at_a(0.0);
    for i in 1..=N {
        let t = i as f64 / N as f64;
        let p = at_a(t);
        let (s0, s1) = (side_b(&prev), side_b(&p));
        if s0 * s1 < 0.0 && s0.abs() > 1e-6 && s1.abs() > 1e-6 && t > 0.01 && t < 0.99 {
            let x = prev + (p - prev) * (s0 / (s0 - s1));
            if inside_b(&x) {
                let found = hits.iter().flat_map(|h| h.hits()).any(|h| (h.point - x).norm() < 0.05);
                prop_assert!(found, "missed a crossing near {x:?}: {hits:?}");
            }
        }
        prev = p;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn sweep_and_end_points_are_what_was_built((a, sw) in arc_with_sweep(plane(), true, 3)) {
        prop_assert!((a.sweep() - sw).abs() < 1e-9, "sweep {} expected {}", a.sweep(), sw);
        prop_assert_eq!(a.point_at(0.0), a.start);
        prop_assert_eq!(a.point_at(1.0), a.end);
        prop_assert!(close3(&a.point_at(1e-15), &a.start, 1e-9));
        prop_assert!(close3(&a.point_at(1.0 - 1e-15), &a.end, 1e-9));
        let r = a.radius();
        let n0 = a.plane.normal_coord(&a.start);
        for t in [0.1, 0.37, 0.5, 0.93] {
            let p = a.point_at(t);
            let c = a.plane.project(&a.center);
            prop_assert!(((a.plane.project(&p) - c).norm() - r).abs() < 1e-9);
            prop_assert!((a.plane.normal_coord(&p) - (n0 + a.rise() * t)).abs() < 1e-9);
        }
    }

    #[test]
    fn three_point_round_trip(a in planar_arc()) {
        let b = Arc3::from_three_points(&a.start, &a.point_at(0.5), &a.end, a.plane).unwrap();
        let tol = 1e-9 * a.radius().max(1.0);
        prop_assert!(close3(&b.center, &a.center, tol * 100.0), "{:?} vs {:?}", b.center, a.center);
        prop_assert_eq!(b.ccw, a.ccw);
        prop_assert_eq!(b.start, a.start);
        prop_assert_eq!(b.end, a.end);
        prop_assert!((b.sweep() - a.sweep()).abs() < 1e-9);
    }

    #[test]
    fn bulge_round_trip((a, _) in arc_with_sweep(Just(Plane::Xy), false, 0)) {
        let b = bulge_of(&a).unwrap();
        prop_assert!(b.is_finite() && (b > 0.0) == a.ccw);
        let back = arc_from_bulge(&a.start, &a.end, b).unwrap();
        prop_assert!(close3(&back.center, &a.center, 1e-7 * a.radius().max(1.0)), "{:?} vs {:?}", back.center, a.center);
        prop_assert_eq!(back.ccw, a.ccw);
        prop_assert!((back.sweep() - a.sweep()).abs() < 1e-9);
    }

    #[test]
    fn reversed_twice_is_the_original(a in any_arc(), t in 0.0..1.0f64) {
        let r = a.reversed();
        prop_assert_eq!(r.reversed(), a);
        prop_assert!((r.sweep() + a.sweep()).abs() < 1e-9);
        prop_assert!((r.length() - a.length()).abs() < 1e-9 * a.length().max(1.0));
        prop_assert!(close3(&r.point_at(1.0 - t), &a.point_at(t), 1e-8));
        let (ta, tr) = (a.tangent_at(t).unwrap(), r.tangent_at(1.0 - t).unwrap());
        prop_assert!((ta + tr).norm() < 1e-8);
    }

    #[test]
    fn split_halves_add_up(a in any_arc(), t in 0.02..0.98f64) {
        let (h1, h2) = a.split_at(t).unwrap();
        prop_assert_eq!(h1.start, a.start);
        prop_assert_eq!(h2.end, a.end);
        prop_assert_eq!(h1.end, h2.start);
        prop_assert_eq!(h1.extra_turns + h2.extra_turns <= a.extra_turns + 1, true);
        prop_assert!((h1.sweep() + h2.sweep() - a.sweep()).abs() < 1e-8);
        prop_assert!((h1.length() + h2.length() - a.length()).abs() < 1e-8 * a.length().max(1.0));
        prop_assert!(close3(&h2.point_at(0.5), &a.point_at(t + (1.0 - t) * 0.5), 1e-8));
    }

    #[test]
    fn length_and_tangent_match_sampling(a in any_arc()) {
        const N: usize = 4000;
        let mut poly = 0.0;
        for i in 0..N {
            poly += (a.point_at((i + 1) as f64 / N as f64) - a.point_at(i as f64 / N as f64)).norm();
        }
        // A chord polyline is shorter than the arc by about L·(Δθ)²/24.
        prop_assert!(poly <= a.length() + 1e-9 && a.length() - poly < 1e-5 * a.length().max(1.0));
        for t in [0.0, 0.3, 0.8] {
            let h = 1e-6;
            let fd = (a.point_at(t + h) - a.point_at(t - h)).normalize();
            prop_assert!((a.tangent_at(t).unwrap() - fd).norm() < 1e-5);
        }
    }

    #[test]
    fn bbox_is_exact(a in any_arc()) {
        const N: usize = 4000;
        let b = a.bbox();
        let mut lo = P3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
        let mut hi = -lo;
        for i in 0..=N {
            let p = a.point_at(i as f64 / N as f64);
            prop_assert!(b.contains_tol(&p, 1e-9), "{p:?} outside {b:?}");
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        // Sampling misses an extreme by at most r·(1 - cos(Δθ/2)).
        let step = a.sweep().abs() / N as f64;
        let slack = a.radius() * step * step / 8.0 + 1e-9;
        for k in 0..3 {
            prop_assert!(lo[k] - b.min[k] <= slack && b.max[k] - hi[k] <= slack, "axis {k}: {b:?} vs {lo:?}..{hi:?}");
        }
    }

    #[test]
    fn closest_point_beats_dense_samples(a in planar_arc(), q in (-80.0..80.0f64, -80.0..80.0f64, -80.0..80.0f64)) {
        let p = P3::new(q.0, q.1, q.2);
        let (c, t) = a.closest_point(&p).unwrap();
        prop_assert!(close3(&a.point_at(t), &c, 1e-9));
        let best = (c - p).norm();
        for i in 0..=2000 {
            let s = a.point_at(i as f64 / 2000.0);
            prop_assert!(best <= (s - p).norm() + 1e-9, "sample {i} nearer than {best}");
        }
    }

    #[test]
    fn line_line_hits_lie_on_both(a in xy_line(), b in xy_line(), tol in prop_oneof![Just(0.0), 1e-9..1e-3f64]) {
        let hits = line_line(&a, &b, tol).unwrap();
        check_hits(&hits, |p| on_line(&a, p), |p| on_line(&b, p), |t| line_xy(&a, t), |t| line_xy(&b, t), tol)?;
        let d = xy(&b.end) - xy(&b.start);
        let len = d.norm();
        check_complete(
            &hits,
            |t| line_xy(&a, t),
            |p| d.perp(&(p - xy(&b.start))) / len,
            |p| { let u = (p - xy(&b.start)).dot(&d) / (len * len); u > 0.01 && u < 0.99 },
        )?;
    }

    #[test]
    fn line_arc_hits_lie_on_both(a in xy_line(), b in xy_arc(), tol in prop_oneof![Just(0.0), 1e-9..1e-3f64]) {
        let hits = line_arc(&a, &b, tol).unwrap();
        check_hits(&hits, |p| on_line(&a, p), |p| on_arc(&b, p), |t| line_xy(&a, t), |t| arc_xy(&b, t), tol)?;
        let c = xy(&b.center);
        check_complete(
            &hits,
            |t| line_xy(&a, t),
            |p| (p - c).norm() - b.radius(),
            |p| on_arc(&b, p) < 1e-3 && (p - xy(&b.start)).norm() > 0.05 && (p - xy(&b.end)).norm() > 0.05,
        )?;
    }

    #[test]
    fn arc_arc_hits_lie_on_both(a in xy_arc(), b in xy_arc(), tol in prop_oneof![Just(0.0), 1e-9..1e-3f64]) {
        let hits = arc_arc(&a, &b, tol).unwrap();
        check_hits(&hits, |p| on_arc(&a, p), |p| on_arc(&b, p), |t| arc_xy(&a, t), |t| arc_xy(&b, t), tol)?;
        let c = xy(&b.center);
        check_complete(
            &hits,
            |t| arc_xy(&a, t),
            |p| (p - c).norm() - b.radius(),
            |p| on_arc(&b, p) < 1e-3 && (p - xy(&b.start)).norm() > 0.05 && (p - xy(&b.end)).norm() > 0.05,
        )?;
    }

    #[test]
    fn arcs_on_one_circle_overlap_consistently(
        a in xy_arc(),
        a0 in -PI..PI,
        sw in prop_oneof![0.05..(TAU - 0.05), Just(0.0)],
        ccw in any::<bool>(),
        tol in prop_oneof![Just(0.0), 1e-9..1e-3f64],
    ) {
        let sw = if ccw { sw } else { -sw };
        let mut b = build(Plane::Xy, xy(&a.center), 0.0, a.radius(), a0, sw, 0.0, 0);
        b.ccw = ccw;
        let hits = arc_arc(&a, &b, tol).unwrap();
        check_hits(&hits, |p| on_arc(&a, p), |p| on_arc(&b, p), |t| arc_xy(&a, t), |t| arc_xy(&b, t), tol)?;
        prop_assert!(hits.len() <= 2);
        // Shared length from sampling a: the fraction of a lying on b.
        const N: usize = 2000;
        let on_b = (0..N).filter(|i| on_arc(&b, &arc_xy(&a, (*i as f64 + 0.5) / N as f64)) < 1e-6).count();
        let sampled = a.length() * on_b as f64 / N as f64;
        let reported: f64 = hits.iter().map(|i| match i {
            Intersection::Overlap { start, end } => {
                // Along a's travel; a stretch may wrap over a full circle's seam.
                let d = end.t1 - start.t1;
                let d = if d * a.length() > tol { d } else { d + 1.0 };
                d * a.length()
            }
            Intersection::Point { .. } => 0.0,
        }).sum();
        prop_assert!((sampled - reported).abs() < 2.0 * a.length() / N as f64 + 2.0 * tol + 1e-6,
            "sampled {sampled}, reported {reported}: {hits:?}");
    }
}

/// Any f64 at all, weighted towards the values that break geometry code.
fn wild() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        -2.0..2.0f64,
        any::<f64>(),
    ]
}

fn wild_p3() -> impl Strategy<Value = P3> {
    (wild(), wild(), wild()).prop_map(|(x, y, z)| P3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Garbage in (NaN, infinities, zero radius, coincident points) must give
    /// `None`, NaN or an answer, never a panic or a hang.
    #[test]
    fn nothing_panics(
        c in wild_p3(), s in wild_p3(), e in wild_p3(), q in wild_p3(),
        ccw in any::<bool>(), pl in plane(), extra in prop_oneof![Just(0u32), Just(u32::MAX), 0..5u32],
        t in wild(), tol in wild(), bulge in wild(),
    ) {
        let arc = Arc3 { center: c, start: s, end: e, ccw, plane: pl, extra_turns: extra };
        let _ = (arc.radius(), arc.sweep(), arc.length(), arc.point_at(t), arc.tangent_at(t), arc.bbox());
        let _ = (arc.closest_point(&q), arc.reversed(), arc.split_at(t), arc.point_at_length(t));
        let _ = Arc3::new(c, s, e, ccw, pl, extra);
        let _ = Arc3::from_three_points(&c, &s, &e, pl);
        let _ = (arc_from_bulge(&s, &e, bulge), bulge_of(&arc));
        let line = Line3::new(s, e);
        let other = Line3::new(c, q);
        let _ = (line.closest_point(&q), line.tangent(), line.split_at(t), line.bbox());
        let xy_arc = Arc3 { plane: Plane::Xy, ..arc };
        let _ = (line_line(&line, &other, tol), line_arc(&line, &xy_arc, tol), arc_arc(&xy_arc, &xy_arc.reversed(), tol));
        if let Some(a) = Arc3::new(c, s, e, ccw, Plane::Xy, 0) {
            let _ = (arc_arc(&a, &a, tol.abs()), line_arc(&other, &a, tol.abs()));
        }
    }
}

fn any_point() -> impl Strategy<Value = P3> {
    (-100.0..100.0f64, -100.0..100.0f64, -100.0..100.0f64).prop_map(|(x, y, z)| P3::new(x, y, z))
}

/// Any segment: a line in space or an arc of any plane, helix and turns.
fn any_segment() -> impl Strategy<Value = Segment> {
    prop_oneof![
        (any_point(), any_point()).prop_map(|(a, b)| Segment::line(a, b)),
        any_arc().prop_map(Segment::Arc),
    ]
}

/// Distance from `p` to the segment, by dense sampling (works for helices).
fn sampled_distance(s: &Segment, p: &P3) -> f64 {
    (0..=2000)
        .map(|i| (s.point_at(i as f64 / 2000.0) - p).norm())
        .fold(f64::INFINITY, f64::min)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn segment_reversed_twice_is_identity(s in any_segment()) {
        prop_assert_eq!(s.reversed().reversed(), s);
        let r = s.reversed();
        prop_assert_eq!(r.start(), s.end());
        prop_assert_eq!(r.end(), s.start());
        prop_assert!((r.length() - s.length()).abs() <= 1e-9 * s.length().max(1.0));
        prop_assert!(close3(&r.midpoint(), &s.midpoint(), 1e-9 * s.length().max(1.0)));
    }

    #[test]
    fn segment_split_lengths_add_up(s in any_segment(), t in 0.02..0.98f64) {
        let len = s.length();
        let (a, b) = s.split_at(t).unwrap();
        prop_assert!((a.length() + b.length() - len).abs() <= 1e-9 * len.max(1.0),
            "{} + {} != {}", a.length(), b.length(), len);
        prop_assert!((a.length() - t * len).abs() <= 1e-9 * len.max(1.0));
        prop_assert_eq!(a.start(), s.start());
        prop_assert_eq!(b.end(), s.end());
        prop_assert_eq!(a.end(), b.start());
        let by_length = s.split_at_length(t * len, 1e-7).unwrap();
        prop_assert!(close3(&by_length.0.end(), &a.end(), 1e-9 * len.max(1.0)));
    }

    #[test]
    fn segment_point_at_length_ends_and_midpoint(s in any_segment()) {
        let len = s.length();
        prop_assert_eq!(s.point_at_length(0.0), s.start());
        prop_assert_eq!(s.point_at_length(len), s.end());
        let m = s.midpoint();
        prop_assert!(close3(&s.point_at_length(0.5 * len), &m, 1e-9 * len.max(1.0)));
        // The midpoint lies on the segment, halfway along it.
        prop_assert!(sampled_distance(&s, &m) <= 1e-9 * len.max(1.0));
        if let Some(d) = s.distance(&m) {
            prop_assert!(d <= 1e-9 * len.max(1.0), "midpoint {} off", d);
        }
        let b = s.bbox();
        let slack = 1e-9 * len.max(1.0);
        for q in [s.start(), m, s.end()] {
            prop_assert!((0..3).all(|k| q[k] >= b.min[k] - slack && q[k] <= b.max[k] + slack));
        }
    }

    #[test]
    fn segment_closest_point_beats_samples(s in any_segment(), p in any_point()) {
        if let Some((q, t)) = s.closest_point(&p) {
            prop_assert!((0.0..=1.0).contains(&t));
            prop_assert!(close3(&s.point_at(t), &q, 1e-9 * s.length().max(1.0)));
            prop_assert!((q - p).norm() <= sampled_distance(&s, &p) + 1e-9);
        } else {
            prop_assert!(s.arc().is_some_and(|a| a.is_helical(crate::geometry::EPS_LEN)));
        }
    }

    #[test]
    fn segment_tangents_are_unit_and_match_the_general_formula(s in any_segment()) {
        for (fast, t) in [(s.start_tangent(), 0.0), (s.end_tangent(), 1.0)] {
            if let Some(general) = s.tangent_at(t) {
                prop_assert!((fast.norm() - 1.0).abs() < 1e-9);
                prop_assert!((fast - general).norm() < 1e-6, "{:?} vs {:?}", fast, general);
            }
        }
    }

    #[test]
    fn chain_arcs_sweep_like_arc3(a in xy_arc()) {
        // A chain's unchecked XY arc is the same arc as the checked one.
        let s = Segment::arc_xy(a.start, a.end, a.center, a.ccw);
        let x = s.to_arc_xy().unwrap();
        prop_assert_eq!(x.sweep, a.sweep());
        prop_assert_eq!(x.radius, a.radius());
        let end = x.point_at_angle(x.start_angle + x.sweep);
        prop_assert!((end - xy(&a.end)).norm() < 1e-9);
        prop_assert_eq!(s.checked(), Some(s));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn segment_intersect_dispatches_by_kind(l in xy_line(), m in xy_line(), a in xy_arc(), b in xy_arc()) {
        use super::intersect::{arc_line, intersect};
        let tol = 1e-9;
        prop_assert_eq!(intersect(&Segment::Line(l), &Segment::Line(m), tol), line_line(&l, &m, tol));
        prop_assert_eq!(intersect(&Segment::Line(l), &Segment::Arc(a), tol), line_arc(&l, &a, tol));
        prop_assert_eq!(intersect(&Segment::Arc(a), &Segment::Line(l), tol), arc_line(&a, &l, tol));
        prop_assert_eq!(intersect(&Segment::Arc(a), &Segment::Arc(b), tol), arc_arc(&a, &b, tol));
    }
}
