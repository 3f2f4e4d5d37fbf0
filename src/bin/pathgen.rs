//! pathgen: toolpaths, and G-code from toolpaths.

use clap::{Args as ClapArgs, Parser, Subcommand};
use microcam::cli::{self, CliError, Output};
use microcam::formats::chains::ChainsWriter;
use microcam::formats::toolpath::ToolpathWriter;
use microcam::gcode::writer::{GcodeWriter, WriteError, WriteOptions};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::geometry::P2;
use microcam::geometry::{P3, Plane};
use microcam::laser::arcfit;
use microcam::laser::contour::{
    ContourOptions, DEFAULT_CLEANUP_TOL, Direction, OrderMode, Warning, contour, contour_streamed, estimated_moves,
};
use microcam::laser::elem::Elem;
use microcam::laser::input::read_chains;
use microcam::laser::offset::Side;
use microcam::laser::patterns;
use microcam::laser::plan::{Tagged, all_cut, plan_paths};
use microcam::laser::setup::{DEFAULT_DECIMALS, LaserSetup};
use microcam::machine::{Controller, Machine, pmac};
use microcam::model::chain::{Chain, ChainsHeader, Segment};
use microcam::model::toolpath::{FeedUnit, Header, Record};
use microcam::source::ToolpathSource;
use std::path::PathBuf;
use std::process::ExitCode;

#[path = "pathgen/dropcutter.rs"]
mod dropcutter;
#[path = "pathgen/fill.rs"]
mod fill;
#[path = "pathgen/pocket.rs"]
mod pocket;
#[path = "pathgen/slice.rs"]
mod slice;

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
    Arcfit(Box<ArcfitArgs>),
    /// Check a laser toolpath against the machine: speed, acceleration,
    /// shutter timing; prints a JSON report, exit 1 when a limit is broken.
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

#[derive(ClapArgs)]
struct AuditArgs {
    /// Toolpath or G-code to check ('-' for stdin).
    file: Option<PathBuf>,
    /// Printing precision of the input (mm): radii and switch points may be
    /// off by this much (1e-4 for 4-decimal G-code, 1e-9 for toolpaths).
    #[arg(long, default_value_t = 1e-4)]
    precision: f64,
    #[command(flatten)]
    machine: MachineArgs,
}

const PATTERN_EXAMPLES: &str = "\
Examples:
  pathgen helix --center 1,1 --radius 0.3 --pitch -0.01 --turns 5 --gcode pmac
  pathgen spiral --kind archimedean --radius 0.5 --step 0.01 --inward
  pathgen spiral --kind square --size 1 --step 0.02 --svg sq.svg
  pathgen zigzag --length 2 --width 1 --step 0.01 --along y --plane xz
  pathgen cone --d1 1 --d2 0.4 --height 0.3 --levels 10 --step 0.01

Output is microcam.toolpath/1 (feeds in mm/s) or G-code with --gcode; every
move runs at --feed with the beam switched per the shutter timing.";

