//! `pathgen dropcutter --waterline` / `--waterline-step`: closed loops at
//! constant Z, written point by point or fitted with arcs (`--arc-fit`).

use super::{
    DropcutterArgs, arc_fit_arg, chord_tol_arg, fit_passes, fit_summary, positive, write_passes, write_records,
};
use microcam::cli::{CliError, Output};
use microcam::dropcutter::DropCutter;
use microcam::dropcutter::arcs::fit_loop;
use microcam::dropcutter::output::{Feeds, toolpath_records_of_segments};
use microcam::dropcutter::waterline::Waterline;
use microcam::geometry::P3;
use microcam::progress::{Meter, Show};

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
    let arc_fit = arc_fit_arg(a)?;
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
    let fitted = arc_fit.map(|t| {
        let loops = fit_passes(a, &cl, |l| fit_loop(l, t));
        (loops, t)
    });
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
        microcam::diag!("pathgen: dropcutter: {}", fit_summary(loops, *t, "loops", &cl));
    }
    Ok(())
}
