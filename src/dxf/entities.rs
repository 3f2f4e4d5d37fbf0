//! Entities: from the group codes of one entity to a typed value.
//!
//! The reader sits just after `0 / TYPE`; [`read_entity`] consumes the
//! entity's tags (and, for POLYLINE, the VERTEX entities and SEQEND that
//! follow it) and leaves the next `0` tag unread. Coordinates are kept as
//! the file states them (OCS for planar entities); placing them in the world
//! is `expand`'s job.

use super::reader::{DxfError, Pos, Reader};
use crate::geometry::{P3, V3};
use std::sync::Arc;

/// A typed drawing entity we can turn into geometry.
#[derive(Debug, Clone, PartialEq)]
pub enum EntityShape {
    /// LINE (or the old 3DLINE): a straight segment in world coordinates.
    Line {
        /// Start (groups 10/20/30).
        a: P3,
        /// End (groups 11/21/31).
        b: P3,
    },
    /// ARC: angles in degrees, counter-clockwise in the OCS.
    Arc {
        /// Centre, in the OCS.
        c: P3,
        /// Radius (drawing units).
        r: f64,
        /// Start angle (degrees, group 50).
        a0: f64,
        /// End angle (degrees, group 51); the arc runs counter-clockwise
        /// from `a0` to `a1`, a full circle when they are equal.
        a1: f64,
        /// Extrusion direction, which defines the OCS (group 210).
        ext: V3,
    },
    /// CIRCLE: a full turn, counter-clockwise in the OCS.
    Circle {
        /// Centre, in the OCS.
        c: P3,
        /// Radius (drawing units).
        r: f64,
        /// Extrusion direction, which defines the OCS.
        ext: V3,
    },
    /// LWPOLYLINE or 2-D POLYLINE: OCS vertices with bulges, at `elevation`.
    Poly2 {
        /// (x, y, bulge) per vertex; the bulge (`tan(sweep / 4)`, positive
        /// counter-clockwise) belongs to the segment to the next vertex.
        verts: Vec<(f64, f64, f64)>,
        /// The last vertex joins the first (flag 1 of group 70).
        closed: bool,
        /// The OCS Z of every vertex.
        elevation: f64,
        /// Extrusion direction, which defines the OCS.
        ext: V3,
        /// Read from an LWPOLYLINE (for the summary's counts).
        lw: bool,
    },
    /// 3-D POLYLINE: world vertices, straight segments.
    Poly3 {
        /// The vertices in order.
        verts: Vec<P3>,
        /// The last vertex joins the first.
        closed: bool,
    },
    /// ELLIPSE (full or partial), in world coordinates:
    /// `c + major cos t + minor sin t` with `minor = ratio · (ext × major)`.
    Ellipse {
        /// Centre.
        c: P3,
        /// Major semi-axis as a vector from the centre (drawing units).
        major: V3,
        /// Minor to major axis length.
        ratio: f64,
        /// Start parameter (radians, group 41; 0 when absent).
        t0: f64,
        /// End parameter (radians, group 42; 2π when absent); the curve
        /// runs counter-clockwise about `ext` from `t0` to `t1`.
        t1: f64,
        /// Extrusion direction: the ellipse's normal.
        ext: V3,
    },
    /// SPLINE, as the file states it: a NURBS when it has two or more
    /// control points, else a curve through its fit points.
    Spline {
        /// Polynomial degree (group 71, clamped to 0..=64).
        degree: usize,
        /// Knot vector (groups 40).
        knots: Vec<f64>,
        /// Control points, world coordinates (groups 10).
        ctrl: Vec<P3>,
        /// Control point weights (groups 41); unit weights are used when
        /// they are absent or unusable.
        weights: Vec<f64>,
        /// Fit points (groups 11), used when there are no control points.
        fit: Vec<P3>,
        /// Flag 1 of group 70. Informative only: the control points and
        /// knots alone define the curve.
        closed: bool,
    },
    /// POINT: kept as a point (drill marks), not as geometry to chain.
    Point {
        /// The point, world coordinates.
        p: P3,
    },
    /// INSERT or MINSERT: a placed (and possibly arrayed) block.
    Insert(Box<Insert>),
}

/// An INSERT (or MINSERT): block `block` placed at `p`, scaled, rotated
/// about the OCS Z axis, and repeated `rows` × `cols` times.
#[derive(Debug, Clone, PartialEq)]
pub struct Insert {
    /// The block's name, upper-cased once the drawing is read (DXF block
    /// names are case-insensitive).
    pub block: String,
    /// Insertion point, in the OCS; the block's base point lands here.
    pub p: P3,
    /// X, Y and Z scale factors (groups 41, 42, 43; negative mirrors).
    pub scale: V3,
    /// Rotation about the OCS Z axis (degrees, counter-clockwise).
    pub rotation_deg: f64,
    /// Array columns (group 70, at least 1).
    pub cols: u32,
    /// Array rows (group 71, at least 1).
    pub rows: u32,
    /// Distance between columns, in the rotated but unscaled insert frame.
    pub col_spacing: f64,
    /// Distance between rows, in the rotated but unscaled insert frame.
    pub row_spacing: f64,
    /// Extrusion direction, which defines the OCS.
    pub ext: V3,
}

