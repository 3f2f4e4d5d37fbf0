//! A bounding-volume hierarchy over a mesh's triangles, with ray queries
//! (first hit, every hit, hit count, inside test) and nearest-point
//! queries, one at a time or in parallel batches (rayon).
//!
//! Built here rather than taken from a crate (`bvh`, `obvhs`, `parry3d`):
//! see docs/mesh.md for the reasons and figures. In short:
//!
//! - **Build**: binned surface-area heuristic (12 bins; the longest axis
//!   above 256 triangles, all three below), leaves of up to 4 triangles,
//!   children's bounds taken from the bins of the split, the top levels
//!   built in parallel. Nodes are flattened depth-first, 32 bytes each (an
//!   f32 box, rounded outward and padded, plus two u32), so the left child
//!   is always the next node (nearest-point queries walk this tree).
//! - **Ray traversal** walks a 4-wide tree collapsed from it: each quad
//!   holds its four children's boxes as structure of arrays (128 bytes),
//!   met by one ray with a few 4-lane operations, entry and exit rows
//!   chosen by the sign of the direction, children visited nearest first.
//!   Big batches of first-hit queries are cast in the order of a Morton
//!   code of where each ray enters the mesh's box and of its direction.
//! - **Ray-triangle test**: the watertight test of Woop, Benthin and Wald
//!   (2013) in f64: a ray through a shared edge or vertex can never slip
//!   between two triangles. On top of it a tie rule (a zero edge function
//!   counts as inside only for "top-left" edges, as rasterisers do) makes a
//!   ray through a shared edge hit exactly one of the two triangles, so
//!   hit counts along a ray through a closed mesh are even.
//! - **Triangles** are stored in leaf order as f64 corners, so a leaf is one
//!   contiguous read.
//!
//! Parameters along a ray are in units of `dir`'s length (`dir` need not
//! be a unit vector).

use rayon::prelude::*;

use super::Mesh;
use crate::geometry::{P3, V3};

/// A ray `origin + t * dir`, for `t` in `[t_min, t_max]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point (mm).
    pub origin: P3,
    /// Direction (need not be unit; `t` is in its lengths).
    pub dir: V3,
    /// Smallest parameter that counts as a hit.
    pub t_min: f64,
    /// Largest parameter that counts as a hit.
    pub t_max: f64,
}

impl Ray {
    /// A ray from `origin` along `dir`, `t` in `[0, ∞)`.
    pub fn new(origin: P3, dir: V3) -> Ray {
        Ray {
            origin,
            dir,
            t_min: 0.0,
            t_max: f64::INFINITY,
        }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> P3 {
        self.origin + self.dir * t
    }
}

/// Where a ray meets a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Index of the triangle in the mesh.
    pub triangle: u32,
    /// Barycentric weight of the triangle's second corner.
    pub u: f64,
    /// Barycentric weight of the third corner (the first has `1 - u - v`).
    pub v: f64,
    /// True when the ray meets the triangle's front (its normal opposes `dir`).
    pub front: bool,
}

/// The point of the mesh nearest a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// The nearest point on the mesh.
    pub point: P3,
    /// The triangle it lies on.
    pub triangle: u32,
    /// Distance from the query point (mm).
    pub distance: f64,
}

#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(32))]
struct Node {
    min: [f32; 3],
    /// Leaf: first triangle (in leaf order). Interior: right child.
    a: u32,
    max: [f32; 3],
    /// Leaf: triangle count (> 0). Interior: 0 (left child is the next node).
    n: u32,
}

/// An interior node for ray traversal, 4 wide (the binary tree collapsed):
/// the four children's boxes as structure of arrays, so one ray meets all
/// four with the same few 4-lane f32 operations, in two cache lines.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
struct Quad {
    /// Child boxes: rows min x, y, z, max x, y, z; columns the children.
    b: [[f32; 4]; 6],
    /// Child: quad index (count 0) or first triangle (count > 0).
    child: [u32; 4],
    /// 0 for an interior child, the triangle count of a leaf, EMPTY for
    /// an unused slot.
    count: [u32; 4],
}

const EMPTY: u32 = u32::MAX;

impl Quad {
    const NONE: Quad = Quad {
        b: [
            [f32::INFINITY; 4],
            [f32::INFINITY; 4],
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
            [f32::NEG_INFINITY; 4],
            [f32::NEG_INFINITY; 4],
        ],
        child: [0; 4],
        count: [EMPTY; 4],
    };
}

/// The hierarchy, owning a copy of the triangles in leaf order.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    quads: Vec<Quad>,
    tris: Vec<[P3; 3]>,
    ids: Vec<u32>,
}

const BINS: usize = 12;
const MAX_LEAF: usize = 4;
const PAR_MIN: usize = 1 << 15;

