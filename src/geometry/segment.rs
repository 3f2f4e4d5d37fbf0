//! One exact piece of a path: a straight [`Line3`] or a circular or helical
//! [`Arc3`].
//!
//! Chains (what a drawing is), planned laser paths and toolpath moves all
//! carry this one type, so every question about a line-or-arc (its length,
//! sweep, midpoint, tangents, extents, where it splits, how it reverses) is
//! answered here and nowhere else.
//!
//! Chains use only XY arcs at constant height, built with
//! [`Segment::arc_xy`]: start equal to end is a full circle. Planned paths
//! and toolpath moves may hold arcs in any principal plane, helices and
//! extra turns.

use super::arc::Arc3;
use super::bbox::BBox3;
use super::line::Line3;
use super::{P2, P3, Plane, V3};

/// A line or an arc, in travel order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Segment {
    /// A straight segment.
    Line(Line3),
    /// A circular arc, or a helix rising along its plane normal.
    Arc(Arc3),
}

/// An XY arc taken apart: centre, radius, start angle and signed sweep, as
/// [`Segment::to_arc_xy`] gives it. For code that works in angles (sampling
/// a circle, angular intervals) rather than points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcXy {
    /// Centre in XY.
    pub center: P2,
    /// Radius (mm): the distance from the centre to the start.
    pub radius: f64,
    /// Angle of the start point about the centre (radians, `(-π, π]`).
    pub start_angle: f64,
    /// Signed sweep (radians, positive counter-clockwise; a full turn when
    /// the arc closes).
    pub sweep: f64,
}

impl ArcXy {
    /// The point at angle `a` on the circle.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::arc_xy(P3::new(2.0, 0.0, 0.0), P3::new(0.0, 2.0, 0.0), P3::origin(), true);
    /// let a = s.to_arc_xy().unwrap();
    /// let p = a.point_at_angle(a.start_angle + a.sweep);
    /// assert!((p.x - 0.0).abs() < 1e-12 && (p.y - 2.0).abs() < 1e-12);
    /// ```
    pub fn point_at_angle(&self, a: f64) -> P2 {
        P2::new(
            self.center.x + self.radius * a.cos(),
            self.center.y + self.radius * a.sin(),
        )
    }

    /// How far (radians, in the direction of travel, in `[0, 2π)`) the
    /// direction `a` lies from the start: `a` is on the arc when this is at
    /// most `|sweep|`, and at parameter `offset / |sweep|`.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// // Clockwise from +x: -y is a quarter turn on, +y three quarters.
    /// let s = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(0.0, -1.0, 0.0), P3::origin(), false);
    /// let a = s.to_arc_xy().unwrap();
    /// assert!((a.angle_offset(-std::f64::consts::FRAC_PI_2) - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    /// assert!(a.angle_offset(std::f64::consts::FRAC_PI_2) > a.sweep.abs());
    /// ```
    pub fn angle_offset(&self, a: f64) -> f64 {
        if self.sweep >= 0.0 {
            super::tol::rem_tau(a - self.start_angle)
        } else {
            super::tol::rem_tau(self.start_angle - a)
        }
    }

    /// True when the direction `a` lies on the arc (ends included).
    pub fn contains_angle(&self, a: f64) -> bool {
        self.angle_offset(a) <= self.sweep.abs()
    }
}

impl Segment {
    /// A straight segment from `a` to `b`.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::line(P3::origin(), P3::new(3.0, 4.0, 0.0));
    /// assert_eq!(s.length(), 5.0);
    /// ```
    pub fn line(a: P3, b: P3) -> Segment {
        Segment::Line(Line3::new(a, b))
    }

