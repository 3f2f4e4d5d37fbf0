//! A uniform grid over the triangles' XY boxes: which triangles can a
//! cutter's disc at (x, y) reach.
//!
//! Each cell lists the triangles whose XY box overlaps it, highest top
//! first, so a drop can stop scanning a cell as soon as the tops fall
//! below the best contact found so far (no triangle can lift the tip above
//! its own top). A triangle spanning several cells is visited once per
//! query: only in the cell holding the low corner of its box clipped to the
//! query square. A uniform grid beat a kd-tree over the same boxes for
//! drop-cutter's queries (small squares, meshes of even triangle size);
//! docs/dropcutter.md has the figures.

use super::cutter_vs_triangle::Tri;

/// Triangles binned by their XY boxes (compressed rows: `start[c]..start[c+1]`
/// of `items` are cell c's triangles).
#[derive(Debug, Clone)]
pub struct Grid {
    x0: f64,
    y0: f64,
    /// Cell side (mm).
    h: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

/// Most cells a grid may have, so a tiny cell size on a large mesh cannot
/// exhaust memory.
const MAX_CELLS: f64 = 16.0e6;

impl Grid {
    /// Bin `tris` in square cells of side about `cell` (mm); the side grows
    /// when the grid would be too large.
    pub fn build(tris: &[Tri], cell: f64) -> Grid {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for t in tris {
            x0 = x0.min(t.bb[0]);
            y0 = y0.min(t.bb[1]);
            x1 = x1.max(t.bb[2]);
            y1 = y1.max(t.bb[3]);
        }
        if tris.is_empty() {
            (x0, y0, x1, y1) = (0.0, 0.0, 0.0, 0.0);
        }
        let (w, hgt) = ((x1 - x0).max(0.0), (y1 - y0).max(0.0));
        let mut h = if cell.is_finite() && cell > 0.0 { cell } else { 1.0 };
        h = h.max((w * hgt / MAX_CELLS).sqrt()).max(w.max(hgt) / MAX_CELLS.sqrt());
        if h <= 0.0 {
            h = 1.0;
        }
        let nx = ((w / h).floor() as usize + 1).max(1);
        let ny = ((hgt / h).floor() as usize + 1).max(1);
        let mut g = Grid {
            x0,
            y0,
            h,
            nx,
            ny,
            start: vec![0; nx * ny + 1],
            items: Vec::new(),
        };
        // Two passes (count, then fill) keep the lists in one allocation.
        for t in tris {
            let (i0, j0, i1, j1) = g.span(t.bb[0], t.bb[1], t.bb[2], t.bb[3]);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    g.start[j * nx + i + 1] += 1;
                }
            }
        }
        for c in 0..nx * ny {
            g.start[c + 1] += g.start[c];
        }
        let mut fill: Vec<u32> = g.start[..nx * ny].to_vec();
        g.items = vec![0; g.start[nx * ny] as usize];
        for (k, t) in tris.iter().enumerate() {
            let (i0, j0, i1, j1) = g.span(t.bb[0], t.bb[1], t.bb[2], t.bb[3]);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let c = j * nx + i;
                    g.items[fill[c] as usize] = k as u32;
                    fill[c] += 1;
                }
            }
        }
        for c in 0..nx * ny {
            let (a, b) = (g.start[c] as usize, g.start[c + 1] as usize);
            g.items[a..b].sort_by(|&p, &q| tris[q as usize].zmax.total_cmp(&tris[p as usize].zmax).then(p.cmp(&q)));
        }
        g
    }

    /// Cell column of x (clamped to the grid).
    #[inline]
    fn col(&self, x: f64) -> usize {
        let i = ((x - self.x0) / self.h).floor();
        if i <= 0.0 { 0 } else { (i as usize).min(self.nx - 1) }
    }

    #[inline]
    fn row(&self, y: f64) -> usize {
        let j = ((y - self.y0) / self.h).floor();
        if j <= 0.0 { 0 } else { (j as usize).min(self.ny - 1) }
    }

    /// Cells covered by a box: (i0, j0, i1, j1), inclusive.
    #[inline]
    fn span(&self, xa: f64, ya: f64, xb: f64, yb: f64) -> (usize, usize, usize, usize) {
        (self.col(xa), self.row(ya), self.col(xb), self.row(yb))
    }

    /// Visit each triangle whose box may meet the square of half-side `r`
    /// around (x, y) once, in each cell from the highest top down; `f`
    /// returns false to skip the rest of a cell.
    #[inline]
    pub fn query<'a>(&self, tris: &'a [Tri], x: f64, y: f64, r: f64, f: impl FnMut(&'a Tri) -> bool) {
        self.query_box(tris, [x - r, y - r, x + r, y + r], f);
    }

    /// [`Grid::query`] handing `f` each triangle's index in `tris` too.
    #[inline]
    pub fn query_indexed<'a>(&self, tris: &'a [Tri], x: f64, y: f64, r: f64, f: impl FnMut(usize, &'a Tri) -> bool) {
        self.query_box_indexed(tris, [x - r, y - r, x + r, y + r], f);
    }

    /// Visit each triangle whose box may meet the box `[x0, y0, x1, y1]`
    /// once, in each cell from the highest top down; `f` returns false to
    /// skip the rest of a cell.
    #[inline]
    pub fn query_box<'a>(&self, tris: &'a [Tri], q: [f64; 4], mut f: impl FnMut(&'a Tri) -> bool) {
        self.query_box_indexed(tris, q, |_, t| f(t));
    }

    /// [`Grid::query_box`] handing `f` each triangle's index in `tris` too.
    #[inline]
    pub fn query_box_indexed<'a>(&self, tris: &'a [Tri], q: [f64; 4], mut f: impl FnMut(usize, &'a Tri) -> bool) {
        let [qx0, qy0, qx1, qy1] = q;
        if qx1 < self.x0
            || qy1 < self.y0
            || qx0 > self.x0 + self.h * self.nx as f64
            || qy0 > self.y0 + self.h * self.ny as f64
        {
            return;
        }
        let (i0, j0, i1, j1) = self.span(qx0, qy0, qx1, qy1);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let c = j * self.nx + i;
                for &k in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                    let t = &tris[k as usize];
                    if t.bb[0] > qx1 || t.bb[2] < qx0 || t.bb[1] > qy1 || t.bb[3] < qy0 {
                        continue;
                    }
                    // Owner cell of this pair: the low corner of box ∩ square.
                    if (i0 < i && self.col(t.bb[0].max(qx0)) != i) || (j0 < j && self.row(t.bb[1].max(qy0)) != j) {
                        continue;
                    }
                    if !f(k as usize, t) {
                        break;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P3;
    use crate::mesh::Triangle;

    #[test]
    fn every_overlapping_triangle_is_visited_exactly_once() {
        // Triangles of many sizes; the visits must be exactly the brute
        // force list of boxes meeting the square.
        let mut tris = Vec::new();
        let mut s = 0x1234_5678_9abc_def0u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..300 {
            let (cx, cy, sz) = (rnd() * 10.0, rnd() * 10.0, rnd() * rnd() * 4.0);
            tris.push(Tri::new(&Triangle::new(
                P3::new(cx, cy, rnd()),
                P3::new(cx + sz, cy + rnd() * sz, rnd()),
                P3::new(cx - rnd() * sz, cy + sz, rnd()),
            )));
        }
        for cell in [0.3, 1.0, 3.7] {
            let g = Grid::build(&tris, cell);
            for _ in 0..200 {
                let (x, y, r) = (rnd() * 12.0 - 1.0, rnd() * 12.0 - 1.0, rnd() * 2.0);
                let mut seen = Vec::new();
                g.query(&tris, x, y, r, |t| {
                    seen.push(tris.iter().position(|u| std::ptr::eq(u, t)).unwrap());
                    true
                });
                let mut want: Vec<usize> = (0..tris.len())
                    .filter(|&k| {
                        let b = tris[k].bb;
                        !(b[0] > x + r || b[2] < x - r || b[1] > y + r || b[3] < y - r)
                    })
                    .collect();
                seen.sort();
                want.sort();
                assert_eq!(seen, want, "cell {cell} at {x},{y} r {r}");
                // A fibre's strip: long along one axis, narrow across.
                let len = rnd() * 14.0;
                let q = if r < 1.0 {
                    [x - 2.0, y - r, x - 2.0 + len, y + r]
                } else {
                    [x - r, y - 2.0, x + r, y - 2.0 + len]
                };
                let mut seen = Vec::new();
                g.query_box(&tris, q, |t| {
                    seen.push(tris.iter().position(|u| std::ptr::eq(u, t)).unwrap());
                    true
                });
                let mut want: Vec<usize> = (0..tris.len())
                    .filter(|&k| {
                        let b = tris[k].bb;
                        !(b[0] > q[2] || b[2] < q[0] || b[1] > q[3] || b[3] < q[1])
                    })
                    .collect();
                seen.sort();
                want.sort();
                assert_eq!(seen, want, "cell {cell}: box {q:?}");
            }
        }
    }
}
