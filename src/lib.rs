//! microcam: from a DXF drawing to a running program on a precision stage.
//!
//! The library holds all the logic; the binaries under `src/bin/` only parse
//! arguments, call into here and write output.
//!
//! - [`geometry`]: points, planes, exact lines and arcs.
//! - [`model`]: chains and toolpaths in memory.
//! - [`formats`]: the JSON Lines pipe formats, streaming.
//! - [`gcode`]: ISO and PMAC G-code, read and written.
//! - [`dxf`]: DXF import and chain detection.
//! - [`paths`]: constant-velocity laser toolpaths from chains (contour,
//!   patterns, corner loops, cut order, shutter timing).
//! - [`sim`]: what a program does on the machine: time, beam and material removal.
//! - [`preview`]: SVG previews of toolpaths.
//! - [`pmac`]: Turbo PMAC protocol, client, emulator, splitting and upload.
//! - [`cutter`]: end mill shapes shared by every milling tool.
//! - [`dexel`]: tri-dexel stock cut by swept tool volumes (3- and 5-axis).
//! - [`verify`]: CL data in, machined part compared with the design.
//! - [`mesh`]: triangle meshes (STL, OBJ) and queries on them.
//! - [`corpus`]: where the shared test corpus lies, for tests and benchmarks.
//! - [`cli`]: conventions shared by every binary.

pub mod cli;
pub mod corpus;
pub mod cutter;
pub mod dexel;
pub mod dxf;
pub mod formats;
pub mod gcode;
pub mod geometry;
pub mod mesh;
pub mod model;
pub mod paths;
pub mod pmac;
pub mod preview;
pub mod sim;
pub mod source;
pub mod verify;
