//! gsim: interpret and simulate a program (G-code of either dialect, or
//! toolpath JSON Lines).

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::Parser;
use microcam::cli::{self, CliError, Output};
use microcam::cutter::Cutter;
use microcam::formats::read_chains;
use microcam::formats::toolpath::{StreamError, write_stream_batches};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::geometry::P3;
use microcam::machine::{Controller, Machine, Overrides};
use microcam::model::chain::Chain;
use microcam::model::toolpath::{FeedUnit, Record};
use microcam::preview::Preview;
use microcam::progress::{self, Meter, Show};
use microcam::sim::beam::CommandTiming;
use microcam::sim::picture::write_png;
use microcam::sim::report::{SimError, Simulator, StepPlan};
use microcam::sim::stl::write_stl;
use microcam::sim::stock::Stock;
use microcam::source::ToolpathSource;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  gsim --moves part.ngc > part.jsonl        interpreted moves as toolpath JSON Lines
  gsim --moves --dialect pmac prog.pmc      a PMAC motion program
  pathgen emit --dialect pmac part.jsonl | gsim    report on a generated program
  gsim --machine micro-mill --blocks b.csv prog.pmc   per-block feeds and times
  gsim --machine my-stage.json --ta-ms 50 prog.pmc    a profile file, TA overridden
  gsim part.ngc | jq .cycle_time_s
  gsim --svg part.svg part.ngc              report, and a top-view preview

Without --moves gsim prints a microcam.gsim/1 report: path lengths, counts
and extents; cycle, cutting, rapid and dwell time under the machine's
controller model; the blocks that cannot reach their feed and why; where
the shutter really passes the beam, per cut. Built-in machines: laser-stage
(Turbo PMAC, the default for PMAC programs and mm/s toolpaths), micro-mill
(Turbo PMAC, TA 133 ms), lookahead (grbl-style planner, the default for ISO
programs). Moves outside the machine's travel, feed moves without a feed and
bad profiles are errors (exit 2) naming the line.

Input is G-code (ISO/RS274 or Turbo PMAC text, detected unless --dialect is
given) or microcam.toolpath/1 JSON Lines; '-' or no FILE reads stdin.
Exit status: 0 ok, 1 failure, 2 bad usage or bad input (the message names
the file and line).";

