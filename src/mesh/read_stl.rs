//! STL, ASCII and binary, read by a small parser of our own.
//!
//! Why not `stl_io` (a dependency, and used elsewhere): it decides ASCII
//! versus binary by whether the file starts with `solid`, so a binary file
//! whose 80-byte header starts with `solid` (common: SolidWorks and PRO2STL
//! write one) is parsed as text and fails; it stops after the first
//! `endsolid`, so a file with several solids loses all but the first; it
//! rejects trailing bytes after a binary file's triangles and a triangle
//! count of 0 written by streaming exporters; and its errors carry no line
//! or byte offset. Here the binary layout (84 + 50 n bytes) is checked
//! first, whatever the header says; the text reader takes any whitespace
//! (tabs, CRLF), keywords in any case and any number of solids.
//!
//! Binary records are decoded in parallel chunks (rayon): a million
//! triangles in tens of milliseconds (see docs/mesh.md).

use super::Mesh;
use super::read::{Group, LoadedMesh, MeshError};
use crate::geometry::P3;

/// Does the byte count fit a binary STL with the triangle count in its
/// header (84 + 50 n bytes)?
pub fn binary_size_matches(bytes: &[u8]) -> bool {
    if bytes.len() < 84 {
        return false;
    }
    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
    84 + 50 * n == bytes.len() as u64
}

/// Read an STL file, ASCII or binary.
pub fn read_stl(bytes: &[u8]) -> Result<LoadedMesh, MeshError> {
    if binary_size_matches(bytes) {
        return read_binary(bytes);
    }
    if starts_with_solid(bytes) && !has_nul(bytes) {
        let ascii = read_ascii(bytes);
        // A binary file with a text-like header and a trailing byte or two
        // fails as text; take it as binary when its count fits.
        if ascii.is_err() && bytes.len() >= 84 {
            let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
            if n > 0 && 84 + 50 * n <= bytes.len() as u64 {
                return read_binary(bytes);
            }
        }
        return ascii;
    }
    if bytes.len() >= 84 {
        return read_binary(bytes);
    }
    Err(MeshError::Refused(format!(
        "not an STL file: {} bytes, too short for a binary STL (84-byte header) and no `solid` line",
        bytes.len()
    )))
}

fn starts_with_solid(bytes: &[u8]) -> bool {
    let t = bytes.trim_ascii_start();
    t.len() >= 5 && t[..5].eq_ignore_ascii_case(b"solid")
}

/// NUL bytes never occur in a text STL but fill most binary headers; they
/// tell a binary file whose header starts with `solid` and whose size is
/// off (trailing bytes) from a text file.
fn has_nul(bytes: &[u8]) -> bool {
    bytes[..bytes.len().min(84)].contains(&0)
}

fn read_binary(bytes: &[u8]) -> Result<LoadedMesh, MeshError> {
    let mut notes = Vec::new();
    let n_header = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
    let body = (bytes.len() - 84) as u64;
    let n = if n_header == 0 && body >= 50 {
        // Streaming exporters write the count as 0 and never go back.
        notes.push(format!(
            "triangle count 0 in the header; read {} triangles from the file size",
            body / 50
        ));
        body / 50
    } else {
        n_header
    };
    if 50 * n > body {
        return Err(MeshError::Byte {
            offset: 84 + 50 * (body / 50),
            message: format!(
                "binary STL truncated: the header says {n} triangles ({} bytes), the file has {} bytes",
                84 + 50 * n,
                bytes.len()
            ),
        });
    }
    if 50 * n < body {
        notes.push(format!(
            "ignored {} trailing bytes after the last triangle",
            body - 50 * n
        ));
    }
    let n = n as usize;
    let (vertices, triangles) = parse_records(&bytes[84..84 + 50 * n])?;
    let header = &bytes[..80];
    let name_end = header.iter().position(|&b| b == 0).unwrap_or(80);
    let name = String::from_utf8_lossy(&header[..name_end]).trim().to_string();
    Ok(LoadedMesh {
        mesh: Mesh { vertices, triangles },
        format: "stl-binary".into(),
        groups: vec![Group {
            name,
            triangles: 0..n as u32,
        }],
        notes,
    })
}