    /// An arc in the XY plane around `center`, as chains carry it: taken as
    /// given (not checked, the centre keeps its own height), no extra turns;
    /// start equal to end is a full circle.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let p = P3::new(1.0, 0.0, 0.0);
    /// let circle = Segment::arc_xy(p, p, P3::origin(), false);
    /// assert!((circle.sweep().unwrap() + std::f64::consts::TAU).abs() < 1e-15);
    /// ```
    pub fn arc_xy(start: P3, end: P3, center: P3, ccw: bool) -> Segment {
        Segment::Arc(Arc3 {
            center,
            start,
            end,
            ccw,
            plane: Plane::Xy,
            extra_turns: 0,
        })
    }

    /// The same segment, checked the way [`Arc3::new`] checks an arc: `None`
    /// for an arc with a non-finite coordinate or a radius below
    /// [`EPS_LEN`](super::EPS_LEN); the arc's centre is moved to its start's
    /// height. Lines pass unchanged.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let o = P3::origin();
    /// assert!(Segment::arc_xy(o, o, o, true).checked().is_none());
    /// let a = Segment::arc_xy(P3::new(1.0, 0.0, 2.0), P3::new(0.0, 1.0, 2.0), o, true);
    /// assert_eq!(a.checked().unwrap().arc().unwrap().center.z, 2.0);
    /// ```
    pub fn checked(&self) -> Option<Segment> {
        match self {
            Segment::Line(_) => Some(*self),
            Segment::Arc(a) => Arc3::new(a.center, a.start, a.end, a.ccw, a.plane, a.extra_turns).map(Segment::Arc),
        }
    }

    /// The arc, if this is one.
    pub fn arc(&self) -> Option<&Arc3> {
        match self {
            Segment::Arc(a) => Some(a),
            Segment::Line(_) => None,
        }
    }

    /// True for an arc.
    pub fn is_arc(&self) -> bool {
        matches!(self, Segment::Arc(_))
    }

    /// Where travel begins.
    pub fn start(&self) -> P3 {
        match self {
            Segment::Line(l) => l.start,
            Segment::Arc(a) => a.start,
        }
    }

    /// Where travel ends.
    pub fn end(&self) -> P3 {
        match self {
            Segment::Line(l) => l.end,
            Segment::Arc(a) => a.end,
        }
    }

    /// Move the start point to `p` (snapping a piece onto its neighbour; an
    /// arc keeps its centre).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let mut s = Segment::line(P3::origin(), P3::new(1.0, 0.0, 0.0));
    /// s.set_start(P3::new(0.0, 1.0, 0.0));
    /// assert_eq!(s.start(), P3::new(0.0, 1.0, 0.0));
    /// ```
    pub fn set_start(&mut self, p: P3) {
        match self {
            Segment::Line(l) => l.start = p,
            Segment::Arc(a) => a.start = p,
        }
    }

    /// Move the end point to `p` (an arc keeps its centre).
    pub fn set_end(&mut self, p: P3) {
        match self {
            Segment::Line(l) => l.end = p,
            Segment::Arc(a) => a.end = p,
        }
    }

    /// The same segment travelled the other way (see [`Arc3::reversed`]).
    /// Reversing twice gives back the original exactly.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let a = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.0), P3::origin(), true);
    /// let r = a.reversed();
    /// assert_eq!(r.start(), a.end());
    /// assert!(!r.arc().unwrap().ccw);
    /// assert_eq!(r.reversed(), a);
    /// ```
    pub fn reversed(&self) -> Segment {
        match self {
            Segment::Line(l) => Segment::Line(l.reversed()),
            Segment::Arc(a) => Segment::Arc(a.reversed()),
        }
    }

    /// Path length (mm): the arc length for arcs (helical rise included).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let quarter = Segment::arc_xy(P3::new(2.0, 0.0, 0.0), P3::new(0.0, 2.0, 0.0), P3::origin(), true);
    /// assert!((quarter.length() - std::f64::consts::PI).abs() < 1e-14);
    /// ```
    pub fn length(&self) -> f64 {
        match self {
            Segment::Line(l) => l.length(),
            Segment::Arc(a) => a.length(),
        }
    }

