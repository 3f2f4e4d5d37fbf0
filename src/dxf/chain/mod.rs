//! Chain detection: from loose lines and arcs to ordered, oriented chains.
//!
//! Near-linear throughout, in five ideas, one file each:
//! - `nodes.rs`: end points clustered into nodes with a spatial hash (and a
//!   short list of the nodes just seen, which catches the shared end of
//!   consecutive pieces without a probe);
//! - `assign.rs`: every piece's ends to node ids, on a large drawing on
//!   two halves of the plane at once, with the ids one pass gives;
//! - `repair.rs`: zero-length pieces, collinear overlaps (buckets of
//!   direction and offset), duplicates (pieces between the same two nodes,
//!   found through the node adjacency), snapping;
//! - `walk.rs`: the graph walk from nodes of degree != 2, then cycles;
//! - `orient.rs`: nesting depth through a grid over the closed chains'
//!   boxes, and the exact point-in-chain and area tests.
//!
//! The steps that only read (collinear keys and candidates, the two
//! halves' nodes, the chains' boxes, areas and nesting) run on the thread
//! pool; the steps that change the drawing (merges, the walk) run in
//! drawing order, so the output does not depend on the thread count.
//!
//! The chaining of Bayesteh (2013) compares every pair of segments; this
//! one never does.
//!
//! Every change to the drawing is counted in [`ChainReport`] and noted on the
//! chain it touched (`repairs`).

mod assign;
mod nodes;
mod orient;
mod repair;
mod walk;

use crate::geometry::P3;
use crate::model::chain::{Chain, ChainRef, Segment};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

pub use orient::signed_area;

/// What chaining changed, for the stderr summary.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ChainReport {
    /// Pieces dropped as no longer than the tolerance (arcs also when their
    /// radius is within it; lines also when both ends joined one node).
    pub zero_length: u64,
    /// Pieces dropped as drawn twice: a line between the same two ends
    /// (either way round), an arc with the same centre and midpoint, a line
    /// lying along another.
    pub duplicates: u64,
    /// Collinear lines that overlapped, merged into one.
    pub overlaps: u64,
    /// Nodes where ends farther apart than round-off (1e-6 mm) but within
    /// the tolerance were joined.
    pub gaps_closed: u64,
    /// The largest gap closed (mm).
    pub max_gap: f64,
    /// Closed chains reversed so that outer contours run counter-clockwise
    /// and holes clockwise.
    pub reversed: u64,
    /// Pieces dropped for a NaN or infinite coordinate.
    pub non_finite: u64,
    /// Open chains in the result.
    pub open: u64,
    /// Closed chains in the result.
    pub closed: u64,
}

/// Gaps below this are float round-off in the file, not drawing errors:
/// they are closed silently (the chains format prints to 1e-9 mm).
const REPORT_GAP: f64 = 1e-6;

/// A fast, deterministic hasher for integer keys (FxHash). The std SipHash
/// is built against hostile keys; here it would be a third of the run time.
#[derive(Default)]
pub(super) struct Fx(u64);

impl Hasher for Fx {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(*b as u64);
        }
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, i: i64) {
        self.write_u64(i as u64);
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(i as u64);
    }
    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }
}

pub(super) type FxMap<K, V> = HashMap<K, V, BuildHasherDefault<Fx>>;

fn finite(s: &Segment) -> bool {
    s.is_finite()
}

pub(super) fn midpoint(s: &Segment) -> P3 {
    s.midpoint()
}

/// One piece being chained: the same size as the `(Segment, u32)` it is
/// made from, so the conversion reuses the input's memory.
#[derive(Clone, Copy, Debug)]
struct Work {
    seg: Segment,
    order: u32,
    alive: bool,
}

/// Repair notes by piece (few pieces have any).
type Notes = FxMap<usize, Vec<String>>;

/// One chain in [`Chains`]: a run of `seq`, reversed on output when
/// orientation asks for it.
#[derive(Debug, Clone, Copy)]
struct Item {
    start: u32,
    len: u32,
    order: u32,
    layer: u32,
    closed: bool,
    reversed: bool,
}

