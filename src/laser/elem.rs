//! One exact piece of a planned path: a line or a (possibly helical) arc.
//! Planning works on these rather than on toolpath records so that splitting
//! (for shutter timing) and tangent checks (for corner loops) stay exact.

use crate::geometry::arc::Arc3;
use crate::geometry::line::Line3;
use crate::geometry::{P3, Plane, V3};
use crate::model::toolpath::{ArcData, MotionKind};

/// Pieces shorter than this (mm) are dropped when splitting: a 1 nm move is
/// below every controller's resolution and would only add a block.
pub const MIN_PIECE: f64 = 1e-7;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Elem {
    Line(Line3),
    Arc(Arc3),
}

impl Elem {
    pub fn line(a: P3, b: P3) -> Elem {
        Elem::Line(Line3::new(a, b))
    }

    pub fn start(&self) -> P3 {
        match self {
            Elem::Line(l) => l.start,
            Elem::Arc(a) => a.start,
        }
    }

    pub fn end(&self) -> P3 {
        match self {
            Elem::Line(l) => l.end,
            Elem::Arc(a) => a.end,
        }
    }

    /// Move the start point to `p` (snapping a piece onto its neighbour;
    /// an arc keeps its centre).
    pub fn set_start(&mut self, p: P3) {
        match self {
            Elem::Line(l) => l.start = p,
            Elem::Arc(a) => a.start = p,
        }
    }

    /// Move the end point to `p` (an arc keeps its centre).
    pub fn set_end(&mut self, p: P3) {
        match self {
            Elem::Line(l) => l.end = p,
            Elem::Arc(a) => a.end = p,
        }
    }

    pub fn length(&self) -> f64 {
        match self {
            Elem::Line(l) => l.length(),
            Elem::Arc(a) => a.length(),
        }
    }

    /// Unit direction of travel at the start (zero vector for a degenerate piece).
    pub fn dir_start(&self) -> V3 {
        match self {
            Elem::Line(l) => l.tangent(),
            Elem::Arc(a) => planar_tangent(a, &a.start).or_else(|| a.tangent_at(0.0)),
        }
        .unwrap_or_else(V3::zeros)
    }

    /// Unit direction of travel at the end.
    pub fn dir_end(&self) -> V3 {
        match self {
            Elem::Line(l) => l.tangent(),
            Elem::Arc(a) => planar_tangent(a, &a.end).or_else(|| a.tangent_at(1.0)),
        }
        .unwrap_or_else(V3::zeros)
    }

    /// Radius of curvature of the path (infinite for a line). For a helix
    /// the curvature radius is r·(1 + (rise/(r·sweep))²), larger than r; we
    /// use r, which is the conservative (larger acceleration) figure.
    pub fn curvature_radius(&self) -> f64 {
        match self {
            Elem::Line(_) => f64::INFINITY,
            Elem::Arc(a) => a.radius(),
        }
    }

    pub fn point_at_length(&self, s: f64) -> P3 {
        let len = self.length();
        let t = if len > 0.0 { (s / len).clamp(0.0, 1.0) } else { 0.0 };
        match self {
            Elem::Line(l) => l.point_at(t),
            Elem::Arc(a) => a.point_at(t),
        }
    }

    /// The two pieces either side of `s` mm from the start; `None` when `s`
    /// is within [`MIN_PIECE`] of either end.
    pub fn split_at_length(&self, s: f64) -> Option<(Elem, Elem)> {
        let len = self.length();
        if !(s > MIN_PIECE && s < len - MIN_PIECE) {
            return None;
        }
        let t = s / len;
        match self {
            Elem::Line(l) => l.split_at(t).map(|(a, b)| (Elem::Line(a), Elem::Line(b))),
            Elem::Arc(a) => a.split_at(t).map(|(x, y)| (Elem::Arc(x), Elem::Arc(y))),
        }
    }

    pub fn reversed(&self) -> Elem {
        match self {
            Elem::Line(l) => Elem::Line(l.reversed()),
            Elem::Arc(a) => Elem::Arc(a.reversed()),
        }
    }

    /// Shift by `d`.
    pub fn translated(&self, d: V3) -> Elem {
        match self {
            Elem::Line(l) => Elem::line(l.start + d, l.end + d),
            Elem::Arc(a) => Elem::Arc(Arc3 {
                center: a.center + d,
                start: a.start + d,
                end: a.end + d,
                ..*a
            }),
        }
    }

    pub fn motion_kind(&self) -> MotionKind {
        match self {
            Elem::Line(_) => MotionKind::Line,
            Elem::Arc(a) => MotionKind::Arc(ArcData {
                center: a.center,
                ccw: a.ccw,
                plane: a.plane,
                extra_turns: a.extra_turns,
            }),
        }
    }

    /// The plane a loop at this piece's end should turn in: the arc's own
    /// plane, or XY for lines (laser contours are planar in XY).
    pub fn plane(&self) -> Plane {
        match self {
            Elem::Line(_) => Plane::Xy,
            Elem::Arc(a) => a.plane,
        }
    }
}

/// The tangent of a planar arc at one of its end points: the radius turned
/// a quarter turn, no trigonometry (planning asks this at every joint of a
/// million-segment job). `None` for helical arcs, which keep the general
/// formula.
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

/// Total length of a path.
pub fn path_length(p: &[Elem]) -> f64 {
    p.iter().map(Elem::length).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_tangents_match_the_general_ones() {
        for plane in [Plane::Xy, Plane::Xz, Plane::Yz] {
            for ccw in [true, false] {
                let c = P3::new(0.3, -0.2, 0.1);
                let c2 = plane.project(&c);
                let s2 = crate::geometry::P2::new(1.0, 0.5);
                let r = (s2 - c2).norm();
                let e2 = c2 + crate::geometry::V2::new(2.0f64.cos(), 2.0f64.sin()) * r;
                let nz = plane.normal_coord(&c);
                let a = Arc3::new(c, plane.lift(&s2, nz), plane.lift(&e2, nz), ccw, plane, 0).unwrap();
                let el = Elem::Arc(a);
                assert!(
                    (el.dir_start() - a.tangent_at(0.0).unwrap()).norm() < 1e-9,
                    "{plane:?} {ccw}"
                );
                assert!(
                    (el.dir_end() - a.tangent_at(1.0).unwrap()).norm() < 1e-6,
                    "{plane:?} {ccw}"
                );
            }
        }
    }
}
