//! The chain model: ordered, connected runs of exact lines and arcs taken
//! from a drawing.

use crate::geometry::P3;

/// One exact segment of a chain, in travel order: a line, or an arc in the
/// XY plane at constant height built with [`Segment::arc_xy`] (start equal
/// to end is a full circle). The geometry kernel's one line/arc type.
pub use crate::geometry::segment::{ArcXy, Segment};

/// A connected chain of segments.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Chain {
    /// Identifier, unique within a stream (toolpath moves name it).
    pub id: u64,
    /// The drawing layer the chain came from, if any.
    pub layer: Option<String>,
    /// True when the chain ends where it starts.
    pub closed: bool,
    /// The segments in travel order, each starting where the last ended.
    pub segments: Vec<Segment>,
    /// Drill / pierce marks (DXF POINT entities) carried with the chain.
    pub points: Vec<P3>,
    /// Human-readable notes on what was mended to make this chain.
    pub repairs: Vec<String>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
/// A chain's parts, borrowed: what `formats::chains::format_chain_ref`
/// writes, for a producer that holds its chains in another form
/// (dxf2chains formats 50,000 chains and more without building each).
pub struct ChainRef<'a> {
    /// As [`Chain::id`].
    pub id: u64,
    /// As [`Chain::layer`].
    pub layer: Option<&'a str>,
    /// As [`Chain::closed`].
    pub closed: bool,
    /// As [`Chain::segments`].
    pub segments: &'a [Segment],
    /// As [`Chain::points`].
    pub points: &'a [P3],
    /// As [`Chain::repairs`].
    pub repairs: &'a [String],
}

/// The header record of a chains stream.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ChainsHeader {
    /// Where the chains came from (a file name), if known.
    pub source: Option<String>,
}