/// All chains of a drawing, stored flat: the snapped pieces stay where
/// they were read (`work`), `seq` lists them in chain order, and a small
/// record per chain says which run of `seq` it is. No second copy of the
/// geometry and no allocation per chain; [`Chains::iter`] hands the chains
/// out one at a time in output order.
#[derive(Default)]
pub struct Chains {
    work: Vec<Work>,
    seq: Vec<u32>,
    items: Vec<Item>,
    repairs: FxMap<u32, Vec<String>>,
    layers: Vec<String>,
    /// POINT entities by layer: one chain each, after the others.
    points: Vec<(u32, Vec<P3>)>,
}

impl Chains {
    /// Number of chains, point chains included.
    pub fn len(&self) -> usize {
        self.items.len() + self.points.len()
    }

    /// True when the drawing gave no chain at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// How many chains carry only POINT entities.
    pub fn point_chains(&self) -> usize {
        self.points.len()
    }

    /// The segments of one chain, in travel order, into `buf`.
    fn segments_into(&self, it: &Item, buf: &mut Vec<Segment>) {
        buf.clear();
        let run = &self.seq[it.start as usize..(it.start + it.len) as usize];
        if it.reversed {
            buf.extend(run.iter().rev().map(|&k| self.work[k as usize].seg.reversed()));
        } else {
            buf.extend(run.iter().map(|&k| self.work[k as usize].seg));
        }
    }

    /// Chain `k` (from 0) in output order, with id `k + 1`.
    pub fn get(&self, k: usize) -> Option<Chain> {
        if let Some(it) = self.items.get(k) {
            let mut segments = Vec::with_capacity(it.len as usize);
            self.segments_into(it, &mut segments);
            return Some(Chain {
                id: k as u64 + 1,
                layer: self.layers.get(it.layer as usize).cloned(),
                closed: it.closed,
                segments,
                points: Vec::new(),
                repairs: self.repairs.get(&(k as u32)).cloned().unwrap_or_default(),
            });
        }
        let (l, p) = self.points.get(k - self.items.len())?;
        Some(Chain {
            id: k as u64 + 1,
            layer: self.layers.get(*l as usize).cloned(),
            points: p.clone(),
            ..Default::default()
        })
    }

    /// Chain `k` as [`Chains::get`] gives it, borrowed instead of built:
    /// its segments into `buf`, its layer and notes from the chains. A
    /// writer of 50,000 chains and more spares a `Vec`, a layer string and
    /// the notes' clones per chain. `None` past the last chain.
    pub fn view<'a>(&'a self, k: usize, buf: &'a mut Vec<Segment>) -> Option<ChainRef<'a>> {
        let (layer, closed, points, repairs): (u32, bool, &[P3], &[String]) = match self.items.get(k) {
            Some(it) => {
                self.segments_into(it, buf);
                let repairs = self.repairs.get(&(k as u32)).map_or(&[][..], |v| v.as_slice());
                (it.layer, it.closed, &[], repairs)
            }
            None => {
                let (l, p) = self.points.get(k - self.items.len())?;
                buf.clear();
                (*l, false, p.as_slice(), &[])
            }
        };
        Some(ChainRef {
            id: k as u64 + 1,
            layer: self.layers.get(layer as usize).map(String::as_str),
            closed,
            segments: buf,
            points,
            repairs,
        })
    }

    /// The chains in output order with ids from 1.
    pub fn iter(&self) -> impl Iterator<Item = Chain> + Clone + '_ {
        (0..self.len()).filter_map(move |k| self.get(k))
    }
}