/// Triangles per parallel chunk of the binary reader.
const CHUNK: usize = 16384;

/// The corners of `n` 50-byte binary records, in parallel chunks (rayon);
/// the first non-finite coordinate in file order is the error.
fn parse_records(body: &[u8]) -> Result<(Vec<P3>, Vec<[u32; 3]>), MeshError> {
    use rayon::prelude::*;
    let n = body.len() / 50;
    let mut vertices = vec![P3::origin(); 3 * n];
    let bad = vertices
        .par_chunks_mut(3 * CHUNK)
        .zip(body.par_chunks(50 * CHUNK))
        .enumerate()
        .filter_map(|(c, (vs, recs))| {
            for (j, rec) in recs.chunks_exact(50).enumerate() {
                for k in 0..3 {
                    let o = 12 + 12 * k;
                    let f = |j: usize| f32::from_le_bytes([rec[o + j], rec[o + j + 1], rec[o + j + 2], rec[o + j + 3]]);
                    let (x, y, z) = (f(0), f(4), f(8));
                    if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                        return Some((c * CHUNK + j, k, o));
                    }
                    vs[3 * j + k] = P3::new(x as f64, y as f64, z as f64);
                }
            }
            None
        })
        .min();
    if let Some((i, k, o)) = bad {
        return Err(MeshError::Byte {
            offset: (84 + 50 * i + o) as u64,
            message: format!("triangle {} vertex {} is not a finite number", i + 1, k + 1),
        });
    }
    let triangles = (0..n as u32)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Ok((vertices, triangles))
}

/// Whitespace-separated words with their line numbers.
struct Words<'a> {
    s: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Words<'a> {
    fn next(&mut self) -> Option<(&'a [u8], usize)> {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            if self.s[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        if self.pos >= self.s.len() {
            return None;
        }
        let start = self.pos;
        while self.pos < self.s.len() && !self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        Some((&self.s[start..self.pos], self.line))
    }

    /// The rest of the current line (a solid's name), trimmed.
    fn rest_of_line(&mut self) -> String {
        let start = self.pos;
        while self.pos < self.s.len() && self.s[self.pos] != b'\n' {
            self.pos += 1;
        }
        String::from_utf8_lossy(&self.s[start..self.pos]).trim().to_string()
    }

    fn expect(&mut self, kw: &str, what: &str) -> Result<usize, MeshError> {
        match self.next() {
            Some((w, line)) if w.eq_ignore_ascii_case(kw.as_bytes()) => Ok(line),
            Some((w, line)) => Err(MeshError::Line {
                line,
                message: format!("expected `{kw}` {what}, found `{}`", shown(w)),
            }),
            None => Err(MeshError::Line {
                line: self.line,
                message: format!("file ends where `{kw}` {what} was expected"),
            }),
        }
    }

    fn number(&mut self, what: &str) -> Result<f64, MeshError> {
        match self.next() {
            Some((w, line)) => {
                let v = std::str::from_utf8(w).ok().and_then(|t| t.parse::<f64>().ok());
                match v {
                    Some(v) if v.is_finite() => Ok(v),
                    _ => Err(MeshError::Line {
                        line,
                        message: format!("{what}: `{}` is not a finite number", shown(w)),
                    }),
                }
            }
            None => Err(MeshError::Line {
                line: self.line,
                message: format!("file ends inside {what}"),
            }),
        }
    }
}

fn shown(w: &[u8]) -> String {
    let s = String::from_utf8_lossy(&w[..w.len().min(40)]).to_string();
    if w.len() > 40 { format!("{s}...") } else { s }
}

