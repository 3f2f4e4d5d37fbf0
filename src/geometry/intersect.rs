//! Intersections of lines and arcs in the XY plane.
//!
//! Chaining, offsetting and trimming need to know where two primitives meet,
//! restricted to their extents and at a tolerance: drawings are never exact,
//! and a tangency that misses by a nanometre must still count as one. The
//! primitives are projected onto XY (Z is ignored, so a helical XY arc meets
//! things where its shadow does); an arc in another plane has no circular
//! shadow and is refused.
//!
//! Results come as a list of [`Intersection`]s sorted along the first
//! primitive. A shared stretch (collinear lines, arcs on the same circle) is
//! reported as one `Overlap` rather than as its two end points, because
//! callers treat it differently (merge duplicates, not split). Every reported
//! point lies within `tol` of both primitives. Arcs are treated as circles of
//! their start radius; an arc of more than one turn is met on its first
//! pass, and its parameters refer to that pass.
//!
//! The tolerance is never taken below the rounding noise of the input
//! (1e-12 of the largest coordinate or radius), so `tol = 0` means "as exact
//! as floating point allows": two arcs built on the same circle still overlap.

use super::arc::Arc3;
use super::line::Line3;
use super::segment::Segment;
use super::tol::{finite_p3, normalize_angle, valid_tol};
use super::{P2, Plane, V2};
use std::f64::consts::TAU;

/// Where two primitives meet: the point and its parameter (0 = start,
/// 1 = end, as in `point_at`) on the first and on the second primitive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// The meeting point in XY.
    pub point: P2,
    /// Parameter on the first primitive, in [0, 1].
    pub t1: f64,
    /// Parameter on the second primitive, in [0, 1].
    pub t2: f64,
}

/// One intersection between two primitives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Intersection {
    /// The primitives meet at a point. `tangent` is true when they touch
    /// without crossing (within the tolerance), e.g. a line tangent to an arc.
    Point {
        /// Where they meet.
        hit: Hit,
        /// Touching, not crossing.
        tangent: bool,
    },
    /// The primitives share a stretch longer than the tolerance, from
    /// `start` to `end` in the first primitive's direction of travel.
    Overlap {
        /// Where the shared stretch begins along the first primitive.
        start: Hit,
        /// Where the shared stretch ends along the first primitive.
        end: Hit,
    },
}

impl Intersection {
    /// The one or two hits this intersection consists of.
    pub fn hits(&self) -> Vec<Hit> {
        match *self {
            Intersection::Point { hit, .. } => vec![hit],
            Intersection::Overlap { start, end } => vec![start, end],
        }
    }

    /// The same intersection seen from the other primitive: `t1` and `t2`
    /// swapped (an overlap keeps the first primitive's order of its ends).
    pub fn swapped(&self) -> Intersection {
        let sw = |h: Hit| Hit {
            point: h.point,
            t1: h.t2,
            t2: h.t1,
        };
        match *self {
            Intersection::Point { hit, tangent } => Intersection::Point { hit: sw(hit), tangent },
            Intersection::Overlap { start, end } => Intersection::Overlap {
                start: sw(start),
                end: sw(end),
            },
        }
    }

    fn sort_key(&self) -> f64 {
        match self {
            Intersection::Point { hit, .. } => hit.t1,
            Intersection::Overlap { start, end } => start.t1.min(end.t1),
        }
    }
}

/// A segment projected onto XY.
#[derive(Clone, Copy)]
struct Seg {
    p: P2,
    q: P2,
}

impl Seg {
    fn new(l: &Line3) -> Option<Seg> {
        (finite_p3(&l.start) && finite_p3(&l.end)).then(|| Seg {
            p: P2::new(l.start.x, l.start.y),
            q: P2::new(l.end.x, l.end.y),
        })
    }

    fn d(&self) -> V2 {
        self.q - self.p
    }

    fn len(&self) -> f64 {
        self.d().norm()
    }