    /// An arc's signed sweep (radians, positive counter-clockwise; see
    /// [`Arc3::sweep`]); `None` for a line.
    pub fn sweep(&self) -> Option<f64> {
        self.arc().map(Arc3::sweep)
    }

    /// An arc's radius (mm); `None` for a line.
    pub fn radius(&self) -> Option<f64> {
        self.arc().map(Arc3::radius)
    }

    /// Radius of curvature of the path (infinite for a line). For a helix
    /// the true curvature radius is r·(1 + (rise/(r·sweep))²), larger than
    /// r; this answers r, the conservative (larger acceleration) figure.
    pub fn curvature_radius(&self) -> f64 {
        match self {
            Segment::Line(_) => f64::INFINITY,
            Segment::Arc(a) => a.radius(),
        }
    }

    /// The plane the segment turns in: the arc's own plane, or XY for lines.
    pub fn plane(&self) -> Plane {
        match self {
            Segment::Line(_) => Plane::Xy,
            Segment::Arc(a) => a.plane,
        }
    }

    /// The point at parameter `t` (0 = start, 1 = end, uniform in length);
    /// the ends are returned exactly.
    pub fn point_at(&self, t: f64) -> P3 {
        match self {
            Segment::Line(l) => l.point_at(t),
            Segment::Arc(a) => a.point_at(t),
        }
    }

    /// The point halfway along the segment.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let half = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(-1.0, 0.0, 0.0), P3::origin(), true);
    /// assert!((half.midpoint() - P3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
    /// ```
    pub fn midpoint(&self) -> P3 {
        self.point_at(0.5)
    }

    /// The point `s` mm along the segment from its start, `s` clamped to
    /// the segment (a zero-length segment answers its start).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::line(P3::origin(), P3::new(4.0, 0.0, 0.0));
    /// assert_eq!(s.point_at_length(1.0), P3::new(1.0, 0.0, 0.0));
    /// assert_eq!(s.point_at_length(9.0), s.end());
    /// ```
    pub fn point_at_length(&self, s: f64) -> P3 {
        self.point_at(length_fraction(s, self.length()))
    }

    /// Unit tangent in the direction of travel at parameter `t`; `None` for
    /// a segment without length.
    pub fn tangent_at(&self, t: f64) -> Option<V3> {
        match self {
            Segment::Line(l) => l.tangent(),
            Segment::Arc(a) => a.tangent_at(t),
        }
    }

    /// Unit direction of travel at the start; the zero vector for a
    /// degenerate piece. Planar arcs answer without trigonometry (planning
    /// asks this at every joint of a million-segment job).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::{P3, V3};
    /// let a = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.0), P3::origin(), true);
    /// assert_eq!(a.start_tangent(), V3::new(0.0, 1.0, 0.0));
    /// assert_eq!(a.end_tangent(), V3::new(-1.0, 0.0, 0.0));
    /// ```
    pub fn start_tangent(&self) -> V3 {
        match self {
            Segment::Line(l) => l.tangent(),
            Segment::Arc(a) => planar_tangent(a, &a.start).or_else(|| a.tangent_at(0.0)),
        }
        .unwrap_or_else(V3::zeros)
    }

    /// Unit direction of travel at the end; the zero vector for a
    /// degenerate piece.
    pub fn end_tangent(&self) -> V3 {
        match self {
            Segment::Line(l) => l.tangent(),
            Segment::Arc(a) => planar_tangent(a, &a.end).or_else(|| a.tangent_at(1.0)),
        }
        .unwrap_or_else(V3::zeros)
    }

    /// The tight axis-aligned box (an arc's box includes the axis extremes
    /// its sweep passes).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let half = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(-1.0, 0.0, 0.0), P3::origin(), true);
    /// assert!((half.bbox().max.y - 1.0).abs() < 1e-15);
    /// ```
    pub fn bbox(&self) -> BBox3 {
        match self {
            Segment::Line(l) => l.bbox(),
            Segment::Arc(a) => a.bbox(),
        }
    }

