//! `pathgen arcfit`: tangent-continuous arcs fitted to points or a polyline.

use super::common::positive;
use clap::Args as ClapArgs;
use microcam::cli::{self, CliError, Output};
use microcam::formats::chains::ChainsWriter;
use microcam::laser::arcfit;
use microcam::model::chain::{Chain, ChainsHeader, Segment};
use std::path::PathBuf;

pub(crate) const ARCFIT_EXAMPLES: &str = "\
Examples:
  pathgen arcfit --arc-tol 0.0005 curve.xy > curve.chains    points of a smooth curve to biarcs
  pathgen arcfit --polyline --report outline.xy              blocks and deviations only (JSON)
  pathgen arcfit curve.xy | pathgen contour --gcode pmac > curve.pmc

Input: one 'x y' (or 'x,y') per line, '#' comments; '-' or no FILE reads
stdin. By default only the points must lie within --arc-tol of the arcs
(samples of a curve); --polyline keeps the arcs within --arc-tol of the
polyline both ways. Output is one open microcam.chains/1 chain of arcs and
lines, or with --report a microcam.arcfit-report/1 line. Exit status: 0 ok
(a warning when the fit misses the tolerance), 1 failure, 2 bad usage or
bad input.";

#[derive(ClapArgs)]
pub(crate) struct ArcfitArgs {
    /// Points, one 'x y' (or 'x,y') per line, '#' comments; '-' for stdin.
    file: Option<PathBuf>,
    /// Largest deviation from the polyline (mm).
    #[arg(
        long = "arc-tol",
        alias = "tolerance",
        value_name = "ARC_TOL",
        default_value_t = 0.001
    )]
    tolerance: f64,
    /// Print a JSON report (blocks, deviation) instead of chains.
    #[arg(long)]
    report: bool,
    /// The input is a polyline to stay within (both ways), not samples of
    /// a smooth curve (the default: only the points must be within).
    #[arg(long)]
    polyline: bool,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

pub(crate) fn arcfit_cmd(a: ArcfitArgs) -> Result<(), CliError> {
    let tol = positive("arc-tol", a.tolerance)?;
    let mut input = cli::open_input(a.file.as_deref())?;
    let name = input.name.clone();
    let text = cli::read_to_string(&mut input)?;
    let pts = arcfit::parse_points(&text).map_err(|(line, msg)| CliError::input(format!("{name}:{line}: {msg}")))?;
    if pts.len() < 2 {
        return Err(CliError::input(format!("{name}: need at least two points")));
    }
    let fit = arcfit::fit_points(&pts, tol, 0.0, a.polyline);
    if fit.is_empty() {
        return Err(CliError::input(format!("{name}: need at least two distinct points")));
    }
    // Dense check: 256 samples per piece against the polyline, and every
    // point against the fit.
    let dev_poly = arcfit::max_deviation(&fit, &pts, 256);
    let dev_pts = arcfit::point_deviation(&fit, &pts);
    let dev = if a.polyline { dev_poly } else { dev_pts };
    let mut out = Output::new(a.output.as_deref());
    use std::io::Write;
    if a.report {
        let arcs = fit.iter().filter(|e| matches!(e, Segment::Arc(_))).count();
        writeln!(
            out,
            "{{\"schema\":\"microcam.arcfit-report/1\",\"points\":{},\"polyline_blocks\":{},\"biarc_blocks\":{},\"arcs\":{},\"lines\":{},\"tolerance_mm\":{},\"max_point_deviation_mm\":{:.9},\"max_polyline_deviation_mm\":{:.9}}}",
            pts.len(),
            pts.len() - 1,
            fit.len(),
            arcs,
            fit.len() - arcs,
            tol,
            dev_pts,
            dev_poly
        )?;
    } else {
        // Fitted arcs are XY arcs of less than a turn: chain segments as they are.
        let segments = fit;
        let mut w = ChainsWriter::new(&mut out);
        w.header(&ChainsHeader { source: Some(name) })?;
        w.chain(&Chain {
            id: 1,
            closed: false,
            segments,
            ..Default::default()
        })?;
        w.finish()?;
    }
    if dev > tol {
        microcam::diag!("pathgen: warning: arcfit: deviation {dev} mm exceeds the tolerance {tol} mm");
    }
    out.commit()
}
