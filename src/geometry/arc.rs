//! Circular and helical arcs in one of the three principal planes.
//!
//! An `Arc3` is stored the way G-code and the pipe formats carry it: centre,
//! start, end, sense and plane (plus RS274 `P` extra turns), not as angles.
//! That keeps end points exact (they are shared with the neighbouring
//! segments) and makes the arc's meaning independent of how it was built.
//!
//! The end may differ from the start along the plane normal: the arc is then
//! a helix rising linearly with the swept angle. Start equal to end in the
//! plane means a full turn.
//!
//! Rounded input (a G-code arc whose end is a few nanometres off the circle)
//! is tolerated: the radius is blended linearly from the start's radius to
//! the end's radius over the sweep, so `point_at(1)` is the end.

use super::bbox::BBox3;
use super::planar::sweep_angle;
use super::tol::{finite_p3, normalize_angle, positive_finite};
use super::{EPS_LEN, P2, P3, Plane, V2, V3};
use std::f64::consts::{FRAC_PI_2, TAU};

/// A circular arc in `plane`, optionally helical along the plane normal.
///
/// `center` lies in the start's plane (its normal coordinate equals the
/// start's). The signed sweep is measured from start to end around the
/// centre, positive when `ccw`, and grows by a full turn for each of
/// `extra_turns`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arc3 {
    /// Centre of the circle, at the start's normal coordinate.
    pub center: P3,
    /// Where travel begins (t = 0).
    pub start: P3,
    /// Where travel ends (t = 1); a different normal coordinate makes a helix.
    pub end: P3,
    /// Counter-clockwise seen from the positive plane normal (G3 / CIRCLE2).
    pub ccw: bool,
    /// The plane the circle lies in (G17/G18/G19).
    pub plane: Plane,
    /// Whole turns added to the sweep (RS274 `P2` = one extra turn).
    pub extra_turns: u32,
}

impl Arc3 {
    /// A checked arc: `None` when any coordinate is not finite or the radius
    /// is below `EPS_LEN`. The centre's normal coordinate is set to the
    /// start's, so callers may pass the centre at any height.
    pub fn new(center: P3, start: P3, end: P3, ccw: bool, plane: Plane, extra_turns: u32) -> Option<Self> {
        if !(finite_p3(&center) && finite_p3(&start) && finite_p3(&end)) {
            return None;
        }
        let center = plane.lift(&plane.project(&center), plane.normal_coord(&start));
        let arc = Self {
            center,
            start,
            end,
            ccw,
            plane,
            extra_turns,
        };
        if arc.radius() >= EPS_LEN { Some(arc) } else { None }
    }

    /// One full turn around `center` in `plane`, starting and ending at
    /// `start`. `None` for non-finite input or a radius below `EPS_LEN`.
    pub fn full_circle(center: P3, start: P3, ccw: bool, plane: Plane) -> Option<Self> {
        Self::new(center, start, start, ccw, plane, 0)
    }

    fn c2(&self) -> P2 {
        self.plane.project(&self.center)
    }

    fn s2(&self) -> P2 {
        self.plane.project(&self.start)
    }

    fn e2(&self) -> P2 {
        self.plane.project(&self.end)
    }

    /// Radius in mm: the in-plane distance from centre to start.
    pub fn radius(&self) -> f64 {
        (self.s2() - self.c2()).norm()
    }

    /// The in-plane distance from centre to end. Equal to `radius()` for a
    /// well-formed arc; the difference measures how badly rounded the input is.
    pub fn end_radius(&self) -> f64 {
        (self.e2() - self.c2()).norm()
    }

    /// Rise along the plane normal from start to end (0 for a planar arc).
    pub fn rise(&self) -> f64 {
        self.plane.normal_coord(&self.end) - self.plane.normal_coord(&self.start)
    }

    /// True when the arc rises more than `tol` along its normal.
    pub fn is_helical(&self, tol: f64) -> bool {
        self.rise().abs() > tol
    }

    /// Angle of the start around the centre, in the plane's (first, second)
    /// axes, in `(-π, π]`.
    pub fn start_angle(&self) -> f64 {
        let v = self.s2() - self.c2();
        v.y.atan2(v.x)
    }

