//! Building the hierarchy: a binned surface-area heuristic over the
//! triangles' f32 boxes (an exact sweep for nodes of a few triangles),
//! the top levels in parallel, the binary nodes flattened depth-first and then collapsed into the 4-wide quads that
//! rays traverse (the design and its figures: the module doc of
//! [`super`] and docs/mesh.md).

use rayon::prelude::*;

use super::{Bvh, Node, Quad};
use crate::mesh::Mesh;

const BINS: usize = 12;
pub(super) const MAX_LEAF: usize = 4;
pub(super) const PAR_MIN: usize = 1 << 15;

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
        crate::progress::lap("before the bvh");
        // Corners straight from the mesh, here and for the tree's own copy
        // below: an array of every triangle's corners in file order (72
        // bytes a triangle) lived through the whole build, 71 MB of the
        // peak on a 1 M-triangle STL (examples/mesh_bench: 438 -> 368 MB
        // peak RSS, time unchanged within the noise).
        let corners = |t: &[u32; 3]| {
            [
                mesh.vertices[t[0] as usize],
                mesh.vertices[t[1] as usize],
                mesh.vertices[t[2] as usize],
            ]
        };
        let mut prims: Vec<Prim> = mesh
            .triangles
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(i, t)| {
                let c = corners(t);
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for p in &c {
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
        crate::progress::lap("bvh: prims");
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
        let nodes = if n > 0 {
            join_runs(build_runs(&mut prims, 0, pad, all, call))
        } else {
            Vec::new()
        };
        crate::progress::lap("bvh: tree");
        let ids: Vec<u32> = prims.iter().map(|p| p.id()).collect();
        let tris = ids
            .par_iter()
            .with_min_len(4096)
            .map(|&i| corners(&mesh.triangles[i as usize]))
            .collect();
        crate::progress::lap("bvh: ids, corners");
        let quads = quads_of(&nodes);
        crate::progress::lap("bvh: quads");
        Bvh {
            nodes,
            quads,
            tris,
            ids,
        }
    }
}

/// The 4-wide traversal tree of a depth-first binary node list whose root
/// is interior: each quad takes up to four descendants of a binary node,
/// opening the child with the largest box first.
fn quads_of(nodes: &[Node]) -> Vec<Quad> {
    // A quad holds at least one interior node of its own, and a binary
    // tree of n nodes has (n - 1) / 2 interior ones: reserving that keeps
    // the list from growing by copies (and fresh page faults) each time.
    let mut out = Vec::with_capacity(nodes.len() / 2 + 1);
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
                // Leaves hold at most MAX_LEAF (4) triangles.
                q.count[c] = ch.n as u8;
                q.leaves |= 1 << c;
            } else {
                q.child[c] = out.len() as u32;
                q.inner |= 1 << c;
                out.push(Quad::NONE);
                todo.push((j, q.child[c] as usize));
            }
        }
        out[qi] = q;
    }
    out
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

/// What a node does with its triangles: stays a leaf, or splits them at
/// `mid` (already partitioned), with the two sides' bounds when the
/// binning gave them.
enum Step {
    Leaf,
    Split { mid: usize, kids: Option<Sides> },
}

/// Decide a node over `ids` (box `bb`, centroid box `cb`) and partition
/// its triangles for the split.
fn step(ids: &mut [Prim], bb: &Aabb, cb: &Aabb) -> Step {
    let n = ids.len();
    if n > 2 && n <= SMALL {
        return small_step(ids, bb);
    }
    let split = if n <= 2 { None } else { best_split(ids, bb, cb) };
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
            return Step::Split { mid: n / 2, kids: None };
        }
        return Step::Leaf;
    }
    Step::Split { mid, kids }
}

/// The two sides of a split at `mid` and their bounds.
fn sides(ids: &mut [Prim], mid: usize, kids: Option<Sides>) -> (&mut [Prim], &mut [Prim], Sides) {
    let (l, r) = ids.split_at_mut(mid);
    let kids = kids.unwrap_or_else(|| [bounds(l), bounds(r)]);
    (l, r, kids)
}

