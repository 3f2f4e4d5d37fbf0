//! The simulated stock as a watertight binary STL whose size follows the
//! surface, not the resolution.
//!
//! The heights sit at cell centres (gsim's height field, or the tops of
//! stlverify's Z dexels). Squares of four neighbouring centres are merged
//! greedily into rectangles whose heights all lie within `tol` of one
//! plane (flat floors and the untouched top become a few large pieces;
//! rough regions stay one square each). A vertex is kept where it is the
//! corner of some rectangle; every rectangle is triangulated through all
//! kept vertices on its border (two triangles when only its corners are
//! kept, else a fan from its centre), so neighbours share every edge and
//! there are no T-junctions. The walls and the bottom use the kept
//! vertices of the outline. Every edge is shared by exactly two triangles
//! with opposite directions, so the mesh is closed and consistently
//! oriented (outward normals), which Boolean tools and slicers require.
//! No surface point strays more than `2·tol` from the heights (each
//! rectangle lies within `tol` of its plane, and so do its vertices); the
//! default `tol` is a quarter of the cell, so half a cell at most.
//! The part covered is the box between the outermost cell centres, half a
//! cell inside the stock box on each side.

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

/// A height field to mesh: heights at `(x0 + (i + ½)·dx, y0 + (j + ½)·dy)`,
/// row-major, above a flat bottom.
#[derive(Debug, Clone, Copy)]
pub struct Heights<'a> {
    /// X of the grid's low edge, mm.
    pub x0: f64,
    /// Y of the grid's low edge, mm.
    pub y0: f64,
    /// Spacing of the heights along X, mm.
    pub dx: f64,
    /// Spacing of the heights along Y, mm.
    pub dy: f64,
    /// Heights per row.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// The heights, mm, row-major (`ny` rows of `nx`); a height below
    /// `bottom` is meshed at `bottom`.
    pub z: &'a [f64],
    /// Z of the flat bottom, mm.
    pub bottom: f64,
}

impl<'a> From<&'a Stock> for Heights<'a> {
    fn from(s: &'a Stock) -> Self {
        Heights {
            x0: s.x0,
            y0: s.y0,
            dx: s.cell,
            dy: s.cell,
            nx: s.nx,
            ny: s.ny,
            z: &s.z,
            bottom: s.bottom,
        }
    }
}

/// What [`write_heights_stl`] wrote.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StlStats {
    /// Triangles written (top, walls and bottom).
    pub triangles: u64,
    /// Triangles one-per-half-square meshing would have written.
    pub per_cell_triangles: u64,
    /// Rectangles the top was merged into.
    pub pieces: u64,
    /// Guaranteed bound on the vertical distance from any height to the
    /// mesh, mm.
    pub max_deviation_bound_mm: f64,
}

/// A merged rectangle of squares and its plane (in index units).
struct Rect {
    i: usize,
    j: usize,
    w: usize,
    h: usize,
    z0: f64,
    gx: f64,
    gy: f64,
}

/// Greedy merge of squares into near-planar rectangles.
fn rects(hf: &Heights, tol: f64) -> Vec<Rect> {
    let (nx, ny) = (hf.nx, hf.ny);
    let z = |i: usize, j: usize| hf.z[j * nx + i].max(hf.bottom);
    let (sx, sy) = (nx - 1, ny - 1);
    let mut used = vec![false; sx * sy];
    let mut out = Vec::new();
    for j in 0..sy {
        for i in 0..sx {
            if used[j * sx + i] {
                continue;
            }
            let z0 = z(i, j);
            let gx = 0.5 * (z(i + 1, j) - z0 + z(i + 1, j + 1) - z(i, j + 1));
            let gy = 0.5 * (z(i, j + 1) - z0 + z(i + 1, j + 1) - z(i + 1, j));
            let ok = |a: usize, b: usize| (z(a, b) - (z0 + gx * (a - i) as f64 + gy * (b - j) as f64)).abs() <= tol;
            let (mut w, mut h) = (1, 1);
            if [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
                .iter()
                .all(|&(a, b)| ok(a, b))
            {
                while i + w < sx && !used[j * sx + i + w] && ok(i + w + 1, j) && ok(i + w + 1, j + 1) {
                    w += 1;
                }
                'rows: while j + h < sy {
                    for a in i..i + w {
                        if used[(j + h) * sx + a] {
                            break 'rows;
                        }
                    }
                    for a in i..=i + w {
                        if !ok(a, j + h + 1) {
                            break 'rows;
                        }
                    }
                    h += 1;
                }
            }
            for b in j..j + h {
                for a in i..i + w {
                    used[b * sx + a] = true;
                }
            }
            out.push(Rect { i, j, w, h, z0, gx, gy });
        }
    }
    out
}

