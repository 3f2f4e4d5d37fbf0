//! `pathgen dropcutter --waterline` / `--waterline-step`: closed loops at
//! constant Z, written point by point or fitted with arcs (`--arc-fit`).

use super::{DropcutterArgs, FormatArg, chord_tol_arg, positive, write_passes, write_records};
use microcam::cli::{CliError, Output};
use microcam::dropcutter::DropCutter;
use microcam::dropcutter::output::{Feeds, toolpath_records_of_segments};
use microcam::dropcutter::waterline::Waterline;
use microcam::geometry::{P2, P3};
use microcam::laser::arcfit::fit_points;
use microcam::model::chain::Segment;
use microcam::progress::{Meter, Show};
use rayon::prelude::*;

/// `--waterline` / `--waterline-step`: closed loops at each level, top
/// down, sampled on fibres `--step-over` apart.
pub(super) fn run(
    a: &DropcutterArgs,
    dc: &DropCutter,
    floor: f64,
    safe_z: f64,
    feeds: Feeds,
    name: &str,
) -> Result<(), CliError> {
    let sampling = positive(
        "step-over",
        a.step_over
            .ok_or_else(|| CliError::input("--step-over (the waterline's fibre spacing) is required"))?,
    )?;
    let chord_tol = chord_tol_arg(a)?;
    // Checked before the waterlines are traced: they are most of the work.
    let arc_fit = match a.arc_fit {
        None => None,
        Some(_) if a.gcode.is_none() && a.format == FormatArg::Cl => {
            return Err(CliError::input(
                "--arc-fit: CL data holds points only; use --format toolpath or --gcode",
            ));
        }
        Some(t) => Some(positive("arc-fit", t)?),
    };
    let top = dc.bbox().max.z;
    let mut levels: Vec<f64> = match (&a.waterline, a.waterline_step) {
        (Some(zs), _) => {
            if let Some(z) = zs.iter().find(|z| !z.is_finite() || **z < floor) {
                return Err(CliError::input(format!(
                    "--waterline {z}: not a finite height at or above the floor {floor}"
                )));
            }
            zs.clone()
        }
        (None, Some(dz)) => {
            let dz = positive("waterline-step", dz)?;
            let n = ((top - floor) / dz * (1.0 + 1e-12)).floor();
            if n > 100_000.0 {
                return Err(CliError::input(format!(
                    "--waterline-step {dz}: {n:.0} levels from {top} down to {floor}, more than 100000"
                )));
            }
            (1..=n as usize).map(|k| top - k as f64 * dz).collect()
        }
        (None, None) => Vec::new(),
    };
    // Top down, each level once.
    levels.sort_by(|p, q| q.total_cmp(p));
    levels.dedup();
    let wl = Waterline {
        sampling,
        // Far below any stage's resolution, and a few bisection steps.
        tol: (sampling * 1e-6).max(1e-9),
        chord_tol,
    };
    // Dropping the fibre grid is most of the work: the meter counts its
    // nodes, then the levels traced.
    let units = 2 * wl.grid_nodes(dc).map_err(|e| CliError::input(format!("{name}: {e}")))?;
    let meter = Meter::start("pathgen", "waterlines", units, Show::from_flags(a.quiet, false));
    let per_level = wl
        .levels(dc, &levels)
        .map_err(|e| CliError::input(format!("{name}: {e}")))?;
    let mut cl: Vec<Vec<P3>> = Vec::new();
    for (loops, &z) in per_level.into_iter().zip(&levels) {
        cl.extend(
            loops
                .into_iter()
                .map(|l| l.into_iter().map(|p| P3::new(p.x, p.y, z)).collect()),
        );
    }
    meter.finish();
    let mut out = Output::new(a.output.as_deref());
    let fitted = match arc_fit {
        None => None,
        Some(t) => {
            // Seconds on a large mesh (a few times the trace): shown by points fitted.
            let points = cl.iter().map(Vec::len).sum::<usize>() as u64;
            let meter = Meter::start("pathgen", "fitting arcs", points, Show::from_flags(a.quiet, false));
            let loops: Vec<Vec<Segment>> = cl
                .par_iter()
                .map(|l| {
                    let pts: Vec<P2> = l.iter().map(|p| P2::new(p.x, p.y)).collect();
                    let fit = fit_points(&pts, t, l.first().map_or(0.0, |p| p.z), true);
                    microcam::progress::advance(l.len() as u64);
                    fit
                })
                .collect();
            meter.finish();
            Some((loops, t))
        }
    };
    match &fitted {
        Some((loops, _)) => write_records(a, toolpath_records_of_segments(loops, safe_z, feeds), name, &mut out)?,
        None => write_passes(a, dc.cutter(), &cl, safe_z, feeds, name, &mut out)?,
    }
    out.commit()?;
    microcam::diag!(
        "pathgen: dropcutter: {} waterline levels, {} loops, {} CL points",
        levels.len(),
        cl.len(),
        cl.iter().map(Vec::len).sum::<usize>()
    );
    if let Some((loops, t)) = &fitted {
        let arcs = loops.iter().flatten().filter(|s| matches!(s, Segment::Arc(_))).count();
        microcam::diag!(
            "pathgen: dropcutter: arcs fitted within {t} mm of the loops' chords: {} moves ({arcs} arcs) for {} points",
            loops.iter().map(Vec::len).sum::<usize>(),
            cl.iter().map(Vec::len).sum::<usize>()
        );
    }
    Ok(())
}