fn read_ascii(bytes: &[u8]) -> Result<LoadedMesh, MeshError> {
    let mut w = Words {
        s: bytes,
        pos: 0,
        line: 1,
    };
    let mut vertices: Vec<P3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut groups = Vec::new();
    let mut notes = Vec::new();
    let mut fanned = 0usize;
    // One or more `solid name ... endsolid [name]` blocks.
    while let Some((word, line)) = w.next() {
        if !word.eq_ignore_ascii_case(b"solid") {
            if word.iter().all(|&b| b == 0) {
                notes.push("ignored NUL bytes after the last solid".into());
                break;
            }
            return Err(MeshError::Line {
                line,
                message: format!("expected `solid`, found `{}`", shown(word)),
            });
        }
        let name = w.rest_of_line();
        let first = triangles.len() as u32;
        loop {
            let Some((kw, line)) = w.next() else {
                notes.push(format!("solid `{name}` has no `endsolid`; read to the end of the file"));
                break;
            };
            if kw.eq_ignore_ascii_case(b"endsolid") {
                w.rest_of_line();
                break;
            }
            if !kw.eq_ignore_ascii_case(b"facet") {
                return Err(MeshError::Line {
                    line,
                    message: format!("expected `facet` or `endsolid`, found `{}`", shown(kw)),
                });
            }
            w.expect("normal", "after `facet`")?;
            for _ in 0..3 {
                w.number("facet normal")?;
            }
            w.expect("outer", "after the facet normal")?;
            w.expect("loop", "after `outer`")?;
            let mut loop_v: Vec<P3> = Vec::with_capacity(3);
            loop {
                match w.next() {
                    Some((k, _)) if k.eq_ignore_ascii_case(b"vertex") => {
                        let x = w.number("vertex")?;
                        let y = w.number("vertex")?;
                        let z = w.number("vertex")?;
                        loop_v.push(P3::new(x, y, z));
                    }
                    Some((k, line)) if k.eq_ignore_ascii_case(b"endloop") => {
                        if loop_v.len() < 3 {
                            return Err(MeshError::Line {
                                line,
                                message: format!("facet with {} vertices (needs 3)", loop_v.len()),
                            });
                        }
                        break;
                    }
                    Some((k, line)) => {
                        return Err(MeshError::Line {
                            line,
                            message: format!("expected `vertex` or `endloop`, found `{}`", shown(k)),
                        });
                    }
                    None => {
                        return Err(MeshError::Line {
                            line: w.line,
                            message: "file ends inside a facet".into(),
                        });
                    }
                }
            }
            w.expect("endfacet", "after `endloop`")?;
            if loop_v.len() > 3 {
                fanned += 1;
            }
            // A polygon facet (some exporters) becomes a fan.
            for k in 1..loop_v.len() as u32 - 1 {
                let i = vertices.len() as u32;
                vertices.extend([loop_v[0], loop_v[k as usize], loop_v[k as usize + 1]]);
                triangles.push([i, i + 1, i + 2]);
            }
        }
        groups.push(Group {
            name,
            triangles: first..triangles.len() as u32,
        });
    }
    if fanned > 0 {
        notes.push(format!(
            "split {fanned} facets with more than 3 vertices into fans of triangles"
        ));
    }
    if groups.is_empty() {
        return Err(MeshError::Refused("empty STL file".into()));
    }
    Ok(LoadedMesh {
        mesh: Mesh { vertices, triangles },
        format: "stl-ascii".into(),
        groups,
        notes,
    })
}

