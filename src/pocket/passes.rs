//! The passes of a grid pocket at full depth (the Iowa State grid-pocket
//! thesis (1999) §3.5): the main path (navigation reversed), the wall pass
//! along the tool-centre offset of the boundary, and the X and Y zigzag
//! clean-up between neighbouring cells the navigation did not join (§3.2:
//! on a sculptured bottom, material is left between neighbours the tool
//! never moved directly between).
//!
//! Each pass is a polyline at the touching height, split where a chord
//! would dip below it ([`Contact::safe_line`]); the main path also keeps
//! its cell points grouped in straight runs for the curve fits.

use super::contact::Contact;
use super::grid::{Grid, Region};
use super::navigate::{Navigation, neighbour};
use crate::geometry::{P2, P3};
use rayon::prelude::*;

/// What a pass is for; previews colour by it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PassKind {
    /// The main path: the navigation reversed, over every cell.
    Main,
    /// Along the tool-centre offset of the boundary.
    Wall,
    /// Clean-up between X neighbours the navigation did not join.
    XZigzag,
    /// Clean-up between Y neighbours the navigation did not join.
    YZigzag,
    /// A contour-parallel loop of the offset strategy.
    Offset,
    /// A feed move between passes inside the pocket.
    Link,
}

impl PassKind {
    /// The name used in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PassKind::Main => "main",
            PassKind::Wall => "wall",
            PassKind::XZigzag => "x_zigzag",
            PassKind::YZigzag => "y_zigzag",
            PassKind::Offset => "offset",
            PassKind::Link => "link",
        }
    }
}

/// One pass at full depth.
#[derive(Debug, Clone)]
pub struct Pass {
    /// What the pass is for.
    pub kind: PassKind,
    /// Touching points, gouge-safe as a polyline.
    pub pts: Vec<P3>,
    /// Main path only: the cell points in straight runs (each run shares
    /// its first point with the previous run's last).
    pub runs: Vec<Vec<P3>>,
}

/// Touching point of an XY position.
pub fn touch(c: &Contact, p: P2) -> P3 {
    P3::new(p.x, p.y, c.tip_z(p.x, p.y))
}

/// A polyline through `xy` at touching height, split for gouge safety.
pub fn lift(c: &Contact, xy: &[P2]) -> Vec<P3> {
    // Each piece starts where the one before ended (safe_line ends on its
    // target), so the touches and then the pieces are independent: both run
    // on every core, in order, the same points as one after the other.
    let touched: Vec<P3> = xy.par_iter().map(|p| touch(c, *p)).collect();
    let Some(first) = touched.first() else {
        return Vec::new();
    };
    let pieces: Vec<Vec<P3>> = touched
        .par_windows(2)
        .map(|w| {
            let mut piece = Vec::new();
            c.safe_line(w[0], w[1], &mut piece);
            piece
        })
        .collect();
    let mut out = Vec::with_capacity(1 + pieces.iter().map(Vec::len).sum::<usize>());
    out.push(*first);
    out.extend(pieces.into_iter().flatten());
    out
}

/// The main path: each navigation walk reversed, last walk first.
pub fn main_passes(c: &Contact, grid: &Grid, nav: &Navigation) -> Vec<Pass> {
    nav.walks
        .iter()
        .rev()
        .map(|w| {
            let xy: Vec<P2> = w.iter().rev().map(|&id| grid.centre(grid.cells[id])).collect();
            let cells: Vec<P3> = xy.iter().map(|p| touch(c, *p)).collect();
            let mut runs: Vec<Vec<P3>> = Vec::new();
            for k in 0..cells.len() {
                let straight = k >= 2 && {
                    let (a, b, d) = (xy[k - 2], xy[k - 1], xy[k]);
                    (b - a).perp(&(d - b)).abs() < 1e-12 && (b - a).dot(&(d - b)) > 0.0
                };
                match runs.last_mut() {
                    Some(r) if straight || r.len() < 2 => r.push(cells[k]),
                    Some(r) => {
                        let last = *r.last().expect("runs are not empty");
                        runs.push(vec![last, cells[k]]);
                    }
                    None => runs.push(vec![cells[k]]),
                }
            }
            Pass {
                kind: PassKind::Main,
                pts: lift(c, &xy),
                runs,
            }
        })
        .collect()
}

