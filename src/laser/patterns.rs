//! Parametric laser patterns (Bayesteh (2013) §6.1.3): helix, square and
//! Archimedean spirals, zigzag hatching and cones. Each builds exact path
//! pieces; planning then adds leads, loops and shutter timing, so every
//! pattern runs at constant V with the beam switched exactly.

use super::arcfit::biarc;
use super::constant_velocity::Tagged;
use super::dubins::connect;
use super::setup::LaserSetup;
use crate::geometry::Segment;
use crate::geometry::arc::Arc3;
use crate::geometry::{P2, P3, Plane, V2, V3};
use crate::model::toolpath::Role;
use std::f64::consts::TAU;

/// A helix of `turns` whole turns about `center` (at the start height),
/// radius `r`, rising `pitch` per turn (negative descends), starting on +X.
pub fn helix(center: P3, r: f64, pitch: f64, turns: u32, ccw: bool) -> Vec<Segment> {
    let mut out = Vec::with_capacity(turns as usize);
    let mut p = center + V3::new(r, 0.0, 0.0);
    for _ in 0..turns {
        let q = p + V3::new(0.0, 0.0, pitch);
        let c = P3::new(center.x, center.y, p.z);
        if let Some(a) = Arc3::new(c, p, q, ccw, Plane::Xy, 0) {
            out.push(Segment::Arc(a));
        }
        p = q;
    }
    out
}

/// A square spiral about `center` with legs growing by `step` every half
/// turn, out to a square of side `size`. Outward starts at the centre;
/// inward is the same path reversed. Its corners get loops when planned.
pub fn square_spiral(center: P3, step: f64, size: f64, inward: bool) -> Vec<Segment> {
    let mut pts = vec![center];
    let mut p = center;
    let dirs = [V3::x(), V3::y(), -V3::x(), -V3::y()];
    let mut len = step;
    let mut k = 0;
    let half = 0.5 * size;
    loop {
        let q = p + dirs[k % 4] * len;
        if (q.x - center.x).abs() > half + 1e-12 || (q.y - center.y).abs() > half + 1e-12 {
            break;
        }
        pts.push(q);
        p = q;
        if k % 2 == 1 {
            len += step;
        }
        k += 1;
    }
    let mut out: Vec<Segment> = pts.windows(2).map(|w| Segment::line(w[0], w[1])).collect();
    if inward {
        out.reverse();
        for e in &mut out {
            *e = e.reversed();
        }
    }
    out
}

/// An Archimedean spiral r = a + b·θ from radius `a` out to `r_max`
/// (b = `step` / 2π, so passes are `step` apart), closed by a full circle
/// at `r_max`; inward runs the circle first and the spiral in. The spiral
/// is exact to within `tol` as biarcs, tangent-continuous throughout.
pub fn archimedean(center: P3, a: f64, step: f64, r_max: f64, inward: bool, tol: f64) -> Vec<Segment> {
    archimedean_limited(center, a, step, r_max, inward, tol, usize::MAX).unwrap_or_default()
}

