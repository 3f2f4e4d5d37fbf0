//! One entry point for reading a mesh: [`read_path`] for a file, [`read_bytes`]
//! for bytes already in memory (stdin). The format comes from the extension
//! when there is one, else from the content; the units scale every
//! coordinate to millimetres (STL carries no units, OBJ none either).
//!
//! The readers return the triangles as read, three vertices each, with no
//! welding: welding and repairs are separate steps ([`super::weld`],
//! [`super::topology`]) so that the ray queries, which need neither, stay as
//! fast as the file allows.

use std::fmt;
use std::ops::Range;
use std::path::Path;

use super::Mesh;

/// Length unit of the coordinates in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Units {
    /// Millimetres (the default, and what every other tool works in).
    #[default]
    Mm,
    /// Inches (25.4 mm).
    Inch,
    /// Micrometres (0.001 mm).
    Um,
}

impl Units {
    /// Millimetres per file unit.
    pub fn to_mm(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inch => 25.4,
            Units::Um => 0.001,
        }
    }
}

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// STL, ASCII or binary (told apart by content).
    Stl,
    /// Wavefront OBJ.
    Obj,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Stl => "stl",
            Format::Obj => "obj",
        })
    }
}

/// How to read a mesh.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadOptions {
    /// Unit of the file's coordinates.
    pub units: Units,
    /// Force a format; `None` = from the extension, else from the content.
    pub format: Option<Format>,
}

/// A named run of triangles: an STL `solid` or an OBJ object/group.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Group {
    /// The name in the file (may be empty).
    pub name: String,
    /// Which triangles of [`LoadedMesh::mesh`] belong to it.
    pub triangles: Range<u32>,
}

/// A mesh as read, with what the reader noticed on the way.
#[derive(Debug, Clone, Default)]
pub struct LoadedMesh {
    /// The triangles in mm, three vertices each (not welded).
    pub mesh: Mesh,
    /// The format actually read, with its variant (`"stl-binary"`,
    /// `"stl-ascii"`, `"obj"`).
    pub format: String,
    /// Solids or groups, in file order, covering every triangle.
    pub groups: Vec<Group>,
    /// Things read leniently or skipped (trailing bytes, a missing
    /// `endsolid`, OBJ line elements), one sentence each.
    pub notes: Vec<String>,
}

/// Why a mesh could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// A syntax or value error at a line of a text file.
    #[error("line {line}: {message}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong there.
        message: String,
    },
    /// An error at a byte offset of a binary file.
    #[error("byte {offset}: {message}")]
    Byte {
        /// 0-based offset from the start of the file.
        offset: u64,
        /// What is wrong there.
        message: String,
    },
    /// Not a mesh file this reader knows, or no triangles in it.
    #[error("{0}")]
    Refused(String),
}

/// Every mesh of the shared test corpus ([`crate::corpus::meshes`]) that
/// the reader takes and that has triangles, with its path, read with the
/// default options; the files it refuses are left out (the reader's own
/// tests answer for those). `None` when the corpus is absent: the caller
/// records the skip. For tests and benchmarks.
pub fn read_corpus_meshes() -> Option<Vec<(std::path::PathBuf, Mesh)>> {
    let files = crate::corpus::meshes();
    if files.is_empty() {
        return None;
    }
    let read = files.into_iter().filter_map(|f| {
        let m = read_path(&f, &ReadOptions::default()).ok()?;
        (!m.mesh.triangles.is_empty()).then_some((f, m.mesh))
    });
    Some(read.collect())
}

/// Read a mesh file; the format from `opts.format`, else the extension
/// (`.stl`, `.obj`, any case), else the content.
pub fn read_path(path: &Path, opts: &ReadOptions) -> Result<LoadedMesh, MeshError> {
    let bytes = std::fs::read(path)?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let format = opts.format.or(match ext.as_deref() {
        Some("stl") => Some(Format::Stl),
        Some("obj") => Some(Format::Obj),
        _ => None,
    });
    read_bytes(&bytes, &ReadOptions { format, ..*opts })
}

/// Read a mesh from bytes (e.g. all of stdin); the format from
/// `opts.format`, else guessed from the content.
pub fn read_bytes(bytes: &[u8], opts: &ReadOptions) -> Result<LoadedMesh, MeshError> {
    let format = match opts.format {
        Some(f) => f,
        None => sniff(bytes)?,
    };
    let mut m = match format {
        Format::Stl => super::read_stl::read_stl(bytes)?,
        Format::Obj => super::read_obj::read_obj(bytes)?,
    };
    if m.mesh.triangles.is_empty() {
        return Err(MeshError::Refused(format!("no triangles in this {} file", m.format)));
    }
    let k = opts.units.to_mm();
    if k != 1.0 {
        for v in &mut m.mesh.vertices {
            v.coords *= k;
        }
    }
    Ok(m)
}