/// Write `hf` as binary STL, merging squares within `tol` of a plane. A
/// grid narrower than two cells on an axis is an error.
pub fn write_heights_stl<W: Write>(hf: &Heights, tol: f64, title: &str, w: &mut W) -> io::Result<StlStats> {
    let (nx, ny) = (hf.nx, hf.ny);
    if nx < 2 || ny < 2 {
        return Err(io::Error::other("stock needs at least 2 x 2 cells for an STL"));
    }
    let rs = rects(hf, tol.max(0.0));
    let mut kept = vec![false; nx * ny];
    for r in &rs {
        for (a, b) in [(r.i, r.j), (r.i + r.w, r.j), (r.i, r.j + r.h), (r.i + r.w, r.j + r.h)] {
            kept[b * nx + a] = true;
        }
    }
    let px = |i: usize| hf.x0 + (i as f64 + 0.5) * hf.dx;
    let py = |j: usize| hf.y0 + (j as f64 + 0.5) * hf.dy;
    let top = |i: usize, j: usize| -> V { [px(i), py(j), hf.z[j * nx + i].max(hf.bottom)] };
    let bot = |i: usize, j: usize| -> V { [px(i), py(j), hf.bottom] };
    let mut buf = Vec::with_capacity(1 << 20);
    let mut count: u64 = 0;
    let mut emit = |buf: &mut Vec<u8>, a: V, b: V, c: V| {
        tri(buf, a, b, c);
        count += 1;
    };
    let mut ring: Vec<(usize, usize)> = Vec::new();
    for r in &rs {
        ring.clear();
        let (i0, j0, i1, j1) = (r.i, r.j, r.i + r.w, r.j + r.h);
        ring.extend((i0..i1).map(|a| (a, j0)));
        ring.extend((j0..j1).map(|b| (i1, b)));
        ring.extend((i0 + 1..=i1).rev().map(|a| (a, j1)));
        ring.extend((j0 + 1..=j1).rev().map(|b| (i0, b)));
        ring.retain(|&(a, b)| kept[b * nx + a]);
        if ring.len() == 4 {
            let [a, b, c, d] = [ring[0], ring[1], ring[2], ring[3]].map(|(a, b)| top(a, b));
            emit(&mut buf, a, b, c);
            emit(&mut buf, a, c, d);
        } else {
            let centre = [
                0.5 * (px(i0) + px(i1)),
                0.5 * (py(j0) + py(j1)),
                r.z0 + r.gx * 0.5 * r.w as f64 + r.gy * 0.5 * r.h as f64,
            ];
            for k in 0..ring.len() {
                let (p, q) = (ring[k], ring[(k + 1) % ring.len()]);
                emit(&mut buf, centre, top(p.0, p.1), top(q.0, q.1));
            }
        }
    }
    // Walls: the kept outline vertices counter-clockwise seen from above;
    // each wall quad (p, q on top, their feet below) faces outward.
    let mut outline = Vec::with_capacity(2 * (nx + ny));
    outline.extend((0..nx - 1).map(|i| (i, 0)));
    outline.extend((0..ny - 1).map(|j| (nx - 1, j)));
    outline.extend((1..nx).rev().map(|i| (i, ny - 1)));
    outline.extend((1..ny).rev().map(|j| (0, j)));
    outline.retain(|&(a, b)| kept[b * nx + a]);
    for k in 0..outline.len() {
        let (p, q) = (outline[k], outline[(k + 1) % outline.len()]);
        let (pt, qt, pb, qb) = (top(p.0, p.1), top(q.0, q.1), bot(p.0, p.1), bot(q.0, q.1));
        emit(&mut buf, pb, qb, qt);
        emit(&mut buf, pb, qt, pt);
    }
    // Bottom: a fan from its centre, facing down.
    let c = [0.5 * (px(0) + px(nx - 1)), 0.5 * (py(0) + py(ny - 1)), hf.bottom];
    for k in 0..outline.len() {
        let (p, q) = (outline[k], outline[(k + 1) % outline.len()]);
        emit(&mut buf, c, bot(q.0, q.1), bot(p.0, p.1));
    }
    let n32 = u32::try_from(count).map_err(|_| io::Error::other("too many triangles for STL; use a larger cell"))?;
    let mut header = [b' '; 80];
    let t = title.as_bytes();
    let l = t.len().min(80);
    header[..l].copy_from_slice(&t[..l]);
    w.write_all(&header)?;
    w.write_all(&n32.to_le_bytes())?;
    w.write_all(&buf)?;
    let (ux, uy) = ((nx - 1) as u64, (ny - 1) as u64);
    Ok(StlStats {
        triangles: count,
        per_cell_triangles: 4 * ux * uy + 4 * (ux + uy),
        pieces: rs.len() as u64,
        max_deviation_bound_mm: 2.0 * tol.max(0.0),
    })
}

