//! Exact offsets of chains (lines and arcs) through cavalier_contours, which
//! offsets arc polylines exactly and trims self-intersections and loops that
//! collapse.

use crate::geometry::P3;
use crate::geometry::bulge::arc_from_bulge;
use crate::model::chain::{Chain, Segment};
use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline};

/// Which side of a chain the beam centre runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Side {
    /// On the chain itself.
    On,
    /// Inside a closed chain (open chains are cut on the line).
    Inside,
    /// Outside a closed chain (open chains are cut on the line).
    Outside,
    /// Left of the direction of travel.
    Left,
    /// Right of the direction of travel.
    Right,
}

/// The chain's segments as path pieces.
pub fn chain_elems(c: &Chain) -> Vec<Segment> {
    c.segments
        .iter()
        .filter_map(|s| match s {
            Segment::Line(l) => (l.length() > 0.0).then_some(*s),
            Segment::Arc(_) => s.checked(),
        })
        .collect()
}

/// The chain as a cavalier polyline (XY; z is carried separately). A full
/// circle becomes two half arcs because one bulge cannot say a full turn.
pub fn to_polyline(c: &Chain) -> Polyline<f64> {
    let mut pl = Polyline::new();
    for s in &c.segments {
        let start = s.start();
        match s.checked() {
            Some(Segment::Line(_)) => pl.add(start.x, start.y, 0.0),
            None => continue,
            Some(Segment::Arc(arc)) => {
                let sweep = arc.sweep();
                if sweep.abs() > std::f64::consts::PI {
                    // More than a half turn: two halves, so no bulge exceeds 1
                    // (a full circle has no single bulge at all).
                    let mid = arc.point_at(0.5);
                    let b = (sweep / 8.0).tan();
                    pl.add(start.x, start.y, b);
                    pl.add(mid.x, mid.y, b);
                } else {
                    pl.add(start.x, start.y, (sweep / 4.0).tan());
                }
            }
        }
    }
    if c.closed {
        pl.set_is_closed(true);
    } else if let Some(last) = c.segments.last() {
        let e = last.end();
        pl.add(e.x, e.y, 0.0);
    }
    pl
}

/// Largest sagitta (mm) of a polyline arc written as its chord: a
/// nanometre, far below any stage's resolution.
const LINE_SAGITTA: f64 = 1e-6;

/// Largest radius (mm) of a polyline arc kept as an arc: the toolpath
/// reader refuses centres beyond 1e9 mm (no machine means them), and
/// offsets of long, almost straight arcs come out with centres near that
/// (a fill of the corpus drawing Stir_1.dxf had one at 1.08e9 mm, a
/// sagitta of 0.3 nm). Up to a chord of 1 m, the chord of such an arc
/// lies within 1.25 µm of it.
const LINE_RADIUS: f64 = 1e8;

/// Whether the polyline piece of `bulge` over a chord of `chord` mm is
/// written as a line: its sagitta (chord·|bulge|/2) is under
/// [`LINE_SAGITTA`] or its radius (chord·(1 + bulge²)/(4·|bulge|)) over
/// [`LINE_RADIUS`].
fn straight(bulge: f64, chord: f64) -> bool {
    let b = bulge.abs();
    b == 0.0 || 0.5 * chord * b <= LINE_SAGITTA || chord * (1.0 + b * b) > 4.0 * b * LINE_RADIUS
}

/// Polyline back to path pieces at height `z`; arcs all but straight
/// become lines (a sagitta under 1 nm, or a radius over 1e8 mm: the
/// toolpath reader refuses centres beyond 1e9 mm).
pub fn from_polyline(pl: &Polyline<f64>, z: f64) -> Vec<Segment> {
    let n = pl.vertex_count();
    let segs = if pl.is_closed() { n } else { n.saturating_sub(1) };
    let mut out = Vec::with_capacity(segs);
    for i in 0..segs {
        let v = pl.at(i);
        let w = pl.at((i + 1) % n);
        let a = P3::new(v.x, v.y, z);
        let b = P3::new(w.x, w.y, z);
        if (b - a).norm() <= 1e-9 {
            continue;
        }
        if straight(v.bulge, (b - a).norm()) {
            out.push(Segment::line(a, b));
        } else if let Some(arc) = arc_from_bulge(&a, &b, v.bulge) {
            out.push(Segment::Arc(arc));
        } else {
            out.push(Segment::line(a, b));
        }
    }
    // Snap joints exactly: each piece starts where the previous ended.
    for i in 1..out.len() {
        let e = out[i - 1].end();
        out[i].set_start(e);
    }
    out
}

/// Signed area of a closed polyline (positive counter-clockwise).
pub fn signed_area(pl: &Polyline<f64>) -> f64 {
    if pl.is_closed() { pl.area() } else { 0.0 }
}

