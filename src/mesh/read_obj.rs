//! Wavefront OBJ through `tobj`: objects and groups kept as [`Group`]s,
//! polygons triangulated, line (`l`) and point (`p`) elements ignored with
//! a note (a mesh for machining has no use for them), materials ignored.
//!
//! tobj's own triangulation is a fan from the first corner, which folds a
//! concave polygon over itself; so faces are loaded as polygons and split
//! here by ear clipping in the polygon's best-fit plane.
//!
//! tobj's errors name no line, so when it refuses a file a short scan finds
//! the first line that is wrong (a `v` without three numbers, an `f` index
//! out of range) and the error names it.

use super::Mesh;
use super::read::{Group, LoadedMesh, MeshError};
use crate::geometry::{P3, V3};

/// The file with its `vt` and `vn` lines blanked (line count kept), or the
/// file itself when it has none. A mesh for machining uses positions only,
/// and tobj 4.0.5 checks a face's texture-coordinate and normal indices
/// with unchecked arithmetic (`vt * 2 + 1`): an index near `usize::MAX`
/// overflows there (found by the `obj_read` fuzz target). Without those
/// lines tobj never reaches that code; the face words' `/vt/vn` parts are
/// then ignored.
fn without_texcoords_and_normals(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    // The keyword as tobj finds it: the first word of the line split at
    // Unicode white space (so `vt` followed by a vertical tab or a
    // no-break space counts too: the fuzzer found the first). A line that
    // is not UTF-8 makes tobj refuse the file anyway.
    let is_attr =
        |line: &[u8]| std::str::from_utf8(line).is_ok_and(|s| matches!(s.split_whitespace().next(), Some("vt" | "vn")));
    if !bytes.split(|&c| c == b'\n').any(is_attr) {
        return std::borrow::Cow::Borrowed(bytes);
    }
    let mut out = Vec::with_capacity(bytes.len());
    for (k, line) in bytes.split(|&c| c == b'\n').enumerate() {
        if k > 0 {
            out.push(b'\n');
        }
        if !is_attr(line) {
            out.extend_from_slice(line);
        }
    }
    std::borrow::Cow::Owned(out)
}

/// Read an OBJ file (materials are not loaded).
pub fn read_obj(bytes: &[u8]) -> Result<LoadedMesh, MeshError> {
    let opts = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let positions_only = without_texcoords_and_normals(bytes);
    let mut rd = std::io::BufReader::new(positions_only.as_ref());
    let (models, _materials) = match tobj::load_obj_buf(&mut rd, &opts, |_| Err(tobj::LoadError::OpenFileFailed)) {
        Ok(r) => r,
        Err(e) => return Err(locate(bytes).unwrap_or(MeshError::Refused(format!("OBJ: {e}")))),
    };
    let mut vertices: Vec<P3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut groups = Vec::new();
    let mut notes = Vec::new();
    let mut bad_polys = 0usize;
    for m in &models {
        let first = triangles.len() as u32;
        let base = vertices.len() as u32;
        let p = &m.mesh.positions;
        vertices.extend(
            p.chunks_exact(3)
                .map(|c| P3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
        );
        let idx = &m.mesh.indices;
        let arities: Vec<u32> = if m.mesh.face_arities.is_empty() {
            vec![3; idx.len() / 3]
        } else {
            m.mesh.face_arities.clone()
        };
        let mut at = 0usize;
        for &n in &arities {
            let n = n as usize;
            let poly: Vec<u32> = idx[at..at + n].iter().map(|&i| base + i).collect();
            at += n;
            if n < 3 {
                bad_polys += 1;
                continue;
            }
            if n == 3 {
                triangles.push([poly[0], poly[1], poly[2]]);
                continue;
            }
            let pts: Vec<P3> = poly.iter().map(|&i| vertices[i as usize]).collect();
            for [a, b, c] in ear_clip(&pts) {
                triangles.push([poly[a], poly[b], poly[c]]);
            }
        }
        if triangles.len() as u32 > first {
            groups.push(Group {
                name: m.name.clone(),
                triangles: first..triangles.len() as u32,
            });
        }
    }
    if vertices
        .iter()
        .any(|v| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()))
    {
        return Err(locate(bytes).unwrap_or(MeshError::Refused("OBJ: a vertex is not a finite number".into())));
    }
    let (lines, points) = count_ignored(bytes);
    if lines > 0 {
        notes.push(format!(
            "ignored {lines} line elements (`l`): a mesh has no use for them"
        ));
    }
    if points > 0 {
        notes.push(format!("ignored {points} point elements (`p`)"));
    }
    if bad_polys > 0 {
        notes.push(format!("ignored {bad_polys} faces with fewer than 3 corners"));
    }
    Ok(LoadedMesh {
        mesh: Mesh { vertices, triangles },
        format: "obj".into(),
        groups,
        notes,
    })
}