#[derive(ClapArgs)]
struct HelixArgs {
    /// Centre X,Y.
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    center: (f64, f64),
    /// Start height (mm).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    z: f64,
    /// Radius (mm).
    #[arg(long)]
    radius: f64,
    /// Rise per turn (mm; negative goes down).
    #[arg(long, allow_hyphen_values = true)]
    pitch: f64,
    /// Whole turns.
    #[arg(long, default_value_t = 1)]
    turns: u32,
    /// Clockwise instead of counter-clockwise.
    #[arg(long)]
    cw: bool,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
struct SpiralArgs {
    /// square or archimedean.
    #[arg(long, value_parser = ["square", "archimedean"], default_value = "archimedean")]
    kind: String,
    /// Centre X,Y.
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    center: (f64, f64),
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    z: f64,
    /// Distance between passes (mm).
    #[arg(long)]
    step: f64,
    /// Square: side of the square (mm).
    #[arg(long)]
    size: Option<f64>,
    /// Archimedean: outer radius (mm), closed by a full circle there.
    #[arg(long)]
    radius: Option<f64>,
    /// Archimedean: radius where the spiral starts (a in r = a + b·θ; default: step).
    #[arg(long)]
    inner: Option<f64>,
    /// Run from the outside in.
    #[arg(long)]
    inward: bool,
    /// Archimedean: largest deviation of the arcs from the spiral (mm).
    #[arg(long, default_value_t = 1e-5)]
    tolerance: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
struct ZigzagArgs {
    /// Corner X,Y,Z where the first line starts.
    #[arg(long, value_parser = parse_triple_f64, default_value = "0,0,0", allow_hyphen_values = true)]
    origin: (f64, f64, f64),
    /// Plane of the hatching.
    #[arg(long, value_parser = ["xy", "xz"], default_value = "xy")]
    plane: String,
    /// Cut lines along this axis (the plane's other axis steps).
    #[arg(long, value_parser = ["x", "y", "z"], default_value = "x")]
    along: String,
    /// Length of each line (mm).
    #[arg(long)]
    length: f64,
    /// Extent across the lines (mm).
    #[arg(long)]
    width: f64,
    /// Distance between lines (mm).
    #[arg(long)]
    step: f64,
    /// Smallest turnaround radius (mm); never below V²/a.
    #[arg(long, default_value_t = 0.0)]
    corner_radius: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
struct ConeArgs {
    /// Centre X,Y.
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    center: (f64, f64),
    /// Surface height (mm); passes go down from here.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    z: f64,
    /// Diameter at the surface (mm).
    #[arg(long)]
    d1: f64,
    /// Diameter at depth --height (mm).
    #[arg(long)]
    d2: f64,
    /// Depth of the cone (mm).
    #[arg(long)]
    height: f64,
    /// Number of Z levels.
    #[arg(long, default_value_t = 10)]
    levels: u32,
    /// Distance between spiral passes (mm; default the beam diameter).
    #[arg(long)]
    step: Option<f64>,
    /// Beam spot diameter (mm): each section is filled to its edge minus the radius.
    #[arg(long, default_value_t = 0.01)]
    beam_diameter: f64,
    #[arg(long, default_value_t = 1e-5)]
    tolerance: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
struct ArcfitArgs {
    /// Points, one 'x y' (or 'x,y') per line, '#' comments; '-' for stdin.
    file: Option<PathBuf>,
    /// Largest deviation from the polyline (mm).
    #[arg(long, default_value_t = 0.001)]
    tolerance: f64,
    /// Print a JSON report (blocks, deviation) instead of chains.
    #[arg(long)]
    report: bool,
    /// The input is a polyline to stay within (both ways), not samples of
    /// a smooth curve (the default: only the points must be within).
    #[arg(long)]
    polyline: bool,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn parse_triple_f64(s: &str) -> Result<(f64, f64, f64), String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("expected X,Y,Z, got '{s}'"))?;
    match v[..] {
        [x, y, z] => Ok((x, y, z)),
        _ => Err(format!("expected X,Y,Z, got '{s}'")),
    }
}

fn positive(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be positive, got {v}")))
    }
}

fn finite(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be a finite number, got {v}")))
    }
}

fn non_negative(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!(
            "--{name} must be a finite number >= 0, got {v}"
        )))
    }
}

fn at_least_one(name: &str, v: u32) -> Result<u32, CliError> {
    if v >= 1 {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be at least 1, got {v}")))
    }
}

const CONTOUR_EXAMPLES: &str = "\
Examples:
  pathgen contour part.chains > part.jsonl                 cut on the lines
  pathgen contour --side outside --beam-diameter 0.01 part.chains --gcode pmac > part.pmc
  pathgen contour --side inside --offset 0.02 --levels 5 --level-step -0.005 part.chains
  pathgen contour --array 3,2 --pitch 5,5 --svg part.svg part.chains

Input is microcam.chains/1 ('-' or no FILE reads stdin); output is
microcam.toolpath/1 (feeds in mm/s) or G-code with --gcode. Warnings
(vanished offsets, cuts shorter than the minimum exposure, arcs tighter than
V^2/a) go to stderr. Exit status: 0 ok, 1 failure, 2 bad usage or bad input.";

/// The stage and shutter: a machine profile (`--machine`, default the
/// laser stage of Bayesteh 2013), then these flags over it.
#[derive(ClapArgs)]
struct MachineArgs {
    /// Machine profile: a built-in name (laser-stage, lookahead) or a
    /// microcam.machine/1 JSON file. Its acceleration time and shutter are
    /// the defaults of the flags below.
    #[arg(long, default_value = "laser-stage", value_name = "NAME|FILE")]
    machine: String,
    /// Feed V while the beam is on (mm/s).
    #[arg(long, default_value_t = 2.0)]
    feed: f64,
    /// Acceleration time TA (ms). Default: the profile's (on a Turbo PMAC
    /// its TA/TS rule; on a look-ahead planner V over its acceleration).
    #[arg(long = "ta-ms", visible_alias = "ta", allow_negative_numbers = true)]
    ta: Option<f64>,
    /// Deceleration time TD (ms). Default: TA.
    #[arg(long = "td-ms", visible_alias = "td", allow_negative_numbers = true)]
    td: Option<f64>,
    /// S-curve time TS (ms) written into the program.
    #[arg(
        long = "ts-ms",
        visible_alias = "ts",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    ts: f64,
    /// Acceleration (mm/s^2): sets TA = TD = V/a instead.
    #[arg(long = "accel-mm-s2", visible_alias = "accel", allow_negative_numbers = true)]
    accel: Option<f64>,
    /// Shutter delay before opening starts (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    open_delay: Option<f64>,
    /// Shutter transfer time to fully open (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    open_transfer: Option<f64>,
    /// Shutter delay before closing starts (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    close_delay: Option<f64>,
    /// Shutter transfer time to fully closed (ms). Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    close_transfer: Option<f64>,
    /// Minimum exposure (ms); shorter cuts are reported. Default: the profile's.
    #[arg(long, allow_negative_numbers = true)]
    min_exposure: Option<f64>,
    /// Corners turning less than this (degrees) are tangent: no loop.
    #[arg(long, default_value_t = 0.5)]
    tangent_tol: f64,
    /// Controller the program is planned for: pmac (M33== acts where the
    /// blend into its block starts; blocks at V get a short TA) or lookahead
    /// (commands act at block boundaries). Default: lookahead with --gcode
    /// iso, else the profile's.
    #[arg(long, value_enum)]
    controller: Option<Controller>,
    /// PMAC: TA (whole ms) of the blocks at V between a path's ramps.
    /// Default: 2 × the close delay, so the close command sits on the
    /// boundary at the cut end.
    #[arg(long = "cut-ta-ms", visible_alias = "cut-ta")]
    cut_ta: Option<f64>,
}

