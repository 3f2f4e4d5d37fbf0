//! Waterlines: the closed paths a cutter follows around a model at one
//! height, touching it without cutting into it (constant-Z finishing of
//! steep walls, where raster drop-cutter passes leave wide scallops).
//!
//! The tip at `(x, y, z)` cuts into the model exactly when the cutter
//! dropped at `(x, y)` stops above `z`. So the waterline at `z` is the
//! boundary of the *blocked* set `{(x, y) : drop(x, y) > z}`: the drop is
//! the one exact test, shared with the raster passes. That boundary is
//! found on "fibres" as OpenCAMLib's waterline does: lines along X and Y
//! a sampling step apart. Every grid node is classified by one drop (in
//! parallel); each grid edge whose ends differ holds a point of the
//! waterline, found by bisection along the edge to within `tol`; the
//! points are joined cell by cell (marching squares, a saddle cell
//! decided by a drop at its centre) into closed loops. The loops are
//! directed with the blocked side — the material — on the right of the
//! direction of travel: climb milling with a clockwise (M3) spindle, so
//! round an island clockwise and round a pocket's wall counter-clockwise.
//!
//! What is exact and what is sampled: every loop vertex lies on a fibre
//! within `tol` of a point where the cutter touches the model (the drop
//! on either side of it is checked, not interpolated). Between fibres the
//! loop is a straight chord: a blocked feature narrower than the sampling
//! step between two fibres can be missed, and a corner of the waterline
//! is cut by at most the chord's sag. Choose the sampling below the
//! smallest feature to keep.

use super::{DropCutter, DropError};
use crate::geometry::P2;
use rayon::prelude::*;
use std::collections::HashMap;

/// How finely waterlines are sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waterline {
    /// Distance between fibres (grid lines along X and along Y), mm.
    pub sampling: f64,
    /// Bisection stops when a loop vertex is known within this along its
    /// fibre, mm.
    pub tol: f64,
}

/// More fibre grid nodes than this are refused (a node height is 8 bytes;
/// minutes of drops on two cores).
pub const MAX_NODES: f64 = 5.0e7;

impl Waterline {
    /// The loops at tip height `z`, each closed (its last point is its
    /// first) and directed with the model on its right; in a fixed order
    /// (by the grid cell each loop's first segment lies in). No loop when
    /// the cutter touches nothing above `z`.
    pub fn loops(&self, dc: &DropCutter, z: f64) -> Result<Vec<Vec<P2>>, DropError> {
        Ok(self.levels(dc, &[z])?.pop().unwrap_or_default())
    }

    /// Nodes of the fibre grid [`levels`](Self::levels) drops for this
    /// mesh and cutter; the progress counter advances by twice this over
    /// a whole call (once per node dropped, then in equal shares per
    /// level traced).
    pub fn grid_nodes(&self, dc: &DropCutter) -> Result<u64, DropError> {
        self.check()?;
        let g = Fibres::new(dc, self.sampling)?;
        Ok((g.nx * g.ny) as u64)
    }

