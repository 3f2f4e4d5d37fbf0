//! Planar sections of a mesh at Z levels, as closed nested loops and as
//! `microcam.chains/1` chains: the planar-section flow of Bayesteh (2013),
//! slicing a model at Z steps for the beam to fill level by level.
//!
//! The mesh must be welded (shared vertices indexed once), so that a
//! section point is identified by the mesh edge it lies on and the loops
//! are linked by topology, not by distances. Vertices exactly at the level
//! count as below it: the section is the limit from just above the plane.
//! So a plane through a vertex makes no zero-length piece that matters (the
//! repeated point is removed), a plane along a facet makes none at all, and
//! a level at a part's flat bottom gives the bottom face's outline while a
//! level at its flat top gives nothing.
//!
//! Each triangle crossing the plane gives one piece, directed so that the
//! solid lies on its left (outward normal turned by +90° about Z): outer
//! boundaries run counter-clockwise, holes clockwise. Open or non-manifold
//! meshes leave open runs; their ends are joined within a tolerance (with
//! a warning). Nesting depth decides outer versus hole in the end, whatever
//! the triangles said: even depth counter-clockwise, odd clockwise.

use std::collections::HashMap;

use crate::geometry::{P2, P3};
use crate::laser::arcfit;
use crate::mesh::Mesh;
use crate::model::chain::{Chain, Segment};

/// How to section.
#[derive(Debug, Clone, Copy)]
pub struct SliceOptions {
    /// Open runs whose ends are closer than this are joined (mm).
    pub join_tol: f64,
    /// A point this close to the line through its neighbours is dropped
    /// (straight pieces merged), mm.
    pub collinear_tol: f64,
    /// Fit arcs within this (mm) to runs of short pieces; `None` keeps the
    /// polygon.
    pub arc_tol: Option<f64>,
}

impl Default for SliceOptions {
    fn default() -> Self {
        SliceOptions {
            join_tol: 1e-3,
            collinear_tol: 1e-9,
            arc_tol: None,
        }
    }
}

/// One closed loop of a section.
#[derive(Debug, Clone, PartialEq)]
pub struct Loop {
    /// Corners in order, the first not repeated at the end.
    pub points: Vec<P2>,
    /// How many other loops enclose it (0 = outer boundary).
    pub depth: usize,
    /// False when its ends could not be joined within the tolerance (left
    /// open, written as an open chain).
    pub closed: bool,
}

impl Loop {
    /// Signed area (mm², positive counter-clockwise).
    pub fn area(&self) -> f64 {
        polygon_area(&self.points)
    }
}

/// The section at one level.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// The level (mm).
    pub z: f64,
    /// Its loops, outer boundaries counter-clockwise and holes clockwise.
    pub loops: Vec<Loop>,
    /// What was mended (gaps joined) or could not be, one sentence each.
    pub warnings: Vec<String>,
}

/// Signed area of a closed polygon (shoelace).
pub fn polygon_area(p: &[P2]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|i| p[i].x * p[(i + 1) % n].y - p[(i + 1) % n].x * p[i].y)
        .sum::<f64>()
        * 0.5
}

/// Levels every `step` from the top of `[zmin, zmax]` down (the first one
/// step below the top) or from the bottom up (the first at the bottom).
pub fn step_levels(zmin: f64, zmax: f64, step: f64, from_top: bool) -> Vec<f64> {
    let mut out = Vec::new();
    if step.is_nan() || step <= 0.0 || zmax.is_nan() || zmin.is_nan() || zmax < zmin {
        return out;
    }
    let n = ((zmax - zmin) / step).floor() as usize + 1;
    let eps = 1e-9 * (zmax - zmin).max(step);
    for k in 0..n.min(10_000_000) {
        if from_top {
            let z = zmax - (k + 1) as f64 * step;
            if z < zmin - eps {
                break;
            }
            out.push(z.max(zmin));
        } else {
            let z = zmin + k as f64 * step;
            if z >= zmax - eps {
                break;
            }
            out.push(z);
        }
    }
    out
}

type EdgeKey = (u32, u32);

