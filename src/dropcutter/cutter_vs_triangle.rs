//! Dropping one cutter onto one triangle: the exact contact against the
//! triangle's three vertices, three edges and its facet, as OpenCAMLib's
//! drop-cutter does it.
//!
//! The cutter hangs on the vertical axis through (x, y); its tip (the lowest
//! point on the axis) is the cutter location (CL). Over the disc of radius R
//! the underside is `tip + profile(ρ)`, and `profile` is convex and
//! non-decreasing for flat, ball and torus cutters. So for a planar piece of
//! surface the quantity `z_surface(q) − profile(|q − axis|)` is concave in
//! q: its maximum over a triangle (the CL z at which the cutter first
//! touches it) is either a stationary point inside the facet (the facet
//! contact), a stationary point inside an edge (the edge contact), or a
//! vertex. Taking the highest of the seven candidates is exact.
//!
//! Facet and ball/flat edge contacts have closed forms. The torus edge
//! contact is the offset-ellipse problem of OpenCAMLib (the ring circle
//! dropped onto the cylinder of radius `corner` around the edge); here it
//! is solved in its 1-D form: along the edge's horizontal parameter s the
//! height `z(s) − profile(√(d² + s²))` is concave, so its maximum is the
//! unique root of the monotone slope equation, bracketed and bisected to
//! the last bit (the contact z then has an error quadratically smaller).

use crate::cutter::Cutter;
use crate::mesh::Triangle;

/// A triangle prepared for repeated drops: vertices, the upward unit normal
/// and the plane offset, its XY box and its top.
#[derive(Debug, Clone, Copy)]
pub struct Tri {
    /// Vertices as `[x, y, z]`.
    pub v: [[f64; 3]; 3],
    /// Unit normal with nz >= 0 (zeros for a degenerate triangle).
    pub n: [f64; 3],
    /// Plane: n · p = d.
    pub d: f64,
    /// XY box: min x, min y, max x, max y.
    pub bb: [f64; 4],
    /// Highest vertex z: no contact can put the tip above it.
    pub zmax: f64,
}

/// Facets steeper than this (|nz| below it) are left to their edges and
/// vertices: the facet contact of a vertical wall is on its edges.
const VERTICAL_NZ: f64 = 1e-12;

impl Tri {
    /// Prepare a triangle.
    pub fn new(t: &Triangle) -> Tri {
        let v = [[t.a.x, t.a.y, t.a.z], [t.b.x, t.b.y, t.b.z], [t.c.x, t.c.y, t.c.z]];
        let n = match t.normal() {
            Some(n) if n.z < 0.0 => [-n.x, -n.y, -n.z],
            Some(n) => [n.x, n.y, n.z],
            None => [0.0; 3],
        };
        let d = n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2];
        let mut bb = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        let mut zmax = f64::NEG_INFINITY;
        for p in &v {
            bb[0] = bb[0].min(p[0]);
            bb[1] = bb[1].min(p[1]);
            bb[2] = bb[2].max(p[0]);
            bb[3] = bb[3].max(p[1]);
            zmax = zmax.max(p[2]);
        }
        Tri { v, n, d, bb, zmax }
    }

    /// Whether the XY box comes within `r` of (x, y) (the cutter's disc).
    #[inline]
    pub fn near(&self, x: f64, y: f64, r: f64) -> bool {
        let dx = (self.bb[0] - x).max(x - self.bb[2]).max(0.0);
        let dy = (self.bb[1] - y).max(y - self.bb[3]).max(0.0);
        dx * dx + dy * dy <= r * r
    }

    /// Whether (x, y) lies in the triangle's XY projection (boundary
    /// included; a contact on the boundary is also an edge contact).
    #[inline]
    pub(crate) fn contains_xy(&self, x: f64, y: f64) -> bool {
        let [a, b, c] = self.v;
        let e = |p: [f64; 3], q: [f64; 3]| (q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0]);
        let (e0, e1, e2) = (e(a, b), e(b, c), e(c, a));
        (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0)
    }

    /// Height of the triangle's plane at (x, y).
    #[inline]
    pub(crate) fn plane_z(&self, x: f64, y: f64) -> f64 {
        (self.d - self.n[0] * x - self.n[1] * y) / self.n[2]
    }
}

/// The cutter in the form the contact formulas want.
#[derive(Debug, Clone, Copy)]
pub struct ContactCutter {
    /// The cutter these figures are of.
    pub cutter: Cutter,
    /// Tool radius R.
    pub r: f64,
    /// Corner radius (0 flat, R ball).
    pub rc: f64,
    /// Radius of the flat bottom, R − rc.
    pub a: f64,
}