/// Interpret a program and report on it.
#[derive(Parser)]
#[command(name = "gsim", version, about, after_help = EXAMPLES)]
struct Args {
    /// Program to read ('-' for stdin).
    file: Option<PathBuf>,
    /// Print the interpreted program as microcam.toolpath/1 JSON Lines
    /// (absolute positions in mm, arcs with centres, beam state).
    #[arg(long)]
    moves: bool,
    /// G-code dialect (default: detected from the text).
    #[arg(long, value_parser = ["iso", "pmac"])]
    dialect: Option<String>,
    /// PMAC variable that drives the shutter.
    #[arg(long, default_value = "M33")]
    shutter_var: String,
    /// PMAC variable that counts blocks (its assignments are bookkeeping).
    #[arg(long, default_value = "P400")]
    line_counter_var: String,
    /// Machine position when the program starts, mm: X,Y,Z.
    // One string parsed here: clap's delimiter and value count disagree on
    // "0,0,-1" (it counted the items before splitting them).
    #[arg(long, default_value = "0,0,0", value_name = "X,Y,Z", allow_hyphen_values = true)]
    start: String,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Machine profile: a built-in name (laser-stage, micro-mill, lookahead)
    /// or a microcam.machine/1 JSON file.
    #[arg(long)]
    machine: Option<String>,
    /// Per-block series as CSV (line, kind, length, commanded and achieved
    /// feed, time, limit).
    #[arg(long, value_name = "FILE.csv")]
    blocks: Option<PathBuf>,
    /// Shutter timing for switches whose statement is not known: `M33==`
    /// (sync, as pathgen writes) or `M33=` (immediate, executed one move
    /// ahead). PMAC programs say it per statement, which wins.
    #[arg(long, value_parser = ["sync", "immediate"], default_value = "sync")]
    shutter_timing: String,
    /// Controller model, overriding the profile's.
    #[arg(long, value_enum)]
    controller: Option<Controller>,
    /// PMAC acceleration time TA until the program sets one, ms.
    #[arg(long, allow_negative_numbers = true)]
    ta_ms: Option<f64>,
    /// PMAC S-curve time TS until the program sets one, ms.
    #[arg(long, allow_negative_numbers = true)]
    ts_ms: Option<f64>,
    /// Path acceleration of the look-ahead planner, mm/s².
    #[arg(long, allow_negative_numbers = true)]
    accel_mm_s2: Option<f64>,
    /// Junction deviation of the look-ahead planner, mm.
    #[arg(long, allow_negative_numbers = true)]
    junction_deviation_mm: Option<f64>,
    /// Blocks the look-ahead planner sees.
    #[arg(long)]
    lookahead_blocks: Option<usize>,
    /// Highest path feed, mm/s.
    #[arg(long, allow_negative_numbers = true)]
    max_feed_mm_s: Option<f64>,
    /// Rapid speed, mm/s.
    #[arg(long, allow_negative_numbers = true)]
    rapid_mm_s: Option<f64>,
    /// Blocks per second the controller can compute (0 = no limit).
    #[arg(long, allow_negative_numbers = true)]
    block_rate_hz: Option<f64>,
    /// The drawing's chains (microcam.chains/1): report exposure per chain,
    /// matching each cut to the chain its moves lie on.
    #[arg(long, value_name = "FILE")]
    chains: Option<PathBuf>,
    /// How far (mm, in XY) a cut's moves may lie from a drawing chain and
    /// still count as cutting it.
    #[arg(
        long = "chain-tol",
        alias = "chain-tol-mm",
        value_name = "CHAIN_TOL",
        default_value_t = 0.1
    )]
    chain_tol_mm: f64,
    /// Stock box for material removal, mm: XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX.
    /// Without --tool each tool cuts with its own cutter, from the tool
    /// table and the program's CAM tool comments (`(T1 D=3 CR=0.5 ...)`).
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    stock: Option<String>,
    /// Cutter for material removal: flat:D, ball:D or torus:D:RC (mm); one
    /// cutter for the whole program.
    #[arg(long, requires = "stock")]
    tool: Option<String>,
    /// LinuxCNC tool table (.tbl) for ISO programs: cutter radius
    /// compensation by D word (G41/G42) takes the tool's diameter from it.
    #[arg(long, value_name = "FILE.tbl")]
    tool_table: Option<PathBuf>,
    /// The tool table's lengths are inches (default: millimetres).
    #[arg(long, requires = "tool_table")]
    tool_table_inch: bool,
    /// Folders searched for `name.ngc` when an ISO program calls a
    /// subroutine `o<name>` it does not define (as LinuxCNC's
    /// SUBROUTINE_PATH); repeat the option or separate folders with ':'.
    #[arg(long, value_name = "DIR[:DIR...]")]
    subroutine_path: Vec<String>,
    /// PMAC download files: read motion program N (`OPEN PROG N`);
    /// default: the first motion program in the file.
    #[arg(long, value_name = "N")]
    program: Option<u32>,
    /// Height-field cell size, mm (default: tool diameter / 50).
    #[arg(long)]
    cell_mm: Option<f64>,
    /// The simulated stock as a watertight binary STL (needs --stock).
    #[arg(long, value_name = "FILE.stl", requires = "stock")]
    stl: Option<PathBuf>,
    /// Top view of the simulated stock with the path drawn over it, PNG
    /// (needs --stock).
    #[arg(long, value_name = "FILE.png", requires = "stock")]
    png: Option<PathBuf>,
    /// Per-block removed volume as CSV (needs --stock).
    #[arg(long, value_name = "FILE.csv", requires = "stock")]
    removal: Option<PathBuf>,
    /// Cutter flutes: cut feed moves in steps of feed per tooth × --step-scale
    /// and report chip volume per step (Bayesteh (2013) §3.1).
    #[arg(long, requires = "stock")]
    flutes: Option<u32>,
    /// Steps are this many feeds per tooth long.
    #[arg(long, default_value_t = 10.0, requires = "flutes")]
    step_scale: f64,
    /// Spindle speed, rpm, overriding the program's S words.
    #[arg(long, requires = "flutes")]
    rpm: Option<f64>,
    /// Per-step chip volume as CSV (needs --flutes).
    #[arg(long, value_name = "FILE.csv", requires = "flutes")]
    steps: Option<PathBuf>,
    /// Show progress on stderr even when it is not a terminal (plain lines,
    /// for a log); on a terminal a bar appears by itself for long runs.
    #[arg(long, conflicts_with = "quiet")]
    progress: bool,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
    /// Also write a top-view SVG preview of the path (exact arcs, beam-on
    /// moves in red) to this file.
    #[arg(long, value_name = "FILE.svg")]
    svg: Option<PathBuf>,
    /// Machine travel, mm: XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX.
    #[arg(long, value_name = "XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX", allow_hyphen_values = true)]
    limits: Option<String>,
}

fn main() -> ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("gsim", || run(args))
}
/// `--limits`: six comma-separated numbers.
fn parse_limits(s: &str) -> Result<[f64; 6], CliError> {
    microcam::cli::parse_numbers::<6>(s, "--limits", "XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX")
}

