//! The topology report of a welded mesh, and the repairs that make a
//! mesh fit to slice and machine: degenerate triangles dropped, duplicate
//! triangles removed, orientation made consistent (and outward for closed
//! parts). Repairs are listed one sentence each, as dxf2chains lists its
//! own.
//!
//! Edges are found by sorting (vertex pair, triangle) records, not by a
//! hash map, so the order of everything reported is fixed by the input.

use serde::Serialize;

use super::Mesh;
use crate::geometry::P3;

/// What a mesh is made of and whether it closes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TopologyReport {
    /// Triangles.
    pub triangles: usize,
    /// Vertices used by a triangle.
    pub vertices: usize,
    /// Distinct edges.
    pub edges: usize,
    /// Edges with one triangle (the rims of holes).
    pub boundary_edges: usize,
    /// Edges with more than two triangles.
    pub non_manifold_edges: usize,
    /// Zero-area triangles (a repeated corner or three corners on a line).
    pub degenerate_triangles: usize,
    /// Triangles on the same three vertices as an earlier one.
    pub duplicate_triangles: usize,
    /// Edges whose two triangles run along them the same way (one of
    /// them is inside out).
    pub inconsistent_edges: usize,
    /// Connected parts (triangles sharing edges).
    pub components: usize,
    /// No boundary and no non-manifold edges, orientation consistent.
    pub watertight: bool,
    /// Enclosed volume when watertight (negative if inside out).
    pub volume_mm3: Option<f64>,
    /// Total triangle area.
    pub area_mm2: f64,
    /// Box around the used vertices: [min x, y, z, max x, y, z].
    pub bbox_mm: [f64; 6],
}

/// One edge record: the two vertices (smaller first), the triangle and
/// whether the triangle runs along it from smaller to larger.
#[derive(Clone, Copy)]
struct EdgeRec {
    a: u32,
    b: u32,
    tri: u32,
    forward: bool,
}

fn edge_records(m: &Mesh) -> Vec<EdgeRec> {
    let mut e = Vec::with_capacity(3 * m.triangles.len());
    for (i, t) in m.triangles.iter().enumerate() {
        for k in 0..3 {
            let (p, q) = (t[k], t[(k + 1) % 3]);
            if p == q {
                continue;
            }
            e.push(EdgeRec {
                a: p.min(q),
                b: p.max(q),
                tri: i as u32,
                forward: p < q,
            });
        }
    }
    e.sort_unstable_by_key(|r| (r.a, r.b, r.tri));
    e
}

/// Runs of records on the same edge.
fn edge_groups(e: &[EdgeRec]) -> impl Iterator<Item = &[EdgeRec]> {
    e.chunk_by(|x, y| x.a == y.a && x.b == y.b)
}

fn is_degenerate(m: &Mesh, t: &[u32; 3], area_tol: f64) -> bool {
    t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || m.triangle_of(t).area() <= area_tol
}

/// The area below which a triangle counts as degenerate: tiny against the
/// part's size, so only true slivers of rounding go.
fn area_tol(m: &Mesh) -> f64 {
    let b = m.bbox();
    if b.is_empty() {
        return 0.0;
    }
    let d = b.size().norm();
    1e-14 * d * d
}

/// Report on `m` (weld it first: a triangle soup has only boundary edges).
pub fn report(m: &Mesh) -> TopologyReport {
    let at = area_tol(m);
    let degenerate = m.triangles.iter().filter(|t| is_degenerate(m, t, at)).count();
    let duplicate = duplicates(m).iter().filter(|&&d| d).count();
    let e = edge_records(m);
    let (mut edges, mut boundary, mut nonman, mut incons) = (0, 0, 0, 0);
    for g in edge_groups(&e) {
        edges += 1;
        match g.len() {
            1 => boundary += 1,
            2 => incons += (g[0].forward == g[1].forward) as usize,
            _ => nonman += 1,
        }
    }
    let components = components(m, &e).1;
    // Closed needs a surface: a mesh of degenerate triangles only has no
    // edges, so none open, and was called watertight with a volume of 0.
    let watertight = boundary == 0 && nonman == 0 && incons == 0 && degenerate < m.triangles.len();
    let volume = watertight.then(|| signed_volume(m));
    let mut used = vec![false; m.vertices.len()];
    for t in &m.triangles {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let b = m.bbox();
    TopologyReport {
        triangles: m.triangles.len(),
        vertices: used.iter().filter(|&&u| u).count(),
        edges,
        boundary_edges: boundary,
        non_manifold_edges: nonman,
        degenerate_triangles: degenerate,
        duplicate_triangles: duplicate,
        inconsistent_edges: incons,
        components,
        watertight,
        volume_mm3: volume,
        // `+ 0.0`: an empty sum of floats is -0.0, printed as "-0.0".
        area_mm2: m.iter_triangles().map(|t| t.area()).sum::<f64>() + 0.0,
        bbox_mm: if b.is_empty() {
            [0.0; 6]
        } else {
            [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z]
        },
    }
}

/// `true` for each triangle on the same vertex set as an earlier one
/// (either winding).
fn duplicates(m: &Mesh) -> Vec<bool> {
    let mut keys: Vec<([u32; 3], u32)> = m
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let mut k = *t;
            k.sort_unstable();
            (k, i as u32)
        })
        .collect();
    keys.sort_unstable();
    let mut dup = vec![false; m.triangles.len()];
    for w in keys.windows(2) {
        if w[0].0 == w[1].0 {
            dup[w[1].1 as usize] = true;
        }
    }
    dup
}