    fn at(&self, t: f64) -> P2 {
        self.p + self.d() * t
    }

    /// Parameter of the foot of `x` on the infinite line (unclamped).
    fn project(&self, x: &P2) -> f64 {
        let l2 = self.d().norm_squared();
        if l2 > 0.0 {
            (x - self.p).dot(&self.d()) / l2
        } else {
            0.0
        }
    }

    /// Distance from `x` to the infinite line.
    fn line_dist(&self, x: &P2) -> f64 {
        (x - self.at(self.project(x))).norm()
    }

    /// Accept a line parameter within `tol` (in length) of [0, 1], clamped.
    fn accept(&self, t: f64, tol: f64) -> Option<f64> {
        let slack = tol / self.len();
        (t >= -slack && t <= 1.0 + slack).then(|| t.clamp(0.0, 1.0))
    }

    fn closest(&self, x: &P2) -> (P2, f64) {
        let t = self.project(x).clamp(0.0, 1.0);
        (self.at(t), t)
    }
}

/// An XY arc with its circle data precomputed.
#[derive(Clone, Copy)]
struct Circ {
    arc: Arc3,
    c: P2,
    r: f64,
    a0: f64,
    /// Absolute sweep.
    sw: f64,
}

impl Circ {
    fn new(a: &Arc3) -> Option<Circ> {
        if a.plane != Plane::Xy || ![a.center, a.start, a.end].iter().all(finite_p3) {
            return None;
        }
        let sw = a.sweep().abs();
        sw.is_finite().then(|| Circ {
            arc: *a,
            c: P2::new(a.center.x, a.center.y),
            r: a.radius(),
            a0: a.start_angle(),
            sw,
        })
    }

    fn point(&self, t: f64) -> P2 {
        let p = self.arc.point_at(t);
        P2::new(p.x, p.y)
    }

    /// How far (radians, in the direction of travel, in [0, 2π)) the
    /// direction of `x` lies from the start.
    fn delta(&self, x: &P2) -> f64 {
        let v = x - self.c;
        let phi = v.y.atan2(v.x);
        if self.arc.ccw {
            normalize_angle(phi - self.a0)
        } else {
            normalize_angle(self.a0 - phi)
        }
    }

    /// First-pass parameter of the direction of `x`, accepting up to `tol`
    /// (in length) beyond either end, clamped to [0, 1].
    fn accept(&self, x: &P2, tol: f64) -> Option<f64> {
        let delta = self.delta(x);
        if delta <= self.sw {
            return Some(delta / self.sw);
        }
        let slack = tol / self.r;
        let past_end = delta - self.sw;
        let before_start = TAU - delta;
        if past_end.min(before_start) > slack {
            None
        } else if past_end <= before_start {
            Some(1.0)
        } else {
            Some(0.0)
        }
    }

    fn closest(&self, x: &P2) -> (P2, f64) {
        let mut best = (self.point(0.0), 0.0);
        let mut consider = |t: f64| {
            let q = self.point(t);
            if (q - x).norm() < (best.0 - x).norm() {
                best = (q, t);
            }
        };
        consider(1.0);
        if (x - self.c).norm() > 0.0 {
            let delta = self.delta(x);
            if delta <= self.sw {
                consider(delta / self.sw);
            }
        }
        best
    }

    /// Start of the arc's first-pass angular interval in ccw order, and its
    /// width (at most a full turn).
    fn ccw_interval(&self) -> (f64, f64) {
        let span = self.sw.min(TAU);
        let lo = if self.arc.ccw { self.a0 } else { self.a0 - span };
        (lo, span)
    }

    /// Parameter of the point at ccw offset `x` from `ccw_interval().0`.
    fn t_of_offset(&self, x: f64) -> f64 {
        let (_, span) = self.ccw_interval();
        let x = if x > span { x - TAU } else { x };
        let travel = if self.arc.ccw { x } else { span - x };
        (travel / self.sw).clamp(0.0, 1.0)
    }
}

