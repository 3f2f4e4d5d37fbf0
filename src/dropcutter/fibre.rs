//! The blocked stretches of a fibre (or of one edge of it) at one height,
//! exactly, as OpenCAMLib's fibre intervals are: what a waterline needs
//! where the boundary crosses an edge twice between two grid nodes, or a
//! free gap crosses an edge between two blocked ones, which the nodes'
//! own drops cannot see.
//!
//! Why one triangle gives one stretch: the tip height at which the cutter
//! first touches a triangle, `f(c) = max over q in T of z(q) − profile(|q − c|)`,
//! is the partial maximum over the convex triangle of a function jointly
//! concave in (q, c) (z is linear on the facet, the profile convex and
//! non-decreasing, +∞ beyond the cutter's radius). So `f` is concave in
//! the axis position c, and along a fibre `{f > z}` is one interval,
//! possibly empty. Its maximum is found by golden-section search, which is
//! exact for a concave function (a plateau can only be its maximum), with
//! an upper bound from secants that rejects most triangles in a few drops;
//! its two ends by bisection from that maximum outwards. The fibre's
//! blocked set is the union of the triangles' stretches.

use super::DropCutter;
use super::cutter_vs_triangle::{ContactCutter, Tri, drop_on};

/// A fibre edge between two grid nodes: the points `(x0 + s, y0)` (along
/// X) or `(x0, y0 + s)` (along Y) for s in `[0, len]`.
#[derive(Debug, Clone, Copy)]
pub(super) struct FibreEdge {
    pub x0: f64,
    pub y0: f64,
    pub along_x: bool,
    pub len: f64,
}

impl FibreEdge {
    pub(super) fn at(&self, s: f64) -> (f64, f64) {
        if self.along_x {
            (self.x0 + s, self.y0)
        } else {
            (self.x0, self.y0 + s)
        }
    }
}

/// One blocked stretch of an edge, by its free ends: `None` where it
/// reaches the edge's end node (that node is blocked), otherwise the
/// parameter of a free point within the tolerance of the stretch.
pub(super) type Stretch = (Option<f64>, Option<f64>);

/// Inverse golden ratio.
const G: f64 = 0.618_033_988_749_894_8;

/// The blocked stretches of `e` at tip height `z`, in order along it,
/// disjoint: stretches whose free ends are within `tol` of each other are
/// joined (a free gap narrower than the tolerance is no gap). A stretch
/// whose peak rises above `z` over less than about `tol` of the edge may be
/// missed.
///
/// Only what can change the union is searched. What the stretches found
/// so far block is kept merged (a [`Cover`]); a triangle is searched only
/// on the parts of the edge still open. The triangles that block wherever
/// their disc reaches (see [`stretch_in`]) go first, at the cost of their
/// reach alone: inside a model's section they cover nearly everything, and
/// the others are left a few short parts near the waterline.
pub(super) fn blocked_stretches(dc: &DropCutter, e: &FibreEdge, z: f64, tol: f64) -> Vec<Stretch> {
    let s = &dc.shape;
    let (x1, y1) = e.at(e.len);
    let query = [e.x0 - s.r, e.y0 - s.r, x1 + s.r, y1 + s.r];
    let (u0, along) = if e.along_x { (e.x0, 0) } else { (e.y0, 1) };
    let mut cover = Cover::new(tol);
    let mut found: Vec<Stretch> = Vec::new();
    let mut parts: Vec<Part> = Vec::new();
    let mut new: Vec<Stretch> = Vec::new();
    let mut later: Vec<&Tri> = Vec::new();
    let mut take = |t: &Tri, cover: &mut Cover| {
        // The triangle's box widened by the radius bounds its reach.
        if cover.covers(t.bb[along] - s.r - u0, t.bb[along + 2] + s.r - u0) {
            return;
        }
        let Some(reach) = reach(t, e, s.r) else {
            return;
        };
        cover.open_parts(reach, e.len, &mut parts);
        new.extend(
            parts
                .iter()
                .filter_map(|part| stretch_in(dc, t, e, z, tol, reach, part)),
        );
        for st in new.drain(..) {
            cover.add(st);
            found.push(st);
        }
    };
    dc.grid.query_box(&dc.tris, query, |t| {
        // Highest tops first in each cell: nothing below z can block.
        if t.zmax <= z {
            return false;
        }
        if blocks_all_it_reaches(s, t, z) {
            take(t, &mut cover);
        } else {
            later.push(t);
        }
        true
    });
    for t in later {
        take(t, &mut cover);
    }
    union(found, tol)
}

