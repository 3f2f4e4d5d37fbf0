//! Chain detection: from loose lines and arcs to ordered, oriented chains.
//!
//! Near-linear throughout: end points are clustered with a spatial hash
//! (cells of the join tolerance, 3x3 neighbourhood), collinear overlaps are
//! found through a hash of (direction, offset), duplicates through the pair
//! of end nodes, and nesting through a grid over the closed chains' boxes.
//! The thesis' method compares every pair of segments; this one never does.
//!
//! Every change to the drawing is counted in [`Report`] and noted on the
//! chain it touched (`repairs`).

use crate::geometry::{P3, V3};
use crate::model::chain::{Chain, Segment};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

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
struct Fx(u64);

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

type FxMap<K, V> = HashMap<K, V, BuildHasherDefault<Fx>>;

fn finite(s: &Segment) -> bool {
    let ok = |p: &P3| p.iter().all(|x| x.is_finite());
    match s {
        Segment::Line { start, end } => ok(start) && ok(end),
        Segment::Arc { start, end, center, .. } => ok(start) && ok(end) && ok(center),
    }
}

pub use crate::model::chain::arc_sweep;

fn midpoint(s: &Segment) -> P3 {
    match *s {
        Segment::Line { start, end } => P3::from((start.coords + end.coords) * 0.5),
        Segment::Arc {
            start,
            end,
            center,
            ccw,
        } => {
            let r = (start - center).xy().norm();
            let a = (start.y - center.y).atan2(start.x - center.x) + 0.5 * arc_sweep(&start, &end, &center, ccw);
            P3::new(center.x + r * a.cos(), center.y + r * a.sin(), start.z)
        }
    }
}

/// Whether angle `t` lies on the arc from `start` (inclusive) sweeping
/// `sweep` radians (signed).
fn on_sweep(a0: f64, sweep: f64, t: f64) -> bool {
    let tau = std::f64::consts::TAU;
    let off = if sweep >= 0.0 {
        (t - a0).rem_euclid(tau)
    } else {
        (a0 - t).rem_euclid(tau)
    };
    off <= sweep.abs()
}

/// The XY box of a segment, arcs included exactly (their axis extremes).
fn seg_box(s: &Segment, lo: &mut (f64, f64), hi: &mut (f64, f64)) {
    let mut grow = |x: f64, y: f64| {
        *lo = (lo.0.min(x), lo.1.min(y));
        *hi = (hi.0.max(x), hi.1.max(y));
    };
    let (p, q) = (s.start(), s.end());
    grow(p.x, p.y);
    grow(q.x, q.y);
    if let Segment::Arc {
        start,
        end,
        center,
        ccw,
    } = s
    {
        let r = (start - center).xy().norm();
        let a0 = (start.y - center.y).atan2(start.x - center.x);
        let sw = arc_sweep(start, end, center, *ccw);
        for k in 0..4 {
            let t = k as f64 * std::f64::consts::FRAC_PI_2;
            if on_sweep(a0, sw, t) {
                grow(center.x + r * t.cos(), center.y + r * t.sin());
            }
        }
    }
}

/// Point in a closed chain: the parity of crossings of the ray from `p`
/// towards +X, with lines and arcs exactly (no tessellation, so memory
/// does not grow with arc counts).
fn inside(segs: &[Segment], p: &P3) -> bool {
    let mut c = false;
    for s in segs {
        match *s {
            Segment::Line { start: a, end: b } => {
                if (a.y > p.y) != (b.y > p.y) {
                    let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
                    if x > p.x {
                        c = !c;
                    }
                }
            }
            Segment::Arc {
                start,
                end,
                center,
                ccw,
            } => {
                let r = (start - center).xy().norm();
                let dy = p.y - center.y;
                if dy.abs() >= r {
                    continue;
                }
                let dx = (r * r - dy * dy).sqrt();
                let a0 = (start.y - center.y).atan2(start.x - center.x);
                let sw = arc_sweep(&start, &end, &center, ccw);
                for x in [center.x - dx, center.x + dx] {
                    if x > p.x && on_sweep(a0, sw, dy.atan2(x - center.x)) {
                        // Half-open at the arc's end, so a crossing exactly
                        // at a shared vertex counts once.
                        let at_end = (P3::new(x, p.y, end.z) - end).xy().norm() <= 1e-12 * r.max(1.0);
                        if !at_end {
                            c = !c;
                        }
                    }
                }
            }
        }
    }
    c
}