/// Join `segments` (each with a layer index into `layers`) into chains
/// within `tol`, and attach POINT entities as per-layer point chains.
pub fn build(
    segments: Vec<(Segment, u32)>,
    points: &[(P3, u32)],
    layers: &[String],
    tol: f64,
) -> (Chains, ChainReport) {
    let tol = if tol.is_finite() { tol.max(0.0) } else { 0.0 };
    let mut report = ChainReport::default();
    let mut layer_of: Vec<u32> = Vec::with_capacity(segments.len());
    // In place (same size and alignment): no second copy of the drawing,
    // and one pass over it for the layers and the finiteness check.
    let mut work: Vec<Work> = segments
        .into_iter()
        .enumerate()
        .map(|(i, (seg, l))| {
            layer_of.push(l);
            let alive = finite(&seg);
            report.non_finite += u64::from(!alive);
            Work {
                seg,
                order: i as u32,
                alive,
            }
        })
        .collect();
    // Layer by layer, in drawing order within each layer, without a
    // comparison sort of the 88-byte records (see `layer_runs`).
    crate::progress::lap("chain: pieces");
    let runs = layer_runs(&mut work, layer_of, layers.len());
    crate::progress::lap("chain: group by layer");
    let mut out = Chains {
        layers: layers.to_vec(),
        ..Default::default()
    };
    // Exactly what can survive: growth by doubling would leave up to half
    // of this array's memory unused at the peak.
    out.seq.reserve_exact(work.iter().filter(|x| x.alive).count());
    let mut repairs: Vec<(u32, Vec<String>)> = Vec::new();
    for (l, from, to) in runs {
        walk::chain_layer(
            &mut work[from..to],
            from as u32,
            l,
            tol,
            &mut report,
            &mut out,
            &mut repairs,
        );
    }
    out.work = work;
    orient::orient(&mut out, tol, &mut report);
    crate::progress::lap("orient: probes");
    // Output order: by each chain's first piece in the drawing (the orders
    // are distinct, so sorting (order, chain) words is the same order).
    let mut perm: Vec<u64> = out
        .items
        .iter()
        .enumerate()
        .map(|(k, it)| (u64::from(it.order) << 32) | k as u64)
        .collect();
    perm.sort_unstable();
    let mut rank = vec![0u32; perm.len()];
    for (pos, &k) in perm.iter().enumerate() {
        rank[(k & 0xffff_ffff) as usize] = pos as u32;
    }
    out.items = perm.iter().map(|&k| out.items[(k & 0xffff_ffff) as usize]).collect();
    drop(perm);
    out.repairs = repairs.into_iter().map(|(k, v)| (rank[k as usize], v)).collect();
    for (l, _) in layers.iter().enumerate() {
        let pts: Vec<P3> = points
            .iter()
            .filter(|(_, pl)| *pl as usize == l)
            .map(|(p, _)| *p)
            .collect();
        if !pts.is_empty() {
            out.points.push((l as u32, pts));
        }
    }
    crate::progress::lap("chain: output order");
    for it in &out.items {
        if it.closed {
            report.closed += 1;
        } else {
            report.open += 1;
        }
    }
    (out, report)
}

/// Each layer's range of `work` (piece `i` on layer `layer_of[i]`,
/// `order == i`), in ascending layer order: within a range, the alive
/// pieces are exactly that layer's alive pieces, in drawing order.
///
/// When one layer holds nearly all pieces (a cut layer and a few marks:
/// the usual drawing), its range is the whole array as it stands, and the
/// other layers' pieces are copied to the end, grouped by layer, their
/// places in the whole marked dead: sliding the 88-byte pieces of the big
/// layer together cost 5 ms of one core on a 340,000-piece drawing, and the
/// copies are at most an eighth of the array. Otherwise the array is
/// grouped by [`group_by_layer`].
fn layer_runs(work: &mut Vec<Work>, layer_of: Vec<u32>, n_layers: usize) -> Vec<(u32, usize, usize)> {
    let count = layer_counts(&layer_of, n_layers);
    let n_layers = count.len();
    let n = work.len();
    let Some(big) = (0..n_layers).max_by_key(|&k| (count[k], std::cmp::Reverse(k))) else {
        return Vec::new();
    };
    let rest = n - count[big];
    if rest == 0 {
        return if n == 0 { Vec::new() } else { vec![(big as u32, 0, n)] };
    }
    if rest > n / 8 {
        return group_by_layer(work, layer_of, &count);
    }
    // The other layers' pieces after the array, by layer, in drawing
    // order within each.
    let mut fill = vec![0usize; n_layers];
    let mut at = n;
    for k in 0..n_layers {
        if k != big {
            fill[k] = at;
            at += count[k];
        }
    }
    work.reserve_exact(rest);
    let filler = Work {
        seg: work[0].seg,
        order: 0,
        alive: false,
    };
    work.resize(n + rest, filler);
    for (i, &l) in layer_of.iter().enumerate() {
        let l = l as usize;
        if l != big {
            work[fill[l]] = work[i];
            fill[l] += 1;
            work[i].alive = false;
        }
    }
    let mut runs = Vec::new();
    for k in 0..n_layers {
        if k == big {
            runs.push((k as u32, 0, n));
        } else if count[k] > 0 {
            runs.push((k as u32, fill[k] - count[k], fill[k]));
        }
    }
    runs
}

