//! `pathgen helix`, `spiral`, `zigzag` and `cone`: the generated laser patterns.

use super::common::{
    GenOutput, MAX_WARNINGS, MachineArgs, at_least_one, finite, non_negative, parse_pair_f64, parse_triple_f64,
    positive, short_note, write_generated,
};
use clap::Args as ClapArgs;
use microcam::cli::CliError;
use microcam::geometry::{P3, Plane};
use microcam::laser::constant_velocity::{Tagged, all_cut, plan_paths};
use microcam::laser::contour::Warning;
use microcam::laser::patterns;
use microcam::laser::setup::LaserSetup;
use microcam::progress;

pub(crate) const PATTERN_EXAMPLES: &str = "\
Examples:
  pathgen helix --center 1,1 --radius 0.3 --pitch -0.01 --turns 5 --gcode pmac
  pathgen spiral --kind archimedean --radius 0.5 --step 0.01 --inward
  pathgen spiral --kind square --size 1 --step 0.02 --svg sq.svg
  pathgen zigzag --length 2 --width 1 --step 0.01 --along y --plane xz
  pathgen cone --d1 1 --d2 0.4 --height 0.3 --levels 10 --step 0.01

Output is microcam.toolpath/1 (feeds in mm/s) or G-code with --gcode; every
move runs at --feed with the beam switched per the shutter timing.";

#[derive(ClapArgs)]
pub(crate) struct HelixArgs {
    /// Centre X,Y.
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    center: (f64, f64),
    /// Start height (mm).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    z: f64,
    /// Radius (mm).
    #[arg(long)]
    radius: f64,
    /// Rise per turn (mm; negative goes down).
    #[arg(long, allow_hyphen_values = true)]
    pitch: f64,
    /// Whole turns.
    #[arg(long, default_value_t = 1)]
    turns: u32,
    /// Clockwise instead of counter-clockwise.
    #[arg(long)]
    cw: bool,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
pub(crate) struct SpiralArgs {
    /// square or archimedean.
    #[arg(long, value_parser = ["square", "archimedean"], default_value = "archimedean")]
    kind: String,
    /// Centre X,Y.
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    center: (f64, f64),
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    z: f64,
    /// Distance between passes (mm).
    #[arg(long)]
    step: f64,
    /// Square: side of the square (mm).
    #[arg(long)]
    size: Option<f64>,
    /// Archimedean: outer radius (mm), closed by a full circle there.
    #[arg(long)]
    radius: Option<f64>,
    /// Archimedean: radius where the spiral starts (a in r = a + b·θ; default: step).
    #[arg(long)]
    inner: Option<f64>,
    /// Run from the outside in.
    #[arg(long)]
    inward: bool,
    /// Archimedean: largest deviation of the arcs from the spiral (mm).
    #[arg(
        long = "arc-tol",
        alias = "tolerance",
        value_name = "ARC_TOL",
        default_value_t = 1e-5
    )]
    tolerance: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
pub(crate) struct ZigzagArgs {
    /// Corner X,Y,Z where the first line starts.
    #[arg(long, value_parser = parse_triple_f64, default_value = "0,0,0", allow_hyphen_values = true)]
    origin: (f64, f64, f64),
    /// Plane of the hatching.
    #[arg(long, value_parser = ["xy", "xz"], default_value = "xy")]
    plane: String,
    /// Cut lines along this axis (the plane's other axis steps).
    #[arg(long, value_parser = ["x", "y", "z"], default_value = "x")]
    along: String,
    /// Length of each line (mm).
    #[arg(long)]
    length: f64,
    /// Extent across the lines (mm).
    #[arg(long)]
    width: f64,
    /// Distance between lines (mm).
    #[arg(long)]
    step: f64,
    /// Smallest turnaround radius (mm); never below V²/a.
    #[arg(long, default_value_t = 0.0)]
    corner_radius: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

#[derive(ClapArgs)]
pub(crate) struct ConeArgs {
    /// Centre X,Y.
    #[arg(long, value_parser = parse_pair_f64, default_value = "0,0", allow_hyphen_values = true)]
    center: (f64, f64),
    /// Surface height (mm); passes go down from here.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    z: f64,
    /// Diameter at the surface (mm).
    #[arg(long)]
    d1: f64,
    /// Diameter at depth --height (mm).
    #[arg(long)]
    d2: f64,
    /// Depth of the cone (mm).
    #[arg(long)]
    height: f64,
    /// Number of Z levels.
    #[arg(long, default_value_t = 10)]
    levels: u32,
    /// Distance between spiral passes (mm; default the beam diameter).
    #[arg(long)]
    step: Option<f64>,
    /// Beam spot diameter (mm): each section is filled to its edge minus the radius.
    #[arg(long, default_value_t = 0.01)]
    beam_diameter: f64,
    #[arg(
        long = "arc-tol",
        alias = "tolerance",
        value_name = "ARC_TOL",
        default_value_t = 1e-5
    )]
    tolerance: f64,
    #[command(flatten)]
    machine: MachineArgs,
    #[command(flatten)]
    out: GenOutput,
}

