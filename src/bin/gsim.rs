//! gsim: interpret and simulate a program (G-code of either dialect, or
//! toolpath JSON Lines).

use clap::Parser;
use microcam::cli::{self, CliError, Output};
use microcam::formats::toolpath::{StreamError, write_stream};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::geometry::P3;
use microcam::model::toolpath::Record;
use microcam::preview::Preview;
use microcam::sim::summary::Summary;
use microcam::source::ToolpathSource;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  gsim --moves part.ngc > part.jsonl        interpreted moves as toolpath JSON Lines
  gsim --moves --dialect pmac prog.pmc      a PMAC motion program
  pathgen emit --dialect pmac part.jsonl | gsim    summary of a generated program
  gsim part.ngc | jq .feed_length_mm
  gsim --svg part.svg part.ngc              summary, and a top-view preview

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
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [0.0, 0.0, 0.0])]
    start: Vec<f64>,
    /// Also write a top-view SVG preview of the path to this file.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    cli::run("gsim", || run(args))
}

fn run(args: Args) -> Result<(), CliError> {
    let dialect = args
        .dialect
        .as_deref()
        .map(|d| d.parse::<Dialect>().map_err(CliError::input))
        .transpose()?;
    let start = P3::new(args.start[0], args.start[1], args.start[2]);
    let opts = ReadOptions {
        dialect,
        shutter_var: args.shutter_var.to_ascii_uppercase(),
        line_counter_var: args.line_counter_var.to_ascii_uppercase(),
        start,
    };
    let input = cli::open_input(args.file.as_deref())?;
    let source = ToolpathSource::open(input, &opts)?;
    let title = source.name().to_string();
    let mut out = Output::new(args.output.as_deref());
    let mut preview = args.svg.as_ref().map(|_| Preview::new(start));
    let mut observe = |r: &Record| {
        if let Some(p) = preview.as_mut() {
            p.add(r);
        }
    };
    if args.moves {
        let header = source.header.clone();
        let records = source.inspect(|r| {
            if let Ok(r) = r {
                observe(r);
            }
        });
        // Interpret on this thread, format and write on another.
        match write_stream(&header, records, &mut out) {
            Ok(_) => {}
            Err(StreamError::Source(e)) => return Err(e),
            Err(StreamError::Io(e)) => return Err(e.into()),
        }
    } else {
        let name = source.header.source.clone();
        let mut s = Summary::new(source.header.feed_unit, start);
        for rec in source {
            let rec = rec?;
            observe(&rec);
            s.add(&rec);
        }
        writeln!(out, "{}", s.to_json(name.as_deref()))?;
    }
    if let (Some(path), Some(p)) = (args.svg.as_deref(), preview) {
        let mut f = Output::new(Some(path));
        f.write_all(p.finish(&title).as_bytes())?;
        f.commit()?;
    }
    out.commit()
}