/// All chains of a drawing.
fn read_drawing(path: &std::path::Path) -> Result<Vec<Chain>, CliError> {
    let input = cli::open_input(Some(path))?;
    let (_, chains) = read_chains(input.reader).map_err(|e| CliError::in_file(&input.name, e))?;
    Ok(chains)
}

/// A bad program is bad input (exit 2); a failed series write is a failure.
fn sim_error(source: &str, e: SimError) -> CliError {
    match e {
        SimError::Io(e) => CliError::failure(e.to_string()),
        e => CliError::in_file(source, e),
    }
}

/// The first lines of a program (where CAM posts list their tools), or
/// nothing when it cannot be read here (the reader names that error).
fn program_head(p: &std::path::Path) -> String {
    use std::io::BufRead;
    let Ok(f) = std::fs::File::open(p) else {
        return String::new();
    };
    let mut text = String::new();
    for line in std::io::BufReader::new(f).lines().take(2000) {
        match line {
            Ok(l) => {
                text.push_str(&l);
                text.push('\n');
            }
            Err(_) => break,
        }
    }
    text
}

fn run(args: Args) -> Result<(), CliError> {
    let dialect = args
        .dialect
        .as_deref()
        .map(|d| d.parse::<Dialect>().map_err(CliError::input))
        .transpose()?;
    let st = microcam::cli::parse_numbers::<3>(&args.start, "--start", "X,Y,Z")?;
    let start = P3::new(st[0], st[1], st[2]);
    let tool_table = match args.tool_table.as_deref() {
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|e| CliError::in_file(&p.display().to_string(), e))?;
            let t = microcam::gcode::tooltable::ToolTable::parse(&text, args.tool_table_inch)
                .map_err(|e| CliError::input(format!("{}: {e}", p.display())))?;
            Some(std::sync::Arc::new(t))
        }
        None => None,
    };
    let opts = ReadOptions {
        dialect,
        shutter_var: args.shutter_var.to_ascii_uppercase(),
        line_counter_var: args.line_counter_var.to_ascii_uppercase(),
        start,
        tool_table: tool_table.clone(),
        subroutine_path: args
            .subroutine_path
            .iter()
            .flat_map(|p| p.split(':'))
            .filter(|p| !p.is_empty())
            .map(PathBuf::from)
            .collect(),
        pmac_program: args.program,
        ..ReadOptions::default()
    };
    let input = cli::open_input(args.file.as_deref())?;
    let source = ToolpathSource::open(input, &opts)?;
    let title = source.name().to_string();
    // What the reader accepted without acting on it (PMAC on-line
    // commands, skipped PLCs), on stderr as `file:line: note: ...`.
    let notes = opts.notes.clone();
    let print_notes = || {
        for (line, text) in notes.take() {
            microcam::diag!("gsim: {title}:{line}: note: {text}");
        }
    };
    let r = simulate(&args, source, start, &title, tool_table.as_deref());
    print_notes();
    r
}

