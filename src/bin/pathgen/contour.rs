//! `pathgen contour`: chains cut with offsets, ordering, leads, corner loops and shutter timing.

use super::common::{
    GenOutput, MachineArgs, at_least_one, finite, non_negative, parse_pair_f64, parse_pair_u32, short_note, warn_all,
    write_generated, write_streamed_counting_short,
};
use clap::Args as ClapArgs;
use microcam::cli::{self, CliError};
use microcam::formats::read_chains;
use microcam::geometry::P2;
use microcam::laser::contour::{
    ContourOptions, DEFAULT_CLEANUP_TOL, Direction, OrderMode, contour, contour_streamed, estimated_moves,
};
use microcam::laser::offset::Side;
use microcam::laser::setup::LaserSetup;
use microcam::machine::Machine;
use microcam::model::chain::Chain;
use std::path::PathBuf;

pub(crate) const CONTOUR_EXAMPLES: &str = "\
Examples:
  pathgen contour part.chains > part.jsonl                 cut on the lines
  pathgen contour --side outside --beam-diameter 0.01 part.chains --gcode pmac > part.pmc
  pathgen contour --side inside --offset 0.02 --levels 5 --level-step -0.005 part.chains
  pathgen contour --array 3,2 --pitch 5,5 --svg part.svg part.chains

Input is microcam.chains/1 ('-' or no FILE reads stdin); output is
microcam.toolpath/1 (feeds in mm/s) or G-code with --gcode. Warnings
(vanished offsets, cuts shorter than the minimum exposure, arcs tighter than
V^2/a) go to stderr. Exit status: 0 ok, 1 failure, 2 bad usage or bad input.";

#[derive(ClapArgs)]
pub(crate) struct ContourArgs {
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

pub(crate) fn contour_cmd(a: ContourArgs) -> Result<(), CliError> {
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
    // The library names its stages (offsets, order, planning) and counts
    // each.
    let meter = a.out.meter("contour", 0);
    if a.out.svg.is_some() {
        // The preview needs the whole job.
        let job = contour(&chains, &m, &o);
        meter.finish();
        warn_all(&job.warnings);
        cleanup_note(&job.cleanup, &m, &o);
        let (short, total) = write_generated(&job.records, &a.out, source, &m, false)?;
        short_note(short, total, &m);
        return Ok(());
    }
    let mut warnings = Vec::new();
    let mut cleanup = Default::default();
    let written = write_streamed_counting_short(&a.out, source, &m, |sink| {
        (warnings, cleanup) = contour_streamed(&chains, &m, &o, sink);
    });
    meter.finish();
    let (short, total) = written?;
    warn_all(&warnings);
    cleanup_note(&cleanup, &m, &o);
    short_note(short, total, &m);
    if timing {
        microcam::diag!(
            "pathgen: timing: read {:.3} s, plan and write {:.3} s",
            (t1 - t0).as_secs_f64(),
            t1.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// What the cleanup of short pieces did, on stderr.
pub(crate) fn cleanup_note(st: &microcam::laser::cleanup::CleanStats, m: &LaserSetup, o: &ContourOptions) {
    let fixed = st.short - st.left;
    if fixed > 0 {
        microcam::diag!(
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
        microcam::diag!(
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
pub(crate) const TRAVEL_FALLBACK_MM: f64 = 1000.0;

/// Warn when the drawing is larger than the machine can travel: most
/// often a DXF drawn in other units than the millimetres assumed.
pub(crate) fn warn_travel(chains: &[Chain], machine: &str) {
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
        microcam::diag!(
            "pathgen: warning: the drawing is {:.3} x {:.3} mm, larger than {whose}; chains are in mm, \
             converted by dxf2chains from the DXF's unit ($INSUNITS, millimetres when absent): if the drawing \
             is in another unit, give it with `dxf2chains --units`",
            size[0],
            size[1]
        );
    }
}