/// Component label per triangle (through edges with exactly two
/// triangles, and through boundary vertices' shared edges) and the count.
fn components(m: &Mesh, e: &[EdgeRec]) -> (Vec<u32>, usize) {
    let n = m.triangles.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for g in edge_groups(e) {
        for r in &g[1..] {
            let (a, b) = (find(&mut parent, g[0].tri), find(&mut parent, r.tri));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut count = 0usize;
    let mut root_label = vec![u32::MAX; n];
    for (i, l) in label.iter_mut().enumerate() {
        let r = find(&mut parent, i as u32) as usize;
        if root_label[r] == u32::MAX {
            root_label[r] = count as u32;
            count += 1;
        }
        *l = root_label[r];
    }
    (label, count)
}

/// Signed volume of the whole mesh.
fn signed_volume(m: &Mesh) -> f64 {
    part_volumes(m, 1, |_| 0)[0]
}

/// Signed volume of each part (`part_of(i)` the part of triangle i, below
/// `parts`), in one pass: each part's terms are added in triangle order.
/// One pass a part, as it was until 8 December 2026, took 11 s for a mesh
/// of 10,000 separate cubes and 170 s for 40,000 (each pass read every
/// triangle and the box of every vertex).
fn part_volumes(m: &Mesh, parts: usize, part_of: impl Fn(usize) -> usize) -> Vec<f64> {
    // About the box centre, to keep the sum well conditioned far from the origin.
    let c = m.bbox().center().unwrap_or(P3::origin());
    let mut v = vec![0.0; parts];
    for (i, t) in m.triangles.iter().enumerate() {
        let tr = m.triangle_of(t);
        v[part_of(i)] += (tr.a - c).dot(&(tr.b - c).cross(&(tr.c - c))) / 6.0;
    }
    v
}

/// Drop degenerate and duplicate triangles, make each part's orientation
/// consistent (flipping the fewer triangles) and turn closed parts with a
/// negative volume outward. Returns the repaired mesh and one sentence per
/// kind of repair done (empty when none was needed).
pub fn repair(m: &Mesh) -> (Mesh, Vec<String>) {
    let mut notes = Vec::new();
    let at = area_tol(m);
    let dup = duplicates(m);
    let (mut n_deg, mut n_dup) = (0, 0);
    let mut tris = Vec::with_capacity(m.triangles.len());
    for (i, t) in m.triangles.iter().enumerate() {
        if is_degenerate(m, t, at) {
            n_deg += 1;
        } else if dup[i] {
            n_dup += 1;
        } else {
            tris.push(*t);
        }
    }
    if n_deg > 0 {
        notes.push(format!("dropped {n_deg} degenerate triangles"));
    }
    if n_dup > 0 {
        notes.push(format!("removed {n_dup} duplicate triangles"));
    }
    let mut out = Mesh {
        vertices: m.vertices.clone(),
        triangles: tris,
    };
    let (flipped, inverted) = orient(&mut out);
    if flipped > 0 {
        notes.push(format!(
            "flipped {flipped} triangles to make the orientation consistent"
        ));
    }
    if inverted > 0 {
        notes.push(format!(
            "turned {inverted} closed parts inside out (their volume was negative)"
        ));
    }
    (out, notes)
}

/// Breadth-first over edges shared by exactly two triangles: a neighbour
/// that runs along the shared edge the same way is flipped. Per part, the
/// smaller side flips. Returns (triangles flipped, closed parts inverted).
fn orient(m: &mut Mesh) -> (usize, usize) {
    let n = m.triangles.len();
    let e = edge_records(m);
    // Adjacency through manifold edges: (neighbour, same direction?).
    let mut adj: Vec<Vec<(u32, bool)>> = vec![Vec::new(); n];
    for g in edge_groups(&e) {
        if g.len() == 2 {
            let same = g[0].forward == g[1].forward;
            adj[g[0].tri as usize].push((g[1].tri, same));
            adj[g[1].tri as usize].push((g[0].tri, same));
        }
    }
    let mut flip = vec![None::<bool>; n];
    let mut flipped = 0;
    let mut part = vec![u32::MAX; n];
    let mut parts = 0u32;
    let mut queue = std::collections::VecDeque::new();
    for s in 0..n {
        if flip[s].is_some() {
            continue;
        }
        flip[s] = Some(false);
        part[s] = parts;
        queue.push_back(s as u32);
        let mut members = vec![s as u32];
        while let Some(t) = queue.pop_front() {
            let ft = flip[t as usize].unwrap_or(false);
            for &(u, same) in &adj[t as usize] {
                if flip[u as usize].is_none() {
                    flip[u as usize] = Some(ft ^ same);
                    part[u as usize] = parts;
                    members.push(u);
                    queue.push_back(u);
                }
            }
        }
        let k = members.iter().filter(|&&t| flip[t as usize] == Some(true)).count();
        if 2 * k > members.len() {
            for &t in &members {
                flip[t as usize] = flip[t as usize].map(|f| !f);
            }
        }
        parts += 1;
    }
    for (t, f) in m.triangles.iter_mut().zip(&flip) {
        if *f == Some(true) {
            t.swap(1, 2);
            flipped += 1;
        }
    }
    // Closed parts (every edge of the part shared by exactly two of its
    // triangles) should enclose a positive volume.
    let e = edge_records(m);
    let mut open_part = vec![false; parts as usize];
    for g in edge_groups(&e) {
        if g.len() != 2 || g[0].forward == g[1].forward {
            for r in g {
                open_part[part[r.tri as usize] as usize] = true;
            }
        }
    }
    let vols = part_volumes(m, parts as usize, |i| part[i] as usize);
    let invert: Vec<bool> = (0..parts as usize).map(|p| !open_part[p] && vols[p] < 0.0).collect();
    for (t, &l) in m.triangles.iter_mut().zip(&part) {
        if invert[l as usize] {
            t.swap(1, 2);
        }
    }
    (flipped, invert.iter().filter(|&&i| i).count())
}

/// A mesh welded, reported on and repaired: what `pathgen slice` and
/// `pathgen mesh-info` work from.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The welded, repaired mesh.
    pub mesh: Mesh,
    /// What welding did.
    pub weld: super::weld::WeldReport,
    /// Topology after welding, before repairs.
    pub before: TopologyReport,
    /// The repairs done, one sentence each.
    pub repairs: Vec<String>,
    /// Topology after the repairs.
    pub after: TopologyReport,
}

/// Weld within `weld_tol` (mm), report, repair, report again.
pub fn prepare(mesh: &Mesh, weld_tol: f64) -> Prepared {
    let (welded, weld) = super::weld::weld(mesh, weld_tol);
    let before = report(&welded);
    let (fixed, repairs) = repair(&welded);
    let after = if repairs.is_empty() {
        before.clone()
    } else {
        report(&fixed)
    };
    Prepared {
        mesh: fixed,
        weld,
        before,
        repairs,
        after,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{solids, weld::weld};

    #[test]
    fn closed_sphere_report_and_volume() {
        let m = solids::sphere(P3::new(5.0, 0.0, 0.0), 1.0, 64, 32);
        let r = report(&m);
        assert!(r.watertight);
        assert_eq!(
            (
                r.boundary_edges,
                r.non_manifold_edges,
                r.inconsistent_edges,
                r.components
            ),
            (0, 0, 0, 1)
        );
        assert_eq!(r.edges * 2, r.triangles * 3);
        let v = r.volume_mm3.unwrap();
        assert!(v > 0.99 * 4.0 / 3.0 * std::f64::consts::PI && v < 4.0 / 3.0 * std::f64::consts::PI);
    }

    #[test]
    fn repairs_are_done_and_listed() {
        let mut m = solids::cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
        m.triangles[3].swap(0, 1); // one inside out
        m.triangles.push(m.triangles[5]); // a duplicate
        m.triangles.push([0, 0, 1]); // degenerate
        let r = report(&m);
        assert!(!r.watertight);
        assert_eq!((r.degenerate_triangles, r.duplicate_triangles), (1, 1));
        assert!(r.inconsistent_edges >= 3);
        let (fixed, notes) = repair(&m);
        assert_eq!(notes.len(), 3, "{notes:?}");
        assert!(notes[2].contains("flipped 1 "), "{notes:?}");
        let r = report(&fixed);
        assert!(r.watertight, "{r:?}");
        assert!((r.volume_mm3.unwrap() - 6.0).abs() < 1e-12);
        // A whole part inside out is turned back.
        let mut inv = solids::cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
        for t in &mut inv.triangles {
            t.swap(1, 2);
        }
        let (fixed, notes) = repair(&inv);
        assert_eq!(
            notes,
            vec!["turned 1 closed parts inside out (their volume was negative)".to_string()]
        );
        assert!(report(&fixed).volume_mm3.unwrap() > 0.0);
    }

    #[test]
    fn each_inside_out_part_of_many_is_turned_and_only_those() {
        // 300 separate boxes of different sizes, every third inside out,
        // and one open box inside out (left as it is: it has no volume).
        let mut m = Mesh {
            vertices: vec![],
            triangles: vec![],
        };
        let mut volume = 0.0;
        for k in 0..300 {
            let (x, s) = (3.0 * k as f64, 1.0 + (k % 7) as f64 * 0.25);
            let mut c = solids::cuboid(P3::new(x, 0.0, 0.0), P3::new(x + s, s, 2.0 * s));
            if k % 3 == 1 {
                for t in &mut c.triangles {
                    t.swap(1, 2);
                }
            }
            volume += 2.0 * s * s * s;
            let base = m.vertices.len() as u32;
            m.vertices.extend(c.vertices);
            m.triangles.extend(c.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        let mut open = solids::cuboid(P3::new(-5.0, 0.0, 0.0), P3::new(-4.0, 1.0, 1.0));
        open.triangles.pop();
        for t in &mut open.triangles {
            t.swap(1, 2);
        }
        let base = m.vertices.len() as u32;
        m.vertices.extend(open.vertices);
        let open_tris: Vec<[u32; 3]> = open.triangles.iter().map(|t| t.map(|v| v + base)).collect();
        m.triangles.extend(open_tris.iter().copied());
        let (fixed, notes) = repair(&m);
        assert_eq!(
            notes,
            vec!["turned 100 closed parts inside out (their volume was negative)".to_string()]
        );
        // The open box's triangles are as they were; every closed box
        // encloses its volume.
        assert_eq!(
            fixed.triangles[fixed.triangles.len() - open_tris.len()..],
            open_tris[..]
        );
        let closed = Mesh {
            vertices: fixed.vertices.clone(),
            triangles: fixed.triangles[..fixed.triangles.len() - open_tris.len()].to_vec(),
        };
        let r = report(&closed);
        assert_eq!(r.components, 300);
        assert!((r.volume_mm3.unwrap() - volume).abs() < 1e-9 * volume, "{r:?}");
        let e = edge_records(&closed);
        let labels = components(&closed, &e).0;
        let vols = part_volumes(&closed, 300, |i| labels[i] as usize);
        assert!(vols.iter().all(|&v| v > 0.0), "{vols:?}");
    }

    #[test]
    fn degenerate_only_and_empty_meshes_are_not_closed() {
        // Every corner welded into one point (a huge --weld-tol): no edges
        // at all, so none open, but no surface either.
        let p = P3::new(1.0, 2.0, 3.0);
        let m = Mesh {
            vertices: vec![p],
            triangles: vec![[0, 0, 0]; 4],
        };
        let r = report(&m);
        assert_eq!(r.degenerate_triangles, 4);
        assert!(!r.watertight && r.volume_mm3.is_none(), "{r:?}");
        let empty = report(&Mesh {
            vertices: vec![],
            triangles: vec![],
        });
        assert!(!empty.watertight);
        // 0.0, not the -0.0 of an empty float sum ("-0.0" in the JSON).
        assert!(empty.area_mm2 == 0.0 && empty.area_mm2.is_sign_positive());
    }

    #[test]
    fn open_and_non_manifold_meshes() {
        let mut m = solids::cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
        m.triangles.pop();
        let r = report(&m);
        assert_eq!(r.boundary_edges, 3);
        assert!(!r.watertight && r.volume_mm3.is_none());
        // Two boxes sharing an edge line: soup welded gives 4 triangles on it.
        let a = solids::cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
        let b = solids::cuboid(P3::new(1.0, 1.0, 0.0), P3::new(2.0, 2.0, 1.0));
        let tris: Vec<_> = a.iter_triangles().chain(b.iter_triangles()).collect();
        let (w, _) = weld(&Mesh::from_triangles(&tris), 1e-9);
        let r = report(&w);
        assert!(r.non_manifold_edges >= 1, "{r:?}");
        assert_eq!(r.components, 1);
    }
}
