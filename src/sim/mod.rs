//! Simulation of a toolpath: what the machine will do with a program.
//!
//! - [`summary`]: path lengths, counts and extents, one pass, constant memory.
//! - [`machine`]: machine profiles (controller model, limits, latencies).
//! - [`time`]: motion time per block under the PMAC or look-ahead model.

pub mod machine;
pub mod summary;
pub mod time;
