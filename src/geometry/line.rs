//! Straight segments in space.
//!
//! A `Line3` is the exact primitive behind DXF LINEs, G1 moves, leads and
//! links. Its parameter `t` runs from 0 at `start` to 1 at `end`, uniformly
//! in arc length, so `point_at(t)` and `point_at_length(s)` agree.

use super::bbox::BBox3;
use super::tol::positive_finite;
use super::{P3, V3};
use nalgebra::Point;

/// A straight segment from `start` to `end`. A zero-length segment is
/// allowed (it is a point); methods that need a direction return `None`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line3 {
    /// Where travel begins (t = 0).
    pub start: P3,
    /// Where travel ends (t = 1).
    pub end: P3,
}

impl Line3 {
    /// A segment from `start` to `end`.
    pub fn new(start: P3, end: P3) -> Self {
        Self { start, end }
    }

    /// `end - start`: the displacement, not normalised.
    pub fn delta(&self) -> V3 {
        self.end - self.start
    }

    /// Length in mm.
    pub fn length(&self) -> f64 {
        self.delta().norm()
    }

    /// True when the segment is shorter than `tol` (a point, for all purposes).
    /// NaN coordinates count as degenerate.
    pub fn is_degenerate(&self, tol: f64) -> bool {
        let len = self.length();
        len.is_nan() || tol.is_nan() || len <= tol
    }

    /// The point at parameter `t` (0 = start, 1 = end). `t` outside [0, 1]
    /// extrapolates along the line; the end points are returned exactly.
    pub fn point_at(&self, t: f64) -> P3 {
        if t == 0.0 {
            self.start
        } else if t == 1.0 {
            self.end
        } else {
            self.start + self.delta() * t
        }
    }

    /// The point `s` mm along the segment from `start`. `None` for a
    /// zero-length segment (no direction to walk).
    ///
    /// ```
    /// use microcam::geometry::{Line3, P3};
    /// let s = Line3::new(P3::origin(), P3::new(3.0, 4.0, 0.0));
    /// assert_eq!(s.length(), 5.0);
    /// assert_eq!(s.point_at_length(2.5), Some(P3::new(1.5, 2.0, 0.0)));
    /// assert_eq!(Line3::new(P3::origin(), P3::origin()).point_at_length(1.0), None);
    /// ```
    pub fn point_at_length(&self, s: f64) -> Option<P3> {
        let len = self.length();
        if positive_finite(len) {
            Some(self.point_at(s / len))
        } else {
            None
        }
    }

    /// Unit direction of travel; `None` when the segment has no length.
    pub fn tangent(&self) -> Option<V3> {
        let len = self.length();
        if positive_finite(len) {
            Some(self.delta() / len)
        } else {
            None
        }
    }

    /// The tight axis-aligned box of the segment.
    pub fn bbox(&self) -> BBox3 {
        BBox3::from_points(&[self.start, self.end])
    }

    /// The point of the segment nearest `p` and its parameter in [0, 1].
    /// A zero-length segment answers its start with t = 0.
    ///
    /// ```
    /// use microcam::geometry::{Line3, P3};
    /// let s = Line3::new(P3::origin(), P3::new(10.0, 0.0, 0.0));
    /// assert_eq!(s.closest_point(&P3::new(4.0, 3.0, 0.0)), (P3::new(4.0, 0.0, 0.0), 0.4));
    /// assert_eq!(s.distance(&P3::new(13.0, 4.0, 0.0)), 5.0);
    /// ```
    pub fn closest_point(&self, p: &P3) -> (P3, f64) {
        let d = self.delta();
        let l2 = d.norm_squared();
        if !positive_finite(l2) {
            return (self.start, 0.0);
        }
        let t = ((p - self.start).dot(&d) / l2).clamp(0.0, 1.0);
        if t.is_nan() {
            return (self.start, 0.0);
        }
        (self.point_at(t), t)
    }

    /// Distance from `p` to the nearest point of the segment.
    pub fn distance(&self, p: &P3) -> f64 {
        (p - self.closest_point(p).0).norm()
    }

    /// The same segment travelled the other way.
    pub fn reversed(&self) -> Line3 {
        Line3::new(self.end, self.start)
    }

    /// The two pieces either side of parameter `t`; `None` unless
    /// `0 < t < 1` (splitting at an end would leave a zero-length piece).
    pub fn split_at(&self, t: f64) -> Option<(Line3, Line3)> {
        if t > 0.0 && t < 1.0 {
            let m = self.point_at(t);
            Some((Line3::new(self.start, m), Line3::new(m, self.end)))
        } else {
            None
        }
    }
}