/// An entity with its layer name and where it started in the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Entity {
    /// Shared by the entities of a run on one layer (one allocation per
    /// run, not per entity).
    pub layer: Arc<str>,
    /// The geometry.
    pub shape: EntityShape,
    /// Where its `0` tag sits, for error messages.
    pub pos: Pos,
}

/// What [`read_entity`] found.
pub enum Read {
    /// An entity we can place.
    Entity(Entity),
    /// A type we do not turn into geometry (TEXT, HATCH, ...), or a
    /// variant we cannot (polyface mesh): counted by name.
    Skipped(String),
}

/// Scratch space reused across entities so that reading a million of them
/// does not allocate a million times.
#[derive(Default)]
pub struct Scratch {
    layer: String,
    /// The layer name of the last entity read, shared.
    last_layer: Option<Arc<str>>,
    name: String,
    p10: Vec<P3>,
    bulge: Vec<f64>,
    p11: Vec<P3>,
    f40: Vec<f64>,
    f41: Vec<f64>,
    f42: Option<f64>,
    f43: Option<f64>,
    f44: f64,
    f45: f64,
    f50: f64,
    f38: f64,
    i70: i64,
    i71: i64,
    i72: i64,
    paper: bool,
    ext: V3,
}

impl Scratch {
    fn clear(&mut self) {
        self.layer.clear();
        self.layer.push('0');
        self.name.clear();
        self.p10.clear();
        self.bulge.clear();
        self.p11.clear();
        self.f40.clear();
        self.f41.clear();
        self.f42 = None;
        self.f43 = None;
        self.f44 = 0.0;
        self.f45 = 0.0;
        self.f50 = 0.0;
        self.f38 = 0.0;
        self.i70 = 0;
        self.i71 = 0;
        self.i72 = 0;
        self.paper = false;
        self.ext = V3::z();
    }
}

impl Scratch {
    /// The layer just read, as the shared name of the previous entity's
    /// when it is the same.
    fn shared_layer(&mut self) -> Arc<str> {
        match &self.last_layer {
            Some(l) if **l == *self.layer => l.clone(),
            _ => {
                let l: Arc<str> = Arc::from(self.layer.as_str());
                self.last_layer = Some(l.clone());
                l
            }
        }
    }
}

fn set_coord(points: &mut [P3], axis: usize, v: f64) {
    if let Some(p) = points.last_mut() {
        p[axis] = v;
    }
}

/// Read the tags of one entity into `s`, stopping before the
/// next `0` tag.
fn read_tags(r: &mut Reader, s: &mut Scratch) -> Result<(), DxfError> {
    s.clear();
    while let Some(code) = r.next_tag()? {
        match code {
            0 => {
                r.unread();
                break;
            }
            8 => {
                s.layer.clear();
                s.layer.push_str(r.text().trim());
            }
            2 => {
                s.name.clear();
                s.name.push_str(r.text().trim());
            }
            10 => {
                s.p10.push(P3::new(r.float(), 0.0, 0.0));
                s.bulge.push(0.0);
            }
            20 => set_coord(&mut s.p10, 1, r.float()),
            30 => set_coord(&mut s.p10, 2, r.float()),
            11 => s.p11.push(P3::new(r.float(), 0.0, 0.0)),
            21 => set_coord(&mut s.p11, 1, r.float()),
            31 => set_coord(&mut s.p11, 2, r.float()),
            38 => s.f38 = r.float(),
            40 => s.f40.push(r.float()),
            41 => s.f41.push(r.float()),
            42 => {
                // After a vertex it is that vertex's bulge (LWPOLYLINE).
                if let Some(b) = s.bulge.last_mut() {
                    *b = r.float();
                }
                s.f42 = Some(r.float());
            }
            43 => s.f43 = Some(r.float()),
            44 => s.f44 = r.float(),
            45 => s.f45 = r.float(),
            50 => s.f50 = r.float(),
            51 => s.f41.push(r.float()),
            70 => s.i70 = r.int(),
            71 => s.i71 = r.int(),
            72 => s.i72 = r.int(),
            // Paper-space entities (title blocks, viewports) are not the part.
            67 => s.paper = r.int() == 1,
            210 => s.ext.x = r.float(),
            220 => s.ext.y = r.float(),
            230 => s.ext.z = r.float(),
            _ => {}
        }
    }
    Ok(())
}

