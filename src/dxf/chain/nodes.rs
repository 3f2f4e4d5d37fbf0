//! End points to nodes: every end point joins the first node seen within
//! the tolerance (the lowest node id among those within it), or becomes a
//! new node. Nodes are therefore more than the tolerance apart.
//!
//! A spatial hash of cells eight tolerances wide finds the candidates: the
//! cells that the square of the tolerance around the point touches, one in
//! most cases and at most four. Each cell keeps its first node; the others
//! follow through `next` (no allocation per cell). Before any of that, the
//! point is compared with the few nodes just created or found: consecutive
//! pieces of a drawing share their ends exactly, and a point equal to a
//! node's own point can only belong to that node (any other node is more
//! than the tolerance away from it), so about half of all end points never
//! touch the hash table.

use super::FxMap;
use crate::geometry::P3;

pub(super) const NONE: u32 = u32::MAX;

/// How many recent nodes are compared exactly: the corners of a polygon of
/// up to eight sides come round again before they leave.
const RECENT: usize = 8;

pub(super) struct Nodes {
    tol: f64,
    /// The tolerance with a margin for round-off in the distance test.
    reach: f64,
    cell: f64,
    grid: FxMap<u64, u32>,
    next: Vec<u32>,
    /// Each node's point (its first point).
    pub reps: Vec<P3>,
    /// The largest distance of a point joined to each node.
    pub gaps: Vec<f64>,
    recent: [u32; RECENT],
    slot: usize,
}

/// Cell coordinates packed into one word: cells 2^32 apart share a key,
/// which only adds candidates (the distance test is exact) and halves the
/// table.
fn ckey(x: i64, y: i64) -> u64 {
    ((x as u32 as u64) << 32) | (y as u32 as u64)
}

impl Nodes {
    /// An empty set of nodes joining ends within `tol` (mm), sized for
    /// about `points` ends.
    pub fn new(tol: f64, points: usize) -> Nodes {
        let mut grid = FxMap::default();
        grid.reserve(points / 2);
        Nodes {
            tol,
            reach: tol * (1.0 + 1e-6),
            cell: (8.0 * tol).max(1e-9),
            grid,
            next: Vec::new(),
            reps: Vec::new(),
            gaps: Vec::new(),
            recent: [NONE; RECENT],
            slot: 0,
        }
    }

    fn remember(&mut self, id: u32) {
        self.recent[self.slot] = id;
        self.slot = (self.slot + 1) % RECENT;
    }

    /// The node of point `p`.
    pub fn node_of(&mut self, p: &P3) -> u32 {
        for &id in &self.recent {
            if id != NONE && self.reps[id as usize] == *p {
                return id;
            }
        }
        let c = self.cell;
        let cell = |v: f64| (v / c).floor() as i64;
        let (x0, x1) = (cell(p.x - self.reach), cell(p.x + self.reach));
        let (y0, y1) = (cell(p.y - self.reach), cell(p.y + self.reach));
        let mut best: Option<u32> = None;
        // At most 2 x 2 cells (the cell is wider than twice the reach);
        // far out, where the casts saturate, the range is clamped.
        for cx in x0..=x1.min(x0.saturating_add(1)) {
            for cy in y0..=y1.min(y0.saturating_add(1)) {
                let mut id = self.grid.get(&ckey(cx, cy)).copied().unwrap_or(NONE);
                while id != NONE {
                    if (self.reps[id as usize] - p).norm() <= self.tol && best.is_none_or(|b| id < b) {
                        best = Some(id);
                    }
                    id = self.next[id as usize];
                }
            }
        }
        let id = match best {
            Some(id) => {
                let g = (self.reps[id as usize] - p).norm();
                if g > self.gaps[id as usize] {
                    self.gaps[id as usize] = g;
                }
                id
            }
            None => {
                let id = self.reps.len() as u32;
                self.reps.push(*p);
                self.gaps.push(0.0);
                let head = self.grid.entry(ckey(cell(p.x), cell(p.y))).or_insert(NONE);
                self.next.push(*head);
                *head = id;
                id
            }
        };
        self.remember(id);
        id
    }

    /// The grid is only needed while points are added.
    pub fn finish(self) -> (Vec<P3>, Vec<f64>) {
        (self.reps, self.gaps)
    }
}

