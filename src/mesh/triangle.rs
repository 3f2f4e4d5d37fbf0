//! One ray against one triangle (the watertight test) and the nearest
//! point of a triangle: the exact per-triangle geometry under the
//! hierarchy's traversal.

use super::{Hit, Ray};
use crate::geometry::{P3, V3};

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
    pub(crate) kx: usize,
    pub(crate) ky: usize,
    pub(crate) kz: usize,
    /// `dir[kx] / dir[kz]`, `dir[ky] / dir[kz]`, `1 / dir[kz]`.
    pub(crate) s: [f64; 3],
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
