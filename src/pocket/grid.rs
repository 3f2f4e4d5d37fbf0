//! The tool-centre region and the grid cells in it.
//!
//! The region is where the tool centre may go without the cutter crossing
//! the pocket boundary: the boundary offset inward by the tool radius
//! (exact lines and arcs through cavalier_contours). It is then written as
//! polygons that lie inside that exact region: convex arcs by chords,
//! concave arcs (around reflex corners of the pocket) by tangent polygons,
//! whose edges keep the tool radius from the corner. A grid cell is in the
//! pocket when its centre lies in those polygons (the Iowa State grid-pocket
//! thesis (1999) §3.5 steps 5-7: the cutter's extreme points at the
//! vertices make an inner polygon, and the grid centres inside it are
//! machined).

use crate::geometry::P2;
use crate::geometry::line::point_segment_distance;
use cavalier_contours::polyline::{PlineSource, PlineSourceMut, PlineVertex, Polyline};
use std::collections::HashMap;

/// Largest gap (mm) between a convex arc of the region and its chords.
const CHORD_TOL: f64 = 1e-4;

/// The tool-centre region as polygons (counter-clockwise, lines only).
#[derive(Debug, Clone, Default)]
pub struct Region {
    /// Closed polygons (last vertex joins the first), counter-clockwise,
    /// mm; a point is in the region by non-zero winding over all of them.
    pub loops: Vec<Vec<P2>>,
}

/// A closed polyline made counter-clockwise.
pub fn ccw(mut pl: Polyline<f64>) -> Polyline<f64> {
    pl.set_is_closed(true);
    if pl.area() < 0.0 {
        pl.invert_direction_mut();
    }
    pl
}

/// The vertices of a closed arc polyline as a polygon inside it: chords on
/// arcs turning left (convex for a counter-clockwise loop), tangent
/// polygons on arcs turning right (concave), so no edge comes closer to an
/// arc's centre than its radius.
pub fn polygonize(pl: &Polyline<f64>) -> Vec<P2> {
    let n = pl.vertex_count();
    let mut out = Vec::new();
    for i in 0..n {
        let v: PlineVertex<f64> = pl.at(i);
        let w = pl.at((i + 1) % n);
        let (a, b) = (P2::new(v.x, v.y), P2::new(w.x, w.y));
        out.push(a);
        if v.bulge.abs() < 1e-12 || (b - a).norm() < 1e-12 {
            continue;
        }
        let sweep = 4.0 * v.bulge.atan();
        let chord = (b - a).norm();
        let r = chord / (2.0 * (0.5 * sweep).sin().abs());
        // Centre: left of the chord for a left turn.
        let mid = a + (b - a) * 0.5;
        let nrm = P2::new(-(b.y - a.y), b.x - a.x).coords / chord;
        let h = (r * r - 0.25 * chord * chord).max(0.0).sqrt();
        let c = if (sweep > 0.0) == (sweep.abs() < std::f64::consts::PI) {
            mid + nrm * h
        } else {
            mid - nrm * h
        };
        let a0 = (a.y - c.y).atan2(a.x - c.x);
        let step_max = 2.0 * (1.0 - (CHORD_TOL / r).min(1.0)).acos();
        let m = ((sweep.abs() / step_max.max(1e-6)).ceil() as usize).clamp(1, 10_000);
        let phi = sweep / m as f64;
        if sweep > 0.0 {
            for k in 1..m {
                let t = a0 + phi * k as f64;
                out.push(c + nalgebra::Vector2::new(t.cos(), t.sin()) * r);
            }
        } else {
            let rr = r / (0.5 * phi).cos();
            for k in 0..m {
                let t = a0 + phi * (k as f64 + 0.5);
                out.push(c + nalgebra::Vector2::new(t.cos(), t.sin()) * rr);
            }
        }
    }
    out
}

fn seg_cross(a: P2, b: P2, c: P2, d: P2) -> bool {
    let o = |p: P2, q: P2, r: P2| (q - p).perp(&(r - p));
    let (d1, d2, d3, d4) = (o(a, b, c), o(a, b, d), o(c, d, a), o(c, d, b));
    ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
}

impl Region {
    /// The region of a counter-clockwise boundary offset inward by `r`.
    pub fn new(boundary: &Polyline<f64>, r: f64) -> Region {
        let b = ccw(boundary.clone());
        let loops = b
            .parallel_offset(r)
            .into_iter()
            .filter(|p| p.is_closed() && p.area().abs() > 1e-12)
            .map(|p| polygonize(&ccw(p)))
            .collect();
        Region { loops }
    }

    /// True when nothing is left.
    pub fn is_empty(&self) -> bool {
        self.loops.is_empty()
    }

    /// Point in the region (non-zero winding over all loops), or on its
    /// edge within 1e-9 mm (a tool centre exactly a radius from the wall
    /// is allowed).
    pub fn contains(&self, p: P2) -> bool {
        self.loops.iter().any(|l| winding(l, p) != 0) || self.edge_distance(p) <= 1e-9
    }