#[allow(clippy::too_many_lines)]
fn simulate(
    args: &Args,
    source: ToolpathSource,
    start: P3,
    title: &str,
    tool_table: Option<&microcam::gcode::tooltable::ToolTable>,
) -> Result<(), CliError> {
    let title = title.to_string();
    let mut out = Output::new(args.output.as_deref());
    let mut preview = args.svg.as_ref().map(|_| Preview::new(start));
    let mut observe = |r: &Record| {
        if let Some(p) = preview.as_mut() {
            p.add(r);
        }
    };
    if args.moves {
        let header = source.header.clone();
        let mut source = source;
        let fill = |batch: &mut Vec<Record>, max: usize| {
            let from = batch.len();
            source.next_batch(batch, max)?;
            batch[from..].iter().for_each(&mut observe);
            Ok(())
        };
        // Interpret on this thread, format and write on another.
        match write_stream_batches(&header, fill, &mut out) {
            Ok(_) => {}
            Err(StreamError::Source(e)) => return Err(e),
            Err(StreamError::Io(e)) => return Err(e.into()),
        }
    } else {
        let name = source.header.source.clone();
        let spec = args.machine.clone().unwrap_or_else(|| {
            match source.header.feed_unit {
                FeedUnit::MmPerS => "laser-stage",
                FeedUnit::MmPerMin => "lookahead",
            }
            .to_string()
        });
        let mut machine = Machine::load(&spec).map_err(|e| CliError::input(e.to_string()))?;
        let overrides = Overrides {
            controller: args.controller,
            ta_ms: args.ta_ms,
            ts_ms: args.ts_ms,
            accel_mm_s2: args.accel_mm_s2,
            junction_deviation_mm: args.junction_deviation_mm,
            max_feed_mm_s: args.max_feed_mm_s,
            rapid_mm_s: args.rapid_mm_s,
            block_rate_hz: args.block_rate_hz,
            lookahead_blocks: args.lookahead_blocks,
            limits_mm: args.limits.as_deref().map(parse_limits).transpose()?,
        };
        machine.apply(&overrides).map_err(|e| CliError::input(e.to_string()))?;
        let timing = if args.shutter_timing == "immediate" {
            CommandTiming::Immediate
        } else {
            CommandTiming::Sync
        };
        let csv = args.blocks.as_deref().map(|p| Output::new(Some(p)));
        let src_name = source.name().to_string();
        let header = source.header.clone();
        let mut sim = Simulator::new(&header, machine, timing, start, csv);
        if args.chains.is_some() {
            sim = sim.with_chain_probes();
        }
        if let Some(st) = args.stock.as_deref() {
            // One cutter (--tool), or one per tool number.
            let (cutter, per_tool) = match args.tool.as_deref() {
                Some(tool) => (
                    Cutter::parse(tool).map_err(|e| CliError::input(format!("--tool: {e}")))?,
                    None,
                ),
                None => {
                    let text = match args.file.as_deref() {
                        Some(p) if p != std::path::Path::new("-") => program_head(p),
                        _ => String::new(),
                    };
                    let cam = microcam::gcode::tooltable::cam_tool_comments(
                        &text,
                        microcam::gcode::tooltable::first_units_are_inch(&text),
                    );
                    let tools = microcam::gcode::tooltable::tool_cutters(tool_table, &cam);
                    let first = tools.values().next().copied().ok_or_else(|| {
                        CliError::input(
                            "--stock needs a cutter: --tool, or tools with a diameter in --tool-table or in the program's CAM tool comments ((T1 D=3 CR=0.5 ...))",
                        )
                    })?;
                    (first, Some(tools))
                }
            };
            let smallest = per_tool.as_ref().map_or(cutter.radius(), |t| {
                t.values().map(Cutter::radius).fold(f64::INFINITY, f64::min)
            });
            let b = microcam::cli::parse_numbers::<6>(st, "--stock", "X0,Y0,Z0,X1,Y1,Z1")?;
            let cell = args.cell_mm.unwrap_or(smallest / 25.0);
            let stock = Stock::new(P3::new(b[0], b[1], b[2]), P3::new(b[3], b[4], b[5]), cell)
                .map_err(|e| CliError::input(format!("--stock: {e}")))?;
            let rcsv = args.removal.as_deref().map(|p| Output::new(Some(p)));
            sim = sim.with_removal(stock, cutter, rcsv);
            if let Some(tools) = per_tool {
                sim = sim.with_tool_cutters(tools);
            }
            if args.png.is_some() {
                sim = sim.with_picture();
            }
            if let Some(flutes) = args.flutes {
                if flutes == 0 || !(args.step_scale.is_finite() && args.step_scale > 0.0) {
                    return Err(CliError::input("--flutes and --step-scale must be positive"));
                }
                let plan = StepPlan {
                    flutes,
                    scale: args.step_scale,
                    rpm: args.rpm,
                };
                sim = sim.with_steps(plan, args.steps.as_deref().map(|p| Output::new(Some(p))));
            }
        }
        // A bar for long runs where a person watches (a terminal), plain
        // lines with --progress, nothing with --quiet.
        let meter = Meter::start(
            "gsim",
            "simulating records",
            0,
            Show::from_flags(args.quiet, args.progress),
        );
        for rec in source {
            let rec = rec?;
            observe(&rec);
            sim.add(&rec).map_err(|e| sim_error(&src_name, e))?;
            progress::advance(1);
        }
        meter.finish();
        let (mut report, series) = sim.finish().map_err(|e| sim_error(&src_name, e))?;
        if let Some(p) = args.chains.as_deref() {
            report = report.with_drawing(&read_drawing(p)?, args.chain_tol_mm);
        }
        writeln!(out, "{}", report.to_json(name.as_deref()))?;
        for w in series.into_iter().flatten() {
            w.commit()?;
        }
        if let (Some(p), Some((_, stock)), Some(o)) = (args.png.as_deref(), report.removal.as_ref(), &report.picture) {
            let (w, h, rgb) = o.render(stock);
            let mut out = Output::new(Some(p));
            write_png(&mut out, w, h, &rgb).map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?;
            out.commit()?;
        }
        if let (Some(p), Some((_, stock))) = (args.stl.as_deref(), report.removal.as_ref()) {
            let mut o = Output::new(Some(p));
            write_stl(stock, &mut o).map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?;
            o.commit()?;
        }
    }
    if let (Some(path), Some(p)) = (args.svg.as_deref(), preview) {
        let mut f = Output::new(Some(path));
        f.write_all(p.finish(&title).as_bytes())?;
        f.commit()?;
    }
    out.commit()
}
