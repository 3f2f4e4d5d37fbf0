//! feedopt: new feeds for a milling program from its simulated chip volume.

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::{Parser, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::cutter::Cutter;
use microcam::feedopt::force::Coefficients;
use microcam::feedopt::schedule::By;
use microcam::feedopt::{self, FeedoptError, Mode, Options, Target, report};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::geometry::P3;
use microcam::machine::{Machine, Overrides};
use microcam::progress::{Meter, Show};
use std::io::Write;
use std::path::PathBuf;

const EXAMPLES: &str = "\
Examples:
  feedopt --tool flat:0.794 --stock -2,-2,-1,2,2,0 --report r.json pocket.ngc > fast.ngc
  feedopt --mode split --rpm 60000 --tool flat:0.794 --stock -2,-2,-1,2,2,0 \\
          --report r.json --csv steps.csv --svg profile.svg --png profile.png pocket.pmc > fast.pmc
  feedopt --force --target force --tool flat:0.794 --stock -2,-2,-1,2,2,0 pocket.ngc

The program (ISO or Turbo PMAC text) is simulated on a height-field stock in
steps of f_min per tooth x 10 (Bayesteh 2013 ch. 3); each step's chip volume
per tooth maps linearly to a feed per tooth between --fz-max-um (smallest
chip) and --fz-min-um (largest chip), smoothed over --window-mm of path and
capped so no chip exceeds the largest chip at f_min. per-block mode gives each
block one feed (mean chip, or --by max); split mode adds sub-blocks, none
shorter in time than the controller's minimum block (PMAC: the acceleration
time TA; 0.4 mm at 3 mm/s on the thesis' stage), and writes the per-block
program instead when splitting would not save time under gsim's time model.
naive splits at every step, as the thesis first did, for comparison.

Only F words change (split mode also inserts sub-block lines marked
'feedopt split'); comments, N numbers and other words are kept byte for
byte, and running feedopt on its own output changes nothing. Plunges (no XY
travel) keep their feed; feed moves that cut nothing get f_max or --air-feed.

Input: '-' or no FILE reads stdin; the program goes to stdout (or -o).
Exit status: 0 ok, 1 failure, 2 bad usage or bad input (no spindle speed,
path off the stock, a tool that never cuts; nothing is written).";

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    PerBlock,
    Split,
    Naive,
}

#[derive(Clone, Copy, ValueEnum)]
enum ByArg {
    Mean,
    Max,
}

#[derive(Clone, Copy, ValueEnum)]
enum TargetArg {
    Chip,
    Force,
}

#[derive(Clone, Copy, ValueEnum)]
enum DialectArg {
    Iso,
    Pmac,
}

/// Schedule feeds from simulated chip volume.
#[derive(Parser)]
#[command(name = "feedopt", version, about, after_help = EXAMPLES)]
struct Args {
    /// Program to read ('-' for stdin).
    file: Option<PathBuf>,
    /// Write the program here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// The microcam.feedopt/1 JSON report.
    #[arg(long, value_name = "FILE.json")]
    report: Option<PathBuf>,
    /// Per-step series (chip, feed, force before and after) as CSV.
    #[arg(long, value_name = "FILE.csv")]
    csv: Option<PathBuf>,
    /// Chip-volume and feed profiles along the path as SVG.
    #[arg(long, value_name = "FILE.svg")]
    svg: Option<PathBuf>,
    /// Chip-volume and feed profiles along the path as PNG (upper panel
    /// chip volume per tooth, lower feed per tooth; grey before, blue after).
    #[arg(long, value_name = "FILE.png")]
    png: Option<PathBuf>,
    /// One feed per block, or sub-blocks.
    #[arg(long, value_enum, default_value = "per-block")]
    mode: ModeArg,
    /// A block's feed from its mean chip or its largest chip.
    #[arg(long, value_enum, default_value = "mean")]
    by: ByArg,
    /// Schedule for a chip-volume band or a constant mean force (needs --force).
    #[arg(long, value_enum, default_value = "chip")]
    target: TargetArg,
    /// Feed per tooth at the largest chip, µm.
    #[arg(long, default_value_t = 1.0)]
    fz_min_um: f64,
    /// Feed per tooth at the smallest chip, µm.
    #[arg(long, default_value_t = 1.5)]
    fz_max_um: f64,
    /// Cutter flutes.
    #[arg(long, default_value_t = 2)]
    flutes: u32,
    /// Spindle speed, rpm, overriding the program's S words (PMAC programs
    /// have none).
    #[arg(long)]
    rpm: Option<f64>,
    /// Cutter: flat:D, ball:D or torus:D:RC (mm).
    #[arg(long)]
    tool: String,
    /// Stock box, mm: X0,Y0,Z0,X1,Y1,Z1.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    stock: String,
    /// Height-field cell, mm (default: tool diameter / 50).
    #[arg(long)]
    cell_mm: Option<f64>,
    /// Simulation step, mm (default: f_min per tooth × 10).
    #[arg(long)]
    step_mm: Option<f64>,
    /// Moving-average window, mm of path.
    #[arg(long, default_value_t = 0.2)]
    window_mm: f64,
    /// Feed for feed moves that cut nothing, in the program's unit
    /// (default: f_max).
    #[arg(long)]
    air_feed: Option<f64>,
    /// Shortest sub-block, ms (default: the machine's PMAC TA).
    #[arg(long)]
    min_block_ms: Option<f64>,
    /// Merge neighbouring sub-blocks whose feeds differ by less than this
    /// fraction.
    #[arg(long, default_value_t = 0.05)]
    merge_tol: f64,
    /// Machine profile: built-in name or microcam.machine/1 file.
    #[arg(long, default_value = "micro-mill")]
    machine: String,
    /// PMAC acceleration time TA, ms, overriding the profile's.
    #[arg(long)]
    ta_ms: Option<f64>,
    /// Estimate cutting forces (mechanistic model; default coefficients are
    /// aluminium-alloy figures from Altintas, Manufacturing Automation).
    #[arg(long)]
    force: bool,
    /// Force coefficients file (JSON: ktc_n_mm2, krc_n_mm2, kte_n_mm,
    /// kre_n_mm); implies --force.
    #[arg(long, value_name = "FILE.json")]
    force_coefficients: Option<PathBuf>,
    /// G-code dialect (default: detected).
    #[arg(long, value_enum)]
    dialect: Option<DialectArg>,
    /// Machine position when the program starts, mm: X,Y,Z.
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    start: String,
    /// No progress bar on stderr (notes, warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
}
fn main() -> std::process::ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("feedopt", || run(args))
}

