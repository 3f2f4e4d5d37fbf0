//! Axis-aligned bounding boxes.
//!
//! Used for quick rejection (spatial hashing of chain ends, travel-limit
//! checks, stock sizing, previews). A box starts empty and grows by points
//! or other boxes; the empty box is the identity of `union`.

use super::{P3, V3};

/// An axis-aligned box in machine space, `min <= max` on every axis unless
/// it is empty. The empty box has `min = +inf`, `max = -inf`, so extending
/// it by a point gives exactly that point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BBox3 {
    /// Smallest x, y, z covered.
    pub min: P3,
    /// Largest x, y, z covered.
    pub max: P3,
}

impl Default for BBox3 {
    fn default() -> Self {
        Self::empty()
    }
}

impl BBox3 {
    /// The box covering nothing; the starting value when accumulating.
    pub fn empty() -> Self {
        Self {
            min: P3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            max: P3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        }
    }

    /// The box covering exactly one point (empty if the point is not finite).
    pub fn from_point(p: &P3) -> Self {
        let mut b = Self::empty();
        b.extend(p);
        b
    }

    /// The smallest box covering all finite points of an iterator.
    ///
    /// ```
    /// use microcam::geometry::{BBox3, P3};
    /// let b = BBox3::from_points(&[P3::new(1.0, -2.0, 0.0), P3::new(-1.0, 3.0, 0.5), P3::new(f64::NAN, 0.0, 0.0)]);
    /// assert_eq!((b.min, b.max), (P3::new(-1.0, -2.0, 0.0), P3::new(1.0, 3.0, 0.5)));
    /// assert!(BBox3::empty().is_empty());
    /// ```
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a P3>) -> Self {
        let mut b = Self::empty();
        for p in points {
            b.extend(p);
        }
        b
    }

    /// True when the box covers no point.
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// Grow the box to cover `p`. Points with a NaN or infinite coordinate are
    /// ignored, so one bad value cannot poison a whole drawing's extents.
    pub fn extend(&mut self, p: &P3) {
        if !p.iter().all(|c| c.is_finite()) {
            return;
        }
        for i in 0..3 {
            self.min[i] = self.min[i].min(p[i]);
            self.max[i] = self.max[i].max(p[i]);
        }
    }

    /// The smallest box covering both boxes.
    pub fn union(&self, other: &BBox3) -> BBox3 {
        if self.is_empty() {
            return *other;
        }
        if other.is_empty() {
            return *self;
        }
        BBox3 {
            min: P3::new(
                self.min.x.min(other.min.x),
                self.min.y.min(other.min.y),
                self.min.z.min(other.min.z),
            ),
            max: P3::new(
                self.max.x.max(other.max.x),
                self.max.y.max(other.max.y),
                self.max.z.max(other.max.z),
            ),
        }
    }

    /// True when `p` lies inside or on the boundary. Never true for the
    /// empty box or a NaN point.
    pub fn contains(&self, p: &P3) -> bool {
        self.contains_tol(p, 0.0)
    }

    /// True when `p` lies inside the box grown by `tol` on every side.
    pub fn contains_tol(&self, p: &P3, tol: f64) -> bool {
        (0..3).all(|i| self.min[i] - tol <= p[i] && p[i] <= self.max[i] + tol)
    }

    /// True when the two boxes share at least one point (touching counts).
    pub fn intersects(&self, other: &BBox3) -> bool {
        (0..3).all(|i| self.min[i] <= other.max[i] && other.min[i] <= self.max[i])
    }

    /// Edge lengths along x, y, z; zero for the empty box.
    pub fn size(&self) -> V3 {
        if self.is_empty() {
            V3::zeros()
        } else {
            self.max - self.min
        }
    }

    /// The parameters `[t0, t1]` within `span` of the points `p + t d`
    /// inside the box grown by `grow` on every side (the slab test);
    /// `None` when there are none. A zero component of `d` keeps the line
    /// in its slab or out of it whole.
    pub fn clip_line(&self, p: &P3, d: &V3, span: (f64, f64), grow: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = span;
        for k in 0..3 {
            let (lo, hi) = (self.min[k] - grow, self.max[k] + grow);
            if d[k] == 0.0 {
                if p[k] < lo || p[k] > hi {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - p[k]) / d[k], (hi - p[k]) / d[k]);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }

    /// The centre of the box; `None` for the empty box.
    pub fn center(&self) -> Option<P3> {
        if self.is_empty() {
            None
        } else {
            Some(nalgebra::center(&self.min, &self.max))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_box_is_identity_of_union_and_contains_nothing() {
        let e = BBox3::empty();
        assert!(e.is_empty());
        assert!(!e.contains(&P3::origin()));
        assert_eq!(e.size(), V3::zeros());
        assert!(e.center().is_none());
        let b = BBox3::from_point(&P3::new(1.0, 2.0, 3.0));
        assert!(!b.is_empty());
        assert_eq!(e.union(&b), b);
        assert_eq!(b.union(&e), b);
    }

    #[test]
    fn lines_are_clipped_to_the_grown_box() {
        let b = BBox3::from_points(&[P3::new(0.0, 0.0, 0.0), P3::new(2.0, 1.0, 1.0)]);
        let (p, d) = (P3::new(-1.0, 0.5, 0.5), V3::new(1.0, 0.0, 0.0));
        assert_eq!(b.clip_line(&p, &d, (0.0, 10.0), 0.0), Some((1.0, 3.0)));
        assert_eq!(b.clip_line(&p, &d, (0.0, 10.0), 0.5), Some((0.5, 3.5)));
        assert_eq!(b.clip_line(&p, &d, (0.0, 0.9), 0.0), None);
        assert_eq!(b.clip_line(&p, &d, (2.0, 2.5), 0.0), Some((2.0, 2.5)));
        // Parallel to a slab: inside it whole, or out of it whole.
        assert_eq!(b.clip_line(&P3::new(-1.0, 1.2, 0.5), &d, (0.0, 10.0), 0.0), None);
        assert_eq!(
            b.clip_line(&P3::new(-1.0, 1.2, 0.5), &d, (0.0, 10.0), 0.25),
            Some((0.75, 3.25))
        );
        // Oblique, through a corner region.
        let q = b.clip_line(&P3::new(-1.0, -1.0, -1.0), &V3::new(1.0, 1.0, 1.0), (0.0, 10.0), 0.0);
        assert_eq!(q, Some((1.0, 2.0)));
    }

    #[test]
    fn extend_union_and_contains() {
        let mut b = BBox3::from_points(&[P3::new(0.0, 0.0, 0.0), P3::new(2.0, -1.0, 4.0)]);
        assert_eq!(b.min, P3::new(0.0, -1.0, 0.0));
        assert_eq!(b.max, P3::new(2.0, 0.0, 4.0));
        b.extend(&P3::new(f64::NAN, 100.0, 100.0));
        assert_eq!(b.max, P3::new(2.0, 0.0, 4.0), "NaN points are ignored");
        assert!(b.contains(&P3::new(1.0, -0.5, 4.0)));
        assert!(!b.contains(&P3::new(1.0, 0.1, 2.0)));
        assert!(b.contains_tol(&P3::new(1.0, 0.1, 2.0), 0.1));
        assert!(!b.contains(&P3::new(f64::NAN, 0.0, 0.0)));
        let c = BBox3::from_point(&P3::new(5.0, 5.0, 5.0));
        let u = b.union(&c);
        assert_eq!(u.min, P3::new(0.0, -1.0, 0.0));
        assert_eq!(u.max, P3::new(5.0, 5.0, 5.0));
        assert_eq!(u.size(), V3::new(5.0, 6.0, 5.0));
        assert_eq!(u.center(), Some(P3::new(2.5, 2.0, 2.5)));
        assert!(!b.intersects(&c));
        assert!(u.intersects(&c));
        assert!(!BBox3::empty().intersects(&u));
    }
}
