//! Curves to tangent-continuous arcs: each span between two points becomes
//! a biarc (two arcs meeting tangentially, matching the tangent estimates at
//! both points) or a single arc leaving along the incoming tangent, so the
//! whole fit has continuous tangents — no corner loops, no speed changes —
//! and far fewer blocks than a polyline at the same tolerance. Sharp corners
//! in the input are kept as corners. docs/arcfit.md compares it with the
//! curvature matching of Bayesteh (2013) ([`super::arcfit_seed`]).

use crate::geometry::Segment;
use crate::geometry::arc::Arc3;
use crate::geometry::line::point_segment_distance;
use crate::geometry::{P2, P3, Plane, V2};
use std::f64::consts::TAU;

mod deviation;
pub use deviation::{Grid, deviation_within, elem_box, max_deviation, point_deviation, trace_elem, work_done};
use deviation::{Probe, all_within};

fn lift(p: &P2, z: f64) -> P3 {
    P3::new(p.x, p.y, z)
}

fn perp(v: &V2) -> V2 {
    V2::new(-v.y, v.x)
}

/// The arc (or line) leaving `p` along unit tangent `t` and ending at `q`.
pub(crate) fn arc_from_tangent(p: P2, t: V2, q: P2, z: f64) -> Segment {
    let d = q - p;
    let n = perp(&t);
    let dn = d.dot(&n);
    // Nearly straight: a line is exact within 1e-12 of a radius-1e9 arc.
    if dn.abs() <= 1e-12 * d.norm_squared().max(1e-300).sqrt() || d.norm_squared() / (2.0 * dn.abs()) > 1e9 {
        return Segment::line(lift(&p, z), lift(&q, z));
    }
    let rho = d.norm_squared() / (2.0 * dn);
    let c = p + n * rho;
    match Arc3::new(lift(&c, z), lift(&p, z), lift(&q, z), rho > 0.0, Plane::Xy, 0) {
        Some(a) => Segment::Arc(a),
        None => Segment::line(lift(&p, z), lift(&q, z)),
    }
}

/// Points from text: one `x y` (or `x,y`) per line, `#` starts a comment,
/// blank lines are skipped. An error names the 1-based line.
pub fn parse_points(text: &str) -> Result<Vec<P2>, (usize, &'static str)> {
    let mut pts = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or((i + 1, "expected numbers 'x y'"))?;
        // Beyond a kilometre nothing here is a drawing any stage can cut,
        // and squared distances would overflow into infinities.
        if v.iter().any(|x| x.abs() > 1e9) {
            return Err((i + 1, "coordinate beyond ±1e9 mm"));
        }
        if v.len() < 2 {
            return Err((i + 1, "expected 'x y'"));
        }
        pts.push(P2::new(v[0], v[1]));
    }
    Ok(pts)
}

/// Two arcs from `p0` (unit tangent `t0`) to `p1` (unit tangent `t1`),
/// tangent to each other at their joint (the equal-parameter biarc).
pub fn biarc(p0: P2, t0: V2, p1: P2, t1: V2, z: f64) -> Vec<Segment> {
    let v = p1 - p0;
    if v.norm() < 1e-12 {
        return Vec::new();
    }
    let t = t0 + t1;
    let denom = 2.0 * (1.0 - t0.dot(&t1));
    let vt = v.dot(&t);
    let d = if denom.abs() < 1e-12 {
        let vt1 = v.dot(&t1);
        if vt1.abs() < 1e-12 {
            // Tangents parallel and across the chord: no finite biarc.
            return vec![Segment::line(lift(&p0, z), lift(&p1, z))];
        }
        v.norm_squared() / (4.0 * vt1)
    } else {
        (-vt + (vt * vt + denom * v.norm_squared()).sqrt()) / denom
    };
    let j = P2::from((p0.coords + p1.coords + (t0 - t1) * d) * 0.5);
    let a = arc_from_tangent(p0, t0, j, z);
    // The joint's tangent is the first arc's end tangent.
    let tj = a.end_tangent().xy();
    let tj = if tj.norm() > 0.0 { tj.normalize() } else { v.normalize() };
    let b = arc_from_tangent(j, tj, p1, z);
    let mut out = Vec::with_capacity(2);
    for e in [a, b] {
        if e.length() > 1e-12 {
            out.push(e);
        }
    }
    out
}

/// Distance from `p` to a piece (XY).
pub fn dist_to_elem(p: &P2, e: &Segment) -> f64 {
    let q = P3::new(p.x, p.y, e.start().z);
    match e {
        Segment::Line(l) => l.distance(&q),
        Segment::Arc(a) => a.distance(&q).unwrap_or(f64::INFINITY),
    }
}

