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
//! parallel). Along every whole fibre, the exact blocked stretches are
//! found triangle by triangle (module `fibre`): one triangle blocks one
//! interval of a fibre, whose ends are bisected to within `tol`. So an
//! edge whose ends are both free can hold two crossings, where the
//! boundary dips across it between the nodes; an edge with ends that
//! differ three; and an edge blocked at both ends two, where a free gap
//! (two islands closer than the sampling) crosses it. The crossings are
//! joined cell by cell (marching squares generalised to any even number
//! of crossings round a cell; a cell with four or more decided by a drop
//! at its centre) into
//! closed loops. The loops are directed with the blocked side — the
//! material — on the right of the direction of travel: climb milling with
//! a clockwise (M3) spindle, so round an island clockwise and round a
//! pocket's wall counter-clockwise.
//!
//! What is exact and what is sampled: every loop vertex lies on a fibre
//! within `tol` of a point where the cutter touches the model (the drop
//! on either side of it is checked, not interpolated), and every place a
//! fibre enters or leaves the blocked set is a vertex. Between fibres the
//! loop is a straight chord: a blocked feature or a free gap that no fibre
//! meets is missed, one that meets a single fibre only is left out (its
//! "loop" would run through it and back), and a corner of the waterline is
//! cut by at most the chord's sag. Choose the sampling below the smallest
//! feature to keep. With [`Waterline::chord_tol`] the chords are refined:
//! points found across each chord's middle (see `split_chord`) are added
//! until every chord is within the tolerance of the waterline; those
//! points lie between the fibres, each a free point within `tol` of a
//! blocked one.

use super::fibre::{FibreEdge, Stretch, blocked_stretches};
use super::{DropCutter, DropError};
use crate::geometry::P2;
use rayon::prelude::*;

/// How finely waterlines are sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waterline {
    /// Distance between fibres (grid lines along X and along Y), mm.
    pub sampling: f64,
    /// Bisection stops when a loop vertex is known within this along its
    /// fibre, mm.
    pub tol: f64,
    /// When set, points are added between fibres until the middle of
    /// every chord lies within half of this of the waterline, which puts
    /// the whole chord within this where the waterline bends one way
    /// between its ends (mm): OpenCAMLib's adaptive waterline refines its
    /// fibres for the same reason. `None`: the fibre points joined by
    /// chords.
    pub chord_tol: Option<f64>,
}

