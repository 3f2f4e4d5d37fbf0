//! The simulated stock as a watertight binary STL.
//!
//! Vertices sit at the cell centres at their heights (the top surface,
//! two triangles per square of four centres) and at the same points on the
//! stock's bottom (the bottom surface, same triangulation, facing down);
//! walls join the outline of the two. Every edge is shared by exactly two
//! triangles with opposite directions, so the mesh is closed and
//! consistently oriented (outward normals), which Boolean tools and slicers
//! require. The part covered is the box between the outermost cell centres,
//! half a cell inside the stock box on each side.

use super::stock::Stock;
use std::io::{self, Write};

type V = [f64; 3];

fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn tri(out: &mut Vec<u8>, a: V, b: V, c: V) {
    let n = cross(sub(b, a), sub(c, a));
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = if l > 0.0 {
        [n[0] / l, n[1] / l, n[2] / l]
    } else {
        [0.0; 3]
    };
    for v in [n, a, b, c] {
        for x in v {
            out.extend_from_slice(&(x as f32).to_le_bytes());
        }
    }
    out.extend_from_slice(&[0, 0]);
}

/// Number of triangles [`write_stl`] writes for a stock.
pub fn triangle_count(s: &Stock) -> u64 {
    let (nx, ny) = (s.nx as u64, s.ny as u64);
    if nx < 2 || ny < 2 {
        return 0;
    }
    4 * (nx - 1) * (ny - 1) + 4 * ((nx - 1) + (ny - 1))
}

/// Write the stock as binary STL. A stock narrower than two cells on an
/// axis has no centre grid to mesh and is an error.
pub fn write_stl<W: Write>(s: &Stock, w: &mut W) -> io::Result<()> {
    if s.nx < 2 || s.ny < 2 {
        return Err(io::Error::other("stock needs at least 2 x 2 cells for an STL"));
    }
    let n = triangle_count(s);
    let n32 = u32::try_from(n).map_err(|_| io::Error::other("too many triangles for STL; use a larger cell"))?;
    let mut header = [b' '; 80];
    let title = b"microcam gsim simulated stock (height field, mm)";
    header[..title.len()].copy_from_slice(title);
    w.write_all(&header)?;
    w.write_all(&n32.to_le_bytes())?;
    let c = s.cell;
    let top = |i: usize, j: usize| -> V {
        [
            s.x0 + (i as f64 + 0.5) * c,
            s.y0 + (j as f64 + 0.5) * c,
            s.z[j * s.nx + i].max(s.bottom),
        ]
    };
    let bot = |i: usize, j: usize| -> V { [s.x0 + (i as f64 + 0.5) * c, s.y0 + (j as f64 + 0.5) * c, s.bottom] };
    let mut buf = Vec::with_capacity(1 << 20);
    for j in 0..s.ny - 1 {
        for i in 0..s.nx - 1 {
            // Top faces up (counter-clockwise seen from above), bottom down.
            let (a, b, cc, d) = (top(i, j), top(i + 1, j), top(i + 1, j + 1), top(i, j + 1));
            tri(&mut buf, a, b, cc);
            tri(&mut buf, a, cc, d);
            let (a, b, cc, d) = (bot(i, j), bot(i + 1, j), bot(i + 1, j + 1), bot(i, j + 1));
            tri(&mut buf, a, cc, b);
            tri(&mut buf, a, d, cc);
        }
        if buf.len() >= 1 << 20 {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    // Walls: walk the outline counter-clockwise seen from above; each wall
    // quad (p, q on top, their feet below) faces outward.
    let mut outline = Vec::with_capacity(2 * (s.nx + s.ny));
    outline.extend((0..s.nx - 1).map(|i| (i, 0)));
    outline.extend((0..s.ny - 1).map(|j| (s.nx - 1, j)));
    outline.extend((1..s.nx).rev().map(|i| (i, s.ny - 1)));
    outline.extend((1..s.ny).rev().map(|j| (0, j)));
    for k in 0..outline.len() {
        let (p, q) = (outline[k], outline[(k + 1) % outline.len()]);
        let (pt, qt, pb, qb) = (top(p.0, p.1), top(q.0, q.1), bot(p.0, p.1), bot(q.0, q.1));
        tri(&mut buf, pb, qb, qt);
        tri(&mut buf, pb, qt, pt);
    }
    w.write_all(&buf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;
    use crate::geometry::P3;
    use std::collections::HashMap;

    fn parse(stl: &[u8]) -> Vec<[[f32; 3]; 3]> {
        let n = u32::from_le_bytes(stl[80..84].try_into().unwrap()) as usize;
        assert_eq!(stl.len(), 84 + 50 * n);
        (0..n)
            .map(|t| {
                let o = 84 + 50 * t + 12;
                let f = |k: usize| f32::from_le_bytes(stl[o + 4 * k..o + 4 * k + 4].try_into().unwrap());
                [[f(0), f(1), f(2)], [f(3), f(4), f(5)], [f(6), f(7), f(8)]]
            })
            .collect()
    }

    #[test]
    fn the_mesh_is_closed_oriented_and_holds_the_stock_volume() {
        let mut s = Stock::new(P3::new(0.0, 0.0, -1.0), P3::new(4.0, 3.0, 0.0), 0.1).unwrap();
        s.cut_line(
            &P3::new(1.0, 1.5, -0.4),
            &P3::new(3.0, 1.0, -0.2),
            &Cutter::Ball { radius: 0.5 },
        );
        let mut stl = Vec::new();
        write_stl(&s, &mut stl).unwrap();
        let tris = parse(&stl);
        assert_eq!(tris.len() as u64, triangle_count(&s));
        // Every directed edge once, and its reverse once.
        let key = |v: [f32; 3]| v.map(|x| x.to_bits());
        let mut edges: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
        for t in &tris {
            for k in 0..3 {
                *edges.entry((key(t[k]), key(t[(k + 1) % 3]))).or_default() += 1;
            }
        }
        for ((a, b), n) in &edges {
            assert_eq!(*n, 1, "edge used twice the same way");
            assert_eq!(edges.get(&(*b, *a)), Some(&1), "open edge");
        }
        // Divergence theorem: positive (outward normals) and equal to the
        // height field integrated over the same triangles.
        let vol: f64 = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v.map(f64::from));
                (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum();
        let h = |i: usize, j: usize| s.z[j * s.nx + i] - s.bottom;
        let mut want = 0.0;
        for j in 0..s.ny - 1 {
            for i in 0..s.nx - 1 {
                let area = 0.5 * s.cell * s.cell;
                want += area * (h(i, j) + h(i + 1, j) + h(i + 1, j + 1)) / 3.0;
                want += area * (h(i, j) + h(i + 1, j + 1) + h(i, j + 1)) / 3.0;
            }
        }
        assert!((vol - want).abs() < 1e-5 * want, "{vol} vs {want}");
        assert!(want < 3.9 * 2.9 * 1.0, "the cut is in the mesh");
    }
}
