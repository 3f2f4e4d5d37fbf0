//! Cut order: Bayesteh (2013) visits chains by nearest neighbour; we start from
//! that tour and improve it with 2-opt and Or-opt moves restricted to each
//! node's nearest neighbours (the standard neighbour-list speed-up, so a
//! pass costs O(n·k) candidate checks instead of O(n²)).
//!
//! The tour is an open path from the machine's start point; each node is a
//! point (a chain's start, which for closed chains is also its end).

use crate::geometry::P2;

/// Neighbours kept per node for improvement moves.
const K: usize = 10;

fn dist(a: &P2, b: &P2) -> f64 {
    (a - b).norm()
}

/// Total rapid travel of visiting `pts` in `order` from `start`.
pub fn travel(pts: &[P2], order: &[usize], start: P2) -> f64 {
    let mut p = start;
    let mut t = 0.0;
    for &i in order {
        t += dist(&p, &pts[i]);
        p = pts[i];
    }
    t
}

/// A uniform grid over the points for nearest-neighbour queries.
struct Grid {
    min: P2,
    cell: f64,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<usize>>,
}

impl Grid {
    fn new(pts: &[P2]) -> Grid {
        let mut min = P2::new(f64::INFINITY, f64::INFINITY);
        let mut max = P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in pts {
            min = min.inf(p);
            max = max.sup(p);
        }
        let n = pts.len().max(1) as f64;
        let span = (max - min).map(|v| v.max(1e-9));
        // About two points per cell.
        let cell = ((span.x * span.y) / n * 2.0)
            .sqrt()
            .max(span.x.max(span.y) / 4096.0)
            .max(1e-9);
        let nx = ((span.x / cell) as usize + 1).min(4096);
        let ny = ((span.y / cell) as usize + 1).min(4096);
        let mut cells = vec![Vec::new(); nx * ny];
        let mut g = Grid {
            min,
            cell,
            nx,
            ny,
            cells: Vec::new(),
        };
        for (i, p) in pts.iter().enumerate() {
            let (cx, cy) = g.cell_of(p);
            cells[cy * nx + cx].push(i);
        }
        g.cells = cells;
        g
    }

    fn cell_of(&self, p: &P2) -> (usize, usize) {
        let cx = (((p.x - self.min.x) / self.cell) as usize).min(self.nx - 1);
        let cy = (((p.y - self.min.y) / self.cell) as usize).min(self.ny - 1);
        (cx, cy)
    }

    /// Up to `k` nearest points to `q` among those `keep` accepts, nearest
    /// first (ties by index, for determinism).
    fn nearest(&self, pts: &[P2], q: &P2, k: usize, keep: impl Fn(usize) -> bool) -> Vec<usize> {
        let (cx, cy) = self.cell_of(q);
        let mut found: Vec<(f64, usize)> = Vec::new();
        let mut ring = 0usize;
        loop {
            let x0 = cx.saturating_sub(ring);
            let y0 = cy.saturating_sub(ring);
            let x1 = (cx + ring).min(self.nx - 1);
            let y1 = (cy + ring).min(self.ny - 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    // Only cells exactly `ring` away (Chebyshev) are new.
                    if ring > 0 && !(x + ring == cx || x == cx + ring || y + ring == cy || y == cy + ring) {
                        continue;
                    }
                    for &i in &self.cells[y * self.nx + x] {
                        if keep(i) {
                            found.push((dist(q, &pts[i]), i));
                        }
                    }
                }
            }
            // Everything within `ring` cells of q's cell is found; points
            // closer than ring·cell are therefore all in.
            let covered = ring as f64 * self.cell;
            let all = x0 == 0 && y0 == 0 && x1 == self.nx - 1 && y1 == self.ny - 1;
            found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let good = found.iter().take_while(|f| f.0 <= covered).count();
            if good >= k || all {
                found.truncate(k);
                return found.into_iter().map(|f| f.1).collect();
            }
            ring += 1;
        }
    }
}

/// The order of Bayesteh (2013): always go to the nearest unvisited point.
pub fn nearest_neighbour(pts: &[P2], start: P2) -> Vec<usize> {
    let n = pts.len();
    if n == 0 {
        return Vec::new();
    }
    let grid = Grid::new(pts);
    let mut done = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut here = start;
    // Removing visited points from the grid keeps queries local.
    let mut g = grid;
    for _ in 0..n {
        let next = g.nearest(pts, &here, 1, |i| !done[i]);
        let Some(&i) = next.first() else { break };
        done[i] = true;
        order.push(i);
        here = pts[i];
        let (cx, cy) = g.cell_of(&pts[i]);
        let nx = g.nx;
        g.cells[cy * nx + cx].retain(|&j| j != i);
    }
    order
}

