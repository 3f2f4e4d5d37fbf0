//! The chain model: ordered, connected runs of exact lines and arcs taken
//! from a drawing.

use crate::geometry::P3;

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
