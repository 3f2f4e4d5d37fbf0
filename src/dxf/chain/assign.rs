//! End points to node ids: every alive piece's start and end joined to the
//! first node within the tolerance, as [`Nodes`] does in drawing order, on
//! one thread or, on a large drawing, on two halves of the plane at once.

use super::Work;
use super::nodes::{NONE, Nodes};
use crate::geometry::P3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// Every piece's end nodes, and the nodes' points and gaps.
pub(super) struct Assigned {
    /// Piece `i`'s start and end node; `(NONE, NONE)` for a dead piece.
    pub ends: Vec<(u32, u32)>,
    /// The points and gaps of the nodes, of one side or two.
    sides: [Found; 2],
    /// Where node `n` is: `from[n]` is its index in `sides[0]`, or in
    /// `sides[1]` with [`RIGHT`] set. Empty when there is one side, whose
    /// indices are the node ids.
    from: Vec<u32>,
}

/// The nodes' points and the largest distance of a point joined to each.
#[derive(Default)]
struct Found {
    reps: Vec<P3>,
    gaps: Vec<f64>,
}

/// Set on the ids of the right side's nodes (in the end slots and in
/// [`Assigned`]'s `from`): local ids stay below 2^31, as a drawing of
/// 2^31 nodes would need some 100 GB.
const RIGHT: u32 = 1 << 31;

impl Assigned {
    /// How many nodes there are.
    pub fn len(&self) -> usize {
        self.sides[0].reps.len() + self.sides[1].reps.len()
    }

    fn locate(&self, n: u32) -> (&Found, usize) {
        match self.from.get(n as usize) {
            None => (&self.sides[0], n as usize),
            Some(&k) if k & RIGHT != 0 => (&self.sides[1], (k & !RIGHT) as usize),
            Some(&k) => (&self.sides[0], k as usize),
        }
    }

    /// Node `n`'s point (the first point joined to it).
    pub fn rep(&self, n: u32) -> P3 {
        let (f, k) = self.locate(n);
        f.reps[k]
    }

    /// The largest distance of a point joined to node `n`.
    pub fn gap(&self, n: u32) -> f64 {
        let (f, k) = self.locate(n);
        f.gaps[k]
    }
}

/// Below this many pieces the clustering runs on one thread: splitting
/// would cost more than it saves.
const SPLIT_MIN: usize = 1 << 14;

/// The nodes of the alive pieces' end points, exactly as
/// [`Nodes::node_of`] on each start and end in drawing order gives them.
///
/// On a large drawing the plane is cut by a vertical line that no end point
/// comes near (farther than twice the tolerance, with a margin, on either
/// side) and each half is clustered on its own thread. No node of one half
/// can be within the tolerance of a point of the other, so each point meets
/// the same candidates as in one pass; the ids of each half come in the
/// order of their first points, and merging the halves by that order gives
/// the ids one pass gives. A drawing with no such line near its median
/// (every x taken, as in a dense grid) is clustered in one pass.
pub(super) fn assign(w: &[Work], tol: f64) -> Assigned {
    assign_from(w, tol, w.len() >= SPLIT_MIN && rayon::current_num_threads() > 1)
}

/// [`assign`], splitting where `split` and a line is found.
fn assign_from(w: &[Work], tol: f64, split: bool) -> Assigned {
    // One array of end slots for both sides: each point's slot is written
    // by the one side it lies on (relaxed stores: plain moves on x86), so
    // the drawing costs one array of ends, not one per side.
    // Filled on the pool: 2.7 MB on the mix benchmark, which one thread
    // took 1.3 ms to write.
    let slots: Vec<[AtomicU32; 2]> = (0..w.len())
        .into_par_iter()
        .with_min_len(1 << 14)
        .map(|_| [AtomicU32::new(NONE), AtomicU32::new(NONE)])
        .collect();
    if split && let Some(Split { side, left, right, .. }) = split_line(w, tol) {
        // Each half reads the one byte per piece saying which of its ends
        // are its own, and a piece's 88 bytes only for those.
        let (l, r) = rayon::join(
            || cluster(w, tol, left, &slots, 0, |i| if side[i] == 0 { 0 } else { !side[i] & 3 }),
            || cluster(w, tol, right, &slots, RIGHT, |i| side[i] & 3),
        );
        return merge(slots, l, r);
    }
    let found = cluster(w, tol, 2 * w.len(), &slots, 0, |i| if w[i].alive { 3 } else { 0 });
    Assigned {
        ends: slots
            .into_iter()
            .map(|[a, b]| (a.into_inner(), b.into_inner()))
            .collect(),
        sides: [found, Found::default()],
        from: Vec::new(),
    }
}

