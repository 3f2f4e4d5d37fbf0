//! Simulation of a toolpath: what the machine will do with a program.
//!
//! - [`summary`]: path lengths, counts and extents, one pass, constant memory.

pub mod summary;