/// [`archimedean`], giving up once it has made more than `max` pieces:
/// `Err` then carries the number of pieces the whole spiral would take,
/// extrapolated from the part made (the work is bounded by `max`, however
/// small `step` or `tol`).
pub fn archimedean_limited(
    center: P3,
    a: f64,
    step: f64,
    r_max: f64,
    inward: bool,
    tol: f64,
    max: usize,
) -> Result<Vec<Segment>, f64> {
    let b = step / TAU;
    let z = center.z;
    let pt = |th: f64| {
        let r = a + b * th;
        P2::new(center.x + r * th.cos(), center.y + r * th.sin())
    };
    let tan = |th: f64| {
        let r = a + b * th;
        V2::new(b * th.cos() - r * th.sin(), b * th.sin() + r * th.cos()).normalize()
    };
    let th_end = if b > 0.0 { ((r_max - a) / b).max(0.0) } else { 0.0 };
    let mut out = Vec::new();
    let mut th = 0.0;
    let mut dth: f64 = 0.25;
    let mut spans = 0usize;
    // Adaptive spans: grow while the biarc stays within tol of the true
    // spiral at interior samples, halve when it does not.
    let fits = |t0: f64, t1: f64| -> Option<Vec<Segment>> {
        let f = biarc(pt(t0), tan(t0), pt(t1), tan(t1), z);
        let ok = (1..8).all(|k| {
            let p = pt(t0 + (t1 - t0) * k as f64 / 8.0);
            f.iter()
                .map(|e| super::arcfit::dist_to_elem(&p, e))
                .fold(f64::INFINITY, f64::min)
                <= tol
        });
        ok.then_some(f)
    };
    while th < th_end - 1e-12 {
        let mut d = dth.min(th_end - th);
        let piece = loop {
            match fits(th, th + d) {
                Some(f) => break f,
                None if d > 1e-4 => d *= 0.5,
                None => break biarc(pt(th), tan(th), pt(th + d), tan(th + d), z),
            }
        };
        out.extend(piece);
        th += d;
        dth = (2.0 * d).min(1.0);
        // Every span counts, even one whose biarc came out empty, so the
        // loop ends whatever the numbers.
        spans += 1;
        if out.len().max(spans) > max {
            return Err(out.len().max(spans) as f64 * (th_end / th).max(1.0));
        }
    }
    // The closing circle at r_max, starting where the spiral ends.
    let end = out.last().map_or(P3::new(center.x + r_max, center.y, z), |e| e.end());
    if let Some(c) = Arc3::new(P3::new(center.x, center.y, z), end, end, true, Plane::Xy, 0) {
        out.push(Segment::Arc(c));
    }
    if inward {
        out.reverse();
        for e in &mut out {
            *e = e.reversed();
        }
    }
    Ok(out)
}

/// Zigzag hatching of a `width` x `length` rectangle from `origin`: cut
/// lines along the first axis of `plane` (or the second when `along_second`),
/// `step` apart, joined by beam-off turnarounds of radius at least
/// `corner_radius` and the stage's V²/a, long enough for the shutter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Zigzag {
    /// The corner where the first cut line starts (mm).
    pub origin: P3,
    /// The plane of the rectangle; its first two axes are the lines' axes.
    pub plane: Plane,
    /// Cut along the plane's second axis instead of its first.
    pub along_second: bool,
    /// Length of each cut line (mm).
    pub length: f64,
    /// Extent across the lines (mm): `floor(width / step) + 1` lines.
    pub width: f64,
    /// Distance between lines (mm).
    pub step: f64,
    /// Least radius of the turnarounds (mm); the stage's V²/a wins when
    /// larger.
    pub corner_radius: f64,
}

/// The zigzag as one tagged path: cut lines alternating in direction,
/// joined by beam-off Dubins turnarounds (role `Loop`) that
/// [`plan_tagged`](super::constant_velocity::plan_tagged) keeps as they are.
pub fn zigzag(z: &Zigzag, m: &LaserSetup) -> Tagged {
    let Zigzag {
        origin,
        plane,
        along_second,
        length,
        width,
        step,
        corner_radius,
    } = *z;
    let (i, j, _) = plane.axes();
    let mut ax = V3::zeros();
    let mut ay = V3::zeros();
    ax[i] = 1.0;
    ay[j] = 1.0;
    if along_second {
        std::mem::swap(&mut ax, &mut ay);
    }
    let n = (width / step).floor() as usize + 1;
    let r = corner_radius.max(m.min_radius());
    let mut out: Tagged = Vec::with_capacity(4 * n);
    for k in 0..n {
        let base = origin + ay * (k as f64 * step);
        let (a, b) = if k % 2 == 0 {
            (base, base + ax * length)
        } else {
            (base + ax * length, base)
        };
        if let Some((last, _)) = out.last() {
            let from = last.end();
            let din = last.end_tangent();
            let dout = (b - a).normalize();
            let p2 = |v: V3| {
                let (pi, pj, _) = plane.axes();
                V2::new(v[pi], v[pj])
            };
            if let Some(turn) = connect(from, p2(din), a, p2(dout), r, m.connection_shape(), plane) {
                out.extend(turn.into_iter().map(|e| (e, Role::Loop)));
            }
        }
        out.push((Segment::line(a, b), Role::Cut));
    }
    out
}

