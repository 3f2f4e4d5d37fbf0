//! Cleaning a cut path before planning: pieces a Turbo PMAC cannot run at
//! V (shorter than V·1 ms, its least TA, plus the writer's rounding) are
//! merged into their neighbours or refitted, with the deviation from the
//! path as given bounded by a tolerance and measured.
//!
//! Offsetting a polyline of many short pieces leaves such slivers: mitre
//! legs of a few nanometres where a convex join turned by a fraction of a
//! degree, trimmed stubs where concave pieces intersect, bevels at sharp
//! corners. Planned as they are, each becomes a block the controller
//! stretches to its TA, slowing the stage with the shutter open.
//!
//! Each short piece `s`, with its neighbours `a` (before) and `b` (after),
//! is replaced by the candidate that moves the path least, among:
//!
//! - `a` and `s` as one piece from `a`'s start to `s`'s end (a line, or an
//!   arc leaving along `a`'s start tangent): lines collinear within the
//!   tolerance are joined;
//! - `s` and `b` as one piece, likewise;
//! - `a`, `s` and `b` as one biarc keeping the tangents at both outer
//!   ends (the arc fit's biarc, [`super::arcfit::biarc`]): a run of short
//!   pieces along a curve becomes arcs, tangent to what is around it;
//! - `s` collapsed to a point (its midpoint, or where the lines of `a` and
//!   `b` meet), `a` and `b` retargeted there.
//!
//! A candidate is taken only when every piece it makes is at least as long
//! as the short piece it removes (so the loop ends) and its deviation is
//! within the tolerance. The deviation of a candidate is measured by
//! sampling the old pieces against the new and the new against the old,
//! both ways, and added to what the old pieces already carried, so the
//! reported figure bounds the distance from the path as given. Pieces that
//! no candidate removes within the tolerance are left and counted.

use super::arcfit::{arc_from_tangent, biarc, dist_to_elem};
use crate::geometry::Segment;
use crate::geometry::arc::ArcFrame;
use crate::geometry::segment::length_fraction;
use crate::geometry::{P2, P3, Plane};

/// What the cleanup does: pieces shorter than `min_len` (mm) are removed
/// when that moves the path by at most `tol` (mm). `tol` 0 turns it off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CleanOptions {
    /// The least block (mm): V·1 ms plus the writer's rounding margin.
    pub min_len: f64,
    /// Largest deviation from the path as given (mm); 0 turns the cleanup
    /// off.
    pub tol: f64,
}

/// What the cleanup did, summed over paths.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CleanStats {
    /// Pieces shorter than the least block before cleaning.
    pub short: usize,
    /// Of those, how many are still there (no candidate within the tolerance).
    pub left: usize,
    /// Pieces before cleaning.
    pub pieces_in: usize,
    /// Pieces after cleaning.
    pub pieces_out: usize,
    /// Largest deviation from the path as given (mm, a bound measured by
    /// sampling, see the module documentation).
    pub max_dev: f64,
}

impl CleanStats {
    /// Sum another path's figures into these (the deviation is the larger
    /// of the two).
    pub fn add(&mut self, o: &CleanStats) {
        self.short += o.short;
        self.left += o.left;
        self.pieces_in += o.pieces_in;
        self.pieces_out += o.pieces_out;
        self.max_dev = self.max_dev.max(o.max_dev);
    }
}

/// Samples per piece when measuring a candidate's deviation.
const SAMPLES: usize = 16;

/// A piece and the deviation it already carries from the path as given.
#[derive(Debug, Clone, Copy)]
struct Item {
    e: Segment,
    err: f64,
}

/// Whether the piece lies in one XY plane at height `z` (cleanup works in
/// XY; anything else is left as it is).
fn flat(e: &Segment, z: f64) -> bool {
    let level = e.start().z == z && e.end().z == z;
    match e {
        Segment::Line(_) => level,
        Segment::Arc(a) => level && a.plane == Plane::Xy && a.extra_turns == 0 && a.rise() == 0.0,
    }
}

/// `e` with its end moved to `p`: a line, or an arc leaving along `e`'s
/// start tangent (so a tangent joint before it stays tangent).
fn retarget_end(e: &Segment, p: P3) -> Segment {
    match e {
        Segment::Line(l) => Segment::line(l.start, p),
        Segment::Arc(a) => arc_from_tangent(a.start.xy(), e.start_tangent().xy(), p.xy(), a.start.z),
    }
}

/// `e` with its start moved to `p` (the mirror of [`retarget_end`]).
fn retarget_start(e: &Segment, p: P3) -> Segment {
    retarget_end(&e.reversed(), p).reversed()
}

