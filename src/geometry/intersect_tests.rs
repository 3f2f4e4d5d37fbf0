//! Tests of the segment intersections (intersect.rs).

use super::*;
use crate::geometry::P3;
use std::f64::consts::{FRAC_PI_2, PI};

const TOL: f64 = 1e-9;

fn ln(a: [f64; 2], b: [f64; 2]) -> Line3 {
    Line3::new(P3::new(a[0], a[1], 0.0), P3::new(b[0], b[1], 0.0))
}

/// Arc on a circle around `c` of radius `r` from angle `a0` sweeping `sw` (signed; 0 = full ccw circle).
fn arc(c: [f64; 2], r: f64, a0: f64, sw: f64) -> Arc3 {
    let at = |a: f64| P3::new(c[0] + r * a.cos(), c[1] + r * a.sin(), 0.0);
    Arc3::new(P3::new(c[0], c[1], 0.0), at(a0), at(a0 + sw), sw >= 0.0, Plane::Xy, 0).unwrap()
}

fn circle(c: [f64; 2], r: f64) -> Arc3 {
    arc(c, r, 0.0, 0.0)
}

fn pt(i: &Intersection) -> (Hit, bool) {
    match *i {
        Intersection::Point { hit, tangent } => (hit, tangent),
        Intersection::Overlap { .. } => panic!("expected a point, got {i:?}"),
    }
}

fn ov(i: &Intersection) -> (Hit, Hit) {
    match *i {
        Intersection::Overlap { start, end } => (start, end),
        Intersection::Point { .. } => panic!("expected an overlap, got {i:?}"),
    }
}

fn near(a: P2, x: f64, y: f64) -> bool {
    (a - P2::new(x, y)).norm() < 1e-9
}

#[test]
fn crossing_and_missing_segments() {
    let r = line_line(&ln([0.0, 0.0], [2.0, 2.0]), &ln([0.0, 2.0], [2.0, 0.0]), TOL).unwrap();
    assert_eq!(r.len(), 1);
    let (h, tangent) = pt(&r[0]);
    assert!(near(h.point, 1.0, 1.0) && !tangent);
    assert!((h.t1 - 0.5).abs() < 1e-12 && (h.t2 - 0.5).abs() < 1e-12);
    assert!(
        line_line(&ln([0.0, 0.0], [1.0, 0.0]), &ln([2.0, -1.0], [2.0, 1.0]), TOL)
            .unwrap()
            .is_empty()
    );
    assert!(
        line_line(&ln([0.0, 0.0], [1.0, 0.0]), &ln([0.0, 1.0], [1.0, 1.0]), TOL)
            .unwrap()
            .is_empty()
    );
}

#[test]
fn collinear_segments_overlap_or_touch() {
    let r = line_line(&ln([0.0, 0.0], [4.0, 0.0]), &ln([6.0, 0.0], [2.0, 0.0]), TOL).unwrap();
    assert_eq!(r.len(), 1);
    let (s, e) = ov(&r[0]);
    assert!(near(s.point, 2.0, 0.0) && (s.t1 - 0.5).abs() < 1e-12 && (s.t2 - 1.0).abs() < 1e-12);
    assert!(near(e.point, 4.0, 0.0) && (e.t1 - 1.0).abs() < 1e-12 && (e.t2 - 0.5).abs() < 1e-12);
    let r = line_line(&ln([0.0, 0.0], [1.0, 0.0]), &ln([1.0, 0.0], [2.0, 0.0]), TOL).unwrap();
    assert_eq!(r.len(), 1);
    let (h, _) = pt(&r[0]);
    assert!(near(h.point, 1.0, 0.0) && h.t1 == 1.0 && h.t2 == 0.0);
    assert!(
        line_line(&ln([0.0, 0.0], [1.0, 0.0]), &ln([1.1, 0.0], [2.0, 0.0]), TOL)
            .unwrap()
            .is_empty()
    );
    // Nearly collinear within tolerance still overlaps.
    let r = line_line(&ln([0.0, 0.0], [10.0, 0.0]), &ln([1.0, 1e-7], [3.0, -1e-7]), 1e-6).unwrap();
    assert!(matches!(r[..], [Intersection::Overlap { .. }]));
}