/// A box during the build, in f32 rounded outward (half the memory of
/// f64 to stream through at every level; the node boxes are f32 anyway).
/// Four lanes (the fourth is not a coordinate) so a union is one 4-lane
/// min and max.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
struct Aabb {
    min: [f32; 4],
    max: [f32; 4],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: [f32::INFINITY; 4],
        max: [f32::NEG_INFINITY; 4],
    };
    // Compare-and-select rather than f32::min/max (which order NaNs and
    // cost several instructions each): the boxes are of finite corners.
    #[inline(always)]
    fn grow(&mut self, o: &Aabb) {
        for k in 0..4 {
            self.min[k] = if o.min[k] < self.min[k] { o.min[k] } else { self.min[k] };
            self.max[k] = if o.max[k] > self.max[k] { o.max[k] } else { self.max[k] };
        }
    }
    #[inline(always)]
    fn grow_p(&mut self, p: &[f32; 4]) {
        for (k, &v) in p.iter().enumerate() {
            self.min[k] = if v < self.min[k] { v } else { self.min[k] };
            self.max[k] = if v > self.max[k] { v } else { self.max[k] };
        }
    }
    fn half_area(&self) -> f64 {
        let d = [
            self.max[0] as f64 - self.min[0] as f64,
            self.max[1] as f64 - self.min[1] as f64,
            self.max[2] as f64 - self.min[2] as f64,
        ];
        if d[0] < 0.0 {
            return 0.0;
        }
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

/// `x` rounded down (`up` false) or up to an f32.
#[inline]
fn round_f32(x: f64, up: bool) -> f32 {
    let f = x as f32;
    if up && (f as f64) < x {
        f.next_up()
    } else if !up && (f as f64) > x {
        f.next_down()
    } else {
        f
    }
}

/// A triangle during the build: box, centroid and index (48 bytes), moved
/// together by the partitions so every pass over a node reads memory in
/// order. The index rides in the centroid's fourth lane (as bits; the
/// centroid boxes ignore that lane).
#[derive(Clone, Copy)]
struct Prim {
    b: Aabb,
    c: [f32; 4],
}

impl Prim {
    #[inline]
    fn id(&self) -> u32 {
        self.c[3].to_bits()
    }
}

impl Bvh {
    /// Build over every triangle of `mesh` (degenerate ones included: they
    /// are never hit by rays but take part in nearest-point queries).
    pub fn new(mesh: &Mesh) -> Bvh {
        let n = mesh.triangles.len();
        let corners: Vec<[P3; 3]> = mesh
            .triangles
            .par_iter()
            .with_min_len(4096)
            .map(|t| {
                [
                    mesh.vertices[t[0] as usize],
                    mesh.vertices[t[1] as usize],
                    mesh.vertices[t[2] as usize],
                ]
            })
            .collect();
        let mut prims: Vec<Prim> = corners
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(i, c)| {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for p in c {
                    for k in 0..3 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                }
                let (lo4, hi4) = (lo.map(|v| round_f32(v, false)), hi.map(|v| round_f32(v, true)));
                let b = Aabb {
                    min: [lo4[0], lo4[1], lo4[2], 0.0],
                    max: [hi4[0], hi4[1], hi4[2], 0.0],
                };
                let m = [0, 1, 2].map(|k| (0.5 * (lo[k] + hi[k])) as f32);
                Prim {
                    b,
                    c: [m[0], m[1], m[2], f32::from_bits(i as u32)],
                }
            })
            .collect();
        // The root's box and centroid box (each node's children get theirs
        // from the bins of its split).
        let (all, call) = bounds(&prims);
        // Absolute padding of every box: covers the f32 rounding of ray
        // origins and slab parameters for rays starting within a few scene
        // sizes of the mesh.
        let scale = (0..3)
            .map(|k| (all.max[k].abs().max(all.min[k].abs())) as f64)
            .fold(0.0, f64::max);
        let pad = scale * 1e-6 + 1e-12;
        let mut nodes = Vec::with_capacity(2 * n / MAX_LEAF + 1);
        if n > 0 {
            build(&mut prims, 0, &mut nodes, pad, all, call);
        }
        let ids: Vec<u32> = prims.iter().map(|p| p.id()).collect();
        let tris = ids
            .par_iter()
            .with_min_len(4096)
            .map(|&i| corners[i as usize])
            .collect();
        let quads = quads_of(&nodes);
        Bvh {
            nodes,
            quads,
            tris,
            ids,
        }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True for a hierarchy over no triangles.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// Number of nodes (for reports and benchmarks).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The nearest hit along the ray, if any. Triangles count as closed
    /// here (a ray exactly through an edge or vertex hits every triangle
    /// on it, at the same point), so a ray through the rim of a part's top
    /// face, or exactly through a vertex, never slips through; of several
    /// hits at the same `t` the lowest triangle index is reported, so the
    /// answer does not depend on the tree.
    pub fn first_hit(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let t_max = std::cell::Cell::new(ray.t_max);
        self.traverse(
            ray,
            |_| t_max.get(),
            |bvh, i, pre| {
                if let Some(h) = bvh.hit_tri(i, ray, pre, t_max.get(), Edges::Closed)
                    && best.is_none_or(|b| h.t < b.t || (h.t == b.t && h.triangle < b.triangle))
                {
                    t_max.set(h.t);
                    best = Some(h);
                }
            },
        );
        best
    }

    /// Every hit along the ray, sorted by `t` (then triangle index). A ray
    /// through a shared edge or vertex of a consistently oriented mesh
    /// counts it once.
    pub fn all_hits(&self, ray: &Ray) -> Vec<Hit> {
        let mut out = Vec::new();
        self.traverse(
            ray,
            |_| ray.t_max,
            |bvh, i, pre| {
                if let Some(h) = bvh.hit_tri(i, ray, pre, ray.t_max, Edges::TopLeft) {
                    out.push(h);
                }
            },
        );
        out.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.triangle.cmp(&b.triangle)));
        out
    }

    /// How many triangles the ray crosses.
    pub fn count_hits(&self, ray: &Ray) -> usize {
        let mut n = 0;
        self.traverse(
            ray,
            |_| ray.t_max,
            |bvh, i, pre| {
                n += bvh.hit_tri(i, ray, pre, ray.t_max, Edges::TopLeft).is_some() as usize;
            },
        );
        n
    }

    /// Is `p` inside a closed mesh? Parity of the crossings of a ray in a
    /// fixed oblique direction (no axis-aligned faces lie along it).
    pub fn contains(&self, p: &P3) -> bool {
        let d = V3::new(
            0.577_350_269_189_625_8,
            0.577_350_269_189_625_7 * 1.000_123,
            0.577_350_269_189_626 * 0.999_871,
        );
        !self.count_hits(&Ray::new(*p, d)).is_multiple_of(2)
    }

    /// The nearest point of the mesh to `p` (None for an empty mesh).
    pub fn nearest(&self, p: &P3) -> Option<Nearest> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best_d2 = f64::INFINITY;
        let mut best: Option<(P3, u32)> = None;
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0u32;
        loop {
            let nd = &self.nodes[node as usize];
            if nd.n > 0 {
                for i in nd.a..nd.a + nd.n {
                    let [a, b, c] = self.tris[i as usize];
                    let q = closest_on_triangle(p, &a, &b, &c);
                    let d2 = (q - p).norm_squared();
                    if d2 < best_d2 {
                        best_d2 = d2;
                        best = Some((q, self.ids[i as usize]));
                    }
                }
            } else {
                let l = node + 1;
                let r = nd.a;
                let dl = box_d2(&self.nodes[l as usize], p);
                let dr = box_d2(&self.nodes[r as usize], p);
                let (near, far, dn, df) = if dl <= dr { (l, r, dl, dr) } else { (r, l, dr, dl) };
                if dn < best_d2 {
                    if df < best_d2 && sp < stack.len() {
                        stack[sp] = far;
                        sp += 1;
                    }
                    node = near;
                    continue;
                }
            }
            // Pop the next node still closer than the best so far.
            loop {
                if sp == 0 {
                    return best.map(|(q, t)| Nearest {
                        point: q,
                        triangle: t,
                        distance: best_d2.sqrt(),
                    });
                }
                sp -= 1;
                node = stack[sp];
                if box_d2(&self.nodes[node as usize], p) < best_d2 {
                    break;
                }
            }
        }
    }

    /// Work a first-hit query does: (nodes whose children were box-tested,
    /// triangles tested). For benchmarks and docs/mesh.md.
    pub fn first_hit_cost(&self, ray: &Ray) -> (usize, usize) {
        let t_max = std::cell::Cell::new(ray.t_max);
        let tris = std::cell::Cell::new(0usize);
        let nodes = std::cell::Cell::new(0usize);
        self.traverse(
            ray,
            |_| {
                nodes.set(nodes.get() + 1);
                t_max.get()
            },
            |bvh, i, pre| {
                tris.set(tris.get() + 1);
                if let Some(h) = bvh.hit_tri(i, ray, pre, t_max.get(), Edges::Closed) {
                    t_max.set(h.t);
                }
            },
        );
        (nodes.get(), tris.get())
    }

    /// [`Bvh::first_hit`] for many rays, in parallel; the answers are
    /// those of `first_hit` ray by ray, in the order given.
    ///
    /// Incoherent rays (random origins and directions) are cast in the
    /// order of a key (a Morton code of where each ray enters the mesh's
    /// box and of its direction), so consecutive rays walk mostly the same
    /// nodes and find them in cache; the sort costs a few percent of the
    /// casting and pays for itself several times over on random rays.
    pub fn first_hits(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        const SORT_MIN: usize = 4096;
        if rays.len() < SORT_MIN || self.nodes.is_empty() {
            return rays.par_iter().with_min_len(256).map(|r| self.first_hit(r)).collect();
        }
        let order = self.ray_order(rays);
        let sorted: Vec<Option<Hit>> = order
            .par_iter()
            .with_min_len(1024)
            .map(|&i| self.first_hit(&rays[i as usize]))
            .collect();
        let mut rank = vec![0u32; rays.len()];
        for (p, &i) in order.iter().enumerate() {
            rank[i as usize] = p as u32;
        }
        rank.par_iter()
            .with_min_len(4096)
            .map(|&p| sorted[p as usize])
            .collect()
    }

    /// The indices of `rays` sorted by a 30-bit Morton code of where each
    /// enters the root box (5 bits an axis) and of its unit direction (5
    /// bits a component); rays that miss the box come last.
    fn ray_order(&self, rays: &[Ray]) -> Vec<u32> {
        let root = &self.nodes[0];
        let lo = root.min.map(f64::from);
        let ext = [0, 1, 2].map(|k| (root.max[k] as f64 - lo[k]).max(f64::MIN_POSITIVE));
        let q = |x: f64| (x.clamp(0.0, 0.999_999) * 32.0) as u32;
        let mut keys: Vec<u64> = rays
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(i, r)| {
                let (o, d) = (r.origin, r.dir);
                let (mut t0, mut t1) = (r.t_min.max(0.0), r.t_max);
                for k in 0..3 {
                    let a = (lo[k] - o[k]) / d[k];
                    let b = (lo[k] + ext[k] - o[k]) / d[k];
                    let (near, far) = if a < b { (a, b) } else { (b, a) };
                    t0 = if near > t0 { near } else { t0 };
                    t1 = if far < t1 { far } else { t1 };
                }
                let key = if t0 <= t1 && t0.is_finite() {
                    let len = d.norm();
                    let mut c = [0u32; 6];
                    for k in 0..3 {
                        c[k] = q((o[k] + d[k] * t0 - lo[k]) / ext[k]);
                        c[k + 3] = q(0.5 + 0.5 * d[k] / len);
                    }
                    let mut m = 0u32;
                    for bit in (0..5).rev() {
                        for ck in c {
                            m = (m << 1) | ((ck >> bit) & 1);
                        }
                    }
                    m
                } else {
                    u32::MAX
                };
                ((key as u64) << 32) | i as u64
            })
            .collect();
        radix_sort_high32(&mut keys);
        keys.into_iter().map(|k| k as u32).collect()
    }

    /// [`Bvh::all_hits`] for many rays, in parallel.
    pub fn all_hits_batch(&self, rays: &[Ray]) -> Vec<Vec<Hit>> {
        rays.par_iter().with_min_len(256).map(|r| self.all_hits(r)).collect()
    }

    /// [`Bvh::nearest`] for many points, in parallel.
    pub fn nearest_batch(&self, points: &[P3]) -> Vec<Option<Nearest>> {
        points.par_iter().with_min_len(256).map(|p| self.nearest(p)).collect()
    }

    /// Visit every leaf triangle whose node box the ray enters before the
    /// current `t_max` (asked again at each step, so first-hit queries
    /// shrink it), nearer child first.
    #[inline]
    fn traverse(&self, ray: &Ray, mut t_max: impl FnMut(()) -> f64, mut leaf: impl FnMut(&Bvh, usize, &Pre)) {
        if self.nodes.is_empty() {
            return;
        }
        let Some(pre) = Pre::new(ray) else { return };
        let t0 = ray.t_min as f32;
        let root = &self.nodes[0];
        if pre.slab(root, t0, t_max(()) as f32).is_none() {
            return;
        }
        if root.n > 0 {
            for i in root.a..root.a + root.n {
                leaf(self, i as usize, &pre);
            }
            return;
        }
        let mut stack = Stack::new();
        let mut node = 0u32;
        let slack = 1.0 + 4.0 * f32::EPSILON;
        loop {
            let q = &self.quads[node as usize];
            let (e, hit) = pre.slab4(q, t0, t_max(()) as f32);
            // The children the ray enters, nearest first.
            let mut kids = [(0f32, 0u32); 4];
            let mut k = 0;
            for c in 0..4 {
                if hit[c] && q.count[c] != EMPTY {
                    let mut j = k;
                    while j > 0 && kids[j - 1].0 > e[c] {
                        kids[j] = kids[j - 1];
                        j -= 1;
                    }
                    kids[j] = (e[c], c as u32);
                    k += 1;
                }
            }
            // Leaves now (they shrink t_max); interior children onto the
            // stack farthest first, and down into the nearest.
            let mut down = None;
            for &(entry, c) in kids[..k].iter().rev() {
                let c = c as usize;
                if q.count[c] > 0 {
                    continue;
                }
                if let Some(d) = down {
                    stack.push(d);
                }
                down = Some((q.child[c], entry));
            }
            for &(_, c) in &kids[..k] {
                let c = c as usize;
                if q.count[c] > 0 {
                    for i in q.child[c]..q.child[c] + q.count[c] {
                        leaf(self, i as usize, &pre);
                    }
                }
            }
            if let Some((n, entry)) = down
                && entry <= t_max(()) as f32 * slack
            {
                node = n;
                continue;
            }
            // Pop the next node the ray still enters before t_max.
            loop {
                let Some((n, entry)) = stack.pop() else { return };
                if entry <= t_max(()) as f32 * slack {
                    node = n;
                    break;
                }
            }
        }
    }

    #[inline]
    fn hit_tri(&self, i: usize, ray: &Ray, pre: &Pre, t_max: f64, edges: Edges) -> Option<Hit> {
        intersect(&self.tris[i], self.ids[i], ray, &pre.sh, t_max, edges)
    }
}

