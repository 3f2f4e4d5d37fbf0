//! Triangle meshes: the models the milling half starts from (STL, OBJ) and
//! the design parts it verifies against.
//!
//! A [`Mesh`] is an indexed triangle list in millimetres. Readers, welding,
//! the topology report, the ray-query BVH and planar sections build on it.
//!
//! - [`read`]: one entry point, [`read_path`] / [`read_bytes`], for STL
//!   (ASCII and binary, [`read_stl`]) and OBJ ([`read_obj`]), with units.
//! - [`weld`]: merge vertices within a tolerance (spatial hash, linear time).
//! - [`topology`]: the topology report and the repairs (degenerate and
//!   duplicate triangles dropped, orientation made consistent).
//! - [`solids`]: generated closed solids (sphere, torus, cylinder, box).
//! - [`bvh`]: a bounding-volume hierarchy with ray and nearest-point queries.
//! - [`parallel`]: first hits of many rays in one direction (a 2-D grid over
//!   the projection; the verification rays).
#![warn(missing_docs)]

pub mod bvh;
pub mod parallel;
pub mod read;
pub mod read_obj;
pub mod read_stl;
pub mod solids;
pub mod topology;
pub mod weld;

pub use read::{Format, Group, LoadedMesh, MeshError, ReadOptions, Units, read_bytes, read_corpus_meshes, read_path};

use crate::geometry::{BBox3, P3, V3};

/// An indexed triangle mesh (mm). Triangles index into `vertices`; their
/// winding gives the outward normal by the right-hand rule.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions (mm).
    pub vertices: Vec<P3>,
    /// Triangles as three indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// One triangle by value, for the geometric queries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    /// First corner.
    pub a: P3,
    /// Second corner.
    pub b: P3,
    /// Third corner.
    pub c: P3,
}

impl Triangle {
    /// A triangle from its corners, in winding order.
    pub fn new(a: P3, b: P3, c: P3) -> Triangle {
        Triangle { a, b, c }
    }

    /// Twice the area times the unit normal (right-hand rule over a, b, c).
    pub fn cross(&self) -> V3 {
        (self.b - self.a).cross(&(self.c - self.a))
    }

    /// Unit normal, `None` for a degenerate (zero-area) triangle.
    pub fn normal(&self) -> Option<V3> {
        let n = self.cross();
        let l = n.norm();
        (l > 0.0 && l.is_finite()).then(|| n / l)
    }

    /// Area (mm²).
    pub fn area(&self) -> f64 {
        0.5 * self.cross().norm()
    }

    /// Box around the three corners.
    pub fn bbox(&self) -> BBox3 {
        let mut b = BBox3::empty();
        b.extend(&self.a);
        b.extend(&self.b);
        b.extend(&self.c);
        b
    }
}

impl Mesh {
    /// The `i`-th triangle by value.
    pub fn triangle(&self, i: usize) -> Triangle {
        let [a, b, c] = self.triangles[i];
        Triangle::new(
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        )
    }

    /// The triangle on three vertex indices, by value.
    pub fn triangle_of(&self, t: &[u32; 3]) -> Triangle {
        Triangle::new(
            self.vertices[t[0] as usize],
            self.vertices[t[1] as usize],
            self.vertices[t[2] as usize],
        )
    }

    /// Every triangle by value, in order.
    pub fn iter_triangles(&self) -> impl ExactSizeIterator<Item = Triangle> + '_ {
        (0..self.triangles.len()).map(|i| self.triangle(i))
    }

    /// Box around every vertex that a triangle uses.
    pub fn bbox(&self) -> BBox3 {
        let mut b = BBox3::empty();
        for t in &self.triangles {
            for &v in t {
                b.extend(&self.vertices[v as usize]);
            }
        }
        b
    }

    /// Build from triangles given by value (no welding: three vertices each).
    pub fn from_triangles(tris: &[Triangle]) -> Mesh {
        let mut m = Mesh {
            vertices: Vec::with_capacity(tris.len() * 3),
            triangles: Vec::with_capacity(tris.len()),
        };
        for t in tris {
            let i = m.vertices.len() as u32;
            m.vertices.extend([t.a, t.b, t.c]);
            m.triangles.push([i, i + 1, i + 2]);
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_normal_area_and_mesh_box() {
        let t = Triangle::new(P3::new(0.0, 0.0, 0.0), P3::new(2.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.5));
        assert!((t.area() - 0.5 * (1.0f64 + 0.25).sqrt() * 2.0).abs() < 1e-12);
        let n = t.normal().unwrap();
        assert!((n.norm() - 1.0).abs() < 1e-12 && n.z > 0.0);
        let flat = Triangle::new(P3::origin(), P3::new(1.0, 0.0, 0.0), P3::new(2.0, 0.0, 0.0));
        assert!(flat.normal().is_none());
        let m = Mesh::from_triangles(&[t]);
        let b = m.bbox();
        assert_eq!(b.max, P3::new(2.0, 1.0, 0.5));
        assert_eq!(m.triangle(0), t);
    }
}