    /// Signed swept angle in radians, positive counter-clockwise. Start equal
    /// to end in the plane (within `EPS_LEN`) is a full turn; each extra turn
    /// adds `2π` in the direction of travel.
    ///
    /// ```
    /// use microcam::geometry::{Arc3, P3, Plane};
    /// use std::f64::consts::{FRAC_PI_2, PI};
    /// let ccw = Arc3::new(P3::origin(), P3::new(2.0, 0.0, 0.0), P3::new(0.0, 2.0, 0.0), true, Plane::Xy, 0).unwrap();
    /// assert!((ccw.sweep() - FRAC_PI_2).abs() < 1e-15);
    /// assert!((ccw.length() - PI).abs() < 1e-14);
    /// let cw = Arc3 { ccw: false, ..ccw };
    /// assert!((cw.sweep() + 3.0 * FRAC_PI_2).abs() < 1e-14);
    /// ```
    pub fn sweep(&self) -> f64 {
        sweep_angle(&self.c2(), &self.s2(), &self.e2(), self.ccw, self.extra_turns, EPS_LEN)
    }

    /// [`Arc3::start_angle`] and [`Arc3::sweep`] together, bit for bit as
    /// each gives them, with the start's `atan2` done once: orientation
    /// and point-in-chain tests take both for every arc of a drawing.
    pub fn start_angle_and_sweep(&self) -> (f64, f64) {
        let a0 = self.start_angle();
        let s = crate::geometry::planar::sweep_from_start_angle(
            a0,
            &self.c2(),
            &self.s2(),
            &self.e2(),
            self.ccw,
            self.extra_turns,
            EPS_LEN,
        );
        (a0, s)
    }

    /// Path length in mm: `sqrt((r·sweep)² + rise²)`, with `r` the mean of the
    /// start and end radii.
    pub fn length(&self) -> f64 {
        let r = 0.5 * (self.radius() + self.end_radius());
        (r * self.sweep()).hypot(self.rise())
    }

    /// The point at parameter `t` (0 = start, 1 = end), uniform in angle and
    /// hence in length. `t = 0` and `t = 1` return the stored end points
    /// exactly; other values outside [0, 1] extrapolate.
    pub fn point_at(&self, t: f64) -> P3 {
        if t == 0.0 {
            return self.start;
        }
        if t == 1.0 {
            return self.end;
        }
        ArcFrame::new(self).point_at(t)
    }

    /// The point `s` mm along the arc from its start; `None` for an arc of
    /// zero length.
    pub fn point_at_length(&self, s: f64) -> Option<P3> {
        let len = self.length();
        if positive_finite(len) {
            Some(self.point_at(s / len))
        } else {
            None
        }
    }

    /// Unit tangent in the direction of travel at parameter `t`; `None` when
    /// the arc has no length (zero radius and no rise) or is not finite.
    pub fn tangent_at(&self, t: f64) -> Option<V3> {
        let (r0, r1) = (self.radius(), self.end_radius());
        let r = r0 + (r1 - r0) * t;
        let sw = self.sweep();
        let a = self.start_angle() + sw * t;
        let (sin, cos) = a.sin_cos();
        // d/dt of c + r(t)·(cos a, sin a) with a = a0 + sweep·t.
        let d2 = V2::new(cos, sin) * (r1 - r0) + V2::new(-sin, cos) * (r * sw);
        let d = self.plane.lift(&P2::from(d2), self.rise()).coords;
        let n = d.norm();
        if positive_finite(n) { Some(d / n) } else { None }
    }

    /// The exact axis-aligned box: both ends plus every axis extreme
    /// (0°, 90°, 180°, 270° in the plane) the sweep passes.
    pub fn bbox(&self) -> BBox3 {
        let mut b = BBox3::from_points(&[self.start, self.end]);
        let f = ArcFrame::new(self);
        for k in 0..4 {
            if let Some((t0, t1)) = f.passes(k as f64 * FRAC_PI_2) {
                b.extend(&f.point_at(t0));
                b.extend(&f.point_at(t1));
            }
        }
        b
    }