fn samples(es: &[Probe]) -> impl Iterator<Item = P2> + '_ {
    es.iter().flat_map(|e| {
        let len = e.len;
        (0..=SAMPLES).map(move |k| e.point_at_length(len * k as f64 / SAMPLES as f64).xy())
    })
}

/// A piece ready to be sampled and measured against: its length and, for
/// an arc, its angles, worked out once (they are asked for at every one
/// of a few hundred samples per candidate). The same numbers as
/// `Segment::point_at_length` and `dist_to_elem`, bit for bit.
struct Probe {
    e: Segment,
    len: f64,
    arc: Option<ArcFrame>,
}

impl Probe {
    fn new(e: &Segment) -> Probe {
        Probe {
            e: *e,
            len: e.length(),
            arc: match e {
                Segment::Arc(a) => Some(ArcFrame::new(a)),
                Segment::Line(_) => None,
            },
        }
    }

    /// `Segment::point_at_length`.
    fn point_at_length(&self, s: f64) -> P3 {
        let t = length_fraction(s, self.len);
        match &self.arc {
            Some(f) => f.point_at(t),
            None => self.e.point_at(t),
        }
    }

    /// `dist_to_elem`.
    fn distance(&self, p: &P2) -> f64 {
        match &self.arc {
            Some(f) => f
                .distance(&P3::new(p.x, p.y, self.e.start().z))
                .unwrap_or(f64::INFINITY),
            None => dist_to_elem(p, &self.e),
        }
    }
}

/// Hausdorff distance (sampled) between two runs of pieces with the same
/// ends; `None` as soon as a sample shows that the distance plus `carried`
/// fails `keep` (which must hold for every value up to some bound and
/// fail past it, so the running maximum can stop early: the candidates
/// that lose are most of those measured).
fn deviation(old: &[Segment], new: &[Segment], carried: f64, keep: impl Fn(f64) -> bool) -> Option<f64> {
    let (old, new): (Vec<Probe>, Vec<Probe>) = (
        old.iter().map(Probe::new).collect(),
        new.iter().map(Probe::new).collect(),
    );
    let near = |p: P2, to: &[Probe]| to.iter().map(|e| e.distance(&p)).fold(f64::INFINITY, f64::min);
    let mut m = 0.0f64;
    for p in samples(&old) {
        m = m.max(near(p, &new));
        if !keep(m + carried) {
            return None;
        }
    }
    for p in samples(&new) {
        m = m.max(near(p, &old));
        if !keep(m + carried) {
            return None;
        }
    }
    Some(m + carried)
}

/// Where the lines through `a` (its end tangent) and `b` (its start
/// tangent) meet, if they do.
fn meet(a: &Segment, b: &Segment) -> Option<P3> {
    let (p, u) = (a.end().xy(), a.end_tangent().xy());
    let (q, v) = (b.start().xy(), b.start_tangent().xy());
    let den = u.perp(&v);
    if den.abs() < 1e-9 {
        return None;
    }
    let t = (q - p).perp(&v) / den;
    let m = p + u * t;
    m.x.is_finite().then(|| P3::new(m.x, m.y, a.end().z))
}

/// The replacements for `old` (2 or 3 pieces, the short one at `s`), best
/// first is chosen by the caller.
fn candidates(old: &[Segment], s: usize) -> Vec<(usize, usize, Vec<Segment>)> {
    // (first old index replaced, count replaced, new pieces)
    let mut out = Vec::new();
    let sh = old[s];
    if s > 0 {
        let a = old[s - 1];
        out.push((s - 1, 2, vec![retarget_end(&a, sh.end())]));
    }
    if s + 1 < old.len() {
        let b = old[s + 1];
        out.push((s, 2, vec![retarget_start(&b, sh.start())]));
    }
    if s > 0 && s + 1 < old.len() {
        let (a, b) = (old[s - 1], old[s + 1]);
        let z = a.start().z;
        let p0 = a.start().xy();
        let p1 = b.end().xy();
        let (t0, t1) = (a.start_tangent().xy(), b.end_tangent().xy());
        if t0.norm() > 0.0 && t1.norm() > 0.0 {
            let f = biarc(p0, t0.normalize(), p1, t1.normalize(), z);
            if !f.is_empty() {
                out.push((s - 1, 3, f));
            }
        }
        if let (Segment::Line(_), Segment::Line(_)) = (a, b) {
            out.push((s - 1, 3, vec![Segment::line(a.start(), b.end())]));
        }
        let mid = sh.point_at_length(0.5 * sh.length());
        for m in [Some(mid), meet(&a, &b)].into_iter().flatten() {
            out.push((s - 1, 3, vec![retarget_end(&a, m), retarget_start(&b, m)]));
        }
    }
    out
}