fn dist_to_polyline(p: &P2, pts: &[P2]) -> f64 {
    pts.windows(2)
        .map(|w| point_segment_distance(p, &w[0], &w[1]))
        .fold(f64::INFINITY, f64::min)
}

/// Unit tangent at `a` of the circle through `a`, `b`, `c`, pointing the
/// way `a` → `b` runs (the chord direction when the three are collinear).
fn circle_tangent(a: P2, b: P2, c: P2) -> V2 {
    let (ab, ac) = (b - a, c - a);
    let chord = ab.normalize();
    let cross = ab.perp(&ac);
    let (lab2, lac2) = (ab.norm_squared(), ac.norm_squared());
    // Collinear (or NaN): the chord.
    if cross.abs().partial_cmp(&(1e-12 * (lab2 * lac2).sqrt())) != Some(std::cmp::Ordering::Greater) {
        return chord;
    }
    // Centre relative to a; the tangent is the radius turned a quarter.
    let u = V2::new(ac.y * lab2 - ab.y * lac2, ab.x * lac2 - ac.x * lab2) / (2.0 * cross);
    let t = perp(&u);
    let t = if t.dot(&ab) < 0.0 { -t } else { t };
    if t.norm() > 0.0 { t.normalize() } else { chord }
}

/// Tangent estimates at each point: the direction of the circle through it
/// and its neighbours (exact for points on a circle). At the ends of an open
/// sequence, the tangent of the circle through the last three points (the
/// chord direction for two points); a closed sequence (last point = first)
/// wraps round instead.
pub fn tangents(pts: &[P2]) -> Vec<V2> {
    let n = pts.len();
    let closed = n >= 4 && (pts[n - 1] - pts[0]).norm() <= 1e-12;
    let bessel = |prev: P2, p: P2, next: P2| {
        let (a, b) = (p - prev, next - p);
        let (la, lb) = (a.norm(), b.norm());
        // Weighted so that the tangent of a circle through the three
        // points comes out exactly (Bessel's tangent).
        let t = a * (lb / la) + b * (la / lb);
        if t.norm() > 0.0 { t.normalize() } else { b.normalize() }
    };
    (0..n)
        .map(|i| {
            if n < 2 {
                return V2::x();
            }
            if n == 2 {
                return (pts[1] - pts[0]).normalize();
            }
            if closed && (i == 0 || i == n - 1) {
                return bessel(pts[n - 2], pts[0], pts[1]);
            }
            if i == 0 {
                return circle_tangent(pts[0], pts[1], pts[2]);
            }
            if i == n - 1 {
                return -circle_tangent(pts[n - 1], pts[n - 2], pts[n - 3]);
            }
            bessel(pts[i - 1], pts[i], pts[i + 1])
        })
        .collect()
}

/// Consecutive pieces on one circle (centres and radii within `eps`, same
/// sense, less than a turn together) or one line become one piece: a biarc
/// between two points of a circle with the circle's tangents is two arcs of
/// that circle.
fn merge_pieces(pieces: Vec<Segment>, eps: f64) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::with_capacity(pieces.len());
    for e in pieces {
        let merged = match (out.last(), &e) {
            (Some(Segment::Arc(a)), Segment::Arc(b))
                if a.ccw == b.ccw
                    && a.plane == b.plane
                    && a.rise() == 0.0
                    && b.rise() == 0.0
                    && a.extra_turns == 0
                    && b.extra_turns == 0
                    && (a.center - b.center).norm() + (a.radius() - b.radius()).abs() <= eps =>
            {
                let sweep = a.sweep().abs() + b.sweep().abs();
                Arc3::new(a.center, a.start, b.end, a.ccw, a.plane, 0)
                    .filter(|m| sweep < TAU - 1e-6 && (m.sweep().abs() - sweep).abs() <= 1e-9)
                    .map(Segment::Arc)
            }
            (Some(Segment::Line(a)), Segment::Line(b)) => {
                let (d, j) = (b.end - a.start, a.end - a.start);
                let off = d.cross(&j).norm() / d.norm().max(1e-300);
                (off <= eps && d.dot(&j) > 0.0 && (b.end - a.end).dot(&j) > 0.0).then(|| Segment::line(a.start, b.end))
            }
            _ => None,
        };
        match merged {
            Some(m) => *out.last_mut().expect("merged with the last piece") = m,
            None => out.push(e),
        }
    }
    out
}

