//! pathgen: toolpaths, and G-code from toolpaths.

use clap::{Args as ClapArgs, Parser, Subcommand};
use microcam::cli::{self, CliError, Output};
use microcam::gcode::writer::{GcodeWriter, WriteError, WriteOptions};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::formats::chains::ChainsReader;
use microcam::formats::toolpath::ToolpathWriter;
use microcam::geometry::P2;
use microcam::model::toolpath::{FeedUnit, Header, Record};
use microcam::paths::contour::{ContourOptions, Direction, OrderMode, Warning, contour};
use microcam::paths::machine::Machine;
use microcam::paths::offset::Side;
use microcam::source::ToolpathSource;
use std::path::PathBuf;
use std::process::ExitCode;

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

/// The stage and shutter (defaults: seed 000's laser stage, Fig. 6-40).
#[derive(ClapArgs)]
struct MachineArgs {
    /// Feed V while the beam is on (mm/s).
    #[arg(long, default_value_t = 2.0)]
    feed: f64,
    /// Acceleration time TA (ms).
    #[arg(long, default_value_t = 100.0)]
    ta: f64,
    /// Deceleration time TD (ms).
    #[arg(long, default_value_t = 100.0)]
    td: f64,
    /// S-curve time TS (ms).
    #[arg(long, default_value_t = 0.0)]
    ts: f64,
    /// Acceleration (mm/s^2): sets TA = TD = V/a instead.
    #[arg(long)]
    accel: Option<f64>,
    /// Shutter delay before opening starts (ms).
    #[arg(long, default_value_t = 3.0)]
    open_delay: f64,
    /// Shutter transfer time to fully open (ms).
    #[arg(long, default_value_t = 9.0)]
    open_transfer: f64,
    /// Shutter delay before closing starts (ms).
    #[arg(long, default_value_t = 3.0)]
    close_delay: f64,
    /// Shutter transfer time to fully closed (ms).
    #[arg(long, default_value_t = 14.0)]
    close_transfer: f64,
    /// Minimum exposure (ms); shorter cuts are reported.
    #[arg(long, default_value_t = 15.0)]
    min_exposure: f64,
    /// Corners turning less than this (degrees) are tangent: no loop.
    #[arg(long, default_value_t = 0.5)]
    tangent_tol: f64,
}

impl MachineArgs {
    fn machine(&self) -> Result<Machine, CliError> {
        let mut m = Machine {
            feed: self.feed,
            ta_ms: self.ta,
            td_ms: self.td,
            ts_ms: self.ts,
            open_delay_ms: self.open_delay,
            open_transfer_ms: self.open_transfer,
            close_delay_ms: self.close_delay,
            close_transfer_ms: self.close_transfer,
            min_exposure_ms: self.min_exposure,
            tangent_tol_deg: self.tangent_tol,
        };
        if let Some(a) = self.accel {
            if !(a.is_finite() && a > 0.0) {
                return Err(CliError::input(format!("--accel must be positive, got {a}")));
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
}

#[derive(ClapArgs)]
struct ContourArgs {
    /// Chains to cut ('-' for stdin).
    file: Option<PathBuf>,
    /// Where the beam centre runs: on the chain, inside/outside closed
    /// chains, or left/right of travel.
    #[arg(long, value_parser = ["on", "inside", "outside", "left", "right"], default_value = "on")]
    side: String,
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
    /// Chain order: input, nearest (the seed's), optimized (nearest + 2-opt/Or-opt).
    #[arg(long, value_parser = ["input", "nearest", "optimized"], default_value = "optimized")]
    order: String,
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
    let cli = Cli::parse();
    cli::run("pathgen", || match cli.command {
        Command::Emit(a) => emit(a),
        Command::Contour(a) => contour_cmd(*a),
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
        eprintln!("pathgen: warning: {} more warnings not shown", warnings.len() - MAX_WARNINGS);
    }
}

/// Write generated records as a toolpath or, with `--gcode`, as G-code
/// through the same writer as `emit`; the SVG preview goes beside.
fn write_generated(records: &[Record], o: &GenOutput, source: Option<String>, m: &Machine) -> Result<(), CliError> {
    if let Some(path) = &o.svg {
        let mut svg = Output::new(Some(path));
        microcam::paths::svg::write_svg(&mut svg, records, m).map_err(CliError::from)?;
        svg.commit()?;
    }
    let mut out = Output::new(o.output.as_deref());
    match &o.gcode {
        Some(d) => {
            let dialect: Dialect = d.parse().map_err(CliError::input)?;
            let opts = write_options(dialect, &o.writer);
            let name = source.unwrap_or_else(|| "<generated>".into());
            write_gcode(
                records.iter().cloned().map(Ok::<_, CliError>),
                FeedUnit::MmPerS,
                opts,
                &name,
                &mut out,
            )?;
        }
        None => {
            let mut w = ToolpathWriter::new(&mut out);
            w.header(&Header {
                feed_unit: FeedUnit::MmPerS,
                source,
            })?;
            for r in records {
                w.record(r)?;
            }
            w.finish()?;
        }
    }
    out.commit()
}

fn contour_cmd(a: ContourArgs) -> Result<(), CliError> {
    let m = a.machine.machine()?;
    let side = match a.side.as_str() {
        "inside" => Side::Inside,
        "outside" => Side::Outside,
        "left" => Side::Left,
        "right" => Side::Right,
        _ => Side::On,
    };
    let distance = a.offset.unwrap_or(0.5 * a.beam_diameter);
    if !(distance.is_finite() && distance >= 0.0) {
        return Err(CliError::input(format!("offset must be >= 0, got {distance}")));
    }
    let o = ContourOptions {
        side,
        distance,
        levels: a.levels.max(1),
        level_step: a.level_step,
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
    let reader = ChainsReader::new(input.reader).map_err(|e| CliError::in_file(&name, e))?;
    let source = reader.header().source.clone().or(Some(name.clone()));
    let timing = std::env::var_os("PATHGEN_TIMING").is_some();
    let t0 = std::time::Instant::now();
    let chains = reader
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| CliError::in_file(&name, e))?;
    let t1 = std::time::Instant::now();
    let job = contour(&chains, &m, &o);
    drop(chains);
    let t2 = std::time::Instant::now();
    warn_all(&job.warnings);
    write_generated(&job.records, &a.out, source, &m)?;
    if timing {
        let t3 = std::time::Instant::now();
        eprintln!(
            "pathgen: timing: read {:.3} s, plan {:.3} s, write {:.3} s",
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t3 - t2).as_secs_f64()
        );
    }
    Ok(())
}
