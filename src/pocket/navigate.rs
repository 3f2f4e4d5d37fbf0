//! Interior navigation over the grid cells (the Iowa State grid-pocket
//! thesis (1999) §3.4, Figs. 9-12).
//!
//! Start at the cell with the minimum Y, left-most among those, heading +X.
//! At each cell the next one is the first free neighbour in
//! counter-clockwise order starting from the right of the heading: right
//! turn, straight on, left turn (the way back is always cut). "Free" means
//! not yet visited and reachable by a straight move that stays in the
//! tool-centre region. Turning right first keeps the path against the wall
//! or the cut area on its right, so it winds inward counter-clockwise like
//! a window frame and follows concave walls into their recesses; the
//! thesis' own listing shows exactly these turns.
//!
//! When every neighbour is cut the walk is at a dead end. The thesis stops
//! there; we must visit every cell, so we walk back over cut cells by the
//! shortest grid path to the nearest uncut one and go on (a link that
//! stays in the region at cutting height). Cells no grid path reaches (the
//! region falls apart in pieces) start a new walk, reached by a retract.
//! The main path is the navigation reversed, so it ends at the pocket's
//! edge, next to where the wall pass starts (thesis §1).

use super::grid::{CellIx, Grid, Region};
use std::collections::{BTreeSet, VecDeque};

/// Headings, counter-clockwise from +X.
const DIRS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

/// The navigation: walks (each a chain of neighbouring cells, by id) and
/// the neighbour pairs it joined.
#[derive(Debug, Clone, Default)]
pub struct Navigation {
    /// The walks in the order they were made; each is a chain of cell ids
    /// (indices into [`Grid::cells`]), neighbour to neighbour, with the
    /// walks back over cut cells included.
    pub walks: Vec<Vec<usize>>,
    /// Joined neighbour pairs (smaller id first).
    pub joined: BTreeSet<(usize, usize)>,
}

/// Neighbour `d` of cell `c` when a straight move there stays in the region.
pub fn neighbour(grid: &Grid, region: &Region, c: usize, d: (i64, i64)) -> Option<usize> {
    let (i, j) = grid.cells[c];
    let n: CellIx = (i + d.0, j + d.1);
    let id = grid.id(n)?;
    region.segment_inside(grid.centre((i, j)), grid.centre(n)).then_some(id)
}

/// Navigate all cells of `grid`.
pub fn navigate(grid: &Grid, region: &Region) -> Navigation {
    let n = grid.cells.len();
    let adj: Vec<[Option<usize>; 4]> = (0..n)
        .map(|c| {
            let mut a = [None; 4];
            for (k, d) in DIRS.iter().enumerate() {
                a[k] = neighbour(grid, region, c, *d);
            }
            a
        })
        .collect();
    let mut visited = vec![false; n];
    let mut nav = Navigation::default();
    let mut left = n;
    while left > 0 {
        // Cells are sorted by (j, i): the first unvisited one has the
        // minimum Y, left-most.
        let Some(start) = (0..n).find(|&c| !visited[c]) else {
            break;
        };
        let mut walk = vec![start];
        visited[start] = true;
        left -= 1;
        let mut cur = start;
        let mut heading = 0usize;
        loop {
            // Right, straight, left: counter-clockwise from the right.
            let next = [3usize, 0, 1]
                .iter()
                .map(|t| (heading + t) % 4)
                .find_map(|h| adj[cur][h].filter(|&m| !visited[m]).map(|m| (h, m)));
            if let Some((h, m)) = next {
                nav.joined.insert((cur.min(m), cur.max(m)));
                walk.push(m);
                visited[m] = true;
                left -= 1;
                cur = m;
                heading = h;
                continue;
            }
            // Dead end: shortest grid path over cut cells to an uncut one.
            match bfs_to_unvisited(&adj, &visited, cur) {
                Some(path) => {
                    for w in path.windows(2) {
                        nav.joined.insert((w[0].min(w[1]), w[0].max(w[1])));
                    }
                    let last = *path.last().expect("bfs path has the target");
                    let prev = path[path.len() - 2];
                    heading = (0..4).find(|&h| adj[prev][h] == Some(last)).unwrap_or(0);
                    walk.extend_from_slice(&path[1..]);
                    visited[last] = true;
                    left -= 1;
                    cur = last;
                }
                None => break,
            }
        }
        nav.walks.push(walk);
    }
    nav
}

