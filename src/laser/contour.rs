//! `pathgen contour`: chains -> offset paths -> ordered, planned moves.

use super::cleanup::{CleanOptions, CleanStats, clean_path};
use super::constant_velocity::{Note, plan_path, to_records};
use super::offset::{Side, offset_chain, to_polyline};
use super::order;
use super::setup::LaserSetup;
use crate::geometry::Segment;
use crate::geometry::{P2, P3, V3};
use crate::model::chain::Chain;
use crate::model::toolpath::Record;
use cavalier_contours::polyline::PlineSource;
use rayon::prelude::*;

/// Travel sense of closed paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// As drawn (after offsetting).
    Keep,
    /// Counter-clockwise seen from +Z.
    Ccw,
    /// Clockwise seen from +Z.
    Cw,
}

/// How chains are ordered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrderMode {
    /// Input order.
    Input,
    /// Nearest neighbour, as in Bayesteh (2013).
    Nearest,
    /// Nearest neighbour improved by 2-opt and Or-opt.
    Optimized,
}

/// What `pathgen contour` is asked for, beyond the machine.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourOptions {
    /// Which side of each chain the beam centre runs on; inside and
    /// outside are of the part, so a hole's sides swap.
    pub side: Side,
    /// Offset from the chain (mm, not negative); 0 cuts on the line.
    pub distance: f64,
    /// Passes per chain, each `level_step` further along Z.
    pub levels: u32,
    /// Z shift between passes (mm; negative goes down).
    pub level_step: f64,
    /// Copies of the whole job in X and Y, `pitch` apart.
    pub array: (u32, u32),
    /// Distance between copies in X and Y (mm).
    pub pitch: (f64, f64),
    /// Start closed paths at their vertex nearest this point; without it
    /// they start at their first corner, so the seam costs no loop.
    pub start_near: Option<P2>,
    /// Travel sense of closed paths.
    pub direction: Direction,
    /// How chains are ordered.
    pub order: OrderMode,
    /// Where the machine starts (for ordering).
    pub origin: P2,
    /// Largest deviation (mm) the cleanup may make to remove pieces shorter
    /// than the machine's least block ([`super::cleanup`]); 0 turns it off.
    pub cleanup_tol: f64,
}

/// Default of [`ContourOptions::cleanup_tol`]: 1 µm, a fifth of the
/// default beam radius (5 µm) and ten times the 4-decimal rounding.
pub const DEFAULT_CLEANUP_TOL: f64 = 0.001;

impl Default for ContourOptions {
    fn default() -> Self {
        ContourOptions {
            side: Side::On,
            distance: 0.0,
            levels: 1,
            level_step: 0.0,
            array: (1, 1),
            pitch: (0.0, 0.0),
            start_near: None,
            direction: Direction::Keep,
            order: OrderMode::Optimized,
            origin: P2::origin(),
            cleanup_tol: DEFAULT_CLEANUP_TOL,
        }
    }
}

/// Something to tell the user, tied to a chain.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// The chain's id (`microcam.chains/1`).
    pub chain: u64,
    /// What happened, one line for the user.
    pub message: String,
}

/// A planned job: moves and what the user should know.
#[derive(Debug, Default)]
pub struct ContourJob {
    /// The toolpath: the ramps first, then every path's moves in cutting
    /// order.
    pub records: Vec<Record>,
    /// One per chain and kind of note.
    pub warnings: Vec<Warning>,
    /// What the cleanup of short pieces did (once per path, not per copy).
    pub cleanup: CleanStats,
}

pub use crate::geometry::segment::signed_area;

fn reverse_path(path: &mut [Segment]) {
    path.reverse();
    for e in path.iter_mut() {
        *e = e.reversed();
    }
}

/// Rotate a closed path to start at its vertex nearest `q` (the lowest
/// index among equally near ones).
pub(crate) fn start_near(path: &mut [Segment], q: &P2) {
    let best = (0..path.len()).min_by(|&a, &b| {
        let da = (path[a].start().xy() - q).norm();
        let db = (path[b].start().xy() - q).norm();
        da.total_cmp(&db).then(a.cmp(&b))
    });
    if let Some(k) = best {
        path.rotate_left(k);
    }
}

/// Rotate a closed path to start at its first non-tangent joint, so the
/// seam (lead-out then lead-in) falls on a corner: that saves a loop there
/// and never leaves a stub shorter than the minimum exposure before it.
fn start_at_corner(path: &mut [Segment], cos_tol: f64) {
    let n = path.len();
    let k = (0..n).find(|&i| path[(i + n - 1) % n].end_tangent().dot(&path[i].start_tangent()) < cos_tol);
    if let Some(k) = k {
        path.rotate_left(k);
    }
}

struct Item {
    chain: u64,
    path: Vec<Segment>,
    /// Index of the outermost closed chain containing this one (itself if none).
    root: usize,
    /// How many closed chains contain this one.
    depth: usize,
}