/// Tell STL from OBJ by content: a binary STL's size is 84 + 50 n, an
/// ASCII STL starts with `solid`, an OBJ has `v` and `f` lines.
fn sniff(bytes: &[u8]) -> Result<Format, MeshError> {
    if super::read_stl::binary_size_matches(bytes) {
        return Ok(Format::Stl);
    }
    let head = &bytes[..bytes.len().min(4096)];
    let text = String::from_utf8_lossy(head);
    let t = text.trim_start().as_bytes();
    if t.len() >= 5 && t[..5].eq_ignore_ascii_case(b"solid") {
        return Ok(Format::Stl);
    }
    let objish = text.lines().any(|l| {
        let l = l.trim_start();
        l.starts_with("v ") || l.starts_with("v\t") || l.starts_with("f ") || l.starts_with("o ") || l.starts_with("g ")
    });
    if objish {
        return Ok(Format::Obj);
    }
    if bytes.len() >= 84 {
        // A binary STL with trailing bytes or a short count; the STL
        // reader says which.
        return Ok(Format::Stl);
    }
    Err(MeshError::Refused(
        "not an STL or OBJ file (no `solid` header, no binary STL layout, no OBJ `v`/`f` lines)".into(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_scale_and_sniffing() {
        let stl = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        let m = read_bytes(
            stl,
            &ReadOptions {
                units: Units::Inch,
                format: None,
            },
        )
        .unwrap();
        assert_eq!(m.format, "stl-ascii");
        assert_eq!(m.mesh.vertices[1].x, 25.4);
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let m = read_bytes(
            obj,
            &ReadOptions {
                units: Units::Um,
                format: None,
            },
        )
        .unwrap();
        assert_eq!(m.format, "obj");
        assert!((m.mesh.vertices[1].x - 0.001).abs() < 1e-15);
        assert!(matches!(
            read_bytes(b"hello", &ReadOptions::default()),
            Err(MeshError::Refused(_))
        ));
        let empty = b"solid e\nendsolid e\n";
        let e = read_bytes(empty, &ReadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("no triangles"), "{e}");
    }
}

#[cfg(test)]
mod corpus_tests {
    use super::*;
    use crate::corpus;

    /// Every corpus STL and OBJ reads, or is refused with a message.
    #[test]
    fn corpus_meshes_read_or_are_refused() {
        let files = corpus::meshes();
        if files.is_empty() {
            corpus::skip("corpus_meshes_read_or_are_refused");
            return;
        }
        let mut read = 0;
        for f in &files {
            match read_path(f, &ReadOptions::default()) {
                Ok(m) => {
                    read += 1;
                    assert!(!m.mesh.triangles.is_empty(), "{}", f.display());
                    assert!(m.mesh.vertices.iter().all(|v| v.coords.iter().all(|c| c.is_finite())));
                    let covered: u32 = m.groups.iter().map(|g| g.triangles.len() as u32).sum();
                    assert_eq!(covered as usize, m.mesh.triangles.len(), "{}", f.display());
                    eprintln!(
                        "{}: {} {} triangles, {} groups, notes {:?}",
                        f.display(),
                        m.format,
                        m.mesh.triangles.len(),
                        m.groups.len(),
                        m.notes
                    );
                }
                Err(e) => {
                    let msg = e.to_string();
                    assert!(msg.len() > 10, "{}: {msg}", f.display());
                    eprintln!("{}: refused: {msg}", f.display());
                }
            }
        }
        // The well-formed corpus files all read.
        assert!(read >= files.len() - 1, "only {read} of {} read", files.len());
        corpus::record("corpus_meshes_read_or_are_refused", files.len());
    }
}

#[cfg(test)]
mod robustness {
    use super::*;
    use crate::geometry::P3;
    use crate::mesh::read_stl::{write_ascii, write_binary};
    use crate::mesh::solids;
    use proptest::prelude::*;

    fn seeds() -> Vec<Vec<u8>> {
        let m = solids::cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
        vec![
            write_binary(&m, "solid binary"),
            write_ascii(&m, "a").into_bytes(),
            b"o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf -1 -2 -3\nl 1 2\n".to_vec(),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// Mutated files read or fail with an error, never a panic; and
        /// what reads welds, reports and slices without a panic.
        #[test]
        fn mutated_files_never_panic(which in 0usize..3, edits in proptest::collection::vec((0usize..4096, any::<u8>(), 0u8..3), 1..8)) {
            let mut b = seeds()[which].clone();
            for (pos, byte, op) in edits {
                let p = pos % (b.len() + 1);
                match op {
                    0 if p < b.len() => b[p] = byte,
                    1 => b.insert(p, byte),
                    _ => b.truncate(p.max(1)),
                }
            }
            for format in [None, Some(Format::Stl), Some(Format::Obj)] {
                if let Ok(m) = read_bytes(&b, &ReadOptions { format, ..Default::default() }) {
                    let p = crate::mesh::topology::prepare(&m.mesh, 1e-6);
                    let bb = p.mesh.bbox();
                    if !bb.is_empty() {
                        let z = 0.5 * (bb.min.z + bb.max.z);
                        let _ = crate::slice::section(&p.mesh, z, &Default::default());
                    }
                }
            }
        }
    }
}