/// Least number of pieces an Archimedean spiral from radius `a` to
/// `r_max`, `step` apart, is made of: the fit's spans never exceed 1 rad,
/// so at least two arcs per radian (the estimate pathgen refuses
/// impossible requests with before making anything).
pub fn archimedean_pieces(a: f64, step: f64, r_max: f64) -> f64 {
    2.0 * ((r_max - a).max(0.0) / (step / TAU)).ceil() + 1.0
}

/// Cut lines of a zigzag `width` across, `step` apart.
pub fn zigzag_lines(width: f64, step: f64) -> f64 {
    (width / step).floor() + 1.0
}

/// Legs of a square spiral out to `size`, legs growing by `step`.
pub fn square_spiral_legs(step: f64, size: f64) -> f64 {
    2.0 * (size / step).ceil() + 2.0
}

/// One pass of a cone (Bayesteh (2013) eqs. 6.4-6.6): the cone angle from the
/// diameters `d1` (at the surface, z0) and `d2` (at depth `h`), the pass
/// height H_p = H - p·H/levels, and the section diameter
/// d2 + 2·H_p·tan(α). Returns (z, diameter) of each pass, surface first.
pub fn cone_levels(z0: f64, d1: f64, d2: f64, h: f64, levels: u32) -> Vec<(f64, f64)> {
    let alpha = ((d1 - d2) / 2.0 / h).atan();
    (0..levels.max(1))
        .map(|p| {
            let hp = h - p as f64 * (h / levels.max(1) as f64);
            (z0 - (h - hp), d2 + 2.0 * hp * alpha.tan())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_sections_follow_the_cone() {
        let l = cone_levels(0.0, 1.0, 0.4, 0.3, 3);
        assert_eq!(l.len(), 3);
        assert!((l[0].0 - 0.0).abs() < 1e-12 && (l[0].1 - 1.0).abs() < 1e-12);
        assert!((l[1].0 + 0.1).abs() < 1e-12 && (l[1].1 - 0.8).abs() < 1e-12);
        assert!((l[2].0 + 0.2).abs() < 1e-12 && (l[2].1 - 0.6).abs() < 1e-12);
    }

    #[test]
    fn archimedean_stays_on_the_spiral_and_is_tangent_continuous() {
        let c = P3::new(1.0, 2.0, 0.0);
        let (a, step) = (0.1, 0.05);
        let path = archimedean(c, a, step, 1.0, false, 1e-5);
        for w in path.windows(2) {
            assert!((w[0].end() - w[1].start()).norm() < 1e-9);
        }
        let spiral = &path[..path.len() - 1];
        for w in spiral.windows(2) {
            assert!(w[0].end_tangent().dot(&w[1].start_tangent()) > 1.0 - 1e-9);
        }
        // Sample: r - a - bθ ≈ 0 modulo a turn.
        let b = step / TAU;
        for e in spiral {
            let p = e.point_at_length(0.5 * e.length()) - c;
            let r = p.xy().norm();
            let th = p.y.atan2(p.x).rem_euclid(TAU);
            let k = ((r - a - b * th) / step).round();
            let err = r - a - b * (th + k * TAU);
            assert!(err.abs() < 2e-5, "off the spiral by {err}");
        }
        let ring = path.last().unwrap();
        assert!((ring.length() - TAU * 1.0).abs() < 1e-3);
    }

    #[test]
    fn square_spiral_legs_and_size() {
        let s = square_spiral(P3::origin(), 0.1, 1.0, false);
        assert_eq!(s[0].length(), 0.1);
        assert!((s[1].length() - 0.1).abs() < 1e-12 && (s[2].length() - 0.2).abs() < 1e-12);
        for e in &s {
            assert!(e.end().x.abs() <= 0.5 + 1e-12 && e.end().y.abs() <= 0.5 + 1e-12);
        }
        let inv = square_spiral(P3::origin(), 0.1, 1.0, true);
        assert_eq!(inv.last().unwrap().end(), P3::origin());
    }
}
