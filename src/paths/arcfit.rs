//! Curves to tangent-continuous arcs (biarcs): each span between two
//! points with given tangents becomes two arcs meeting tangentially, so the
//! whole fit has continuous tangents — no corner loops, no speed changes —
//! and far fewer blocks than a polyline at the same tolerance.

use super::elem::Elem;
use crate::geometry::arc::Arc3;
use crate::geometry::{P2, P3, Plane, V2};

fn lift(p: &P2, z: f64) -> P3 {
    P3::new(p.x, p.y, z)
}

fn perp(v: &V2) -> V2 {
    V2::new(-v.y, v.x)
}

/// The arc (or line) leaving `p` along unit tangent `t` and ending at `q`.
fn arc_from_tangent(p: P2, t: V2, q: P2, z: f64) -> Elem {
    let d = q - p;
    let n = perp(&t);
    let dn = d.dot(&n);
    // Nearly straight: a line is exact within 1e-12 of a radius-1e9 arc.
    if dn.abs() <= 1e-12 * d.norm_squared().max(1e-300).sqrt() || d.norm_squared() / (2.0 * dn.abs()) > 1e9 {
        return Elem::line(lift(&p, z), lift(&q, z));
    }
    let rho = d.norm_squared() / (2.0 * dn);
    let c = p + n * rho;
    match Arc3::new(lift(&c, z), lift(&p, z), lift(&q, z), rho > 0.0, Plane::Xy, 0) {
        Some(a) => Elem::Arc(a),
        None => Elem::line(lift(&p, z), lift(&q, z)),
    }
}

/// Two arcs from `p0` (unit tangent `t0`) to `p1` (unit tangent `t1`),
/// tangent to each other at their joint (the equal-parameter biarc).
pub fn biarc(p0: P2, t0: V2, p1: P2, t1: V2, z: f64) -> Vec<Elem> {
    let v = p1 - p0;
    if v.norm() < 1e-12 {
        return Vec::new();
    }
    let t = t0 + t1;
    let denom = 2.0 * (1.0 - t0.dot(&t1));
    let vt = v.dot(&t);
    let d = if denom.abs() < 1e-12 {
        let vt1 = v.dot(&t1);
        if vt1.abs() < 1e-12 {
            // Tangents parallel and across the chord: no finite biarc.
            return vec![Elem::line(lift(&p0, z), lift(&p1, z))];
        }
        v.norm_squared() / (4.0 * vt1)
    } else {
        (-vt + (vt * vt + denom * v.norm_squared()).sqrt()) / denom
    };
    let j = P2::from((p0.coords + p1.coords + (t0 - t1) * d) * 0.5);
    let a = arc_from_tangent(p0, t0, j, z);
    // The joint's tangent is the first arc's end tangent.
    let tj = a.dir_end().xy();
    let tj = if tj.norm() > 0.0 { tj.normalize() } else { v.normalize() };
    let b = arc_from_tangent(j, tj, p1, z);
    let mut out = Vec::with_capacity(2);
    for e in [a, b] {
        if e.length() > 1e-12 {
            out.push(e);
        }
    }
    out
}

/// Distance from `p` to a piece (XY).
pub fn dist_to_elem(p: &P2, e: &Elem) -> f64 {
    let q = P3::new(p.x, p.y, e.start().z);
    match e {
        Elem::Line(l) => l.distance(&q),
        Elem::Arc(a) => a.distance(&q).unwrap_or(f64::INFINITY),
    }
}

