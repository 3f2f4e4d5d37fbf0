//! pathgen: toolpaths, and G-code from toolpaths.

use clap::{Args as ClapArgs, Parser, Subcommand};
use microcam::cli::{self, CliError, Output};
use microcam::gcode::writer::{GcodeWriter, WriteError, WriteOptions};
use microcam::gcode::{Dialect, ReadOptions};
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
}

#[derive(ClapArgs)]
struct EmitArgs {
    /// Toolpath to write ('-' for stdin).
    file: Option<PathBuf>,
    /// Output dialect.
    #[arg(long, value_parser = ["iso", "pmac"], default_value = "pmac")]
    dialect: String,
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
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    cli::run("pathgen", || match cli.command {
        Command::Emit(a) => emit(a),
    })
}

fn emit(a: EmitArgs) -> Result<(), CliError> {
    let dialect: Dialect = a.dialect.parse().map_err(CliError::input)?;
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
        opts.header = Some(a.header);
    } else if dialect == Dialect::Pmac && a.program != 1 {
        let mut h = opts.default_header();
        if let Some(first) = h.first_mut() {
            *first = format!("OPEN PROG {} CLEAR", a.program);
        }
        opts.header = Some(h);
    }
    if !a.trailer.is_empty() {
        opts.trailer = Some(a.trailer);
    }
    let read = ReadOptions {
        shutter_var: opts.shutter_var.clone(),
        line_counter_var: a.line_counter.to_ascii_uppercase(),
        ..Default::default()
    };
    let input = cli::open_input(a.file.as_deref())?;
    let source = ToolpathSource::open(input, &read)?;
    let name = source.name().to_string();
    let mut out = Output::new(a.output.as_deref());
    let mut w = GcodeWriter::new(&mut out, opts, source.header.feed_unit);
    let bad = |e: WriteError| match e {
        WriteError::Io(e) => CliError::from(e),
        e => CliError::input(format!("{name}: {e}")),
    };
    for rec in source {
        w.record(&rec?).map_err(bad)?;
    }
    w.finish().map_err(bad)?;
    out.commit()
}
