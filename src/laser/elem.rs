//! Planning works on exact pieces ([`crate::geometry::Segment`]: a line or
//! a possibly helical arc) rather than on toolpath records, so that
//! splitting (for shutter timing) and tangent checks (for corner loops) stay
//! exact. This module holds what planning adds to them.

/// Pieces shorter than this (mm) are dropped when splitting: a 1 nm move is
/// below every controller's resolution and would only add a block.
pub const MIN_PIECE: f64 = 1e-7;