/// A closed loop of vertices walked once round from its vertex nearest
/// `near` (the first vertex without one; the lowest index among equally
/// near ones), each edge cut into pieces of at most `pitch` so a pass laid
/// on the surface follows it, and closed by its start again. Returns the
/// points and the start vertex.
pub fn closed_loop_from_nearest(l: &[P2], near: Option<P2>, pitch: f64) -> (Vec<P2>, P2) {
    let k0 = match near {
        Some(q) => (0..l.len())
            .min_by(|&a, &b| (l[a] - q).norm().total_cmp(&(l[b] - q).norm()))
            .unwrap_or(0),
        None => 0,
    };
    let mut xy = Vec::new();
    for s in 0..l.len() {
        let (a, b) = (l[(k0 + s) % l.len()], l[(k0 + s + 1) % l.len()]);
        let n = (((b - a).norm() / pitch).ceil() as usize).max(1);
        for t in 0..n {
            xy.push(a + (b - a) * (t as f64 / n as f64));
        }
    }
    xy.push(l[k0]);
    (xy, l[k0])
}

/// The wall pass around each loop of the region, starting at the vertex
/// nearest `near` (the thesis starts the wall where the main path ends),
/// densified to the grid pitch so the height follows the surface.
pub fn wall_passes(c: &Contact, region: &Region, near: P2, pitch: f64) -> Vec<Pass> {
    let mut loops: Vec<&Vec<P2>> = region.loops.iter().collect();
    let dist = |l: &Vec<P2>| l.iter().map(|p| (p - near).norm()).fold(f64::INFINITY, f64::min);
    loops.sort_by(|a, b| dist(a).total_cmp(&dist(b)));
    loops
        .into_iter()
        .filter(|l| l.len() >= 3)
        .map(|l| {
            let (xy, _) = closed_loop_from_nearest(l, Some(near), pitch);
            Pass {
                kind: PassKind::Wall,
                pts: lift(c, &xy),
                runs: Vec::new(),
            }
        })
        .collect()
}

/// Zigzag clean-up along X (`along_x`) or Y: on every row (column), the
/// runs of neighbouring cell pairs the navigation did not join, rows in
/// turn, alternating direction.
pub fn zigzag_passes(c: &Contact, grid: &Grid, region: &Region, nav: &Navigation, along_x: bool) -> Vec<Pass> {
    let kind = if along_x { PassKind::XZigzag } else { PassKind::YZigzag };
    let d = if along_x { (1, 0) } else { (0, 1) };
    // Lines of cells: rows (X) or columns (Y), each sorted along the line.
    let mut lines: std::collections::BTreeMap<i64, Vec<usize>> = Default::default();
    for (id, &(i, j)) in grid.cells.iter().enumerate() {
        lines.entry(if along_x { j } else { i }).or_default().push(id);
    }
    let mut out = Vec::new();
    for (row, (_, mut ids)) in lines.into_iter().enumerate() {
        ids.sort_by_key(|&id| if along_x { grid.cells[id].0 } else { grid.cells[id].1 });
        let mut runs: Vec<Vec<usize>> = Vec::new();
        let mut cur: Vec<usize> = Vec::new();
        for &id in &ids {
            let pair = neighbour(grid, region, id, d).filter(|&m| !nav.joined.contains(&(id.min(m), id.max(m))));
            match pair {
                Some(m) => {
                    if cur.is_empty() {
                        cur.push(id);
                    }
                    cur.push(m);
                }
                None => {
                    if cur.len() >= 2 {
                        runs.push(std::mem::take(&mut cur));
                    }
                    cur.clear();
                }
            }
        }
        if row % 2 == 1 {
            runs.reverse();
            for r in &mut runs {
                r.reverse();
            }
        }
        for r in runs {
            let xy: Vec<P2> = r.iter().map(|&id| grid.centre(grid.cells[id])).collect();
            out.push(Pass {
                kind,
                pts: lift(c, &xy),
                runs: Vec::new(),
            });
        }
    }
    out
}