pub(crate) fn finish_pattern(paths: Vec<Tagged>, m: &LaserSetup, out: &GenOutput, what: &str) -> Result<(), CliError> {
    // A spinner while the paths are planned, then a bar of moves written.
    let meter = out.meter("moves written", 0);
    let (records, notes) = plan_paths(&paths, m, None);
    progress::add_total(records.len() as u64);
    let mut seen = std::collections::BTreeSet::new();
    let warnings: Vec<Warning> = notes
        .iter()
        .map(|n| n.to_string())
        .filter(|s| seen.insert(s.clone()))
        .map(|message| Warning { chain: 0, message })
        .collect();
    let written = write_generated(&records, out, Some(what.to_string()), m, true);
    meter.finish();
    if records.is_empty() {
        microcam::diag!("pathgen: warning: {what}: nothing to cut with these sizes");
    }
    for w in warnings.iter().take(MAX_WARNINGS) {
        microcam::diag!("pathgen: warning: {what}: {}", w.message);
    }
    let (short, total) = written?;
    short_note(short, total, m);
    Ok(())
}

pub(crate) fn helix_cmd(a: HelixArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let r = positive("radius", a.radius)?;
    let pitch = finite("pitch", a.pitch)?;
    let turns = at_least_one("turns", a.turns)?;
    // One arc per turn, a rapid, a lead-in and a lead-out.
    a.out
        .check_size("helix", f64::from(turns) + 4.0, &format!("--turns {turns}"))?;
    let c = P3::new(a.center.0, a.center.1, finite("z", a.z)?);
    let path = patterns::helix(c, r, pitch, turns, !a.cw);
    finish_pattern(vec![all_cut(path)], &m, &a.out, "helix")
}

pub(crate) fn spiral_cmd(a: SpiralArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let step = positive("step", a.step)?;
    let tol = arc_tol(a.tolerance)?;
    let c = P3::new(a.center.0, a.center.1, finite("z", a.z)?);
    let path = if a.kind == "square" {
        let size = positive(
            "size",
            a.size.ok_or_else(|| CliError::input("square spiral needs --size"))?,
        )?;
        // Each leg and the loop at its corner (a few pieces).
        a.out.check_size(
            "spiral",
            5.0 * patterns::square_spiral_legs(step, size),
            &format!("--size {size} at --step {step}"),
        )?;
        patterns::square_spiral(c, step, size, a.inward)
    } else {
        let r = positive(
            "radius",
            a.radius
                .ok_or_else(|| CliError::input("archimedean spiral needs --radius"))?,
        )?;
        let inner = a.inner.unwrap_or(step);
        if !(inner.is_finite() && inner >= 0.0 && inner < r) {
            return Err(CliError::input(format!("--inner must be in [0, radius), got {inner}")));
        }
        let how = format!("--radius {r} at --step {step}");
        a.out
            .check_size("spiral", patterns::archimedean_pieces(inner, step, r), &how)?;
        let max = usize::try_from(a.out.max_moves).unwrap_or(usize::MAX);
        patterns::archimedean_limited(c, inner, step, r, a.inward, tol, max)
            .map_err(|n| a.out.too_big("spiral", n, &format!("{how} within --arc-tol {tol}")))?
    };
    finish_pattern(vec![all_cut(path)], &m, &a.out, "spiral")
}