/// Every point's node, and the nodes' points and gaps: the answer of
/// [`Nodes::node_of`] called on `points` in order, computed on all cores.
pub(super) struct Clusters {
    /// The node of each point.
    pub node: Vec<u32>,
    /// Each node's point (its first point).
    pub reps: Vec<P3>,
    /// The largest distance of a point joined to each node.
    pub gaps: Vec<f64>,
}

/// Below this many points the sequential [`Nodes`] is as fast.
const PARALLEL_FROM: usize = 1 << 13;
/// A cell holding more points than this sends the whole layer to the
/// sequential [`Nodes`], whose work per point is bounded by the nodes
/// (more than `tol` apart) in a cell, not by the points.
const DENSE_CELL: usize = 48;
/// Points before each point compared exactly (consecutive pieces share
/// their ends; a star of lines comes back to its centre every other point).
const WINDOW: usize = 8;

/// Cluster `points` within `tol` exactly as [`Nodes::node_of`] does in
/// order: each point joins the lowest-numbered node whose point is within
/// `tol`, or starts a new node.
///
/// The sequential rule needs, for each point, only the earlier points
/// within `tol` that started nodes, and those are few and known before
/// the rule is applied:
/// 1. a point equal to one of the few points just before it belongs to
///    that point's node (any node within `tol` of it is the other's; a
///    later node has a higher number) — it is linked, not looked up;
/// 2. the other points, sorted by cell on all cores, find the earlier
///    such points within `tol` in their own cell and, near a cell's edge,
///    the neighbouring ones (in parallel; almost always none);
/// 3. one pass in point order applies the rule with those short lists
///    (only points that started nodes count), in cache order.
pub(super) fn cluster(points: &[P3], tol: f64) -> Clusters {
    if points.len() < PARALLEL_FROM {
        return sequential(points, tol);
    }
    match near_lists(points, tol) {
        Some((link, near)) => resolve(points, &link, &near),
        None => sequential(points, tol),
    }
}

fn sequential(points: &[P3], tol: f64) -> Clusters {
    let mut n = Nodes::new(tol, points.len());
    let node = points.iter().map(|p| n.node_of(p)).collect();
    let (reps, gaps) = n.finish();
    Clusters { node, reps, gaps }
}

