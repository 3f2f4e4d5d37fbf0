//! The chain model: ordered, connected runs of exact lines and arcs taken
//! from a drawing.

use crate::geometry::{P2, P3};

/// One exact segment of a chain, in travel order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Segment {
    Line {
        start: P3,
        end: P3,
    },
    /// A circular arc in the XY plane (at constant z); start == end is a
    /// full circle.
    Arc {
        start: P3,
        end: P3,
        center: P3,
        ccw: bool,
    },
}

impl Segment {
    pub fn start(&self) -> P3 {
        match self {
            Segment::Line { start, .. } | Segment::Arc { start, .. } => *start,
        }
    }

    pub fn end(&self) -> P3 {
        match self {
            Segment::Line { end, .. } | Segment::Arc { end, .. } => *end,
        }
    }

    /// The same segment travelled the other way.
    pub fn reversed(&self) -> Segment {
        match *self {
            Segment::Line { start, end } => Segment::Line { start: end, end: start },
            Segment::Arc {
                start,
                end,
                center,
                ccw,
            } => Segment::Arc {
                start: end,
                end: start,
                center,
                ccw: !ccw,
            },
        }
    }

    /// An arc's XY geometry as centre, radius, start angle and signed sweep
    /// (radians, positive counter-clockwise; a full turn when it closes);
    /// `None` for a line. The one place chains' arcs are taken apart.
    pub fn arc_xy(&self) -> Option<ArcXy> {
        match self {
            Segment::Line { .. } => None,
            Segment::Arc {
                start,
                end,
                center,
                ccw,
            } => Some(ArcXy {
                center: P2::new(center.x, center.y),
                radius: (start - center).xy().norm(),
                start_angle: (start.y - center.y).atan2(start.x - center.x),
                sweep: arc_sweep(start, end, center, *ccw),
            }),
        }
    }

    /// Length in XY (mm): the arc length for arcs.
    pub fn length(&self) -> f64 {
        match self {
            Segment::Line { start, end } => (end - start).norm(),
            Segment::Arc {
                start,
                end,
                center,
                ccw,
            } => (start - center).xy().norm() * arc_sweep(start, end, center, *ccw).abs(),
        }
    }
}

/// An XY arc as [`Segment::arc_xy`] gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcXy {
    pub center: P2,
    pub radius: f64,
    /// Angle of the start point about the centre (radians).
    pub start_angle: f64,
    /// Signed sweep (radians, positive counter-clockwise).
    pub sweep: f64,
}

impl ArcXy {
    /// The point at angle `a` on the circle.
    pub fn point_at_angle(&self, a: f64) -> P2 {
        P2::new(
            self.center.x + self.radius * a.cos(),
            self.center.y + self.radius * a.sin(),
        )
    }
}

/// Signed sweep of an XY arc (radians, positive counter-clockwise); a full
/// circle when start == end.
pub fn arc_sweep(start: &P3, end: &P3, center: &P3, ccw: bool) -> f64 {
    let tau = std::f64::consts::TAU;
    let a0 = (start.y - center.y).atan2(start.x - center.x);
    let a1 = (end.y - center.y).atan2(end.x - center.x);
    let mut s = if ccw {
        (a1 - a0).rem_euclid(tau)
    } else {
        -(a0 - a1).rem_euclid(tau)
    };
    if start == end || s == 0.0 {
        s = if ccw { tau } else { -tau };
    }
    s
}

/// A connected chain of segments.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Chain {
    pub id: u64,
    pub layer: Option<String>,
    pub closed: bool,
    pub segments: Vec<Segment>,
    /// Drill / pierce marks (DXF POINT entities) carried with the chain.
    pub points: Vec<P3>,
    /// Human-readable notes on what was mended to make this chain.
    pub repairs: Vec<String>,
}

/// The header record of a chains stream.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ChainsHeader {
    pub source: Option<String>,
}
