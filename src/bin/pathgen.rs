//! pathgen: toolpaths, and G-code from toolpaths.

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::{Parser, Subcommand};
use microcam::cli;
use std::process::ExitCode;

#[path = "pathgen/arcfit.rs"]
mod arcfit;
#[path = "pathgen/audit.rs"]
mod audit;
#[path = "pathgen/common.rs"]
mod common;
#[path = "pathgen/contour.rs"]
mod contour;
#[path = "pathgen/dropcutter.rs"]
mod dropcutter;
#[path = "pathgen/emit.rs"]
mod emit;
#[path = "pathgen/fill.rs"]
mod fill;
#[path = "pathgen/patterns.rs"]
mod patterns;
#[path = "pathgen/pocket.rs"]
mod pocket;
#[path = "pathgen/slice.rs"]
mod slice;

use arcfit::*;
use audit::*;
use contour::*;
use emit::*;
use patterns::*;

const EXAMPLES: &str = "\
Examples:
  pathgen emit --dialect pmac part.jsonl > part.pmc     toolpath to PMAC motion program
  pathgen emit --dialect iso --decimals 5 part.jsonl    toolpath to ISO G-code
  gsim --moves part.ngc | pathgen emit --dialect pmac   convert ISO to PMAC text
  pathgen emit --dialect pmac --shutter-immediate --no-line-counter part.jsonl

Input is microcam.toolpath/1 JSON Lines or G-code of either dialect; '-' or
no FILE reads stdin. Exit status: 0 ok, 1 failure, 2 bad usage or bad input.";

/// Generate toolpaths and G-code.
#[derive(Parser)]
#[command(name = "pathgen", version, about, after_help = EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write a toolpath as G-code (PMAC motion program or ISO).
    #[command(after_help = EXAMPLES)]
    Emit(EmitArgs),
    /// Cut chains: offset, order, lead in/out, loop corners, time the shutter.
    #[command(after_help = CONTOUR_EXAMPLES)]
    Contour(Box<ContourArgs>),
    /// A helix (holes): radius, pitch per turn, whole turns.
    #[command(after_help = PATTERN_EXAMPLES)]
    Helix(Box<HelixArgs>),
    /// A square or Archimedean spiral, inward or outward.
    #[command(after_help = PATTERN_EXAMPLES)]
    Spiral(Box<SpiralArgs>),
    /// Zigzag hatching along X or Y in plane XY or XZ.
    #[command(after_help = PATTERN_EXAMPLES)]
    Zigzag(Box<ZigzagArgs>),
    /// A cone: spirals on Z levels, diameters per Bayesteh (2013) eqs. 6.4-6.6.
    #[command(after_help = PATTERN_EXAMPLES)]
    Cone(Box<ConeArgs>),
    /// Fit tangent-continuous arcs (biarcs) to points or a polyline.
    #[command(after_help = ARCFIT_EXAMPLES)]
    Arcfit(Box<ArcfitArgs>),
    /// Check a laser toolpath against the machine: speed, acceleration,
    /// shutter timing; prints a JSON report, exit 1 when a limit is broken.
    #[command(after_help = AUDIT_EXAMPLES)]
    Audit(Box<AuditArgs>),
    /// Sections of an STL/OBJ model at Z levels, as closed nested chains.
    #[command(after_help = slice::SLICE_EXAMPLES)]
    Slice(Box<slice::SliceArgs>),
    /// Topology report of an STL/OBJ mesh (and the repairs), as JSON.
    #[command(after_help = slice::INFO_EXAMPLES)]
    MeshInfo(Box<slice::MeshInfoArgs>),
    /// Freeform pocket by grid navigation (Iowa State grid-pocket thesis,
    /// 1999): layered rough and finish cuts, or contour-parallel offsets.
    #[command(after_help = pocket::EXAMPLES)]
    Pocket(Box<pocket::PocketArgs>),
    /// CL data from a mesh: drop a flat, ball or torus cutter on a raster
    /// or along chains (3-axis), or 5-axis along the surface normal.
    #[command(after_help = dropcutter::EXAMPLES)]
    Dropcutter(Box<dropcutter::DropcutterArgs>),
    /// Fill closed chains (sections from `slice`, regions from dxf2chains):
    /// offset passes or hatch, through the laser planner.
    #[command(after_help = fill::EXAMPLES)]
    Fill(Box<fill::FillArgs>),
}

fn main() -> ExitCode {
    let cli = microcam::cli::parse::<Cli>();
    cli::run("pathgen", || match cli.command {
        Command::Emit(a) => emit(a),
        Command::Contour(a) => contour_cmd(*a),
        Command::Helix(a) => helix_cmd(*a),
        Command::Spiral(a) => spiral_cmd(*a),
        Command::Zigzag(a) => zigzag_cmd(*a),
        Command::Cone(a) => cone_cmd(*a),
        Command::Arcfit(a) => arcfit_cmd(*a),
        Command::Audit(a) => audit_cmd(*a),
        Command::Slice(a) => slice::slice_cmd(*a),
        Command::MeshInfo(a) => slice::mesh_info_cmd(*a),
        Command::Pocket(a) => pocket::run(*a),
        Command::Dropcutter(a) => dropcutter::run(*a),
        Command::Fill(a) => fill::run(*a),
    })
}