/// A binary STL of these triangles (for tests, benchmarks and fuzz seeds).
pub fn write_binary(mesh: &Mesh, header: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(84 + 50 * mesh.triangles.len());
    let mut h = [0u8; 80];
    let hb = header.as_bytes();
    h[..hb.len().min(80)].copy_from_slice(&hb[..hb.len().min(80)]);
    out.extend_from_slice(&h);
    out.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
    for t in mesh.iter_triangles() {
        let n = t.normal().unwrap_or_default();
        for v in [n.x, n.y, n.z] {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        }
        for p in [t.a, t.b, t.c] {
            for v in [p.x, p.y, p.z] {
                out.extend_from_slice(&(v as f32).to_le_bytes());
            }
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

/// An ASCII STL of these triangles, shortest round-trip numbers.
pub fn write_ascii(mesh: &Mesh, name: &str) -> String {
    let mut s = format!("solid {name}\n");
    for t in mesh.iter_triangles() {
        let n = t.normal().unwrap_or_default();
        s.push_str(&format!(" facet normal {} {} {}\n  outer loop\n", n.x, n.y, n.z));
        for p in [t.a, t.b, t.c] {
            s.push_str(&format!("   vertex {} {} {}\n", p.x, p.y, p.z));
        }
        s.push_str("  endloop\n endfacet\n");
    }
    s.push_str(&format!("endsolid {name}\n"));
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Triangle;

    fn tri_mesh() -> Mesh {
        Mesh::from_triangles(&[
            Triangle::new(P3::new(0.0, 0.0, 0.0), P3::new(1.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.0)),
            Triangle::new(P3::new(0.0, 0.0, 1.0), P3::new(1.0, 0.5, 0.0), P3::new(0.25, 1.0, 0.0)),
        ])
    }

    #[test]
    fn binary_round_trip_even_with_solid_header_and_trailing_bytes() {
        let m = tri_mesh();
        let b = write_binary(&m, "solid pretending to be text");
        let r = read_stl(&b).unwrap();
        assert_eq!(r.format, "stl-binary");
        assert_eq!(r.mesh, m);
        let mut t = b.clone();
        t.extend_from_slice(b"\0\0\0junk");
        let r = read_stl(&t).unwrap();
        assert_eq!(r.mesh, m);
        assert!(r.notes[0].contains("7 trailing bytes"), "{:?}", r.notes);
        // Count 0 in the header.
        let mut z = b.clone();
        z[80..84].copy_from_slice(&[0; 4]);
        assert_eq!(read_stl(&z).unwrap().mesh, m);
        // Truncated: names the byte offset.
        let e = read_stl(&b[..b.len() - 10]).unwrap_err().to_string();
        assert!(e.starts_with("byte 134:") && e.contains("truncated"), "{e}");
    }

    #[test]
    fn ascii_odd_whitespace_case_and_several_solids() {
        let m = tri_mesh();
        let a = write_ascii(&m, "one");
        let r = read_stl(a.as_bytes()).unwrap();
        assert_eq!(r.format, "stl-ascii");
        assert_eq!(r.mesh, m);
        let odd = "SOLID A\r\n\tFACET NORMAL 0 0 1\r\n OUTER  LOOP\r\n\tVERTEX 0 0 0\r\nvertex\t1 0 0\r\n vertex 0 1 0\r\nENDLOOP\r\nENDFACET\r\nENDSOLID A\r\nsolid b\nfacet normal 0 0 0 outer loop vertex 0 0 1 vertex 1 0 1 vertex 0 1 1 vertex -1 0 1 endloop endfacet endsolid\n";
        let r = read_stl(odd.as_bytes()).unwrap();
        assert_eq!(r.mesh.triangles.len(), 3);
        assert_eq!(r.groups.len(), 2);
        assert_eq!(r.groups[1].name, "b");
        assert_eq!(r.groups[1].triangles, 1..3);
        assert!(r.notes.iter().any(|n| n.contains("fans")));
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let bad = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 zero 0\n";
        let e = read_stl(bad.as_bytes()).unwrap_err().to_string();
        assert!(e.starts_with("line 5:") && e.contains("zero"), "{e}");
        let bad = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\nendfacet\nendsolid\n";
        let e = read_stl(bad.as_bytes()).unwrap_err().to_string();
        assert!(e.starts_with("line 5:") && e.contains("1 vertices"), "{e}");
        let bad = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 nan\n";
        assert!(read_stl(bad.as_bytes()).unwrap_err().to_string().starts_with("line 6:"));
        assert!(read_stl(b"solid").unwrap().mesh.triangles.is_empty());
        assert!(read_stl(b"xyz").is_err());
    }
}
