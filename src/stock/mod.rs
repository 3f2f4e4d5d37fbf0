//! Material removal: a stock block, cutters, and the swept removal of
//! material by straight moves, with the chip volume of each cut.
//!
//! - [`cutter`]: flat, ball and torus end mills as height profiles.
//! - [`heightfield`]: the stock as heights on a regular XY grid (a Z-map),
//!   cut exactly by horizontal moves and by dense stamps along ramps.
//! - [`mesh`]: the simulated stock as a watertight STL.
//!
//! A height field is the right model for 3-axis milling and laser ablation
//! from above (no undercuts); it is what lets the kernel touch only the
//! cells a move can reach and run rows in parallel.

pub mod cutter;
pub mod heightfield;
pub mod mesh;
pub mod path;
pub mod run;

pub use cutter::Cutter;
pub use heightfield::{HeightField, StockError};
