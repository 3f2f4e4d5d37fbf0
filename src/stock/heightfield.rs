//! The stock as a height field: the height of the material at the centre
//! of every cell of a regular XY grid that tiles the stock box exactly.
//!
//! A straight move of the cutter removes, in each cell, everything above
//! the lower envelope of the cutter's surface swept along the move. For a
//! horizontal move that envelope is exact: at a cell centre at distance `d`
//! from the move's XY segment it is `z + profile(d)`. Each grid row meets
//! the swept capsule in one interval, computed in closed form, so only
//! cells the cutter can reach are visited. A move that changes Z is cut as a
//! run of short horizontal pieces, each at the higher Z of its ends. That
//! leaves at most one piece's Z step of material, and pieces are chosen so
//! the step is under a quarter of the cell size.
//!
//! Each cut lowers a cell to `min(height, envelope)`. That is idempotent,
//! so cutting the same place again (overlapping moves, the many short steps
//! of a chip-volume simulation) never removes more. Volumes use the
//! midpoint rule, which is unbiased. Its error comes from cells a wall passes
//! through: at most one row of cells along each wall, and it averages out
//! over a path. (Weighting partly covered cells by their coverage looks more
//! accurate for one cut, but repeated cuts compound the fraction and
//! over-remove along every wall, so it is not done.)

use super::cutter::Cutter;
use crate::geometry::P3;
use rayon::prelude::*;
use thiserror::Error;

/// Most nodes a height field may have (2 GiB of f32 heights): beyond that
/// a user surely asked for a finer resolution than they meant.
pub const MAX_NODES: usize = 1 << 29;

/// Nodes a cut must touch before its rows are spread over threads: below
/// this, the hand-over costs more than it saves.
const PARALLEL_NODES: usize = 1 << 15;

#[derive(Debug, Error, PartialEq)]
pub enum StockError {
    #[error("stock box must have positive, finite size, got {0:?} to {1:?}")]
    Box([f64; 3], [f64; 3]),
    #[error("resolution must be positive and finite, got {0} mm")]
    Resolution(f64),
    #[error("{nodes} grid nodes at resolution {res} mm is more than {max}: choose a coarser resolution")]
    TooLarge { nodes: usize, res: f64, max: usize },
    #[error("move end point is not finite")]
    NotFinite,
}

/// The stock: mean heights (mm) of (nx x ny) cells tiling [min, max] in XY.
#[derive(Debug, Clone)]
pub struct HeightField {
    x0: f64,
    y0: f64,
    dx: f64,
    dy: f64,
    nx: usize,
    ny: usize,
    bottom: f64,
    top: f64,
    h: Vec<f32>,
}

impl HeightField {
    /// A full stock block from `min` to `max` with cells as close to `res`
    /// square as lets them tile the box exactly.
    pub fn new(min: P3, max: P3, res: f64) -> Result<HeightField, StockError> {
        let size = max - min;
        if !(size.x > 0.0 && size.y > 0.0 && size.z > 0.0 && size.iter().all(|v| v.is_finite())) {
            return Err(StockError::Box(min.coords.into(), max.coords.into()));
        }
        if !(res > 0.0 && res.is_finite()) {
            return Err(StockError::Resolution(res));
        }
        let cells = |len: f64| ((len / res).round() as usize).max(1);
        let (cx, cy) = (cells(size.x), cells(size.y));
        let nodes = cx.saturating_mul(cy);
        if nodes > MAX_NODES || cx >= MAX_NODES || cy >= MAX_NODES {
            return Err(StockError::TooLarge {
                nodes,
                res,
                max: MAX_NODES,
            });
        }
        Ok(HeightField {
            x0: min.x,
            y0: min.y,
            dx: size.x / cx as f64,
            dy: size.y / cy as f64,
            nx: cx,
            ny: cy,
            bottom: min.z,
            top: max.z,
            h: vec![max.z as f32; nodes],
        })
    }