    fn check(&self) -> Result<(), DropError> {
        let h = self.sampling;
        if !(h.is_finite() && h > 0.0) {
            return Err(DropError::Option(format!(
                "the waterline sampling must be positive, got {h}"
            )));
        }
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(DropError::Option(format!(
                "the waterline tolerance must be positive, got {}",
                self.tol
            )));
        }
        Ok(())
    }

    /// The loops at each of the heights `zs`, in their order. The node
    /// heights do not depend on the level (a node is blocked at `z` when
    /// the drop there stops above `z`), so the fibre grid is dropped once
    /// for all levels, down to the lowest; only the bisections and saddle
    /// centres drop again per level.
    pub fn levels(&self, dc: &DropCutter, zs: &[f64]) -> Result<Vec<Vec<Vec<P2>>>, DropError> {
        self.check()?;
        if let Some(z) = zs.iter().find(|z| !z.is_finite()) {
            return Err(DropError::Option(format!("waterline height {z} is not finite")));
        }
        let Some(lowest) = zs.iter().copied().reduce(f64::min) else {
            return Ok(Vec::new());
        };
        let grid = Fibres::new(dc, self.sampling)?;
        // Node heights, row by row in parallel; contacts below the lowest
        // level need not be searched for.
        let heights: Vec<f64> = (0..grid.ny)
            .into_par_iter()
            .flat_map_iter(|j| {
                let y = grid.y(j);
                crate::progress::advance(grid.nx as u64);
                (0..grid.nx).map(move |i| dc.drop_above(grid.x(i), y, lowest))
            })
            .collect();
        let nodes = heights.len() as u64;
        let share = nodes / zs.len() as u64;
        let mut out = Vec::with_capacity(zs.len());
        for (k, &z) in zs.iter().enumerate() {
            out.push(self.trace(dc, &grid, &heights, z));
            let last = k + 1 == zs.len();
            crate::progress::advance(if last { nodes - share * k as u64 } else { share });
        }
        Ok(out)
    }

    /// The loops at `z` from the node heights.
    fn trace(&self, dc: &DropCutter, grid: &Fibres, heights: &[f64], z: f64) -> Vec<Vec<P2>> {
        let h = self.sampling;
        let blocked = |x: f64, y: f64| dc.drop_above(x, y, z) > z;
        let state: Vec<bool> = heights.par_iter().map(|&hz| hz > z).collect();
        // Edges whose ends differ, in id order, and their points.
        let crossing: Vec<usize> = (0..grid.n_edges())
            .filter(|&e| {
                let (a, b) = grid.edge_nodes(e);
                state[a] != state[b]
            })
            .collect();
        let points: Vec<P2> = crossing
            .par_iter()
            .map(|&e| {
                let (a, b) = grid.edge_nodes(e);
                let (pa, pb) = (grid.node_xy(a), grid.node_xy(b));
                // Bisect from the free end `lo` to the blocked end `hi`.
                let (mut lo, mut hi) = if state[a] { (pb, pa) } else { (pa, pb) };
                while (hi - lo).norm() > self.tol {
                    let m = P2::from((lo.coords + hi.coords) * 0.5);
                    if m == lo || m == hi {
                        break;
                    }
                    if blocked(m.x, m.y) {
                        hi = m;
                    } else {
                        lo = m;
                    }
                }
                // The free end: the cutter there touches, never cuts.
                lo
            })
            .collect();
        let index_of: HashMap<usize, usize> = crossing.iter().enumerate().map(|(k, &e)| (e, k)).collect();
        // Directed segments, cell by cell: from an edge where the cell
        // boundary (counter-clockwise) enters the blocked set to one where
        // it leaves it, which keeps the blocked side on the right. A
        // crossing edge is entered in one of its two cells and left in the
        // other (they run along it in opposite directions), and the grid's
        // outer nodes are free, so each crossing starts exactly one segment
        // and ends exactly one: the segments form closed loops.
        const NONE: usize = usize::MAX;
        let mut next = vec![NONE; crossing.len()];
        let mut starts: Vec<usize> = Vec::new();
        for j in 0..grid.ny - 1 {
            for i in 0..grid.nx - 1 {
                let corners = [
                    grid.node(i, j),
                    grid.node(i + 1, j),
                    grid.node(i + 1, j + 1),
                    grid.node(i, j + 1),
                ];
                let s = corners.map(|n| state[n]);
                if s.iter().all(|&b| b == s[0]) {
                    continue;
                }
                // Cell edges counter-clockwise: bottom, right, top, left,
                // each running from corner k to corner k + 1.
                let edges = [
                    grid.h_edge(i, j),
                    grid.v_edge(i + 1, j),
                    grid.h_edge(i, j + 1),
                    grid.v_edge(i, j),
                ];
                let mut ins = Vec::with_capacity(2);
                let mut outs = Vec::with_capacity(2);
                for k in 0..4 {
                    match (s[k], s[(k + 1) % 4]) {
                        (false, true) => ins.push(k),
                        (true, false) => outs.push(k),
                        _ => {}
                    }
                }
                // With two crossings there is one way to join them. In a
                // saddle (two blocked corners facing each other) the drop at
                // the centre says whether the blocked corners are joined
                // (pair each entry with the exit before it) or apart (with
                // the exit after it).
                let joined = ins.len() == 2 && {
                    let c = grid.node_xy(corners[0]);
                    blocked(c.x + 0.5 * h, c.y + 0.5 * h)
                };
                for &k in &ins {
                    let o = if joined {
                        outs.iter().rev().find(|&&o| o < k).or(outs.last())
                    } else {
                        outs.iter().find(|&&o| o > k).or(outs.first())
                    };
                    if let (Some(from), Some(&o)) = (index_of.get(&edges[k]), o)
                        && let Some(&to) = index_of.get(&edges[o])
                    {
                        next[*from] = to;
                        starts.push(*from);
                    }
                }
            }
        }
        // Follow the segments into loops.
        let mut used = vec![false; crossing.len()];
        let mut loops = Vec::new();
        for &start in &starts {
            if used[start] {
                continue;
            }
            let mut lp = Vec::new();
            let mut k = start;
            while k != NONE && !used[k] {
                used[k] = true;
                lp.push(points[k]);
                k = next[k];
            }
            if k == start && lp.len() >= 2 {
                lp.push(lp[0]);
                loops.push(lp);
            }
        }
        loops
    }
}