/// Which triangles a ray exactly through an edge or vertex hits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Edges {
    /// Every triangle on the edge or vertex (closed triangles): for first
    /// hits, so no ray slips through anywhere, a mesh's rim included.
    Closed,
    /// Exactly one of the triangles sharing an edge or vertex, by the
    /// rasterisers' top-left rule: for counts and parity.
    TopLeft,
}

/// The ray's shear into the frame where it runs along +z (Woop, Benthin
/// and Wald 2013): the axis of the largest direction component becomes z,
/// the other two are swapped when it is negative to keep the winding.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shear {
    kx: usize,
    ky: usize,
    kz: usize,
    s: [f64; 3],
}

impl Shear {
    pub(crate) fn new(d: &V3) -> Option<Shear> {
        if !(d.x.is_finite() && d.y.is_finite() && d.z.is_finite()) || *d == V3::zeros() {
            return None;
        }
        let kz = d.iamax();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Some(Shear {
            kx,
            ky,
            kz,
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
        })
    }
}

/// Watertight ray-triangle test (Woop, Benthin and Wald 2013) in f64. The
/// edge functions of an edge are computed from its two corners alone, in
/// the same order for both triangles sharing it, so their signs agree
/// exactly and no ray passes between two triangles; `edges` decides who
/// owns a ray exactly on an edge or vertex.
#[inline(always)]
pub(crate) fn intersect(tri: &[P3; 3], id: u32, ray: &Ray, sh: &Shear, t_max: f64, edges: Edges) -> Option<Hit> {
    let [a, b, c] = tri;
    let (kx, ky, kz) = (sh.kx, sh.ky, sh.kz);
    let (o, s) = (&ray.origin, &sh.s);
    let ta = [a[kx] - o[kx], a[ky] - o[ky], a[kz] - o[kz]];
    let tb = [b[kx] - o[kx], b[ky] - o[ky], b[kz] - o[kz]];
    let tc = [c[kx] - o[kx], c[ky] - o[ky], c[kz] - o[kz]];
    let (ax, ay) = (ta[0] - s[0] * ta[2], ta[1] - s[1] * ta[2]);
    let (bx, by) = (tb[0] - s[0] * tb[2], tb[1] - s[1] * tb[2]);
    let (cx, cy) = (tc[0] - s[0] * tc[2], tc[1] - s[1] * tc[2]);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    if edges == Edges::TopLeft && (u == 0.0 || v == 0.0 || w == 0.0) {
        // On an edge: only "top-left" edges (after orienting by the
        // triangle's facing) keep the hit, so exactly one of the two
        // triangles sharing the edge does.
        let sg = det.signum();
        let top_left = |dx: f64, dy: f64| {
            let (dx, dy) = (sg * dx, sg * dy);
            dy > 0.0 || (dy == 0.0 && dx > 0.0)
        };
        if (u == 0.0 && !top_left(cx - bx, cy - by))
            || (v == 0.0 && !top_left(ax - cx, ay - cy))
            || (w == 0.0 && !top_left(bx - ax, by - ay))
        {
            return None;
        }
    }
    let t_num = (u * ta[2] + v * tb[2] + w * tc[2]) * s[2];
    let t = t_num / det;
    if !(t >= ray.t_min && t <= t_max) {
        return None;
    }
    Some(Hit {
        t,
        triangle: id,
        u: v / det,
        v: w / det,
        front: (b - a).cross(&(c - a)).dot(&ray.dir) < 0.0,
    })
}