/// Either primitive, for the shared end-point checks.
#[derive(Clone, Copy)]
enum Shape {
    Seg(Seg),
    Circ(Circ),
}

impl Shape {
    /// A segment's XY shadow; `None` for non-finite coordinates or an arc
    /// outside the XY plane.
    fn new(s: &Segment) -> Option<Shape> {
        match s {
            Segment::Line(l) => Seg::new(l).map(Shape::Seg),
            Segment::Arc(a) => Circ::new(a).map(Shape::Circ),
        }
    }

    fn closest(&self, x: &P2) -> (P2, f64) {
        match self {
            Shape::Seg(s) => s.closest(x),
            Shape::Circ(c) => c.closest(x),
        }
    }

    fn ends(&self) -> [(P2, f64); 2] {
        match self {
            Shape::Seg(s) => [(s.p, 0.0), (s.q, 1.0)],
            Shape::Circ(c) => [(c.point(0.0), 0.0), (c.point(1.0), 1.0)],
        }
    }
}

/// Relative size of floating-point noise in the closed forms below.
const NOISE: f64 = 1e-12;

/// `tol` raised to the rounding noise of coordinates of magnitude `scale`.
fn effective_tol(tol: f64, scale: impl IntoIterator<Item = f64>) -> f64 {
    let m = scale.into_iter().fold(0.0f64, |m, x| m.max(x.abs()));
    tol.max(NOISE * m)
}

impl Seg {
    fn scale(&self) -> [f64; 4] {
        [self.p.x, self.p.y, self.q.x, self.q.y]
    }
}

impl Circ {
    fn scale(&self) -> [f64; 3] {
        [self.c.x.abs() + self.r, self.c.y.abs() + self.r, self.r]
    }
}

fn mid(a: &P2, b: &P2) -> P2 {
    nalgebra::center(a, b)
}

fn point(point: P2, t1: f64, t2: f64, tangent: bool) -> Intersection {
    Intersection::Point {
        hit: Hit { point, t1, t2 },
        tangent,
    }
}

/// Add the end points of either primitive that lie within `tol` of the
/// other and are not already reported. This catches what the closed forms
/// miss at a tolerance: an end resting on the other primitive at a shallow
/// angle, and degenerate (point-like) primitives.
fn end_touches(a: &Shape, b: &Shape, tol: f64, out: &mut Vec<Intersection>) {
    if out.iter().any(|i| matches!(i, Intersection::Overlap { .. })) {
        return;
    }
    let dedup = (2.0 * tol).max(super::EPS_LEN);
    let add = |out: &mut Vec<Intersection>, x: P2, t1: f64, t2: f64| {
        let known = out.iter().flat_map(|i| i.hits()).any(|h| (h.point - x).norm() <= dedup);
        if !known {
            out.push(point(x, t1, t2, false));
        }
    };
    for (x, ta) in a.ends() {
        let (q, tb) = b.closest(&x);
        if (q - x).norm() <= tol {
            add(out, x, ta, tb);
        }
    }
    for (x, tb) in b.ends() {
        let (q, ta) = a.closest(&x);
        if (q - x).norm() <= tol {
            add(out, x, ta, tb);
        }
    }
}

fn finish(mut out: Vec<Intersection>) -> Vec<Intersection> {
    out.sort_by(|a, b| a.sort_key().total_cmp(&b.sort_key()));
    out
}

