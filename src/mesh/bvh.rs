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

use crate::geometry::{BBox3, P3, V3};

#[path = "bvh_build.rs"]
mod build;
#[path = "triangle.rs"]
mod triangle;
pub use triangle::closest_on_triangle;
pub(crate) use triangle::{Edges, Shear, intersect};

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
    /// Child: quad index (interior) or first triangle (leaf).
    child: [u32; 4],
    /// A leaf child's triangle count (at most `MAX_LEAF`); 0 otherwise.
    count: [u8; 4],
    /// Bit c set when child c is a leaf.
    leaves: u8,
    /// Bit c set when child c is an interior quad (neither bit: an unused
    /// slot). Kept here, not derived from the counts: the walk reads them
    /// at every quad, and deriving them took 40-odd instructions there.
    inner: u8,
}

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
        count: [0; 4],
        leaves: 0,
        inner: 0,
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

impl Bvh {
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
            |bvh, leaf, pre| {
                for i in leaf {
                    if let Some(h) = bvh.hit_tri(i, ray, pre, t_max.get(), Edges::Closed)
                        && best.is_none_or(|b| h.t < b.t || (h.t == b.t && h.triangle < b.triangle))
                    {
                        t_max.set(h.t);
                        best = Some(h);
                    }
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
            |bvh, leaf, pre| {
                for i in leaf {
                    if let Some(h) = bvh.hit_tri(i, ray, pre, ray.t_max, Edges::TopLeft) {
                        out.push(h);
                    }
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
            |bvh, leaf, pre| {
                for i in leaf {
                    n += bvh.hit_tri(i, ray, pre, ray.t_max, Edges::TopLeft).is_some() as usize;
                }
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

    /// Visit every triangle that may come within `r` of the segment
    /// `p0`–`p1` (its index in the mesh and its corners): those in leaves
    /// whose box, grown by `r` on every side, the segment crosses. A
    /// superset of the triangles within `r` (the grown box holds the
    /// rounded one), each visited once; the caller tests them exactly.
    /// For a tool's swept body (the 5-axis gouge check): a capsule query
    /// on the 3-D tree, where a grid over the XY plane would list every
    /// triangle under a steep tool's whole shadow.
    pub fn for_each_near_segment(&self, p0: P3, p1: P3, r: f64, mut f: impl FnMut(u32, &[P3; 3])) {
        self.try_for_each_near_segment(p0, p1, r, |i, t| {
            f(i, t);
            std::ops::ControlFlow::Continue(())
        });
    }

    /// [`Bvh::for_each_near_segment`], stopping at the first triangle for
    /// which `f` breaks (a yes-or-no query that has its answer).
    pub fn try_for_each_near_segment(
        &self,
        p0: P3,
        p1: P3,
        r: f64,
        mut f: impl FnMut(u32, &[P3; 3]) -> std::ops::ControlFlow<()>,
    ) {
        if self.nodes.is_empty() || r.is_nan() || r < 0.0 {
            return;
        }
        let d = p1 - p0;
        let meets = |n: &Node| {
            let b = BBox3 {
                min: P3::new(n.min[0] as f64, n.min[1] as f64, n.min[2] as f64),
                max: P3::new(n.max[0] as f64, n.max[1] as f64, n.max[2] as f64),
            };
            b.clip_line(&p0, &d, (0.0, 1.0), r).is_some()
        };
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        let mut node = 0u32;
        loop {
            let nd = &self.nodes[node as usize];
            if meets(nd) {
                if nd.n > 0 {
                    for i in nd.a..nd.a + nd.n {
                        if f(self.ids[i as usize], &self.tris[i as usize]).is_break() {
                            return;
                        }
                    }
                } else {
                    stack.push(nd.a);
                    node += 1;
                    continue;
                }
            }
            match stack.pop() {
                Some(n) => node = n,
                None => return,
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
            |box_test| {
                nodes.set(nodes.get() + box_test as usize);
                t_max.get()
            },
            |bvh, leaf, pre| {
                for i in leaf {
                    tris.set(tris.get() + 1);
                    if let Some(h) = bvh.hit_tri(i, ray, pre, t_max.get(), Edges::Closed) {
                        t_max.set(h.t);
                    }
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
        crate::progress::lap("before the rays");
        let order = self.ray_order(rays);
        crate::progress::lap("rays: order");
        // The rays gathered into their cast order a block at a time first:
        // read in a tight loop, their cache misses overlap one another,
        // where read at the start of each walk they stall it; a block (128
        // KB) stays in cache and its buffer is reused, where one copy of
        // all the rays would cost a page fault every 64 of them.
        const BLOCK: usize = 2048;
        let sorted: Vec<Option<Hit>> = order
            .par_chunks(BLOCK)
            .map_init(
                || Vec::with_capacity(BLOCK),
                |buf: &mut Vec<Ray>, block| {
                    buf.clear();
                    buf.extend(block.iter().map(|&i| rays[i as usize]));
                    buf.iter().map(|r| self.first_hit(r)).collect::<Vec<_>>()
                },
            )
            .flatten_iter()
            .collect();
        crate::progress::lap("rays: gather and cast");
        let mut rank = vec![0u32; rays.len()];
        for (p, &i) in order.iter().enumerate() {
            rank[i as usize] = p as u32;
        }
        let answers = rank
            .par_iter()
            .with_min_len(4096)
            .map(|&p| sorted[p as usize])
            .collect();
        crate::progress::lap("rays: answers in order");
        answers
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
                    // Bit b of component k lands at 6 b + 5 - k: the six
                    // components interleaved, most significant bits first.
                    c.iter()
                        .enumerate()
                        .fold(0u32, |m, (k, &ck)| m | SPREAD6[ck as usize] << (5 - k))
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
    /// shrink it; with `true` when asked for a quad's box test, so a
    /// benchmark can count them), nearer child first.
    #[inline]
    fn traverse(
        &self,
        ray: &Ray,
        mut t_max: impl FnMut(bool) -> f64,
        mut leaf: impl FnMut(&Bvh, std::ops::Range<usize>, &Pre),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let Some(pre) = Pre::new(ray) else { return };
        let t0 = ray.t_min as f32;
        let root = &self.nodes[0];
        if pre.slab(root, t0, t_max(false) as f32).is_none() {
            return;
        }
        if root.n > 0 {
            leaf(self, root.a as usize..(root.a + root.n) as usize, &pre);
            return;
        }
        let mut stack = Stack::new();
        let mut node = 0u32;
        let slack = 1.0 + 4.0 * f32::EPSILON;
        loop {
            let q = &self.quads[node as usize];
            let (e, entered) = pre.slab4(q, t0, t_max(true) as f32);
            // Bit c set: the ray enters child c. Leaves are tested at once
            // (they shrink t_max); interior children go down nearest first.
            let mut inner = entered & q.inner as u32;
            let mut leaves = entered & q.leaves as u32;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                leaf(
                    self,
                    q.child[c] as usize..q.child[c] as usize + q.count[c] as usize,
                    &pre,
                );
            }
            let limit = t_max(false) as f32 * slack;
            // The common cases without a sort: one child entered, or two.
            let next = match inner.count_ones() {
                0 => None,
                1 => {
                    let c = inner.trailing_zeros() as usize;
                    (e[c] <= limit).then_some(q.child[c])
                }
                2 => {
                    let c0 = inner.trailing_zeros() as usize;
                    let c1 = (inner & (inner - 1)).trailing_zeros() as usize;
                    let (near, far) = if e[c1] < e[c0] { (c1, c0) } else { (c0, c1) };
                    if e[far] <= limit {
                        stack.push((q.child[far], e[far]));
                    }
                    (e[near] <= limit).then_some(q.child[near])
                }
                _ => {
                    // Three or four: farthest pushed first, nearest taken.
                    let mut kids = [(0f32, 0u32); 4];
                    let mut k = 0;
                    while inner != 0 {
                        let c = inner.trailing_zeros() as usize;
                        inner &= inner - 1;
                        let mut j = k;
                        while j > 0 && kids[j - 1].0 < e[c] {
                            kids[j] = kids[j - 1];
                            j -= 1;
                        }
                        kids[j] = (e[c], q.child[c]);
                        k += 1;
                    }
                    for &(entry, n) in &kids[..k - 1] {
                        if entry <= limit {
                            stack.push((n, entry));
                        }
                    }
                    (kids[k - 1].0 <= limit).then_some(kids[k - 1].1)
                }
            };
            if let Some(n) = next {
                node = n;
                continue;
            }
            // Pop the next node the ray still enters before t_max.
            loop {
                let Some((n, entry)) = stack.pop() else { return };
                if entry <= t_max(false) as f32 * slack {
                    node = n;
                    break;
                }
            }
        }
    }

    #[inline(always)]
    fn hit_tri(&self, i: usize, ray: &Ray, pre: &Pre, t_max: f64, edges: Edges) -> Option<Hit> {
        intersect(&self.tris[i], self.ids[i], ray, &pre.sh, t_max, edges)
    }
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
    /// within `[t0, t1]`, and which it enters at all (bit c for child c).
    #[inline(always)]
    fn slab4(&self, q: &Quad, t0: f32, t1: f32) -> ([f32; 4], u32) {
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
        let mask = (lo[0] <= hi[0]) as u32
            | ((lo[1] <= hi[1]) as u32) << 1
            | ((lo[2] <= hi[2]) as u32) << 2
            | ((lo[3] <= hi[3]) as u32) << 3;
        (lo, mask)
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

/// The five bits of a Morton component spread six apart (bit b at 6 b).
const SPREAD6: [u32; 32] = {
    let mut t = [0u32; 32];
    let mut x = 0;
    while x < 32 {
        let mut b = 0;
        while b < 5 {
            t[x] |= ((x as u32 >> b) & 1) << (6 * b);
            b += 1;
        }
        x += 1;
    }
    t
};

/// Sort by the high 32 bits (LSD radix, 4 passes of 8 bits; stable, so
/// equal keys keep the order of the low bits' index). The counts of all
/// four passes are taken in one read of the keys.
fn radix_sort_high32(v: &mut Vec<u64>) {
    let mut count = [[0usize; 257]; 4];
    for &x in v.iter() {
        for (pass, c) in count.iter_mut().enumerate() {
            c[((x >> (32 + 8 * pass)) & 255) as usize + 1] += 1;
        }
    }
    let mut tmp = vec![0u64; v.len()];
    for (pass, count) in count.iter_mut().enumerate() {
        if count.contains(&v.len()) {
            continue;
        }
        let shift = 32 + 8 * pass;
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

#[cfg(test)]
#[path = "bvh_tests.rs"]
pub(crate) mod tests;
