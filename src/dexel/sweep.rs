//! Where a straight line meets the volume a tool sweeps along a straight
//! move: the exact interval for each convex piece of the tool.
//!
//! A tool with a fixed axis is a union of convex pieces (cylinders and
//! balls clipped between two planes across the axis). A piece moved along
//! the segment `u · D`, `u` in [0, 1], and a line `X(t) = O + t·e` meet
//! where some `(t, u)` satisfies one quadratic inequality
//! `|A + t·B - u·C|² <= r²` (the distance from the axis for a cylinder,
//! from the centre for a ball) and four linear ones (the two clipping
//! planes and `0 <= u <= 1`). That set is convex in the `(t, u)` plane, so
//! its projection on `t` is one interval, and the extremes of `t` lie at
//! one of: the ellipse's own extremes in `t`, a corner of the polygon of
//! the linear constraints, or where a polygon edge crosses the ellipse.
//! Checking those few candidates gives the interval exactly (to rounding):
//! no sampling along the move.

use crate::geometry::{P3, V3};

/// One convex piece of a tool placed at the start of a move, and the move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    /// A point on the axis (cylinder) or the centre (ball).
    pub c: P3,
    /// Unit tool axis, tip towards holder.
    pub a: V3,
    /// Radius, mm.
    pub r: f64,
    /// `true`: the quadratic measures distance from the axis (cylinder);
    /// `false`: distance from `c` (ball).
    pub cylinder: bool,
    /// Lower clipping plane across the axis: `s0 <= a·(X - c)`, mm.
    pub s0: f64,
    /// Upper clipping plane: `a·(X - c) <= s1`, mm; `s1 >= s0`.
    pub s1: f64,
    /// The move of the piece (end minus start), mm.
    pub d: V3,
}

/// Tolerance of the feasibility checks, mm (or mm² for the quadratic).
pub(super) const EPS: f64 = 1e-9;

/// One linear constraint `alpha + beta·t + gamma·u >= 0`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Lin {
    pub(super) alpha: f64,
    pub(super) beta: f64,
    pub(super) gamma: f64,
}

impl Lin {
    #[inline]
    pub(super) fn at(&self, t: f64, u: f64) -> f64 {
        self.alpha + self.beta * t + self.gamma * u
    }
}

/// Real roots of `|p + x·q|² = r2`, if any.
#[inline]
pub(super) fn roots(p: V3, q: V3, r2: f64) -> Option<(f64, f64)> {
    let qq = q.dot(&q);
    if qq < 1e-24 {
        return None;
    }
    let pq = p.dot(&q);
    let disc = pq * pq - qq * (p.dot(&p) - r2);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some(((-pq - s) / qq, (-pq + s) / qq))
}

impl Piece {
    /// The projection that measures the quadratic's distance.
    #[inline]
    pub(super) fn project(&self, v: V3) -> V3 {
        if self.cylinder { v - self.a * self.a.dot(&v) } else { v }
    }

    /// The four linear constraints `alpha + beta·t + gamma·u >= 0` for a
    /// line whose origin is `s` along the axis from `c`, `se` the line's
    /// direction and `sd` the move along the axis: the two clipping planes
    /// and `0 <= u <= 1`.
    #[inline]
    pub(super) fn constraints(&self, s: f64, se: f64, sd: f64) -> [Lin; 4] {
        [
            Lin {
                alpha: s - self.s0,
                beta: se,
                gamma: -sd,
            },
            Lin {
                alpha: self.s1 - s,
                beta: -se,
                gamma: sd,
            },
            Lin {
                alpha: 0.0,
                beta: 0.0,
                gamma: 1.0,
            },
            Lin {
                alpha: 1.0,
                beta: 0.0,
                gamma: -1.0,
            },
        ]
    }