/// Try to remove the short piece at `items[s]` (looking at one neighbour
/// each side). Returns whether it was removed.
fn fix(items: &mut Vec<Item>, s: usize, o: &CleanOptions) -> bool {
    let lo = s.saturating_sub(1);
    let hi = (s + 2).min(items.len());
    let z = items[s].e.start().z;
    if !items[lo..hi].iter().all(|it| flat(&it.e, z)) {
        return false;
    }
    let old: Vec<Segment> = items[lo..hi].iter().map(|it| it.e).collect();
    let short_len = items[s].e.length();
    let mut best: Option<(f64, usize, usize, Vec<Segment>)> = None;
    for (first, count, new) in candidates(&old, s - lo) {
        // Joined ends stay where they were.
        let (Some(n0), Some(n1)) = (new.first(), new.last()) else {
            continue;
        };
        if (n0.start() - old[first].start()).norm() > 1e-9 || (n1.end() - old[first + count - 1].end()).norm() > 1e-9 {
            continue;
        }
        if new.iter().any(|e| e.length() <= short_len || !e.length().is_finite()) {
            continue;
        }
        let carried = items[lo + first..lo + first + count]
            .iter()
            .map(|it| it.err)
            .fold(0.0, f64::max);
        // Within the tolerance and better than the best so far; both
        // tests only fail more as the running maximum grows.
        let keep = |dev: f64| dev <= o.tol && best.as_ref().is_none_or(|b| dev < b.0);
        if let Some(dev) = deviation(&old[first..first + count], &new, carried, keep) {
            best = Some((dev, first, count, new));
        }
    }
    let Some((dev, first, count, mut new)) = best else {
        return false;
    };
    // Snap the joins exactly.
    let at = lo + first;
    if let Some(n) = new.first_mut() {
        n.set_start(items[at].e.start());
    }
    if let Some(n) = new.last_mut() {
        n.set_end(items[at + count - 1].e.end());
    }
    items.splice(at..at + count, new.into_iter().map(|e| Item { e, err: dev }));
    true
}