    /// Distance from `p` to the nearest edge of the region's polygons.
    pub fn edge_distance(&self, p: P2) -> f64 {
        let mut best = f64::INFINITY;
        for l in &self.loops {
            for i in 0..l.len() {
                best = best.min(point_segment_distance(&p, &l[i], &l[(i + 1) % l.len()]));
            }
        }
        best
    }

    /// The straight segment a-b stays in the region: both ends inside and
    /// no edge crossed.
    pub fn segment_inside(&self, a: P2, b: P2) -> bool {
        if !(self.contains(a) && self.contains(b)) {
            return false;
        }
        for l in &self.loops {
            for i in 0..l.len() {
                if seg_cross(a, b, l[i], l[(i + 1) % l.len()]) {
                    return false;
                }
            }
        }
        self.contains(a + (b - a) * 0.5)
    }
}

/// Winding number of a closed polygon about `p`.
pub fn winding(poly: &[P2], p: P2) -> i32 {
    let mut w = 0;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let side = (b - a).perp(&(p - a));
        if a.y <= p.y {
            if b.y > p.y && side > 0.0 {
                w += 1;
            }
        } else if b.y <= p.y && side < 0.0 {
            w -= 1;
        }
    }
    w
}

/// Cell index (column i along X, row j along Y).
pub type CellIx = (i64, i64);

/// The grid: pitch, origin, and the cells of the region.
#[derive(Debug, Clone)]
pub struct Grid {
    /// Cell pitch along X, mm.
    pub dx: f64,
    /// Cell pitch along Y, mm.
    pub dy: f64,
    /// Lower-left corner of cell (0, 0).
    pub origin: P2,
    /// Cells in the region, sorted by (j, i).
    pub cells: Vec<CellIx>,
    index: HashMap<CellIx, usize>,
}

impl Grid {
    /// Cells of pitch (dx, dy) from `origin` whose centres lie in `region`.
    pub fn new(region: &Region, origin: P2, dx: f64, dy: f64) -> Grid {
        let (mut lo, mut hi) = (
            P2::new(f64::INFINITY, f64::INFINITY),
            P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for p in region.loops.iter().flatten() {
            lo = P2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = P2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
        let mut cells = Vec::new();
        if !region.is_empty() {
            let (i0, i1) = (
                ((lo.x - origin.x) / dx).floor() as i64 - 1,
                ((hi.x - origin.x) / dx).ceil() as i64 + 1,
            );
            let (j0, j1) = (
                ((lo.y - origin.y) / dy).floor() as i64 - 1,
                ((hi.y - origin.y) / dy).ceil() as i64 + 1,
            );
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let g = Grid::centre_of(origin, dx, dy, (i, j));
                    if region.contains(g) {
                        cells.push((i, j));
                    }
                }
            }
        }
        let index = cells.iter().enumerate().map(|(k, c)| (*c, k)).collect();
        Grid {
            dx,
            dy,
            origin,
            cells,
            index,
        }
    }

    fn centre_of(origin: P2, dx: f64, dy: f64, c: CellIx) -> P2 {
        P2::new(origin.x + (c.0 as f64 + 0.5) * dx, origin.y + (c.1 as f64 + 0.5) * dy)
    }

    /// Centre of cell `c`.
    pub fn centre(&self, c: CellIx) -> P2 {
        Grid::centre_of(self.origin, self.dx, self.dy, c)
    }

    /// Position of `c` in `cells`, if it is a cell of the region.
    pub fn id(&self, c: CellIx) -> Option<usize> {
        self.index.get(&c).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pline(pts: &[(f64, f64)]) -> Polyline<f64> {
        let mut p = Polyline::new_closed();
        for &(x, y) in pts {
            p.add(x, y, 0.0);
        }
        p
    }

    #[test]
    fn l_shape_region_keeps_the_radius_from_the_reflex_corner() {
        // L shape, clockwise on purpose.
        let b = pline(&[(0.0, 0.0), (0.0, 4.0), (2.0, 4.0), (2.0, 2.0), (4.0, 2.0), (4.0, 0.0)]);
        let reg = Region::new(&b, 0.5);
        assert_eq!(reg.loops.len(), 1);
        for p in &reg.loops[0] {
            // Every polygon vertex is at least r from the reflex corner (2,2).
            assert!((p - P2::new(2.0, 2.0)).norm() >= 0.5 - 1e-9);
            assert!(p.x >= 0.5 - 1e-9 && p.y >= 0.5 - 1e-9);
        }
        assert!(reg.contains(P2::new(1.0, 1.0)));
        assert!(!reg.contains(P2::new(2.2, 2.2)));
        assert!(!reg.segment_inside(P2::new(1.0, 3.0), P2::new(3.0, 1.0)));
        let g = Grid::new(&reg, P2::new(0.0, 0.0), 0.5, 0.5);
        assert!(g.cells.contains(&(1, 1)));
        assert!(!g.cells.contains(&(0, 0)));
        assert!(g.id((5, 5)).is_none());
    }
}