/// Write gsim's stock as binary STL, merged within a quarter cell.
pub fn write_stl<W: Write>(s: &Stock, w: &mut W) -> io::Result<StlStats> {
    write_heights_stl(
        &Heights::from(s),
        0.25 * s.cell,
        "microcam gsim simulated stock (height field, mm)",
        w,
    )
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
        let st = write_stl(&s, &mut stl).unwrap();
        let tris = parse(&stl);
        assert_eq!(tris.len() as u64, st.triangles);
        assert!(st.triangles * 3 < st.per_cell_triangles, "{st:?}");
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
        let area = (s.nx - 1) as f64 * (s.ny - 1) as f64 * s.cell * s.cell;
        assert!(
            (vol - want).abs() <= st.max_deviation_bound_mm * area,
            "{vol} vs {want}"
        );
        // Every height within the bound of the mesh, seen from above.
        let mesh = crate::mesh::Mesh::from_triangles(
            &tris
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| P3::new(v[0] as f64, v[1] as f64, v[2] as f64));
                    crate::mesh::Triangle::new(a, b, c)
                })
                .collect::<Vec<_>>(),
        );
        let bvh = crate::mesh::bvh::Bvh::new(&mesh);
        let mut worst: f64 = 0.0;
        for j in 0..s.ny {
            for i in 0..s.nx {
                let (x, y) = (s.x0 + (i as f64 + 0.5) * s.cell, s.y0 + (j as f64 + 0.5) * s.cell);
                let ray = crate::mesh::bvh::Ray::new(
                    P3::new(
                        x + if i + 1 == s.nx { -1e-7 } else { 1e-7 },
                        y + if j + 1 == s.ny { -1.3e-7 } else { 1.3e-7 },
                        5.0,
                    ),
                    -crate::geometry::V3::z(),
                );
                let hit = bvh.first_hit(&ray).expect("a top over every centre");
                worst = worst.max((5.0 - hit.t - s.z[j * s.nx + i]).abs());
            }
        }
        assert!(worst <= st.max_deviation_bound_mm + 1e-5, "{worst}");
        assert!(want < 3.9 * 2.9 * 1.0, "the cut is in the mesh");
    }
}
