//! Drop-cutter: 3-axis cutter locations (CL points) on a triangle mesh for
//! flat, ball and torus end mills, the method of OpenCAMLib.
//!
//! A cutter hanging on the vertical axis through (x, y) is lowered until it
//! first touches the mesh; its tip height then is the CL z. Each triangle
//! under the cutter's disc gives an exact contact height
//! ([`cutter_vs_triangle`]) and the CL z is the highest of them. A grid over
//! the triangles' XY boxes ([`index`]) finds the candidates; batches of
//! points run in parallel with rayon.
//!
//! On top of the drop: raster and along-chain sampling ([`raster`]),
//! adaptive refinement to a chordal tolerance ([`adaptive`]), 5-axis
//! locations along the surface normal in the layout of Singh 2014's
//! Annexure 2 ([`fiveaxis`]) with a check that the rest of the tool
//! stays out of the part ([`gouge`]), constant-Z waterlines ([`waterline`]), and
//! the outputs ([`output`]).

#![warn(missing_docs)]

pub mod adaptive;
pub mod arcs;
pub mod cutter_vs_triangle;
mod fibre;
pub mod fiveaxis;
pub mod gouge;
pub mod index;
pub mod job5;
pub mod normals;
pub mod output;
pub mod raster;
pub mod swing;
pub mod tilt;
pub mod waterline;

use crate::cutter::Cutter;
use crate::geometry::{BBox3, P2, P3};
use crate::mesh::Mesh;
use cutter_vs_triangle::{ContactCutter, Tri, drop_on};
use index::Grid;
use rayon::prelude::*;
use thiserror::Error;

/// Why a drop-cutter job cannot be set up.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum DropError {
    /// The mesh has no triangles to drop on.
    #[error("the mesh has no triangles")]
    EmptyMesh,
    /// A vertex of this triangle (0-based) has a NaN or infinite
    /// coordinate.
    #[error("the mesh has a coordinate that is not finite (triangle {0})")]
    NotFinite(usize),
    /// A job option out of range (a step, a rectangle, a point count, a
    /// 5-axis cutter); the message names the option.
    #[error("{0}")]
    Option(String),
}

/// A mesh prepared for dropping one cutter on it.
#[derive(Debug, Clone)]
pub struct DropCutter {
    shape: ContactCutter,
    tris: Vec<Tri>,
    grid: Grid,
    bbox: BBox3,
}

impl DropCutter {
    /// Prepare `mesh` for `cutter`. Degenerate triangles are kept: their
    /// edges and vertices still touch the cutter.
    pub fn new(mesh: &Mesh, cutter: Cutter) -> Result<DropCutter, DropError> {
        if mesh.triangles.is_empty() {
            return Err(DropError::EmptyMesh);
        }
        let mut tris = Vec::with_capacity(mesh.triangles.len());
        for (i, t) in mesh.iter_triangles().enumerate() {
            let ok = [t.a, t.b, t.c]
                .iter()
                .all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite());
            if !ok {
                return Err(DropError::NotFinite(i));
            }
            tris.push(Tri::new(&t));
        }
        let grid = Grid::build(&tris, cell_size(&tris, cutter.radius()));
        Ok(DropCutter {
            shape: ContactCutter::new(cutter),
            tris,
            grid,
            bbox: mesh.bbox(),
        })
    }

    /// The cutter.
    pub fn cutter(&self) -> Cutter {
        self.shape.cutter
    }

    /// Box of the mesh.
    pub fn bbox(&self) -> BBox3 {
        self.bbox
    }

    /// Tip z of the cutter dropped at (x, y); `None` when its disc reaches
    /// no triangle.
    pub fn drop(&self, x: f64, y: f64) -> Option<f64> {
        let z = self.drop_above(x, y, f64::NEG_INFINITY);
        (z > f64::NEG_INFINITY).then_some(z)
    }

    /// Tip z at (x, y), never below `floor` (the table under the part);
    /// contacts lower than the floor are not searched for, which makes the
    /// drop faster.
    pub fn drop_above(&self, x: f64, y: f64, floor: f64) -> f64 {
        let s = &self.shape;
        let mut best = floor;
        self.grid.query(&self.tris, x, y, s.r, |t| {
            if t.zmax <= best {
                return false;
            }
            if t.near(x, y, s.r) {
                drop_on(s, x, y, t, &mut best);
            }
            true
        });
        best
    }

    /// CL points at many (x, y), in parallel; z is never below `floor`
    /// (pass `f64::NEG_INFINITY` for none: points that touch nothing are
    /// then at −∞).
    pub fn drop_many(&self, xy: &[P2], floor: f64) -> Vec<P3> {
        // In chunks, so the progress counter is touched once per chunk,
        // not once per point.
        let chunks: Vec<Vec<P3>> = xy
            .par_chunks(256)
            .map(|c| {
                let v: Vec<P3> = c
                    .iter()
                    .map(|p| P3::new(p.x, p.y, self.drop_above(p.x, p.y, floor)))
                    .collect();
                crate::progress::advance(c.len() as u64);
                v
            })
            .collect();
        chunks.concat()
    }

    /// The highest point of the mesh straight below (x, y) and the unit
    /// upward normal of the facet it lies on; `None` off the mesh. (The
    /// contact point for a zero-radius tool, used by 5-axis.)
    pub fn surface_point(&self, x: f64, y: f64) -> Option<(f64, [f64; 3])> {
        self.surface_contact(x, y).map(|(z, t)| (z, self.tris[t].n))
    }

    /// The highest point of the mesh straight below (x, y): its height
    /// and the index of the triangle it lies on (of the highest, the
    /// first met); `None` off the mesh.
    pub fn surface_contact(&self, x: f64, y: f64) -> Option<(f64, usize)> {
        let mut best: Option<(f64, usize)> = None;
        self.grid.query_indexed(&self.tris, x, y, 0.0, |i, t| {
            if best.is_some_and(|(z, _)| t.zmax <= z) {
                return false;
            }
            if t.n[2] > 1e-12 && t.contains_xy(x, y) {
                let z = t.plane_z(x, y);
                if best.is_none_or(|(b, _)| z > b) {
                    best = Some((z, i));
                }
            }
            true
        });
        best
    }

    /// Smooth normals over this mesh's triangles, facets within `crease`
    /// radians of one another averaged ([`normals::SmoothNormals`]).
    pub fn smooth_normals(&self, crease: f64) -> normals::SmoothNormals {
        normals::SmoothNormals::new(&self.tris, crease)
    }

    /// The smoothed normal at (x, y) on triangle `t` (as
    /// [`DropCutter::surface_contact`] gives them) under `normals`.
    pub fn smooth_normal_at(&self, normals: &normals::SmoothNormals, t: usize, p: P3) -> crate::geometry::V3 {
        normals.at(&self.tris, t, p)
    }
}

/// Grid cell side: about the cutter diameter, but not much below the
/// typical triangle so that large triangles do not fill many cells.
fn cell_size(tris: &[Tri], r: f64) -> f64 {
    let mut ext: Vec<f64> = tris
        .iter()
        .map(|t| (t.bb[2] - t.bb[0]).max(t.bb[3] - t.bb[1]))
        .collect();
    let mid = ext.len() / 2;
    let median = if ext.is_empty() {
        0.0
    } else {
        *ext.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    (2.0 * r).max(median).max(1e-6)
}

#[cfg(test)]
mod tests;
