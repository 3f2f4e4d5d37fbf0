//! plough2d: chip and ploughing area per cutter step of a micro flat end
//! mill along a program (Bayesteh 2013, chapter 5).

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::{Parser, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::geometry::P3;
use microcam::plough::output::{plot_svg, stock_rgb, stock_svg, summary, write_csv};
use microcam::plough::pocket::Pocket;
use microcam::plough::{Method, Params, Plough, PloughError};
use microcam::progress::{self, Meter, Show};
use microcam::sim::picture::write_png;
use microcam::source::ToolpathSource;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  plough2d --stock 0,0,4,3 --rpm 60000 pocket.pmc            JSON summary
  plough2d --stock 0,0,4,3 --csv steps.csv --plot plot.svg --png stock.png pocket.pmc
  plough2d --stock 0,0,4,3 --method both pocket.pmc | jq .comparison
  plough2d --write-pocket 0.5 > pocket.pmc     the example pocket at 0.5 mm/s

The defaults are Bayesteh 2013's run: scale factor 10, resolution 10 um,
tool 0.794 mm with 2 teeth, minimum chip thickness 2.4 um (the material's
0.24 um times the scale factor, since every step's chip is scale times
thicker than one tooth's), accuracy 1 um. Feed per tooth = F [mm/s] /
(rpm/60 x teeth); F is mm/s in PMAC programs and mm/min in ISO ones. The
spindle speed comes from S words or --rpm (which wins).

Rapids do not cut; feed moves cut in XY (Z is ignored). Outputs appear only
when the whole run succeeds. Exit status: 0 ok, 1 failure, 2 bad usage or
bad input (no spindle speed, tool larger than the stock, a resolution that
needs more than --max-memory-mib or more cutter steps than --max-steps; the message names the file and line).";

#[derive(Clone, Copy, ValueEnum)]
enum MethodArg {
    /// Dual dexel (any stock history; the default).
    Dexel,
    /// The exact reference alone.
    Exact,
    /// Both; the summary compares them.
    Both,
}

/// 2-D ploughing simulation for micro flat end milling.
#[derive(Parser)]
#[command(name = "plough2d", version, about, after_help = EXAMPLES)]
struct Args {
    /// Program (ISO or PMAC G-code, or toolpath JSON Lines; '-' for stdin).
    file: Option<PathBuf>,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
    /// Stock outline, mm: X0,Y0,X1,Y1 (W = X1-X0, H = Y1-Y0).
    #[arg(long, value_name = "X0,Y0,X1,Y1", allow_hyphen_values = true)]
    stock: Option<String>,
    /// Dexel spacing R, um.
    #[arg(long, default_value_t = 10.0)]
    resolution_um: f64,
    /// Cutter diameter D, mm.
    #[arg(long, default_value_t = 0.794)]
    diameter_mm: f64,
    /// Teeth (flutes) N.
    #[arg(long = "flutes", alias = "teeth", value_name = "FLUTES", default_value_t = 2)]
    teeth: u32,
    /// Minimum chip thickness in the scaled model, um.
    #[arg(long, default_value_t = 2.4)]
    min_chip_um: f64,
    /// Ploughing accuracy T_p (arc length between radii), um.
    #[arg(long, default_value_t = 1.0)]
    accuracy_um: f64,
    /// Scale factor on the feed per tooth.
    #[arg(
        long = "step-scale",
        alias = "scale",
        value_name = "STEP_SCALE",
        default_value_t = 10.0
    )]
    scale: f64,
    /// Spindle speed, rpm (overrides the program's S words).
    #[arg(long)]
    rpm: Option<f64>,
    /// Which computation gives the areas.
    #[arg(long, value_enum, default_value = "dexel")]
    method: MethodArg,
    /// Memory cap for the stock and the series, MiB.
    #[arg(long, default_value_t = 1024.0)]
    max_memory_mib: f64,
    /// Most cutter steps the run may take (refused before the move that
    /// would pass it: bounds the time).
    #[arg(long, default_value_t = microcam::plough::DEFAULT_MAX_STEPS)]
    max_steps: u64,
    /// G-code dialect (default: detected).
    #[arg(long, value_parser = ["iso", "pmac"])]
    dialect: Option<String>,
    /// Machine position when the program starts, mm: X,Y,Z.
    #[arg(long, default_value = "0,0,0", value_name = "X,Y,Z", allow_hyphen_values = true)]
    start: String,
    /// Summary here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Per-step series as CSV.
    #[arg(long, value_name = "FILE.csv")]
    csv: Option<PathBuf>,
    /// Plot of chip and ploughing area along the path, SVG.
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// Final stock with the path, SVG.
    #[arg(long, value_name = "FILE.svg")]
    svg: Option<PathBuf>,
    /// Final stock with the path, PNG.
    #[arg(long, value_name = "FILE.png")]
    png: Option<PathBuf>,
    /// Print the thesis-like pocket program at this feed (mm/s) and exit.
    #[arg(long, value_name = "FEED_MM_S", conflicts_with = "file")]
    write_pocket: Option<f64>,
    /// Dialect of --write-pocket.
    #[arg(long, value_parser = ["iso", "pmac"], default_value = "pmac")]
    pocket_dialect: String,
}