fn first(v: &[P3]) -> P3 {
    v.first().copied().unwrap_or_else(P3::origin)
}

fn finite_p(p: &P3) -> bool {
    p.iter().all(|x| x.is_finite())
}

/// Read one entity whose `0 / kind` tag was just consumed.
pub fn read_entity(kind: &str, r: &mut Reader, s: &mut Scratch) -> Result<Read, DxfError> {
    let pos = r.pos;
    read_tags(r, s)?;
    let bad = |msg: &str| DxfError::at(pos, format!("{kind}: {msg}"));
    if s.paper && kind != "POLYLINE" {
        return Ok(Read::Skipped(format!("{kind} (paper space)")));
    }
    let shape = match kind {
        "LINE" | "3DLINE" => {
            let a = first(&s.p10);
            let b = s.p11.first().copied().ok_or_else(|| bad("no end point (group 11)"))?;
            // LINE is a world-coordinate entity; its extrusion only gives
            // thickness a direction.
            EntityShape::Line { a, b }
        }
        "ARC" => {
            let r0 = s.f40.first().copied().ok_or_else(|| bad("no radius (group 40)"))?;
            // Code 50 is the start angle, 51 the end angle (stored in f41
            // because ARC has no group 41).
            let a1 = s.f41.first().copied().ok_or_else(|| bad("no end angle (group 51)"))?;
            EntityShape::Arc {
                c: first(&s.p10),
                r: r0,
                a0: s.f50,
                a1,
                ext: s.ext,
            }
        }
        "CIRCLE" => EntityShape::Circle {
            c: first(&s.p10),
            r: s.f40.first().copied().ok_or_else(|| bad("no radius (group 40)"))?,
            ext: s.ext,
        },
        "LWPOLYLINE" => EntityShape::Poly2 {
            verts: s.p10.iter().zip(&s.bulge).map(|(p, b)| (p.x, p.y, *b)).collect(),
            closed: s.i70 & 1 != 0,
            elevation: s.f38,
            ext: s.ext,
            lw: true,
        },
        "POLYLINE" => return read_polyline(r, s, pos),
        "ELLIPSE" => {
            let major = s
                .p11
                .first()
                .map(|p| p.coords)
                .ok_or_else(|| bad("no major axis (group 11)"))?;
            let ratio = s.f40.first().copied().ok_or_else(|| bad("no axis ratio (group 40)"))?;
            EntityShape::Ellipse {
                c: first(&s.p10),
                major,
                ratio,
                t0: s.f41.first().copied().unwrap_or(0.0),
                t1: s.f42.unwrap_or(std::f64::consts::TAU),
                ext: s.ext,
            }
        }
        "SPLINE" => EntityShape::Spline {
            degree: s.i71.clamp(0, 64) as usize,
            knots: s.f40.clone(),
            ctrl: s.p10.clone(),
            weights: s.f41.clone(),
            fit: s.p11.clone(),
            closed: s.i70 & 1 != 0,
        },
        "POINT" => EntityShape::Point { p: first(&s.p10) },
        "INSERT" | "MINSERT" => {
            if s.name.is_empty() {
                return Err(bad("no block name (group 2)"));
            }
            // 41/42/43 are the X/Y/Z scales; 42 also landed in f42.
            let sx = s.f41.first().copied().unwrap_or(1.0);
            let sy = s.f42.unwrap_or(1.0);
            let sz = s.f43.unwrap_or(1.0);
            EntityShape::Insert(Box::new(Insert {
                block: s.name.clone(),
                p: first(&s.p10),
                scale: V3::new(sx, sy, sz),
                rotation_deg: s.f50,
                cols: s.i70.clamp(1, 100_000) as u32,
                rows: s.i71.clamp(1, 100_000) as u32,
                col_spacing: s.f44,
                row_spacing: s.f45,
                ext: s.ext,
            }))
        }
        other => return Ok(Read::Skipped(other.to_string())),
    };
    if !shape_finite(&shape) {
        return Err(bad("non-finite coordinate"));
    }
    Ok(Read::Entity(Entity {
        layer: s.shared_layer(),
        shape,
        pos,
    }))
}

fn shape_finite(s: &EntityShape) -> bool {
    match s {
        EntityShape::Line { a, b } => finite_p(a) && finite_p(b),
        EntityShape::Arc { c, r, a0, a1, .. } => finite_p(c) && r.is_finite() && a0.is_finite() && a1.is_finite(),
        EntityShape::Circle { c, r, .. } => finite_p(c) && r.is_finite(),
        _ => true,
    }
}

