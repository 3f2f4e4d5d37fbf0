//! `pathgen fill`: area fill of closed chains (offset passes or hatch),
//! planned by the laser machinery. Included from pathgen.rs.

use super::common::{GenOutput, MachineArgs, short_note, warn_all, write_generated, write_streamed_counting_short};
use clap::Args as ClapArgs;
use microcam::cli::{self, CliError};
use microcam::formats::read_chains;
use microcam::laser::fill::{FillOptions, Pattern, plan_prepared, prepare};
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
Examples:
  pathgen slice part.stl --z-step 0.01 --arc-tol 0.0005 | pathgen fill --gcode pmac > part.pmc
  pathgen fill region.chains                                offset passes, stepover = beam radius
  pathgen fill --pattern hatch --angle 45 --outline --step-over 0.004 region.chains
  dxf2chains logo.dxf | pathgen fill --beam-diameter 0.02 --svg logo.svg > logo.jsonl

Input is microcam.chains/1 ('-' or no FILE reads stdin): closed chains,
grouped by their Z (one level each, in input order) and nested by
containment (a chain inside an odd number of others is a hole). Open
chains are ignored with a warning. The beam centre stays one beam radius
inside each region and outside its holes; passes are --step-over apart
(default the beam radius) and joined by beam-off links at the feed, then
planned like `pathgen contour` (leads, corner loops, shutter timing).
Method: Bayesteh (2013) §6.3.3.6, sections of a model filled level by
level. A job estimated above --max-moves moves is refused before any work.
Output is microcam.toolpath/1 or G-code with --gcode. Exit status: 0 ok,
1 failure, 2 bad usage or bad input (no closed chain, empty region, a job
too large).";

#[derive(ClapArgs)]
pub struct FillArgs {
    /// Closed chains to fill ('-' for stdin).
    file: Option<PathBuf>,
    /// offset: contour-parallel passes inward; hatch: zigzag lines.
    #[arg(long, value_enum, default_value_t = Pattern::Offset)]
    pattern: Pattern,
    /// Beam spot diameter (mm): passes keep its radius inside the region.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    beam_diameter: f64,
    /// Distance between passes (mm). Default: the beam radius.
    #[arg(
        long = "step-over",
        alias = "stepover",
        value_name = "STEP_OVER",
        allow_negative_numbers = true
    )]
    stepover: Option<f64>,
    /// Hatch: direction of the lines (degrees from +X).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    angle: f64,
    /// Hatch: cut the region's outline (one beam radius in) after the lines.
    #[arg(long)]
    outline: bool,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

pub fn run(a: FillArgs) -> Result<(), CliError> {
    let m = a.machine.machine(a.out.gcode.as_deref())?;
    if !(a.beam_diameter.is_finite() && a.beam_diameter > 0.0) {
        return Err(CliError::input(format!(
            "--beam-diameter must be positive, got {}",
            a.beam_diameter
        )));
    }
    let r = 0.5 * a.beam_diameter;
    let o = FillOptions {
        pattern: a.pattern,
        beam_radius: r,
        stepover: a.stepover.unwrap_or(r),
        angle_deg: a.angle,
        outline: a.outline,
        max_moves: a.out.max_moves,
    };
    let input = cli::open_input(a.file.as_deref())?;
    let name = input.name.clone();
    let (header, chains) = read_chains(input.reader).map_err(|e| CliError::in_file(&name, e))?;
    let source = header.source.or(Some(name.clone()));
    let prepared = prepare(&chains, &o).map_err(|e| CliError::input(format!("{name}: {e}")))?;
    // The library advances each region's share of the job's estimate as
    // the region is planned.
    let meter = a.out.meter("fill: moves (estimated)", prepared.estimate.moves);
    if a.out.svg.is_some() {
        let mut records = Vec::new();
        let warnings = plan_prepared(&prepared, &m, &o, |r| {
            records.extend(r);
            true
        });
        meter.finish();
        warn_all(&warnings);
        let (short, total) = write_generated(&records, &a.out, source, &m, false)?;
        short_note(short, total, &m);
        return Ok(());
    }
    let mut warnings = Vec::new();
    let written = write_streamed_counting_short(&a.out, source, &m, |sink| {
        warnings = plan_prepared(&prepared, &m, &o, sink);
    });
    meter.finish();
    let (short, total) = written?;
    warn_all(&warnings);
    short_note(short, total, &m);
    Ok(())
}
