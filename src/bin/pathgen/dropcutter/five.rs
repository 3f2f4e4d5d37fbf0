//! `pathgen dropcutter --five-axis`: the options checked and made into a
//! [`FiveAxisJob`] (the library runs it), the job's summary lines on
//! stderr, and the CL data under a comment naming its rules.

use super::{AxisChangeArg, DropcutterArgs, GougeArg, NormalsArg, bad, positive};
use microcam::cli::{CliError, Output};
use microcam::dropcutter::DropCutter;
use microcam::dropcutter::fiveaxis::FiveAxis;
use microcam::dropcutter::gouge::{GougeReport, GougeRule, SettleReport};
use microcam::dropcutter::job5::{FiveAxisJob, GougeMode};
use microcam::dropcutter::normals::DEFAULT_CREASE_DEG;
use microcam::dropcutter::output::write_cldata5;
use microcam::dropcutter::swing::AxisReport;
use microcam::dropcutter::tilt::{TiltReport, TiltSearch};
use microcam::formats::cldata::ClWriter;
use microcam::geometry::P2;
use microcam::progress::{Meter, Show};

/// The job and the option values its CL comment names, in degrees and mm
/// as given.
struct Options {
    job: FiveAxisJob,
    crease_deg: Option<f64>,
    max_turn: f64,
    turn_step: f64,
    turn_ramp: f64,
}

/// Every 5-axis option checked (exit 2 on a bad one) before any work.
fn options(a: &DropcutterArgs, cutter_radius: f64) -> Result<Options, CliError> {
    let five = FiveAxis {
        lead: a.lead.to_radians(),
        tilt: a.tilt.to_radians(),
        axis_length: positive("axis-length", a.axis_length)?,
    };
    let crease_deg = match (a.normals, a.crease) {
        (NormalsArg::Facet, Some(_)) => return Err(CliError::input("--crease goes with --normals smooth")),
        (NormalsArg::Facet, None) => None,
        (NormalsArg::Smooth, crease) => {
            let deg = crease.unwrap_or(DEFAULT_CREASE_DEG);
            if !(0.0..=180.0).contains(&deg) {
                return Err(CliError::input(format!("--crease {deg}: degrees, 0 to 180")));
            }
            Some(deg)
        }
    };
    if a.gouge != GougeArg::Tilt && (a.max_turn.is_some() || a.turn_step.is_some() || a.turn_ramp.is_some()) {
        return Err(CliError::input(
            "--max-turn, --turn-step and --turn-ramp go with --gouge tilt",
        ));
    }
    let turn_ramp = a.turn_ramp.unwrap_or(2.0 * cutter_radius);
    if !(turn_ramp.is_finite() && turn_ramp >= 0.0) {
        return Err(CliError::input(format!("--turn-ramp {turn_ramp}: mm, 0 or more")));
    }
    // No two axes are more than 180 degrees apart: that limit is none.
    let max_axis_change = match a.max_axis_change {
        180.0 => None,
        d if (0.1..180.0).contains(&d) => Some(d.to_radians()),
        d => {
            return Err(CliError::input(format!(
                "--max-axis-change {d}: degrees, 0.1 to 180, or off"
            )));
        }
    };
    let (max_turn, turn_step) = (a.max_turn.unwrap_or(30.0), a.turn_step.unwrap_or(5.0));
    let in_range = (0.0..=90.0).contains(&max_turn) && turn_step > 0.0 && turn_step <= 90.0;
    if !in_range {
        return Err(CliError::input(format!(
            "--max-turn {max_turn} and --turn-step {turn_step}: degrees, 0 to 90 and above 0 to 90"
        )));
    }
    if a.gouge == GougeArg::Off && !a.holder.is_empty() {
        return Err(CliError::input("--holder goes with the gouge check (not --gouge off)"));
    }
    for h in &a.holder {
        h.fits(cutter_radius)
            .map_err(|e| CliError::input(format!("--holder: {e}")))?;
    }
    if let Some(h) = a.holder.iter().find(|h| h.height >= five.axis_length) {
        return Err(CliError::input(format!(
            "--holder: its face at {} mm is not below --axis-length {} (the length of tool checked)",
            h.height, five.axis_length
        )));
    }
    let gouge = match a.gouge {
        GougeArg::Off => GougeMode::Off,
        GougeArg::Report => GougeMode::Report,
        GougeArg::Lift => GougeMode::Lift,
        GougeArg::Tilt => GougeMode::Tilt(TiltSearch {
            max: max_turn.to_radians(),
            step: turn_step.to_radians(),
            ramp: turn_ramp,
            both: true,
        }),
    };
    Ok(Options {
        job: FiveAxisJob {
            five,
            smooth_crease: crease_deg.map(f64::to_radians),
            gouge,
            holders: a.holder.clone(),
            max_axis_change,
            axis_steps: a.axis_change == AxisChangeArg::Steps,
        },
        crease_deg,
        max_turn,
        turn_step,
        turn_ramp,
    })
}