/// How many pieces each layer has: `n_layers` entries, more when a piece
/// names a layer beyond them.
fn layer_counts(layer_of: &[u32], n_layers: usize) -> Vec<usize> {
    let mut count = vec![0usize; n_layers];
    for &l in layer_of {
        let l = l as usize;
        if l >= count.len() {
            count.resize(l + 1, 0);
        }
        count[l] += 1;
    }
    count
}

/// Reorder `work` (piece `i` on layer `layer_of[i]`, `order == i`) by
/// layer, keeping the drawing order within a layer (what sorting by
/// (layer, order) gives), and return each non-empty layer's range in
/// ascending layer order.
///
/// Without a comparison sort and without a second copy of the drawing:
/// the pieces of the other layers than the largest are copied aside, the
/// largest layer's pieces slide (in order, each once) to where their layer
/// goes, and the others are put back around them. All passes are
/// sequential; the extra memory is the smaller layers' pieces.
fn group_by_layer(work: &mut [Work], layer_of: Vec<u32>, count: &[usize]) -> Vec<(u32, usize, usize)> {
    let n_layers = count.len();
    let mut start = vec![0usize; n_layers + 1];
    start[1..].copy_from_slice(count);
    for k in 0..n_layers {
        start[k + 1] += start[k];
    }
    let runs: Vec<(u32, usize, usize)> = (0..n_layers)
        .filter(|&k| start[k + 1] > start[k])
        .map(|k| (k as u32, start[k], start[k + 1]))
        .collect();
    if layer_of.is_sorted() {
        return runs;
    }
    let Some(&(big, s, e)) = runs.iter().max_by_key(|r| (r.2 - r.1, std::cmp::Reverse(r.0))) else {
        return runs;
    };
    let side: Vec<Work> = work
        .iter()
        .zip(&layer_of)
        .filter(|&(_, &l)| l != big)
        .map(|(x, _)| *x)
        .collect();
    // The k-th piece of the largest layer goes from p_k to s + k. With
    // m_k = p_k - k (the other pieces before it, growing with k), those
    // with m_k >= s move left and are moved first, in increasing order;
    // then those with m_k < s move right, in decreasing order. Every slot
    // written is free by then (its piece was copied aside or moved).
    let big_at: Vec<u32> = (0..work.len() as u32)
        .filter(|&i| layer_of[i as usize] == big)
        .collect();
    let first_left = (0..big_at.len())
        .find(|&k| big_at[k] as usize - k >= s)
        .unwrap_or(big_at.len());
    for k in first_left..big_at.len() {
        let p = big_at[k] as usize;
        work[s + k] = work[p];
    }
    for k in (0..first_left).rev() {
        let p = big_at[k] as usize;
        work[s + k] = work[p];
    }
    debug_assert_eq!(e - s, big_at.len());
    drop(big_at);
    // The other layers, in order, around it.
    let mut fill = start;
    for x in side {
        let l = layer_of[x.order as usize] as usize;
        work[fill[l]] = x;
        fill[l] += 1;
    }
    runs
}

/// Short, stable number text for repair notes: six decimals, trailing
/// zeros dropped, no "-0".
///
/// A drawing of parts that do not quite meet gets a note per gap (12,648
/// on the mix benchmark, three numbers each), and `format!` with its
/// exact decimal expansion took most of the time of formatting them. So
/// the value is scaled to millionths and rounded in floating point, which
/// is the correctly rounded result whenever the scaled value is not within
/// a thousandth of a half (its round-off is below 2^-12 for |x| < 1e6);
/// the rest, and large or non-finite values, take the exact path.
pub(super) fn fmt_num(x: f64) -> String {
    let mut out = String::with_capacity(16);
    push_num(&mut out, x);
    out
}

