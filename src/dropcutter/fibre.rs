//! The blocked stretches of one fibre edge at one height, exactly, as
//! OpenCAMLib's fibre intervals are: what a waterline needs where the
//! boundary crosses an edge twice between two grid nodes, which the nodes'
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
    fn at(&self, s: f64) -> (f64, f64) {
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
pub(super) fn blocked_stretches(dc: &DropCutter, e: &FibreEdge, z: f64, tol: f64) -> Vec<Stretch> {
    let s = &dc.shape;
    let (xm, ym) = e.at(0.5 * e.len);
    let mut found: Vec<Stretch> = Vec::new();
    dc.grid.query(&dc.tris, xm, ym, s.r + 0.5 * e.len, |t| {
        // Highest tops first in each cell: nothing below z can block.
        if t.zmax <= z {
            return false;
        }
        if may_block(s, t, e, z)
            && let Some(st) = stretch_of(dc, t, e, z, tol)
        {
            found.push(st);
        }
        true
    });
    union(found, tol)
}

/// The drop on one triangle at parameter `sp` of the edge (−∞ when the
/// cutter's disc misses it).
fn drop_one(dc: &DropCutter, t: &Tri, e: &FibreEdge, sp: f64) -> f64 {
    let (x, y) = e.at(sp);
    let mut best = f64::NEG_INFINITY;
    drop_on(&dc.shape, x, y, t, &mut best);
    best
}

/// This triangle's stretch on `e` above `z`, if any.
fn stretch_of(dc: &DropCutter, t: &Tri, e: &FibreEdge, z: f64, tol: f64) -> Option<Stretch> {
    let (lo, hi) = reach(t, e, dc.shape.r)?;
    let f = |sp: f64| drop_one(dc, t, e, sp);
    let w = peak_above(&f, lo, hi, z, tol)?;
    // Outwards from the peak: {f > z} is an interval, so bisection between
    // a point inside and one outside meets its end.
    let side = |inside: f64, end: f64| -> Option<f64> {
        if f(end) > z {
            return None;
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
    Some((side(w, 0.0), side(w, e.len)))
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

/// The part of the edge where the cutter's disc reaches the triangle's
/// XY projection: where the drop is finite. The set of axis positions
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
    let (lo, hi) = ((lo - u0).max(0.0), (hi - u0).min(e.len));
    (lo <= hi).then_some((lo, hi))
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