impl MachineArgs {
    /// The laser setup: the profile, then the flags; `gcode` is the dialect
    /// written, which picks the controller when `--controller` is not given.
    fn machine(&self, gcode: Option<&str>) -> Result<LaserSetup, CliError> {
        let profile = Machine::load(&self.machine).map_err(|e| CliError::input(format!("--machine: {e}")))?;
        let shutter = profile.shutter.clone().ok_or_else(|| {
            CliError::input(format!(
                "--machine: profile '{}' has no shutter section; the laser strategies need one",
                profile.name
            ))
        })?;
        let controller = match (self.controller, gcode) {
            (Some(c), _) => c,
            (None, Some("iso")) => Controller::Lookahead,
            (None, _) => profile.controller,
        };
        let profile_ta_ms = match profile.controller {
            Controller::Pmac => 1000.0 * pmac::accel_time_s(profile.ta_ms, profile.ts_ms),
            Controller::Lookahead => 1000.0 * self.feed / profile.accel_mm_s2,
        };
        let ta = self.ta.unwrap_or(profile_ta_ms);
        let close_delay = self.close_delay.unwrap_or(shutter.close_delay_ms);
        let mut m = LaserSetup {
            feed: self.feed,
            ta_ms: ta,
            td_ms: self.td.unwrap_or(ta),
            ts_ms: self.ts,
            open_delay_ms: self.open_delay.unwrap_or(shutter.open_delay_ms),
            open_transfer_ms: self.open_transfer.unwrap_or(shutter.open_transfer_ms),
            close_delay_ms: close_delay,
            close_transfer_ms: self.close_transfer.unwrap_or(shutter.close_transfer_ms),
            min_exposure_ms: self.min_exposure.unwrap_or(shutter.min_exposure_ms),
            tangent_tol_deg: self.tangent_tol,
            controller,
            cut_ta_ms: self
                .cut_ta
                .unwrap_or((2.0 * close_delay).clamp(1.0, ta.max(self.td.unwrap_or(ta)).max(1.0))),
            decimals: DEFAULT_DECIMALS,
        };
        if let Some(a) = self.accel {
            if !(a.is_finite() && a > 0.0) {
                return Err(CliError::input(format!("--accel-mm-s2 must be positive, got {a}")));
            }
            m = m.with_accel(a);
        }
        m.validate().map_err(|e| CliError::input(e.to_string()))?;
        Ok(m)
    }
}

/// Where generated moves go.
#[derive(ClapArgs)]
struct GenOutput {
    /// Write G-code of this dialect instead of a toolpath.
    #[arg(long, value_parser = ["iso", "pmac"])]
    gcode: Option<String>,
    #[command(flatten)]
    writer: WriterArgs,
    /// Also write an SVG preview here.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Refuse (exit 2) a job estimated to make more moves than this.
    #[arg(long, default_value_t = DEFAULT_MAX_MOVES, value_name = "N")]
    max_moves: u64,
}

/// Default of `--max-moves`: 10 million moves, about 1 GB of toolpath text.
const DEFAULT_MAX_MOVES: u64 = 10_000_000;

impl GenOutput {
    /// The machine for a generator: the profile and flags, with the block
    /// margin taken from the decimals the program is written with.
    fn setup(&self, machine: &MachineArgs) -> Result<LaserSetup, CliError> {
        let mut m = machine.machine(self.gcode.as_deref())?;
        m.decimals = self.writer.decimals.unwrap_or(DEFAULT_DECIMALS);
        Ok(m)
    }

    /// Refuse a job whose estimated size passes `--max-moves`.
    fn check_size(&self, what: &str, moves: f64, how: &str) -> Result<(), CliError> {
        if moves.is_nan() || moves > self.max_moves as f64 {
            return Err(self.too_big(what, moves, how));
        }
        Ok(())
    }

    fn too_big(&self, what: &str, moves: f64, how: &str) -> CliError {
        CliError::input(format!(
            "{what}: {how} makes about {moves:.3e} moves, more than --max-moves {}; ask for less, or raise \
             --max-moves",
            self.max_moves
        ))
    }
}

