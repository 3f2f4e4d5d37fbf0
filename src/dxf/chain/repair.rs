//! Repairs before and during the walk: zero-length pieces, collinear
//! overlaps and duplicates merged or removed, ends snapped onto their
//! nodes. Each repair is counted in the report and noted on its piece.

use super::nodes::NONE;
use super::{ChainReport, Notes, Work, fmt_num, midpoint};
use crate::geometry::{Line3, P3, V3, floor_i64};
use crate::model::chain::Segment;
use rayon::prelude::*;

/// Merge lines lying on one another: exact and near duplicates and partial
/// overlaps become one line spanning their union.
///
/// Lines are grouped by (direction, offset from the origin) buckets; each
/// group, together with its neighbouring buckets (a line a hair across a
/// bucket boundary), is swept in order along its direction, comparing each
/// line only with the lines whose span it reaches. Rows of equal lines (a
/// grid of parts) therefore cost n log n, not n squared.
///
/// Pieces shorter than the tolerance ([`is_short`]) are removed first, in
/// the same pass over the pieces as the keys: each pass reads the whole
/// drawing (88 bytes a piece), and on two cores sharing the memory the
/// passes, not the arithmetic, set the pace.
pub(super) fn zero_length_and_collinear(w: &mut [Work], notes: &mut Notes, tol: f64, report: &mut ChainReport) {
    const ANGLE_BUCKET: f64 = 1e-4;
    let off_bucket = (2.0 * tol).max(1e-9);
    let n_ang = (std::f64::consts::PI / ANGLE_BUCKET).ceil() as i64;
    // (bucket, line) sorted: each bucket is a contiguous range, found by
    // binary search; no table of vectors. The keys are made on the pool, in
    // drawing order (`collect` keeps it); each holds its line's index, so
    // they are distinct and any sort gives the one order.
    let short = std::sync::atomic::AtomicU64::new(0);
    let mut keyed: Vec<Keyed> = w
        .par_iter_mut()
        .enumerate()
        .filter_map(|(i, x)| {
            if x.alive && is_short(&x.seg, tol) {
                x.alive = false;
                short.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            let Segment::Line(Line3 { start: a, end: b }) = x.seg else {
                return None;
            };
            let len = (b - a).xy().norm();
            // Only lines in a plane of constant z can lie on one another here.
            if !x.alive || len <= tol || (b.z - a.z).abs() > tol {
                return None;
            }
            let mut d = (b - a).xy() / len;
            if d.y < 0.0 || (d.y == 0.0 && d.x < 0.0) {
                d = -d;
            }
            let ai = floor_i64(d.y.atan2(d.x) / ANGLE_BUCKET).clamp(0, n_ang - 1);
            let off = d.x * a.y - d.y * a.x;
            Some(Keyed::new(ai, floor_i64(off / off_bucket), i as u32))
        })
        .collect();
    report.zero_length += short.into_inner();
    keyed.par_sort_unstable();
    let buckets = Buckets::new(keyed, n_ang);
    let keyed = &buckets.keyed;
    // The groups, then their candidates on the pool: most lines are alone
    // with their neighbours, and only the groups with two or more lines to
    // compare go on to the sweep, which merges and so runs in order.
    let swept: Vec<(usize, Vec<usize>)> = (0..keyed.len())
        .into_par_iter()
        .filter(|&g0| g0 == 0 || keyed[g0 - 1].bucket() != keyed[g0].bucket())
        .map_init(Vec::new, |cand, g0| {
            buckets.candidates(g0, cand);
            (cand.len() >= 2).then(|| (keyed[g0].idx() as usize, cand.clone()))
        })
        .flatten_iter()
        .collect();
    let mut active: Vec<usize> = Vec::new();
    let mut by_start: Vec<(f64, usize)> = Vec::new();
    for (first, cand) in swept {
        let Segment::Line(Line3 { start: p, end: q }) = w[first].seg else {
            continue;
        };
        let d = (q - p).xy().normalize();
        let span = |s: &Segment| {
            let (a, b) = (s.start(), s.end());
            let (x, y) = (d.x * a.x + d.y * a.y, d.x * b.x + d.y * b.y);
            (x.min(y), x.max(y))
        };
        // Each line's start along the direction, read once: a line is
        // changed only after its turn (when it is kept and a later one
        // merges into it), so these are the values the sweep sees.
        by_start.clear();
        by_start.extend(cand.iter().map(|&i| (span(&w[i].seg).0, i)));
        by_start.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        by_start.dedup_by_key(|x| x.1);
        active.clear();
        for &(lo, i) in by_start.iter() {
            if !w[i].alive {
                continue;
            }
            active.retain(|&k| w[k].alive && span(&w[k].seg).1 >= lo - tol);
            let Segment::Line(Line3 { start: a, end: b }) = w[i].seg else {
                continue;
            };
            let mut merged = false;
            for &k in active.iter() {
                if let Some((start, end, dup)) = overlap(&w[k].seg, a, b, tol) {
                    w[k].seg = Segment::line(start, end);
                    w[k].order = w[k].order.min(w[i].order);
                    w[i].alive = false;
                    let note = if dup {
                        report.duplicates += 1;
                        "duplicate removed"
                    } else {
                        report.overlaps += 1;
                        "collinear overlap merged"
                    };
                    let m = P3::from((a.coords + b.coords) * 0.5);
                    notes
                        .entry(k)
                        .or_default()
                        .push(format!("{note} at [{}, {}]", fmt_num(m.x), fmt_num(m.y)));
                    merged = true;
                    break;
                }
            }
            if !merged {
                active.push(i);
            }
        }
    }
}

/// A line's collinear bucket (direction, offset) and index in one word,
/// ordered as the tuple `(direction, offset, index)`: the direction needs
/// 15 bits, the offset (sign bit flipped) 64, the index 32.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Keyed(u128);

impl Keyed {
    fn new(ang: i64, off: i64, idx: u32) -> Keyed {
        Keyed(((ang as u128) << 96) | (((off as u64) ^ (1 << 63)) as u128) << 32 | idx as u128)
    }
    fn ang(self) -> i64 {
        (self.0 >> 96) as i64
    }
    fn off(self) -> i64 {
        (((self.0 >> 32) as u64) ^ (1 << 63)) as i64
    }
    fn idx(self) -> u32 {
        self.0 as u32
    }
    fn bucket(self) -> (i64, i64) {
        (self.ang(), self.off())
    }
}

/// The sorted keys with each direction's range of them (an array over the
/// directions: no hashing); offsets are found within a range by binary
/// search.
struct Buckets {
    keyed: Vec<Keyed>,
    by_angle: Vec<(u32, u32)>,
    n_ang: i64,
}

impl Buckets {
    /// `keyed` sorted, with directions `0..n_ang`.
    fn new(keyed: Vec<Keyed>, n_ang: i64) -> Buckets {
        let mut by_angle: Vec<(u32, u32)> = vec![(0, 0); n_ang as usize];
        let mut g = 0;
        while g < keyed.len() {
            let a = keyed[g].ang();
            let end = g + keyed[g..].partition_point(|e| e.ang() == a);
            by_angle[a as usize] = (g as u32, end as u32);
            g = end;
        }
        Buckets { keyed, by_angle, n_ang }
    }

    /// The lines of the bucket starting at `keyed[g0]` and of its
    /// neighbouring buckets (direction and offset one bucket either way),
    /// into `cand`, from the keys alone. Directions are folded into
    /// [0, pi): a line just below pi is a neighbour of one just above 0,
    /// with its offset's sign flipped.
    fn candidates(&self, g0: usize, cand: &mut Vec<usize>) {
        let keyed = &self.keyed;
        let key = keyed[g0].bucket();
        cand.clear();
        for da in -1..=1 {
            let raw = key.0 + da;
            let wrapped = !(0..self.n_ang).contains(&raw);
            let a_key = raw.rem_euclid(self.n_ang);
            let (lo, hi) = self.by_angle[a_key as usize];
            let s = &keyed[lo as usize..hi as usize];
            if s.is_empty() {
                continue;
            }
            // The offsets `base - 1 ..= base + 1` are one run of the
            // direction's range, found by two binary searches; where they
            // wrap round the integers (offsets of some 1e16 tolerances),
            // three runs, as the wrapping arithmetic has them.
            let base = if wrapped {
                key.1.wrapping_neg().wrapping_sub(1)
            } else {
                key.1
            };
            let run = |first: i64, last: i64| {
                let a = s.partition_point(|e| e.off() < first);
                let b = a + s[a..].partition_point(|e| e.off() <= last);
                lo as usize + a..lo as usize + b
            };
            // Dead lines are skipped by the sweep: not looking at them here
            // spares a cache miss per line alone in its bucket.
            match (base.checked_sub(1), base.checked_add(1)) {
                // In the group's own direction the run holds `g0`: it is
                // found by stepping out from there, over the lines it
                // gives, instead of two binary searches of a direction
                // that may hold most of the drawing.
                (Some(first), Some(last)) if da == 0 => {
                    let (lo, hi) = (lo as usize, hi as usize);
                    let mut a = g0;
                    while a > lo && keyed[a - 1].off() >= first {
                        a -= 1;
                    }
                    let mut b = g0;
                    while b < hi && keyed[b].off() <= last {
                        b += 1;
                    }
                    cand.extend(keyed[a..b].iter().map(|e| e.idx() as usize));
                }
                (Some(first), Some(last)) => cand.extend(keyed[run(first, last)].iter().map(|e| e.idx() as usize)),
                _ => {
                    for dofs in -1..=1 {
                        let o = base.wrapping_add(dofs);
                        cand.extend(keyed[run(o, o)].iter().map(|e| e.idx() as usize));
                    }
                }
            }
        }
    }
}

/// If line `a`-`b` lies along `kept` (within `tol`, same z) and overlaps it
/// by more than `tol`, the union's ends (in `kept`'s direction) and whether
/// `a`-`b` was a duplicate (same ends within `tol`).
fn overlap(kept: &Segment, a: P3, b: P3, tol: f64) -> Option<(P3, P3, bool)> {
    let Segment::Line(Line3 { start: p, end: q }) = *kept else {
        return None;
    };
    if (p.z - a.z).abs() > tol || (q.z - p.z).abs() > tol || (b.z - a.z).abs() > tol {
        return None;
    }
    let len = (q - p).xy().norm();
    let d = (q - p).xy() / len;
    let dist = |x: &P3| (d.x * (x.y - p.y) - d.y * (x.x - p.x)).abs();
    if dist(&a) > tol || dist(&b) > tol {
        return None;
    }
    let proj = |x: &P3| d.x * (x.x - p.x) + d.y * (x.y - p.y);
    let (sa, sb) = (proj(&a), proj(&b));
    let (lo, hi) = (sa.min(sb), sa.max(sb));
    if hi.min(len) - lo.max(0.0) <= tol {
        return None;
    }
    let dup = ((a - p).norm() <= tol && (b - q).norm() <= tol) || ((a - q).norm() <= tol && (b - p).norm() <= tol);
    let start = if lo < -tol { if sa < sb { a } else { b } } else { p };
    let end = if hi > len + tol { if sa > sb { a } else { b } } else { q };
    Some((start, end, dup))
}

/// Move a segment's ends to `a` and `b`; an arc's centre moves onto the
/// new ends' bisector so that both ends stay on one circle.
pub(super) fn snap(s: &Segment, a: P3, b: P3) -> Segment {
    match *s {
        Segment::Line(_) => Segment::line(a, b),
        Segment::Arc(arc) => {
            let (start, center) = (arc.start, arc.center);
            let center = if a == b {
                center + (a - start)
            } else {
                let m = P3::from((a.coords + b.coords) * 0.5);
                let d = b - a;
                let n = V3::new(-d.y, d.x, 0.0).normalize();
                let mut c = m + n * (center - m).dot(&n);
                c.z = a.z;
                c
            };
            Segment::arc_xy(a, b, center, arc.ccw)
        }
    }
}

/// See [`is_short`].
const CHORD_SHORTCUT_TOL: f64 = 1e-5;

/// A piece shorter than the tolerance (or an arc of a radius below it).
///
/// An arc is never shorter than its chord: an arc whose chord is more than
/// twice the tolerance is kept without its sweep (two `atan2`s) being
/// computed. The sweep's round-off is far below that margin whenever the
/// tolerance is at least [`CHORD_SHORTCUT_TOL`] (radii are below 1e10 mm
/// after the range check); below it every arc is measured.
fn is_short(seg: &Segment, tol: f64) -> bool {
    match seg.radius() {
        Some(r) => {
            let chord = (seg.end() - seg.start()).xy().norm();
            r <= tol || (!(tol >= CHORD_SHORTCUT_TOL && chord > 2.0 * tol) && seg.length() <= tol)
        }
        None => seg.length() <= tol,
    }
}

/// The pieces at each node, in piece order (compressed rows: node `n`'s
/// pieces are `adj[start[n]..start[n + 1]]`; a piece from a node to itself
/// is listed twice).
pub(super) fn adjacency(alive: &[bool], ends: &[(u32, u32)], n_nodes: usize) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; n_nodes + 1];
    for (i, &a) in alive.iter().enumerate() {
        if a {
            start[ends[i].0 as usize + 1] += 1;
            start[ends[i].1 as usize + 1] += 1;
        }
    }
    for k in 0..n_nodes {
        start[k + 1] += start[k];
    }
    let mut adj = vec![0u32; start[n_nodes] as usize];
    // Node n's entries go at start[n], start[n] + 1, ...: `start` itself
    // is the cursor, which leaves each node's entry at its successor's
    // start; one move back restores it. A copy of `start` as the cursor
    // cost a fresh 1.4 MB (350 page faults) on the mix benchmark.
    for (i, &a) in alive.iter().enumerate() {
        if a {
            for n in [ends[i].0, ends[i].1] {
                adj[start[n as usize] as usize] = i as u32;
                start[n as usize] += 1;
            }
        }
    }
    start.copy_within(0..n_nodes, 1);
    start[0] = 0;
    (start, adj)
}