fn dist_to_polyline(p: &P2, pts: &[P2]) -> f64 {
    pts.windows(2)
        .map(|w| {
            let d = w[1] - w[0];
            let l2 = d.norm_squared();
            let t = if l2 > 0.0 {
                ((p - w[0]).dot(&d) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (w[0] + d * t)).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Tangent estimates at each point: the direction of the circle through it
/// and its neighbours (exact for points on a circle), chord direction at
/// the ends.
pub fn tangents(pts: &[P2]) -> Vec<V2> {
    let n = pts.len();
    (0..n)
        .map(|i| {
            if n < 2 {
                return V2::x();
            }
            if i == 0 || i == n - 1 || n < 3 {
                let d = if i == 0 {
                    pts[1] - pts[0]
                } else {
                    pts[n - 1] - pts[n - 2]
                };
                return d.normalize();
            }
            let (a, b) = (pts[i] - pts[i - 1], pts[i + 1] - pts[i]);
            let (la, lb) = (a.norm(), b.norm());
            // Weighted so that the tangent of a circle through the three
            // points comes out exactly (Bessel's tangent).
            let t = a * (lb / la) + b * (la / lb);
            if t.norm() > 0.0 { t.normalize() } else { b.normalize() }
        })
        .collect()
}

/// Largest distance from the points to the fit (points are the truth; the
/// curve between them is unknown).
pub fn point_deviation(fit: &[Elem], pts: &[P2]) -> f64 {
    pts.iter()
        .map(|p| fit.iter().map(|e| dist_to_elem(p, e)).fold(f64::INFINITY, f64::min))
        .fold(0.0, f64::max)
}

/// Largest deviation between a fit and a polyline: the fit sampled densely
/// against the polyline, and the polyline's vertices against the fit.
pub fn max_deviation(fit: &[Elem], pts: &[P2], samples_per_piece: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for e in fit {
        for k in 0..=samples_per_piece {
            let p = e.point_at_length(e.length() * k as f64 / samples_per_piece as f64).xy();
            worst = worst.max(dist_to_polyline(&p, pts));
        }
    }
    for p in pts {
        let d = fit.iter().map(|e| dist_to_elem(p, e)).fold(f64::INFINITY, f64::min);
        worst = worst.max(d);
    }
    worst
}

/// Fit biarcs to a point sequence within `tol`: spans grow greedily while
/// the biarc over them stays within `tol` of every point in between and,
/// when `polyline` is set, of every polyline piece too (the polyline is then
/// the shape; otherwise the points are samples of an unknown smooth curve).
pub fn fit_points(pts: &[P2], tol: f64, z: f64, polyline: bool) -> Vec<Elem> {
    let mut clean: Vec<P2> = Vec::with_capacity(pts.len());
    for p in pts {
        if clean.last().is_none_or(|q: &P2| (p - q).norm() > 1e-12) {
            clean.push(*p);
        }
    }
    let pts = clean;
    if pts.len() < 2 {
        return Vec::new();
    }
    let tan = tangents(&pts);
    let fits = |i: usize, j: usize| -> Option<Vec<Elem>> {
        let f = biarc(pts[i], tan[i], pts[j], tan[j], z);
        // 32 samples per arc, with 5 % margin, keeps the dense check
        // (which samples far finer) within tol.
        let dev = if polyline {
            max_deviation(&f, &pts[i..=j], 32)
        } else {
            point_deviation(&f, &pts[i..=j])
        };
        (dev <= 0.95 * tol).then_some(f)
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < pts.len() - 1 {
        // Gallop then bisect for the longest span that fits.
        let mut good = i + 1;
        let mut best = fits(i, good).unwrap_or_else(|| vec![Elem::line(lift(&pts[i], z), lift(&pts[good], z))]);
        let mut step = 1;
        let mut bad = None;
        while good + step < pts.len() {
            match fits(i, good + step) {
                Some(f) => {
                    good += step;
                    best = f;
                    step *= 2;
                }
                None => {
                    bad = Some(good + step);
                    break;
                }
            }
        }
        if let Some(mut hi) = bad {
            while hi - good > 1 {
                let mid = (good + hi) / 2;
                match fits(i, mid) {
                    Some(f) => {
                        good = mid;
                        best = f;
                    }
                    None => hi = mid,
                }
            }
        }
        out.extend(best);
        i = good;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn biarcs_join_tangentially_and_hit_both_ends() {
        for (t0, t1) in [(0.3f64, -1.2f64), (0.0, 0.0), (1.0, 2.5), (-0.7, 0.9)] {
            let (p0, p1) = (P2::new(0.0, 0.0), P2::new(2.0, 0.5));
            let (u0, u1) = (V2::new(t0.cos(), t0.sin()), V2::new(t1.cos(), t1.sin()));
            let f = biarc(p0, u0, p1, u1, 0.0);
            assert!((f[0].start().xy() - p0).norm() < 1e-12);
            assert!((f.last().unwrap().end().xy() - p1).norm() < 1e-9);
            assert!((f[0].dir_start().xy() - u0).norm() < 1e-9);
            assert!((f.last().unwrap().dir_end().xy() - u1).norm() < 1e-6, "{t0} {t1}");
            for w in f.windows(2) {
                assert!(w[0].dir_end().dot(&w[1].dir_start()) > 1.0 - 1e-9);
            }
        }
    }

    #[test]
    fn sampled_points_fit_far_fewer_blocks() {
        // Coarse samples of a sine: as points (not a polyline) they fit in
        // a handful of biarcs, every point within tol.
        let pts: Vec<P2> = (0..=126)
            .map(|i| P2::new(i as f64 * 0.05, (i as f64 * 0.05).sin()))
            .collect();
        let f = fit_points(&pts, 1e-4, 0.0, false);
        assert!(point_deviation(&f, &pts) <= 1e-4);
        assert!(f.len() * 2 < pts.len(), "{} pieces", f.len());
    }

    #[test]
    fn a_sine_fits_within_tolerance_in_fewer_blocks() {
        let pts: Vec<P2> = (0..=400)
            .map(|i| {
                let x = i as f64 * 0.025;
                P2::new(x, x.sin())
            })
            .collect();
        for tol in [1e-3, 1e-4] {
            let f = fit_points(&pts, tol, 0.0, true);
            let dev = max_deviation(&f, &pts, 64);
            assert!(dev <= tol * 1.0001, "deviation {dev} > {tol}");
            assert!(f.len() * 4 < pts.len(), "{} pieces for {} points", f.len(), pts.len());
            for w in f.windows(2) {
                assert!((w[0].end() - w[1].start()).norm() < 1e-9);
                assert!(w[0].dir_end().dot(&w[1].dir_start()) > (0.5f64).to_radians().cos());
            }
        }
    }
}