/// Per-ray values for the slab and triangle tests.
struct Pre {
    sh: Shear,
    org: [f32; 3],
    inv: [f32; 3],
    /// Rows of a quad's boxes the ray enters (near) and leaves (far) by,
    /// per axis, from the sign of the direction.
    near: [usize; 3],
    far: [usize; 3],
}

impl Pre {
    fn new(ray: &Ray) -> Option<Pre> {
        let d = ray.dir;
        let sh = Shear::new(&d)?;
        let inv = [(1.0 / d.x) as f32, (1.0 / d.y) as f32, (1.0 / d.z) as f32];
        let org = [ray.origin.x as f32, ray.origin.y as f32, ray.origin.z as f32];
        let near = [0, 1, 2].map(|k| if inv[k].is_sign_negative() { k + 3 } else { k });
        let far = near.map(|r| (r + 3) % 6);
        Some(Pre {
            sh,
            org,
            inv,
            near,
            far,
        })
    }

    /// Entry parameters of the ray into the four child boxes of a quad
    /// within `[t0, t1]`, and which it enters at all.
    #[inline(always)]
    fn slab4(&self, q: &Quad, t0: f32, t1: f32) -> ([f32; 4], [bool; 4]) {
        let mut lo = [t0; 4];
        let mut hi = [t1 * (1.0 + 4.0 * f32::EPSILON); 4];
        for k in 0..3 {
            let (nb, fb) = (&q.b[self.near[k]], &q.b[self.far[k]]);
            let (o, inv) = (self.org[k], self.inv[k]);
            for c in 0..4 {
                let a = (nb[c] - o) * inv;
                let b = (fb[c] - o) * inv;
                // Comparisons, not f32::min/max: a NaN (0 * inf on a box
                // face the ray runs in) falls through, never culls.
                lo[c] = if a > lo[c] { a } else { lo[c] };
                hi[c] = if b < hi[c] { b } else { hi[c] };
            }
        }
        (lo, [lo[0] <= hi[0], lo[1] <= hi[1], lo[2] <= hi[2], lo[3] <= hi[3]])
    }