/// Which closed chains contain which: (root, depth) per chain. A chain is
/// inside another when its box is inside the other's box and its first
/// point has a non-zero winding number about it.
fn nesting(chains: &[Chain]) -> Vec<(usize, usize)> {
    let plines: Vec<_> = chains.par_iter().map(to_polyline).collect();
    let boxes: Vec<Option<(P2, P2)>> = plines
        .iter()
        .zip(chains)
        .map(|(p, c)| {
            if !c.closed || p.vertex_count() == 0 {
                return None;
            }
            p.extents()
                .map(|e| (P2::new(e.min_x, e.min_y), P2::new(e.max_x, e.max_y)))
        })
        .collect();
    // A uniform grid of about n cells; each closed chain's box is listed in
    // every cell it overlaps, so a query point meets only the boxes around
    // it (one big outer contour is listed everywhere, which is fine).
    let mut lo = P2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (a, b) in boxes.iter().flatten() {
        lo = lo.inf(a);
        hi = hi.sup(b);
    }
    let side = (boxes.iter().flatten().count() as f64).sqrt().ceil().clamp(1.0, 1024.0) as usize;
    let cell = ((hi - lo).max() / side as f64).max(1e-9);
    let idx = |v: f64, o: f64| (((v - o) / cell).max(0.0) as usize).min(side - 1);
    let mut grid: Vec<Vec<usize>> = vec![Vec::new(); if lo.x.is_finite() { side * side } else { 0 }];
    for (j, b) in boxes.iter().enumerate() {
        if let Some((a, b)) = b {
            for y in idx(a.y, lo.y)..=idx(b.y, lo.y) {
                for x in idx(a.x, lo.x)..=idx(b.x, lo.x) {
                    grid[y * side + x].push(j);
                }
            }
        }
    }
    let containers: Vec<Vec<usize>> = (0..chains.len())
        .into_par_iter()
        .map(|i| {
            let Some(first) = chains[i].segments.first() else {
                return Vec::new();
            };
            let q = first.start();
            let (blo, bhi) = boxes[i].unwrap_or((q.xy(), q.xy()));
            if grid.is_empty() || q.x < lo.x || q.y < lo.y || q.x > hi.x || q.y > hi.y {
                return Vec::new();
            }
            grid[idx(q.y, lo.y) * side + idx(q.x, lo.x)]
                .iter()
                .copied()
                .filter(|&j| {
                    j != i && {
                        let (a, b) = boxes[j].expect("only boxes are listed");
                        a.x <= blo.x && a.y <= blo.y && b.x >= bhi.x && b.y >= bhi.y
                    }
                })
                .filter(|&j| plines[j].winding_number(cavalier_contours::core::math::Vector2::new(q.x, q.y)) != 0)
                .collect()
        })
        .collect();
    containers
        .iter()
        .enumerate()
        .map(|(i, cs)| {
            // The root is the container that nobody else contains.
            let root = cs.iter().copied().find(|&j| containers[j].is_empty()).unwrap_or(i);
            (root, cs.len())
        })
        .collect()
}

/// Least number of moves a contour job makes: every chain's pieces plus
/// its rapid, lead-in and two lead-out moves, for every level and copy.
/// pathgen refuses a job past its `--max-moves` on this figure before
/// allocating anything for it.
pub fn estimated_moves(chains: &[Chain], o: &ContourOptions) -> f64 {
    let per_pass: f64 = chains.iter().map(|c| c.segments.len() as f64 + 4.0).sum();
    per_pass * f64::from(o.levels.max(1)) * f64::from(o.array.0.max(1)) * f64::from(o.array.1.max(1))
}

/// Plan a whole contour job: offset, clean, orient and order every chain,
/// then plan each path at constant velocity, for every level and array
/// copy.
pub fn contour(chains: &[Chain], m: &LaserSetup, o: &ContourOptions) -> ContourJob {
    let (items, plan, warnings, cleanup) = prepare(chains, m, o);
    let mut job = ContourJob {
        records: vec![super::constant_velocity::ramps_record(m)],
        warnings,
        cleanup,
    };
    job.warnings
        .extend(plan_in_chunks(&items, &plan, m, usize::MAX, |recs| {
            job.records.extend(recs);
            true
        }));
    job
}

/// The paths [`contour`] cuts for each chain, before ordering and
/// planning: offset on the side the chain's nesting gives it (a hole gets
/// the other side), cleaned of pieces shorter than the machine's least
/// block, in the travel sense asked for. Tests and reports use this to
/// know what must be cut.
pub fn cut_paths(chains: &[Chain], m: &LaserSetup, o: &ContourOptions) -> Vec<(Vec<Vec<Segment>>, CleanStats)> {
    let nest = nesting(chains);
    chains
        .par_iter()
        .zip(&nest)
        .map(|(c, &(_, depth))| {
            let (paths, st, _) = chain_paths(c, depth, m, o);
            (paths, st)
        })
        .collect()
}