    /// The two pieces either side of parameter `t`; `None` unless
    /// `0 < t < 1` (and, for arcs, both pieces have length: see
    /// [`Arc3::split_at`]).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::line(P3::origin(), P3::new(2.0, 0.0, 0.0));
    /// let (a, b) = s.split_at(0.25).unwrap();
    /// assert_eq!((a.length(), b.length()), (0.5, 1.5));
    /// ```
    pub fn split_at(&self, t: f64) -> Option<(Segment, Segment)> {
        match self {
            Segment::Line(l) => l.split_at(t).map(|(a, b)| (Segment::Line(a), Segment::Line(b))),
            Segment::Arc(a) => a.split_at(t).map(|(x, y)| (Segment::Arc(x), Segment::Arc(y))),
        }
    }

    /// The two pieces either side of `s` mm from the start; `None` when `s`
    /// is within `min_piece` of either end.
    pub fn split_at_length(&self, s: f64, min_piece: f64) -> Option<(Segment, Segment)> {
        let len = self.length();
        if !(s > min_piece && s < len - min_piece) {
            return None;
        }
        self.split_at(s / len)
    }

    /// The point of the segment nearest `p`, with its parameter in [0, 1].
    /// `None` for a helical arc or non-finite input (see
    /// [`Arc3::closest_point`]).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::line(P3::origin(), P3::new(10.0, 0.0, 0.0));
    /// assert_eq!(s.closest_point(&P3::new(4.0, 3.0, 0.0)), Some((P3::new(4.0, 0.0, 0.0), 0.4)));
    /// assert_eq!(s.distance(&P3::new(4.0, 3.0, 0.0)), Some(3.0));
    /// ```
    pub fn closest_point(&self, p: &P3) -> Option<(P3, f64)> {
        match self {
            Segment::Line(l) => Some(l.closest_point(p)),
            Segment::Arc(a) => a.closest_point(p),
        }
    }

    /// Distance from `p` to the segment; `None` where
    /// [`closest_point`](Self::closest_point) is.
    pub fn distance(&self, p: &P3) -> Option<f64> {
        match self {
            Segment::Line(l) => Some(l.distance(p)),
            Segment::Arc(a) => a.distance(p),
        }
    }

    /// Distance in XY from `p` to the segment: `p` is taken at the
    /// segment's start height, so a point is matched to a drawing in the
    /// plane whatever its Z. `f64::INFINITY` where
    /// [`distance`](Self::distance) has no answer (a segment read from a
    /// file may want [`checked`](Self::checked) first).
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::line(P3::new(0.0, 0.0, 5.0), P3::new(4.0, 0.0, 5.0));
    /// assert_eq!(s.distance_xy(&P3::new(1.0, 3.0, -2.0)), 3.0);
    /// ```
    pub fn distance_xy(&self, p: &P3) -> f64 {
        self.distance(&P3::new(p.x, p.y, self.start().z))
            .unwrap_or(f64::INFINITY)
    }

    /// The segment shifted by `d`.
    pub fn translated(&self, d: V3) -> Segment {
        match self {
            Segment::Line(l) => Segment::line(l.start + d, l.end + d),
            Segment::Arc(a) => Segment::Arc(Arc3 {
                center: a.center + d,
                start: a.start + d,
                end: a.end + d,
                ..*a
            }),
        }
    }

    /// True when every coordinate (ends and an arc's centre) is finite.
    pub fn is_finite(&self) -> bool {
        let ok = |p: &P3| super::tol::finite_p3(p);
        match self {
            Segment::Line(l) => ok(&l.start) && ok(&l.end),
            Segment::Arc(a) => ok(&a.start) && ok(&a.end) && ok(&a.center),
        }
    }