/// Build the subtree over `ids` (which start at `offset` in the full id
/// list; `bb` and `cb` their box and centroid box) on this thread,
/// appending nodes to `out` depth-first; returns its root index.
fn build(ids: &mut [Prim], offset: usize, out: &mut Vec<Node>, pad: f64, bb: Aabb, cb: Aabb) -> u32 {
    let me = out.len() as u32;
    out.push(to_node(&bb, pad));
    match step(ids, &bb, &cb) {
        Step::Leaf => {
            let nd = &mut out[me as usize];
            nd.a = offset as u32;
            nd.n = ids.len() as u32;
        }
        Step::Split { mid, kids } => {
            let (l, r, [(lb, lc), (rb, rc)]) = sides(ids, mid, kids);
            build(l, offset, out, pad, lb, lc);
            let rr = build(r, offset + mid, out, pad, rb, rc);
            out[me as usize].a = rr;
        }
    }
    me
}

/// A run of the depth-first node list, built on its own thread. Its
/// interior nodes' right-child indices are relative to the run's first
/// node; `add` makes them indices in the whole list.
struct Run {
    nodes: Vec<Node>,
    add: u32,
}

/// Build the subtree over `ids` as [`build`] does, the two sides of big
/// nodes in parallel, as runs in depth-first order with indices relative
/// to the subtree's root. The runs are joined once at the end: copying
/// each side's nodes into its parent's list at every parallel level cost
/// 5 copies of the whole tree on 1 M triangles.
fn build_runs(ids: &mut [Prim], offset: usize, pad: f64, bb: Aabb, cb: Aabb) -> Vec<Run> {
    let n = ids.len();
    if n < PAR_MIN {
        // A subtree of n triangles has at most 2n - 1 nodes.
        let mut out = Vec::with_capacity(2 * n.max(1) - 1);
        build(ids, offset, &mut out, pad, bb, cb);
        return vec![Run { nodes: out, add: 0 }];
    }
    let mut me = to_node(&bb, pad);
    match step(ids, &bb, &cb) {
        Step::Leaf => {
            me.a = offset as u32;
            me.n = n as u32;
            vec![Run {
                nodes: vec![me],
                add: 0,
            }]
        }
        Step::Split { mid, kids } => {
            let (l, r, [(lb, lc), (rb, rc)]) = sides(ids, mid, kids);
            let (mut left, mut right) = rayon::join(
                || build_runs(l, offset, pad, lb, lc),
                || build_runs(r, offset + mid, pad, rb, rc),
            );
            let nl: usize = left.iter().map(|r| r.nodes.len()).sum();
            me.a = 1 + nl as u32;
            left.iter_mut().for_each(|r| r.add += 1);
            right.iter_mut().for_each(|r| r.add += 1 + nl as u32);
            let mut runs = Vec::with_capacity(1 + left.len() + right.len());
            runs.push(Run {
                nodes: vec![me],
                add: 0,
            });
            runs.append(&mut left);
            runs.append(&mut right);
            runs
        }
    }
}

/// The whole node list from the root's runs.
fn join_runs(runs: Vec<Run>) -> Vec<Node> {
    let total = runs.iter().map(|r| r.nodes.len()).sum();
    let mut out = Vec::with_capacity(total);
    for r in runs {
        out.extend(r.nodes.iter().map(|&nd| {
            let mut nd = nd;
            if nd.n == 0 {
                nd.a += r.add;
            }
            nd
        }));
    }
    out
}

/// Bounds of the two sides of a split: (box, centroid box) left, right.
type Sides = [(Aabb, Aabb); 2];

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