/// For each point: an earlier point equal to it (`NONE` if none in the
/// window), and (sorted by point) the pairs (point, earlier point within
/// `tol`) among the points without such a link. `None` when some cell is
/// dense.
#[allow(clippy::type_complexity)]
fn near_lists(points: &[P3], tol: f64) -> Option<(Vec<u32>, Vec<(u32, u32)>)> {
    use rayon::prelude::*;
    let link: Vec<u32> = (0..points.len())
        .into_par_iter()
        .map(|i| {
            let p = &points[i];
            (i.saturating_sub(WINDOW)..i)
                .find(|&j| points[j] == *p)
                .map_or(NONE, |j| j as u32)
        })
        .collect();
    let cell = (32.0 * tol).max(1e-9);
    let reach = tol * (1.0 + 1e-6);
    let c = |v: f64| (v / cell).floor() as i64;
    let mut keyed: Vec<(u64, u32)> = link
        .par_iter()
        .enumerate()
        .filter(|(_, l)| **l == NONE)
        .map(|(i, _)| (ckey(c(points[i].x), c(points[i].y)), i as u32))
        .collect();
    keyed.par_sort_unstable();
    // Cells as runs of `keyed`: chunks of whole cells for the threads.
    let range_of = |key: u64| {
        let a = keyed.partition_point(|e| e.0 < key);
        a..a + keyed[a..].partition_point(|e| e.0 == key)
    };
    let chunk = (keyed.len() / (4 * rayon::current_num_threads().max(1))).max(1024);
    let mut cuts = vec![0usize];
    while *cuts.last().unwrap() < keyed.len() {
        let mut e = (*cuts.last().unwrap() + chunk).min(keyed.len());
        while e < keyed.len() && keyed[e].0 == keyed[e - 1].0 {
            e += 1;
        }
        cuts.push(e);
    }
    // Per chunk: the near pairs, and the points equal to an earlier one in
    // their cell (linked like the window's).
    type Part = (Vec<(u32, u32)>, Vec<(u32, u32)>);
    let parts: Vec<Option<Part>> = cuts
        .par_windows(2)
        .map(|w| {
            let (mut pairs, mut equal) = (Vec::new(), Vec::new());
            let (mut cell_pts, mut distinct) = (Vec::new(), Vec::new());
            let mut a = w[0];
            while a < w[1] {
                let key = keyed[a].0;
                let b = a + keyed[a..w[1]].partition_point(|e| e.0 == key);
                // Equal points together, the earliest first: it stands for
                // the others.
                cell_pts.clear();
                cell_pts.extend(keyed[a..b].iter().map(|e| e.1));
                let at = |i: &u32| {
                    let p = &points[*i as usize];
                    [p.x, p.y, p.z]
                };
                cell_pts.sort_unstable_by(|i, j| {
                    at(i)
                        .partial_cmp(&at(j))
                        .unwrap_or(std::cmp::Ordering::Equal)
                        .then(i.cmp(j))
                });
                distinct.clear();
                for (k, &i) in cell_pts.iter().enumerate() {
                    match distinct.last() {
                        Some(&f) if k > 0 && points[f as usize] == points[i as usize] => equal.push((i, f)),
                        _ => distinct.push(i),
                    }
                }
                if distinct.len() > DENSE_CELL {
                    return None;
                }
                for &i in &distinct {
                    let p = &points[i as usize];
                    for &j in &distinct {
                        if j < i && (points[j as usize] - p).norm() <= tol {
                            pairs.push((i, j));
                        }
                    }
                    // The neighbouring cells the tolerance square reaches.
                    let (x0, x1) = (c(p.x - reach), c(p.x + reach));
                    let (y0, y1) = (c(p.y - reach), c(p.y + reach));
                    let (cx, cy) = (c(p.x), c(p.y));
                    // At most 2 x 2 cells (a cell is far wider than the
                    // square); far out, where the casts saturate, clamped.
                    for x in x0..=x1.min(x0.saturating_add(1)) {
                        for y in y0..=y1.min(y0.saturating_add(1)) {
                            let other = ckey(x, y);
                            if (x, y) == (cx, cy) || other == key {
                                continue;
                            }
                            for e in &keyed[range_of(other)] {
                                if e.1 < i && (points[e.1 as usize] - p).norm() <= tol {
                                    pairs.push((i, e.1));
                                }
                            }
                        }
                    }
                }
                a = b;
            }
            Some((pairs, equal))
        })
        .collect();
    let mut link = link;
    let mut near = Vec::new();
    for p in parts {
        let (pairs, equal) = p?;
        near.extend(pairs);
        for (i, f) in equal {
            link[i as usize] = f;
        }
    }
    near.par_sort_unstable();
    near.dedup();
    Some((link, near))
}