    /// Entry parameter of the ray into the node box within `[t0, t1]`.
    #[inline(always)]
    fn slab(&self, n: &Node, t0: f32, t1: f32) -> Option<f32> {
        let mut lo = t0;
        let mut hi = t1 * (1.0 + 4.0 * f32::EPSILON);
        for k in 0..3 {
            let a = (n.min[k] - self.org[k]) * self.inv[k];
            let b = (n.max[k] - self.org[k]) * self.inv[k];
            // NaN (0 * inf on a box face) must not cull: min/max ignore it.
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        }
        (lo <= hi).then_some(lo)
    }
}

/// Sort by the high 32 bits (LSD radix, 4 passes of 8 bits; stable, so
/// equal keys keep the order of the low bits' index).
fn radix_sort_high32(v: &mut Vec<u64>) {
    let mut tmp = vec![0u64; v.len()];
    for pass in 0..4 {
        let shift = 32 + 8 * pass;
        let mut count = [0usize; 257];
        for &x in v.iter() {
            count[((x >> shift) & 255) as usize + 1] += 1;
        }
        if count.contains(&v.len()) {
            continue;
        }
        for i in 1..257 {
            count[i] += count[i - 1];
        }
        for &x in v.iter() {
            let b = ((x >> shift) & 255) as usize;
            tmp[count[b]] = x;
            count[b] += 1;
        }
        std::mem::swap(v, &mut tmp);
    }
}