/// Intersections of two segments in XY. Collinear segments (each end of one
/// within `tol` of the other's line) that share more than `tol` of length
/// give one `Overlap`; if they only touch, a `Point`. `None` when a
/// coordinate is not finite or `tol` is negative or NaN.
///
/// ```
/// use microcam::geometry::intersect::{Intersection, line_line};
/// use microcam::geometry::{Line3, P3};
/// let a = Line3::new(P3::new(0.0, 0.0, 0.0), P3::new(2.0, 2.0, 0.0));
/// let b = Line3::new(P3::new(0.0, 2.0, 0.0), P3::new(2.0, 0.0, 0.0));
/// let hits = line_line(&a, &b, 1e-9).unwrap();
/// let Intersection::Point { hit, .. } = hits[0] else { panic!() };
/// assert!((hit.t1 - 0.5).abs() < 1e-15 && (hit.point.x - 1.0).abs() < 1e-15);
/// ```
pub fn line_line(a: &Line3, b: &Line3, tol: f64) -> Option<Vec<Intersection>> {
    seg_seg(Seg::new(a)?, Seg::new(b)?, tol)
}

/// Intersections of two segments of any kind in XY, sorted along the first:
/// [`line_line`], [`line_arc`], [`arc_line`] or [`arc_arc`] as their kinds
/// say. `None` when an arc is not in the XY plane, a coordinate is not
/// finite, or `tol` is invalid.
///
/// ```
/// use microcam::geometry::intersect::{Intersection, intersect};
/// use microcam::geometry::{P3, Segment};
/// let line = Segment::line(P3::new(-2.0, 0.5, 0.0), P3::new(2.0, 0.5, 0.0));
/// let circle = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(1.0, 0.0, 0.0), P3::origin(), true);
/// let hits = intersect(&line, &circle, 1e-9).unwrap();
/// assert_eq!(hits.len(), 2);
/// let Intersection::Point { hit, .. } = hits[0] else { panic!() };
/// assert!((hit.point.x + 0.75f64.sqrt()).abs() < 1e-12);
/// ```
pub fn intersect(a: &Segment, b: &Segment, tol: f64) -> Option<Vec<Intersection>> {
    match (Shape::new(a)?, Shape::new(b)?) {
        (Shape::Seg(x), Shape::Seg(y)) => seg_seg(x, y, tol),
        (Shape::Seg(x), Shape::Circ(y)) => seg_circ(x, y, tol),
        (Shape::Circ(x), Shape::Seg(y)) => seg_circ(y, x, tol).map(swap_sorted),
        (Shape::Circ(x), Shape::Circ(y)) => circ_circ(x, y, tol),
    }
}

fn seg_seg(sa: Seg, sb: Seg, tol: f64) -> Option<Vec<Intersection>> {
    if !valid_tol(tol) {
        return None;
    }
    let tol = effective_tol(tol, sa.scale().into_iter().chain(sb.scale()));
    let mut out = Vec::new();
    let (la, lb) = (sa.len(), sb.len());
    if la > tol && lb > tol {
        let collinear = (sa.line_dist(&sb.p) <= tol && sa.line_dist(&sb.q) <= tol)
            || (sb.line_dist(&sa.p) <= tol && sb.line_dist(&sa.q) <= tol);
        if collinear {
            collinear_overlap(&sa, &sb, tol, &mut out);
        } else {
            let (r, s) = (sa.d(), sb.d());
            let denom = r.perp(&s);
            if denom != 0.0 {
                let w = sb.p - sa.p;
                let t = w.perp(&s) / denom;
                let u = w.perp(&r) / denom;
                if let (Some(t), Some(u)) = (sa.accept(t, tol), sb.accept(u, tol)) {
                    out.push(point(mid(&sa.at(t), &sb.at(u)), t, u, false));
                }
            }
        }
    }
    end_touches(&Shape::Seg(sa), &Shape::Seg(sb), tol, &mut out);
    Some(finish(out))
}