fn resolve(points: &[P3], link: &[u32], near: &[(u32, u32)]) -> Clusters {
    let mut node = vec![NONE; points.len()];
    let mut reps: Vec<P3> = Vec::new();
    let mut gaps: Vec<f64> = Vec::new();
    // Whether each point started a node.
    let mut started = vec![false; points.len()];
    let mut at = 0;
    for i in 0..points.len() {
        if link[i] != NONE {
            node[i] = node[link[i] as usize];
            continue;
        }
        let lo = at;
        while at < near.len() && near[at].0 == i as u32 {
            at += 1;
        }
        // The lowest-numbered node is the one started by the earliest point.
        let first = near[lo..at].iter().map(|e| e.1).filter(|&j| started[j as usize]).min();
        match first {
            Some(j) => {
                let id = node[j as usize];
                let g = (reps[id as usize] - points[i]).norm();
                if g > gaps[id as usize] {
                    gaps[id as usize] = g;
                }
                node[i] = id;
            }
            None => {
                node[i] = reps.len() as u32;
                reps.push(points[i]);
                gaps.push(0.0);
                started[i] = true;
            }
        }
    }
    Clusters { node, reps, gaps }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_node_within_tolerance_wins_and_gaps_are_kept() {
        let mut n = Nodes::new(0.001, 8);
        let a = n.node_of(&P3::new(0.0, 0.0, 0.0));
        let b = n.node_of(&P3::new(0.0015, 0.0, 0.0));
        assert_ne!(a, b, "more than the tolerance apart");
        // Within the tolerance of both: the first node.
        assert_eq!(n.node_of(&P3::new(0.00075, 0.0, 0.0)), a);
        assert_eq!(n.node_of(&P3::new(0.0015, 0.0, 0.0)), b);
        // Across a cell boundary (cells are 0.008 wide).
        let c = n.node_of(&P3::new(0.0079996, 1.0, 0.0));
        assert_eq!(n.node_of(&P3::new(0.0080004, 1.0, 0.0)), c);
        assert_eq!(n.node_of(&P3::new(-0.0079996, -1.0, 0.0)), 3);
        assert_eq!(n.node_of(&P3::new(-0.0080004, -1.0, 0.0)), 3);
        let (reps, gaps) = n.finish();
        assert_eq!(reps.len(), 4);
        assert!((gaps[a as usize] - 0.00075).abs() < 1e-12);
        assert_eq!(gaps[b as usize], 0.0);
    }

    #[test]
    fn many_points_match_a_brute_force_clustering() {
        // Points on a fine lattice with jitter, so many fall within the
        // tolerance of several nodes; compared with the definition.
        let tol = 0.01;
        let mut x: u64 = 12345;
        let mut rnd = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let pts: Vec<P3> = (0..3000)
            .map(|_| P3::new((rnd() * 40.0).floor() * 0.007 + rnd() * 0.004, rnd() * 0.05, 0.0))
            .collect();
        let mut n = Nodes::new(tol, pts.len());
        let mut reps: Vec<P3> = Vec::new();
        for p in &pts {
            let want = match reps.iter().position(|r| (r - p).norm() <= tol) {
                Some(k) => k as u32,
                None => {
                    reps.push(*p);
                    reps.len() as u32 - 1
                }
            };
            assert_eq!(n.node_of(p), want);
        }
    }

    /// `cluster` against the sequential `Nodes` on drawings big enough for
    /// the parallel path: shared ends, near misses across cell edges,
    /// repeats far apart, tolerance zero, and a dense spot that sends the
    /// layer back to the sequential rule.
    #[test]
    fn parallel_clustering_equals_the_sequential_rule() {
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut rnd = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut parallel = 0;
        for case in 0..12 {
            let tol = [0.001, 0.0, 0.05, 1e-7][case % 4];
            let n = PARALLEL_FROM + 3000 * case;
            let mut pts: Vec<P3> = Vec::with_capacity(n);
            // Fresh points: the ones near points are put near (a gap in a
            // drawing is between two ends, not a cloud).
            let mut fresh: Vec<P3> = Vec::new();
            while pts.len() < n {
                let r = rnd();
                let p = if r < 0.3 && !pts.is_empty() {
                    // Repeat a point from anywhere before (outside the window).
                    pts[(rnd() * pts.len() as f64) as usize]
                } else if r < 0.4 && !fresh.is_empty() {
                    // Near an earlier point: within or just beyond tol.
                    let q = fresh[(rnd() * fresh.len() as f64) as usize];
                    let d = tol * (0.2 + 1.6 * rnd());
                    let a = rnd() * std::f64::consts::TAU;
                    P3::new(q.x + d * a.cos(), q.y + d * a.sin(), q.z)
                } else if r < 0.45 {
                    // On a cell edge of the parallel grid.
                    let cell = (32.0 * tol).max(1e-9);
                    P3::new((rnd() * 100.0).floor() * cell, rnd() * 3.0, 0.0)
                } else {
                    let p = P3::new(rnd() * 3.0, rnd() * 3.0, (rnd() * 2.0).floor());
                    fresh.push(p);
                    p
                };
                pts.push(p);
                if rnd() < 0.4 {
                    pts.push(p);
                }
            }
            if case == 11 {
                // A dense spot: many distinct points in one cell.
                for k in 0..200 {
                    pts.push(P3::new(5.0 + k as f64 * 0.3 * tol, 5.0, 0.0));
                }
            }
            let took_parallel = near_lists(&pts, tol).is_some();
            parallel += took_parallel as usize;
            assert!(case != 11 || !took_parallel, "the dense spot must fall back");
            let got = cluster(&pts, tol);
            let want = sequential(&pts, tol);
            assert_eq!(got.node, want.node, "case {case}");
            assert_eq!(got.reps, want.reps, "case {case}");
            assert_eq!(got.gaps, want.gaps, "case {case}");
            assert!(want.reps.len() < pts.len());
        }
        assert!(parallel >= 6, "only {parallel} cases took the parallel path");
    }
}