/// How many times a chord is halved at most by the refinement: 2^10
/// pieces between two fibre points.
const MAX_REFINE_DEPTH: u32 = 10;

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
        if let Some(t) = self.chord_tol
            && !(t.is_finite() && t > 0.0)
        {
            return Err(DropError::Option(format!(
                "the waterline chord tolerance must be positive, got {t}"
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
            let mut loops = self.trace(dc, &grid, &heights, z);
            if let Some(chord_tol) = self.chord_tol {
                let blocked = |p: P2| dc.drop_above(p.x, p.y, z) > z;
                loops = loops
                    .into_par_iter()
                    .filter_map(|lp| self.refine(&blocked, &lp, chord_tol))
                    .collect();
            }
            out.push(loops);
            let last = k + 1 == zs.len();
            crate::progress::advance(if last { nodes - share * k as u64 } else { share });
        }
        Ok(out)
    }

    /// `lp` (closed, the blocked side on its right) with points added
    /// between its vertices until the middle of every chord is within
    /// half of `chord_tol` of the waterline, or a chord has been halved
    /// [`MAX_REFINE_DEPTH`] times.
    ///
    /// A loop on one fibre (a feature that meets no other: there and back
    /// along its stretch) is refined like any other, its two chords probed
    /// out to the neighbouring fibres on either side (the feature meets
    /// neither, so it ends before them), which turns it into a loop round
    /// the feature; `None` when that finds nothing, and the loop is left
    /// out as without refinement.
    fn refine(&self, blocked: &impl Fn(P2) -> bool, lp: &[P2], chord_tol: f64) -> Option<Vec<P2>> {
        let one_fibre = on_one_fibre(lp);
        let mut out = Vec::with_capacity(lp.len() * 2);
        for w in lp.windows(2) {
            out.push(w[0]);
            let reach = if one_fibre {
                self.sampling
            } else {
                0.5 * (w[1] - w[0]).norm()
            };
            self.split_chord(blocked, w[0], w[1], chord_tol, reach, MAX_REFINE_DEPTH, &mut out);
        }
        out.extend(lp.last());
        (!on_one_fibre(&out)).then_some(out)
    }

    /// Push the points that chord `a`-`b` needs between its ends.
    ///
    /// The waterline near the chord's middle `m` is found along the
    /// chord's normal: when `m` is free the chord runs outside the blocked
    /// set and the waterline lies to its right (the blocked side), when `m`
    /// is blocked it lies to the left. One drop at half of `chord_tol`
    /// that way settles most chords (the waterline is that close, and so
    /// within the tolerance along the whole chord where it bends one way);
    /// otherwise the crossing is bisected between there and `reach` out
    /// (half the chord's length: a circular arc's sag is at most that), to
    /// `tol` like the fibre points, the free end kept (every vertex is a
    /// free point). A chord whose far probe finds no crossing is left as it
    /// is: the waterline there is farther than the chord's reach, which a
    /// finer sampling, not a refinement, has to catch.
    #[allow(clippy::too_many_arguments)]
    fn split_chord(
        &self,
        blocked: &impl Fn(P2) -> bool,
        a: P2,
        b: P2,
        chord_tol: f64,
        reach: f64,
        depth: u32,
        out: &mut Vec<P2>,
    ) {
        let d = b - a;
        let len = d.norm();
        // A chord no longer than the tolerance is within it of any curve
        // through its ends that it bounds with a sag of at most half its
        // length.
        if depth == 0 || len <= chord_tol || reach <= 0.5 * chord_tol {
            return;
        }
        let m = a + d * 0.5;
        let right = crate::geometry::V2::new(d.y, -d.x) / len;
        let inside = blocked(m);
        let way = if inside { -right } else { right };
        // Half the tolerance at the middle: over a span that bends one way
        // the gap between chord and curve is a concave function along the
        // chord, zero at its ends, so nowhere more than twice its value at
        // the middle.
        let settled = m + way * (0.5 * chord_tol);
        if blocked(settled) != inside {
            return;
        }
        let (mut near, mut far) = (settled, m + way * reach);
        if blocked(far) == inside {
            return;
        }
        while (far - near).norm() > self.tol {
            let mid = near + (far - near) * 0.5;
            if blocked(mid) == inside {
                near = mid;
            } else {
                far = mid;
            }
        }
        let p = if inside { far } else { near };
        let half = |u: P2, v: P2| 0.5 * (v - u).norm();
        self.split_chord(blocked, a, p, chord_tol, half(a, p), depth - 1, out);
        out.push(p);
        self.split_chord(blocked, p, b, chord_tol, half(p, b), depth - 1, out);
    }

    /// The loops at `z` from the node heights.
    fn trace(&self, dc: &DropCutter, grid: &Fibres, heights: &[f64], z: f64) -> Vec<Vec<P2>> {
        let h = self.sampling;
        let blocked = |x: f64, y: f64| dc.drop_above(x, y, z) > z;
        let state: Vec<bool> = heights.par_iter().map(|&hz| hz > z).collect();
        // Every fibre's blocked stretches, whole fibres at once: a triangle
        // is searched once per fibre, not once per grid edge it reaches.
        let fibres: Vec<Vec<Stretch>> = (0..grid.ny + grid.nx)
            .into_par_iter()
            .map(|k| blocked_stretches(dc, &grid.fibre(k), z, self.tol))
            .collect();
        // Every edge's crossings, in order along it (from its lower node):
        // its fibre's stretch ends that fall on it, where the stretches
        // agree with its nodes' drops; where round-off makes them disagree
        // (a node within the tolerance of a stretch's end), the edge's own
        // search. An edge blocked at both ends holds crossings where a free
        // gap crosses it.
        let per_edge: Vec<(usize, Vec<P2>)> = (0..grid.n_edges())
            .into_par_iter()
            .filter_map(|e| {
                let (a, b) = grid.edge_nodes(e);
                let (f, p0, p1) = grid.edge_on_fibre(e);
                let st = &fibres[f];
                let agree = blocked_at(st, p0) == state[a] && blocked_at(st, p1) == state[b];
                let pts = if agree {
                    let fe = grid.fibre(f);
                    ends_within(st, p0, p1)
                        .map(|s| {
                            let (x, y) = fe.at(s);
                            P2::new(x, y)
                        })
                        .collect()
                } else if state[a] && state[b] {
                    Vec::new()
                } else {
                    self.edge_crossings(dc, grid, e, (state[a], state[b]), z)
                };
                (!pts.is_empty()).then_some((e, pts))
            })
            .collect();
        // Crossing ids: edge e's are first[e]..first[e + 1].
        let mut first = vec![0u32; grid.n_edges() + 1];
        for (e, pts) in &per_edge {
            first[e + 1] = pts.len() as u32;
        }
        for e in 0..grid.n_edges() {
            first[e + 1] += first[e];
        }
        let points: Vec<P2> = per_edge.into_iter().flat_map(|(_, p)| p).collect();
        // Directed segments, cell by cell: from a crossing where the cell
        // boundary (counter-clockwise) enters the blocked set to one where
        // it leaves it, which keeps the blocked side on the right. A
        // crossing is entered in one of its edge's two cells and left in
        // the other (they run along the edge in opposite directions), and
        // the grid's outer edges are free, so each crossing starts exactly
        // one segment and ends exactly one: the segments form closed loops.
        const NONE: usize = usize::MAX;
        let mut next = vec![NONE; points.len()];
        let mut starts: Vec<usize> = Vec::new();
        let mut seq: Vec<(usize, bool)> = Vec::new();
        for j in 0..grid.ny - 1 {
            for i in 0..grid.nx - 1 {
                // Cell edges counter-clockwise (bottom, right, top, left),
                // each with whether the walk runs along it from its lower
                // node, and the corner it starts at.
                let edges = [
                    (grid.h_edge(i, j), true, grid.node(i, j)),
                    (grid.v_edge(i + 1, j), true, grid.node(i + 1, j)),
                    (grid.h_edge(i, j + 1), false, grid.node(i + 1, j + 1)),
                    (grid.v_edge(i, j), false, grid.node(i, j + 1)),
                ];
                if edges.iter().all(|&(e, _, _)| first[e] == first[e + 1]) {
                    continue;
                }
                // The crossings in walking order, each an entry into the
                // blocked set or an exit from it; they alternate.
                seq.clear();
                for &(e, forward, corner) in &edges {
                    let mut inside = state[corner];
                    let ids = first[e] as usize..first[e + 1] as usize;
                    let mut push = |k: usize| {
                        seq.push((k, !inside));
                        inside = !inside;
                    };
                    if forward {
                        ids.for_each(&mut push);
                    } else {
                        ids.rev().for_each(&mut push);
                    }
                }
                // With two crossings there is one way to join them. With
                // more (a saddle), the drop at the centre says whether the
                // blocked stretches are joined through the cell (pair each
                // entry with the exit before it) or apart (with the exit
                // after it).
                let n = seq.len();
                let joined = n >= 4 && {
                    let c = grid.node_xy(grid.node(i, j));
                    blocked(c.x + 0.5 * h, c.y + 0.5 * h)
                };
                for p in 0..n {
                    let (from, entry) = seq[p];
                    if !entry {
                        continue;
                    }
                    let q = if joined { (p + n - 1) % n } else { (p + 1) % n };
                    let (to, exit) = seq[q];
                    if !exit {
                        next[from] = to;
                        starts.push(from);
                    }
                }
            }
        }
        // Follow the segments into loops. A loop whose points all lie on
        // one fibre is a blocked stretch that no other fibre meets: its
        // "loop" would run through it and back, so it is left out (the
        // feature is narrower than the sampling), unless the loops are
        // refined, which traces it (`refine`).
        let mut used = vec![false; points.len()];
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
            let kept = self.chord_tol.is_some() || !on_one_fibre(&lp);
            if k == start && lp.len() >= 2 && kept {
                lp.push(lp[0]);
                loops.push(lp);
            }
        }
        loops
    }

    /// The points where edge `e` (its ends' states given) crosses the
    /// boundary of the blocked set at `z`, searched on the edge alone: the
    /// way out where its fibre's stretches disagree with the node states
    /// (a node within the tolerance of a stretch's end). In order from its
    /// lower node, each a free point within `tol` of a blocked one: the
    /// edge's own exact stretches where they agree with the node states;
    /// where they do not either, the one bisection between the nodes (no
    /// crossing when both are free).
    fn edge_crossings(&self, dc: &DropCutter, grid: &Fibres, e: usize, ends: (bool, bool), z: f64) -> Vec<P2> {
        let (a, b) = grid.edge_nodes(e);
        let (pa, pb) = (grid.node_xy(a), grid.node_xy(b));
        let along_x = pa.y == pb.y;
        let fe = FibreEdge {
            x0: pa.x,
            y0: pa.y,
            along_x,
            len: if along_x { pb.x - pa.x } else { pb.y - pa.y },
        };
        let at = |s: f64| {
            if along_x {
                P2::new(pa.x + s, pa.y)
            } else {
                P2::new(pa.x, pa.y + s)
            }
        };
        let st = blocked_stretches(dc, &fe, z, self.tol);
        let starts_blocked = st.first().is_some_and(|s| s.0.is_none());
        let ends_blocked = st.last().is_some_and(|s| s.1.is_none());
        if (starts_blocked, ends_blocked) == ends && !st.iter().any(|s| s.0.is_none() && s.1.is_none()) {
            return st.iter().flat_map(|s| [s.0, s.1]).flatten().map(at).collect();
        }
        if ends.0 == ends.1 {
            return Vec::new();
        }
        // Bisect from the free end `lo` to the blocked end `hi`.
        let (mut lo, mut hi) = if ends.0 { (pb, pa) } else { (pa, pb) };
        while (hi - lo).norm() > self.tol {
            let m = P2::from((lo.coords + hi.coords) * 0.5);
            if m == lo || m == hi {
                break;
            }
            if dc.drop_above(m.x, m.y, z) > z {
                hi = m;
            } else {
                lo = m;
            }
        }
        // The free end: the cutter there touches, never cuts.
        vec![lo]
    }
}