/// The fibre grid: nodes a sampling step apart from the mesh's box less
/// the cutter's diameter (so the outermost nodes, a diameter out, are
/// always free and every loop closes inside the grid) to at least as far
/// beyond its top corner. OpenCAMLib's `Waterline` lays its fibres on the
/// same lattice, which lets the two be compared vertex for vertex.
#[derive(Clone, Copy)]
struct Fibres {
    x0: f64,
    y0: f64,
    h: f64,
    nx: usize,
    ny: usize,
}

impl Fibres {
    fn new(dc: &DropCutter, h: f64) -> Result<Fibres, DropError> {
        let bb = dc.bbox();
        let pad = 2.0 * dc.cutter().radius();
        let (x0, y0) = (bb.min.x - pad, bb.min.y - pad);
        let fx = ((bb.max.x + pad - x0) / h).ceil() + 1.0;
        let fy = ((bb.max.y + pad - y0) / h).ceil() + 1.0;
        if !(fx * fy).is_finite() || fx * fy > MAX_NODES {
            return Err(DropError::Option(format!(
                "waterline sampling {h} mm gives {fx:.0} x {fy:.0} fibre nodes, more than {MAX_NODES:e}"
            )));
        }
        Ok(Fibres {
            x0,
            y0,
            h,
            nx: fx as usize,
            ny: fy as usize,
        })
    }

    fn x(&self, i: usize) -> f64 {
        self.x0 + i as f64 * self.h
    }

    fn y(&self, j: usize) -> f64 {
        self.y0 + j as f64 * self.h
    }

    fn node(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    fn node_xy(&self, n: usize) -> P2 {
        P2::new(self.x(n % self.nx), self.y(n / self.nx))
    }

    /// Edges along X first, `(nx - 1) * ny` of them, then along Y.
    fn n_edges(&self) -> usize {
        (self.nx - 1) * self.ny + self.nx * (self.ny - 1)
    }

    /// The edge from node (i, j) to (i + 1, j).
    fn h_edge(&self, i: usize, j: usize) -> usize {
        j * (self.nx - 1) + i
    }

    /// The edge from node (i, j) to (i, j + 1).
    fn v_edge(&self, i: usize, j: usize) -> usize {
        (self.nx - 1) * self.ny + j * self.nx + i
    }

    fn edge_nodes(&self, e: usize) -> (usize, usize) {
        let nh = (self.nx - 1) * self.ny;
        if e < nh {
            let (j, i) = (e / (self.nx - 1), e % (self.nx - 1));
            (self.node(i, j), self.node(i + 1, j))
        } else {
            let e = e - nh;
            let (j, i) = (e / self.nx, e % self.nx);
            (self.node(i, j), self.node(i, j + 1))
        }
    }
}

#[cfg(test)]
#[path = "waterline_tests.rs"]
mod tests;