/// Binned SAH along the longest centroid axis: the cheapest split and
/// the bounds of its two sides, or None when keeping a leaf is cheaper
/// (and allowed). Nodes of up to [`SMALL`] triangles take the exact sweep
/// of [`small_step`] over all three axes instead.
fn best_split(ids: &[Prim], bb: &Aabb, cb: &Aabb) -> Option<(Split, Sides)> {
    let n = ids.len();
    // One axis: binning all three tripled the work where most of the
    // build's time goes, and on the test meshes it added under 1.5 % to
    // the quads a random ray visits (docs/mesh.md, "Building the BVH").
    let axis = (0..3)
        .max_by(|&a, &b| (cb.max[a] - cb.min[a]).total_cmp(&(cb.max[b] - cb.min[b])))
        .unwrap_or(0);
    let lo = cb.min[axis];
    let ext = cb.max[axis] - lo;
    if ext.is_nan() || ext <= 0.0 {
        return None;
    }
    let k = BINS as f32 / ext;
    if !k.is_finite() {
        return None;
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
    let mut best = (f64::INFINITY, None);
    let mut acc = Aabb::EMPTY;
    let mut cnt = 0u32;
    for j in 0..BINS - 1 {
        acc.grow(&bins[j].0);
        cnt += bins[j].2;
        let cost = acc.half_area() * cnt as f64 + right[j + 1];
        if cnt > 0 && (cnt as usize) < n && cost < best.0 {
            best = (cost, Some(Split { axis, lo, k, last: j }));
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
    for (j, b) in bins.iter().enumerate() {
        let side = &mut sides[(j > split.last) as usize];
        side.0.grow(&b.0);
        side.1.grow(&b.1);
    }
    Some((split, sides))
}

/// Most nodes hold a handful of triangles. For them the cost of binning
/// is per node (twelve bins set up and swept twice an axis), and the
/// exact sweep (each axis in centroid order, every cut between
/// neighbours) costs less and finds the best cut rather than the best
/// between bin walls. Up to 32 cost more than up to 16 (docs/mesh.md).
const SMALL: usize = 16;

/// [`step`] for 3 to [`SMALL`] triangles: the cheapest cut of each
/// axis's centroid order, the triangles reordered along the best.
fn small_step(ids: &mut [Prim], bb: &Aabb) -> Step {
    let n = ids.len();
    debug_assert!(n > 2 && n <= SMALL);
    // f32 bits made to order as integers the way total_cmp orders floats.
    let key = |x: f32| {
        let b = x.to_bits() as i32;
        b ^ ((((b >> 31) as u32) >> 1) as i32)
    };
    let mut best = (f64::INFINITY, 0usize);
    let mut best_order = [0u8; SMALL];
    let mut right = [0.0f64; SMALL];
    for axis in 0..3 {
        // Insertion sort of (key, index): stable, so equal centroids keep
        // their order and the result does not depend on the sort's details.
        let mut ord = [(0i32, 0u8); SMALL];
        for (i, q) in ids.iter().enumerate() {
            let k = key(q.c[axis]);
            let mut j = i;
            while j > 0 && ord[j - 1].0 > k {
                ord[j] = ord[j - 1];
                j -= 1;
            }
            ord[j] = (k, i as u8);
        }
        let mut acc = Aabb::EMPTY;
        for j in (1..n).rev() {
            acc.grow(&ids[ord[j].1 as usize].b);
            right[j] = acc.half_area() * (n - j) as f64;
        }
        let mut acc = Aabb::EMPTY;
        let mut improved = false;
        for j in 0..n - 1 {
            acc.grow(&ids[ord[j].1 as usize].b);
            let cost = acc.half_area() * (j + 1) as f64 + right[j + 1];
            if cost < best.0 {
                best = (cost, j + 1);
                improved = true;
            }
        }
        if improved {
            for (o, &(_, i)) in best_order.iter_mut().zip(&ord[..n]) {
                *o = i;
            }
        }
    }
    let (cost, mid) = best;
    if mid == 0 {
        // No finite cost (cannot happen for finite boxes): keep a leaf or
        // halve by position, as the binned path does.
        return if n <= MAX_LEAF {
            Step::Leaf
        } else {
            Step::Split { mid: n / 2, kids: None }
        };
    }
    let split_cost = 1.0 + cost / bb.half_area().max(f64::MIN_POSITIVE);
    if n <= MAX_LEAF && n as f64 <= split_cost {
        return Step::Leaf;
    }
    let copy: [Prim; SMALL] = std::array::from_fn(|i| ids[best_order[i.min(n - 1)] as usize]);
    ids.copy_from_slice(&copy[..n]);
    Step::Split { mid, kids: None }
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