/// POLYLINE: the header entity, then VERTEX entities up to SEQEND.
fn read_polyline(r: &mut Reader, s: &mut Scratch, pos: Pos) -> Result<Read, DxfError> {
    let flags = s.i70;
    let paper = s.paper;
    let layer = s.shared_layer();
    let elevation = s.p10.first().map(|p| p.z).unwrap_or(0.0);
    let ext = s.ext;
    let mut verts2 = Vec::new();
    let mut verts3 = Vec::new();
    loop {
        match r.next_tag()? {
            None => return Err(DxfError::at(pos, "POLYLINE: file ends before SEQEND")),
            Some(0) => {}
            Some(_) => unreachable_tag(r)?,
        }
        match r.text() {
            "VERTEX" => {
                read_tags(r, s)?;
                let vflags = s.i70;
                // Spline frame control points (16) are not on the curve;
                // polyface face records (128 without 64) are not vertices.
                if vflags & 16 != 0 || (vflags & 128 != 0 && vflags & 64 == 0) {
                    continue;
                }
                let p = first(&s.p10);
                if !finite_p(&p) || !s.f42.unwrap_or(0.0).is_finite() {
                    return Err(DxfError::at(r.pos, "VERTEX: non-finite coordinate"));
                }
                verts2.push((p.x, p.y, s.f42.unwrap_or(0.0)));
                verts3.push(p);
            }
            "SEQEND" => {
                read_tags(r, s)?;
                break;
            }
            _ => {
                // R12 writers occasionally omit SEQEND: the polyline ends
                // at the next entity.
                r.unread();
                break;
            }
        }
    }
    if paper {
        return Ok(Read::Skipped("POLYLINE (paper space)".into()));
    }
    if flags & (16 | 64) != 0 {
        return Ok(Read::Skipped("POLYLINE (mesh)".into()));
    }
    let closed = flags & 1 != 0;
    let shape = if flags & 8 != 0 {
        EntityShape::Poly3 { verts: verts3, closed }
    } else {
        EntityShape::Poly2 {
            verts: verts2,
            closed,
            elevation,
            ext,
            lw: false,
        }
    };
    Ok(Read::Entity(Entity { layer, shape, pos }))
}

/// After an entity's tags the next tag is always a `0`; anything else
/// means `read_tags` stopped early, which it never does.
fn unreachable_tag(r: &Reader) -> Result<(), DxfError> {
    Err(DxfError::at(
        r.pos,
        format!("unexpected group code {} between entities", r.code),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn read(text: &str) -> Read {
        let mut r = Reader::new(Box::new(Cursor::new(text.as_bytes().to_vec()))).unwrap();
        assert_eq!(r.next_tag().unwrap(), Some(0));
        let kind = r.text().to_string();
        read_entity(&kind, &mut r, &mut Scratch::default()).unwrap()
    }

    #[test]
    fn lwpolyline_bulges_belong_to_their_vertex() {
        let t = "0\nLWPOLYLINE\n8\nCUT\n90\n3\n70\n1\n10\n0\n20\n0\n10\n1\n20\n0\n42\n0.5\n10\n1\n20\n1\n0\nEOF\n";
        let Read::Entity(e) = read(t) else { panic!() };
        assert_eq!(&*e.layer, "CUT");
        let EntityShape::Poly2 { verts, closed, .. } = e.shape else {
            panic!()
        };
        assert!(closed);
        assert_eq!(verts, vec![(0.0, 0.0, 0.0), (1.0, 0.0, 0.5), (1.0, 1.0, 0.0)]);
    }

    #[test]
    fn polyline_reads_vertices_to_seqend() {
        let t =
            "0\nPOLYLINE\n66\n1\n70\n1\n0\nVERTEX\n10\n0\n20\n0\n42\n1\n0\nVERTEX\n10\n2\n20\n0\n0\nSEQEND\n0\nEOF\n";
        let Read::Entity(e) = read(t) else { panic!() };
        let EntityShape::Poly2 { verts, closed, .. } = e.shape else {
            panic!()
        };
        assert!(closed);
        assert_eq!(verts, vec![(0.0, 0.0, 1.0), (2.0, 0.0, 0.0)]);
    }

    #[test]
    fn unknown_types_are_skipped_by_name() {
        let Read::Skipped(k) = read("0\nMTEXT\n1\nhello\n0\nEOF\n") else {
            panic!()
        };
        assert_eq!(k, "MTEXT");
    }

    #[test]
    fn arc_without_radius_is_an_error() {
        let mut r = Reader::new(Box::new(Cursor::new(b"0\nARC\n10\n0\n0\nEOF\n".to_vec()))).unwrap();
        r.next_tag().unwrap();
        let e = read_entity("ARC", &mut r, &mut Scratch::default())
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("line 1") && e.contains("radius"), "{e}");
    }
}