/// A small LIFO of (node, entry parameter) that spills to the heap only
/// for trees deeper than any sensible build makes.
struct Stack {
    fixed: [(u32, f32); 48],
    len: usize,
    spill: Vec<(u32, f32)>,
}

impl Stack {
    #[inline(always)]
    fn new() -> Stack {
        Stack {
            fixed: [(0, 0.0); 48],
            len: 0,
            spill: Vec::new(),
        }
    }
    #[inline(always)]
    fn push(&mut self, x: (u32, f32)) {
        if self.len < self.fixed.len() {
            self.fixed[self.len] = x;
            self.len += 1;
        } else {
            self.spill.push(x);
        }
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if let Some(x) = self.spill.pop() {
            return Some(x);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.fixed[self.len])
    }
}

/// The 4-wide traversal tree of a depth-first binary node list whose root
/// is interior: each quad takes up to four descendants of a binary node,
/// opening the child with the largest box first.
fn quads_of(nodes: &[Node]) -> Vec<Quad> {
    let mut out = Vec::new();
    if nodes.first().is_none_or(|r| r.n > 0) {
        return out;
    }
    let area = |n: &Node| {
        let d = [0, 1, 2].map(|k| (n.max[k] - n.min[k]).max(0.0));
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    };
    out.push(Quad::NONE);
    let mut todo = vec![(0usize, 0usize)];
    while let Some((bn, qi)) = todo.pop() {
        let mut kids = [bn + 1, nodes[bn].a as usize, 0, 0];
        let mut k = 2;
        while k < 4 {
            let open = (0..k)
                .filter(|&i| nodes[kids[i]].n == 0)
                .max_by(|&i, &j| area(&nodes[kids[i]]).total_cmp(&area(&nodes[kids[j]])));
            let Some(i) = open else { break };
            let b = kids[i];
            kids[i] = b + 1;
            kids[k] = nodes[b].a as usize;
            k += 1;
        }
        let mut q = Quad::NONE;
        for (c, &j) in kids[..k].iter().enumerate() {
            let ch = &nodes[j];
            for ax in 0..3 {
                q.b[ax][c] = ch.min[ax];
                q.b[ax + 3][c] = ch.max[ax];
            }
            if ch.n > 0 {
                q.child[c] = ch.a;
                q.count[c] = ch.n;
            } else {
                q.child[c] = out.len() as u32;
                q.count[c] = 0;
                out.push(Quad::NONE);
                todo.push((j, q.child[c] as usize));
            }
        }
        out[qi] = q;
    }
    out
}

fn box_d2(n: &Node, p: &P3) -> f64 {
    let mut d2 = 0.0;
    for k in 0..3 {
        let v = p[k];
        let lo = n.min[k] as f64;
        let hi = n.max[k] as f64;
        let e = if v < lo {
            lo - v
        } else if v > hi {
            v - hi
        } else {
            0.0
        };
        d2 += e * e;
    }
    d2
}