/// Distance from `p` to the segment from `a` to `b`, in any dimension
/// (2-D for plane work, 3-D in space): the perpendicular foot's parameter
/// is clamped to the segment, so beyond an end the distance is to that
/// end. A zero-length segment (`a == b`) answers the distance to `a`.
///
/// This is the one formula every caller uses, and its rounding is part of
/// golden outputs (arc fitting, pocket motions): the nearest point is
/// `a + (b - a)·t`, not `b` itself at `t = 1`, unlike
/// [`Line3::closest_point`], which returns the stored end exactly.
///
/// ```
/// use microcam::geometry::line::point_segment_distance;
/// use microcam::geometry::{P2, P3};
/// let (a, b) = (P2::new(0.0, 0.0), P2::new(4.0, 0.0));
/// assert_eq!(point_segment_distance(&P2::new(1.0, 3.0), &a, &b), 3.0);
/// assert_eq!(point_segment_distance(&P2::new(7.0, 4.0), &a, &b), 5.0);
/// assert_eq!(point_segment_distance(&P2::new(3.0, 4.0), &a, &a), 5.0);
/// let up = P3::new(0.0, 0.0, 2.0);
/// assert_eq!(point_segment_distance(&P3::new(1.0, 0.0, 1.0), &P3::origin(), &up), 1.0);
/// ```
pub fn point_segment_distance<const D: usize>(p: &Point<f64, D>, a: &Point<f64, D>, b: &Point<f64, D>) -> f64 {
    let d = b - a;
    let l2 = d.norm_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(&d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + d * t)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn l(a: [f64; 3], b: [f64; 3]) -> Line3 {
        Line3::new(P3::from(a), P3::from(b))
    }

    #[test]
    fn length_points_and_tangent() {
        let s = l([0.0, 0.0, 0.0], [3.0, 4.0, 0.0]);
        assert_eq!(s.length(), 5.0);
        assert_eq!(s.point_at(0.5), P3::new(1.5, 2.0, 0.0));
        assert_eq!(s.point_at_length(2.5), Some(P3::new(1.5, 2.0, 0.0)));
        assert_eq!(s.point_at(1.0), s.end);
        assert_eq!(s.tangent(), Some(V3::new(0.6, 0.8, 0.0)));
        let b = s.bbox();
        assert_eq!(b.min, P3::new(0.0, 0.0, 0.0));
        assert_eq!(b.max, P3::new(3.0, 4.0, 0.0));
        assert_eq!(s.reversed().start, s.end);
    }

    #[test]
    fn closest_point_clamps_to_the_segment() {
        let s = l([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
        assert_eq!(s.closest_point(&P3::new(4.0, 3.0, 0.0)), (P3::new(4.0, 0.0, 0.0), 0.4));
        assert_eq!(s.closest_point(&P3::new(-4.0, 3.0, 0.0)), (P3::new(0.0, 0.0, 0.0), 0.0));
        assert_eq!(s.closest_point(&P3::new(14.0, 0.0, 3.0)).1, 1.0);
        assert_eq!(s.distance(&P3::new(13.0, 4.0, 0.0)), 5.0);
        assert_eq!(s.distance(&P3::new(5.0, 0.0, -2.0)), 2.0);
    }

    #[test]
    fn degenerate_segments_do_not_panic() {
        let p = l([1.0, 1.0, 1.0], [1.0, 1.0, 1.0]);
        assert!(p.is_degenerate(1e-9));
        assert_eq!(p.tangent(), None);
        assert_eq!(p.point_at_length(1.0), None);
        assert_eq!(p.closest_point(&P3::new(5.0, 1.0, 1.0)), (P3::new(1.0, 1.0, 1.0), 0.0));
        assert!(p.split_at(0.5).is_some());
        assert_eq!(point_segment_distance(&P3::new(5.0, 4.0, 1.0), &p.start, &p.end), 5.0);
        let n = l([f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert!(n.is_degenerate(1e-9));
        assert_eq!(n.tangent(), None);
        assert_eq!(n.closest_point(&P3::origin()).1, 0.0);
        assert!(n.bbox().min.x == 1.0, "NaN end ignored by the box");
        assert!(l([0.0; 3], [1.0, 0.0, 0.0]).split_at(1.0).is_none());
    }

    fn coord() -> impl Strategy<Value = f64> {
        -100.0..100.0f64
    }

    fn point() -> impl Strategy<Value = P3> {
        (coord(), coord(), coord()).prop_map(|(x, y, z)| P3::new(x, y, z))
    }

    proptest! {
        #[test]
        fn closest_point_beats_dense_samples(a in point(), b in point(), p in point()) {
            let s = Line3::new(a, b);
            let (q, t) = s.closest_point(&p);
            prop_assert!((0.0..=1.0).contains(&t));
            prop_assert!((s.point_at(t) - q).norm() < 1e-9);
            let best = (q - p).norm();
            for i in 0..=200 {
                let sample = s.point_at(i as f64 / 200.0);
                prop_assert!(best <= (sample - p).norm() + 1e-9);
            }
        }

        #[test]
        fn point_segment_distance_agrees_with_line3(a in point(), b in point(), p in point()) {
            // The same nearest point as Line3 (up to the rounding of an
            // end), in 3-D and in the XY projection.
            let d = point_segment_distance(&p, &a, &b);
            prop_assert!((d - Line3::new(a, b).distance(&p)).abs() <= 1e-9 * (1.0 + d));
            let flat = |q: P3| P3::new(q.x, q.y, 0.0);
            let d2 = point_segment_distance(&p.xy(), &a.xy(), &b.xy());
            prop_assert!((d2 - Line3::new(flat(a), flat(b)).distance(&flat(p))).abs() <= 1e-9 * (1.0 + d2));
            // Symmetric in the ends (up to rounding), and never more than
            // the nearer end.
            prop_assert!((d - point_segment_distance(&p, &b, &a)).abs() <= 1e-9 * (1.0 + d));
            prop_assert!(d <= (p - a).norm().min((p - b).norm()) + 1e-12);
        }

        #[test]
        fn split_halves_add_up(a in point(), b in point(), t in 0.01..0.99f64) {
            let s = Line3::new(a, b);
            let (h1, h2) = s.split_at(t).unwrap();
            prop_assert!((h1.length() + h2.length() - s.length()).abs() < 1e-9);
            prop_assert_eq!(h1.start, s.start);
            prop_assert_eq!(h2.end, s.end);
            prop_assert_eq!(h1.end, h2.start);
            prop_assert_eq!(s.reversed().reversed(), s);
        }
    }
}