/// Indices of the points where the sequence turns a corner: the chords
/// either side turn by more than 20° and by more than four times the turn
/// at either neighbouring point (a coarse polygon of a smooth curve turns
/// evenly and has none).
fn corners(pts: &[P2]) -> Vec<usize> {
    let n = pts.len();
    if n < 3 {
        return Vec::new();
    }
    let turn = |k: usize| {
        if k == 0 || k + 1 >= n {
            return 0.0;
        }
        let (a, b) = (pts[k] - pts[k - 1], pts[k + 1] - pts[k]);
        a.perp(&b).atan2(a.dot(&b)).abs()
    };
    (1..n - 1)
        .filter(|&k| {
            let t = turn(k);
            t > 20f64.to_radians() && t > 4.0 * turn(k - 1).max(turn(k + 1))
        })
        .collect()
}

/// Caps on a single arc's end-tangent error, in units of tol / span chord
/// (0: biarcs only). Each is tried and the fit with fewest blocks is kept.
const SINGLE_ARC_CAPS: [f64; 4] = [0.0, 4.0, 8.0, 16.0];

/// One tangent-continuous chain through `pts` (no corners inside).
fn fit_chain(pts: &[P2], tol: f64, z: f64, polyline: bool, cap: f64, eps: f64) -> Vec<Segment> {
    let tan = tangents(pts);
    // Quarter points of each interval on the cubic Hermite curve through
    // the points with their tangent estimates: where the smooth curve the
    // points sample most likely runs between them.
    let mids: Vec<P2> = pts
        .windows(2)
        .zip(tan.windows(2))
        .flat_map(|(p, t)| {
            let (m0, m1) = (t[0] * (p[1] - p[0]).norm(), t[1] * (p[1] - p[0]).norm());
            [0.25, 0.5, 0.75].map(|u: f64| {
                let (u2, u3) = (u * u, u * u * u);
                let (h00, h10, h01, h11) = (
                    2.0 * u3 - 3.0 * u2 + 1.0,
                    u3 - 2.0 * u2 + u,
                    3.0 * u2 - 2.0 * u3,
                    u3 - u2,
                );
                P2::from(p[0].coords * h00 + m0 * h10 + p[1].coords * h01 + m1 * h11)
            })
        })
        .collect();
    // 32 samples per arc, with 5 % margin, keeps the dense check (which
    // samples far finer) within tol.
    let limit = 0.95 * tol;
    // Polyline length up to each point.
    let cum: Vec<f64> = std::iter::once(0.0)
        .chain(pts.windows(2).scan(0.0, |acc, w| {
            *acc += (w[1] - w[0]).norm();
            Some(*acc)
        }))
        .collect();
    let within = |f: &[Segment], i: usize, j: usize| {
        if polyline {
            return deviation_within(f, &pts[i..=j], 32, limit);
        }
        // The point checks are one-sided: a loop out and back through the
        // points passes them. A fit of a curve the points sample is no
        // longer than their polyline, bar the sagitta terms: refuse one
        // that is longer by a tenth.
        if f.iter().map(Segment::length).sum::<f64>() > 1.1 * (cum[j] - cum[i]) + 2.0 * tol {
            return false;
        }
        let probes: Vec<Probe> = f.iter().map(Probe::new).collect();
        all_within(&probes, &pts[i..=j], limit) && all_within(&probes, &mids[3 * i..3 * j], limit)
    };
    // The longest span from i that `try_fit` accepts (i + 1 is always
    // taken, with `fallback` when nothing fits).
    let longest = |i: usize, try_fit: &dyn Fn(usize) -> Option<Vec<Segment>>, fallback: Vec<Segment>| {
        let mut good = i + 1;
        let mut best = try_fit(good).unwrap_or(fallback);
        let mut step = 1;
        let mut bad = None;
        while good < pts.len() - 1 {
            // Gallop, the last try clipped to the last point.
            let next = (good + step).min(pts.len() - 1);
            match try_fit(next) {
                Some(f) => {
                    good = next;
                    best = f;
                    step *= 2;
                }
                None => {
                    bad = Some(next);
                    break;
                }
            }
        }
        if let Some(mut hi) = bad {
            while hi - good > 1 {
                let mid = (good + hi) / 2;
                match try_fit(mid) {
                    Some(f) => {
                        good = mid;
                        best = f;
                    }
                    None => hi = mid,
                }
            }
        }
        (good, best)
    };
    let mut out = Vec::new();
    let mut i = 0;
    let mut t_in = tan[0];
    while i < pts.len() - 1 {
        let two = |j: usize| {
            let f = merge_pieces(biarc(pts[i], t_in, pts[j], tan[j], z), eps);
            within(&f, i, j).then_some(f)
        };
        // A single arc leaving along t_in, while its end tangent stays
        // within cap·tol/chord of the estimate there (so the error it hands
        // on stays bounded).
        let one = |j: usize| {
            let e = arc_from_tangent(pts[i], t_in, pts[j], z);
            let te = e.end_tangent().xy();
            let err = te.perp(&tan[j]).atan2(te.dot(&tan[j])).abs();
            let f = vec![e];
            (err <= cap * tol / (pts[j] - pts[i]).norm() && within(&f, i, j)).then_some(f)
        };
        // Nothing fits even the next point: the biarc to it anyway (it
        // passes through both points; only the midpoint estimate is missed)
        // or, against a polyline, the polyline's own piece.
        // On noise the tangent estimates point anywhere, and a biarc whose
        // two tangents both point back along the chord swings out by
        // metres; then the biarc that arrives along the chord (it turns
        // once, within about the chord) is taken when it is shorter.
        let next = if polyline {
            vec![Segment::line(lift(&pts[i], z), lift(&pts[i + 1], z))]
        } else {
            let b = merge_pieces(biarc(pts[i], t_in, pts[i + 1], tan[i + 1], z), eps);
            let chord = (pts[i + 1] - pts[i]).norm();
            let len = |f: &[Segment]| f.iter().map(Segment::length).sum::<f64>();
            if len(&b) > 1.1 * chord + 2.0 * tol {
                let c = merge_pieces(biarc(pts[i], t_in, pts[i + 1], (pts[i + 1] - pts[i]) / chord, z), eps);
                if len(&c) < len(&b) { c } else { b }
            } else {
                b
            }
        };
        let (jb, fb) = longest(i, &two, next);
        let (ja, fa) = if cap > 0.0 && one(i + 1).is_some() {
            longest(i, &one, Vec::new())
        } else {
            (i, Vec::new())
        };
        // More points per block wins; a tie keeps the biarc, which meets
        // the tangent estimate at its end.
        let (j, f) = if !fa.is_empty() && (ja - i) * fb.len() > (jb - i) * fa.len() {
            (ja, fa)
        } else {
            (jb, fb)
        };
        if let Some(e) = f.last() {
            let d = e.end_tangent().xy();
            t_in = if d.norm() > 0.0 { d.normalize() } else { tan[j] };
        }
        out.extend(f);
        i = j;
    }
    merge_pieces(out, eps)
}