    /// The point of a planar arc nearest `p`, with its parameter in [0, 1].
    /// `None` for a helical arc (rise beyond `EPS_LEN`), whose nearest point
    /// has no closed form, or when `p` or the arc is not finite. When `p`
    /// projects onto the centre every point is equally near and the start is
    /// answered.
    pub fn closest_point(&self, p: &P3) -> Option<(P3, f64)> {
        ArcFrame::new(self).closest_point(p)
    }

    /// Distance from `p` to a planar arc; `None` where `closest_point` is.
    pub fn distance(&self, p: &P3) -> Option<f64> {
        ArcFrame::new(self).distance(p)
    }

    /// The same arc travelled the other way: ends swapped, sense flipped,
    /// a helix's centre moved to the new start's normal coordinate (a planar
    /// arc's centre is kept as it is). Reversing twice gives back the
    /// original exactly.
    pub fn reversed(&self) -> Arc3 {
        let center = if self.rise() == 0.0 {
            self.center
        } else {
            self.plane.lift(&self.c2(), self.plane.normal_coord(&self.end))
        };
        Arc3 {
            center,
            start: self.end,
            end: self.start,
            ccw: !self.ccw,
            plane: self.plane,
            extra_turns: self.extra_turns,
        }
    }

    /// The arc from `a` through `b` to `c`, in `plane` (points are projected
    /// onto it). The sense is whichever visits `b` between `a` and `c`. The
    /// end keeps `c`'s normal coordinate, so a rise from `a` to `c` makes a
    /// helix; `b`'s normal coordinate is not used. `None` when the three
    /// projected points are collinear (sine of the angle at `a` below 1e-12)
    /// or two coincide, or any coordinate is not finite.
    ///
    /// ```
    /// use microcam::geometry::{Arc3, P3, Plane};
    /// let a = Arc3::from_three_points(&P3::new(1.0, 0.0, 0.0), &P3::new(0.0, 1.0, 0.0), &P3::new(-1.0, 0.0, 0.0), Plane::Xy).unwrap();
    /// assert!(a.ccw && (a.center - P3::origin()).norm() < 1e-15);
    /// assert!(Arc3::from_three_points(&P3::origin(), &P3::new(1.0, 1.0, 0.0), &P3::new(2.0, 2.0, 0.0), Plane::Xy).is_none());
    /// ```
    pub fn from_three_points(a: &P3, b: &P3, c: &P3, plane: Plane) -> Option<Arc3> {
        if ![a, b, c].into_iter().all(finite_p3) {
            return None;
        }
        let (pa, pb, pc) = (plane.project(a), plane.project(b), plane.project(c));
        let ab = pb - pa;
        let ac = pc - pa;
        let cross = ab.perp(&ac);
        let (lab2, lac2) = (ab.norm_squared(), ac.norm_squared());
        let limit = 1e-12 * (lab2 * lac2).sqrt();
        if !positive_finite(cross.abs()) || limit.is_nan() || cross.abs() <= limit {
            return None;
        }
        let d = 2.0 * cross;
        let u = V2::new(ac.y * lab2 - ab.y * lac2, ab.x * lac2 - ac.x * lab2) / d;
        let center = plane.lift(&(pa + u), plane.normal_coord(a));
        Arc3::new(center, *a, *c, cross > 0.0, plane, 0)
    }

    /// Build an arc whose total absolute sweep should be `abs_sweep`,
    /// choosing `extra_turns` so that `sweep()` reproduces it.
    fn with_abs_sweep(center: P3, start: P3, end: P3, ccw: bool, plane: Plane, abs_sweep: f64) -> Option<Arc3> {
        let mut arc = Arc3::new(center, start, end, ccw, plane, 0)?;
        let base = arc.sweep().abs();
        let turns = ((abs_sweep - base) / TAU).round();
        if !(0.0..=u32::MAX as f64).contains(&turns) {
            return None;
        }
        arc.extra_turns = turns as u32;
        Some(arc)
    }