    /// An arc's XY geometry as centre, radius, start angle and signed sweep;
    /// `None` for a line. Meant for XY arcs (chains); an arc in another
    /// plane is read in that plane's own axes.
    ///
    /// ```
    /// use microcam::geometry::segment::Segment;
    /// use microcam::geometry::P3;
    /// let s = Segment::arc_xy(P3::new(3.0, 1.0, 0.0), P3::new(1.0, 3.0, 0.0), P3::new(1.0, 1.0, 0.0), true);
    /// let a = s.to_arc_xy().unwrap();
    /// assert_eq!((a.radius, a.start_angle), (2.0, 0.0));
    /// assert!((a.sweep - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    /// assert!(Segment::line(P3::origin(), P3::origin()).to_arc_xy().is_none());
    /// ```
    pub fn to_arc_xy(&self) -> Option<ArcXy> {
        self.arc().map(|a| {
            let (start_angle, sweep) = a.start_angle_and_sweep();
            ArcXy {
                center: a.plane.project(&a.center),
                radius: a.radius(),
                start_angle,
                sweep,
            }
        })
    }
}

/// The tangent of a planar arc at one of its end points: the radius turned
/// a quarter turn, no trigonometry. `None` for helical arcs, which keep the
/// general formula.
fn planar_tangent(a: &Arc3, p: &P3) -> Option<V3> {
    if a.rise() != 0.0 {
        return None;
    }
    let (i, j, _) = a.plane.axes();
    let (ri, rj) = (p[i] - a.center[i], p[j] - a.center[j]);
    let n = ri.hypot(rj);
    if n.is_nan() || n <= 0.0 {
        return None;
    }
    let (ti, tj) = if a.ccw { (-rj / n, ri / n) } else { (rj / n, -ri / n) };
    let mut t = V3::zeros();
    t[i] = ti;
    t[j] = tj;
    Some(t)
}

/// The parameter `t` of the point `s` mm along a piece `len` mm long,
/// clamped to the piece (0 for a piece without length): what
/// [`Segment::point_at_length`] evaluates, for callers that keep the
/// length (or an arc's frame) of a piece they sample many times.
pub fn length_fraction(s: f64, len: f64) -> f64 {
    if len > 0.0 { (s / len).clamp(0.0, 1.0) } else { 0.0 }
}

/// Exact signed area (mm²) enclosed by a closed run of segments in XY,
/// positive counter-clockwise: the shoelace sum over the chords plus each
/// arc's circular segment `r²(θ - sin θ)/2` with its signed sweep θ.
///
/// ```
/// use microcam::geometry::segment::{Segment, signed_area};
/// use microcam::geometry::P3;
/// let p = P3::new(2.0, 0.0, 0.0);
/// let circle = Segment::arc_xy(p, p, P3::origin(), true);
/// assert!((signed_area(&[circle]) - 4.0 * std::f64::consts::PI).abs() < 1e-12);
/// assert!((signed_area(&[circle.reversed()]) + 4.0 * std::f64::consts::PI).abs() < 1e-12);
/// ```
pub fn signed_area(segments: &[Segment]) -> f64 {
    let mut a = 0.0;
    for s in segments {
        let (p, q) = (s.start(), s.end());
        a += 0.5 * (p.x * q.y - q.x * p.y);
        if let Some(arc) = s.arc() {
            let r2 = (arc.start - arc.center).xy().norm_squared();
            let sw = arc.sweep();
            a += 0.5 * r2 * (sw - sw.sin());
        }
    }
    a
}