    /// Cells along X and Y.
    pub fn dims(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    /// Cell size along X and Y (mm).
    pub fn spacing(&self) -> (f64, f64) {
        (self.dx, self.dy)
    }

    /// The stock's bottom and original top (mm).
    pub fn z_range(&self) -> (f64, f64) {
        (self.bottom, self.top)
    }

    /// Centre of cell (i, j).
    pub fn node(&self, i: usize, j: usize) -> (f64, f64) {
        (
            self.x0 + (i as f64 + 0.5) * self.dx,
            self.y0 + (j as f64 + 0.5) * self.dy,
        )
    }

    /// The XY corners of the stock box.
    pub fn extent(&self) -> ((f64, f64), (f64, f64)) {
        (
            (self.x0, self.y0),
            (self.x0 + self.nx as f64 * self.dx, self.y0 + self.ny as f64 * self.dy),
        )
    }

    /// Height of cell (i, j).
    pub fn height(&self, i: usize, j: usize) -> f64 {
        self.h[j * self.nx + i] as f64
    }

    /// Material volume (mm^3).
    pub fn volume(&self) -> f64 {
        self.h.iter().map(|&z| z as f64 - self.bottom).sum::<f64>() * self.dx * self.dy
    }

    /// Cut a straight move of `tool` (tip at `a` to tip at `b`), returning
    /// the volume removed (mm^3): the chip volume of this move.
    pub fn cut(&mut self, a: P3, b: P3, tool: &Cutter) -> Result<f64, StockError> {
        if !(a.coords.iter().chain(b.coords.iter()).all(|v| v.is_finite())) {
            return Err(StockError::NotFinite);
        }
        let dz = b.z - a.z;
        if dz == 0.0 {
            return Ok(self.cut_level(a.x, a.y, b.x, b.y, a.z, tool));
        }
        // A ramp or plunge: horizontal pieces, each at the higher Z of its
        // ends, with Z steps under a quarter of the grid spacing.
        let step = 0.25 * self.dx.min(self.dy);
        let xy = ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt();
        let n = ((xy.max(dz.abs()) / step).ceil() as usize).clamp(1, 1 << 20);
        let mut removed = 0.0;
        let at = |t: f64| (a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, a.z + dz * t);
        let mut p = at(0.0);
        for k in 1..=n {
            let q = at(k as f64 / n as f64);
            removed += self.cut_level(p.0, p.1, q.0, q.1, p.2.max(q.2), tool);
            p = q;
        }
        Ok(removed)
    }

    /// Cut a horizontal move at height `z`: exact lower envelope.
    fn cut_level(&mut self, ax: f64, ay: f64, bx: f64, by: f64, z: f64, tool: &Cutter) -> f64 {
        let r = tool.radius();
        if z >= self.top {
            return 0.0;
        }
        let reach = r;
        let y_lo = ay.min(by) - reach;
        let y_hi = ay.max(by) + reach;
        let j0 = ((y_lo - self.y0) / self.dy - 0.5).ceil().max(0.0) as usize;
        let j1f = ((y_hi - self.y0) / self.dy - 0.5).floor();
        if j1f < 0.0 || j0 >= self.ny {
            return 0.0;
        }
        let j1 = (j1f as usize).min(self.ny - 1);
        if j0 > j1 {
            return 0.0;
        }
        let seg = Capsule::new(ax, ay, bx, by, r, reach);
        let geom = RowGeom {
            x0: self.x0,
            y0: self.y0,
            dx: self.dx,
            dy: self.dy,
            nx: self.nx,
        };
        let rows = &mut self.h[j0 * self.nx..(j1 + 1) * self.nx];
        let width = ((seg.len + 2.0 * reach) / self.dx) as usize + 1;
        let work = (j1 - j0 + 1).saturating_mul(width);
        let removed = if work >= PARALLEL_NODES {
            rows.par_chunks_mut(self.nx)
                .enumerate()
                .map(|(k, row)| cut_row(row, j0 + k, &geom, &seg, z, tool))
                .sum::<f64>()
        } else {
            rows.chunks_mut(self.nx)
                .enumerate()
                .map(|(k, row)| cut_row(row, j0 + k, &geom, &seg, z, tool))
                .sum::<f64>()
        };
        removed * self.dx * self.dy
    }
}

/// What a row update needs to know about the grid.
struct RowGeom {
    x0: f64,
    y0: f64,
    dx: f64,
    dy: f64,
    nx: usize,
}

/// The XY region within `reach` of the segment a-b, for a cutter of
/// radius `r` (reach = r plus half a cell, for partly covered cells).
struct Capsule {
    ax: f64,
    ay: f64,
    bx: f64,
    by: f64,
    r: f64,
    reach: f64,
    /// Unit direction and length (len 0: a disc).
    ux: f64,
    uy: f64,
    len: f64,
}

impl Capsule {
    fn new(ax: f64, ay: f64, bx: f64, by: f64, r: f64, reach: f64) -> Capsule {
        let len = ((bx - ax).powi(2) + (by - ay).powi(2)).sqrt();
        let (ux, uy) = if len > 0.0 {
            ((bx - ax) / len, (by - ay) / len)
        } else {
            (1.0, 0.0)
        };
        Capsule {
            ax,
            ay,
            bx,
            by,
            r,
            reach,
            ux,
            uy,
            len,
        }
    }