/// The point of triangle abc nearest p (Ericson, Real-Time Collision
/// Detection, 5.1.5), by Voronoi regions; exact for degenerate triangles.
pub fn closest_on_triangle(p: &P3, a: &P3, b: &P3, c: &P3) -> P3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return a + ab * v;
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return a + ac * w;
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return b + (c - b) * w;
    }
    let denom = va + vb + vc;
    if denom == 0.0 || !denom.is_finite() {
        // Degenerate (collinear corners): nearest of the three edges.
        let segs = [(a, b), (b, c), (c, a)];
        return segs
            .iter()
            .map(|(s, e)| {
                let d = *e - *s;
                let l2 = d.norm_squared();
                let t = if l2 > 0.0 {
                    ((p - *s).dot(&d) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                *s + d * t
            })
            .min_by(|x, y| (x - p).norm_squared().total_cmp(&(y - p).norm_squared()))
            .unwrap_or(*a);
    }
    let v = vb / denom;
    let w = vc / denom;
    a + ab * v + ac * w
}

fn to_node(b: &Aabb, pad: f64) -> Node {
    let lo = |x: f64| {
        let f = (x - pad) as f32;
        if (f as f64) > x - pad { f.next_down() } else { f }
    };
    let hi = |x: f64| {
        let f = (x + pad) as f32;
        if (f as f64) < x + pad { f.next_up() } else { f }
    };
    Node {
        min: [lo(b.min[0] as f64), lo(b.min[1] as f64), lo(b.min[2] as f64)],
        a: 0,
        max: [hi(b.max[0] as f64), hi(b.max[1] as f64), hi(b.max[2] as f64)],
        n: 0,
    }
}

/// Box and centroid box of `ids` (in parallel for big slices: unions,
/// the same result in any order).
fn bounds(ids: &[Prim]) -> (Aabb, Aabb) {
    let one = |c: &[Prim]| {
        let (mut bb, mut cb) = (Aabb::EMPTY, Aabb::EMPTY);
        for q in c {
            bb.grow(&q.b);
            cb.grow_p(&q.c);
        }
        (bb, cb)
    };
    if ids.len() < PAR_MIN {
        return one(ids);
    }
    ids.par_chunks(PAR_MIN / 4).map(one).reduce(
        || (Aabb::EMPTY, Aabb::EMPTY),
        |(mut a, mut b), (c, d)| {
            a.grow(&c);
            b.grow(&d);
            (a, b)
        },
    )
}

/// Build the subtree over `ids` (which start at `offset` in the full id
/// list; `bb` and `cb` their box and centroid box), appending nodes to
/// `out` depth-first; returns its root index.
fn build(ids: &mut [Prim], offset: usize, out: &mut Vec<Node>, pad: f64, bb: Aabb, cb: Aabb) -> u32 {
    let me = out.len() as u32;
    out.push(to_node(&bb, pad));
    let n = ids.len();
    let split = if n <= 2 { None } else { best_split(ids, &bb, &cb) };
    let (mid, kids) = match split {
        Some((sp, kids)) => (partition(ids, |q| sp.left(q)), Some(kids)),
        None if n > MAX_LEAF => {
            // No useful SAH split (identical centroids, or a leaf would be
            // cheaper but too big): split at the median of the longest axis.
            let axis = (0..3)
                .max_by(|&a, &b| (cb.max[a] - cb.min[a]).total_cmp(&(cb.max[b] - cb.min[b])))
                .unwrap_or(0);
            ids.select_nth_unstable_by(n / 2, |x, y| x.c[axis].total_cmp(&y.c[axis]));
            (n / 2, None)
        }
        None => (0, None),
    };
    if mid == 0 || mid == n {
        if n > MAX_LEAF {
            // Degenerate partition (all on one side): halve by position.
            return finish_split(ids, offset, out, pad, me, n / 2, None);
        }
        let nd = &mut out[me as usize];
        nd.a = offset as u32;
        nd.n = n as u32;
        return me;
    }
    finish_split(ids, offset, out, pad, me, mid, kids)
}

/// Bounds of the two sides of a split: (box, centroid box) left, right.
type Sides = [(Aabb, Aabb); 2];

fn finish_split(
    ids: &mut [Prim],
    offset: usize,
    out: &mut Vec<Node>,
    pad: f64,
    me: u32,
    mid: usize,
    kids: Option<Sides>,
) -> u32 {
    let (l, r) = ids.split_at_mut(mid);
    let [(lb, lc), (rb, rc)] = kids.unwrap_or_else(|| [bounds(l), bounds(r)]);
    if l.len() + r.len() >= PAR_MIN {
        let (mut lv, mut rv) = (Vec::new(), Vec::new());
        rayon::join(
            || build(l, offset, &mut lv, pad, lb, lc),
            || build(r, offset + mid, &mut rv, pad, rb, rc),
        );
        let lbase = out.len() as u32;
        out.extend(lv.into_iter().map(|mut n| {
            if n.n == 0 {
                n.a += lbase;
            }
            n
        }));
        let rbase = out.len() as u32;
        out.extend(rv.into_iter().map(|mut n| {
            if n.n == 0 {
                n.a += rbase;
            }
            n
        }));
        out[me as usize].a = rbase;
    } else {
        build(l, offset, out, pad, lb, lc);
        let rr = build(r, offset + mid, out, pad, rb, rc);
        out[me as usize].a = rr;
    }
    me
}

/// A binned split: primitives whose centroid falls in bins `0..=last`
/// of `axis` go left (the same bin function as the binning, so the
/// partition matches the counts the cost was computed from).
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    lo: f32,
    k: f32,
    last: usize,
}