/// The section of a welded mesh at `z`.
pub fn section(mesh: &Mesh, z: f64, opts: &SliceOptions) -> Section {
    let v = &mesh.vertices;
    let below = |i: u32| v[i as usize].z <= z;
    // Crossing point of an edge, computed in one canonical order so the two
    // triangles on the edge get the identical point.
    let cross = |k: EdgeKey| {
        let (a, b) = (v[k.0 as usize], v[k.1 as usize]);
        let (lo, hi) = if a.z <= z { (a, b) } else { (b, a) };
        let t = (z - lo.z) / (hi.z - lo.z);
        if t <= 0.0 {
            P2::new(lo.x, lo.y)
        } else {
            P2::new(lo.x + (hi.x - lo.x) * t, lo.y + (hi.y - lo.y) * t)
        }
    };
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    // Pieces: (from edge, to edge).
    let mut pieces: Vec<(EdgeKey, EdgeKey)> = Vec::new();
    for t in &mesh.triangles {
        let b = [below(t[0]), below(t[1]), below(t[2])];
        let nb = b.iter().filter(|&&x| x).count();
        if nb == 0 || nb == 3 {
            continue;
        }
        let (mut down, mut up) = (None, None);
        for k in 0..3 {
            let (p, q) = (t[k], t[(k + 1) % 3]);
            match (b[k], b[(k + 1) % 3]) {
                (false, true) => down = Some(key(p, q)),
                (true, false) => up = Some(key(p, q)),
                _ => {}
            }
        }
        if let (Some(d), Some(u)) = (down, up) {
            pieces.push((d, u));
        }
    }
    // Link pieces by shared edges.
    let mut by_start: HashMap<EdgeKey, Vec<usize>> = HashMap::with_capacity(pieces.len());
    for (i, p) in pieces.iter().enumerate() {
        by_start.entry(p.0).or_default().push(i);
    }
    let mut by_end: HashMap<EdgeKey, Vec<usize>> = HashMap::new();
    for (i, p) in pieces.iter().enumerate() {
        by_end.entry(p.1).or_default().push(i);
    }
    let mut used = vec![false; pieces.len()];
    let mut runs: Vec<(Vec<EdgeKey>, bool)> = Vec::new();
    for s in 0..pieces.len() {
        if used[s] {
            continue;
        }
        used[s] = true;
        let first = pieces[s].0;
        let mut keys = vec![first, pieces[s].1];
        let mut closed = false;
        loop {
            let end = *keys.last().expect("a run has keys");
            if end == first {
                keys.pop();
                closed = true;
                break;
            }
            let next = by_start.get(&end).and_then(|l| l.iter().copied().find(|&j| !used[j]));
            match next {
                Some(j) => {
                    used[j] = true;
                    keys.push(pieces[j].1);
                }
                None => break,
            }
        }
        // Extend backwards too, for runs started mid-way on an open mesh.
        if !closed {
            loop {
                let prev = by_end.get(&keys[0]).and_then(|l| l.iter().copied().find(|&j| !used[j]));
                match prev {
                    Some(j) => {
                        used[j] = true;
                        keys.insert(0, pieces[j].0);
                    }
                    None => break,
                }
            }
        }
        runs.push((keys, closed));
    }
    let mut warnings = Vec::new();
    let mut closed_pts: Vec<Vec<P2>> = Vec::new();
    let mut open_pts: Vec<Vec<P2>> = Vec::new();
    for (keys, closed) in runs {
        let pts: Vec<P2> = keys.iter().map(|&k| cross(k)).collect();
        if closed {
            closed_pts.push(pts);
        } else {
            open_pts.push(pts);
        }
    }
    let (joined, left_open) = join_open(open_pts, opts.join_tol, &mut warnings);
    closed_pts.extend(joined);
    let mut loops: Vec<Loop> = Vec::new();
    for pts in closed_pts {
        let pts = clean(pts, opts.collinear_tol, true);
        if pts.len() >= 3 && polygon_area(&pts).abs() > 0.0 {
            loops.push(Loop {
                points: pts,
                depth: 0,
                closed: true,
            });
        }
    }
    for pts in left_open {
        let pts = clean(pts, opts.collinear_tol, false);
        if pts.len() >= 2 {
            loops.push(Loop {
                points: pts,
                depth: 0,
                closed: false,
            });
        }
    }
    nest(&mut loops);
    Section { z, loops, warnings }
}