#[test]
fn ends_resting_on_segments_within_tolerance() {
    // T junction missing by 0.1 um.
    let r = line_line(&ln([0.0, 0.0], [2.0, 0.0]), &ln([1.0, 1e-7], [1.0, 1.0]), 1e-6).unwrap();
    assert_eq!(r.len(), 1);
    let (h, _) = pt(&r[0]);
    assert!((h.point - P2::new(1.0, 0.0)).norm() < 1e-6 && (h.t1 - 0.5).abs() < 1e-6 && h.t2 == 0.0);
    // Shallow angle: the lines cross far away, but b's start rests on a.
    let r = line_line(&ln([0.0, 0.0], [10.0, 0.0]), &ln([5.0, 5e-7], [15.0, 1.0]), 1e-6).unwrap();
    assert_eq!(r.len(), 1);
    let (h, _) = pt(&r[0]);
    assert!(near(h.point, 5.0, 5e-7) && (h.t1 - 0.5).abs() < 1e-12);
    // A zero-length segment on another one.
    let r = line_line(&ln([3.0, 0.0], [3.0, 0.0]), &ln([0.0, 0.0], [4.0, 0.0]), TOL).unwrap();
    assert_eq!(r.len(), 1);
    assert!((pt(&r[0]).0.t2 - 0.75).abs() < 1e-12);
}

#[test]
fn line_through_circle_and_arcs() {
    let r = line_arc(&ln([-2.0, 0.0], [2.0, 0.0]), &circle([0.0, 0.0], 1.0), TOL).unwrap();
    assert_eq!(r.len(), 2);
    let (h0, h1) = (pt(&r[0]).0, pt(&r[1]).0);
    assert!(near(h0.point, -1.0, 0.0) && (h0.t1 - 0.25).abs() < 1e-12 && (h0.t2 - 0.5).abs() < 1e-12);
    assert!(near(h1.point, 1.0, 0.0) && (h1.t1 - 0.75).abs() < 1e-12);
    assert!(
        h1.t2 == 0.0 || h1.t2 == 1.0,
        "the full circle starts and ends at (1, 0)"
    );
    let q = arc([0.0, 0.0], 1.0, 0.0, FRAC_PI_2);
    let r = line_arc(&ln([0.0, 0.0], [2.0, 2.0]), &q, TOL).unwrap();
    assert_eq!(r.len(), 1);
    let h = pt(&r[0]).0;
    assert!(near(h.point, 0.5f64.sqrt(), 0.5f64.sqrt()) && (h.t2 - 0.5).abs() < 1e-12);
    // The circle is crossed, but not within the arc.
    assert!(line_arc(&ln([-2.0, -2.0], [0.0, 0.0]), &q, TOL).unwrap().is_empty());
    let swapped = arc_line(&q, &ln([0.0, 0.0], [2.0, 2.0]), TOL).unwrap();
    assert!((pt(&swapped[0]).0.t1 - 0.5).abs() < 1e-12);
}

#[test]
fn tangent_line_touches_once() {
    let r = line_arc(
        &ln([-2.0, 1.0 + 1e-10], [2.0, 1.0 + 1e-10]),
        &circle([0.0, 0.0], 1.0),
        TOL,
    )
    .unwrap();
    assert_eq!(r.len(), 1);
    let (h, tangent) = pt(&r[0]);
    assert!(tangent && (h.point - P2::new(0.0, 1.0)).norm() < 1e-9 && (h.t2 - 0.25).abs() < 1e-9);
    assert!(
        line_arc(&ln([-2.0, 1.1], [2.0, 1.1]), &circle([0.0, 0.0], 1.0), TOL)
            .unwrap()
            .is_empty()
    );
}

#[test]
fn circles_cross_and_touch() {
    let r = arc_arc(&circle([0.0, 0.0], 1.0), &circle([1.0, 0.0], 1.0), TOL).unwrap();
    assert_eq!(r.len(), 2);
    let (h0, h1) = (pt(&r[0]).0, pt(&r[1]).0);
    let y = 0.75f64.sqrt();
    assert!(near(h0.point, 0.5, y) && (h0.t1 - 1.0 / 6.0).abs() < 1e-12 && (h0.t2 - 1.0 / 3.0).abs() < 1e-12);
    assert!(near(h1.point, 0.5, -y) && (h1.t1 - 5.0 / 6.0).abs() < 1e-12);
    let r = arc_arc(&circle([0.0, 0.0], 1.0), &circle([2.0, 0.0], 1.0), TOL).unwrap();
    assert_eq!(r.len(), 1);
    assert!(pt(&r[0]).1 && near(pt(&r[0]).0.point, 1.0, 0.0));
    let r = arc_arc(&circle([0.0, 0.0], 2.0), &circle([1.0, 0.0], 1.0), TOL).unwrap();
    assert_eq!(r.len(), 1);
    assert!(pt(&r[0]).1 && near(pt(&r[0]).0.point, 2.0, 0.0));
    assert!(
        arc_arc(&circle([0.0, 0.0], 1.0), &circle([3.0, 0.0], 1.0), TOL)
            .unwrap()
            .is_empty()
    );
    assert!(
        arc_arc(&circle([0.0, 0.0], 3.0), &circle([0.5, 0.0], 1.0), TOL)
            .unwrap()
            .is_empty()
    );
    // Crossing circles, but the arcs stop short.
    let a = arc([0.0, 0.0], 1.0, PI, FRAC_PI_2);
    assert!(arc_arc(&a, &circle([1.0, 0.0], 1.0), TOL).unwrap().is_empty());
}

