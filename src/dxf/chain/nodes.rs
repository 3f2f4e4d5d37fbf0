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
}