/// The offset paths of a chain at `dist` on `side`. Several paths when the
/// offset splits a shape; none when it vanishes (the caller warns).
pub fn offset_chain(c: &Chain, side: Side, dist: f64) -> Vec<Vec<Segment>> {
    let z = c.segments.first().map(|s| s.start().z).unwrap_or(0.0);
    let pl = to_polyline(c);
    let area = signed_area(&pl);
    // cavalier offsets positive to the left of travel.
    let signed = match side {
        Side::On => 0.0,
        Side::Left => dist,
        Side::Right => -dist,
        Side::Inside if c.closed => dist * area.signum(),
        Side::Outside if c.closed => -dist * area.signum(),
        Side::Inside | Side::Outside => 0.0,
    };
    if signed == 0.0 || dist == 0.0 {
        return vec![chain_elems(c)];
    }
    let vertices: Vec<P3> = c.segments.iter().map(|s| s.start()).collect();
    pl.parallel_offset(signed)
        .iter()
        .map(|p| miter_joins(from_polyline(p, z), &vertices, dist))
        .filter(|p| !p.is_empty())
        .collect()
}

/// Largest join sweep (radians) turned into one miter point; sharper
/// corners get a bevel, since a miter's length grows as 1/cos(sweep/2).
const MAX_MITER_SWEEP: f64 = 150.0 * std::f64::consts::PI / 180.0;

/// An offset rounds every convex corner with an arc of radius `dist`
/// about the source vertex. At V that arc asks V²/dist of the stage — at
/// a 5 µm beam radius hundreds of times its limit — and dwells the beam on
/// the corner. Replace each such join by the straight extensions of its
/// neighbours meeting at a miter point (a bevel for very sharp corners):
/// the corner then becomes a real corner, and planning loops it with the
/// beam off at constant speed.
fn miter_joins(path: Vec<Segment>, vertices: &[P3], dist: f64) -> Vec<Segment> {
    let is_join = |e: &Segment| match e {
        Segment::Arc(a) => {
            (a.radius() - dist).abs() <= 1e-9 * (1.0 + dist)
                && vertices
                    .iter()
                    .any(|v| (v.xy() - a.center.xy()).norm() <= 1e-9 * (1.0 + dist))
        }
        Segment::Line(_) => false,
    };
    let mut out: Vec<Segment> = Vec::with_capacity(path.len() + 4);
    // A miter's legs extend the lines beside the corner: one block each,
    // not a line and a short collinear stub (a stub shorter than the
    // controller's least acceleration time would be run slower than V).
    let push = |out: &mut Vec<Segment>, e: Segment| match out.last().and_then(|prev| continue_line(prev, &e)) {
        Some(joined) => *out.last_mut().expect("checked above") = joined,
        None => out.push(e),
    };
    for e in &path {
        let Segment::Arc(arc) = e else {
            push(&mut out, *e);
            continue;
        };
        if !is_join(e) {
            push(&mut out, *e);
            continue;
        }
        let (a, b) = (arc.start, arc.end);
        let (ta, tb) = (e.start_tangent(), e.end_tangent());
        let sweep = arc.sweep().abs();
        if sweep <= MAX_MITER_SWEEP {
            // Lines a + s·ta and b - u·tb meet at s = u = dist·tan(sweep/2).
            let s = dist * (0.5 * sweep).tan();
            let m = a + ta * s;
            push(&mut out, Segment::line(a, m));
            push(&mut out, Segment::line(m, b));
        } else {
            let (p, q) = (a + ta * dist, b - tb * dist);
            push(&mut out, Segment::line(a, p));
            push(&mut out, Segment::line(p, q));
            push(&mut out, Segment::line(q, b));
        }
    }
    // The path's first piece may continue its last (a closed offset).
    join_closed_ends(&mut out);
    out
}

/// Join a closed path's last piece into its first when the first goes
/// straight on from it, so the seam is not a block boundary.
pub(super) fn join_closed_ends(out: &mut Vec<Segment>) {
    if out.len() > 2
        && let (Some(last), Some(first)) = (out.last(), out.first())
        && let Some(joined) = continue_line(last, first)
    {
        out.pop();
        out[0] = joined;
    }
}