    /// The two pieces either side of parameter `t`, each keeping its share of
    /// the sweep, rise and whole turns. `None` unless `0 < t < 1` and both
    /// pieces are longer than a few `EPS_LEN` (a shorter piece would read
    /// as a full turn).
    pub fn split_at(&self, t: f64) -> Option<(Arc3, Arc3)> {
        if !(t > 0.0 && t < 1.0) {
            return None;
        }
        let sw = self.sweep().abs();
        let r = self.radius().min(self.end_radius());
        let shorter_piece = r * sw * t.min(1.0 - t);
        if shorter_piece.is_nan() || shorter_piece <= 16.0 * EPS_LEN {
            return None;
        }
        let m = self.point_at(t);
        let c = self.c2();
        let first = Self::with_abs_sweep(self.center, self.start, m, self.ccw, self.plane, sw * t)?;
        let mid_center = self.plane.lift(&c, self.plane.normal_coord(&m));
        let second = Self::with_abs_sweep(mid_center, m, self.end, self.ccw, self.plane, sw * (1.0 - t))?;
        Some((first, second))
    }
}

/// An arc's angles, radii and heights computed once, for a caller that
/// asks one arc many questions (sampling it, or measuring many points
/// against it): each [`Arc3::point_at`] or [`Arc3::closest_point`] works
/// them out again (three to eight `atan2` per query). The answers are
/// `Arc3`'s own, bit for bit: those methods are built on this.
#[derive(Debug, Clone, Copy)]
pub struct ArcFrame {
    arc: Arc3,
    /// Centre in the plane.
    c: P2,
    /// Radius at the start and at the end (blended over the sweep).
    r0: f64,
    r1: f64,
    /// Start angle and signed sweep, radians.
    a0: f64,
    sweep: f64,
    /// Normal coordinate of the start, and the rise to the end.
    h0: f64,
    rise: f64,
    /// Planar with finite corners: `closest_point` has an answer.
    measurable: bool,
}

impl ArcFrame {
    /// The frame of `arc`.
    pub fn new(arc: &Arc3) -> ArcFrame {
        let measurable = [&arc.center, &arc.start, &arc.end].into_iter().all(finite_p3) && !arc.is_helical(EPS_LEN);
        ArcFrame {
            arc: *arc,
            c: arc.c2(),
            r0: arc.radius(),
            r1: arc.end_radius(),
            a0: arc.start_angle(),
            sweep: arc.sweep(),
            h0: arc.plane.normal_coord(&arc.start),
            rise: arc.rise(),
            measurable,
        }
    }

    /// [`Arc3::point_at`].
    pub fn point_at(&self, t: f64) -> P3 {
        if t == 0.0 {
            return self.arc.start;
        }
        if t == 1.0 {
            return self.arc.end;
        }
        let r = self.r0 + (self.r1 - self.r0) * t;
        let a = self.a0 + self.sweep * t;
        let q = self.c + V2::new(a.cos(), a.sin()) * r;
        self.arc.plane.lift(&q, self.h0 + self.rise * t)
    }

    /// For an in-plane direction angle `phi`, the parameters of the first
    /// and the last time the arc passes that direction, if it does.
    fn passes(&self, phi: f64) -> Option<(f64, f64)> {
        let sw = self.sweep.abs();
        if !positive_finite(sw) {
            return None;
        }
        let first = if self.arc.ccw {
            normalize_angle(phi - self.a0)
        } else {
            normalize_angle(self.a0 - phi)
        };
        if first.is_nan() || first > sw {
            return None;
        }
        let last = first + ((sw - first) / TAU).floor() * TAU;
        Some((first / sw, (last / sw).min(1.0)))
    }

    /// [`Arc3::distance`].
    pub fn distance(&self, p: &P3) -> Option<f64> {
        self.closest_point(p).map(|(q, _)| (q - p).norm())
    }

    /// Whether `p` lies within `tol` of the arc: the verdict of
    /// `self.distance(p).is_some_and(|d| d <= tol)`, the same in every
    /// case, but most points are settled without trigonometry. A point
    /// farther from the centre's circle than `tol` cannot be near any
    /// point of the arc; a point whose direction lies well inside the
    /// arc's span is as near as its radial gap. Both bounds leave a margin
    /// far above the rounding of the exact computation, and a point in
    /// the margin, near an end, or on an arc of a half turn or more gets
    /// the exact distance. (The biarc fit asks this of every sample of
    /// every trial arc.)
    pub fn within(&self, p: &P3, tol: f64) -> bool {
        match self.within_by_bounds(p, tol) {
            Some(v) => v,
            None => self.distance(p).is_some_and(|d| d <= tol),
        }
    }