fn run(a: Args) -> Result<(), CliError> {
    let cutter = Cutter::parse(&a.tool).map_err(|e| CliError::input(format!("--tool: {e}")))?;
    let b = microcam::cli::parse_numbers::<6>(&a.stock, "--stock", "X0,Y0,Z0,X1,Y1,Z1")?;
    let st = microcam::cli::parse_numbers::<3>(&a.start, "--start", "X,Y,Z")?;
    let mut machine = Machine::load(&a.machine).map_err(|e| CliError::input(e.to_string()))?;
    machine
        .apply(&Overrides {
            ta_ms: a.ta_ms,
            ..Default::default()
        })
        .map_err(|e| CliError::input(e.to_string()))?;
    let force = match (&a.force_coefficients, a.force) {
        (Some(p), _) => Some(Coefficients::load(p).map_err(|e| CliError::input(e.to_string()))?),
        (None, true) => Some(Coefficients::default()),
        (None, false) => None,
    };
    let opts = Options {
        mode: match a.mode {
            ModeArg::PerBlock => Mode::PerBlock,
            ModeArg::Split => Mode::Split,
            ModeArg::Naive => Mode::Naive,
        },
        by: match a.by {
            ByArg::Mean => By::Mean,
            ByArg::Max => By::Max,
        },
        target: match a.target {
            TargetArg::Chip => Target::Chip,
            TargetArg::Force => Target::Force,
        },
        fz_min_mm: a.fz_min_um * 1e-3,
        fz_max_mm: a.fz_max_um * 1e-3,
        flutes: a.flutes,
        rpm: a.rpm,
        cutter,
        stock_min: P3::new(b[0], b[1], b[2]),
        stock_max: P3::new(b[3], b[4], b[5]),
        cell_mm: a.cell_mm.unwrap_or(cutter.diameter() / 50.0),
        step_mm: a.step_mm,
        window_mm: a.window_mm,
        air_feed: a.air_feed,
        min_block_s: a.min_block_ms.map(|m| m * 1e-3),
        merge_tol: a.merge_tol,
        machine,
        read: ReadOptions {
            dialect: a.dialect.map(|d| match d {
                DialectArg::Iso => Dialect::Iso,
                DialectArg::Pmac => Dialect::Pmac,
            }),
            start: P3::new(st[0], st[1], st[2]),
            ..Default::default()
        },
        force,
    };
    let mut input = cli::open_input(a.file.as_deref())?;
    let name = input.name.clone();
    let text = cli::read_to_string(&mut input)?;
    // The simulation at f_min-per-tooth steps is most of the run: minutes
    // on a long 3-D program at a fine cell. The library counts the moves.
    let meter = Meter::start("feedopt", "simulating moves", 0, Show::from_flags(a.quiet, false));
    let out = feedopt::optimise(&text, &opts).map_err(|e| match e {
        FeedoptError::Options(m) => CliError::input(m),
        e => CliError::in_file(&name, e),
    });
    meter.finish();
    let out = out?;
    // Everything is computed: now write, each file whole or not at all.
    let mut files = Vec::new();
    let mut prog = Output::new(a.output.as_deref());
    prog.write_all(out.program.as_bytes())?;
    files.push(prog);
    if let Some(p) = &a.report {
        let mut o = Output::new(Some(p));
        writeln!(o, "{}", out.report.to_json(Some(&name)))?;
        files.push(o);
    }
    if let Some(p) = &a.csv {
        let mut o = Output::new(Some(p));
        o.write_all(report::series_csv(&out.series).as_bytes())?;
        files.push(o);
    }
    if let Some(p) = &a.svg {
        let mut o = Output::new(Some(p));
        o.write_all(report::profiles_svg(&out.series, &name).as_bytes())?;
        files.push(o);
    }
    if let Some(p) = &a.png {
        let mut o = Output::new(Some(p));
        let (w, h, rgb) = report::profiles_rgb(&out.series);
        microcam::sim::picture::write_png(&mut o, w, h, &rgb)?;
        files.push(o);
    }
    for n in &out.report.notes {
        microcam::diag!("feedopt: {n}");
    }
    for f in files {
        f.commit()?;
    }
    Ok(())
}