    /// The x interval where the horizontal line at `y` meets the capsule.
    /// A capsule is convex, so this is one interval: the hull of the
    /// intervals of its two end discs and its middle band.
    fn row_interval(&self, y: f64) -> Option<(f64, f64)> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for (cx, cy) in [(self.ax, self.ay), (self.bx, self.by)] {
            let e = y - cy;
            if e.abs() <= self.reach {
                let w = (self.reach * self.reach - e * e).sqrt();
                lo = lo.min(cx - w);
                hi = hi.max(cx + w);
            }
        }
        if self.len > 0.0 {
            // Band: |cross(u, p - a)| <= r and 0 <= dot(u, p - a) <= len,
            // both linear in x on this row.
            let ey = y - self.ay;
            let c0 = self.ux * ey;
            let d0 = self.uy * ey;
            let cross = if self.uy == 0.0 {
                (c0.abs() <= self.reach).then_some((f64::NEG_INFINITY, f64::INFINITY))
            } else {
                let (p, q) = ((c0 - self.reach) / self.uy, (c0 + self.reach) / self.uy);
                Some((p.min(q), p.max(q)))
            };
            let along = if self.ux == 0.0 {
                (d0 >= 0.0 && d0 <= self.len).then_some((f64::NEG_INFINITY, f64::INFINITY))
            } else {
                let (p, q) = (-d0 / self.ux, (self.len - d0) / self.ux);
                Some((p.min(q), p.max(q)))
            };
            if let (Some(c), Some(d)) = (cross, along) {
                let (l, h) = (c.0.max(d.0), c.1.min(d.1));
                if l <= h {
                    lo = lo.min(self.ax + l);
                    hi = hi.max(self.ax + h);
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// Offset from the segment's nearest point to (x, y).
    #[inline]
    fn offset(&self, x: f64, y: f64) -> (f64, f64) {
        let (px, py) = (x - self.ax, y - self.ay);
        let t = (px * self.ux + py * self.uy).clamp(0.0, self.len);
        (px - self.ux * t, py - self.uy * t)
    }
}

/// Lower row `j` to the cutter's envelope; returns the removed height sum,
/// to be multiplied by the cell area.
fn cut_row(row: &mut [f32], j: usize, g: &RowGeom, seg: &Capsule, z: f64, tool: &Cutter) -> f64 {
    let y = g.y0 + (j as f64 + 0.5) * g.dy;
    let Some((lo, hi)) = seg.row_interval(y) else {
        return 0.0;
    };
    let i0 = ((lo - g.x0) / g.dx - 0.5).ceil().max(0.0) as usize;
    let i1f = ((hi - g.x0) / g.dx - 0.5).floor();
    if i1f < 0.0 || i0 >= g.nx {
        return 0.0;
    }
    let i1 = (i1f as usize).min(g.nx - 1);
    if i0 > i1 {
        return 0.0;
    }
    let mut removed = 0.0f64;
    match tool {
        Cutter::Flat { .. } => {
            // The whole interval is under the flat bottom: a plain minimum
            // the compiler vectorises.
            let zf = z as f32;
            for h in &mut row[i0..=i1] {
                removed += (*h - zf).max(0.0) as f64;
                *h = h.min(zf);
            }
        }
        _ => {
            let r2 = seg.r * seg.r;
            for (k, h) in row[i0..=i1].iter_mut().enumerate() {
                let x = g.x0 + ((i0 + k) as f64 + 0.5) * g.dx;
                let (qx, qy) = seg.offset(x, y);
                let d2 = qx * qx + qy * qy;
                if d2 > r2 {
                    continue;
                }
                let zt = (z + tool.profile(d2)) as f32;
                if *h > zt {
                    removed += (*h - zt) as f64;
                    *h = zt;
                }
            }
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn block(res: f64) -> HeightField {
        HeightField::new(P3::new(0.0, 0.0, -5.0), P3::new(20.0, 10.0, 0.0), res).unwrap()
    }

    /// Volume of a horizontal slot of a cutter of radius r, length l,
    /// depth below the top `depth` (>= the cutter's profile height).
    fn slot_volume(tool: &Cutter, l: f64, depth: f64) -> f64 {
        // Cross-section area of the cutter's lower envelope below the top,
        // swept along l, plus the solid of revolution at the two ends.
        let r = tool.radius();
        let n = 20_000;
        let (mut area, mut rev) = (0.0, 0.0);
        for k in 0..n {
            let d = (k as f64 + 0.5) / n as f64 * r;
            let h = (depth - tool.profile(d * d)).max(0.0);
            area += 2.0 * h * r / n as f64;
            rev += 2.0 * PI * d * h * r / n as f64;
        }
        area * l + rev
    }

    #[test]
    fn straight_slots_remove_the_exact_volume_at_d_over_50() {
        let tools = [
            Cutter::flat(1.0).unwrap(),
            Cutter::ball(1.0).unwrap(),
            Cutter::torus(1.0, 0.3).unwrap(),
        ];
        for tool in tools {
            let mut s = block(2.0 / 50.0);
            let before = s.volume();
            let removed = s.cut(P3::new(4.0, 5.0, -1.5), P3::new(14.0, 5.0, -1.5), &tool).unwrap();
            let want = slot_volume(&tool, 10.0, 1.5);
            assert!(
                (removed - want).abs() / want < 0.005,
                "{tool:?}: removed {removed}, exact {want}"
            );
            assert!(
                (before - s.volume() - removed).abs() < 1e-6 * want,
                "volume bookkeeping"
            );
            // The slot floor and a point beside the slot.
            let (i, j) = (((9.0 / s.spacing().0) as usize), ((5.0 / s.spacing().1) as usize));
            let d = s.node(i, j).1 - 5.0;
            let floor = -1.5 + tool.profile(d * d);
            assert!((s.height(i, j) - floor).abs() < 1e-5, "{} vs {floor}", s.height(i, j));
            let jj = (7.0 / s.spacing().1) as usize;
            assert_eq!(s.height(i, jj), 0.0);
        }
    }

    #[test]
    fn the_error_is_at_most_one_row_per_wall_and_averages_out() {
        // A flat slot whose walls fall exactly on rows of cell centres is
        // the worst case: one extra row, 2 % of a slot at D/50.
        let tool = Cutter::flat(1.0).unwrap();
        let want = slot_volume(&tool, 10.0, 1.5);
        let mut s = block(0.04);
        let v = s
            .cut(P3::new(4.0, 5.02, -1.5), P3::new(14.0, 5.02, -1.5), &tool)
            .unwrap();
        // Bound for point sampling: the cut's outline times half a cell
        // times the depth.
        let bound = (2.0 * 10.0 + 2.0 * PI * 1.0) * 0.02 * 1.5;
        assert!((v - want).abs() <= bound, "{v} vs {want}");
        assert!((v - want).abs() / want < 0.025, "{v} vs {want}");
        // Over slots placed anywhere, the error averages out.
        let mut total = 0.0;
        let n = 40;
        for k in 0..n {
            let mut s = block(0.04);
            let y = 4.0 + 0.04 * (k as f64 * 0.618_034).fract() * 5.0;
            total += s.cut(P3::new(4.0, y, -1.5), P3::new(14.0, y, -1.5), &tool).unwrap();
        }
        let mean = total / n as f64;
        assert!((mean - want).abs() / want < 0.003, "mean {mean} vs {want}");
    }

    #[test]
    fn diagonal_moves_match_axis_moves() {
        let tool = Cutter::ball(0.5).unwrap();
        let mut a = block(0.02);
        let mut b = block(0.02);
        let va = a.cut(P3::new(5.0, 5.0, -0.3), P3::new(11.0, 5.0, -0.3), &tool).unwrap();
        let d = 6.0 / 2f64.sqrt();
        let vb = b
            .cut(P3::new(5.0, 3.0, -0.3), P3::new(5.0 + d, 3.0 + d, -0.3), &tool)
            .unwrap();
        assert!((va - vb).abs() / va < 0.005, "{va} vs {vb}");
    }

    #[test]
    fn a_plunge_leaves_a_cutter_shaped_hole() {
        let tool = Cutter::flat(1.0).unwrap();
        let mut s = block(0.02);
        let v = s.cut(P3::new(10.0, 5.0, 1.0), P3::new(10.0, 5.0, -2.0), &tool).unwrap();
        let want = PI * 2.0;
        assert!((v - want).abs() / want < 0.01, "{v} vs {want}");
        // A second pass over the same path removes nothing.
        assert_eq!(
            s.cut(P3::new(10.0, 5.0, 1.0), P3::new(10.0, 5.0, -2.0), &tool).unwrap(),
            0.0
        );
    }

    #[test]
    fn moves_off_the_stock_and_above_it_remove_nothing() {
        let tool = Cutter::flat(1.0).unwrap();
        let mut s = block(0.1);
        assert_eq!(
            s.cut(P3::new(-5.0, -5.0, -1.0), P3::new(-3.0, -5.0, -1.0), &tool)
                .unwrap(),
            0.0
        );
        assert_eq!(
            s.cut(P3::new(5.0, 5.0, 0.5), P3::new(8.0, 5.0, 0.5), &tool).unwrap(),
            0.0
        );
        assert!(
            s.cut(P3::new(5.0, 5.0, f64::NAN), P3::new(8.0, 5.0, 0.5), &tool)
                .is_err()
        );
        // Cutting across the whole stock removes the slot within the box.
        let v = s
            .cut(P3::new(-2.0, 5.0, -1.0), P3::new(22.0, 5.0, -1.0), &tool)
            .unwrap();
        assert!((v - 2.0 * 20.0).abs() < 0.005 * 40.0, "{v}");
    }

    #[test]
    fn bad_stock_is_an_error_not_a_panic() {
        assert!(HeightField::new(P3::origin(), P3::new(1.0, 1.0, 0.0), 0.1).is_err());
        assert!(HeightField::new(P3::origin(), P3::new(1.0, 1.0, 1.0), 0.0).is_err());
        assert!(matches!(
            HeightField::new(P3::origin(), P3::new(1e6, 1e6, 1.0), 1e-3),
            Err(StockError::TooLarge { .. })
        ));
    }
}