/// One chain's cut paths (see [`cut_paths`]) and a warning when its offset vanishes.
fn chain_paths(
    c: &Chain,
    depth: usize,
    m: &LaserSetup,
    o: &ContourOptions,
) -> (Vec<Vec<Segment>>, CleanStats, Option<Warning>) {
    // Inside/outside are relative to the part: a hole (a chain inside
    // an odd number of others) is material's outside, so swap.
    let side = match (o.side, depth % 2 == 1) {
        (Side::Inside, true) => Side::Outside,
        (Side::Outside, true) => Side::Inside,
        (s, _) => s,
    };
    let mut paths = offset_chain(c, side, o.distance);
    // A chain of zero-length pieces has nothing to cut.
    paths.retain(|p| !p.is_empty());
    let clean = CleanOptions {
        min_len: m.min_block(),
        tol: o.cleanup_tol,
    };
    let mut stats = CleanStats::default();
    for p in &mut paths {
        let closed = !p.is_empty() && (p[0].start() - p[p.len() - 1].end()).norm() < 1e-9;
        let (q, st) = clean_path(std::mem::take(p), closed, &clean);
        *p = q;
        stats.add(&st);
        if !closed {
            continue;
        }
        let a = signed_area(p);
        if (o.direction == Direction::Ccw && a < 0.0) || (o.direction == Direction::Cw && a > 0.0) {
            reverse_path(p);
        }
        match &o.start_near {
            Some(q) => start_near(p, q),
            None => start_at_corner(p, m.tangent_cos()),
        }
    }
    let warn = (paths.is_empty() && !c.segments.is_empty()).then(|| Warning {
        chain: c.id,
        message: format!(
            "offset {} mm {} makes the chain vanish; dropped",
            o.distance,
            format!("{side:?}").to_lowercase()
        ),
    });
    (paths, stats, warn)
}

/// Offsets, nesting and order: the paths to plan, as (item, shift) in
/// cutting order, the warnings so far and what the cleanup did.
#[allow(clippy::type_complexity)]
fn prepare(
    chains: &[Chain],
    m: &LaserSetup,
    o: &ContourOptions,
) -> (Vec<Item>, Vec<(usize, V3)>, Vec<Warning>, CleanStats) {
    // Progress (a tool's bar) in three stages: offsets, order, planning.
    crate::progress::stage("offsetting chains", chains.len() as u64);
    let nest = nesting(chains);
    let per_chain: Vec<(Vec<Vec<Segment>>, CleanStats, Option<Warning>)> = chains
        .par_iter()
        .zip(&nest)
        .map(|(c, &(_, depth))| {
            let r = chain_paths(c, depth, m, o);
            crate::progress::advance(1);
            r
        })
        .collect();
    let mut warnings = Vec::new();
    let mut items: Vec<Item> = Vec::new();
    let mut cleanup = CleanStats::default();
    for (i, (paths, st, warn)) in per_chain.into_iter().enumerate() {
        warnings.extend(warn);
        cleanup.add(&st);
        for path in paths {
            items.push(Item {
                chain: chains[i].id,
                path,
                root: nest[i].0,
                depth: nest[i].1,
            });
        }
    }
    crate::progress::stage("ordering cuts (rounds)", 0);
    let sequence = order_items(&items, o);
    // Whole job per array cell (serpentine so cells link short), each
    // level of every chain inside it.
    let mut plan: Vec<(usize, V3)> = Vec::new();
    for iy in 0..o.array.1.max(1) {
        for k in 0..o.array.0.max(1) {
            let ix = if iy % 2 == 0 { k } else { o.array.0.max(1) - 1 - k };
            for lv in 0..o.levels.max(1) {
                let d = V3::new(ix as f64 * o.pitch.0, iy as f64 * o.pitch.1, lv as f64 * o.level_step);
                plan.extend(sequence.iter().map(|&it| (it, d)));
            }
        }
    }
    crate::progress::stage("planning paths", plan.len() as u64);
    (items, plan, warnings, cleanup)
}