/// Clean one path (continuous; `closed` when it ends where it starts).
pub fn clean_path(path: Vec<Segment>, closed: bool, o: &CleanOptions) -> (Vec<Segment>, CleanStats) {
    let short = |e: &Segment| e.length() < o.min_len;
    let mut st = CleanStats {
        short: path.iter().filter(|e| short(e)).count(),
        pieces_in: path.len(),
        ..Default::default()
    };
    if st.short == 0 || o.tol.is_nan() || o.tol <= 0.0 || path.len() < 2 {
        st.left = st.short;
        st.pieces_out = path.len();
        return (path, st);
    }
    let mut path = path;
    if closed {
        // Start at the longest piece, so the seam is never a sliver; a
        // short piece at the end then has the first as its next neighbour.
        let k = (0..path.len())
            .max_by(|&a, &b| path[a].length().total_cmp(&path[b].length()).then(b.cmp(&a)))
            .unwrap_or(0);
        path.rotate_left(k);
    }
    let mut items: Vec<Item> = path.into_iter().map(|e| Item { e, err: 0.0 }).collect();
    // One pass front to back; a fix shortens the list, so the index steps
    // back one to look at the merged piece again.
    let mut i = 0;
    while i < items.len() {
        if short(&items[i].e) && items.len() > 1 {
            if closed && i + 1 == items.len() && items.len() >= 3 {
                // The last piece: its next neighbour is the first. Any
                // rotation of a closed path is the same path.
                items.rotate_right(2);
                if fix(&mut items, 1, o) {
                    break;
                }
                items.rotate_left(2);
                i += 1;
                continue;
            }
            if fix(&mut items, i, o) {
                i = i.saturating_sub(1);
                continue;
            }
        }
        i += 1;
    }
    st.left = items.iter().filter(|it| short(&it.e)).count();
    st.max_dev = items.iter().map(|it| it.err).fold(0.0, f64::max);
    st.pieces_out = items.len();
    (items.into_iter().map(|it| it.e).collect(), st)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::V3;

    fn poly(pts: &[(f64, f64)]) -> Vec<Segment> {
        pts.windows(2)
            .map(|w| Segment::line(P3::new(w[0].0, w[0].1, 0.0), P3::new(w[1].0, w[1].1, 0.0)))
            .collect()
    }

    fn continuous(p: &[Segment]) {
        for w in p.windows(2) {
            assert_eq!(w[0].end(), w[1].start());
        }
    }

    const O: CleanOptions = CleanOptions {
        min_len: 0.0022,
        tol: 0.001,
    };

    #[test]
    fn nanometre_mitre_legs_join_their_lines() {
        // Two 0.1 mm lines turning by 0.2°, with two 8 nm mitre legs.
        let d = 0.2f64.to_radians();
        let a = P3::new(0.0, 0.0, 0.0);
        let m = P3::new(0.1, 0.0, 0.0);
        let l1 = m + V3::new(8e-6, 0.0, 0.0);
        let l2 = l1 + V3::new(d.cos(), d.sin(), 0.0) * 8e-6;
        let e = l2 + V3::new(d.cos(), d.sin(), 0.0) * 0.1;
        let path = vec![
            Segment::line(a, m),
            Segment::line(m, l1),
            Segment::line(l1, l2),
            Segment::line(l2, e),
        ];
        let (out, st) = clean_path(path, false, &O);
        continuous(&out);
        assert_eq!(st.short, 2);
        assert_eq!(st.left, 0);
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(st.max_dev < 1e-7, "{}", st.max_dev);
        assert_eq!(out[0].start(), a);
        assert_eq!(out[1].end(), e);
    }

    #[test]
    fn a_bevel_at_a_sharp_corner_collapses_within_the_tolerance() {
        // A 90° corner cut by a 2 µm bevel: the corner point is 1 µm off it.
        let b = 2e-3 / 2f64.sqrt();
        let path = poly(&[(0.0, 0.0), (1.0 - b, 0.0), (1.0, b), (1.0, 1.0)]);
        let (out, st) = clean_path(path, false, &O);
        continuous(&out);
        assert_eq!((st.short, st.left), (1, 0));
        assert_eq!(out.len(), 2);
        assert!(st.max_dev <= O.tol);
        assert!(out.iter().all(|e| e.length() >= O.min_len));
        // With a tolerance too small for any candidate it stays, counted.
        let (out, st) = clean_path(
            poly(&[(0.0, 0.0), (1.0 - b, 0.0), (1.0, b), (1.0, 1.0)]),
            false,
            &CleanOptions { tol: 1e-4, ..O },
        );
        assert_eq!((out.len(), st.left, st.max_dev), (3, 1, 0.0));
    }

    #[test]
    fn a_run_of_short_chords_on_a_curve_becomes_arcs() {
        // A circle of radius 1 mm drawn with 1 µm chords over 0.05 rad
        // between two long lines tangent to it.
        let r = 1.0;
        let n = 50;
        let at = |a: f64| P3::new(r * a.cos(), r * a.sin(), 0.0);
        let mut path = vec![Segment::line(P3::new(1.0, -0.5, 0.0), at(0.0))];
        for k in 0..n {
            path.push(Segment::line(at(k as f64 * 1e-3), at((k + 1) as f64 * 1e-3)));
        }
        let end = at(n as f64 * 1e-3);
        let t = V3::new(-end.y, end.x, 0.0);
        path.push(Segment::line(end, end + t * 0.5));
        let (out, st) = clean_path(path, false, &O);
        continuous(&out);
        assert_eq!(st.short, n);
        assert_eq!(st.left, 0);
        assert!(out.iter().all(|e| e.length() >= O.min_len), "{out:?}");
        assert!(st.max_dev <= O.tol);
        // Measured independently: every sample of the result is within the
        // reported deviation of the circle arc or the lines.
        for e in &out {
            for k in 0..=32 {
                let p = e.point_at_length(e.length() * k as f64 / 32.0);
                let ang = p.y.atan2(p.x);
                let d = if (0.0..=0.05).contains(&ang) {
                    (p.coords.xy().norm() - r).abs()
                } else {
                    0.0
                };
                assert!(d <= st.max_dev + 1e-9, "{p:?} {d}");
            }
        }
    }

    #[test]
    fn a_closed_path_with_a_short_last_piece_wraps() {
        let path = poly(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 1e-6), (0.0, 0.0)]);
        let (out, st) = clean_path(path, true, &O);
        continuous(&out);
        assert_eq!(st.left, 0);
        assert_eq!(out.len(), 4);
        assert_eq!(out[0].start(), out[3].end());
        assert!(st.max_dev < 1e-9);
    }

    #[test]
    fn nothing_short_is_left_untouched() {
        let path = poly(&[(0.0, 0.0), (1.0, 0.0), (1.0, 0.3)]);
        let (out, st) = clean_path(path.clone(), false, &O);
        assert_eq!(out, path);
        assert_eq!(st.short, 0);
    }
}