    fn within_by_bounds(&self, p: &P3, tol: f64) -> Option<bool> {
        if !self.measurable || !finite_p3(p) || !tol.is_finite() || self.rise != 0.0 {
            return None;
        }
        let q = self.arc.plane.project(p);
        let v = q - self.c;
        let lv = v.norm();
        let dh = self.h0 - self.arc.plane.normal_coord(p);
        let (rmin, rmax) = (self.r0.min(self.r1), self.r0.max(self.r1));
        // The exact distance is computed from points of the arc built with
        // cos and sin of angles near 2 pi: its rounding is a few ulps of
        // the coordinates involved. This is a hundred times that.
        let err = 1e-13 * (self.c.x.abs() + self.c.y.abs() + rmax + q.x.abs() + q.y.abs() + dh.abs());
        // Every candidate of the exact distance (the ends, the points
        // where the arc passes p's direction) lies between rmin and rmax
        // from the centre, at height h0.
        let gap_in = (rmin - lv).max(lv - rmax).max(0.0);
        if gap_in.hypot(dh) > tol + err {
            return Some(false);
        }
        // Inside the span (an open wedge under half a turn, entered by a
        // margin of 1e-9 rad, far above the angles' rounding), the arc
        // passes p's direction at a radius between rmin and rmax.
        if self.arc.extra_turns != 0 || self.sweep.is_nan() || self.sweep.abs() > 3.0 || lv == 0.0 {
            return None;
        }
        let s = self.arc.plane.project(&self.arc.start) - self.c;
        let e = self.arc.plane.project(&self.arc.end) - self.c;
        let turn = if self.arc.ccw { 1.0 } else { -1.0 };
        let cross = |a: &V2, b: &V2| turn * (a.x * b.y - a.y * b.x);
        let margin = 1e-9 * lv;
        let inside = cross(&s, &v) > margin * s.norm() && cross(&v, &e) > margin * e.norm();
        if !inside {
            return None;
        }
        let gap_out = (lv - rmin).abs().max((lv - rmax).abs()) + 1e-12 * (lv + rmax);
        if gap_out.hypot(dh) + err < tol {
            return Some(true);
        }
        None
    }

    /// [`Arc3::closest_point`].
    pub fn closest_point(&self, p: &P3) -> Option<(P3, f64)> {
        if !self.measurable || !finite_p3(p) {
            return None;
        }
        let q = self.arc.plane.project(p);
        let v = q - self.c;
        // The ends, then where the arc passes the point's direction: the
        // first of equally near candidates wins.
        let mut best = (self.arc.start, 0.0);
        let mut d = (best.0 - p).norm();
        let mut offer = |t: f64| {
            let c = self.point_at(t);
            let dc = (c - p).norm();
            if dc.total_cmp(&d).is_lt() {
                best = (c, t);
                d = dc;
            }
        };
        offer(1.0);
        if let Some((t0, t1)) = self.passes(v.y.atan2(v.x)).filter(|_| v.norm() > 0.0) {
            offer(t0);
            offer(t1);
        }
        Some(best)
    }
}

