//! A bounding-volume hierarchy over a mesh's triangles, with ray queries
//! (first hit, every hit, hit count, inside test) and nearest-point
//! queries, one at a time or in parallel batches (rayon).
//!
//! Built here rather than taken from a crate (`bvh`, `obvhs`, `parry3d`):
//! see docs/mesh.md for the reasons and figures. In short:
//!
//! - **Build**: binned surface-area heuristic (12 bins on each axis), leaves
//!   of up to 4 triangles, the top levels built in parallel. Nodes are
//!   flattened depth-first, 32 bytes each (an f32 box, rounded outward and
//!   padded, plus two u32), so the left child is always the next node.
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

/// The hierarchy, owning a copy of the triangles in leaf order.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<[P3; 3]>,
    ids: Vec<u32>,
}

const BINS: usize = 12;
const MAX_LEAF: usize = 4;
const PAR_MIN: usize = 1 << 15;

#[derive(Clone, Copy)]
struct Aabb {
    min: [f64; 3],
    max: [f64; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
    };
    fn grow(&mut self, o: &Aabb) {
        for k in 0..3 {
            self.min[k] = self.min[k].min(o.min[k]);
            self.max[k] = self.max[k].max(o.max[k]);
        }
    }
    fn grow_p(&mut self, p: &[f64; 3]) {
        for k in 0..3 {
            self.min[k] = self.min[k].min(p[k]);
            self.max[k] = self.max[k].max(p[k]);
        }
    }
    fn half_area(&self) -> f64 {
        let d = [self.max[0] - self.min[0], self.max[1] - self.min[1], self.max[2] - self.min[2]];
        if d[0] < 0.0 {
            return 0.0;
        }
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

struct Prims {
    boxes: Vec<Aabb>,
    cent: Vec<[f64; 3]>,
}

impl Bvh {
    /// Build over every triangle of `mesh` (degenerate ones included: they
    /// are never hit by rays but take part in nearest-point queries).
    pub fn new(mesh: &Mesh) -> Bvh {
        let n = mesh.triangles.len();
        let corners: Vec<[P3; 3]> = mesh
            .triangles
            .iter()
            .map(|t| [mesh.vertices[t[0] as usize], mesh.vertices[t[1] as usize], mesh.vertices[t[2] as usize]])
            .collect();
        let (boxes, cent): (Vec<Aabb>, Vec<[f64; 3]>) = corners
            .par_iter()
            .with_min_len(4096)
            .map(|c| {
                let mut b = Aabb::EMPTY;
                for p in c {
                    b.grow_p(&[p.x, p.y, p.z]);
                }
                let m = [
                    0.5 * (b.min[0] + b.max[0]),
                    0.5 * (b.min[1] + b.max[1]),
                    0.5 * (b.min[2] + b.max[2]),
                ];
                (b, m)
            })
            .unzip();
        let prims = Prims { boxes, cent };
        let mut all = Aabb::EMPTY;
        for b in &prims.boxes {
            all.grow(b);
        }
        // Absolute padding of every box: covers the f32 rounding of ray
        // origins and slab parameters for rays starting within a few scene
        // sizes of the mesh.
        let scale = (0..3).map(|k| all.max[k].abs().max(all.min[k].abs())).fold(0.0, f64::max);
        let pad = scale * 1e-6 + 1e-12;
        let mut ids: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / MAX_LEAF + 1);
        if n > 0 {
            build(&prims, &mut ids, 0, &mut nodes, pad);
        }
        let tris = ids.iter().map(|&i| corners[i as usize]).collect();
        Bvh { nodes, tris, ids }
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

    /// The nearest hit along the ray, if any.
    pub fn first_hit(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let t_max = std::cell::Cell::new(ray.t_max);
        self.traverse(ray, |_| t_max.get(), |bvh, i, pre| {
            if let Some(h) = bvh.hit_tri(i, ray, pre, t_max.get()) {
                t_max.set(h.t);
                best = Some(h);
            }
        });
        best
    }

    /// Every hit along the ray, sorted by `t` (then triangle index). A ray
    /// through a shared edge or vertex of a consistently oriented mesh
    /// counts it once.
    pub fn all_hits(&self, ray: &Ray) -> Vec<Hit> {
        let mut out = Vec::new();
        self.traverse(ray, |_| ray.t_max, |bvh, i, pre| {
            if let Some(h) = bvh.hit_tri(i, ray, pre, ray.t_max) {
                out.push(h);
            }
        });
        out.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.triangle.cmp(&b.triangle)));
        out
    }

    /// How many triangles the ray crosses.
    pub fn count_hits(&self, ray: &Ray) -> usize {
        let mut n = 0;
        self.traverse(ray, |_| ray.t_max, |bvh, i, pre| {
            n += bvh.hit_tri(i, ray, pre, ray.t_max).is_some() as usize;
        });
        n
    }