/// Lines whose ends fell into one node (shorter than the tolerance across)
/// and duplicates: a piece between the same two nodes as an earlier kept
/// one (lines; arcs with the same centre and midpoint) is removed, with a
/// note on the latest such kept piece. The earlier pieces are found among
/// those at the piece's first node, so no table of node pairs is built.
///
/// Returns the [`adjacency`] of the pieces left, which the walk needs:
/// the one built here when nothing was removed from it (the usual case),
/// built again otherwise.
pub(super) fn remove_duplicates(
    w: &mut [Work],
    ends: &[(u32, u32)],
    n_nodes: usize,
    notes: &mut Notes,
    tol: f64,
    report: &mut ChainReport,
) -> (Vec<u32>, Vec<u32>) {
    // The alive flags as a dense array, kept with the pieces' own: the
    // passes below read them for every piece and neighbour, and a flag in
    // an 88-byte piece costs a cache line.
    let mut alive: Vec<bool> = vec![false; w.len()];
    report.zero_length += w
        .par_iter_mut()
        .zip(ends.par_iter())
        .zip(alive.par_iter_mut())
        .with_min_len(1 << 12)
        .map(|((x, &(a, b)), alive)| {
            let short = x.alive && a == b && matches!(x.seg, Segment::Line(_));
            x.alive &= !short;
            *alive = x.alive;
            u64::from(short)
        })
        .sum::<u64>();
    let (start, adj) = adjacency(&alive, ends, n_nodes);
    // The pieces with an earlier piece between the same two nodes, found
    // on the pool from the nodes alone: only these can be duplicates (the
    // ordered pass below only ever removes pieces), and in most drawings
    // they are a handful.
    let paired = |i: usize| {
        let (a, b) = ends[i];
        adj[start[a as usize] as usize..start[a as usize + 1] as usize]
            .iter()
            .any(|&j| {
                let (p, q) = ends[j as usize];
                (j as usize) < i && alive[j as usize] && ((p == a && q == b) || (p == b && q == a))
            })
    };
    let maybe: Vec<u32> = (0..w.len())
        .into_par_iter()
        .with_min_len(1 << 12)
        .filter(|&i| alive[i] && paired(i))
        .map(|i| i as u32)
        .collect();
    let mut removed = false;
    for i in maybe.into_iter().map(|i| i as usize) {
        if !alive[i] {
            continue;
        }
        let (a, b) = ends[i];
        let mut dup_of = None;
        let mut last = NONE;
        for &j in adj[start[a as usize] as usize..start[a as usize + 1] as usize]
            .iter()
            .rev()
        {
            let j_ = j as usize;
            // Later pieces (and this one) are not candidates yet; a piece
            // from a node to itself is listed twice.
            if j_ >= i || j == last || !alive[j_] {
                continue;
            }
            last = j;
            let (p, q) = ends[j_];
            if !((p == a && q == b) || (p == b && q == a)) {
                continue;
            }
            let same = match (&w[i].seg, &w[j_].seg) {
                (Segment::Line(_), Segment::Line(_)) => true,
                (Segment::Arc(a1), Segment::Arc(a2)) => {
                    (a1.center - a2.center).norm() <= tol && (midpoint(&w[i].seg) - midpoint(&w[j_].seg)).norm() <= tol
                }
                _ => false,
            };
            if same {
                dup_of = Some(j_);
                break;
            }
        }
        if let Some(j) = dup_of {
            w[i].alive = false;
            alive[i] = false;
            removed = true;
            report.duplicates += 1;
            let p = midpoint(&w[i].seg);
            notes
                .entry(j)
                .or_default()
                .push(format!("duplicate removed at [{}, {}]", fmt_num(p.x), fmt_num(p.y)));
        }
    }
    if removed {
        adjacency(&alive, ends, n_nodes)
    } else {
        (start, adj)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The compressed rows against a list per node, filled in piece
        /// order: the same pieces at every node, in the same order.
        #[test]
        fn adjacency_lists_each_nodes_pieces_in_piece_order(
            n_nodes in 0usize..40,
            pieces in proptest::collection::vec((0u32..40, 0u32..40, any::<bool>()), 0..120),
        ) {
            let pieces: Vec<(u32, u32, bool)> = if n_nodes == 0 {
                Vec::new()
            } else {
                pieces.into_iter().map(|(a, b, l)| (a % n_nodes as u32, b % n_nodes as u32, l)).collect()
            };
            let ends: Vec<(u32, u32)> = pieces.iter().map(|&(a, b, _)| (a, b)).collect();
            let alive: Vec<bool> = pieces.iter().map(|&(_, _, l)| l).collect();
            let (start, adj) = adjacency(&alive, &ends, n_nodes);
            let mut want: Vec<Vec<u32>> = vec![Vec::new(); n_nodes];
            for (i, &(a, b)) in ends.iter().enumerate() {
                if alive[i] {
                    want[a as usize].push(i as u32);
                    want[b as usize].push(i as u32);
                }
            }
            prop_assert_eq!(start.len(), n_nodes + 1);
            prop_assert_eq!(start[0], 0);
            for (n, w) in want.iter().enumerate() {
                // (A piece from a node to itself is in both lists twice.)
                prop_assert_eq!(&adj[start[n] as usize..start[n + 1] as usize], &w[..], "node {}", n);
            }
            prop_assert_eq!(start[n_nodes] as usize, adj.len());
        }
    }

    /// The neighbourhood by its definition: every key within one direction
    /// bucket (folded round at pi, the offset's sign flipped) and one
    /// offset bucket of the group's, in the wrapping arithmetic of the
    /// offsets.
    fn brute(keyed: &[Keyed], n_ang: i64, g0: usize) -> Vec<usize> {
        let key = keyed[g0].bucket();
        let mut out: Vec<usize> = Vec::new();
        for e in keyed {
            for da in -1..=1 {
                let raw = key.0 + da;
                let wrapped = !(0..n_ang).contains(&raw);
                let base = if wrapped {
                    key.1.wrapping_neg().wrapping_sub(1)
                } else {
                    key.1
                };
                if e.ang() == raw.rem_euclid(n_ang) && (-1..=1).any(|d| e.off() == base.wrapping_add(d)) {
                    out.push(e.idx() as usize);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The two binary searches per direction find what the definition
        /// names, at the fold and at the ends of the offsets too.
        #[test]
        fn candidates_are_the_neighbouring_buckets(
            keys in proptest::collection::vec(
                (0i64..6, prop_oneof![-4i64..4, Just(i64::MIN), Just(i64::MIN + 1), Just(i64::MAX), Just(i64::MAX - 1)]),
                1..60,
            ),
        ) {
            let n_ang = 6;
            let mut keyed: Vec<Keyed> =
                keys.iter().enumerate().map(|(i, &(a, o))| Keyed::new(a, o, i as u32)).collect();
            keyed.sort_unstable();
            let b = Buckets::new(keyed.clone(), n_ang);
            let mut cand = Vec::new();
            for g0 in 0..keyed.len() {
                if g0 > 0 && keyed[g0 - 1].bucket() == keyed[g0].bucket() {
                    continue;
                }
                b.candidates(g0, &mut cand);
                let mut got = cand.clone();
                got.sort_unstable();
                // Each line once: the runs of one direction do not overlap.
                let n = got.len();
                got.dedup();
                prop_assert_eq!(n, got.len(), "a line listed twice");
                prop_assert_eq!(got, brute(&keyed, n_ang, g0));
            }
        }
    }
}