/// The widest angle (radians) one chord of a circle of radius `r` may span
/// with its sagitta, `r·(1 − cos(φ/2))`, within `sag`: `2·acos(1 − sag/r)`,
/// reaching 2π (the whole circle) from `sag = 2r` on. Callers that flatten
/// arcs into chords divide a sweep by it; each caps it as its use needs.
pub fn chord_angle(r: f64, sag: f64) -> f64 {
    2.0 * (1.0 - sag / r).max(-1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn p(x: f64, y: f64, z: f64) -> P3 {
        P3::new(x, y, z)
    }

    fn close(a: &P3, b: &P3) -> bool {
        (a - b).norm() < 1e-9
    }

    #[test]
    fn quarter_circle_length_sweep_and_points() {
        let a = Arc3::new(p(0.0, 0.0, 0.0), p(2.0, 0.0, 0.0), p(0.0, 2.0, 0.0), true, Plane::Xy, 0).unwrap();
        assert!((a.radius() - 2.0).abs() < 1e-15);
        assert!((a.sweep() - PI / 2.0).abs() < 1e-15);
        assert!((a.length() - PI).abs() < 1e-14, "quarter circle r=2 is pi long");
        assert!(close(&a.point_at(0.5), &p(2f64.sqrt(), 2f64.sqrt(), 0.0)));
        assert_eq!(a.point_at(1.0), a.end);
        let t = a.tangent_at(0.0).unwrap();
        assert!((t - V3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
        let cw = Arc3 { ccw: false, ..a };
        assert!((cw.sweep() + 1.5 * PI).abs() < 1e-14);
        assert!((cw.length() - 3.0 * PI).abs() < 1e-13);
        assert!((cw.tangent_at(0.0).unwrap() - V3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn tangent_follows_the_plane_sense() {
        // G18 (ZX plane, normal +Y): ccw from +Z towards +X.
        let a = Arc3::new(p(0.0, 0.0, 0.0), p(0.0, 0.0, 1.0), p(1.0, 0.0, 0.0), true, Plane::Xz, 0).unwrap();
        assert!((a.sweep() - PI / 2.0).abs() < 1e-15);
        assert!((a.tangent_at(0.0).unwrap() - V3::new(1.0, 0.0, 0.0)).norm() < 1e-12);
        // G19 (YZ plane, normal +X): ccw from +Y towards +Z.
        let b = Arc3::new(p(0.0, 0.0, 0.0), p(0.0, 1.0, 0.0), p(0.0, 0.0, 1.0), true, Plane::Yz, 0).unwrap();
        assert!((b.sweep() - PI / 2.0).abs() < 1e-15);
        assert!(close(&b.point_at(0.5), &p(0.0, 0.5f64.sqrt(), 0.5f64.sqrt())));
    }

    #[test]
    fn full_circle_and_helix() {
        let c = Arc3::full_circle(p(1.0, 1.0, 0.0), p(2.0, 1.0, 0.0), false, Plane::Xy).unwrap();
        assert!((c.sweep() + TAU).abs() < 1e-15);
        assert!((c.length() - TAU).abs() < 1e-14);
        assert!(close(&c.point_at(0.25), &p(1.0, 0.0, 0.0)));
        // One extra turn, rising 3 mm: two turns of radius 1.
        let h = Arc3::new(p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(1.0, 0.0, 3.0), true, Plane::Xy, 1).unwrap();
        assert!((h.sweep() - 2.0 * TAU).abs() < 1e-14);
        assert!((h.length() - (2.0 * TAU).hypot(3.0)).abs() < 1e-13);
        assert!(close(&h.point_at(0.5), &p(1.0, 0.0, 1.5)));
        assert!(close(&h.point_at(0.125), &p(0.0, 1.0, 0.375)));
        let t = h.tangent_at(0.0).unwrap();
        let expect = V3::new(0.0, 2.0 * TAU, 3.0).normalize();
        assert!((t - expect).norm() < 1e-12);
        assert!(h.closest_point(&p(0.0, 0.0, 0.0)).is_none(), "helix has no closed form");
    }

    #[test]
    fn bbox_includes_crossed_axis_extremes() {
        // From 45° to 135° ccw crosses 90°: the top of the circle.
        let s = 0.5f64.sqrt();
        let a = Arc3::new(p(0.0, 0.0, 0.0), p(s, s, 0.0), p(-s, s, 0.0), true, Plane::Xy, 0).unwrap();
        let b = a.bbox();
        assert!(close(&b.min, &p(-s, s, 0.0)));
        assert!(close(&b.max, &p(s, 1.0, 0.0)));
        // The same ends clockwise go the long way: through 0°, 270° and 180°.
        let b = Arc3 { ccw: false, ..a }.bbox();
        let (r, f) = (a.reversed().bbox(), a.bbox());
        assert!(close(&r.min, &f.min) && close(&r.max, &f.max));
        assert!(close(&b.min, &p(-1.0, -1.0, 0.0)));
        assert!(close(&b.max, &p(1.0, s, 0.0)));
        // A helix in XZ: the normal (Y) range comes from the rise.
        let h = Arc3::new(p(0.0, 0.0, 0.0), p(0.0, 0.0, 1.0), p(0.0, 2.0, 1.0), true, Plane::Xz, 0).unwrap();
        let b = h.bbox();
        assert!(close(&b.min, &p(-1.0, 0.0, -1.0)));
        assert!(close(&b.max, &p(1.0, 2.0, 1.0)));
    }

    #[test]
    fn closest_point_on_planar_arc() {
        let a = Arc3::new(p(0.0, 0.0, 1.0), p(1.0, 0.0, 1.0), p(0.0, 1.0, 1.0), true, Plane::Xy, 0).unwrap();
        let (q, t) = a.closest_point(&p(3.0, 3.0, 1.0)).unwrap();
        assert!(close(&q, &p(0.5f64.sqrt(), 0.5f64.sqrt(), 1.0)));
        assert!((t - 0.5).abs() < 1e-12);
        let (q, t) = a.closest_point(&p(-1.0, -2.0, 4.0)).unwrap();
        assert!(q == a.start || q == a.end);
        assert!(t == 0.0 || t == 1.0);
        assert!((a.distance(&p(0.0, 5.0, 1.0)).unwrap() - 4.0).abs() < 1e-12);
        assert_eq!(a.closest_point(&p(0.0, 0.0, 1.0)).unwrap().1, 0.0);
    }

    #[test]
    fn three_points_give_the_circumcircle() {
        let a = Arc3::from_three_points(&p(1.0, 0.0, 0.0), &p(0.0, 1.0, 0.0), &p(-1.0, 0.0, 2.0), Plane::Xy).unwrap();
        assert!(close(&a.center, &p(0.0, 0.0, 0.0)));
        assert!(a.ccw);
        assert!((a.sweep() - PI).abs() < 1e-14);
        assert!((a.rise() - 2.0).abs() < 1e-15);
        let b = Arc3::from_three_points(&p(1.0, 0.0, 0.0), &p(0.0, -1.0, 0.0), &p(-1.0, 0.0, 0.0), Plane::Xy).unwrap();
        assert!(!b.ccw);
        assert!(Arc3::from_three_points(&p(0.0, 0.0, 0.0), &p(1.0, 1.0, 0.0), &p(2.0, 2.0, 0.0), Plane::Xy).is_none());
        assert!(Arc3::from_three_points(&p(0.0, 0.0, 0.0), &p(1.0, 1.0, 0.0), &p(0.0, 0.0, 0.0), Plane::Xy).is_none());
        // Collinear in XY but not in XZ.
        let c = Arc3::from_three_points(&p(0.0, 0.0, 0.0), &p(1.0, 0.0, 1.0), &p(2.0, 0.0, 0.0), Plane::Xz).unwrap();
        assert!(close(&c.center, &p(1.0, 0.0, 0.0)));
    }

    #[test]
    fn split_keeps_turns_and_rise() {
        let h = Arc3::new(p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 5.0), true, Plane::Xy, 2).unwrap();
        let total = h.sweep();
        assert!((total - (2.0 * TAU + PI / 2.0)).abs() < 1e-13);
        let (a, b) = h.split_at(0.6).unwrap();
        assert!((a.sweep() - 0.6 * total).abs() < 1e-9);
        assert!((b.sweep() - 0.4 * total).abs() < 1e-9);
        assert!((a.rise() - 3.0).abs() < 1e-12);
        assert_eq!(a.end, b.start);
        assert_eq!(b.end, h.end);
        assert!((b.center.z - 3.0).abs() < 1e-12);
        assert!(h.split_at(0.0).is_none());
        assert!(h.split_at(f64::NAN).is_none());
        assert!(h.split_at(1e-18).is_none());
    }

    #[test]
    fn degenerate_input_gives_none_not_panics() {
        let o = p(0.0, 0.0, 0.0);
        assert!(Arc3::new(o, o, o, true, Plane::Xy, 0).is_none());
        assert!(Arc3::new(o, p(f64::NAN, 0.0, 0.0), o, true, Plane::Xy, 0).is_none());
        assert!(Arc3::from_three_points(&o, &p(f64::INFINITY, 0.0, 0.0), &p(1.0, 1.0, 0.0), Plane::Xy).is_none());
        // Unchecked construction with garbage still must not panic.
        let bad = Arc3 {
            center: o,
            start: p(f64::NAN, 1.0, 0.0),
            end: o,
            ccw: true,
            plane: Plane::Xy,
            extra_turns: u32::MAX,
        };
        let _ = (
            bad.length(),
            bad.point_at(0.5),
            bad.bbox(),
            bad.reversed(),
            bad.split_at(0.5),
        );
        assert!(bad.tangent_at(0.5).is_none());
        assert!(bad.closest_point(&o).is_none());
        let zero = Arc3 {
            center: o,
            start: o,
            end: o,
            ccw: true,
            plane: Plane::Xy,
            extra_turns: 0,
        };
        assert!(zero.tangent_at(0.3).is_none());
        assert_eq!(zero.length(), 0.0);
        assert!(zero.split_at(0.5).is_none());
        assert_eq!(zero.point_at_length(1.0), None);
        let huge = Arc3 {
            extra_turns: u32::MAX,
            ..zero
        };
        let _ = huge.bbox();
    }

    proptest::proptest! {
        /// The start angle and sweep together are bit for bit the two
        /// asked for apart: on arcs of either turn, full circles (start
        /// at end), extra turns and planes other than XY.
        #[test]
        fn start_angle_and_sweep_are_the_separate_ones(
            cx in -1e4f64..1e4, cy in -1e4f64..1e4,
            r in 1e-6f64..1e3,
            a0 in -7.0f64..7.0,
            a1 in -7.0f64..7.0,
            full: bool,
            ccw: bool,
            extra_turns in 0u32..3,
            plane in proptest::sample::select(vec![Plane::Xy, Plane::Xz, Plane::Yz]),
        ) {
            let c = P3::new(cx, cy, 1.5);
            let at = |a: f64| {
                let mut p = c;
                let (i, j, _) = plane.axes();
                p[i] += r * a.cos();
                p[j] += r * a.sin();
                p
            };
            let a = Arc3 {
                center: c,
                start: at(a0),
                end: if full { at(a0) } else { at(a1) },
                ccw,
                plane,
                extra_turns,
            };
            let (s, w) = a.start_angle_and_sweep();
            proptest::prop_assert_eq!(s.to_bits(), a.start_angle().to_bits());
            proptest::prop_assert_eq!(w.to_bits(), a.sweep().to_bits());
        }

        /// `ArcFrame::within` is the exact distance's verdict: points
        /// placed at a radial offset of a few tolerances (and right at
        /// the tolerance, either side of it), at angles inside, near and
        /// past the ends, on arcs of either turn, with start and end radii
        /// a hair apart as fitted arcs have, far from the origin, and
        /// with a height off the plane.
        #[test]
        fn within_is_the_distance_verdict(
            cx in -1e4f64..1e4, cy in -1e4f64..1e4,
            r in 1e-3f64..1e3,
            a0 in -7.0f64..7.0,
            sweep in 1e-6f64..6.2,
            ccw: bool,
            hair in -1e-12f64..1e-12,
            at in -0.2f64..1.2,
            off_tols in -3.0f64..3.0,
            exact_edge in proptest::sample::select(vec![None, Some(1.0 - 1e-15), Some(1.0), Some(1.0 + 1e-15)]),
            tol in proptest::sample::select(vec![1e-6, 1e-3, 0.05]),
            dz in proptest::sample::select(vec![0.0, 1e-4, 0.02]),
        ) {
            let sg = if ccw { 1.0 } else { -1.0 };
            let pt = |a: f64, rr: f64, z: f64| p(cx + rr * a.cos(), cy + rr * a.sin(), z);
            let arc = Arc3 {
                center: p(cx, cy, 0.0),
                start: pt(a0, r, 0.0),
                end: pt(a0 + sg * sweep, r * (1.0 + hair), 0.0),
                ccw,
                plane: Plane::Xy,
                extra_turns: 0,
            };
            let f = ArcFrame::new(&arc);
            let off = match exact_edge {
                Some(k) => k * tol * off_tols.signum(),
                None => off_tols * tol,
            };
            let q = pt(a0 + sg * sweep * at, r + off, dz);
            let want = f.distance(&q).is_some_and(|d| d <= tol);
            proptest::prop_assert_eq!(f.within(&q, tol), want, "q {:?} off {} tol {}", q, off, tol);
        }
    }
}