/// Whether `t` blocks at `z` wherever the cutter's disc reaches it: its
/// lowest point lies more than the deepest profile (the corner radius)
/// above `z`, and the point nearest the axis is touched at most that far
/// below itself.
fn blocks_all_it_reaches(s: &ContactCutter, t: &Tri, z: f64) -> bool {
    t.v[0][2].min(t.v[1][2]).min(t.v[2][2]) - s.rc > z
}

/// Open intervals of an edge known to be blocked, sorted and disjoint
/// (a stretch's free ends are its ends; a missing end is the edge's).
/// Intervals whose ends are within the tolerance are merged, as
/// [`union`] joins stretches: a gap narrower than that is no gap. (Found
/// stretches often meet exactly: a search on a part that starts at an
/// earlier stretch's free end, blocked by this triangle, starts there.)
struct Cover {
    iv: Vec<(f64, f64)>,
    tol: f64,
}

/// A part of an edge not yet known to be blocked, `[lo, hi]`; each end is
/// the edge's own end (`*_edge`) or the free end of a stretch found before.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Part {
    lo: f64,
    hi: f64,
    lo_edge: bool,
    hi_edge: bool,
}

impl Cover {
    fn new(tol: f64) -> Cover {
        Cover { iv: Vec::new(), tol }
    }

    fn add(&mut self, st: Stretch) {
        let (mut a, mut b) = (st.0.unwrap_or(f64::NEG_INFINITY), st.1.unwrap_or(f64::INFINITY));
        // Intervals that overlap (a, b) or end within the tolerance of it
        // are merged into it.
        let lo = self.iv.partition_point(|&(_, q)| q < a - self.tol);
        let hi = self.iv.partition_point(|&(p, _)| p <= b + self.tol);
        if lo < hi {
            a = a.min(self.iv[lo].0);
            b = b.max(self.iv[hi - 1].1);
        }
        self.iv.splice(lo..hi, [(a, b)]);
    }

    /// Whether `[a, b]` lies inside one interval.
    fn covers(&self, a: f64, b: f64) -> bool {
        let k = self.iv.partition_point(|&(_, q)| q <= b);
        k < self.iv.len() && self.iv[k].0 < a
    }

    /// The parts of the edge `[0, len]` outside every interval that meet
    /// `(lo, hi)`, in order, into `out` (cleared first); parts of one
    /// point are left out (nothing is blocked on them).
    fn open_parts(&self, (lo, hi): (f64, f64), len: f64, out: &mut Vec<Part>) {
        out.clear();
        let (mut from, mut from_edge) = (0.0, true);
        let mut push = |a: f64, b: f64, a_edge: bool, b_edge: bool| {
            if a < b && a < hi && b > lo {
                out.push(Part {
                    lo: a,
                    hi: b,
                    lo_edge: a_edge,
                    hi_edge: b_edge,
                });
            }
        };
        // Intervals that end before `lo` only move `from` forward.
        let mut k = self.iv.partition_point(|&(_, q)| q < lo);
        if k > 0 && self.iv[k - 1].1 >= 0.0 {
            (from, from_edge) = (self.iv[k - 1].1, false);
        }
        while from <= len && from < hi {
            let Some(&(a, b)) = self.iv.get(k) else {
                push(from, len, from_edge, true);
                return;
            };
            push(from, a.min(len), from_edge, a >= len);
            if b > from {
                (from, from_edge) = (b, false);
            }
            k += 1;
        }
    }
}

/// The drop on one triangle at parameter `sp` of the edge (−∞ when the
/// cutter's disc misses it).
fn drop_one(dc: &DropCutter, t: &Tri, e: &FibreEdge, sp: f64) -> f64 {
    let (x, y) = e.at(sp);
    let mut best = f64::NEG_INFINITY;
    drop_on(&dc.shape, x, y, t, &mut best);
    best
}

/// This triangle's stretch on the whole edge, if any.
#[cfg(test)]
fn stretch_of(dc: &DropCutter, t: &Tri, e: &FibreEdge, z: f64, tol: f64) -> Option<Stretch> {
    let part = Part {
        lo: 0.0,
        hi: e.len,
        lo_edge: true,
        hi_edge: true,
    };
    stretch_in(dc, t, e, z, tol, reach(t, e, dc.shape.r)?, &part)
}