fn count_ignored(bytes: &[u8]) -> (usize, usize) {
    let (mut l, mut p) = (0, 0);
    for line in bytes.split(|&b| b == b'\n') {
        let t = line.trim_ascii_start();
        if t.starts_with(b"l ") || t.starts_with(b"l\t") {
            l += 1;
        } else if t.starts_with(b"p ") || t.starts_with(b"p\t") {
            p += 1;
        }
    }
    (l, p)
}

/// The first wrong line of an OBJ file tobj refused, if a simple scan can
/// tell (vertex numbers and face indices only).
fn locate(bytes: &[u8]) -> Option<MeshError> {
    let text = String::from_utf8_lossy(bytes);
    let mut nv: i64 = 0;
    let mut nt: i64 = 0;
    let mut nn: i64 = 0;
    for (i, raw) in text.split('\n').enumerate() {
        let line = i + 1;
        let l = raw.split('#').next().unwrap_or("").trim();
        let mut w = l.split_ascii_whitespace();
        let Some(kw) = w.next() else { continue };
        let err = |m: String| Some(MeshError::Line { line, message: m });
        match kw {
            "v" | "vn" | "vt" => {
                let nums: Vec<&str> = w.collect();
                let need = if kw == "vt" { 1 } else { 3 };
                if nums.len() < need
                    || nums
                        .iter()
                        .take(need)
                        .any(|s| s.parse::<f64>().map(|v| !v.is_finite()).unwrap_or(true))
                {
                    return err(format!("`{kw}` needs {need} finite numbers, found `{}`", short(l)));
                }
                match kw {
                    "v" => nv += 1,
                    "vt" => nt += 1,
                    _ => nn += 1,
                }
            }
            "f" => {
                let corners: Vec<&str> = w.collect();
                if corners.len() < 3 {
                    return err(format!("face with {} corners (needs 3): `{}`", corners.len(), short(l)));
                }
                for c in corners {
                    for (k, part) in c.split('/').enumerate() {
                        if part.is_empty() && k > 0 {
                            continue;
                        }
                        let count = [nv, nt, nn].get(k).copied().unwrap_or(0);
                        let ok = match part.parse::<i64>() {
                            Ok(j) if j > 0 => j <= count,
                            Ok(j) if j < 0 => -j <= count,
                            _ => false,
                        };
                        if !ok || k > 2 {
                            return err(format!("face corner `{c}` is not a valid index (have {nv} vertices)"));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    None
}

fn short(s: &str) -> String {
    s.chars().take(60).collect()
}

/// Split a simple polygon (3-D points, roughly planar) into triangles by
/// ear clipping in the plane of its Newell normal; the triangles keep the
/// polygon's winding. Falls back to a fan when no ear is found (a
/// self-intersecting polygon), so every corner is still used.
pub fn ear_clip(pts: &[P3]) -> Vec<[usize; 3]> {
    let n = pts.len();
    let mut nrm = V3::zeros();
    for i in 0..n {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        nrm += V3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    // Project on the two axes other than the normal's largest, keeping the
    // polygon counter-clockwise in 2-D.
    let k = nrm.iamax();
    let (u, v) = match k {
        0 => (1, 2),
        1 => (2, 0),
        _ => (0, 1),
    };
    let s = if nrm[k] >= 0.0 { 1.0 } else { -1.0 };
    let p2: Vec<(f64, f64)> = pts.iter().map(|p| (p[u], s * p[v])).collect();
    let cross = |a: usize, b: usize, c: usize| {
        let (ax, ay) = p2[a];
        let (bx, by) = p2[b];
        let (cx, cy) = p2[c];
        (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    };
    let mut idx: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    let mut guard = 0;
    while idx.len() > 3 && guard < n * n {
        guard += 1;
        let m = idx.len();
        let mut clipped = false;
        for i in 0..m {
            let (a, b, c) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
            if cross(a, b, c) <= 0.0 {
                continue;
            }
            let inside = idx.iter().any(|&q| {
                q != a && q != b && q != c && cross(a, b, q) >= 0.0 && cross(b, c, q) >= 0.0 && cross(c, a, q) >= 0.0
            });
            if inside {
                continue;
            }
            out.push([a, b, c]);
            idx.remove(i);
            clipped = true;
            break;
        }
        if !clipped {
            break;
        }
    }
    for k in 1..idx.len().saturating_sub(1) {
        out.push([idx[0], idx[k], idx[k + 1]]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_polygons_and_lines() {
        let obj = b"o a\nv 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 1 0\nv 0 2 0\nf 1 2 3 4 5\ng b\nf 1 2 3\nl 1 2\n";
        let r = read_obj(obj).unwrap();
        // A concave pentagon: 3 triangles, none folded (total area = polygon area).
        let tri_area: f64 = r.mesh.iter_triangles().take(3).map(|t| t.cross().z * 0.5).sum();
        assert!((tri_area - 3.0).abs() < 1e-12, "{tri_area}");
        assert!(r.mesh.iter_triangles().take(3).all(|t| t.cross().z > 0.0));
        assert_eq!(r.groups.len(), 2);
        assert_eq!(r.groups[1].name, "b");
        assert!(r.notes.iter().any(|n| n.contains("line elements")), "{:?}", r.notes);
    }

    #[test]
    fn texture_and_normal_indices_are_never_looked_at() {
        // Indices tobj would check with overflowing arithmetic, and ones
        // past the end: positions are all a machining mesh uses.
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n  vn 0 0 1\nf 1/9223372036854775807/1 2/1/-9223372036854775807 3/7/9\n";
        let r = read_obj(obj).unwrap();
        assert_eq!(r.mesh.triangles.len(), 1);
        assert_eq!(r.mesh.vertices.len(), 3);
        // `vt` and `vn` followed by any white space tobj splits at.
        for sep in ["\u{b}", "\u{c}", "\u{a0}", "\u{2003}", "\t"] {
            let obj = format!(
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt{sep}1 1\nvn{sep}0 0 1\nf 1/9223372036854775807/1 2/1/-9223372036854775807 3/7/9\n"
            );
            let m = read_obj(obj.as_bytes()).unwrap_or_else(|e| panic!("{sep:?}: {e}"));
            assert_eq!(m.mesh.triangles.len(), 1, "{sep:?}");
        }
        // Line numbers in errors still count the blanked lines.
        let e = read_obj(b"vt 0 0\nvn 0 0 1\nv 0 0 0\nv 1 0 0\nv 0 1 x\nf 1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("line 5:"), "{e}");
    }

    #[test]
    fn errors_name_the_line() {
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 x\nf 1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("line 3:"), "{e}");
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("line 4:"), "{e}");
    }

    #[test]
    fn ear_clip_keeps_area_on_a_comb() {
        // A comb-shaped polygon in the XZ plane.
        let pts: Vec<P3> = [
            (0.0, 0.0),
            (4.0, 0.0),
            (4.0, 3.0),
            (3.0, 3.0),
            (3.0, 1.0),
            (2.0, 1.0),
            (2.0, 3.0),
            (1.0, 3.0),
            (1.0, 1.0),
            (0.0, 1.0),
        ]
        .iter()
        .map(|&(x, z)| P3::new(x, 0.0, z))
        .collect();
        let t = ear_clip(&pts);
        assert_eq!(t.len(), pts.len() - 2);
        let area: f64 = t
            .iter()
            .map(|&[a, b, c]| 0.5 * (pts[b] - pts[a]).cross(&(pts[c] - pts[a])).norm())
            .sum();
        assert!((area - 8.0).abs() < 1e-12, "{area}");
    }
}
