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