fn collinear_overlap(sa: &Seg, sb: &Seg, tol: f64, out: &mut Vec<Intersection>) {
    let (u0, u1) = (sa.project(&sb.p), sa.project(&sb.q));
    let lo = u0.min(u1).max(0.0);
    let hi = u0.max(u1).min(1.0);
    let la = sa.len();
    let hit = |t: f64| {
        let pa = sa.at(t);
        let (pb, u) = sb.closest(&pa);
        Hit {
            point: mid(&pa, &pb),
            t1: t,
            t2: u,
        }
    };
    if (hi - lo) * la > tol {
        out.push(Intersection::Overlap {
            start: hit(lo),
            end: hit(hi),
        });
    } else if (lo - hi) * la <= tol {
        let h = hit((0.5 * (lo + hi)).clamp(0.0, 1.0));
        out.push(Intersection::Point { hit: h, tangent: false });
    }
}

/// Intersections of a segment (first) and an XY arc (second). A line within
/// `tol` of tangent gives one `Point` marked tangent. `None` when the arc is
/// not in the XY plane, a coordinate is not finite, or `tol` is invalid.
pub fn line_arc(a: &Line3, b: &Arc3, tol: f64) -> Option<Vec<Intersection>> {
    seg_circ(Seg::new(a)?, Circ::new(b)?, tol)
}

fn seg_circ(sa: Seg, cb: Circ, tol: f64) -> Option<Vec<Intersection>> {
    if !valid_tol(tol) {
        return None;
    }
    let tol = effective_tol(tol, sa.scale().into_iter().chain(cb.scale()));
    let mut out = Vec::new();
    let la = sa.len();
    if la > tol && cb.r > tol {
        let f = sa.at(sa.project(&cb.c));
        let dist = (f - cb.c).norm();
        let mut cands: Vec<(P2, bool)> = Vec::new();
        if (dist - cb.r).abs() <= tol {
            let on_circle = if dist > 0.0 {
                cb.c + (f - cb.c) * (cb.r / dist)
            } else {
                f
            };
            cands.push((mid(&on_circle, &f), true));
        } else if dist < cb.r {
            let h = (cb.r * cb.r - dist * dist).sqrt();
            let u = sa.d() / la;
            cands.push((f - u * h, false));
            cands.push((f + u * h, false));
        }
        for (x, tangent) in cands {
            if let (Some(t), Some(s)) = (sa.accept(sa.project(&x), tol), cb.accept(&x, tol)) {
                out.push(point(x, t, s, tangent));
            }
        }
    }
    end_touches(&Shape::Seg(sa), &Shape::Circ(cb), tol, &mut out);
    Some(finish(out))
}

/// Intersections of an XY arc (first) and a segment (second): `line_arc`
/// with the parameters swapped and the result sorted along the arc.
pub fn arc_line(a: &Arc3, b: &Line3, tol: f64) -> Option<Vec<Intersection>> {
    line_arc(b, a, tol).map(swap_sorted)
}

/// Hits of (line, arc) seen from the arc: parameters swapped, overlaps
/// turned to the arc's direction, sorted along the arc.
fn swap_sorted(hits: Vec<Intersection>) -> Vec<Intersection> {
    finish(
        hits.iter()
            .map(|i| match i.swapped() {
                Intersection::Overlap { start, end } => Intersection::Overlap { start: end, end: start },
                p => p,
            })
            .collect(),
    )
}

/// Intersections of two XY arcs. Arcs on the same circle (centres and radii
/// within `tol`) give an `Overlap` per shared stretch longer than `tol`
/// (two at most) and a `Point` where they only touch; circles touching
/// within `tol` give one tangent `Point`. `None` when an arc is not in the XY
/// plane, a coordinate is not finite, or `tol` is invalid.
pub fn arc_arc(a: &Arc3, b: &Arc3, tol: f64) -> Option<Vec<Intersection>> {
    circ_circ(Circ::new(a)?, Circ::new(b)?, tol)
}