#[derive(ClapArgs)]
struct ContourArgs {
    /// Chains to cut ('-' for stdin).
    file: Option<PathBuf>,
    /// Where the beam centre runs: on the chain, inside/outside closed
    /// chains, or left/right of travel.
    #[arg(long, value_enum, default_value_t = Side::On)]
    side: Side,
    /// Beam spot diameter (mm); the default offset is its radius.
    #[arg(long, default_value_t = 0.01)]
    beam_diameter: f64,
    /// Offset distance (mm) instead of the beam radius.
    #[arg(long)]
    offset: Option<f64>,
    /// Passes per chain.
    #[arg(long, default_value_t = 1)]
    levels: u32,
    /// Z step between passes (mm; negative goes down).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    level_step: f64,
    /// Copies of the job in X and Y: NX,NY.
    #[arg(long, value_parser = parse_pair_u32, default_value = "1,1")]
    array: (u32, u32),
    /// Pitch of the copies: DX,DY (mm).
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    pitch: (f64, f64),
    /// Start closed paths at the vertex nearest X,Y (default: where drawn).
    #[arg(long, value_parser = parse_pair_f64, allow_hyphen_values = true)]
    start_near: Option<(f64, f64)>,
    /// Travel sense of closed paths.
    #[arg(long, value_parser = ["keep", "ccw", "cw"], default_value = "keep")]
    direction: String,
    /// Chain order: input, nearest (the thesis'), optimized (nearest + 2-opt/Or-opt).
    #[arg(long, value_parser = ["input", "nearest", "optimized"], default_value = "optimized")]
    order: String,
    /// Largest deviation (mm) allowed when pieces shorter than the
    /// controller's least block at V are merged into their neighbours or
    /// refitted as arcs; 0 keeps every piece as it is.
    #[arg(long, default_value_t = DEFAULT_CLEANUP_TOL, value_name = "MM")]
    cleanup_tol: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

fn parse_pair_f64(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("expected X,Y, got '{s}'"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{t}' is not a finite number"))
    };
    Ok((p(a)?, p(b)?))
}

fn parse_pair_u32(s: &str) -> Result<(u32, u32), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("expected NX,NY, got '{s}'"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| v >= 1)
            .ok_or_else(|| format!("'{t}' is not a count >= 1"))
    };
    Ok((p(a)?, p(b)?))
}