fn main() -> ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("plough2d", || run(args))
}
fn run(args: Args) -> Result<(), CliError> {
    if let Some(feed) = args.write_pocket {
        if !(feed.is_finite() && feed > 0.0) {
            return Err(CliError::input("--write-pocket: feed must be positive (mm/s)"));
        }
        let d: Dialect = args.pocket_dialect.parse().map_err(CliError::input)?;
        let mut out = Output::new(args.output.as_deref());
        out.write_all(Pocket::example(feed).program(d).as_bytes())?;
        return out.commit();
    }
    let stock = args
        .stock
        .as_deref()
        .ok_or_else(|| CliError::input("--stock X0,Y0,X1,Y1 is required"))?;
    let stock = microcam::cli::parse_numbers::<4>(stock, "--stock", "X0,Y0,X1,Y1")?;
    let st = microcam::cli::parse_numbers::<3>(&args.start, "--start", "X,Y,Z")?;
    let start = P3::new(st[0], st[1], st[2]);
    let params = Params {
        stock_mm: stock,
        resolution_mm: args.resolution_um * 1e-3,
        diameter_mm: args.diameter_mm,
        teeth: args.teeth,
        h_min_mm: args.min_chip_um * 1e-3,
        accuracy_mm: args.accuracy_um * 1e-3,
        scale: args.scale,
        rpm: args.rpm,
        method: match args.method {
            MethodArg::Dexel => Method::Dexel,
            MethodArg::Exact => Method::Exact,
            MethodArg::Both => Method::Both,
        },
        max_memory_mib: args.max_memory_mib,
        max_steps: args.max_steps,
    };
    let dialect = args
        .dialect
        .as_deref()
        .map(|d| d.parse::<Dialect>().map_err(CliError::input))
        .transpose()?;
    let opts = ReadOptions {
        dialect,
        start,
        ..ReadOptions::default()
    };
    let input = cli::open_input(args.file.as_deref())?;
    let source = ToolpathSource::open(input, &opts)?;
    let name = source.name().to_string();
    let src = source.header.source.clone();
    let bad = |e: PloughError| match e {
        e @ (PloughError::Line { .. } | PloughError::Record { .. }) => CliError::in_file(&name, e),
        e => CliError::input(e.to_string()),
    };
    let mut sim = Plough::new(params, source.header.feed_unit, start).map_err(bad)?;
    let meter = Meter::start("plough2d", "ploughing records", 0, Show::from_flags(args.quiet, false));
    for rec in source {
        sim.add(&rec?).map_err(bad)?;
        progress::advance(1);
    }
    meter.finish();
    let title = format!("plough2d {}", src.as_deref().unwrap_or("<stdin>"));
    // Everything is rendered before anything is committed.
    let mut outs = Vec::new();
    let mut o = Output::new(args.output.as_deref());
    let json =
        serde_json::to_string_pretty(&summary(&sim, src.clone())).map_err(|e| CliError::failure(e.to_string()))?;
    writeln!(o, "{json}")?;
    outs.push(o);
    if let Some(p) = args.csv.as_deref() {
        let mut o = Output::new(Some(p));
        write_csv(&mut o, &sim.steps, sim.params().method)?;
        outs.push(o);
    }
    if let Some(p) = args.plot.as_deref() {
        let mut o = Output::new(Some(p));
        o.write_all(plot_svg(&sim.steps, &title).as_bytes())?;
        outs.push(o);
    }
    if let Some(p) = args.svg.as_deref() {
        let mut o = Output::new(Some(p));
        o.write_all(stock_svg(&sim, &title).as_bytes())?;
        outs.push(o);
    }
    if let Some(p) = args.png.as_deref() {
        let (w, h, rgb) = stock_rgb(&sim);
        let mut o = Output::new(Some(p));
        write_png(&mut o, w, h, &rgb).map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?;
        outs.push(o);
    }
    for o in outs {
        o.commit()?;
    }
    Ok(())
}