fn circ_circ(ca: Circ, cb: Circ, tol: f64) -> Option<Vec<Intersection>> {
    if !valid_tol(tol) {
        return None;
    }
    let tol = effective_tol(tol, ca.scale().into_iter().chain(cb.scale()));
    let mut out = Vec::new();
    if ca.r > tol && cb.r > tol {
        let d = (cb.c - ca.c).norm();
        if d <= tol && (ca.r - cb.r).abs() <= tol {
            coincident_overlap(&ca, &cb, tol, &mut out);
        } else if d > 0.0 {
            let u = (cb.c - ca.c) / d;
            let mut cands: Vec<(P2, bool)> = Vec::new();
            if (d - (ca.r + cb.r)).abs() <= tol {
                cands.push((mid(&(ca.c + u * ca.r), &(cb.c - u * cb.r)), true));
            } else if (d - (ca.r - cb.r).abs()).abs() <= tol {
                let s = if ca.r >= cb.r { 1.0 } else { -1.0 };
                cands.push((mid(&(ca.c + u * (s * ca.r)), &(cb.c + u * (s * cb.r))), true));
            } else if d < ca.r + cb.r && d > (ca.r - cb.r).abs() {
                let x = (d * d + ca.r * ca.r - cb.r * cb.r) / (2.0 * d);
                let h = (ca.r * ca.r - x * x).max(0.0).sqrt();
                let m = ca.c + u * x;
                let n = V2::new(-u.y, u.x);
                cands.push((m - n * h, false));
                cands.push((m + n * h, false));
            }
            for (x, tangent) in cands {
                if let (Some(t), Some(s)) = (ca.accept(&x, tol), cb.accept(&x, tol)) {
                    out.push(point(x, t, s, tangent));
                }
            }
        }
    }
    end_touches(&Shape::Circ(ca), &Shape::Circ(cb), tol, &mut out);
    Some(finish(out))
}

/// Shared stretches of two arcs on (nearly) the same circle, worked out as
/// angular intervals in `a`'s counter-clockwise frame.
fn coincident_overlap(ca: &Circ, cb: &Circ, tol: f64, out: &mut Vec<Intersection>) {
    let ang_tol = tol / ca.r;
    let (lo_a, span_a) = ca.ccw_interval();
    let (lo_b, span_b) = cb.ccw_interval();
    let off = normalize_angle(lo_b - lo_a);
    let mut pieces: Vec<(f64, f64)> = Vec::new();
    for s in [off - TAU, off] {
        let x0 = s.max(0.0);
        let x1 = (s + span_b).min(span_a);
        if x1 >= x0 - ang_tol {
            pieces.push((x0, x1));
        }
    }
    pieces.sort_by(|p, q| p.0.total_cmp(&q.0));
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for p in pieces {
        match merged.last_mut() {
            Some(last) if p.0 <= last.1 + ang_tol => last.1 = last.1.max(p.1),
            _ => merged.push(p),
        }
    }
    // On a full circle, a stretch running over the seam at the start is one.
    if span_a >= TAU && merged.len() >= 2 {
        let (first, last) = (merged[0], merged[merged.len() - 1]);
        if first.0 <= ang_tol && last.1 >= TAU - ang_tol {
            merged.pop();
            merged[0] = (last.0, first.1 + TAU);
        }
    }
    let hit = |x: f64| {
        let ang = lo_a + x;
        let pa = ca.c + V2::new(ang.cos(), ang.sin()) * ca.r;
        let v = pa - cb.c;
        let pb = if v.norm() > 0.0 {
            cb.c + v * (cb.r / v.norm())
        } else {
            pa
        };
        let p = mid(&pa, &pb);
        Hit {
            point: p,
            t1: ca.t_of_offset(x),
            t2: cb.closest(&p).1,
        }
    };
    for (x0, x1) in merged {
        if (x1 - x0) * ca.r > tol {
            let (s, e) = if ca.arc.ccw { (x0, x1) } else { (x1, x0) };
            out.push(Intersection::Overlap {
                start: hit(s),
                end: hit(e),
            });
        } else {
            out.push(Intersection::Point {
                hit: hit(0.5 * (x0 + x1)),
                tangent: false,
            });
        }
    }
}

#[cfg(test)]
#[path = "intersect_tests.rs"]
mod tests;