/// `a` then `b` as one line, when both are lines and `b` goes straight on
/// from where `a` ends.
pub(super) fn continue_line(a: &Segment, b: &Segment) -> Option<Segment> {
    let (Segment::Line(a), Segment::Line(b)) = (a, b) else {
        return None;
    };
    let (d0, d1) = (a.end - a.start, b.end - b.start);
    let (n0, n1) = (d0.norm(), d1.norm());
    (a.end == b.start && n0 > 0.0 && n1 > 0.0 && d0.cross(&d1).norm() <= 1e-12 * n0 * n1 && d0.dot(&d1) > 0.0)
        .then(|| Segment::line(a.start, b.end))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(cw: bool) -> Chain {
        let p = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)];
        let mut pts: Vec<P3> = p.iter().map(|&(x, y)| P3::new(x, y, 0.0)).collect();
        if cw {
            pts.reverse();
        }
        let segments = (0..4).map(|i| Segment::line(pts[i], pts[(i + 1) % 4])).collect();
        Chain {
            id: 1,
            closed: true,
            segments,
            ..Default::default()
        }
    }

    /// Distance from `p` to the nearest point of a square [0,2]² boundary.
    fn dist_to_square(p: &P3) -> f64 {
        let dx = (p.x - p.x.clamp(0.0, 2.0)).abs();
        let dy = (p.y - p.y.clamp(0.0, 2.0)).abs();
        if dx > 0.0 || dy > 0.0 {
            dx.hypot(dy)
        } else {
            p.x.min(2.0 - p.x).min(p.y).min(2.0 - p.y)
        }
    }

    #[test]
    fn square_offsets_keep_their_distance_both_orientations() {
        for cw in [false, true] {
            for (side, d) in [(Side::Outside, 0.3), (Side::Inside, 0.3)] {
                let paths = offset_chain(&square(cw), side, d);
                assert_eq!(paths.len(), 1);
                for e in &paths[0] {
                    for k in 0..=20 {
                        let p = e.point_at_length(e.length() * k as f64 / 20.0);
                        // Along the sides the distance is d; at a miter it
                        // grows to d·√2 at the corner point.
                        let dd = dist_to_square(&p);
                        let on_side = (dd - d).abs() < 1e-9;
                        let in_miter = side == Side::Outside && dd > d && dd <= d * 2f64.sqrt() + 1e-9;
                        assert!(on_side || in_miter, "{side:?} cw={cw} at {p:?}: {dd}");
                        let inside = p.x > 0.0 && p.x < 2.0 && p.y > 0.0 && p.y < 2.0;
                        assert_eq!(inside, side == Side::Inside);
                    }
                }
                // Outside corners are mitred: 4 corners at distance d·√2.
                if side == Side::Outside {
                    let corners = paths[0]
                        .iter()
                        .filter(|e| (dist_to_square(&e.end()) - d * 2f64.sqrt()).abs() < 1e-9);
                    assert_eq!(corners.count(), 4);
                }
            }
        }
    }

    #[test]
    fn an_inside_offset_larger_than_the_shape_vanishes() {
        assert!(offset_chain(&square(false), Side::Inside, 1.2).is_empty());
    }

    #[test]
    fn a_full_circle_offsets_to_a_circle() {
        let c = Chain {
            id: 2,
            closed: true,
            segments: vec![Segment::arc_xy(
                P3::new(1.0, 0.0, 0.5),
                P3::new(1.0, 0.0, 0.5),
                P3::origin(),
                false,
            )],
            ..Default::default()
        };
        let paths = offset_chain(&c, Side::Outside, 0.25);
        assert_eq!(paths.len(), 1);
        let len: f64 = paths[0].iter().map(Segment::length).sum();
        assert!((len - std::f64::consts::TAU * 1.25).abs() < 1e-9);
        for e in &paths[0] {
            let p = e.point_at_length(0.3 * e.length());
            assert!((p.coords.xy().norm() - 1.25).abs() < 1e-9);
            assert_eq!(p.z, 0.5);
        }
    }

    #[test]
    fn all_but_straight_arcs_come_back_as_lines() {
        // (chord mm, bulge, line expected). The second is the arc a fill
        // of Stir_1.dxf made: a 64 mm chord with its centre 1.4e9 mm away.
        let cases = [
            (1.0, 0.1, false),
            (64.0, 64.0 / (4.0 * 1.4e9), true),
            (64.0, 1e-6, false),
            (64.0, 1e-7, true),
            (500.0, 500.0 / (4.0 * 2e8), true),
            (500.0, 500.0 / (4.0 * 5e7), false),
            (0.01, 1e-5, true),
        ];
        for (c, b, line) in cases {
            let mut pl = Polyline::new();
            pl.add(0.0, 0.0, b);
            pl.add(c, 0.0, 0.0);
            let out = from_polyline(&pl, 0.0);
            assert_eq!(out.len(), 1);
            assert_eq!(
                matches!(out[0], Segment::Line(_)),
                line,
                "chord {c} bulge {b}: {:?}",
                out[0]
            );
            assert_eq!((out[0].start(), out[0].end()), (P3::origin(), P3::new(c, 0.0, 0.0)));
            if line {
                // The chord lies within the stated bound of the arc.
                let sagitta = 0.5 * c * b;
                assert!(
                    sagitta <= LINE_SAGITTA || (c <= 1000.0 && sagitta <= 1.25e-3),
                    "{sagitta}"
                );
            } else if let Segment::Arc(a) = out[0] {
                assert!(a.radius() <= LINE_RADIUS && a.center.x.abs() < 1e9 && a.center.y.abs() < 1e9);
            }
        }
    }
}