/// Join open runs end to start (or end to end, reversing one) while the
/// nearest gap is within `tol`; a run whose own ends meet is closed.
fn join_open(mut runs: Vec<Vec<P2>>, tol: f64, warnings: &mut Vec<String>) -> (Vec<Vec<P2>>, Vec<Vec<P2>>) {
    let mut closed = Vec::new();
    let mut open = Vec::new();
    let mut joins = 0usize;
    let mut worst = 0.0f64;
    while let Some(mut cur) = runs.pop() {
        loop {
            let end = *cur.last().expect("runs are not empty");
            let self_gap = (end - cur[0]).norm();
            // Nearest other run start (or end, reversed).
            let mut best: Option<(f64, usize, bool)> = None;
            for (i, r) in runs.iter().enumerate() {
                for (p, rev) in [(r[0], false), (*r.last().expect("not empty"), true)] {
                    let d = (p - end).norm();
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, i, rev));
                    }
                }
            }
            if self_gap <= tol && best.is_none_or(|b| self_gap <= b.0) {
                if self_gap > 0.0 {
                    joins += 1;
                    worst = worst.max(self_gap);
                }
                closed.push(cur);
                break;
            }
            match best {
                Some((d, i, rev)) if d <= tol => {
                    let mut r = runs.swap_remove(i);
                    if rev {
                        r.reverse();
                    }
                    if d > 0.0 {
                        joins += 1;
                        worst = worst.max(d);
                    }
                    let skip = (d == 0.0) as usize;
                    cur.extend(r.into_iter().skip(skip));
                }
                _ => {
                    open.push(cur);
                    break;
                }
            }
        }
    }
    if joins > 0 {
        warnings.push(format!(
            "joined {joins} gaps in the section (largest {worst:.3e} mm): the mesh is open or not manifold here"
        ));
    }
    if !open.is_empty() {
        warnings.push(format!(
            "{} pieces of the section stay open (gaps larger than {tol} mm)",
            open.len()
        ));
    }
    (closed, open)
}

/// Drop repeated points and points on the line through their neighbours.
fn clean(pts: Vec<P2>, col_tol: f64, closed: bool) -> Vec<P2> {
    let mut out: Vec<P2> = Vec::with_capacity(pts.len());
    for p in pts {
        if out.last().is_none_or(|q| *q != p) {
            out.push(p);
        }
    }
    if closed {
        while out.len() > 1 && out.first() == out.last() {
            out.pop();
        }
    }
    // Remove collinear points until none is left (each pass is linear).
    loop {
        let n = out.len();
        if n < 3 {
            return out;
        }
        let mut keep = vec![true; n];
        let mut removed = false;
        let mut prev = if closed { n - 1 } else { 0 };
        let range = if closed { 0..n } else { 1..n - 1 };
        for i in range {
            let next = (i + 1) % n;
            let (a, b, c) = (out[prev], out[i], out[next]);
            let ac = c - a;
            let l = ac.norm();
            let off = if l > 0.0 {
                (b - a).perp(&ac).abs() / l
            } else {
                (b - a).norm()
            };
            // Only when b lies between a and c: a spike back is a real corner.
            if off <= col_tol && (b - a).dot(&ac) >= 0.0 && (c - b).dot(&ac) >= 0.0 {
                keep[i] = false;
                removed = true;
            } else {
                prev = i;
            }
        }
        if !removed {
            return out;
        }
        out = out.into_iter().zip(keep).filter_map(|(p, k)| k.then_some(p)).collect();
    }
}

fn inside(p: &P2, poly: &[P2]) -> bool {
    let mut c = false;
    let n = poly.len();
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            c = !c;
        }
        j = i;
    }
    c
}

/// Depth of each closed loop (loops containing it) and orientation by it.
///
/// A loop's depth counts the closed loops whose box holds a point just
/// inside it ([`probe`]) and that hold that point. The candidates come
/// from a grid over the closed loops' boxes (about one cell per loop), so
/// a section of many small loops (a perforated plate, a lattice) costs
/// about one box test per loop instead of one per pair (docs/mesh.md,
/// "Sections": 40,000 loops at each of 10 levels, 10.1 s with every pair
/// tested, 2.7 s with the grid).
fn nest(loops: &mut [Loop]) {
    use rayon::prelude::*;
    let boxes: Vec<(P2, P2)> = loops.par_iter().map(|l| bbox(&l.points)).collect();
    let probes: Vec<Option<P2>> = loops.par_iter().map(|l| l.closed.then(|| probe(&l.points))).collect();
    let grid = BoxGrid::new(loops, &boxes);
    let depth: Vec<usize> = probes
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let Some(p) = p else { return 0 };
            let holds = |&j: &u32| {
                let j = j as usize;
                let (lo, hi) = boxes[j];
                i != j && p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && inside(p, &loops[j].points)
            };
            match &grid {
                Some(g) => g.candidates(p).iter().filter(|j| holds(j)).count(),
                None => (0..loops.len() as u32)
                    .filter(|j| loops[*j as usize].closed && holds(j))
                    .count(),
            }
        })
        .collect();
    for (l, d) in loops.iter_mut().zip(depth) {
        l.depth = d;
        if l.closed {
            let ccw = l.area() > 0.0;
            if ccw != d.is_multiple_of(2) {
                l.points.reverse();
            }
        }
    }
}