/// Shortest path from `from` to the nearest unvisited cell (inclusive).
fn bfs_to_unvisited(adj: &[[Option<usize>; 4]], visited: &[bool], from: usize) -> Option<Vec<usize>> {
    let mut prev = vec![usize::MAX; adj.len()];
    let mut q = VecDeque::from([from]);
    prev[from] = from;
    while let Some(c) = q.pop_front() {
        for m in adj[c].iter().flatten() {
            if prev[*m] != usize::MAX {
                continue;
            }
            prev[*m] = c;
            if !visited[*m] {
                let mut path = vec![*m];
                let mut k = *m;
                while k != from {
                    k = prev[k];
                    path.push(k);
                }
                path.reverse();
                return Some(path);
            }
            q.push_back(*m);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P2;
    use cavalier_contours::polyline::{PlineSourceMut, Polyline};

    fn region(pts: &[(f64, f64)], r: f64) -> Region {
        let mut p = Polyline::new_closed();
        for &(x, y) in pts {
            p.add(x, y, 0.0);
        }
        Region::new(&p, r)
    }

    #[test]
    fn a_rectangle_is_walked_as_an_inward_counter_clockwise_spiral() {
        let reg = region(&[(0.0, 0.0), (5.0, 0.0), (5.0, 4.0), (0.0, 4.0)], 0.5);
        let g = Grid::new(&reg, P2::origin(), 1.0, 1.0);
        assert_eq!(g.cells.len(), 20);
        let nav = navigate(&g, &reg);
        assert_eq!(nav.walks.len(), 1);
        let walk: Vec<CellIx> = nav.walks[0].iter().map(|&c| g.cells[c]).collect();
        // Bottom row left to right, up the right side, back along the top.
        assert_eq!(
            &walk[..8],
            &[(0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (4, 1), (4, 2), (4, 3)]
        );
        assert_eq!(walk[8], (3, 3));
        // Every cell once: a spiral of a rectangle has no dead end.
        let set: BTreeSet<_> = walk.iter().collect();
        assert_eq!(set.len(), 20);
        assert_eq!(walk.len(), 20);
    }

    #[test]
    fn a_comb_needs_walking_back_and_still_visits_every_cell() {
        // A comb: teeth going up from a base, so the spiral dead-ends.
        let reg = region(
            &[
                (0.0, 0.0),
                (7.0, 0.0),
                (7.0, 5.0),
                (6.0, 5.0),
                (6.0, 2.0),
                (4.0, 2.0),
                (4.0, 5.0),
                (3.0, 5.0),
                (3.0, 2.0),
                (1.0, 2.0),
                (1.0, 5.0),
                (0.0, 5.0),
            ],
            0.25,
        );
        let g = Grid::new(&reg, P2::origin(), 0.5, 0.5);
        let nav = navigate(&g, &reg);
        let seen: BTreeSet<usize> = nav.walks.iter().flatten().copied().collect();
        assert_eq!(seen.len(), g.cells.len());
        for w in &nav.walks {
            for p in w.windows(2) {
                let (a, b) = (g.cells[p[0]], g.cells[p[1]]);
                assert_eq!((a.0 - b.0).abs() + (a.1 - b.1).abs(), 1, "{a:?} -> {b:?}");
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
        /// Skyline pockets (columns of random height: concave, with dead
        /// ends): every cell visited, every step to a neighbour inside the
        /// region, the first cell the lowest left-most one.
        #[test]
        fn skylines_are_fully_visited(heights in proptest::collection::vec(1u32..7, 2..7)) {
            let w = heights.len() as f64;
            let mut pts = vec![(0.0, 0.0), (w, 0.0)];
            for (k, h) in heights.iter().enumerate().rev() {
                pts.push(((k + 1) as f64, *h as f64));
                pts.push((k as f64, *h as f64));
            }
            let reg = region(&pts, 0.2);
            let g = Grid::new(&reg, P2::origin(), 0.5, 0.5);
            let nav = navigate(&g, &reg);
            let seen: BTreeSet<usize> = nav.walks.iter().flatten().copied().collect();
            proptest::prop_assert_eq!(seen.len(), g.cells.len());
            for w in &nav.walks {
                for p in w.windows(2) {
                    let (a, b) = (g.cells[p[0]], g.cells[p[1]]);
                    proptest::prop_assert_eq!((a.0 - b.0).abs() + (a.1 - b.1).abs(), 1);
                    proptest::prop_assert!(reg.segment_inside(g.centre(a), g.centre(b)));
                }
            }
            if let Some(w) = nav.walks.first() {
                let first = g.cells[w[0]];
                proptest::prop_assert!(g.cells.iter().all(|c| (c.1, c.0) >= (first.1, first.0)));
            }
        }
    }
}