impl ContactCutter {
    /// The figures of `cutter`.
    pub fn new(cutter: Cutter) -> ContactCutter {
        let r = cutter.radius();
        let rc = cutter.corner_radius();
        ContactCutter {
            cutter,
            r,
            rc,
            a: (r - rc).max(0.0),
        }
    }

    /// Height of the underside above the tip at distance ρ <= R.
    #[inline]
    pub(super) fn profile(&self, rho: f64) -> f64 {
        if rho <= self.a {
            0.0
        } else {
            let u = rho - self.a;
            self.rc - (self.rc * self.rc - u * u).max(0.0).sqrt()
        }
    }
}

/// Raise `best` to the highest tip z at which the cutter on the axis
/// through (x, y) touches `t`. Leaves it unchanged when the cutter does
/// not reach the triangle or meets it lower.
#[inline]
pub fn drop_on(s: &ContactCutter, x: f64, y: f64, t: &Tri, best: &mut f64) {
    let r2 = s.r * s.r;
    for p in &t.v {
        let (dx, dy) = (p[0] - x, p[1] - y);
        let d2 = dx * dx + dy * dy;
        if d2 <= r2 {
            let z = p[2] - s.profile(d2.sqrt());
            if z > *best {
                *best = z;
            }
        }
    }
    facet(s, x, y, t, best);
    for i in 0..3 {
        edge(s, x, y, t.v[i], t.v[(i + 1) % 3], best);
    }
}

/// The facet contact: the point of the cutter whose normal is the facet's.
#[inline]
fn facet(s: &ContactCutter, x: f64, y: f64, t: &Tri, best: &mut f64) {
    let [nx, ny, nz] = t.n;
    if nz < VERTICAL_NZ {
        return;
    }
    let nh = (nx * nx + ny * ny).sqrt();
    // Centre of the tube circle (corner) that touches: on the ring of
    // radius a, away from the uphill direction; the cutter's flat part
    // for a level facet.
    let (px, py) = if nh > 0.0 {
        (x - s.a * nx / nh, y - s.a * ny / nh)
    } else {
        (x, y)
    };
    // Contact point: from the tube centre against the normal.
    let (cx, cy) = (px - s.rc * nx, py - s.rc * ny);
    if !t.contains_xy(cx, cy) {
        return;
    }
    let z = t.plane_z(cx, cy) + s.rc * nz - s.rc;
    if z > *best {
        *best = z;
    }
}

/// The edge contact on segment p→q (vertices are tested separately).
#[inline]
fn edge(s: &ContactCutter, x: f64, y: f64, p: [f64; 3], q: [f64; 3], best: &mut f64) {
    let (ex, ey) = (q[0] - p[0], q[1] - p[1]);
    let len2 = ex * ex + ey * ey;
    if len2 <= 0.0 {
        // A vertical edge: its highest point in the disc is a vertex.
        return;
    }
    let len = len2.sqrt();
    let (tx, ty) = (ex / len, ey / len);
    let (wx, wy) = (x - p[0], y - p[1]);
    // Foot of the axis on the edge line (distance along from p) and the
    // horizontal distance of the axis from the line.
    let u0 = wx * tx + wy * ty;
    let d = (wx * ty - wy * tx).abs();
    if d > s.r {
        return;
    }
    let m = (q[2] - p[2]) / len;
    let w = (s.r * s.r - d * d).max(0.0).sqrt();
    // s*: contact along the line, measured from the foot.
    let (sc, z) = match s.cutter {
        Cutter::Flat { .. } => {
            let sc = if m > 0.0 {
                w
            } else if m < 0.0 {
                -w
            } else {
                0.0
            };
            (sc, p[2] + m * (u0 + sc))
        }
        Cutter::Ball { radius } => {
            // The section of the ball at distance d is a circle of radius
            // w around the centre; the line is tangent to it.
            let l = (1.0 + m * m).sqrt();
            let sc = w * m / l;
            (sc, p[2] + m * (u0 + sc) + w / l - radius)
        }
        Cutter::Torus { .. } => {
            // The edge's highest point over the disc, less the underside's
            // height at the axis's nearest approach to the line (the
            // profile rises with the distance, which is at least d), bounds
            // any contact: skip the solve when that cannot beat the best
            // so far, or when the edge misses the disc's chord.
            let (s0, s1) = ((u0 - w).max(0.0), (u0 + w).min(len));
            if s0 > s1 || p[2] + m * if m > 0.0 { s1 } else { s0 } - s.profile(d) <= *best {
                return;
            }
            let sc = torus_edge_contact(s, d, m.abs(), w) * m.signum();
            let rho = (d * d + sc * sc).sqrt().min(s.r);
            (sc, p[2] + m * (u0 + sc) - s.profile(rho))
        }
    };
    let along = u0 + sc;
    if !(0.0..=len).contains(&along) {
        return;
    }
    if z > *best {
        *best = z;
    }
}