/// Whether every point of `lp` lies on one line along X or along Y.
fn on_one_fibre(lp: &[P2]) -> bool {
    lp.iter().all(|p| p.x == lp[0].x) || lp.iter().all(|p| p.y == lp[0].y)
}

/// Whether the fibre position `p` lies inside one of the stretches
/// (a free end is free).
fn blocked_at(st: &[Stretch], p: f64) -> bool {
    st.iter()
        .any(|s| s.0.is_none_or(|a| a < p) && s.1.is_none_or(|b| p < b))
}

/// The stretch ends on the part `[p0, p1]` of a fibre, in order: an end
/// where a stretch starts counts on the edge whose lower node it is at,
/// one where a stretch ends on the edge whose upper node it is at (the
/// node, free, is that end).
fn ends_within(st: &[Stretch], p0: f64, p1: f64) -> impl Iterator<Item = f64> + '_ {
    st.iter().flat_map(move |s| {
        let a = s.0.filter(|&a| p0 <= a && a < p1);
        let b = s.1.filter(|&b| p0 < b && b <= p1);
        [a, b].into_iter().flatten()
    })
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

    /// Fibre `k`: the rows along X first (`ny` of them), then the
    /// columns along Y, each from its first node to its last.
    fn fibre(&self, k: usize) -> FibreEdge {
        if k < self.ny {
            FibreEdge {
                x0: self.x(0),
                y0: self.y(k),
                along_x: true,
                len: self.x(self.nx - 1) - self.x(0),
            }
        } else {
            FibreEdge {
                x0: self.x(k - self.ny),
                y0: self.y(0),
                along_x: false,
                len: self.y(self.ny - 1) - self.y(0),
            }
        }
    }

    /// The fibre edge `e` lies on and its ends' positions along it.
    fn edge_on_fibre(&self, e: usize) -> (usize, f64, f64) {
        let nh = (self.nx - 1) * self.ny;
        if e < nh {
            let (j, i) = (e / (self.nx - 1), e % (self.nx - 1));
            (j, self.x(i) - self.x(0), self.x(i + 1) - self.x(0))
        } else {
            let e = e - nh;
            let (j, i) = (e / self.nx, e % self.nx);
            (self.ny + i, self.y(j) - self.y(0), self.y(j + 1) - self.y(0))
        }
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