pub(crate) fn zigzag_cmd(a: ZigzagArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let (plane, along_second) = match (a.plane.as_str(), a.along.as_str()) {
        ("xy", "x") => (Plane::Xy, false),
        ("xy", "y") => (Plane::Xy, true),
        // Plane XZ's axes are (Z, X): lines along X are its second axis.
        ("xz", "x") => (Plane::Xz, true),
        ("xz", "z") => (Plane::Xz, false),
        (p, d) => return Err(CliError::input(format!("--along {d} is not in plane {p}"))),
    };
    let o = P3::new(a.origin.0, a.origin.1, a.origin.2);
    let z = patterns::Zigzag {
        origin: o,
        plane,
        along_second,
        length: positive("length", a.length)?,
        width: non_negative("width", a.width)?,
        step: positive("step", a.step)?,
        corner_radius: non_negative("corner-radius", a.corner_radius)?,
    };
    // Each cut line and its turnaround (a few pieces).
    a.out.check_size(
        "zigzag",
        5.0 * patterns::zigzag_lines(z.width, z.step),
        &format!("--width {} at --step {}", z.width, z.step),
    )?;
    let path = patterns::zigzag(&z, &m);
    finish_pattern(vec![path], &m, &a.out, "zigzag")
}

/// `--arc-tol` of a generated pattern (mm): positive, and not below 1 nm.
/// The pieces grow as the square root of 1/tol, and below a nanometre
/// they buy nothing a stage or the program's decimals can show: 1e-12 mm
/// made a cone of 2.4 million moves and 0.7 GB.
fn arc_tol(t: f64) -> Result<f64, CliError> {
    let t = positive("arc-tol", t)?;
    if t < 1e-6 {
        return Err(CliError::input(format!(
            "--arc-tol {t}: below 1e-6 mm (1 nm), finer than any stage moves or a program's decimals"
        )));
    }
    Ok(t)
}

pub(crate) fn cone_cmd(a: ConeArgs) -> Result<(), CliError> {
    let m = a.out.setup(&a.machine)?;
    let h = positive("height", a.height)?;
    let (d1, d2) = (positive("d1", a.d1)?, positive("d2", a.d2)?);
    let beam = non_negative("beam-diameter", a.beam_diameter)?;
    let step = positive("step", a.step.unwrap_or(beam))?;
    let tol = arc_tol(a.tolerance)?;
    let levels = at_least_one("levels", a.levels)?;
    let z0 = finite("z", a.z)?;
    // At least the widest section's spiral on every level.
    let how = format!("--levels {levels} at --step {step}");
    let widest = 0.5 * d1.max(d2);
    a.out.check_size(
        "cone",
        f64::from(levels) * patterns::archimedean_pieces(step, step, widest.max(step)),
        &how,
    )?;
    let mut budget = usize::try_from(a.out.max_moves).unwrap_or(usize::MAX);
    let mut paths = Vec::new();
    for (z, d) in patterns::cone_levels(z0, d1, d2, h, levels) {
        let r = 0.5 * d - 0.5 * beam;
        if r <= step {
            microcam::diag!(
                "pathgen: warning: cone: section at z={z} (diameter {d}) is narrower than the beam; skipped"
            );
            continue;
        }
        let c = P3::new(a.center.0, a.center.1, z);
        let path = patterns::archimedean_limited(c, step, step, r, false, tol, budget).map_err(|n| {
            a.out
                .too_big("cone", n * f64::from(levels), &format!("{how} within --arc-tol {tol}"))
        })?;
        budget = budget.saturating_sub(path.len());
        paths.push(all_cut(path));
    }
    finish_pattern(paths, &m, &a.out, "cone")
}