/// The 5-axis job over `passes`, written as CL data to `out`; returns how
/// many locations were computed (before the axis steps).
pub(super) fn run(
    a: &DropcutterArgs,
    dc: &DropCutter,
    passes: &[Vec<P2>],
    safe_z: f64,
    name: &str,
    out: &mut Output,
) -> Result<usize, CliError> {
    let o = options(a, dc.cutter().radius())?;
    let job = &o.job;
    let located = job.locate(dc, passes).map_err(bad)?;
    let computed = located.count();
    let meter = Meter::start(
        "pathgen",
        "checking the tool against the part",
        job.check_units(&located),
        Show::from_flags(a.quiet, false),
    );
    let done = job.check(dc, located).map_err(bad)?;
    meter.finish();
    let length = job.five.axis_length;
    if let (Some(s), Some(deg)) = (&done.settled, o.crease_deg) {
        microcam::diag!("pathgen: dropcutter: 5-axis: {}", settle_summary(s, deg));
    }
    let summary = match (&done.gouge, &done.tilt) {
        (Some(g), Some(t)) => Some(tilt_summary(g, t, length)),
        (Some(g), None) if job.gouge == GougeMode::Lift => Some(gouge_summary(g, GougeRule::Lift, length)),
        (Some(g), None) => Some(gouge_summary(g, GougeRule::Report, length)),
        (None, _) => None,
    };
    if let Some(line) = summary {
        microcam::diag!("pathgen: dropcutter: 5-axis: {line}");
    }
    microcam::diag!(
        "pathgen: dropcutter: 5-axis: {}",
        axis_change_summary(&done.axes, job.max_axis_change)
    );
    let mut w = ClWriter::new(out);
    w.comment(&format!(
        "microcam 5-axis CL data: x y z (tool tip) x1 y1 z1 (point on the tool axis), mm; cutter {}, lead {} deg, tilt {} deg, gouge check {}{}{}{}, from {name}",
        dc.cutter(),
        a.lead,
        a.tilt,
        match a.gouge {
            GougeArg::Lift => "lift".to_string(),
            GougeArg::Report => "report".to_string(),
            GougeArg::Off => "off".to_string(),
            GougeArg::Tilt => format!(
                "tilt up to {} deg in steps of {} deg, eased over {} mm",
                o.max_turn, o.turn_step, o.turn_ramp
            ),
        },
        if a.holder.is_empty() {
            String::new()
        } else {
            format!(
                " with a holder of {}",
                a.holder
                    .iter()
                    .map(|h| format!("{} mm diameter from {} mm up the axis", 2.0 * h.radius, h.height))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
        o.crease_deg.map_or(String::new(), |deg| format!(
            ", axes from smoothed normals (crease {deg} deg)"
        )),
        job.max_axis_change.map_or(String::new(), |_| format!(
            ", axis changes over {} deg {}",
            a.max_axis_change,
            match a.axis_change {
                AxisChangeArg::Steps => "turned in checked steps (else lifted)",
                AxisChangeArg::Lift => "lifted",
            }
        ))
    ))?;
    write_cldata5(&mut w, &done.runs, safe_z)?;
    w.finish()?;
    Ok(computed)
}

/// One line on how the smooth-normal locations were set down on the part.
fn settle_summary(r: &SettleReport, crease_deg: f64) -> String {
    let mut line = format!(
        "axes from smoothed normals (crease {crease_deg} deg): {} locations set down on the part along their axes, {} of them raised out of it (up to {:.6} mm: the facets under a smoothed tangent plane, and where the part is tighter than the tool)",
        r.settled, r.raised, r.highest
    );
    if r.nothing_below > 0 {
        line.push_str(&format!("; {} with no part below left as they were", r.nothing_below));
    }
    line
}

/// One line on what the gouge check found and did.
fn gouge_summary(r: &GougeReport, rule: GougeRule, length: f64) -> String {
    let Some(at) = r.deepest_at else {
        return format!(
            "gouge check: none of {} locations cuts into the part (tool checked {length} mm up its axis)",
            r.checked
        );
    };
    format!(
        "gouge check: {} of {} locations cut into the part (up to {:.6} mm along the tool axis, the deepest with its tip at {:.6} {:.6} {:.6}); {}",
        r.gouging,
        r.checked,
        r.deepest,
        at.x,
        at.y,
        at.z,
        match rule {
            GougeRule::Lift => "lifted along the axis until the tool only touches (material is left there)",
            GougeRule::Report => "left as they are (--gouge report)",
        }
    )
}

/// One line on what the tilt search found and did.
fn tilt_summary(r: &GougeReport, t: &TiltReport, length: f64) -> String {
    if r.gouging == 0 {
        return gouge_summary(r, GougeRule::Lift, length);
    }
    format!(
        "gouge check: {} of {} locations cut into the part (up to {:.6} mm along the tool axis); {} turned to clear it (lead or tilt changed by up to {:.1} deg; {} of them both, where no turn of one cleared), {} lifted along the axis where no turn within reach cleared it; {} more turned part way to ease the axis in and out (the turn changes by at most {:.1} deg between neighbours)",
        r.gouging,
        r.checked,
        r.deepest,
        t.tilted,
        t.largest_turn.to_degrees(),
        t.both,
        t.lifted,
        t.eased,
        t.largest_jump.to_degrees()
    )
}

/// One line on how far the tool axis turns between neighbours, and what
/// `--max-axis-change` did where it turned more.
fn axis_change_summary(r: &AxisReport, max: Option<f64>) -> String {
    match max {
        None => format!(
            "the tool axis turns by up to {:.1} deg between neighbouring locations (--max-axis-change off: every change kept as computed)",
            r.largest_kept.to_degrees()
        ),
        Some(m) if r.stepped + r.split == 0 => format!(
            "the tool axis turns by up to {:.1} deg between neighbouring locations, within --max-axis-change {:.1}: nothing stepped or lifted",
            r.largest_kept.to_degrees(),
            m.to_degrees()
        ),
        Some(m) => format!(
            "{} places where the tool axis turns by more than {:.1} deg between neighbours (up to {:.1} deg): {} turned in {} added steps set down on the part, {} ending a run (the tool drawn back to the safe Z, turned and put down again); within runs it turns by up to {:.1} deg",
            r.stepped + r.split,
            m.to_degrees(),
            r.largest_over.to_degrees(),
            r.stepped,
            r.inserted,
            r.split,
            r.largest_kept.to_degrees()
        ),
    }
}
