//! `pathgen audit`: a laser toolpath checked against the machine.

use super::common::{MachineArgs, meter, positive};
use clap::Args as ClapArgs;
use microcam::cli::{self, CliError};
use microcam::gcode::ReadOptions;
use microcam::geometry::P3;
use microcam::model::toolpath::{FeedUnit, Record};
use microcam::progress;
use microcam::source::{SourceKind, ToolpathSource};
use std::path::PathBuf;

pub(crate) const AUDIT_EXAMPLES: &str = "\
Examples:
  pathgen contour part.chains | pathgen audit                toolpath straight from the planner
  pathgen audit --machine laser-stage part.pmc               a PMAC program (4 decimals)
  pathgen audit --precision 1e-3 part.pmc                    a program printed with 3 decimals
  pathgen audit part.jsonl | jq .ok

Input: microcam.toolpath/1 or G-code of either dialect ('-' or no FILE:
stdin), checked against --machine and the stage flags: feed moves at V,
acceleration within the stage's, no corner at speed, no beam-on rapid,
shutter switch points and exposure. The JSON report (microcam.pathgen-audit/1)
goes to stdout. Exit status: 0 within the limits, 1 a limit broken (the
report says which) or a failure, 2 bad usage or bad input.";

#[derive(ClapArgs)]
pub(crate) struct AuditArgs {
    /// Toolpath or G-code to check ('-' for stdin).
    file: Option<PathBuf>,
    /// Printing precision of the input (mm): how far its points may be off,
    /// so radii, switch points and the directions of short moves are
    /// compared within it [default: 1e-4 for G-code (4 decimals; give 1e-3
    /// for 3), 1e-9 for toolpaths]
    #[arg(long)]
    precision: Option<f64>,
    #[command(flatten)]
    machine: MachineArgs,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
}

pub(crate) fn audit_cmd(a: AuditArgs) -> Result<(), CliError> {
    let m = a.machine.machine(None)?;
    if let Some(p) = a.precision {
        positive("precision", p)?;
    }
    let input = cli::open_input(a.file.as_deref())?;
    // Reading is most of an audit; a stream of unknown length: the display
    // counts records.
    let meter = meter("audit: records", 0, a.quiet);
    let source = ToolpathSource::open(input, &ReadOptions::default())?;
    let unit = source.header.feed_unit;
    let kind = source.kind;
    let mut records = Vec::new();
    for r in source {
        progress::advance(1);
        let mut r = r?;
        // Audit in mm/s whatever the program's feed unit.
        if let Record::Move(mv) = &mut r {
            mv.feed = mv.feed.map(|f| unit.convert(f, FeedUnit::MmPerS));
        }
        records.push(r);
    }
    let precision = a.precision.unwrap_or(match kind {
        SourceKind::Gcode(_) => 1e-4,
        SourceKind::Toolpath => 1e-9,
    });
    let au = microcam::laser::audit::audit_at(&records, &m, P3::origin(), precision);
    meter.finish();
    microcam::cli::print_line(&au.report_json(&m, precision))?;
    let ok = au.passes(&m, precision);
    if ok {
        Ok(())
    } else {
        Err(CliError::verdict(
            "the toolpath breaks the machine's limits (see the report)",
        ))
    }
}