/// The nodes of the end points that are this side's, in drawing order:
/// each point's local id, with `tag` set, into its slot. `mine(i)` says
/// which ends of piece `i` are (bit 0 its start, bit 1 its end; 0 for a
/// dead piece).
fn cluster(
    w: &[Work],
    tol: f64,
    points: usize,
    slots: &[[AtomicU32; 2]],
    tag: u32,
    mine: impl Fn(usize) -> u8,
) -> Found {
    let mut nodes = Nodes::new(tol, points);
    // The table slots of the pieces a few places ahead are asked for
    // early, so their cache misses overlap with this piece's work.
    const AHEAD: usize = 8;
    for i in 0..w.len() {
        if i + AHEAD < w.len() {
            let m = mine(i + AHEAD);
            if m != 0 {
                let a = &w[i + AHEAD];
                for (k, p) in [a.seg.start(), a.seg.end()].iter().enumerate() {
                    if m >> k & 1 != 0 {
                        nodes.prefetch(p);
                    }
                }
            }
        }
        let m = mine(i);
        if m == 0 {
            continue;
        }
        let x = &w[i];
        for (k, p) in [x.seg.start(), x.seg.end()].iter().enumerate() {
            if m >> k & 1 != 0 {
                slots[i][k].store(nodes.node_of(p) | tag, Ordering::Relaxed);
            }
        }
    }
    let (reps, gaps) = nodes.finish();
    Found { reps, gaps }
}

/// The two sides' nodes as one set, numbered in the order of their first
/// points; the nodes themselves stay where they are.
fn merge(slots: Vec<[AtomicU32; 2]>, l: Found, r: Found) -> Assigned {
    // A side's ids are given in the order of their first points, so going
    // through the points in drawing order, a point whose local id is the
    // number of that side's nodes met so far is a node's first point: the
    // next id in one pass.
    let (mut to_l, mut to_r): (Vec<u32>, Vec<u32>) =
        (Vec::with_capacity(l.reps.len()), Vec::with_capacity(r.reps.len()));
    let mut from: Vec<u32> = Vec::with_capacity(l.reps.len() + r.reps.len());
    for v in slots.iter().flatten().map(|s| s.load(Ordering::Relaxed)) {
        if v == NONE {
            continue;
        }
        let (to, k) = if v & RIGHT != 0 {
            (&mut to_r, v & !RIGHT)
        } else {
            (&mut to_l, v)
        };
        if k as usize == to.len() {
            to.push(from.len() as u32);
            from.push(v);
        }
    }
    let id = |v: u32| match v {
        NONE => NONE,
        v if v & RIGHT != 0 => to_r[(v & !RIGHT) as usize],
        v => to_l[v as usize],
    };
    // In place: the slots and the pairs have the same size and alignment.
    let ends = slots
        .into_iter()
        .map(|[a, b]| (id(a.into_inner()), id(b.into_inner())))
        .collect();
    Assigned {
        ends,
        sides: [l, r],
        from,
    }
}

/// Where the plane is cut for the two halves.
struct Split {
    /// The line x = m.
    #[cfg_attr(not(test), allow(dead_code))]
    m: f64,
    /// Per piece: bit 0 set when its start lies right of the line, bit 1
    /// its end, bit 2 when the piece is alive (0 for a dead one).
    side: Vec<u8>,
    /// End points on either side.
    left: usize,
    right: usize,
}

/// Per piece: [`Split::side`] of the line x = `m`, or [`BAND`] when an end
/// lies within `band` of it.
const BAND: u8 = 0xff;