/// [`fmt_num`] appended to `out`.
pub(super) fn push_num(out: &mut String, x: f64) {
    let y = x * 1e6;
    if x.abs() < 1e6 {
        let r = y.round();
        let half = (y - y.trunc()).abs();
        if (half - 0.5).abs() > 1e-3 {
            let v = r as i64;
            if v < 0 {
                out.push('-');
            }
            let v = v.unsigned_abs();
            // Writing to a String cannot fail.
            let _ = std::fmt::Write::write_fmt(out, format_args!("{}", v / 1_000_000));
            let frac = v % 1_000_000;
            if frac != 0 {
                let mut digits = *b".000000";
                let mut f = frac;
                for d in digits[1..].iter_mut().rev() {
                    *d = b'0' + (f % 10) as u8;
                    f /= 10;
                }
                let end = digits.iter().rposition(|&d| d != b'0').unwrap_or(0) + 1;
                for &d in &digits[..end] {
                    out.push(char::from(d));
                }
            }
            return;
        }
    }
    out.push_str(&fmt_num_exact(x));
}

/// [`fmt_num`] by the exact decimal expansion.
fn fmt_num_exact(x: f64) -> String {
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::repair::snap;
    use super::*;

    #[test]
    fn fast_note_numbers_are_the_exact_ones() {
        let mut rnd = crate::geometry::test_rng::unit_rng(0x2545_f491_4f6c_dd1d);
        let mut values: Vec<f64> = vec![
            0.0,
            -0.0,
            1e-7,
            -1e-7,
            5e-7,
            -5e-7,
            0.5,
            1.0,
            -1.0,
            999_999.999_999_5,
            1e6,
            1e300,
        ];
        values.extend([f64::NAN, f64::INFINITY, f64::NEG_INFINITY, f64::MIN_POSITIVE]);
        for _ in 0..200_000 {
            let mag = 10f64.powi((rnd() * 14.0) as i32 - 8);
            let v = (rnd() - 0.5) * mag;
            values.push(v);
            // Values right at a rounding half of the sixth decimal, and
            // next to it.
            let h = ((v * 1e6).trunc() + 0.5) / 1e6;
            values.extend([
                h,
                f64::from_bits(h.to_bits() + 1),
                f64::from_bits(h.to_bits().saturating_sub(1)),
            ]);
        }
        for v in values {
            assert_eq!(fmt_num(v), fmt_num_exact(v), "{v:e}");
        }
    }

    fn line(x0: f64, y0: f64, x1: f64, y1: f64) -> (Segment, u32) {
        (Segment::line(P3::new(x0, y0, 0.0), P3::new(x1, y1, 0.0)), 0)
    }

    fn square(x: f64, y: f64, s: f64, cw: bool) -> Vec<(Segment, u32)> {
        let mut v = vec![
            line(x, y, x + s, y),
            line(x + s, y, x + s, y + s),
            line(x + s, y + s, x, y + s),
            line(x, y + s, x, y),
        ];
        if cw {
            v = v.into_iter().rev().map(|(s, l)| (s.reversed(), l)).collect();
        }
        v
    }

    fn build_vec(s: Vec<(Segment, u32)>, p: &[(P3, u32)], l: &[String], tol: f64) -> (Vec<Chain>, ChainReport) {
        let (c, r) = build(s, p, l, tol);
        (c.iter().collect(), r)
    }

    fn layers() -> Vec<String> {
        vec!["0".into()]
    }

    #[test]
    fn a_borrowed_view_is_the_built_chain() {
        // Reversed holes, a gap note, a duplicate note, two layers and
        // POINT chains: every part that `get` builds.
        let mut segs = square(0.0, 0.0, 10.0, true);
        segs.extend(square(2.0, 2.0, 2.0, false).into_iter().map(|(s, _)| (s, 1)));
        segs.push(line(20.0, 0.0, 25.0, 0.0005));
        segs.push(line(25.0, 0.0, 25.0, 5.0));
        segs.push(line(25.0, 0.0, 25.0, 5.0));
        let pts = [(P3::new(1.0, 1.0, 0.0), 0), (P3::new(2.0, 1.0, 0.0), 1)];
        let names: Vec<String> = vec!["CUT".into(), "HOLE".into()];
        let (c, _) = build(segs, &pts, &names, 0.001);
        assert!(c.len() >= 5);
        let mut buf = Vec::new();
        let mut notes = 0;
        for k in 0..c.len() {
            let want = c.get(k).unwrap();
            let got = c.view(k, &mut buf).unwrap();
            assert_eq!(got.id, want.id);
            assert_eq!(got.layer, want.layer.as_deref());
            assert_eq!(got.closed, want.closed);
            assert_eq!(got.segments, &want.segments[..], "chain {k}");
            assert_eq!(got.points, &want.points[..]);
            assert_eq!(got.repairs, &want.repairs[..]);
            notes += want.repairs.len();
        }
        assert!(notes > 0, "the drawing has repair notes");
        assert!(c.points.len() == 2 && c.items.iter().any(|it| it.reversed));
        assert!(c.get(c.len()).is_none());
        assert!(c.view(c.len(), &mut buf).is_none());
    }

    #[test]
    fn shuffled_square_with_gaps_closes() {
        let segs = vec![
            line(10.0, 0.0, 10.0, 10.0),
            line(0.0, 0.0, 10.0005, 0.0),
            line(0.0, 10.0, 0.0, 0.0),
            line(10.0, 10.0, 0.0, 10.0),
        ];
        let (c, r) = build_vec(segs, &[], &layers(), 0.001);
        assert_eq!(c.len(), 1);
        assert!(c[0].closed);
        assert_eq!(c[0].segments.len(), 4);
        assert_eq!(r.gaps_closed, 1);
        assert!(signed_area(&c[0].segments) > 0.0);
        for w in c[0].segments.windows(2) {
            assert_eq!(w[0].end(), w[1].start());
        }
        assert_eq!(c[0].segments[3].end(), c[0].segments[0].start());
    }

    #[test]
    fn hole_is_clockwise_outer_counter_clockwise() {
        let mut segs = square(0.0, 0.0, 10.0, true);
        segs.extend(square(2.0, 2.0, 2.0, false));
        segs.extend(square(2.5, 2.5, 1.0, false));
        let (c, r) = build_vec(segs, &[], &layers(), 0.001);
        assert_eq!(c.len(), 3);
        assert!(signed_area(&c[0].segments) > 0.0);
        assert!(signed_area(&c[1].segments) < 0.0);
        assert!(signed_area(&c[2].segments) > 0.0, "island in a hole");
        assert_eq!(r.reversed, 2);
    }

    #[test]
    fn duplicates_and_overlaps_merge() {
        let segs = vec![
            line(0.0, 0.0, 10.0, 0.0),
            line(10.0, 0.0, 0.0, 0.0),
            line(0.0, 0.0005, 10.0, 0.0),
            line(5.0, 0.0, 15.0, 0.0),
        ];
        let (c, r) = build_vec(segs, &[], &layers(), 0.001);
        assert_eq!(r.duplicates, 2);
        assert_eq!(r.overlaps, 1);
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].segments.len(), 1);
        assert!((c[0].segments[0].length() - 15.0).abs() < 1e-9);
        assert_eq!(c[0].repairs.len(), 3);
    }

    #[test]
    fn touching_collinear_lines_stay_two_pieces() {
        let (c, r) = build_vec(
            vec![line(0.0, 0.0, 5.0, 0.0), line(5.0, 0.0, 10.0, 0.0)],
            &[],
            &layers(),
            0.001,
        );
        assert_eq!(r.overlaps + r.duplicates, 0);
        assert_eq!(c[0].segments.len(), 2);
        assert!(!c[0].closed);
    }

    #[test]
    fn zero_length_and_branches() {
        let segs = vec![
            line(0.0, 0.0, 0.0, 0.0),
            line(0.0, 0.0, 1.0, 0.0),
            line(1.0, 0.0, 2.0, 0.0),
            line(1.0, 0.0, 1.0, 1.0),
        ];
        let (c, r) = build_vec(segs, &[], &layers(), 0.001);
        assert_eq!(r.zero_length, 1);
        assert_eq!(c.len(), 3, "a T junction: three open chains");
    }

    #[test]
    fn snapped_arc_keeps_equal_radii() {
        let arc = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.0), P3::origin(), true);
        let s = snap(&arc, P3::new(1.0004, 0.0, 0.0), P3::new(0.0, 0.9997, 0.0));
        let Segment::Arc(a) = s else { panic!() };
        let (start, end, center) = (a.start, a.end, a.center);
        assert!(((start - center).norm() - (end - center).norm()).abs() < 1e-12);
    }

    #[test]
    fn full_circle_area() {
        let c = Segment::arc_xy(P3::new(2.0, 0.0, 0.0), P3::new(2.0, 0.0, 0.0), P3::origin(), false);
        assert!((signed_area(&[c]) + 4.0 * std::f64::consts::PI).abs() < 1e-12);
        let (ch, _) = build_vec(vec![(c, 0)], &[], &layers(), 0.001);
        assert!(ch[0].closed);
        assert!(signed_area(&ch[0].segments) > 0.0);
    }

    /// Numbers below `m` from a xorshift sequence seeded with `x`: the
    /// layer tests' drawings.
    fn below(mut x: u64) -> impl FnMut(u64) -> u64 {
        move |m: u64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x % m
        }
    }

    #[test]
    fn layer_runs_give_each_layer_its_alive_pieces_in_order() {
        let mut rnd = below(0x9e37_79b9);
        for case in 0..300 {
            let n = rnd(80) as usize;
            let n_layers = 1 + rnd(4) as usize;
            // A dominant layer (a few others mixed in: the pieces are
            // copied to the end), or even layers (grouped in place).
            let share = [1, 8, 20, 100][case % 4];
            let layer_of: Vec<u32> = (0..n)
                .map(|_| {
                    if rnd(share) == 0 {
                        rnd(n_layers as u64) as u32
                    } else {
                        (case % n_layers) as u32
                    }
                })
                .collect();
            let dead: Vec<bool> = (0..n).map(|_| rnd(10) == 0).collect();
            let mut work: Vec<Work> = (0..n)
                .map(|i| Work {
                    seg: line(i as f64, 0.0, i as f64, 1.0).0,
                    order: i as u32,
                    alive: !dead[i],
                })
                .collect();
            let runs = layer_runs(&mut work, layer_of.clone(), n_layers);
            assert!(
                runs.windows(2).all(|r| r[0].0 < r[1].0),
                "case {case}: ascending layers"
            );
            let mut seen = vec![0; n];
            for &(l, from, to) in &runs {
                let got: Vec<u32> = work[from..to].iter().filter(|w| w.alive).map(|w| w.order).collect();
                let want: Vec<u32> = (0..n as u32)
                    .filter(|&i| layer_of[i as usize] == l && !dead[i as usize])
                    .collect();
                assert_eq!(got, want, "case {case}, layer {l}: {layer_of:?}");
                for w in &work[from..to] {
                    assert_eq!(w.seg.start().x, w.order as f64, "a piece travels with its order");
                    if w.alive {
                        seen[w.order as usize] += 1;
                    }
                }
            }
            for i in 0..n {
                assert_eq!(
                    seen[i],
                    usize::from(!dead[i]),
                    "case {case}: piece {i} alive in one run"
                );
            }
            assert!(work.len() <= n + n / 8, "case {case}: the copies are at most an eighth");
        }
    }

    #[test]
    fn grouping_by_layer_is_a_stable_sort() {
        let mut rnd = below(0x1234_5678);
        for case in 0..200 {
            let n = rnd(60) as usize;
            let n_layers = 1 + rnd(5) as usize;
            // Some cases with one dominant layer, some with even layers.
            let layer_of: Vec<u32> = (0..n)
                .map(|_| {
                    if case % 2 == 0 && rnd(4) != 0 {
                        (case % n_layers) as u32
                    } else {
                        rnd(n_layers as u64) as u32
                    }
                })
                .collect();
            let mut work: Vec<Work> = (0..n)
                .map(|i| Work {
                    seg: line(i as f64, 0.0, i as f64, 1.0).0,
                    order: i as u32,
                    alive: true,
                })
                .collect();
            let mut want: Vec<u32> = (0..n as u32).collect();
            want.sort_by_key(|&i| layer_of[i as usize]);
            let runs = group_by_layer(&mut work, layer_of.clone(), &layer_counts(&layer_of, n_layers));
            let got: Vec<u32> = work.iter().map(|w| w.order).collect();
            assert_eq!(got, want, "case {case}: {layer_of:?}");
            for w in &work {
                assert_eq!(w.seg.start().x, w.order as f64);
            }
            let mut at = 0;
            for (l, from, to) in runs {
                assert_eq!(from, at);
                assert!(to > from);
                assert!(work[from..to].iter().all(|w| layer_of[w.order as usize] == l));
                at = to;
            }
            assert_eq!(at, n);
        }
    }
}
