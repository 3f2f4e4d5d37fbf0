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
//! - [`machine`]: machine profiles (controller, stage, shutter, spindle) and the Turbo PMAC timing rule.
//! - [`feedopt`]: feed scheduling from simulated chip volume (milling).
//! - [`laser`]: constant-velocity laser toolpaths from chains (contour,
//!   patterns, corner loops, cut order, shutter timing).
//! - [`sim`]: what a program does on the machine: time, beam and material removal.
//! - [`preview`]: SVG previews of toolpaths.
//! - [`pmac`]: Turbo PMAC protocol, client, emulator, splitting and upload.
//! - [`pocket`]: freeform grid pockets (the Iowa State grid-pocket thesis, 1999).
//! - [`cutter`]: end mill shapes shared by every milling tool.
//! - [`dropcutter`]: 3- and 5-axis cutter locations on meshes.
//! - [`dexel`]: tri-dexel stock cut by swept tool volumes (3- and 5-axis).
//! - [`verify`]: CL data in, machined part compared with the design.
//! - [`mesh`]: triangle meshes (STL, OBJ) and queries on them.
//! - [`probe`]: rotating-wire probe scanning and measurement.
//! - [`slice`](mod@slice): planar sections of meshes at Z levels as closed, nested chains.
//! - [`corpus`]: where the shared test corpus lies, for tests and benchmarks.
//! - [`cli`]: conventions shared by every binary.

// Every public item is documented; a new one without a doc comment is a
// warning, and an error in `make lint` (part of `make test`).
#![warn(missing_docs)]
// Diagnostics go through `diag!` (below) and data through the writers:
// `eprintln!`/`println!` panic when stderr or stdout is a closed pipe.
// Tests may print.
#![cfg_attr(not(test), deny(clippy::print_stderr, clippy::print_stdout))]

/// `eprintln!` that never panics. A diagnostic that cannot be written
/// (stderr closed with `2>&-`, or a pipe whose reader has gone, as in
/// `2>&1 | head -1`) is dropped, and the tool's data and exit status stay
/// what they would have been: `eprintln!` panics on a failed write, which
/// ended such a run with status 101 and its output discarded.
#[macro_export]
macro_rules! diag {
    ($($arg:tt)*) => {{
        use ::std::io::Write as _;
        let _ = ::std::writeln!(::std::io::stderr(), $($arg)*);
    }};
}

pub mod cli;
pub mod corpus;
pub mod cutter;
pub mod dexel;
pub mod dropcutter;
pub mod dxf;
pub mod feedopt;
pub mod formats;
pub mod gcode;
pub mod geometry;
pub mod laser;
pub mod machine;
pub mod mesh;
pub mod model;
pub mod plough;
pub mod pmac;
pub mod pocket;
pub mod preview;
pub mod probe;
pub mod progress;
pub mod sim;
pub mod slice;
pub mod source;
pub mod verify;