/// A line x = m near the median of the end points' x with every alive end
/// point more than twice the reach away from it, which side each point is
/// on, and how many end points lie on either side; `None` when a sample of
/// the drawing offers none that holds.
fn split_line(w: &[Work], tol: f64) -> Option<Split> {
    let band = 2.0 * tol * (1.0 + 1e-6);
    let step = (w.len() / 2048).max(1);
    let mut xs: Vec<f64> = w
        .iter()
        .step_by(step)
        .filter(|x| x.alive)
        .flat_map(|x| [x.seg.start().x, x.seg.end().x])
        .collect();
    if xs.len() < 64 {
        return None;
    }
    xs.sort_unstable_by(f64::total_cmp);
    let mid = xs.len() / 2;
    // Gaps of the sample outwards from the median, within its middle half;
    // each one that is wide enough is checked against every point.
    let mut tries = 0;
    for d in 0..xs.len() / 4 {
        for k in [mid + d, mid - 1 - d] {
            let (a, b) = (xs[k], xs[k + 1]);
            let m = a / 2.0 + b / 2.0;
            if !(m - a > band && b - m > band) {
                continue;
            }
            let side: Vec<u8> = w
                .par_iter()
                .map(|x| {
                    if !x.alive {
                        return 0;
                    }
                    let (p, q) = (x.seg.start().x, x.seg.end().x);
                    if (p - m).abs() <= band || (q - m).abs() <= band {
                        return BAND;
                    }
                    4 | (p >= m) as u8 | ((q >= m) as u8) << 1
                })
                .collect();
            if !side.contains(&BAND) {
                let right: usize = side.iter().map(|&s| (s & 1) as usize + (s >> 1 & 1) as usize).sum();
                let alive = side.iter().filter(|&&s| s != 0).count();
                return Some(Split {
                    m,
                    side,
                    left: 2 * alive - right,
                    right,
                });
            }
            tries += 1;
            if tries == 3 {
                return None;
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Arc3, Plane, V3};
    use crate::model::chain::Segment;
    use proptest::prelude::*;

    /// Everything a walk reads of an assignment, node by node.
    fn nodes_of(a: &Assigned) -> Vec<(P3, f64)> {
        (0..a.len() as u32).map(|n| (a.rep(n), a.gap(n))).collect()
    }

    fn work(seg: Segment, alive: bool) -> Work {
        Work { seg, order: 0, alive }
    }

    /// Pieces with ends on a lattice `pitch` apart, jittered by up to
    /// `jitter`: ends that meet, ends a hair apart and ends just outside
    /// the tolerance, in columns with empty strips between some of them.
    fn drawing() -> impl Strategy<Value = (Vec<Work>, f64)> {
        let tol = prop_oneof![Just(0.0), Just(1e-3), Just(0.01), Just(0.3)];
        let end = (0i32..24, 0i32..6, 0u8..4, -1.0f64..1.0, -1.0f64..1.0);
        let piece = (end.clone(), end, any::<bool>(), 0u8..10);
        (tol, proptest::collection::vec(piece, 40..400)).prop_map(|(tol, pieces)| {
            let pt = |(i, j, k, dx, dy): (i32, i32, u8, f64, f64)| {
                // Columns 0-7 and 16-23 only, mostly: the middle is empty
                // save for a few pieces crossing it.
                let x = if (8..16).contains(&i) {
                    i as f64 * 0.25
                } else {
                    i as f64
                };
                let jitter = [0.0, 0.4 * tol, tol, 2.0 * tol][k as usize];
                P3::new(x + dx * jitter, j as f64 + dy * jitter, 0.0)
            };
            let w = pieces
                .into_iter()
                .map(|(a, b, arc, dead)| {
                    let (p, q) = (pt(a), pt(b));
                    let c = P3::from((p.coords + q.coords) * 0.5);
                    let seg = match Arc3::new(c, p, q, true, Plane::Xy, 0) {
                        Some(a) if arc && (p - q).norm() > 1e-6 => Segment::Arc(a),
                        _ => Segment::line(p, q),
                    };
                    work(seg, dead != 0)
                })
                .collect();
            (w, tol)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Clustering the two halves on their own and merging them gives
        /// the nodes, ids, points and gaps of one pass in drawing order.
        #[test]
        fn split_clustering_is_one_pass((w, tol) in drawing()) {
            let one = assign_from(&w, tol, false);
            let two = assign_from(&w, tol, true);
            prop_assert!(one.from.is_empty());
            prop_assert_eq!(&two.ends, &one.ends);
            prop_assert_eq!(nodes_of(&two), nodes_of(&one));
        }
    }

    /// Real drawings, split wherever a line is found, at three tolerances:
    /// the same nodes as one pass.
    #[test]
    fn corpus_drawings_split_as_one_pass() {
        let files = crate::corpus::files("dxf", &[".dxf"]);
        if files.is_empty() {
            crate::corpus::skip("dxf_split_clustering");
            return;
        }
        let (mut cases, mut split) = (0, 0);
        for path in &files {
            let Ok(f) = std::fs::File::open(path) else { continue };
            let input = Box::new(std::io::BufReader::new(f));
            let Ok(imp) = crate::dxf::import(input, &crate::dxf::ImportOptions::default()) else {
                continue;
            };
            let w: Vec<Work> = imp
                .sink
                .segments
                .iter()
                .map(|(seg, _)| work(*seg, seg.is_finite()))
                .collect();
            for tol in [0.0, 0.001, 0.05] {
                let one = assign_from(&w, tol, false);
                let two = assign_from(&w, tol, true);
                assert_eq!(two.ends, one.ends, "{} at {tol}", path.display());
                assert_eq!(nodes_of(&two), nodes_of(&one), "{} at {tol}", path.display());
                cases += 1;
                split += usize::from(!two.from.is_empty());
            }
        }
        // Most of them are split: the test compares the two ways, not one
        // way with itself.
        assert!(split * 2 > cases, "{split} of {cases} split");
        crate::corpus::record("dxf_split_clustering", cases);
    }

    #[test]
    fn a_drawing_in_two_parts_is_split_and_a_dense_one_is_not() {
        // Squares on the left and on the right, nothing in between.
        let mut w = Vec::new();
        for k in 0..200 {
            let x = if k % 2 == 0 { 0.0 } else { 100.0 } + (k % 7) as f64;
            let y = (k / 2) as f64;
            let c = [
                P3::new(x, y, 0.0),
                P3::new(x + 0.5, y, 0.0),
                P3::new(x + 0.5, y + 0.5, 0.0),
                P3::new(x, y + 0.5, 0.0),
            ];
            for i in 0..4 {
                w.push(work(Segment::line(c[i], c[(i + 1) % 4]), true));
            }
        }
        let two = assign_from(&w, 0.001, true);
        assert!(!two.from.is_empty(), "split");
        let one = assign_from(&w, 0.001, false);
        assert_eq!(two.ends, one.ends);
        assert_eq!(nodes_of(&two), nodes_of(&one));
        // Every x of the middle half within the tolerance of the next:
        // no line can be drawn, and one pass is taken.
        let w: Vec<Work> = (0..400)
            .map(|k| {
                let x = k as f64 * 0.0015;
                work(Segment::line(P3::new(x, 0.0, 0.0), P3::new(x, 1.0, 0.0)), true)
            })
            .collect();
        let a = assign_from(&w, 0.001, true);
        assert!(a.from.is_empty(), "not split");
        assert_eq!(a.ends, assign_from(&w, 0.001, false).ends);
        // The sample (every other piece here) sees the even columns; the
        // pieces it skips stand on the odd ones, halfway between, where the
        // lines through the sample's gaps would pass: every one is refused.
        let w: Vec<Work> = (0..5000)
            .map(|k| {
                let x = (2 * (k / 2 % 25) + k % 2) as f64;
                let y = (k / 50) as f64;
                work(Segment::line(P3::new(x, y, 0.0), P3::new(x, y + 0.5, 0.0)), true)
            })
            .collect();
        assert!(split_line(&w, 0.001).is_none());
        // With the odd columns moved off by a quarter, a line passes.
        let w: Vec<Work> = w
            .iter()
            .enumerate()
            .map(|(k, x)| {
                let d = if k % 2 == 1 { 0.25 } else { 0.0 };
                work(
                    Segment::line(x.seg.start() + V3::new(d, 0.0, 0.0), x.seg.end() + V3::new(d, 0.0, 0.0)),
                    true,
                )
            })
            .collect();
        let Split { m, left, right, .. } = split_line(&w, 0.001).expect("a line between the columns");
        assert_eq!(m % 2.0, 1.0, "{m}: halfway between two even columns");
        assert_eq!(left + right, 10_000);
        let (one, two) = (assign_from(&w, 0.001, false), assign_from(&w, 0.001, true));
        assert!(!two.from.is_empty());
        assert_eq!(two.ends, one.ends);
        assert_eq!(nodes_of(&two), nodes_of(&one));
    }
}