/// Fit tangent-continuous arcs to a point sequence within `tol`.
///
/// Spans grow greedily (galloping, then bisection) while the pieces over
/// them stay within `tol` of every point in between and of the midpoints of
/// the cubic Hermite curve through the points with their tangent estimates
/// (the points are samples of an unknown smooth curve) or, when `polyline`
/// is set, of every polyline piece both ways (the polyline is the shape).
/// Each span is a biarc (meeting the next point's tangent estimate) or a
/// single arc (its end-tangent error capped), whichever covers more points
/// per block; every piece leaves in the direction the previous one arrived.
/// Several caps are tried (0: biarcs only) and the fit with the fewest
/// blocks kept. Pieces on one circle are merged. Sharp corners in the points
/// (where the chords turn by more than 20° and by more than four times the
/// turn at either neighbouring point) are kept: the fit is
/// tangent-continuous between them.
pub fn fit_points(pts: &[P2], tol: f64, z: f64, polyline: bool) -> Vec<Segment> {
    let mut clean: Vec<P2> = Vec::with_capacity(pts.len());
    for p in pts {
        if clean.last().is_none_or(|q: &P2| (p - q).norm() > 1e-12) {
            clean.push(*p);
        }
    }
    let pts = clean;
    if pts.len() < 2 {
        return Vec::new();
    }
    // Pieces on one circle within this are merged (the merge moves the path
    // by at most this much).
    let eps = 1e-2 * tol.abs().min(1.0);
    let mut cuts = vec![0];
    cuts.extend(corners(&pts));
    cuts.push(pts.len() - 1);
    let mut out = Vec::new();
    for w in cuts.windows(2) {
        let part = &pts[w[0]..=w[1]];
        let best = SINGLE_ARC_CAPS
            .iter()
            .map(|&cap| fit_chain(part, tol, z, polyline, cap, eps))
            .min_by_key(Vec::len)
            .unwrap_or_default();
        out.extend(best);
    }
    merge_pieces(out, eps)
}

#[cfg(test)]
mod tests;
