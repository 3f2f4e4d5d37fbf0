//! The in-memory models behind the pipe formats: chains (what a drawing is)
//! and toolpaths (what the machine does). Readers and writers for their JSON
//! Lines forms live in [`crate::formats`]; G-code is read into and written
//! from [`toolpath::Record`] by [`crate::gcode`].

#![warn(missing_docs)]

pub mod chain;
pub mod toolpath;
