//! The simulated stock as a watertight triangle mesh (binary STL).
//!
//! Top: two triangles per grid square through the cell-centre heights,
//! extended to the stock's edges with the edge cells' heights. Sides: a
//! strip from each boundary edge of the top down to the bottom. Bottom: a
//! fan around the bottom's centre through every boundary vertex. Every edge
//! is shared by exactly two triangles with identical f32 vertices, so the
//! mesh is closed and any STL reader welds it.

use super::heightfield::HeightField;
use stl_io::{Normal, Triangle, Vertex};

fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = if len > 0.0 {
        [n[0] / len, n[1] / len, n[2] / len]
    } else {
        [0.0, 0.0, 0.0]
    };
    Triangle {
        normal: Normal::new(n),
        vertices: [Vertex::new(a), Vertex::new(b), Vertex::new(c)],
    }
}

/// All triangles of the stock's surface, outward-facing.
pub fn triangles(s: &HeightField) -> Vec<Triangle> {
    // Vertex grid: the box edges plus every cell centre, so the mesh covers
    // the whole stock box; edge vertices take the edge cells' heights.
    let (cx, cy) = s.dims();
    let (nx, ny) = (cx + 2, cy + 2);
    let (bottom, _) = s.z_range();
    let ((x0, y0), (x1, y1)) = s.extent();
    let coord = |k: usize, n: usize, lo: f64, hi: f64, centre: &dyn Fn(usize) -> f64| -> f64 {
        if k == 0 {
            lo
        } else if k == n - 1 {
            hi
        } else {
            centre(k - 1)
        }
    };
    let vx = |i: usize| coord(i, nx, x0, x1, &|c| s.node(c, 0).0);
    let vy = |j: usize| coord(j, ny, y0, y1, &|c| s.node(0, c).1);
    let hz = |i: usize, j: usize| s.height(i.clamp(1, cx) - 1, j.clamp(1, cy) - 1);
    let p = |i: usize, j: usize| -> [f32; 3] { [vx(i) as f32, vy(j) as f32, hz(i, j) as f32] };
    let low = |i: usize, j: usize| -> [f32; 3] { [vx(i) as f32, vy(j) as f32, bottom as f32] };
    let mut t = Vec::with_capacity(2 * (nx - 1) * (ny - 1) + 6 * (nx + ny));
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            t.push(tri(p(i, j), p(i + 1, j), p(i + 1, j + 1)));
            t.push(tri(p(i, j), p(i + 1, j + 1), p(i, j + 1)));
        }
    }
    // The boundary, counter-clockwise seen from above.
    let mut ring = Vec::with_capacity(2 * (nx + ny));
    ring.extend((0..nx - 1).map(|i| (i, 0)));
    ring.extend((0..ny - 1).map(|j| (nx - 1, j)));
    ring.extend((1..nx).rev().map(|i| (i, ny - 1)));
    ring.extend((1..ny).rev().map(|j| (0, j)));
    let centre = [((x0 + x1) / 2.0) as f32, ((y0 + y1) / 2.0) as f32, bottom as f32];
    for k in 0..ring.len() {
        let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
        t.push(tri(low(a.0, a.1), low(b.0, b.1), p(b.0, b.1)));
        t.push(tri(low(a.0, a.1), p(b.0, b.1), p(a.0, a.1)));
        t.push(tri(centre, low(b.0, b.1), low(a.0, a.1)));
    }
    t
}

/// Write the stock as binary STL.
pub fn write_stl<W: std::io::Write>(s: &HeightField, out: &mut W) -> std::io::Result<()> {
    let t = triangles(s);
    stl_io::write_stl(out, t.iter())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P3;
    use crate::stock::Cutter;
    use std::collections::HashMap;

    #[test]
    fn the_mesh_is_closed_and_encloses_the_stock_volume() {
        let mut s = HeightField::new(P3::new(0.0, 0.0, -2.0), P3::new(4.0, 3.0, 0.0), 0.1).unwrap();
        s.cut(
            P3::new(1.0, 1.5, -0.5),
            P3::new(3.0, 1.5, -0.5),
            &Cutter::ball(0.5).unwrap(),
        )
        .unwrap();
        let t = triangles(&s);
        // Every directed edge appears once and its reverse once.
        let key = |v: &Vertex| (v.0[0].to_bits(), v.0[1].to_bits(), v.0[2].to_bits());
        let mut edges: HashMap<_, i32> = HashMap::new();
        for tr in &t {
            for k in 0..3 {
                let (a, b) = (key(&tr.vertices[k]), key(&tr.vertices[(k + 1) % 3]));
                *edges.entry((a, b)).or_default() += 1;
            }
        }
        for ((a, b), n) in &edges {
            assert_eq!(*n, 1, "edge used {n} times");
            assert_eq!(edges.get(&(*b, *a)), Some(&1), "edge without its twin");
        }
        // Divergence theorem: the enclosed volume equals the stock volume.
        let vol: f64 = t
            .iter()
            .map(|tr| {
                let [a, b, c] = tr.vertices.map(|v| v.0.map(|x| x as f64));
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum();
        // The mesh interpolates between cell centres, the height field
        // averages over cells: the two agree to within a cell's share.
        assert!((vol - s.volume()).abs() < 2e-3 * s.volume(), "{vol} vs {}", s.volume());
        let mut buf = Vec::new();
        write_stl(&s, &mut buf).unwrap();
        assert_eq!(buf.len(), 84 + 50 * t.len());
    }
}
