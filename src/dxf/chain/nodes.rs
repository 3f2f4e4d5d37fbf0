//! End points to nodes: every end point joins the first node seen within
//! the tolerance (the lowest node id among those within it), or becomes a
//! new node. Nodes are therefore more than the tolerance apart.
//!
//! A spatial hash of cells eight tolerances wide finds the candidates: the
//! cells that the square of the tolerance around the point touches, one in
//! most cases and at most four. Each cell keeps its newest node; the others
//! follow through `next` (no allocation per cell). The cells live in an
//! open-addressed table of 8-byte slots (key and head together), so a
//! lookup, and the insert of a new node after it, touch one cache line:
//! with hashbrown's split control bytes and entries every new node cost two
//! cache misses, two thirds of the clustering's time on a drawing of parts
//! at random places. The key is a 32-bit fingerprint of the cell, not the
//! cell: cells with equal fingerprints share one list of nodes, which only
//! adds candidates (the distance test is exact), and the table is half the
//! size of one keyed by both coordinates (fewer cache misses and page
//! faults). The caller can also [`Nodes::prefetch`] the slot of a
//! point a few pieces ahead, so the misses of consecutive pieces overlap
//! instead of queueing one behind the other. Before any of that, the
//! point is compared with the few nodes just created or found: consecutive
//! pieces of a drawing share their ends exactly, and a point equal to a
//! node's own point can only belong to that node (any other node is more
//! than the tolerance away from it), so about half of all end points never
//! touch the hash table.

use crate::geometry::P3;

pub(super) const NONE: u32 = u32::MAX;

/// How many recent nodes are compared exactly: the corners of a polygon of
/// up to eight sides come round again before they leave.
const RECENT: usize = 8;

pub(super) struct Nodes {
    tol: f64,
    /// The tolerance with a margin for round-off in the distance test.
    reach: f64,
    /// One over the cell's width (mm): a multiply per coordinate instead
    /// of a division, eight of them a point with the prefetch. Any
    /// monotonic map to cells serves: the window and the cell a node is
    /// filed under come from the same one.
    per_mm: f64,
    grid: CellTable,
    next: Vec<u32>,
    /// Each node's point (its first point).
    pub reps: Vec<P3>,
    /// The largest distance of a point joined to each node.
    pub gaps: Vec<f64>,
    recent: [u32; RECENT],
    slot: usize,
}

/// A cell's fingerprint: both coordinates mixed into 32 bits. Cells with
/// equal fingerprints share a list of nodes, which only adds candidates
/// (the distance test is exact); among the few hundred thousand cells of a
/// large drawing about a dozen pairs do.
fn ckey(x: i64, y: i64) -> u32 {
    let k = ((x as u32 as u64) << 32) | (y as u32 as u64);
    (k.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) as u32
}

impl Nodes {
    /// An empty set of nodes joining ends within `tol` (mm), sized for
    /// about `points` ends.
    pub fn new(tol: f64, points: usize) -> Nodes {
        let grid = CellTable::with_capacity(points / 2);
        // At most one node per point: reserved, not touched, so only the
        // nodes made cost memory, and the arrays never move as they grow.
        Nodes {
            tol,
            reach: tol * (1.0 + 1e-6),
            per_mm: 1.0 / (8.0 * tol).max(1e-9),
            grid,
            next: Vec::with_capacity(points),
            reps: Vec::with_capacity(points),
            gaps: Vec::with_capacity(points),
            recent: [NONE; RECENT],
            slot: 0,
        }
    }

    /// The cell coordinate of `v` (mm) on either axis.
    #[inline]
    fn cell_of(&self, v: f64) -> i64 {
        crate::geometry::floor_i64(v * self.per_mm)
    }

    /// The cells the square of the tolerance around `p` touches, as
    /// inclusive ranges: at most 2 x 2 (the cell is wider than twice the
    /// reach); far out, where the casts saturate, the range is clamped.
    #[inline]
    fn window(&self, p: &P3) -> (i64, i64, i64, i64) {
        let (x0, x1) = (self.cell_of(p.x - self.reach), self.cell_of(p.x + self.reach));
        let (y0, y1) = (self.cell_of(p.y - self.reach), self.cell_of(p.y + self.reach));
        (x0, x1.min(x0.saturating_add(1)), y0, y1.min(y0.saturating_add(1)))
    }