    /// Is `p` inside a closed mesh? Parity of the crossings of a ray in a
    /// fixed oblique direction (no axis-aligned faces lie along it).
    pub fn contains(&self, p: &P3) -> bool {
        let d = V3::new(0.577_350_269_189_625_8, 0.577_350_269_189_625_7 * 1.000_123, 0.577_350_269_189_626 * 0.999_871);
        self.count_hits(&Ray::new(*p, d)) % 2 == 1
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
        self.traverse(ray, |_| {
            nodes.set(nodes.get() + 1);
            t_max.get()
        }, |bvh, i, pre| {
            tris.set(tris.get() + 1);
            if let Some(h) = bvh.hit_tri(i, ray, pre, t_max.get()) {
                t_max.set(h.t);
            }
        });
        (nodes.get(), tris.get())
    }

    /// [`Bvh::first_hit`] for many rays, in parallel.
    pub fn first_hits(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        rays.par_iter().with_min_len(256).map(|r| self.first_hit(r)).collect()
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
    /// current `t_max` (asked again at each box, so first-hit queries
    /// shrink it), nearer child first.
    #[inline]
    fn traverse(&self, ray: &Ray, mut t_max: impl FnMut(()) -> f64, mut leaf: impl FnMut(&Bvh, usize, &Pre)) {
        if self.nodes.is_empty() {
            return;
        }
        let Some(pre) = Pre::new(ray) else { return };
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0u32;
        let root = &self.nodes[0];
        if pre.slab(root, ray.t_min as f32, t_max(()) as f32).is_none() {
            return;
        }
        loop {
            let nd = &self.nodes[node as usize];
            if nd.n > 0 {
                for i in nd.a..nd.a + nd.n {
                    leaf(self, i as usize, &pre);
                }
            } else {
                let tm = t_max(()) as f32;
                let l = node + 1;
                let r = nd.a;
                let hl = pre.slab(&self.nodes[l as usize], ray.t_min as f32, tm);
                let hr = pre.slab(&self.nodes[r as usize], ray.t_min as f32, tm);
                match (hl, hr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        if sp < stack.len() {
                            stack[sp] = far;
                            sp += 1;
                        }
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            node = stack[sp];
        }
    }

    /// Watertight ray-triangle test (Woop, Benthin and Wald 2013) with the
    /// top-left tie rule for rays exactly through an edge or vertex.
    #[inline]
    fn hit_tri(&self, i: usize, ray: &Ray, pre: &Pre, t_max: f64) -> Option<Hit> {
        let [a, b, c] = &self.tris[i];
        let (kx, ky, kz) = (pre.kx, pre.ky, pre.kz);
        let (o, s) = (&ray.origin, &pre.s);
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
        if u == 0.0 || v == 0.0 || w == 0.0 {
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
            triangle: self.ids[i],
            u: v / det,
            v: w / det,
            front: (b - a).cross(&(c - a)).dot(&ray.dir) < 0.0,
        })
    }
}

/// Per-ray values for the slab and triangle tests.
struct Pre {
    kx: usize,
    ky: usize,
    kz: usize,
    s: [f64; 3],
    org: [f32; 3],
    inv: [f32; 3],
}

impl Pre {
    fn new(ray: &Ray) -> Option<Pre> {
        let d = ray.dir;
        if !(d.x.is_finite() && d.y.is_finite() && d.z.is_finite()) || d == V3::zeros() {
            return None;
        }
        let kz = d.iamax();
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let s = [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]];
        let inv = [(1.0 / d.x) as f32, (1.0 / d.y) as f32, (1.0 / d.z) as f32];
        let org = [ray.origin.x as f32, ray.origin.y as f32, ray.origin.z as f32];
        Some(Pre {
            kx,
            ky,
            kz,
            s,
            org,
            inv,
        })
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

fn box_d2(n: &Node, p: &P3) -> f64 {
    let mut d2 = 0.0;
    for k in 0..3 {
        let v = p[k];
        let lo = n.min[k] as f64;
        let hi = n.max[k] as f64;
        let e = if v < lo { lo - v } else if v > hi { v - hi } else { 0.0 };
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
    if !(denom.abs() > 0.0) || !denom.is_finite() {
        // Degenerate (collinear corners): nearest of the three edges.
        let segs = [(a, b), (b, c), (c, a)];
        return segs
            .iter()
            .map(|(s, e)| {
                let d = *e - *s;
                let l2 = d.norm_squared();
                let t = if l2 > 0.0 { ((p - *s).dot(&d) / l2).clamp(0.0, 1.0) } else { 0.0 };
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
        min: [lo(b.min[0]), lo(b.min[1]), lo(b.min[2])],
        a: 0,
        max: [hi(b.max[0]), hi(b.max[1]), hi(b.max[2])],
        n: 0,
    }
}

/// Build the subtree over `ids` (which start at `offset` in the full id
/// list), appending nodes to `out` depth-first; returns its root index.
fn build(p: &Prims, ids: &mut [u32], offset: usize, out: &mut Vec<Node>, pad: f64) -> u32 {
    let mut bb = Aabb::EMPTY;
    let mut cb = Aabb::EMPTY;
    for &i in ids.iter() {
        bb.grow(&p.boxes[i as usize]);
        cb.grow_p(&p.cent[i as usize]);
    }
    let me = out.len() as u32;
    out.push(to_node(&bb, pad));
    let n = ids.len();
    let split = if n <= 2 { None } else { best_split(p, ids, &bb, &cb) };
    let mid = match split {
        Some((axis, pos)) => partition(ids, |i| p.cent[i as usize][axis] < pos),
        None if n > MAX_LEAF => {
            // No useful SAH split (identical centroids, or a leaf would be
            // cheaper but too big): split at the median of the longest axis.
            let axis = (0..3)
                .max_by(|&a, &b| (cb.max[a] - cb.min[a]).total_cmp(&(cb.max[b] - cb.min[b])))
                .unwrap_or(0);
            ids.select_nth_unstable_by(n / 2, |&x, &y| p.cent[x as usize][axis].total_cmp(&p.cent[y as usize][axis]));
            n / 2
        }
        None => 0,
    };
    if mid == 0 || mid == n {
        if n > MAX_LEAF {
            // Degenerate partition (all on one side): halve by position.
            return finish_split(p, ids, offset, out, pad, me, n / 2);
        }
        let nd = &mut out[me as usize];
        nd.a = offset as u32;
        nd.n = n as u32;
        return me;
    }
    finish_split(p, ids, offset, out, pad, me, mid)
}

fn finish_split(p: &Prims, ids: &mut [u32], offset: usize, out: &mut Vec<Node>, pad: f64, me: u32, mid: usize) -> u32 {
    let (l, r) = ids.split_at_mut(mid);
    if l.len() + r.len() >= PAR_MIN {
        let (mut lv, mut rv) = (Vec::new(), Vec::new());
        rayon::join(|| build(p, l, offset, &mut lv, pad), || build(p, r, offset + mid, &mut rv, pad));
        let lb = out.len() as u32;
        out.extend(lv.into_iter().map(|mut n| {
            if n.n == 0 {
                n.a += lb;
            }
            n
        }));
        let rb = out.len() as u32;
        out.extend(rv.into_iter().map(|mut n| {
            if n.n == 0 {
                n.a += rb;
            }
            n
        }));
        out[me as usize].a = rb;
    } else {
        build(p, l, offset, out, pad);
        let rr = build(p, r, offset + mid, out, pad);
        out[me as usize].a = rr;
    }
    me
}

/// Binned SAH over all three axes: `(axis, position)` of the cheapest
/// split, or None when keeping a leaf is cheaper (and allowed).
fn best_split(p: &Prims, ids: &[u32], bb: &Aabb, cb: &Aabb) -> Option<(usize, f64)> {
    let n = ids.len();
    let mut best = (f64::INFINITY, 0usize, 0.0f64);
    for axis in 0..3 {
        let lo = cb.min[axis];
        let ext = cb.max[axis] - lo;
        if !(ext > 0.0) {
            continue;
        }
        let k = BINS as f64 / ext;
        let mut bins = [(Aabb::EMPTY, 0u32); BINS];
        for &i in ids {
            let b = (((p.cent[i as usize][axis] - lo) * k) as usize).min(BINS - 1);
            bins[b].0.grow(&p.boxes[i as usize]);
            bins[b].1 += 1;
        }
        // Sweep from the right, then from the left.
        let mut right = [0.0f64; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0u32;
        for j in (1..BINS).rev() {
            acc.grow(&bins[j].0);
            cnt += bins[j].1;
            right[j] = acc.half_area() * cnt as f64;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0u32;
        for j in 0..BINS - 1 {
            acc.grow(&bins[j].0);
            cnt += bins[j].1;
            let cost = acc.half_area() * cnt as f64 + right[j + 1];
            if cnt > 0 && (cnt as usize) < n && cost < best.0 {
                best = (cost, axis, lo + (j + 1) as f64 / k);
            }
        }
    }
    if !best.0.is_finite() {
        return None;
    }
    // Cost model: traversal 1, triangle test 1 per triangle.
    let leaf_cost = n as f64;
    let split_cost = 1.0 + best.0 / bb.half_area().max(f64::MIN_POSITIVE);
    if n <= MAX_LEAF && leaf_cost <= split_cost {
        return None;
    }
    Some((best.1, best.2))
}

fn partition(ids: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let mut i = 0;
    for j in 0..ids.len() {
        if left(ids[j]) {
            ids.swap(i, j);
            i += 1;
        }
    }
    i
}

#[cfg(test)]
#[path = "bvh_tests.rs"]
mod tests;