/// Total length (mm) of a run of segments.
///
/// ```
/// use microcam::geometry::segment::{Segment, total_length};
/// use microcam::geometry::P3;
/// let (a, b, c) = (P3::origin(), P3::new(1.0, 0.0, 0.0), P3::new(1.0, 2.0, 0.0));
/// assert_eq!(total_length(&[Segment::line(a, b), Segment::line(b, c)]), 3.0);
/// ```
pub fn total_length(segments: &[Segment]) -> f64 {
    segments.iter().map(Segment::length).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    fn p(x: f64, y: f64, z: f64) -> P3 {
        P3::new(x, y, z)
    }

    #[test]
    fn chain_arcs_mean_what_chains_meant() {
        // A full circle when start == end, either sense.
        let s = p(3.0, 0.0, 0.0);
        let cw = Segment::arc_xy(s, s, P3::origin(), false);
        assert_eq!(cw.sweep(), Some(-TAU));
        assert!((cw.length() - 3.0 * TAU).abs() < 1e-13);
        // A clockwise quarter from +x to -y.
        let q = Segment::arc_xy(p(1.0, 0.0, 0.0), p(0.0, -1.0, 0.0), P3::origin(), false);
        assert!((q.sweep().unwrap() + FRAC_PI_2).abs() < 1e-15);
        assert!((q.midpoint() - p(0.5f64.sqrt(), -(0.5f64.sqrt()), 0.0)).norm() < 1e-15);
        // The centre keeps its own height, and reversing keeps it there
        // (chains written back out carry the centre they were read with).
        let high = Segment::arc_xy(p(1.0, 0.0, 0.5), p(0.0, 1.0, 0.5), P3::origin(), true);
        assert_eq!(high.reversed().arc().unwrap().center, P3::origin());
        assert_eq!(high.reversed().reversed(), high);
        assert_eq!(high.checked().unwrap().arc().unwrap().center.z, 0.5);
    }

    #[test]
    fn tangents_lengths_and_splits() {
        let l = Segment::line(P3::origin(), p(0.0, 0.0, 2.0));
        assert_eq!(l.start_tangent(), V3::z());
        assert_eq!(l.curvature_radius(), f64::INFINITY);
        assert_eq!(l.plane(), Plane::Xy);
        assert!(l.split_at_length(1e-8, 1e-7).is_none());
        let (a, b) = l.split_at_length(0.5, 1e-7).unwrap();
        assert_eq!((a.end(), b.start()), (p(0.0, 0.0, 0.5), p(0.0, 0.0, 0.5)));
        let degenerate = Segment::line(P3::origin(), P3::origin());
        assert_eq!(degenerate.start_tangent(), V3::zeros());
        assert_eq!(degenerate.point_at_length(1.0), P3::origin());
        let half = Segment::arc_xy(p(1.0, 0.0, 0.0), p(-1.0, 0.0, 0.0), P3::origin(), true);
        assert_eq!(half.radius(), Some(1.0));
        assert!((half.length() - PI).abs() < 1e-15);
        assert_eq!(half.translated(V3::new(1.0, 0.0, 0.0)).start(), p(2.0, 0.0, 0.0));
        assert!(half.is_finite() && !Segment::line(p(f64::NAN, 0.0, 0.0), P3::origin()).is_finite());
        let mut m = half;
        m.set_end(p(-1.0, 1e-12, 0.0));
        assert_eq!(m.arc().unwrap().center, P3::origin());
        assert!(
            half.tangent_at(0.5)
                .is_some_and(|t| (t - V3::new(-1.0, 0.0, 0.0)).norm() < 1e-15)
        );
    }

    #[test]
    fn fast_tangents_match_the_general_ones() {
        for plane in [Plane::Xy, Plane::Xz, Plane::Yz] {
            for ccw in [true, false] {
                let c = p(0.3, -0.2, 0.1);
                let c2 = plane.project(&c);
                let s2 = P2::new(1.0, 0.5);
                let r = (s2 - c2).norm();
                let e2 = c2 + crate::geometry::V2::new(2.0f64.cos(), 2.0f64.sin()) * r;
                let nz = plane.normal_coord(&c);
                let a = Arc3::new(c, plane.lift(&s2, nz), plane.lift(&e2, nz), ccw, plane, 0).unwrap();
                let el = Segment::Arc(a);
                assert!(
                    (el.start_tangent() - a.tangent_at(0.0).unwrap()).norm() < 1e-9,
                    "{plane:?} {ccw}"
                );
                assert!(
                    (el.end_tangent() - a.tangent_at(1.0).unwrap()).norm() < 1e-6,
                    "{plane:?} {ccw}"
                );
            }
        }
    }
}