    /// Ask the memory system for the table slots that [`Nodes::node_of`]
    /// will read for `p`. Only a hint: it changes no answer.
    #[inline]
    pub fn prefetch(&self, p: &P3) {
        let (x0, x1, y0, y1) = self.window(p);
        for cx in x0..=x1 {
            for cy in y0..=y1 {
                self.grid.prefetch(ckey(cx, cy));
            }
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
        let (x0, x1, y0, y1) = self.window(p);
        let mut best: Option<u32> = None;
        for cx in x0..=x1 {
            for cy in y0..=y1 {
                let mut id = self.grid.get(ckey(cx, cy));
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
                let key = ckey(self.cell_of(p.x), self.cell_of(p.y));
                let head = self.grid.head_mut(key);
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

/// Cell fingerprint to the newest node in that cell, open-addressed with
/// linear probing. A slot whose head is [`NONE`] is empty; nodes are never
/// removed, so no tombstones. The load stays at most 3/4 (the size of
/// hashbrown's table for the same cells), so a probe for a missing key
/// reads a few slots, mostly of one cache line.
struct CellTable {
    slots: Vec<Slot>,
    /// `32 - log2(slots.len())`: a key's home is the top bits of its hash.
    shift: u32,
    len: usize,
}

#[derive(Clone, Copy)]
struct Slot {
    key: u32,
    head: u32,
}

const EMPTY: Slot = Slot { key: 0, head: NONE };

impl CellTable {
    /// A table that holds `n` cells without growing.
    fn with_capacity(n: usize) -> CellTable {
        let slots = (n.saturating_mul(4) / 3).clamp(16, 1 << 31).next_power_of_two();
        CellTable {
            slots: vec![EMPTY; slots],
            shift: 32 - slots.trailing_zeros(),
            len: 0,
        }
    }

    /// The key is already a hash; one more multiply decorrelates the home
    /// slot from the key's own bits.
    #[inline]
    fn home(&self, key: u32) -> usize {
        (key.wrapping_mul(0x9e37_79b9) >> self.shift) as usize
    }

    #[inline]
    fn prefetch(&self, key: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            let p = &self.slots[self.home(key)] as *const Slot as *const i8;
            // SAFETY: a prefetch is a hint that never faults and reads or
            // writes nothing the program can observe; SSE, which provides
            // it, is part of every x86_64 processor.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = key;
    }

    /// The head of `key`'s cell, or [`NONE`].
    #[inline]
    fn get(&self, key: u32) -> u32 {
        let mask = self.slots.len() - 1;
        let mut i = self.home(key);
        loop {
            let s = self.slots[i];
            if s.head == NONE || s.key == key {
                return s.head;
            }
            i = (i + 1) & mask;
        }
    }

    /// The head of `key`'s cell, made (as [`NONE`]) when missing.
    fn head_mut(&mut self, key: u32) -> &mut u32 {
        if (self.len + 1) * 4 > self.slots.len() * 3 {
            self.grow();
        }
        let mask = self.slots.len() - 1;
        let mut i = self.home(key);
        while self.slots[i].head != NONE && self.slots[i].key != key {
            i = (i + 1) & mask;
        }
        if self.slots[i].head == NONE {
            self.slots[i].key = key;
            self.len += 1;
        }
        &mut self.slots[i].head
    }

    fn grow(&mut self) {
        let old = std::mem::take(&mut self.slots);
        let n = old.len() * 2;
        self.slots = vec![EMPTY; n];
        self.shift = 32 - n.trailing_zeros();
        let mask = n - 1;
        for s in old.into_iter().filter(|s| s.head != NONE) {
            let mut i = self.home(s.key);
            while self.slots[i].head != NONE {
                i = (i + 1) & mask;
            }
            self.slots[i] = s;
        }
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
    fn the_cell_table_grows_and_keeps_every_cell() {
        // Sized for nothing: 5,000 cells force nine doublings; each cell's
        // head must survive every rehash, including keys that collide in
        // their home slot (keys equal in the hash's top bits share a home).
        let mut t = CellTable::with_capacity(0);
        let keys: Vec<u32> = (0..5000u32).map(|k| k.wrapping_mul(0x1_0001) ^ (k << 20)).collect();
        for (i, &k) in keys.iter().enumerate() {
            assert_eq!(t.get(k), NONE);
            *t.head_mut(k) = i as u32;
        }
        assert!(t.slots.len() >= 5000 * 4 / 3, "load stays at most 3/4");
        for (i, &k) in keys.iter().enumerate() {
            assert_eq!(t.get(k), i as u32);
            assert_eq!(*t.head_mut(k), i as u32, "an existing cell is found, not made again");
        }
        assert_eq!(t.len, 5000);
    }

    #[test]
    fn many_points_match_a_brute_force_clustering() {
        // Points on a fine lattice with jitter, so many fall within the
        // tolerance of several nodes; compared with the definition.
        let tol = 0.01;
        let mut rnd = crate::geometry::test_rng::unit_rng(12345);
        let pts: Vec<P3> = (0..3000)
            .map(|_| P3::new((rnd() * 40.0).floor() * 0.007 + rnd() * 0.004, rnd() * 0.05, 0.0))
            .collect();
        // Sized for a tenth of the points: the table grows on the way.
        let mut n = Nodes::new(tol, pts.len() / 10);
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