#[derive(ClapArgs)]
struct EmitArgs {
    /// Toolpath to write ('-' for stdin).
    file: Option<PathBuf>,
    /// Output dialect.
    #[arg(long, value_parser = ["iso", "pmac"], default_value = "pmac")]
    dialect: String,
    #[command(flatten)]
    writer: WriterArgs,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// How G-code is written: shared by `emit` and every generator's `--gcode`,
/// so a generated program is byte-identical to generating a toolpath and
/// piping it through `pathgen emit`.
#[derive(ClapArgs)]
struct WriterArgs {
    /// Decimal places of coordinates and feeds (0-9).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=9))]
    decimals: Option<u8>,
    /// Shutter variable (PMAC).
    #[arg(long, default_value = "M33")]
    shutter_var: String,
    /// Assign the shutter immediately (`M33=1`, executed at look-ahead)
    /// instead of synchronously with motion (`M33==1`, the default).
    #[arg(long)]
    shutter_immediate: bool,
    /// Line-counter variable (PMAC), one increment per motion block.
    #[arg(long, default_value = "P400")]
    line_counter: String,
    /// Write no line counter.
    #[arg(long)]
    no_line_counter: bool,
    /// PMAC program buffer number for the default header (OPEN PROG n CLEAR).
    #[arg(long, default_value_t = 1)]
    program: u32,
    /// Header lines instead of the default (repeatable).
    #[arg(long = "header")]
    header: Vec<String>,
    /// Trailer lines instead of the default (repeatable).
    #[arg(long = "trailer")]
    trailer: Vec<String>,
    /// ISO: number blocks N10, N20, ... with this step.
    #[arg(long, value_name = "STEP")]
    line_numbers: Option<u32>,
    /// Arc centres absolute (G90.1 / ABS(R)) instead of incremental.
    #[arg(long)]
    absolute_centers: bool,
    /// Repeat the motion word on every block.
    #[arg(long)]
    repeat_motion: bool,
    /// Comment each change of source chain and role.
    #[arg(long)]
    comments: bool,
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

fn write_options(dialect: Dialect, a: &WriterArgs) -> WriteOptions {
    let mut opts = WriteOptions::for_dialect(dialect);
    if let Some(d) = a.decimals {
        opts.decimals = d;
    }
    opts.shutter_var = a.shutter_var.to_ascii_uppercase();
    opts.shutter_sync = !a.shutter_immediate;
    opts.line_counter = (!a.no_line_counter && dialect == Dialect::Pmac).then(|| a.line_counter.to_ascii_uppercase());
    opts.line_numbers = a.line_numbers;
    opts.absolute_centers = a.absolute_centers;
    opts.repeat_motion = a.repeat_motion;
    opts.comments = a.comments;
    if !a.header.is_empty() {
        opts.header = Some(a.header.clone());
    } else if dialect == Dialect::Pmac && a.program != 1 {
        let mut h = opts.default_header();
        if let Some(first) = h.first_mut() {
            *first = format!("OPEN PROG {} CLEAR", a.program);
        }
        opts.header = Some(h);
    }
    if !a.trailer.is_empty() {
        opts.trailer = Some(a.trailer.clone());
    }
    opts
}

/// Write records as G-code: the one code path of `emit` and `--gcode`.
fn write_gcode<E>(
    records: impl Iterator<Item = Result<Record, E>>,
    feed_unit: FeedUnit,
    opts: WriteOptions,
    name: &str,
    out: &mut Output,
) -> Result<(), CliError>
where
    CliError: From<E>,
{
    let mut w = GcodeWriter::new(out, opts, feed_unit);
    let bad = |e: WriteError| match e {
        WriteError::Io(e) => <CliError as From<std::io::Error>>::from(e),
        e => CliError::input(format!("{name}: {e}")),
    };
    for rec in records {
        w.record(&rec?).map_err(bad)?;
    }
    w.finish().map_err(bad)?;
    Ok(())
}

fn emit(a: EmitArgs) -> Result<(), CliError> {
    let dialect: Dialect = a.dialect.parse().map_err(CliError::input)?;
    let opts = write_options(dialect, &a.writer);
    let read = ReadOptions {
        shutter_var: opts.shutter_var.clone(),
        line_counter_var: a.writer.line_counter.to_ascii_uppercase(),
        ..Default::default()
    };
    let input = cli::open_input(a.file.as_deref())?;
    let source = ToolpathSource::open(input, &read)?;
    let name = source.name().to_string();
    let feed_unit = source.header.feed_unit;
    let mut out = Output::new(a.output.as_deref());
    write_gcode(source, feed_unit, opts, &name, &mut out)?;
    out.commit()
}

/// Warnings beyond this many are counted, not printed: a drawing with
/// thousands of tight fillets should not bury the rest of stderr.
const MAX_WARNINGS: usize = 20;

fn warn_all(warnings: &[Warning]) {
    for w in warnings.iter().take(MAX_WARNINGS) {
        eprintln!("pathgen: warning: chain {}: {}", w.chain, w.message);
    }
    if warnings.len() > MAX_WARNINGS {
        eprintln!(
            "pathgen: warning: {} more warnings not shown",
            warnings.len() - MAX_WARNINGS
        );
    }
}

/// Write generated records as a toolpath or, with `--gcode`, as G-code
/// through the same writer as `emit`; the SVG preview goes beside.
fn short_note(short: usize, total: usize, m: &LaserSetup) {
    if short > 0 {
        eprintln!(
            "pathgen: note: {short} of {total} feed moves last less than 1 ms at V ({:.6} mm); a Turbo PMAC \
             stretches them to its least TA and slows down there",
            m.min_block()
        );
    }
}

/// Write generated records as a toolpath or, with `--gcode`, as G-code
/// through the same writer as `emit`; the SVG preview goes beside.
fn write_generated(records: &[Record], o: &GenOutput, source: Option<String>, m: &LaserSetup) -> Result<(), CliError> {
    let (short, total) = microcam::laser::audit::stretched_blocks(records, m, P3::origin());
    short_note(short, total, m);
    if let Some(path) = &o.svg {
        let mut svg = Output::new(Some(path));
        microcam::laser::svg::write_svg(&mut svg, records, m).map_err(CliError::from)?;
        svg.commit()?;
    }
    let mut out = Output::new(o.output.as_deref());
    write_records(records.iter().cloned(), o, source, &mut out)?;
    out.commit()
}

/// The one place generated records become output bytes.
fn write_records(
    records: impl Iterator<Item = Record>,
    o: &GenOutput,
    source: Option<String>,
    out: &mut Output,
) -> Result<(), CliError> {
    match &o.gcode {
        Some(d) => {
            let dialect: Dialect = d.parse().map_err(CliError::input)?;
            let opts = write_options(dialect, &o.writer);
            let name = source.unwrap_or_else(|| "<generated>".into());
            write_gcode(records.map(Ok::<_, CliError>), FeedUnit::MmPerS, opts, &name, out)
        }
        None => {
            let mut w = ToolpathWriter::new(out);
            w.header(&Header {
                feed_unit: FeedUnit::MmPerS,
                source,
            })?;
            for r in records {
                w.record(&r)?;
            }
            w.finish()?;
            Ok(())
        }
    }
}

/// Write records handed over in chunks by `produce` on a second thread, so
/// formatting overlaps planning. Output is byte-identical to
/// [`write_generated`] (same writer, same records, same order).
fn write_streamed(
    o: &GenOutput,
    source: Option<String>,
    produce: impl FnOnce(&mut dyn FnMut(Vec<Record>) -> bool),
) -> Result<(), CliError> {
    let mut out = Output::new(o.output.as_deref());
    let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Record>>(2);
    let written = std::thread::scope(|s| {
        let out = &mut out;
        let writer = s.spawn(move || write_records(rx.into_iter().flatten(), o, source, out));
        // A failed writer drops the receiver; stop planning then.
        produce(&mut |chunk| tx.send(chunk).is_ok());
        drop(tx);
        writer
            .join()
            .unwrap_or_else(|_| Err(CliError::failure("the writer thread panicked")))
    });
    written?;
    out.commit()
}

fn contour_cmd(a: ContourArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let side = a.side;
    let beam = non_negative("beam-diameter", a.beam_diameter)?;
    let distance = match a.offset {
        Some(d) => non_negative("offset", d)?,
        None => 0.5 * beam,
    };
    let o = ContourOptions {
        side,
        distance,
        levels: at_least_one("levels", a.levels)?,
        level_step: finite("level-step", a.level_step)?,
        cleanup_tol: non_negative("cleanup-tol", a.cleanup_tol)?,
        array: a.array,
        pitch: a.pitch,
        start_near: a.start_near.map(|(x, y)| P2::new(x, y)),
        direction: match a.direction.as_str() {
            "ccw" => Direction::Ccw,
            "cw" => Direction::Cw,
            _ => Direction::Keep,
        },
        order: match a.order.as_str() {
            "input" => OrderMode::Input,
            "nearest" => OrderMode::Nearest,
            _ => OrderMode::Optimized,
        },
        origin: P2::origin(),
    };
    let input = cli::open_input(a.file.as_deref())?;
    let name = input.name.clone();
    let timing = std::env::var_os("PATHGEN_TIMING").is_some();
    let t0 = std::time::Instant::now();
    let (header, chains) = read_chains(input.reader).map_err(|e| CliError::in_file(&name, e))?;
    let source = header.source.or(Some(name.clone()));
    a.out.check_size(
        "contour",
        estimated_moves(&chains, &o),
        &format!(
            "{} chains x {} levels x {}x{} copies",
            chains.len(),
            o.levels,
            o.array.0,
            o.array.1
        ),
    )?;
    warn_travel(&chains, &a.machine.machine);
    let t1 = std::time::Instant::now();
    if a.out.svg.is_some() {
        // The preview needs the whole job.
        let job = contour(&chains, &m, &o);
        warn_all(&job.warnings);
        cleanup_note(&job.cleanup, &m, &o);
        return write_generated(&job.records, &a.out, source, &m);
    }
    let (mut short, mut total) = (0, 0);
    let mut warnings = Vec::new();
    let mut cleanup = Default::default();
    write_streamed(&a.out, source, |sink| {
        (warnings, cleanup) = contour_streamed(&chains, &m, &o, |chunk| {
            let (s, t) = microcam::laser::audit::stretched_blocks(&chunk, &m, P3::origin());
            short += s;
            total += t;
            sink(chunk)
        });
    })?;
    warn_all(&warnings);
    cleanup_note(&cleanup, &m, &o);
    short_note(short, total, &m);
    if timing {
        eprintln!(
            "pathgen: timing: read {:.3} s, plan and write {:.3} s",
            (t1 - t0).as_secs_f64(),
            t1.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// What the cleanup of short pieces did, on stderr.
fn cleanup_note(st: &microcam::laser::cleanup::CleanStats, m: &LaserSetup, o: &ContourOptions) {
    let fixed = st.short - st.left;
    if fixed > 0 {
        eprintln!(
            "pathgen: cleanup: {fixed} piece(s) shorter than the least block at V ({:.6} mm) merged into their \
             neighbours or refitted ({} pieces -> {}); largest deviation {:.3e} mm (--cleanup-tol {} mm)",
            m.min_block(),
            st.pieces_in,
            st.pieces_out,
            st.max_dev,
            o.cleanup_tol
        );
    }
    if st.left > 0 {
        eprintln!(
            "pathgen: warning: {} piece(s) shorter than the least block at V ({:.6} mm) could not be removed \
             within --cleanup-tol {} mm",
            st.left,
            m.min_block(),
            o.cleanup_tol
        );
    }
}

/// Largest drawing (mm) taken as plausible when the machine profile gives
/// no travel: no micro-machining stage moves a metre.
const TRAVEL_FALLBACK_MM: f64 = 1000.0;

/// Warn when the drawing is larger than the machine can travel: most
/// often a DXF drawn in other units than the millimetres assumed.
fn warn_travel(chains: &[Chain], machine: &str) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for s in chains.iter().flat_map(|c| &c.segments) {
        for p in [s.start(), s.end()] {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    let size = [hi[0] - lo[0], hi[1] - lo[1]];
    if !(size[0].is_finite() && size[1].is_finite()) {
        return;
    }
    let profile = Machine::load(machine).ok();
    let travel = profile
        .as_ref()
        .and_then(|p| p.limits_min_mm.zip(p.limits_max_mm))
        .map(|(a, b)| [b[0] - a[0], b[1] - a[1]]);
    let (limit, whose) = match travel {
        Some(t) => (t, format!("the machine's travel ({} x {} mm)", t[0], t[1])),
        None => (
            [TRAVEL_FALLBACK_MM; 2],
            format!("{TRAVEL_FALLBACK_MM} mm, more than a laser stage travels (the profile gives no travel)"),
        ),
    };
    if size[0] > limit[0] || size[1] > limit[1] {
        eprintln!(
            "pathgen: warning: the drawing is {:.3} x {:.3} mm, larger than {whose}; chains are in mm, \
             converted by dxf2chains from the DXF's unit ($INSUNITS, millimetres when absent): if the drawing \
             is in another unit, give it with `dxf2chains --units`",
            size[0], size[1]
        );
    }
}

fn finish_pattern(paths: Vec<Tagged>, m: &LaserSetup, out: &GenOutput, what: &str) -> Result<(), CliError> {
    let (records, notes) = plan_paths(&paths, m, None);
    if records.is_empty() {
        eprintln!("pathgen: warning: {what}: nothing to cut with these sizes");
    }
    let mut seen = std::collections::BTreeSet::new();
    let warnings: Vec<Warning> = notes
        .iter()
        .map(|n| n.to_string())
        .filter(|s| seen.insert(s.clone()))
        .map(|message| Warning { chain: 0, message })
        .collect();
    for w in warnings.iter().take(MAX_WARNINGS) {
        eprintln!("pathgen: warning: {what}: {}", w.message);
    }
    write_generated(&records, out, Some(what.to_string()), m)
}

fn helix_cmd(a: HelixArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let r = positive("radius", a.radius)?;
    let pitch = finite("pitch", a.pitch)?;
    let turns = at_least_one("turns", a.turns)?;
    // One arc per turn, a rapid, a lead-in and a lead-out.
    a.out
        .check_size("helix", f64::from(turns) + 4.0, &format!("--turns {turns}"))?;
    let c = P3::new(a.center.0, a.center.1, finite("z", a.z)?);
    let path = patterns::helix(c, r, pitch, turns, !a.cw);
    finish_pattern(vec![all_cut(path)], &m, &a.out, "helix")
}

fn spiral_cmd(a: SpiralArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let step = positive("step", a.step)?;
    let tol = positive("tolerance", a.tolerance)?;
    let c = P3::new(a.center.0, a.center.1, finite("z", a.z)?);
    let path = if a.kind == "square" {
        let size = positive(
            "size",
            a.size.ok_or_else(|| CliError::input("square spiral needs --size"))?,
        )?;
        // Each leg and the loop at its corner (a few pieces).
        a.out.check_size(
            "spiral",
            5.0 * patterns::square_spiral_legs(step, size),
            &format!("--size {size} at --step {step}"),
        )?;
        patterns::square_spiral(c, step, size, a.inward)
    } else {
        let r = positive(
            "radius",
            a.radius
                .ok_or_else(|| CliError::input("archimedean spiral needs --radius"))?,
        )?;
        let inner = a.inner.unwrap_or(step);
        if !(inner.is_finite() && inner >= 0.0 && inner < r) {
            return Err(CliError::input(format!("--inner must be in [0, radius), got {inner}")));
        }
        let how = format!("--radius {r} at --step {step}");
        a.out
            .check_size("spiral", patterns::archimedean_pieces(inner, step, r), &how)?;
        let max = usize::try_from(a.out.max_moves).unwrap_or(usize::MAX);
        patterns::archimedean_limited(c, inner, step, r, a.inward, tol, max)
            .map_err(|n| a.out.too_big("spiral", n, &format!("{how} within --tolerance {tol}")))?
    };
    finish_pattern(vec![all_cut(path)], &m, &a.out, "spiral")
}

fn zigzag_cmd(a: ZigzagArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let (plane, along_second) = match (a.plane.as_str(), a.along.as_str()) {
        ("xy", "x") => (Plane::Xy, false),
        ("xy", "y") => (Plane::Xy, true),
        // Plane XZ's axes are (Z, X): lines along X are its second axis.
        ("xz", "x") => (Plane::Xz, true),
        ("xz", "z") => (Plane::Xz, false),
        (p, d) => return Err(CliError::input(format!("--along {d} is not in plane {p}"))),
    };
    let o = P3::new(a.origin.0, a.origin.1, a.origin.2);
    let z = patterns::Zigzag {
        origin: o,
        plane,
        along_second,
        length: positive("length", a.length)?,
        width: non_negative("width", a.width)?,
        step: positive("step", a.step)?,
        corner_radius: non_negative("corner-radius", a.corner_radius)?,
    };
    // Each cut line and its turnaround (a few pieces).
    a.out.check_size(
        "zigzag",
        5.0 * patterns::zigzag_lines(z.width, z.step),
        &format!("--width {} at --step {}", z.width, z.step),
    )?;
    let path = patterns::zigzag(&z, &m);
    finish_pattern(vec![path], &m, &a.out, "zigzag")
}

fn cone_cmd(a: ConeArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let h = positive("height", a.height)?;
    let (d1, d2) = (positive("d1", a.d1)?, positive("d2", a.d2)?);
    let beam = non_negative("beam-diameter", a.beam_diameter)?;
    let step = positive("step", a.step.unwrap_or(beam))?;
    let tol = positive("tolerance", a.tolerance)?;
    let levels = at_least_one("levels", a.levels)?;
    let z0 = finite("z", a.z)?;
    // At least the widest section's spiral on every level.
    let how = format!("--levels {levels} at --step {step}");
    let widest = 0.5 * d1.max(d2);
    a.out.check_size(
        "cone",
        f64::from(levels) * patterns::archimedean_pieces(step, step, widest.max(step)),
        &how,
    )?;
    let mut budget = usize::try_from(a.out.max_moves).unwrap_or(usize::MAX);
    let mut paths = Vec::new();
    for (z, d) in patterns::cone_levels(z0, d1, d2, h, levels) {
        let r = 0.5 * d - 0.5 * beam;
        if r <= step {
            eprintln!("pathgen: warning: cone: section at z={z} (diameter {d}) is narrower than the beam; skipped");
            continue;
        }
        let c = P3::new(a.center.0, a.center.1, z);
        let path = patterns::archimedean_limited(c, step, step, r, false, tol, budget).map_err(|n| {
            a.out.too_big(
                "cone",
                n * f64::from(levels),
                &format!("{how} within --tolerance {tol}"),
            )
        })?;
        budget = budget.saturating_sub(path.len());
        paths.push(all_cut(path));
    }
    finish_pattern(paths, &m, &a.out, "cone")
}

fn arcfit_cmd(a: ArcfitArgs) -> Result<(), CliError> {
    let tol = positive("tolerance", a.tolerance)?;
    let mut input = cli::open_input(a.file.as_deref())?;
    let name = input.name.clone();
    let text = cli::read_to_string(&mut input)?;
    let pts = arcfit::parse_points(&text).map_err(|(line, msg)| CliError::input(format!("{name}:{line}: {msg}")))?;
    if pts.len() < 2 {
        return Err(CliError::input(format!("{name}: need at least two points")));
    }
    let fit = arcfit::fit_points(&pts, tol, 0.0, a.polyline);
    if fit.is_empty() {
        return Err(CliError::input(format!("{name}: need at least two distinct points")));
    }
    // Dense check: 256 samples per piece against the polyline, and every
    // point against the fit.
    let dev_poly = arcfit::max_deviation(&fit, &pts, 256);
    let dev_pts = arcfit::point_deviation(&fit, &pts);
    let dev = if a.polyline { dev_poly } else { dev_pts };
    let mut out = Output::new(a.output.as_deref());
    use std::io::Write;
    if a.report {
        let arcs = fit.iter().filter(|e| matches!(e, Elem::Arc(_))).count();
        writeln!(
            out,
            "{{\"schema\":\"microcam.arcfit-report/1\",\"points\":{},\"polyline_blocks\":{},\"biarc_blocks\":{},\"arcs\":{},\"lines\":{},\"tolerance_mm\":{},\"max_point_deviation_mm\":{:.9},\"max_polyline_deviation_mm\":{:.9}}}",
            pts.len(),
            pts.len() - 1,
            fit.len(),
            arcs,
            fit.len() - arcs,
            tol,
            dev_pts,
            dev_poly
        )?;
    } else {
        let segments = fit
            .iter()
            .map(|e| match e {
                Elem::Line(l) => Segment::Line {
                    start: l.start,
                    end: l.end,
                },
                Elem::Arc(x) => Segment::Arc {
                    start: x.start,
                    end: x.end,
                    center: x.center,
                    ccw: x.ccw,
                },
            })
            .collect();
        let mut w = ChainsWriter::new(&mut out);
        w.header(&ChainsHeader { source: Some(name) })?;
        w.chain(&Chain {
            id: 1,
            closed: false,
            segments,
            ..Default::default()
        })?;
        w.finish()?;
    }
    if dev > tol {
        eprintln!("pathgen: warning: arcfit: deviation {dev} mm exceeds the tolerance {tol} mm");
    }
    out.commit()
}

fn audit_cmd(a: AuditArgs) -> Result<(), CliError> {
    let m = a.machine.machine(None)?;
    positive("precision", a.precision)?;
    let input = cli::open_input(a.file.as_deref())?;
    let source = ToolpathSource::open(input, &ReadOptions::default())?;
    let unit = source.header.feed_unit;
    let mut records = Vec::new();
    for r in source {
        let mut r = r?;
        // Audit in mm/s whatever the program's feed unit.
        if let Record::Move(mv) = &mut r {
            mv.feed = mv.feed.map(|f| unit.convert(f, FeedUnit::MmPerS));
        }
        records.push(r);
    }
    let au = microcam::laser::audit::audit(&records, &m, P3::origin());
    println!("{}", au.report_json(&m, a.precision));
    let ok = au.passes(&m, a.precision);
    if ok {
        Ok(())
    } else {
        Err(CliError::verdict(
            "the toolpath breaks the machine's limits (see the report)",
        ))
    }
}