/// This triangle's stretch above `z` within `part` of the edge, if any
/// (`reach` is where its disc reaches it, from [`reach`]). An end of the
/// stretch at an end of the part is `None` at the edge's own end (that
/// node is blocked) and that end's parameter at a stretch found before
/// (free by that stretch, blocked by this one: the union joins them).
fn stretch_in(
    dc: &DropCutter,
    t: &Tri,
    e: &FibreEdge,
    z: f64,
    tol: f64,
    (rlo, rhi): (f64, f64),
    part: &Part,
) -> Option<Stretch> {
    let (lo, hi) = (rlo.max(part.lo), rhi.min(part.hi));
    if lo > hi {
        return None;
    }
    let f = |sp: f64| drop_one(dc, t, e, sp);
    // The end of a stretch that reaches the part's end.
    let at_bound = |p: f64, is_edge: bool| if is_edge { None } else { Some(p) };
    if blocks_all_it_reaches(&dc.shape, t, z) {
        // Its stretch is the reach. Each end checked: blocked where the
        // reach passes the part's end, free just past the reach otherwise.
        // Round-off that fails either check leaves it to the search.
        // Half the tolerance past the reach is free unless the reach's
        // round-off (a few ulps of the coordinates) is as large: checked
        // by a drop only then.
        let margin_is_safe = 0.5 * tol > 1e-9 * (1.0 + e.x0.abs() + e.y0.abs() + e.len);
        let end = |raw: f64, bound: f64, is_edge: bool, dir: f64| -> Option<Option<f64>> {
            if (raw - bound) * dir > 0.0 {
                return (!is_edge || f(bound) > z).then_some(at_bound(bound, is_edge));
            }
            let p = raw + dir * 0.5 * tol;
            if (p - bound) * dir > 0.0 {
                return (f(bound) <= z).then_some(Some(bound));
            }
            (margin_is_safe || f(p) <= z).then_some(Some(p))
        };
        if let (Some(a), Some(b)) = (
            end(rlo, part.lo, part.lo_edge, -1.0),
            end(rhi, part.hi, part.hi_edge, 1.0),
        ) {
            return Some((a, b));
        }
    } else {
        let sub = FibreEdge {
            x0: if e.along_x { e.x0 + lo } else { e.x0 },
            y0: if e.along_x { e.y0 } else { e.y0 + lo },
            along_x: e.along_x,
            len: hi - lo,
        };
        if !may_block(&dc.shape, t, &sub, z) {
            return None;
        }
    }
    let w = peak_above(&f, lo, hi, z, tol)?;
    // Where the search for an end starts from outside: just past the
    // reach (free: the disc misses the triangle there), or the part's end.
    let outer = |raw: f64, bound: f64, dir: f64| -> f64 {
        let p = raw + dir * 0.5 * tol;
        if (p - bound) * dir >= 0.0 || f(p) > z { bound } else { p }
    };
    // Outwards from the peak: {f > z} is an interval, so bisection between
    // a point inside and one outside meets its end.
    // `end` is free unless it is the part's end (`outer` checked it).
    let side = |inside: f64, end: f64, is_edge: bool| -> Option<f64> {
        if f(end) > z {
            return at_bound(end, is_edge);
        }
        let (mut a, mut b) = (inside, end);
        while (b - a).abs() > tol {
            let m = 0.5 * (a + b);
            if m == a || m == b {
                break;
            }
            if f(m) > z {
                a = m;
            } else {
                b = m;
            }
        }
        Some(b)
    };
    let (out_lo, out_hi) = (outer(rlo, part.lo, -1.0), outer(rhi, part.hi, 1.0));
    Some((side(w, out_lo, part.lo_edge), side(w, out_hi, part.hi_edge)))
}