/// Exact signed area enclosed by a closed chain (positive = counter-clockwise).
pub fn signed_area(segs: &[Segment]) -> f64 {
    let mut a = 0.0;
    for s in segs {
        let (p, q) = (s.start(), s.end());
        a += 0.5 * (p.x * q.y - q.x * p.y);
        if let Segment::Arc {
            start,
            end,
            center,
            ccw,
        } = s
        {
            let r2 = (start - center).xy().norm_squared();
            let sw = arc_sweep(start, end, center, *ccw);
            a += 0.5 * r2 * (sw - sw.sin());
        }
    }
    a
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

    /// The chains in output order with ids from 1.
    pub fn iter(&self) -> impl Iterator<Item = Chain> + Clone + '_ {
        let segs = self.items.iter().enumerate().map(|(k, it)| Chain {
            id: k as u64 + 1,
            layer: self.layers.get(it.layer as usize).cloned(),
            closed: it.closed,
            segments: {
                let mut v = Vec::with_capacity(it.len as usize);
                self.segments_into(it, &mut v);
                v
            },
            points: Vec::new(),
            repairs: self.repairs.get(&(k as u32)).cloned().unwrap_or_default(),
        });
        let n = self.items.len();
        let pts = self.points.iter().enumerate().map(move |(k, (l, p))| Chain {
            id: (n + k) as u64 + 1,
            layer: self.layers.get(*l as usize).cloned(),
            points: p.clone(),
            ..Default::default()
        });
        segs.chain(pts)
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
        chain_layer(
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
    orient(&mut out, tol, &mut report);
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

fn chain_layer(
    w: &mut [Work],
    base: u32,
    layer: u32,
    tol: f64,
    report: &mut Report,
    out: &mut Chains,
    repairs_out: &mut Vec<(u32, Vec<String>)>,
) {
    let mut notes = Notes::default();
    // 1. Zero-length pieces.
    for x in w.iter_mut() {
        let r = match x.seg {
            Segment::Arc { start, center, .. } => (start - center).xy().norm(),
            _ => f64::INFINITY,
        };
        if x.alive && (x.seg.length() <= tol || r <= tol) {
            x.alive = false;
            report.zero_length += 1;
        }
    }
    merge_collinear(w, &mut notes, tol, report);

    // 2. End points to nodes. Cells are twice the tolerance wide, so every
    // node within the tolerance of a point is in the 2x2 block of cells
    // nearest to it. Each cell keeps its first node; the others follow
    // through `next` (no allocation per cell).
    let cell = (2.0 * tol).max(1e-9);
    // Cell coordinates packed into one word: cells 2^32 apart share a key,
    // which only adds candidates (the distance test is exact) and halves
    // the table.
    let ckey = |x: i64, y: i64| ((x as u32 as u64) << 32) | (y as u32 as u64);
    let mut grid: FxMap<u64, u32> = FxMap::default();
    grid.reserve(w.len());
    let mut next: Vec<u32> = Vec::new();
    let mut reps: Vec<P3> = Vec::new();
    let mut gaps: Vec<f64> = Vec::new();
    let mut ends: Vec<(u32, u32)> = vec![(u32::MAX, u32::MAX); w.len()];
    const NONE: u32 = u32::MAX;
    let mut node_of = |p: &P3| {
        let fx = p.x / cell;
        let fy = p.y / cell;
        let (cx, cy) = (fx.floor() as i64, fy.floor() as i64);
        let sx = if fx - fx.floor() < 0.5 { -1 } else { 1 };
        let sy = if fy - fy.floor() < 0.5 { -1 } else { 1 };
        let mut best: Option<u32> = None;
        for (dx, dy) in [(0, 0), (sx, 0), (0, sy), (sx, sy)] {
            let mut id = grid.get(&ckey(cx + dx, cy + dy)).copied().unwrap_or(NONE);
            while id != NONE {
                if (reps[id as usize] - p).norm() <= tol && best.is_none_or(|b| id < b) {
                    best = Some(id);
                }
                id = next[id as usize];
            }
        }
        match best {
            Some(id) => {
                let g = (reps[id as usize] - p).norm();
                if g > gaps[id as usize] {
                    gaps[id as usize] = g;
                }
                id
            }
            None => {
                let id = reps.len() as u32;
                reps.push(*p);
                gaps.push(0.0);
                let head = grid.entry(ckey(cx, cy)).or_insert(NONE);
                next.push(*head);
                *head = id;
                id
            }
        }
    };
    for (i, x) in w.iter().enumerate() {
        if !x.alive {
            continue;
        }
        let a = node_of(&x.seg.start());
        let b = node_of(&x.seg.end());
        ends[i] = (a, b);
    }
    drop(grid);
    drop(next);

    // 3. Duplicates between the same pair of nodes.
    // Pieces between one pair of nodes: the first in `pairs`, the rest
    // through `same_next`.
    let mut pairs: FxMap<(u32, u32), u32> = FxMap::default();
    pairs.reserve(w.len());
    let mut same_next: Vec<u32> = vec![NONE; w.len()];
    for i in 0..w.len() {
        if !w[i].alive {
            continue;
        }
        let (a, b) = ends[i];
        if a == b && matches!(w[i].seg, Segment::Line { .. }) {
            // Both ends in one node: shorter than the tolerance across.
            w[i].alive = false;
            report.zero_length += 1;
            continue;
        }
        let key = (a.min(b), a.max(b));
        let head = pairs.entry(key).or_insert(NONE);
        let mut dup_of = None;
        let mut j = *head as usize;
        while j != NONE as usize {
            let same = match (&w[i].seg, &w[j].seg) {
                (Segment::Line { .. }, Segment::Line { .. }) => true,
                (Segment::Arc { center: c1, .. }, Segment::Arc { center: c2, .. }) => {
                    (c1 - c2).norm() <= tol && (midpoint(&w[i].seg) - midpoint(&w[j].seg)).norm() <= tol
                }
                _ => false,
            };
            if same {
                dup_of = Some(j);
                break;
            }
            j = same_next[j] as usize;
        }
        match dup_of {
            Some(j) => {
                w[i].alive = false;
                report.duplicates += 1;
                let p = midpoint(&w[i].seg);
                notes
                    .entry(j)
                    .or_default()
                    .push(format!("duplicate removed at [{}, {}]", fmt_num(p.x), fmt_num(p.y)));
            }
            None => {
                same_next[i] = *head;
                *head = i as u32;
            }
        }
    }
    drop(pairs);
    drop(same_next);

    // 4. Walk the graph: open chains from nodes of degree != 2, then cycles.
    let n_nodes = reps.len();
    let mut start_idx = vec![0u32; n_nodes + 1];
    for (i, x) in w.iter().enumerate() {
        if x.alive {
            start_idx[ends[i].0 as usize + 1] += 1;
            start_idx[ends[i].1 as usize + 1] += 1;
        }
    }
    for k in 0..n_nodes {
        start_idx[k + 1] += start_idx[k];
    }
    let mut adj = vec![0u32; start_idx[n_nodes] as usize];
    let mut fill = start_idx.clone();
    for (i, x) in w.iter().enumerate() {
        if x.alive {
            for n in [ends[i].0, ends[i].1] {
                adj[fill[n as usize] as usize] = i as u32;
                fill[n as usize] += 1;
            }
        }
    }
    drop(fill);
    let degree = |n: u32| start_idx[n as usize + 1] - start_idx[n as usize];
    let mut used = vec![false; w.len()];
    // Each walk fills `run` (reused) and is turned into a chain at once:
    // no list of all runs is ever held.
    let walk = |first_node: u32, first: usize, used: &mut Vec<bool>, run: &mut Vec<(usize, bool)>| -> u32 {
        run.clear();
        let mut cur = first_node;
        let mut s = first;
        loop {
            used[s] = true;
            let (a, b) = ends[s];
            let fwd = a == cur;
            let next = if fwd { b } else { a };
            run.push((s, fwd));
            cur = next;
            if cur == first_node || degree(cur) != 2 {
                break;
            }
            let lo = start_idx[cur as usize] as usize;
            let hi = start_idx[cur as usize + 1] as usize;
            match adj[lo..hi].iter().find(|&&t| !used[t as usize]) {
                Some(&t) => s = t as usize,
                None => break,
            }
        }
        cur
    };
    let mut run: Vec<(usize, bool)> = Vec::new();
    let alive: Vec<bool> = w.iter().map(|x| x.alive).collect();
    let mut emit = |run: &[(usize, bool)], first: u32, last: u32| {
        let start = out.seq.len() as u32;
        let mut repairs: Vec<String> = Vec::new();
        let mut order = u32::MAX;
        let mut gap_nodes: Vec<u32> = Vec::new();
        for &(i, fwd) in run {
            order = order.min(w[i].order);
            let (a, b) = ends[i];
            let (na, nb) = if fwd { (a, b) } else { (b, a) };
            let seg = if fwd { w[i].seg } else { w[i].seg.reversed() };
            // Snapped in place, turned to the direction of travel.
            w[i].seg = snap(&seg, reps[na as usize], reps[nb as usize]);
            out.seq.push(base + i as u32);
            if let Some(mut v) = notes.remove(&i) {
                repairs.append(&mut v);
            }
            for n in [na, nb] {
                if gaps[n as usize] > REPORT_GAP && !gap_nodes.contains(&n) {
                    gap_nodes.push(n);
                }
            }
        }
        for n in gap_nodes {
            let g = gaps[n as usize];
            let p = reps[n as usize];
            report.gaps_closed += 1;
            report.max_gap = report.max_gap.max(g);
            repairs.push(format!(
                "gap of {} mm closed at [{}, {}]",
                fmt_num(g),
                fmt_num(p.x),
                fmt_num(p.y)
            ));
        }
        if !repairs.is_empty() {
            repairs_out.push((out.items.len() as u32, repairs));
        }
        out.items.push(Item {
            start,
            len: out.seq.len() as u32 - start,
            order,
            layer,
            closed: first == last,
            reversed: false,
        });
    };
    for n in 0..n_nodes as u32 {
        if degree(n) == 2 {
            continue;
        }
        let lo = start_idx[n as usize] as usize;
        let hi = start_idx[n as usize + 1] as usize;
        for &s in &adj[lo..hi] {
            let s = s as usize;
            if !used[s] {
                let last = walk(n, s, &mut used, &mut run);
                emit(&run, n, last);
            }
        }
    }
    for (i, &a) in alive.iter().enumerate() {
        if a && !used[i] {
            let last = walk(ends[i].0, i, &mut used, &mut run);
            emit(&run, ends[i].0, last);
        }
    }
}

/// Short, stable number text for repair notes.
fn fmt_num(x: f64) -> String {
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// Move a segment's ends to `a` and `b`; an arc's centre moves onto the
/// new ends' bisector so that both ends stay on one circle.
fn snap(s: &Segment, a: P3, b: P3) -> Segment {
    match *s {
        Segment::Line { .. } => Segment::Line { start: a, end: b },
        Segment::Arc { start, center, ccw, .. } => {
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
            Segment::Arc {
                start: a,
                end: b,
                center,
                ccw,
            }
        }
    }
}

/// Merge lines lying on one another: exact and near duplicates and partial
/// overlaps become one line spanning their union.
///
/// Lines are grouped by (direction, offset from the origin) buckets; each
/// group, together with its neighbouring buckets (a line a hair across a
/// bucket boundary), is swept in order along its direction, comparing each
/// line only with the lines whose span it reaches. Rows of equal lines (a
/// grid of parts) therefore cost n log n, not n squared.
fn merge_collinear(w: &mut [Work], notes: &mut Notes, tol: f64, report: &mut Report) {
    const ANGLE_BUCKET: f64 = 1e-4;
    let off_bucket = (2.0 * tol).max(1e-9);
    let n_ang = (std::f64::consts::PI / ANGLE_BUCKET).ceil() as i64;
    // (bucket, line) sorted: each bucket is a contiguous range, found by
    // binary search; no table of vectors.
    let mut keyed: Vec<((i64, i64), u32)> = Vec::new();
    for (i, x) in w.iter().enumerate() {
        let Segment::Line { start: a, end: b } = x.seg else {
            continue;
        };
        let len = (b - a).xy().norm();
        // Only lines in a plane of constant z can lie on one another here.
        if !x.alive || len <= tol || (b.z - a.z).abs() > tol {
            continue;
        }
        let mut d = (b - a).xy() / len;
        if d.y < 0.0 || (d.y == 0.0 && d.x < 0.0) {
            d = -d;
        }
        let ai = ((d.y.atan2(d.x) / ANGLE_BUCKET).floor() as i64).clamp(0, n_ang - 1);
        let off = d.x * a.y - d.y * a.x;
        keyed.push(((ai, (off / off_bucket).floor() as i64), i as u32));
    }
    keyed.sort_unstable();
    // Where each bucket's range starts and ends: one hash probe per
    // neighbour instead of a binary search over all lines.
    let mut ranges: FxMap<(i64, i64), (u32, u32)> = FxMap::default();
    let mut g = 0;
    while g < keyed.len() {
        let end = g + keyed[g..].partition_point(|e| e.0 == keyed[g].0);
        ranges.insert(keyed[g].0, (g as u32, end as u32));
        g = end;
    }
    let range_of = |k: (i64, i64)| ranges.get(&k).map_or(0..0, |&(a, b)| a as usize..b as usize);
    let mut cand: Vec<usize> = Vec::new();
    let mut active: Vec<usize> = Vec::new();
    let mut g = 0;
    while g < keyed.len() {
        let key = keyed[g].0;
        let first = keyed[g].1 as usize;
        g += keyed[g..].partition_point(|e| e.0 == key);
        cand.clear();
        for da in -1..=1 {
            // Directions are folded into [0, pi): a line just below pi is a
            // neighbour of one just above 0, with its offset's sign flipped.
            let raw = key.0 + da;
            let wrapped = !(0..n_ang).contains(&raw);
            let a_key = raw.rem_euclid(n_ang);
            for dofs in -1..=1 {
                let o_key = if wrapped { -key.1 - 1 + dofs } else { key.1 + dofs };
                cand.extend(
                    keyed[range_of((a_key, o_key))]
                        .iter()
                        .map(|e| e.1 as usize)
                        .filter(|&i| w[i].alive),
                );
            }
        }
        if cand.len() < 2 {
            continue;
        }
        let Segment::Line { start: p, end: q } = w[first].seg else {
            continue;
        };
        let d = (q - p).xy().normalize();
        let span = |s: &Segment| {
            let (a, b) = (s.start(), s.end());
            let (x, y) = (d.x * a.x + d.y * a.y, d.x * b.x + d.y * b.y);
            (x.min(y), x.max(y))
        };
        cand.sort_by(|&i, &j| span(&w[i].seg).0.total_cmp(&span(&w[j].seg).0).then(i.cmp(&j)));
        cand.dedup();
        active.clear();
        for &i in cand.iter() {
            if !w[i].alive {
                continue;
            }
            let (lo, _) = span(&w[i].seg);
            active.retain(|&k| w[k].alive && span(&w[k].seg).1 >= lo - tol);
            let Segment::Line { start: a, end: b } = w[i].seg else {
                continue;
            };
            let mut merged = false;
            for &k in active.iter() {
                if let Some((start, end, dup)) = overlap(&w[k].seg, a, b, tol) {
                    w[k].seg = Segment::Line { start, end };
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

/// If line `a`-`b` lies along `kept` (within `tol`, same z) and overlaps it
/// by more than `tol`, the union's ends (in `kept`'s direction) and whether
/// `a`-`b` was a duplicate (same ends within `tol`).
fn overlap(kept: &Segment, a: P3, b: P3, tol: f64) -> Option<(P3, P3, bool)> {
    let Segment::Line { start: p, end: q } = *kept else {
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

/// Orient closed chains by nesting depth: even depth (outer contours)
/// counter-clockwise, odd depth (holes) clockwise.
fn orient(chains: &mut Chains, tol: f64, report: &mut Report) {
    struct Info {
        idx: usize,
        lo: (f64, f64),
        hi: (f64, f64),
        area: f64,
        probe: P3,
    }
    let mut infos: Vec<Info> = Vec::new();
    let mut buf: Vec<Segment> = Vec::new();
    for (idx, it) in chains.items.iter().enumerate() {
        if !it.closed || it.len == 0 {
            continue;
        }
        chains.segments_into(it, &mut buf);
        let segs = &buf[..];
        let mut lo = (f64::INFINITY, f64::INFINITY);
        let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for s in segs {
            seg_box(s, &mut lo, &mut hi);
        }
        infos.push(Info {
            idx,
            lo,
            hi,
            area: signed_area(segs),
            probe: midpoint(&segs[0]),
        });
    }
    if infos.is_empty() {
        return;
    }
    // A grid over the boxes: each chain is listed in the cells its box
    // covers (or in `big` when that would be too many cells).
    let total: f64 = infos
        .iter()
        .map(|i| (i.hi.0 - i.lo.0).max(tol) * (i.hi.1 - i.lo.1).max(tol))
        .sum();
    let size = (total / infos.len() as f64).sqrt().max(1e-9);
    // (cell, chain) pairs sorted by cell: a cell's chains are a contiguous
    // range found by binary search (a table of vectors would cost more than
    // the chains themselves).
    let ckey = |x: i64, y: i64| ((x as u32 as u64) << 32) | (y as u32 as u64);
    let mut grid: Vec<(u64, u32)> = Vec::new();
    let mut big: Vec<u32> = Vec::new();
    for (k, i) in infos.iter().enumerate() {
        let (x0, y0) = ((i.lo.0 / size).floor() as i64, (i.lo.1 / size).floor() as i64);
        let (x1, y1) = ((i.hi.0 / size).floor() as i64, (i.hi.1 / size).floor() as i64);
        // In i128: far-out boxes (the casts saturate) must not wrap into a
        // small, or a huge, cell range.
        let cells = (x1 as i128 - x0 as i128 + 1) * (y1 as i128 - y0 as i128 + 1);
        if !(1..=256).contains(&cells) {
            big.push(k as u32);
            continue;
        }
        for x in x0..=x1 {
            for y in y0..=y1 {
                grid.push((ckey(x, y), k as u32));
            }
        }
    }
    grid.sort_unstable();
    // Probes sorted by cell too, so the grid is walked once, in order.
    let mut probes: Vec<(u64, u32)> = infos
        .iter()
        .enumerate()
        .map(|(k, i)| {
            (
                ckey((i.probe.x / size).floor() as i64, (i.probe.y / size).floor() as i64),
                k as u32,
            )
        })
        .collect();
    probes.sort_unstable();
    let mut flip: Vec<usize> = Vec::new();
    let mut lo = 0;
    for &(cell, k) in &probes {
        let k = k as usize;
        let me = &infos[k];
        let p = me.probe;
        while lo < grid.len() && grid[lo].0 < cell {
            lo += 1;
        }
        let hi = lo + grid[lo..].iter().take_while(|e| e.0 == cell).count();
        let mut depth = 0;
        for j in grid[lo..hi].iter().map(|e| e.1).chain(big.iter().copied()) {
            let o = &infos[j as usize];
            if j as usize == k
                || o.area.abs() <= me.area.abs()
                || o.lo.0 > me.lo.0 + tol
                || o.lo.1 > me.lo.1 + tol
                || o.hi.0 < me.hi.0 - tol
                || o.hi.1 < me.hi.1 - tol
            {
                continue;
            }
            chains.segments_into(&chains.items[o.idx], &mut buf);
            if inside(&buf, &p) {
                depth += 1;
            }
        }
        let want_ccw = depth % 2 == 0;
        if me.area != 0.0 && (me.area > 0.0) != want_ccw {
            flip.push(me.idx);
        }
    }
    flip.sort_unstable();
    for idx in flip {
        chains.items[idx].reversed = true;
        report.reversed += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: f64, y0: f64, x1: f64, y1: f64) -> (Segment, u32) {
        (
            Segment::Line {
                start: P3::new(x0, y0, 0.0),
                end: P3::new(x1, y1, 0.0),
            },
            0,
        )
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
        let arc = Segment::Arc {
            start: P3::new(1.0, 0.0, 0.0),
            end: P3::new(0.0, 1.0, 0.0),
            center: P3::origin(),
            ccw: true,
        };
        let s = snap(&arc, P3::new(1.0004, 0.0, 0.0), P3::new(0.0, 0.9997, 0.0));
        let Segment::Arc { start, end, center, .. } = s else {
            panic!()
        };
        assert!(((start - center).norm() - (end - center).norm()).abs() < 1e-12);
    }

    #[test]
    fn full_circle_area() {
        let c = Segment::Arc {
            start: P3::new(2.0, 0.0, 0.0),
            end: P3::new(2.0, 0.0, 0.0),
            center: P3::origin(),
            ccw: false,
        };
        assert!((signed_area(&[c]) + 4.0 * std::f64::consts::PI).abs() < 1e-12);
        let (ch, _) = build_vec(vec![(c, 0)], &[], &layers(), 0.001);
        assert!(ch[0].closed);
        assert!(signed_area(&ch[0].segments) > 0.0);
    }
}