#[test]
fn arcs_on_one_circle_overlap() {
    let a = arc([0.0, 0.0], 1.0, 0.0, PI);
    let b = arc([0.0, 0.0], 1.0, FRAC_PI_2, PI);
    let r = arc_arc(&a, &b, TOL).unwrap();
    assert_eq!(r.len(), 1);
    let (s, e) = ov(&r[0]);
    assert!(near(s.point, 0.0, 1.0) && (s.t1 - 0.5).abs() < 1e-12 && s.t2.abs() < 1e-12);
    assert!(near(e.point, -1.0, 0.0) && (e.t1 - 1.0).abs() < 1e-12 && (e.t2 - 0.5).abs() < 1e-12);
    // Travelling a clockwise: the stretch runs from (-1,0) to (0,1).
    let r = arc_arc(&a.reversed(), &b, TOL).unwrap();
    let (s, e) = ov(&r[0]);
    assert!(near(s.point, -1.0, 0.0) && s.t1.abs() < 1e-12);
    assert!(near(e.point, 0.0, 1.0) && (e.t1 - 0.5).abs() < 1e-12);
    // Two arcs of 3/4 turn share two separate stretches.
    let a = arc([0.0, 0.0], 1.0, 0.0, 1.5 * PI);
    let b = arc([0.0, 0.0], 1.0, PI, 1.5 * PI);
    let r = arc_arc(&a, &b, TOL).unwrap();
    assert_eq!(r.len(), 2);
    let (s0, e0) = ov(&r[0]);
    let (s1, e1) = ov(&r[1]);
    assert!(near(s0.point, 1.0, 0.0) && near(e0.point, 0.0, 1.0));
    assert!(near(s1.point, -1.0, 0.0) && near(e1.point, 0.0, -1.0));
    // End to end on the same circle: a touch, not an overlap.
    let r = arc_arc(
        &arc([0.0, 0.0], 1.0, 0.0, FRAC_PI_2),
        &arc([0.0, 0.0], 1.0, FRAC_PI_2, FRAC_PI_2),
        TOL,
    )
    .unwrap();
    assert_eq!(r.len(), 1);
    let h = pt(&r[0]).0;
    assert!(near(h.point, 0.0, 1.0) && (h.t1 - 1.0).abs() < 1e-12 && h.t2.abs() < 1e-12);
    // A full circle and an arc over its seam: one stretch.
    let r = arc_arc(&circle([0.0, 0.0], 1.0), &arc([0.0, 0.0], 1.0, 1.5 * PI, PI), TOL).unwrap();
    assert_eq!(r.len(), 1);
    let (s, e) = ov(&r[0]);
    assert!(near(s.point, 0.0, -1.0) && (s.t1 - 0.75).abs() < 1e-12 && s.t2.abs() < 1e-12);
    assert!(near(e.point, 0.0, 1.0) && (e.t1 - 0.25).abs() < 1e-12 && (e.t2 - 1.0).abs() < 1e-12);
}

#[test]
fn refuses_what_it_cannot_answer() {
    let xz = Arc3::new(
        P3::origin(),
        P3::new(1.0, 0.0, 0.0),
        P3::new(0.0, 0.0, 1.0),
        true,
        Plane::Xz,
        0,
    )
    .unwrap();
    assert!(arc_arc(&xz, &circle([0.0, 0.0], 1.0), TOL).is_none());
    assert!(line_arc(&ln([0.0, 0.0], [1.0, 0.0]), &xz, TOL).is_none());
    assert!(line_line(&ln([0.0, f64::NAN], [1.0, 0.0]), &ln([0.0, 0.0], [1.0, 0.0]), TOL).is_none());
    assert!(line_line(&ln([0.0, 0.0], [1.0, 0.0]), &ln([0.0, 0.0], [1.0, 0.0]), -1.0).is_none());
    assert!(arc_arc(&circle([0.0, 0.0], 1.0), &circle([0.0, 0.0], 1.0), f64::NAN).is_none());
    // A point-like line resting on an arc is still found.
    let r = line_arc(&ln([0.0, 1.0], [0.0, 1.0]), &circle([0.0, 0.0], 1.0), TOL).unwrap();
    assert_eq!(r.len(), 1);
    // A helical XY arc meets things where its shadow does.
    let helix = Arc3::new(
        P3::origin(),
        P3::new(1.0, 0.0, 0.0),
        P3::new(-1.0, 0.0, 5.0),
        true,
        Plane::Xy,
        0,
    )
    .unwrap();
    let r = line_arc(&ln([0.0, -2.0], [0.0, 2.0]), &helix, TOL).unwrap();
    assert_eq!(r.len(), 1);
    assert!(near(pt(&r[0]).0.point, 0.0, 1.0));
}