/// A point of `[lo, hi]` where the concave `f` exceeds `z`, or `None`
/// when its maximum there is at most `z` (or exceeds it only within the
/// tolerance of its peak).
fn peak_above(f: &impl Fn(f64) -> f64, mut a: f64, mut b: f64, z: f64, tol: f64) -> Option<f64> {
    let (mut fa, mut fb) = (f(a), f(b));
    if fa > z {
        return Some(a);
    }
    if fb > z {
        return Some(b);
    }
    let (mut c, mut d) = (b - G * (b - a), a + G * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    loop {
        if fc > z {
            return Some(c);
        }
        if fd > z {
            return Some(d);
        }
        // Also stop where the points no longer move apart (a tolerance
        // below the coordinates' resolution).
        if concave_bound(a, fa, c, fc, d, fd, b, fb) <= z || b - a <= tol || !(a < c && c < d && d < b) {
            return None;
        }
        if fc < fd {
            (a, fa, c, fc) = (c, fc, d, fd);
            d = a + G * (b - a);
            fd = f(d);
        } else {
            (b, fb, d, fd) = (d, fd, c, fc);
            c = b - G * (b - a);
            fc = f(c);
        }
    }
}

/// An upper bound of a concave function on `[a, b]` from its values at
/// `a < c < d < b`: outside `[c, d]` it lies below the secant through c
/// and d; inside, below the secants through (a, c) and (d, b) extended.
/// +∞ when a value needed is not finite.
#[allow(clippy::too_many_arguments)]
fn concave_bound(a: f64, fa: f64, c: f64, fc: f64, d: f64, fd: f64, b: f64, fb: f64) -> f64 {
    if !(fc.is_finite() && fd.is_finite()) || d <= c {
        return f64::INFINITY;
    }
    let line = |x0: f64, y0: f64, x1: f64, y1: f64, x: f64| y0 + (y1 - y0) * (x - x0) / (x1 - x0);
    let outer = line(c, fc, d, fd, a).max(line(c, fc, d, fd, b));
    if !(fa.is_finite() && fb.is_finite()) || c <= a || b <= d {
        return f64::INFINITY;
    }
    // Inside [c, d]: the lower of the two extended secants, highest at an
    // end of [c, d] or where they cross.
    let l1 = |x: f64| line(a, fa, c, fc, x);
    let l2 = |x: f64| line(d, fd, b, fb, x);
    let mut inner = l1(c).min(l2(c)).max(l1(d).min(l2(d)));
    let (m1, m2) = ((fc - fa) / (c - a), (fb - fd) / (b - d));
    if m1 != m2 {
        let x = (fd - m2 * d - fc + m1 * c) / (m1 - m2);
        if x > c && x < d {
            inner = inner.max(l1(x));
        }
    }
    outer.max(inner).max(fc).max(fd)
}

/// Where on the edge's line (parameters, not clipped to the edge) the
/// cutter's disc reaches the triangle's XY projection: where the drop is
/// finite. The set of axis positions
/// within R of a convex polygon is convex, and its boundary lies on the
/// circles round the vertices and the edges offset by R, so its ends on
/// the fibre's line are the extreme crossings of those.
fn reach(t: &Tri, e: &FibreEdge, r: f64) -> Option<(f64, f64)> {
    // Coordinates along the fibre (u) and across it (w).
    let (u0, w0) = if e.along_x { (e.x0, e.y0) } else { (e.y0, e.x0) };
    let uw = |p: &[f64; 3]| if e.along_x { (p[0], p[1]) } else { (p[1], p[0]) };
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |u: f64| {
        lo = lo.min(u);
        hi = hi.max(u);
    };
    for (k, p) in t.v.iter().enumerate() {
        let (pu, pw) = uw(p);
        let dw = pw - w0;
        if dw.abs() <= r {
            let h = (r * r - dw * dw).max(0.0).sqrt();
            take(pu - h);
            take(pu + h);
        }
        // The edge to the next vertex, offset by ±R across itself.
        let (qu, qw) = uw(&t.v[(k + 1) % 3]);
        let (du, dwq) = (qu - pu, qw - pw);
        let len = (du * du + dwq * dwq).sqrt();
        let offsets: &[f64] = if len > 0.0 { &[-1.0, 0.0, 1.0] } else { &[] };
        for &sgn in offsets {
            let (nu, nw) = (-dwq / len * r * sgn, du / len * r * sgn);
            let (au, aw, bw) = (pu + nu, pw + nw, qw + nw);
            if (aw - w0) * (bw - w0) <= 0.0 && aw != bw {
                let k = (w0 - aw) / (bw - aw);
                take(au + k * du);
            }
        }
    }
    (lo <= hi).then_some((lo - u0, hi - u0))
}

/// Whether the cutter can touch `t` with its tip above `z` somewhere on
/// the edge, by a test that never says no wrongly: a point of the triangle
/// touched at distance ρ from the axis lies at least `profile(ρ)` above the
/// tip. So in three rings of ρ (the flat bottom and half the corner, the
/// next 0.3 of the corner, the rest) the triangle must rise above `z`,
/// `z + profile(a + rc / 2)` and `z + profile(a + 0.8 rc)` within that
/// ring's outer radius of the edge. For the flat end mill (no corner) it is
/// the exact test; for a ball it rejects most of the triangles near a
/// waterline that the cutter's disc covers without touching them above `z`.
fn may_block(s: &ContactCutter, t: &Tri, e: &FibreEdge, z: f64) -> bool {
    let (a, rc) = (s.a, s.rc);
    // First the triangle's XY box against each ring (cheap), then the
    // triangle itself.
    let d2 = box_dist2(t, e);
    if rc <= 0.0 {
        return d2 <= s.r * s.r && reaches_above(t, e, z, s.r);
    }
    let (r1, r2) = (a + 0.5 * rc, a + 0.8 * rc);
    let (z2, z3) = (z + s.profile(r1), z + s.profile(r2));
    (d2 <= r1 * r1 && reaches_above(t, e, z, r1))
        || (t.zmax > z2 && d2 <= r2 * r2 && reaches_above(t, e, z2, r2))
        || (t.zmax > z3 && d2 <= s.r * s.r && reaches_above(t, e, z3, s.r))
}

/// Squared distance in XY from the triangle's box to the edge.
fn box_dist2(t: &Tri, e: &FibreEdge) -> f64 {
    let (x1, y1) = e.at(e.len);
    let dx = (t.bb[0] - x1).max(e.x0 - t.bb[2]).max(0.0);
    let dy = (t.bb[1] - y1).max(e.y0 - t.bb[3]).max(0.0);
    dx * dx + dy * dy
}

/// Whether the part of the triangle above `z` comes within `r` of the
/// edge in XY: no cutter touches a point below its tip, so a triangle that
/// fails this cannot block the edge at `z` (for the flat end mill it is
/// the exact test).
fn reaches_above(t: &Tri, e: &FibreEdge, z: f64, r: f64) -> bool {
    // The triangle clipped to z' >= z, projected: a convex polygon of up
    // to four points.
    let mut poly: [(f64, f64); 4] = [(0.0, 0.0); 4];
    let mut n = 0;
    for k in 0..3 {
        let (p, q) = (t.v[k], t.v[(k + 1) % 3]);
        if p[2] >= z {
            poly[n] = (p[0], p[1]);
            n += 1;
        }
        if (p[2] - z) * (q[2] - z) < 0.0 && n < 4 {
            let k = (z - p[2]) / (q[2] - p[2]);
            poly[n] = (p[0] + k * (q[0] - p[0]), p[1] + k * (q[1] - p[1]));
            n += 1;
        }
    }
    if n == 0 {
        return false;
    }
    let a = e.at(0.0);
    let b = e.at(e.len);
    if n >= 3 && (in_convex(&poly[..n], a) || in_convex(&poly[..n], b)) {
        return true;
    }
    (0..n).any(|k| seg_seg_dist2(a, b, poly[k], poly[(k + 1) % n]) <= r * r)
}

/// Whether `p` lies in the convex polygon `poly` (either orientation,
/// boundary included).
fn in_convex(poly: &[(f64, f64)], p: (f64, f64)) -> bool {
    let (mut pos, mut neg) = (false, false);
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        let c = (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
        pos |= c > 0.0;
        neg |= c < 0.0;
    }
    !(pos && neg)
}

/// Squared distance between two segments in the plane.
fn seg_seg_dist2(a: (f64, f64), b: (f64, f64), c: (f64, f64), d: (f64, f64)) -> f64 {
    let cross = |o: (f64, f64), p: (f64, f64), q: (f64, f64)| (p.0 - o.0) * (q.1 - o.1) - (p.1 - o.1) * (q.0 - o.0);
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    point_seg_dist2(a, c, d)
        .min(point_seg_dist2(b, c, d))
        .min(point_seg_dist2(c, a, b))
        .min(point_seg_dist2(d, a, b))
}

/// Squared distance from a point to a segment in the plane.
fn point_seg_dist2(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let k = if l2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (ex, ey) = (p.0 - a.0 - k * dx, p.1 - a.1 - k * dy);
    ex * ex + ey * ey
}

/// The union of stretches, in order; free ends within `tol` of each other
/// (or overlapping) joined.
fn union(mut v: Vec<Stretch>, tol: f64) -> Vec<Stretch> {
    let key = |s: &Stretch| s.0.unwrap_or(f64::NEG_INFINITY);
    v.sort_by(|p, q| key(p).total_cmp(&key(q)));
    let mut out: Vec<Stretch> = Vec::with_capacity(v.len());
    for s in v {
        if let Some(last) = out.last_mut() {
            let end = last.1.unwrap_or(f64::INFINITY);
            if key(&s) <= end + tol {
                last.1 = match (last.1, s.1) {
                    (None, _) | (_, None) => None,
                    (Some(p), Some(q)) => Some(p.max(q)),
                };
                continue;
            }
        }
        out.push(s);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;
    use crate::geometry::P3;
    use crate::mesh::{Mesh, Triangle};

    #[test]
    fn one_triangle_stretch_is_what_dense_sampling_sees() {
        // Random triangles, fibre edges and heights for the three cutters:
        // the drop sampled at 4,001 points along the edge is above z on
        // one run of points (the concavity the search relies on), found
        // by `stretch_of` with ends within a sample of the run's.
        let mut rnd = crate::geometry::test_rng::unit_rng(0x5eed_f1b2e);
        let cutters = [
            Cutter::Flat { radius: 0.5 },
            Cutter::Ball { radius: 0.5 },
            Cutter::Torus {
                radius: 0.5,
                corner: 0.15,
            },
        ];
        let (mut found, mut empty) = (0, 0);
        for case in 0..600 {
            let mut p = || P3::new(rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd() * 1.5);
            let tri = Triangle { a: p(), b: p(), c: p() };
            let cutter = cutters[case % 3];
            let dc = DropCutter::new(&Mesh::from_triangles(&[tri]), cutter).unwrap();
            let t = dc.tris[0];
            let e = FibreEdge {
                x0: rnd() * 3.0 - 2.5,
                y0: rnd() * 3.0 - 1.5,
                along_x: case % 2 == 0,
                len: 0.2 + rnd() * 1.5,
            };
            let z = t.zmax - rnd() * 1.2;
            let n = 4000;
            let ds = e.len / n as f64;
            let above: Vec<bool> = (0..=n).map(|k| drop_one(&dc, &t, &e, k as f64 * ds) > z).collect();
            let runs = above.windows(2).filter(|w| !w[0] && w[1]).count() + usize::from(above[0]);
            assert!(runs <= 1, "case {case}: {runs} runs above z: not one interval");
            let first = above.iter().position(|&b| b);
            let last = above.iter().rposition(|&b| b);
            let got = if may_block(&dc.shape, &t, &e, z) {
                stretch_of(&dc, &t, &e, z, 1e-9)
            } else {
                None
            };
            match (first, last, got) {
                (None, _, None) => empty += 1,
                (Some(f), Some(l), Some((lo, hi))) => {
                    found += 1;
                    match lo {
                        None => assert_eq!(f, 0, "case {case}"),
                        Some(s) => assert!((s - f as f64 * ds).abs() <= ds + 1e-9, "case {case}: start {s} vs {f}"),
                    }
                    match hi {
                        None => assert_eq!(l, n, "case {case}"),
                        Some(s) => assert!((s - l as f64 * ds).abs() <= ds + 1e-9, "case {case}: end {s} vs {l}"),
                    }
                    // The free ends are free.
                    for s in [lo, hi].into_iter().flatten() {
                        assert!(drop_one(&dc, &t, &e, s) <= z, "case {case}");
                    }
                }
                // A stretch narrower than a sample may be found without
                // being sampled; one that is sampled must be found.
                (None, _, Some((Some(a), Some(b)))) => assert!(b - a <= 2.0 * ds, "case {case}"),
                other => panic!("case {case}: sampled {other:?}"),
            }
        }
        assert!(found > 100 && empty > 100, "found {found}, empty {empty}");
    }

    #[test]
    fn the_cover_and_its_open_parts_partition_the_edge() {
        // Random stretches added in random order: a point is inside the
        // cover exactly when it is inside one of them, and the open parts
        // of any window are what is left of it, with the right ends marked
        // as the edge's own.
        let mut rnd = crate::geometry::test_rng::unit_rng(0xc0_7e4);
        let len = 10.0;
        for case in 0..300 {
            let mut cover = Cover::new(0.0);
            let mut added: Vec<Stretch> = Vec::new();
            for _ in 0..(case % 9) {
                let a = rnd() * 12.0 - 1.0;
                let b = a + rnd() * rnd() * 4.0;
                let st = (
                    (rnd() > 0.1 && a > 0.0).then_some(a),
                    (rnd() > 0.1 && b < len).then_some(b),
                );
                cover.add(st);
                added.push(st);
            }
            let inside = |x: f64| {
                added
                    .iter()
                    .any(|s| s.0.is_none_or(|a| a < x) && s.1.is_none_or(|b| x < b))
            };
            for w in cover.iv.windows(2) {
                assert!(w[0].1 <= w[1].0, "case {case}: {:?}", cover.iv);
            }
            let (lo, hi) = (rnd() * 12.0 - 1.0, rnd() * 12.0 - 1.0);
            let (lo, hi) = (lo.min(hi), lo.max(hi));
            let mut parts = Vec::new();
            cover.open_parts((lo, hi), len, &mut parts);
            let ends: Vec<f64> = added.iter().flat_map(|s| [s.0, s.1]).flatten().collect();
            for k in 0..=2000 {
                let x = -1.0 + 12.0 * k as f64 / 2000.0;
                if ends.contains(&x) {
                    continue;
                }
                let in_part = parts.iter().any(|p| p.lo <= x && x <= p.hi);
                let open = (0.0..=len).contains(&x) && !inside(x);
                // Every point of a part is open; every open point of the
                // window is in a part.
                assert!(!in_part || open, "case {case}: {x} in {parts:?}, covered by {added:?}");
                if open && x > lo && x < hi {
                    assert!(in_part, "case {case}: {x} open, in no part of {parts:?}");
                }
            }
            for p in &parts {
                assert!(p.lo < p.hi && p.lo < hi && p.hi > lo, "case {case}: {p:?}");
                assert!(p.lo >= 0.0 && p.hi <= len);
                // An end is the edge's own or a stretch's free end.
                assert_eq!(p.lo_edge, !ends.contains(&p.lo), "case {case}: {p:?}");
                assert_eq!(p.hi_edge, !ends.contains(&p.hi), "case {case}: {p:?}");
                if p.lo_edge {
                    assert_eq!(p.lo, 0.0);
                }
                if p.hi_edge {
                    assert_eq!(p.hi, len);
                }
                let m = 0.5 * (p.lo + p.hi);
                assert!(!cover.covers(m, m));
            }
            for &(a, b) in &cover.iv {
                let m = match (a.is_finite(), b.is_finite()) {
                    (true, true) => 0.5 * (a + b),
                    (true, false) => a + 1.0,
                    (false, true) => b - 1.0,
                    (false, false) => 0.0,
                };
                assert!(cover.covers(m, m), "case {case}");
                assert!(inside(m), "case {case}");
            }
        }
    }

    #[test]
    fn the_cover_joins_stretches_within_the_tolerance() {
        let mut cover = Cover::new(1e-3);
        cover.add((Some(1.0), Some(2.0)));
        cover.add((Some(3.0), Some(4.0)));
        cover.add((Some(2.0005), Some(2.9995)));
        assert_eq!(cover.iv, vec![(1.0, 4.0)]);
        cover.add((Some(4.1), None));
        cover.add((None, Some(0.5)));
        assert_eq!(cover.iv.len(), 3);
        assert!(cover.covers(1.5, 3.5) && !cover.covers(3.5, 4.05) && cover.covers(5.0, 1e9));
    }

    #[test]
    fn skipping_what_is_covered_changes_no_stretch() {
        // A soup of triangles, whole fibres across it: the stretches found
        // with the cover are the union of every triangle's own stretch.
        let mut rnd = crate::geometry::test_rng::unit_rng(0x50_b7);
        for (case, cutter) in [
            Cutter::Flat { radius: 0.4 },
            Cutter::Ball { radius: 0.4 },
            Cutter::Torus {
                radius: 0.4,
                corner: 0.1,
            },
        ]
        .into_iter()
        .enumerate()
        {
            let mut tris = Vec::new();
            for _ in 0..60 {
                let c = P3::new(rnd() * 6.0, rnd() * 6.0, rnd() * 2.0);
                let mut p = || c + crate::geometry::V3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
                tris.push(Triangle { a: p(), b: p(), c: p() });
            }
            let dc = DropCutter::new(&Mesh::from_triangles(&tris), cutter).unwrap();
            let tol = 1e-9;
            for k in 0..40 {
                let e = FibreEdge {
                    x0: if k % 2 == 0 { -1.0 } else { rnd() * 6.0 },
                    y0: if k % 2 == 0 { rnd() * 6.0 } else { -1.0 },
                    along_x: k % 2 == 0,
                    len: 8.0,
                };
                for z in [0.2, 0.9, 1.6] {
                    let got = blocked_stretches(&dc, &e, z, tol);
                    let all: Vec<Stretch> = dc.tris.iter().filter_map(|t| stretch_of(&dc, t, &e, z, tol)).collect();
                    let want = union(all, tol);
                    assert_eq!(
                        got.len(),
                        want.len(),
                        "case {case} fibre {k} z {z}: {got:?} vs {want:?}"
                    );
                    for (g, w) in got.iter().zip(&want) {
                        for (a, b) in [(g.0, w.0), (g.1, w.1)] {
                            assert_eq!(a.is_none(), b.is_none(), "case {case} fibre {k} z {z}");
                            if let (Some(a), Some(b)) = (a, b) {
                                assert!((a - b).abs() <= 2.0 * tol, "case {case} fibre {k} z {z}: {a} vs {b}");
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn stretches_are_joined_within_the_tolerance_and_sorted() {
        let v = vec![
            (Some(5.0), Some(6.0)),
            (None, Some(1.0)),
            (Some(0.9995), Some(2.0)),
            (Some(5.5), None),
        ];
        assert_eq!(union(v, 1e-3), vec![(None, Some(2.0)), (Some(5.0), None)]);
        assert_eq!(
            union(vec![(Some(1.0), Some(2.0)), (Some(2.1), Some(3.0))], 1e-3).len(),
            2
        );
    }

    #[test]
    fn the_concave_bound_holds_for_parabolas() {
        // f(x) = -(x - m)^2: the bound from four points is at least the max.
        for m in [-0.5, 0.1, 0.3, 0.5, 0.7, 0.95, 1.5] {
            let f = |x: f64| -(x - m) * (x - m);
            let (a, c, d, b) = (0.0, 0.382, 0.618, 1.0);
            let truth = if (0.0..=1.0).contains(&m) { 0.0 } else { f(a).max(f(b)) };
            let ub = concave_bound(a, f(a), c, f(c), d, f(d), b, f(b));
            assert!(ub >= truth - 1e-12, "m {m}: bound {ub} below {truth}");
        }
    }

    #[test]
    fn golden_search_finds_a_narrow_peak_and_rejects_a_low_one() {
        let tent = |m: f64, h: f64| move |x: f64| h - 50.0 * (x - m).abs();
        // Peak 0.01 above z = 0, above it over 0.0004 of [0, 1].
        assert!(peak_above(&tent(0.731, 0.01), 0.0, 1.0, 0.0, 1e-7).is_some());
        assert!(peak_above(&tent(0.731, -0.01), 0.0, 1.0, 0.0, 1e-7).is_none());
        // A plateau at its maximum.
        let plateau = |x: f64| (1.0f64).min(10.0 - 20.0 * (x - 0.5).abs());
        assert!(peak_above(&plateau, 0.0, 1.0, 0.9, 1e-9).is_some());
        // Far from the origin with a tolerance below the coordinates'
        // resolution: it ends.
        assert!(peak_above(&tent(1e6 + 0.3, -1e-3), 1e6, 1e6 + 1.0, 0.0, 1e-15).is_none());
    }

    #[test]
    fn distances_in_the_plane() {
        assert_eq!(seg_seg_dist2((0.0, 0.0), (2.0, 0.0), (1.0, -1.0), (1.0, 1.0)), 0.0);
        assert!((seg_seg_dist2((0.0, 0.0), (2.0, 0.0), (3.0, 1.0), (4.0, 1.0)) - 2.0).abs() < 1e-15);
        assert!(in_convex(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)], (0.2, 0.2)));
        assert!(!in_convex(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)], (0.6, 0.6)));
    }
}
