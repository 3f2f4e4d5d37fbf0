//! `pathgen emit`: a toolpath or G-code program written as G-code.

use super::common::{WriterArgs, meter, write_gcode, write_options};
use clap::Args as ClapArgs;
use microcam::cli::{self, CliError, Output};
use microcam::gcode::{Dialect, ReadOptions};
use microcam::progress;
use microcam::source::ToolpathSource;
use std::path::PathBuf;

#[derive(ClapArgs)]
pub(crate) struct EmitArgs {
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
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
}

pub(crate) fn emit(a: EmitArgs) -> Result<(), CliError> {
    let dialect: Dialect = a.dialect.parse().map_err(CliError::input)?;
    let opts = write_options(dialect, &a.writer);
    let read = ReadOptions {
        shutter_var: opts.shutter_var.clone(),
        line_counter_var: a.writer.line_counter.to_ascii_uppercase(),
        ..Default::default()
    };
    let input = cli::open_input(a.file.as_deref())?;
    // A stream of unknown length (from its first bytes on): the display
    // counts records.
    let meter = meter("emit: records", 0, a.quiet);
    let source = ToolpathSource::open(input, &read)?;
    let name = source.name().to_string();
    let feed_unit = source.header.feed_unit;
    let mut out = Output::new(a.output.as_deref());
    let written = write_gcode(
        source.inspect(|_| progress::advance(1)),
        feed_unit,
        opts,
        &name,
        &mut out,
    );
    meter.finish();
    written?;
    out.commit()
}