/// Where along a line of slope `m` >= 0 at horizontal distance `d` from the
/// axis a torus touches it: the s in [0, w] (w = √(R² − d²)) where the
/// underside's slope along the line, profile'(ρ)·s/ρ with ρ = √(d² + s²),
/// equals m. That slope rises monotonically from 0 (flat bottom) to +∞
/// (the rim), so the root is unique; Newton's method kept inside a
/// shrinking bracket (bisection when a step leaves it) converges to it.
fn torus_edge_contact(s: &ContactCutter, d: f64, m: f64, w: f64) -> f64 {
    if m == 0.0 || w == 0.0 {
        return 0.0;
    }
    let rc2 = s.rc * s.rc;
    // slope − m and its derivative; +∞ at and beyond the rim.
    let eval = |t: f64| -> (f64, f64) {
        let rho = (d * d + t * t).sqrt();
        let u = rho - s.a;
        if u <= 0.0 || rho == 0.0 {
            return (-m, 0.0);
        }
        let h2 = rc2 - u * u;
        if h2 <= 0.0 {
            return (f64::INFINITY, f64::INFINITY);
        }
        let h = h2.sqrt();
        let p1 = u / h; // profile'
        let p2 = rc2 / (h2 * h); // profile''
        let c = t / rho;
        (p1 * c - m, p2 * c * c + p1 * d * d / (rho * rho * rho))
    };
    // Everything below the flat bottom's edge has slope 0.
    let mut lo = (s.a * s.a - d * d).max(0.0).sqrt().min(w);
    let mut hi = w;
    let mut t = 0.5 * (lo + hi);
    let mut f_prev = f64::INFINITY;
    for _ in 0..200 {
        let (f, df) = eval(t);
        if f < 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        if f == 0.0 || hi - lo <= 1e-13 * w {
            return t;
        }
        // Newton while it at least halves |slope − m| and stays inside
        // the bracket; a tiny step alone proves nothing near the rim,
        // where the slope is nearly vertical, so convergence also needs a
        // small residual. The height error is quadratic in the position
        // error at the maximum, so 1e-13·w in s is far below 1e-15 mm in z.
        let newton = t - f / df;
        let ok = f.is_finite() && df > 0.0 && newton > lo && newton < hi && f.abs() < 0.5 * f_prev;
        if ok && (newton - t).abs() <= 1e-13 * w && f.abs() <= 1e-9 * (1.0 + m) {
            return newton;
        }
        f_prev = f.abs();
        t = if ok { newton } else { 0.5 * (lo + hi) };
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::P3;

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Tri {
        Tri::new(&Triangle::new(
            P3::new(a[0], a[1], a[2]),
            P3::new(b[0], b[1], b[2]),
            P3::new(c[0], c[1], c[2]),
        ))
    }

    fn drop1(c: Cutter, x: f64, y: f64, t: &Tri) -> f64 {
        let mut best = f64::NEG_INFINITY;
        drop_on(&ContactCutter::new(c), x, y, t, &mut best);
        best
    }

    /// Brute force: the highest tip over a fine sampling of the triangle
    /// (a lower bound that converges to the exact answer).
    fn brute(c: Cutter, x: f64, y: f64, t: &Tri, n: usize) -> f64 {
        let s = ContactCutter::new(c);
        let mut best = f64::NEG_INFINITY;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let w = 1.0 - u - v;
                let q: Vec<f64> = (0..3).map(|k| w * t.v[0][k] + u * t.v[1][k] + v * t.v[2][k]).collect();
                let rho = ((q[0] - x).powi(2) + (q[1] - y).powi(2)).sqrt();
                if rho <= s.r {
                    best = best.max(q[2] - s.profile(rho));
                }
            }
        }
        best
    }

    #[test]
    fn ball_on_a_tilted_plane_is_the_offset_plane() {
        // Plane z = 0.3 x + 0.1 y: the ball centre is r above it along the
        // normal, so tip = plane(x, y) + r·√(1 + 0.3² + 0.1²) − r.
        let t = tri([-10.0, -10.0, -4.0], [10.0, -10.0, 2.0], [0.0, 10.0, 1.0]);
        let r = 0.5;
        let got = drop1(Cutter::Ball { radius: r }, 0.7, -0.2, &t);
        let want = 0.3 * 0.7 + 0.1 * -0.2 + r * (1.0f64 + 0.09 + 0.01).sqrt() - r;
        assert!((got - want).abs() < 1e-12, "{got} {want}");
    }

    #[test]
    fn flat_on_an_edge_and_a_vertex() {
        // A ridge along y at x = 0, height 1, falling to 0 at x = ±1: a
        // flat cutter of radius 0.5 centred at x = 0.2 sits on the ridge.
        let t = tri([0.0, -5.0, 1.0], [0.0, 5.0, 1.0], [1.0, 0.0, 0.0]);
        assert!((drop1(Cutter::Flat { radius: 0.5 }, 0.2, 0.0, &t) - 1.0).abs() < 1e-12);
        // Rising edge y from z=0 to z=1 over 10 mm: a flat cutter touches
        // with its rim, √(R² − d²) ahead of the foot.
        let t = tri([0.0, 0.0, 0.0], [0.0, 10.0, 1.0], [-5.0, 5.0, -10.0]);
        let (r, d) = (0.5f64, 0.3f64);
        let got = drop1(Cutter::Flat { radius: r }, d, 4.0, &t);
        let want = 0.1 * (4.0 + (r * r - d * d).sqrt());
        assert!((got - want).abs() < 1e-12, "{got} {want}");
    }

    #[test]
    fn torus_on_a_facet() {
        // Plane z = k·x of slope angle θ: the ring touches on its uphill
        // side a = R − rc ahead, the tube where its normal is the plane's:
        // tip = z(x) + a·tanθ + rc/cosθ − rc.
        let k = 0.4f64; // dz/dx
        let t = tri([-10.0, -10.0, -4.0], [10.0, -10.0, 4.0], [0.0, 10.0, 0.0]);
        let (r, rc) = (1.0, 0.25);
        let got = drop1(Cutter::Torus { radius: r, corner: rc }, 0.5, 0.0, &t);
        let th = k.atan();
        let want = k * 0.5 + (r - rc) * k + rc / th.cos() - rc;
        assert!((got - want).abs() < 1e-12, "{got} {want}");
    }

    #[test]
    fn every_contact_agrees_with_brute_force_sampling() {
        let tris = [
            tri([0.0, 0.0, 0.0], [1.0, 0.2, 0.5], [0.3, 1.1, -0.4]),
            tri([0.0, 0.0, 1.0], [2.0, 0.0, 0.0], [0.0, 0.1, 0.9]),
            tri([-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, 0.5, 2.0]),
        ];
        let cutters = [
            Cutter::Flat { radius: 0.4 },
            Cutter::Ball { radius: 0.4 },
            Cutter::Torus {
                radius: 0.4,
                corner: 0.15,
            },
        ];
        for t in &tris {
            for c in cutters {
                for i in 0..7 {
                    for j in 0..7 {
                        let (x, y) = (-0.6 + 0.3 * i as f64, -0.6 + 0.3 * j as f64);
                        let got = drop1(c, x, y, t);
                        let b = brute(c, x, y, t, 400);
                        if b == f64::NEG_INFINITY {
                            continue;
                        }
                        // Exact is never below the samples, and within the
                        // sampling error above them.
                        assert!(got >= b - 1e-12, "{c} at {x},{y}: {got} < {b}");
                        assert!(got - b < 2e-2, "{c} at {x},{y}: {got} vs {b}");
                    }
                }
            }
        }
    }

    #[test]
    fn torus_edge_contact_tends_to_ball_and_flat() {
        let t = tri([0.0, -3.0, -1.0], [0.0, 3.0, 1.5], [-3.0, 0.0, -5.0]);
        for (x, y) in [(0.2, 0.0), (0.5, 1.0), (0.05, -0.5)] {
            let ball = drop1(Cutter::Ball { radius: 0.6 }, x, y, &t);
            let tor = drop1(
                Cutter::Torus {
                    radius: 0.6,
                    corner: 0.6,
                },
                x,
                y,
                &t,
            );
            assert!((ball - tor).abs() < 1e-10, "{ball} {tor}");
        }
    }
}