impl Split {
    #[inline(always)]
    fn bin(axis: usize, lo: f32, k: f32, q: &Prim) -> usize {
        // Through i32 (one conversion instruction; the clamp catches
        // anything out of range).
        (((q.c[axis] - lo) * k) as i32).clamp(0, BINS as i32 - 1) as usize
    }
    #[inline(always)]
    fn left(&self, q: &Prim) -> bool {
        Split::bin(self.axis, self.lo, self.k, q) <= self.last
    }
}

/// Per bin: box, centroid box, count.
type Bins = [(Aabb, Aabb, u32); BINS];

fn bin_prims(ids: &[Prim], axis: usize, lo: f32, k: f32) -> Bins {
    let mut bins = [(Aabb::EMPTY, Aabb::EMPTY, 0u32); BINS];
    for q in ids {
        let b = Split::bin(axis, lo, k, q);
        bins[b].0.grow(&q.b);
        bins[b].1.grow_p(&q.c);
        bins[b].2 += 1;
    }
    bins
}

/// Binned SAH over all three axes: the cheapest split and the bounds of
/// its two sides, or None when keeping a leaf is cheaper (and allowed).
fn best_split(ids: &[Prim], bb: &Aabb, cb: &Aabb) -> Option<(Split, Sides)> {
    let n = ids.len();
    let mut best = (f64::INFINITY, None);
    let mut best_bins = [(Aabb::EMPTY, Aabb::EMPTY, 0u32); BINS];
    // Nodes above 256 triangles: the longest centroid axis only (a third
    // of the binning work where most of the build time goes; the SAH
    // rarely prefers another axis there).
    let longest = (0..3)
        .max_by(|&a, &b| (cb.max[a] - cb.min[a]).total_cmp(&(cb.max[b] - cb.min[b])))
        .unwrap_or(0);
    for axis in 0..3 {
        if n > 256 && axis != longest {
            continue;
        }
        let lo = cb.min[axis];
        let ext = cb.max[axis] - lo;
        if ext.is_nan() || ext <= 0.0 {
            continue;
        }
        let k = BINS as f32 / ext;
        if !k.is_finite() {
            continue;
        }
        let bins = if n >= PAR_MIN {
            // Box unions and counts: the same result in any order.
            ids.par_chunks(PAR_MIN / 4).map(|c| bin_prims(c, axis, lo, k)).reduce(
                || [(Aabb::EMPTY, Aabb::EMPTY, 0u32); BINS],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        x.0.grow(&y.0);
                        x.1.grow(&y.1);
                        x.2 += y.2;
                    }
                    a
                },
            )
        } else {
            bin_prims(ids, axis, lo, k)
        };
        // Sweep from the right, then from the left.
        let mut right = [0.0f64; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0u32;
        for j in (1..BINS).rev() {
            acc.grow(&bins[j].0);
            cnt += bins[j].2;
            right[j] = acc.half_area() * cnt as f64;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0u32;
        let mut improved = false;
        for j in 0..BINS - 1 {
            acc.grow(&bins[j].0);
            cnt += bins[j].2;
            let cost = acc.half_area() * cnt as f64 + right[j + 1];
            if cnt > 0 && (cnt as usize) < n && cost < best.0 {
                best = (cost, Some(Split { axis, lo, k, last: j }));
                improved = true;
            }
        }
        if improved {
            best_bins = bins;
        }
    }
    let (cost, split) = best;
    let split = split?;
    // Cost model: traversal 1, triangle test 1 per triangle.
    let leaf_cost = n as f64;
    let split_cost = 1.0 + cost / bb.half_area().max(f64::MIN_POSITIVE);
    if n <= MAX_LEAF && leaf_cost <= split_cost {
        return None;
    }
    let mut sides = [(Aabb::EMPTY, Aabb::EMPTY); 2];
    for (j, b) in best_bins.iter().enumerate() {
        let side = &mut sides[(j > split.last) as usize];
        side.0.grow(&b.0);
        side.1.grow(&b.1);
    }
    Some((split, sides))
}

fn partition(ids: &mut [Prim], left: impl Fn(&Prim) -> bool) -> usize {
    let mut i = 0;
    for j in 0..ids.len() {
        if left(&ids[j]) {
            ids.swap(i, j);
            i += 1;
        }
    }
    i
}

#[cfg(test)]
#[path = "bvh_tests.rs"]
pub(crate) mod tests;