/// Nearest neighbour improved by 2-opt and Or-opt until no move gains.
pub fn improved(pts: &[P2], start: P2) -> Vec<usize> {
    let n = pts.len();
    let mut order = nearest_neighbour(pts, start);
    if n < 3 {
        return order;
    }
    let grid = Grid::new(pts);
    let neigh: Vec<Vec<usize>> = (0..n).map(|i| grid.nearest(pts, &pts[i], K + 1, |j| j != i)).collect();
    // Position 0 of `t` is the fixed start; node ids shifted by one.
    let mut p: Vec<P2> = Vec::with_capacity(n + 1);
    p.push(start);
    p.extend_from_slice(pts);
    let mut t: Vec<usize> = std::iter::once(0).chain(order.iter().map(|&i| i + 1)).collect();
    let mut pos = vec![0usize; n + 1];
    let d = |a: usize, b: usize| dist(&p[a], &p[b]);
    for _round in 0..50 {
        // Progress (a tool's spinner): rounds, up to 50, fewer when no
        // move gains.
        crate::progress::advance(1);
        let mut improved_any = false;
        // 2-opt: replace edges (t[i],t[i+1]) and (t[j],t[j+1]) by
        // (t[i],t[j]) and (t[i+1],t[j+1]); the path end counts as a free edge.
        for (k, &v) in t.iter().enumerate() {
            pos[v] = k;
        }
        for i in 0..n {
            let a = t[i];
            let b = t[i + 1];
            let dab = d(a, b);
            let na = if a == 0 { Vec::new() } else { neigh[a - 1].clone() };
            for c in na.into_iter().map(|c| c + 1) {
                let dac = d(a, c);
                if dac >= dab {
                    break;
                }
                let j = pos[c];
                if j <= i + 1 {
                    continue;
                }
                let dcd = if j < n { d(c, t[j + 1]) } else { 0.0 };
                let dbd = if j < n { d(b, t[j + 1]) } else { 0.0 };
                if dab + dcd - dac - dbd > 1e-12 {
                    t[i + 1..=j].reverse();
                    for (k, &v) in t.iter().enumerate().take(j + 1).skip(i + 1) {
                        pos[v] = k;
                    }
                    improved_any = true;
                    break;
                }
            }
        }
        // Or-opt: move a run of 1-3 nodes between two neighbours elsewhere,
        // either way round.
        for seg in 1..=3usize {
            let mut i = 1;
            while i + seg <= n {
                let (s0, s1) = (t[i], t[i + seg - 1]);
                let prev = t[i - 1];
                let next = if i + seg <= n { t.get(i + seg).copied() } else { None };
                let removed = d(prev, s0) + next.map_or(0.0, |x| d(s1, x)) - next.map_or(0.0, |x| d(prev, x));
                let mut best: Option<(f64, usize, bool)> = None;
                for &c in neigh[s0 - 1].iter().chain(neigh[s1 - 1].iter()) {
                    let c = c + 1;
                    let j = pos[c];
                    if j >= i - 1 && j < i + seg {
                        continue;
                    }
                    // Insert between t[j] and t[j+1].
                    let (u, w) = (t[j], t.get(j + 1).copied());
                    let base = w.map_or(0.0, |w| d(u, w));
                    let fwd = d(u, s0) + w.map_or(0.0, |w| d(s1, w)) - base;
                    let rev = d(u, s1) + w.map_or(0.0, |w| d(s0, w)) - base;
                    for (cost, r) in [(fwd, false), (rev, true)] {
                        if removed - cost > 1e-12 && best.is_none_or(|b| removed - cost > b.0) {
                            best = Some((removed - cost, j, r));
                        }
                    }
                }
                if let Some((_, j, r)) = best {
                    let mut run: Vec<usize> = t.drain(i..i + seg).collect();
                    if r {
                        run.reverse();
                    }
                    let at = if j < i { j + 1 } else { j + 1 - seg };
                    t.splice(at..at, run);
                    for (k, &v) in t.iter().enumerate() {
                        pos[v] = k;
                    }
                    improved_any = true;
                }
                i += 1;
            }
        }
        if !improved_any {
            break;
        }
    }
    order.clear();
    order.extend(t[1..].iter().map(|&v| v - 1));
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_points(n: usize, seed: u64) -> Vec<P2> {
        let mut s = seed;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n).map(|_| P2::new(100.0 * r(), 100.0 * r())).collect()
    }

    #[test]
    fn orders_are_permutations_and_improve_on_nearest_neighbour() {
        for seed in [1u64, 7, 99] {
            let pts = random_points(500, seed);
            let nn = nearest_neighbour(&pts, P2::origin());
            let op = improved(&pts, P2::origin());
            for o in [&nn, &op] {
                let mut s = o.to_vec();
                s.sort();
                assert_eq!(s, (0..500).collect::<Vec<_>>());
            }
            let (tn, to) = (travel(&pts, &nn, P2::origin()), travel(&pts, &op, P2::origin()));
            assert!(to <= 0.9 * tn, "seed {seed}: improved {to} vs nn {tn}");
        }
    }

    #[test]
    fn nearest_neighbour_matches_brute_force() {
        let pts = random_points(300, 5);
        let mut done = [false; 300];
        let mut here = P2::origin();
        let mut want = Vec::new();
        for _ in 0..300 {
            let i = (0..300)
                .filter(|&i| !done[i])
                .min_by(|&a, &b| dist(&here, &pts[a]).total_cmp(&dist(&here, &pts[b])).then(a.cmp(&b)))
                .unwrap();
            done[i] = true;
            want.push(i);
            here = pts[i];
        }
        assert_eq!(nearest_neighbour(&pts, P2::origin()), want);
    }
}