/// Smallest box holding the points (empty: an inverted infinite box).
fn bbox(points: &[P2]) -> (P2, P2) {
    let mut lo = P2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in points {
        lo = P2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = P2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    (lo, hi)
}

/// The closed loops' boxes on a uniform grid: each cell lists the loops
/// whose box reaches it, in index order.
struct BoxGrid {
    x0: f64,
    y0: f64,
    cw: f64,
    ch: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    refs: Vec<u32>,
}

impl BoxGrid {
    /// `None` when a grid does not pay (a few loops), or would list too
    /// many loops in too many cells (many large loops on one another,
    /// nested rings): then every pair is tested.
    fn new(loops: &[Loop], boxes: &[(P2, P2)]) -> Option<BoxGrid> {
        let closed: Vec<u32> = (0..loops.len() as u32)
            .filter(|&j| loops[j as usize].closed && boxes[j as usize].0.x <= boxes[j as usize].1.x)
            .collect();
        if closed.len() < 64 {
            return None;
        }
        let (mut lo, mut hi) = (boxes[closed[0] as usize].0, boxes[closed[0] as usize].1);
        for &j in &closed {
            let (a, b) = boxes[j as usize];
            lo = P2::new(lo.x.min(a.x), lo.y.min(a.y));
            hi = P2::new(hi.x.max(b.x), hi.y.max(b.y));
        }
        if !(lo.x.is_finite() && lo.y.is_finite() && hi.x.is_finite() && hi.y.is_finite()) {
            return None;
        }
        let side = ((closed.len() as f64).sqrt().ceil() as usize).clamp(1, 2048);
        let (w, h) = (hi.x - lo.x, hi.y - lo.y);
        let nx = if w > 0.0 { side } else { 1 };
        let ny = if h > 0.0 { side } else { 1 };
        let mut g = BoxGrid {
            x0: lo.x,
            y0: lo.y,
            cw: if w > 0.0 { w / nx as f64 } else { 1.0 },
            ch: if h > 0.0 { h / ny as f64 } else { 1.0 },
            nx,
            ny,
            start: vec![0; nx * ny + 1],
            refs: Vec::new(),
        };
        // Each loop's cells; counted first: too many references means the
        // grid sorts nothing out.
        let spans: Vec<(usize, usize, usize, usize)> = closed
            .iter()
            .map(|&j| {
                let (a, b) = boxes[j as usize];
                let ((i0, j0), (i1, j1)) = (g.cell(&a), g.cell(&b));
                (i0, i1, j0, j1)
            })
            .collect();
        let total: usize = spans
            .iter()
            .map(|&(i0, i1, j0, j1)| (i1 - i0 + 1) * (j1 - j0 + 1))
            .sum();
        if total > 64 * closed.len() + (1 << 20) || total > u32::MAX as usize {
            return None;
        }
        for &(i0, i1, j0, j1) in &spans {
            for r in j0..=j1 {
                for q in i0..=i1 {
                    g.start[r * nx + q + 1] += 1;
                }
            }
        }
        for k in 0..nx * ny {
            g.start[k + 1] += g.start[k];
        }
        let mut fill = g.start.clone();
        g.refs = vec![0; total];
        for (&j, &(i0, i1, j0, j1)) in closed.iter().zip(&spans) {
            for r in j0..=j1 {
                for q in i0..=i1 {
                    let c = r * nx + q;
                    g.refs[fill[c] as usize] = j;
                    fill[c] += 1;
                }
            }
        }
        Some(g)
    }

    /// The cell of a point, clamped to the grid. Monotonic in each
    /// coordinate, so a box holding a point lists itself in its cell.
    fn cell(&self, p: &P2) -> (usize, usize) {
        let i = ((p.x - self.x0) / self.cw).floor().clamp(0.0, (self.nx - 1) as f64) as usize;
        let j = ((p.y - self.y0) / self.ch).floor().clamp(0.0, (self.ny - 1) as f64) as usize;
        (i, j)
    }

    /// The loops whose box may hold `p` (every loop whose box does).
    fn candidates(&self, p: &P2) -> &[u32] {
        if !(p.x.is_finite() && p.y.is_finite()) {
            return &[];
        }
        let (i, j) = self.cell(p);
        let c = j * self.nx + i;
        &self.refs[self.start[c] as usize..self.start[c + 1] as usize]
    }
}

/// The midpoint of a loop's longest edge, nudged a hair to the loop's
/// inside; a point of the loop's own region near its boundary.
fn probe(p: &[P2]) -> P2 {
    let n = p.len();
    let i = (0..n)
        .max_by(|&a, &b| {
            (p[(a + 1) % n] - p[a])
                .norm()
                .total_cmp(&(p[(b + 1) % n] - p[b]).norm())
        })
        .unwrap_or(0);
    let (a, b) = (p[i], p[(i + 1) % n]);
    let m = P2::new(0.5 * (a.x + b.x), 0.5 * (a.y + b.y));
    let d = b - a;
    let sgn = if polygon_area(p) > 0.0 { 1.0 } else { -1.0 };
    let nrm = crate::geometry::V2::new(-d.y, d.x) * (sgn * 1e-7);
    m + nrm
}

/// Chains (Z on every point) from sections: one chain per loop, ids from
/// `first_id`; with `arc_tol`, arcs fitted within it to the polygon.
pub fn to_chains(sections: &[Section], arc_tol: Option<f64>, first_id: u64) -> Vec<Chain> {
    let mut out = Vec::new();
    let mut id = first_id;
    for s in sections {
        for l in &s.loops {
            let segments = loop_segments(l, s.z, arc_tol);
            if segments.is_empty() {
                continue;
            }
            out.push(Chain {
                id,
                layer: Some(if l.depth.is_multiple_of(2) {
                    "outer".into()
                } else {
                    "hole".into()
                }),
                closed: l.closed,
                segments,
                points: Vec::new(),
                repairs: if l.closed {
                    Vec::new()
                } else {
                    vec!["left open: gap larger than the join tolerance".into()]
                },
            });
            id += 1;
        }
    }
    out
}

fn loop_segments(l: &Loop, z: f64, arc_tol: Option<f64>) -> Vec<Segment> {
    let lift = |p: &P2| P3::new(p.x, p.y, z);
    let mut pts = l.points.clone();
    if l.closed {
        // Start at the sharpest corner, so the fit's own seam is a corner.
        let n = pts.len();
        let turn = |k: usize| {
            let (a, b) = (pts[k] - pts[(k + n - 1) % n], pts[(k + 1) % n] - pts[k]);
            a.perp(&b).atan2(a.dot(&b)).abs()
        };
        let s = (0..n).max_by(|&a, &b| turn(a).total_cmp(&turn(b))).unwrap_or(0);
        pts.rotate_left(s);
        pts.push(pts[0]);
    }
    match arc_tol {
        Some(tol) if tol > 0.0 && pts.len() > 3 => {
            // Points mode: the section points lie on the model (on its edges),
            // the chords between them do not; arcs through the points are
            // closer to the model than the polygon is.
            let fit = arcfit::fit_points(&pts, tol, z, false);
            // Fitted arcs are XY arcs of less than a turn: chain segments as they are.
            let mut segs: Vec<Segment> = fit;
            // Snap the seam exactly.
            if l.closed
                && let (Some(f), Some(last)) = (segs.first().map(|s| s.start()), segs.last_mut())
            {
                last.set_end(f);
            }
            segs
        }
        _ => pts
            .windows(2)
            .map(|w| Segment::line(lift(&w[0]), lift(&w[1])))
            .collect(),
    }
}

/// Signed area enclosed by a closed chain of lines and XY arcs (mm²):
/// the DXF chainer's exact area, the one formula for both.
pub fn chain_area(c: &Chain) -> f64 {
    crate::dxf::chain::signed_area(&c.segments)
}

#[cfg(test)]
mod tests;