/// Plan `plan` (item, shift) in chunks of `chunk` paths, each chunk on
/// every core, handing each chunk's moves to `sink` in order (so a writer
/// can format one chunk while the next is planned). `sink` returns false
/// to stop early. Returns the warnings, one per chain and kind.
fn plan_in_chunks(
    items: &[Item],
    plan: &[(usize, V3)],
    m: &LaserSetup,
    chunk: usize,
    mut sink: impl FnMut(Vec<Record>) -> bool,
) -> Vec<Warning> {
    let mut warnings = Vec::new();
    for part in plan.chunks(chunk.max(1)) {
        let planned: Vec<(Vec<Record>, Vec<Note>)> = part
            .par_iter()
            .map(|&(it, d)| {
                let path: Vec<Segment> = items[it].path.iter().map(|e| e.translated(d)).collect();
                let mut notes = Vec::new();
                let pieces = plan_path(&path, m, &mut notes);
                let mut recs = Vec::with_capacity(pieces.len() + 1);
                to_records(&pieces, m, Some(items[it].chain), &mut recs);
                (recs, notes)
            })
            .collect();
        crate::progress::advance(part.len() as u64);
        let mut recs = Vec::with_capacity(planned.iter().map(|p| p.0.len()).sum());
        for ((r, notes), &(it, _)) in planned.into_iter().zip(part) {
            recs.extend(r);
            for n in notes {
                warnings.push(Warning {
                    chain: items[it].chain,
                    message: n.to_string(),
                });
            }
        }
        if !sink(recs) {
            break;
        }
    }
    // One warning per chain and kind is enough, however many copies and
    // tight arcs (the first, in cutting order, stands for the rest).
    let mut seen = std::collections::HashSet::new();
    warnings.retain(|w| {
        let kind = if w.message.contains("tighter than V²/a") {
            ""
        } else {
            w.message.as_str()
        };
        seen.insert((w.chain, kind.to_string()))
    });
    warnings
}

/// Plan a contour job chunk by chunk: like [`contour`], but each chunk of
/// moves goes to `sink` as soon as it is planned, so the caller can write
/// while the next chunk is planned and never holds the whole job.
pub fn contour_streamed(
    chains: &[Chain],
    m: &LaserSetup,
    o: &ContourOptions,
    sink: impl FnMut(Vec<Record>) -> bool,
) -> (Vec<Warning>, CleanStats) {
    let (items, plan, mut warnings, cleanup) = prepare(chains, m, o);
    let mut sink = sink;
    if !sink(vec![super::constant_velocity::ramps_record(m)]) {
        return (warnings, cleanup);
    }
    // About 64k moves per chunk for 100-segment chains: big enough to keep
    // both cores busy, small enough that writing overlaps planning.
    warnings.extend(plan_in_chunks(&items, &plan, m, 512, sink));
    (warnings, cleanup)
}

/// Items in cutting order: clusters (an outer chain with all it contains)
/// ordered for short travel; inside a cluster, deepest first so every hole
/// is cut before the contour around it (a cut-out part would otherwise
/// shift before its holes are cut).
fn order_items(items: &[Item], o: &ContourOptions) -> Vec<usize> {
    let mut roots: Vec<usize> = items.iter().map(|it| it.root).collect();
    roots.sort_unstable();
    roots.dedup();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); roots.len()];
    for (i, it) in items.iter().enumerate() {
        let r = roots.binary_search(&it.root).expect("root listed");
        members[r].push(i);
    }
    let point = |i: usize| items[i].path[0].start().xy();
    // Travel is measured at each cluster's exit (its outer path start).
    let reps: Vec<P2> = members
        .iter()
        .map(|ms| {
            point(
                *ms.iter()
                    .min_by_key(|&&i| (items[i].depth, i))
                    .expect("non-empty cluster"),
            )
        })
        .collect();
    let cluster_order: Vec<usize> = match o.order {
        OrderMode::Input => (0..members.len()).collect(),
        OrderMode::Nearest => order::nearest_neighbour(&reps, o.origin),
        OrderMode::Optimized => order::improved(&reps, o.origin),
    };
    let mut out = Vec::with_capacity(items.len());
    let mut here = o.origin;
    for c in cluster_order {
        let mut ms = members[c].clone();
        ms.sort_by(|&a, &b| items[b].depth.cmp(&items[a].depth).then(a.cmp(&b)));
        if o.order == OrderMode::Input || ms.len() == 1 {
            out.extend(&ms);
            if let Some(&l) = ms.last() {
                here = items[l].path.last().map_or(here, |e| e.end().xy());
            }
            continue;
        }
        // Nearest neighbour within each depth, deepest first.
        let mut k = 0;
        while k < ms.len() {
            let depth = items[ms[k]].depth;
            let end = k + ms[k..].iter().take_while(|&&i| items[i].depth == depth).count();
            let group: Vec<usize> = ms[k..end].to_vec();
            let pts: Vec<P2> = group.iter().map(|&i| point(i)).collect();
            for g in order::nearest_neighbour(&pts, here) {
                out.push(group[g]);
                here = items[group[g]].path.last().map_or(here, |e| e.end().xy());
            }
            k = end;
        }
    }
    out
}

/// Where a job starts: the first rapid's target or the origin.
pub fn first_point(records: &[Record]) -> P3 {
    records
        .iter()
        .find_map(|r| r.motion().map(|m| m.to))
        .unwrap_or_else(P3::origin)
}