    /// The interval of `t` where the line `o + t·e` is inside the swept
    /// piece, or `None` when it misses.
    pub fn interval(&self, o: &P3, e: &V3) -> Option<(f64, f64)> {
        let w = o - self.c;
        let a = self.project(w);
        let b = self.project(*e);
        let c = self.project(self.d);
        let r2 = self.r * self.r;
        let s = self.a.dot(&w);
        let se = self.a.dot(e);
        let sd = self.a.dot(&self.d);
        let lins = self.constraints(s, se, sd);
        let q_ok = |t: f64, u: f64| {
            let v = a + b * t - c * u;
            v.dot(&v) <= r2 + EPS * (1.0 + r2)
        };
        let lin_ok =
            |t: f64, u: f64, skip: usize| lins.iter().enumerate().all(|(k, l)| k == skip || l.at(t, u) >= -EPS);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut take = |t: f64| {
            lo = lo.min(t);
            hi = hi.max(t);
        };
        // The ellipse's extremes in t: where dQ/du = 0.
        let cc = c.dot(&c);
        if cc > 1e-24 {
            let k_a = a.dot(&c) / cc;
            let k_b = b.dot(&c) / cc;
            if let Some((t0, t1)) = roots(a - c * k_a, b - c * k_b, r2) {
                for t in [t0, t1] {
                    let u = k_a + k_b * t;
                    if lin_ok(t, u, usize::MAX) {
                        take(t);
                    }
                }
            }
        }
        // Corners of the polygon.
        for i in 0..4 {
            for j in i + 1..4 {
                let (li, lj) = (lins[i], lins[j]);
                let det = li.beta * lj.gamma - lj.beta * li.gamma;
                if det.abs() < 1e-15 {
                    continue;
                }
                let t = (-li.alpha * lj.gamma + lj.alpha * li.gamma) / det;
                let u = (-li.beta * lj.alpha + lj.beta * li.alpha) / det;
                if q_ok(t, u) && lin_ok(t, u, usize::MAX) {
                    take(t);
                }
            }
        }
        // Edges across the ellipse.
        for (k, l) in lins.iter().enumerate() {
            if l.gamma.abs() >= l.beta.abs() {
                if l.gamma == 0.0 {
                    continue;
                }
                // u = u0 + m·t
                let (u0, m) = (-l.alpha / l.gamma, -l.beta / l.gamma);
                if let Some((t0, t1)) = roots(a - c * u0, b - c * m, r2) {
                    for t in [t0, t1] {
                        if lin_ok(t, u0 + m * t, k) {
                            take(t);
                        }
                    }
                }
            } else {
                // t = t0 + m·u
                let (t0, m) = (-l.alpha / l.beta, -l.gamma / l.beta);
                if let Some((u0, u1)) = roots(a + b * t0, b * m - c, r2) {
                    for u in [u0, u1] {
                        let t = t0 + m * u;
                        if lin_ok(t, u, k) {
                            take(t);
                        }
                    }
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// The same piece grown by `delta` in every direction (a superset, for
    /// culling).
    pub fn grown(&self, delta: f64) -> Piece {
        Piece {
            r: self.r + delta,
            s0: self.s0 - delta,
            s1: self.s1 + delta,
            ..*self
        }
    }

    /// Box around the swept piece.
    pub fn bbox(&self) -> ([f64; 3], [f64; 3]) {
        // Box of the piece at rest: the axis segment (or the centre's
        // clipped range) grown by the radius, then the moved copy.
        let (lo_s, hi_s) = if self.cylinder {
            (self.s0, self.s1)
        } else {
            (self.s0.max(-self.r), self.s1.min(self.r))
        };
        let p0 = self.c + self.a * lo_s;
        let p1 = self.c + self.a * hi_s;
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for k in 0..3 {
            // A disc of radius r across the axis reaches r·sqrt(1 - a_k²)
            // along axis k; a ball reaches r.
            let ext = if self.cylinder {
                self.r * (1.0 - self.a[k] * self.a[k]).max(0.0).sqrt()
            } else {
                self.r
            };
            for p in [p0, p1, p0 + self.d, p1 + self.d] {
                lo[k] = lo[k].min(p[k] - ext);
                hi[k] = hi[k].max(p[k] + ext);
            }
        }
        (lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: sample u finely and intersect the stamped piece.
    fn sampled(p: &Piece, o: &P3, e: &V3) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let n = 600;
        for k in 0..=n {
            let u = k as f64 / n as f64;
            let q = Piece {
                c: p.c + p.d * u,
                d: V3::zeros(),
                ..*p
            };
            // Stamped: scan t finely.
            for i in 0..=2000 {
                let t = -10.0 + 20.0 * i as f64 / 2000.0;
                let x = o + e * t;
                let w = x - q.c;
                let s = q.a.dot(&w);
                let dist = if q.cylinder { (w - q.a * s).norm() } else { w.norm() };
                if dist <= q.r && s >= q.s0 && s <= q.s1 {
                    lo = lo.min(t);
                    hi = hi.max(t);
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    #[test]
    fn cylinder_sweep_matches_sampling() {
        let a = V3::new(0.3, -0.2, 1.0).normalize();
        let p = Piece {
            c: P3::new(0.1, 0.2, -1.0),
            a,
            r: 1.0,
            cylinder: true,
            s0: 0.0,
            s1: 3.0,
            d: V3::new(2.0, 0.5, 0.7),
        };
        for (o, e) in [
            (P3::new(0.7, 0.4, 0.0), V3::z()),
            (P3::new(0.0, 0.6, 0.3), V3::x()),
            (P3::new(1.2, 0.0, -0.5), V3::y()),
            (P3::new(3.0, 3.0, 3.0), V3::z()),
        ] {
            let got = p.interval(&o, &e);
            let want = sampled(&p, &o, &e);
            match (got, want) {
                (Some(g), Some(w)) => {
                    assert!((g.0 - w.0).abs() < 0.02 && (g.1 - w.1).abs() < 0.02, "{g:?} {w:?}")
                }
                (None, None) => {}
                _ => panic!("{got:?} vs {want:?} for {o:?}"),
            }
        }
    }

    #[test]
    fn ball_sweep_matches_sampling_and_static_ball_is_exact() {
        let p = Piece {
            c: P3::new(0.0, 0.0, 0.0),
            a: V3::z(),
            r: 1.0,
            cylinder: false,
            s0: -1.0,
            s1: 0.2,
            d: V3::new(1.0, 1.0, -0.5),
        };
        for (o, e) in [(P3::new(0.5, 0.5, 0.0), V3::z()), (P3::new(0.0, 1.1, -0.4), V3::x())] {
            let got = p.interval(&o, &e).unwrap();
            let want = sampled(&p, &o, &e).unwrap();
            assert!((got.0 - want.0).abs() < 0.02 && (got.1 - want.1).abs() < 0.02);
        }
        let still = Piece {
            d: V3::zeros(),
            s1: 1.0,
            ..p
        };
        let (t0, t1) = still.interval(&P3::new(0.6, 0.0, 0.0), &V3::z()).unwrap();
        assert!((t0 + 0.8).abs() < 1e-9 && (t1 - 0.8).abs() < 1e-9);
        assert!(still.interval(&P3::new(1.01, 0.0, 0.0), &V3::z()).is_none());
    }
}
