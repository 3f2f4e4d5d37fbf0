//! Chain detection: from loose lines and arcs to ordered, oriented chains.
//!
//! Near-linear throughout, in four ideas, one file each:
//! - [`nodes`]: end points clustered into nodes with a spatial hash (and a
//!   short list of the nodes just seen, which catches the shared end of
//!   consecutive pieces without a probe);
//! - [`repair`]: zero-length pieces, collinear overlaps (buckets of
//!   direction and offset), duplicates (pieces between the same two nodes,
//!   found through the node adjacency), snapping;
//! - [`walk`]: the graph walk from nodes of degree != 2, then cycles;
//! - [`orient`]: nesting depth through a grid over the closed chains'
//!   boxes, and the exact point-in-chain and area tests.
//!
//! The thesis' method compares every pair of segments; this one never does.
//!
//! Every change to the drawing is counted in [`Report`] and noted on the
//! chain it touched (`repairs`).

mod nodes;
mod orient;
mod repair;
mod walk;

use crate::geometry::P3;
use crate::model::chain::{Chain, Segment};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

pub use orient::signed_area;

/// What chaining changed, for the stderr summary.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Report {
    pub zero_length: u64,
    pub duplicates: u64,
    pub overlaps: u64,
    pub gaps_closed: u64,
    pub max_gap: f64,
    pub reversed: u64,
    pub non_finite: u64,
    pub open: u64,
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

    /// The chains in output order with ids from 1.
    pub fn iter(&self) -> impl Iterator<Item = Chain> + Clone + '_ {
        (0..self.len()).filter_map(move |k| self.get(k))
    }
}

/// Join `segments` (each with a layer index into `layers`) into chains
/// within `tol`, and attach POINT entities as per-layer point chains.
pub fn build(segments: Vec<(Segment, u32)>, points: &[(P3, u32)], layers: &[String], tol: f64) -> (Chains, Report) {
    let tol = if tol.is_finite() { tol.max(0.0) } else { 0.0 };
    let mut report = Report::default();
    let layer_of: Vec<u32> = segments.iter().map(|(_, l)| *l).collect();
    // In place (same size and alignment): no second copy of the drawing.
    let mut work: Vec<Work> = segments
        .into_iter()
        .enumerate()
        .map(|(i, (seg, _))| Work {
            seg,
            order: i as u32,
            alive: true,
        })
        .collect();
    for x in work.iter_mut() {
        if !finite(&x.seg) {
            x.alive = false;
            report.non_finite += 1;
        }
    }
    if !layer_of.is_sorted() {
        work.sort_unstable_by_key(|x| (layer_of[x.order as usize], x.order));
    }
    let mut out = Chains {
        layers: layers.to_vec(),
        ..Default::default()
    };
    // Exactly what can survive: growth by doubling would leave up to half
    // of this array's memory unused at the peak.
    out.seq.reserve_exact(work.iter().filter(|x| x.alive).count());
    let mut repairs: Vec<(u32, Vec<String>)> = Vec::new();
    let mut from = 0;
    while from < work.len() {
        let l = layer_of[work[from].order as usize];
        let to = from + work[from..].partition_point(|x| layer_of[x.order as usize] == l);
        walk::chain_layer(
            &mut work[from..to],
            from as u32,
            l,
            tol,
            &mut report,
            &mut out,
            &mut repairs,
        );
        from = to;
    }
    drop(layer_of);
    out.work = work;
    orient::orient(&mut out, tol, &mut report);
    // Output order: by each chain's first piece in the drawing.
    let mut perm: Vec<u32> = (0..out.items.len() as u32).collect();
    perm.sort_unstable_by_key(|&k| out.items[k as usize].order);
    let mut rank = vec![0u32; perm.len()];
    for (pos, &k) in perm.iter().enumerate() {
        rank[k as usize] = pos as u32;
    }
    out.items = perm.iter().map(|&k| out.items[k as usize]).collect();
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
    for it in &out.items {
        if it.closed {
            report.closed += 1;
        } else {
            report.open += 1;
        }
    }
    (out, report)
}

/// Short, stable number text for repair notes.
pub(super) fn fmt_num(x: f64) -> String {
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::repair::snap;
    use super::*;

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

    fn build_vec(s: Vec<(Segment, u32)>, p: &[(P3, u32)], l: &[String], tol: f64) -> (Vec<Chain>, Report) {
        let (c, r) = build(s, p, l, tol);
        (c.iter().collect(), r)
    }

    fn layers() -> Vec<String> {
        vec!["0".into()]
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
}
