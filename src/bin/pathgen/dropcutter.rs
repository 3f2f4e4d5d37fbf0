//! `pathgen dropcutter`: CL data, a toolpath or G-code from a mesh by
//! dropping a flat, ball or torus cutter (the library's `dropcutter`).

use super::common::{WriterArgs, write_gcode, write_options};
use clap::{Args as ClapArgs, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::cutter::Cutter;
use microcam::dropcutter::adaptive::Adaptive;
use microcam::dropcutter::fiveaxis::{Contact, FiveAxis, Location};
use microcam::dropcutter::gouge::{GougeCheck, GougeReport, GougeRule, Holder, Placement, SettleReport};
use microcam::dropcutter::normals::DEFAULT_CREASE_DEG;
use microcam::dropcutter::output::{
    Feeds, toolpath_records, toolpath_records_of_segments, write_cldata, write_cldata5,
};
use microcam::dropcutter::raster::{Direction, Pattern, Raster, chain_passes};
use microcam::dropcutter::swing::{AxisLimit, AxisReport};
use microcam::dropcutter::tilt::{TiltReport, TiltSearch};
use microcam::dropcutter::waterline::Waterline;
use microcam::dropcutter::{DropCutter, DropError};
use microcam::formats::cldata::ClWriter;
use microcam::formats::read_chains;
use microcam::formats::toolpath::ToolpathWriter;
use microcam::gcode::Dialect;
use microcam::geometry::{P2, P3};
use microcam::laser::arcfit::fit_points;
use microcam::mesh::{ReadOptions, Units};
use microcam::model::chain::Segment;
use microcam::model::toolpath::{FeedUnit, Header, Record};
use microcam::progress::{Meter, Show};
use rayon::prelude::*;
use std::io::Read;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
Examples:
  pathgen dropcutter part.stl --tool ball:1 --step-over 0.1 --step-forward 0.05 > part.cl
  pathgen dropcutter part.stl --tool torus:2:0.25 --step-over 0.2 --direction y --pattern one-way --format toolpath
  pathgen dropcutter part.stl --tool flat:1 --step-over 0.1 --chord-tol 0.001 --gcode iso > part.ngc
  dxf2chains path.dxf | pathgen dropcutter part.stl --tool ball:0.5 --chains - --step-forward 0.02
  pathgen dropcutter part.stl --tool flat:2 --step-over 0.5 --five-axis --lead 5 --tilt 0 > part5.cl
  pathgen dropcutter part.stl --tool torus:1:0.2 --step-over 0.2 --five-axis --gouge report > raw5.cl
  pathgen dropcutter part.stl --tool flat:1 --step-over 0.1 --five-axis --lead 3 --normals smooth > smooth5.cl
  pathgen dropcutter part.stl --tool flat:1 --step-over 0.1 --five-axis --gouge tilt --max-axis-change 10 > stepped5.cl
  pathgen dropcutter part.stl --tool ball:1 --waterline-step 0.2 --step-over 0.02 --gcode iso > walls.ngc
  pathgen dropcutter part.stl --tool flat:1 --waterline 2,1 --step-over 0.2 --chord-tol 0.001 > wl.cl
  pathgen dropcutter part.stl --tool ball:1 --waterline-step 0.2 --step-over 0.02 --arc-fit 0.002 --gcode pmac > walls.pmc

The mesh is STL (ASCII or binary) or OBJ in mm unless --units says otherwise.
CL data rows are 'x y z' (tool tip) or, with --five-axis, 'x y z x1 y1 z1'
(tip and a point up the tool axis: the layout of Singh 2014, Annexure 2).
5-axis locations are checked with the whole tool, --axis-length of it: one
that would cut into the part away from its contact is lifted along its axis
(--gouge lift, the default), turned to another lead or tilt that clears the
part (--gouge tilt, lifted where none within --max-turn does), or only
reported (--gouge report). The axis follows each facet's normal, or with
--normals smooth vertex normals interpolated across the facets (no steps
at facet edges), each tool then set down on the mesh along its axis.
Passes are joined at the safe Z. Waterlines (--waterline, --waterline-step)
are closed loops at constant Z round the model, the model on the right of
the travel (climb milling with M3), found on fibres --step-over apart;
--chord-tol adds points between the fibres where the loop bends.
A summary goes to stderr.
Exit status: 0 ok, 1 failure, 2 bad usage or bad input.";

/// Raster direction.
#[derive(Clone, Copy, ValueEnum)]
pub enum DirArg {
    X,
    Y,
}

/// Raster line order.
#[derive(Clone, Copy, ValueEnum)]
pub enum PatternArg {
    Zigzag,
    OneWay,
}

/// What to write.
#[derive(Clone, Copy, ValueEnum, PartialEq)]
pub enum FormatArg {
    /// CL data text.
    Cl,
    /// microcam.toolpath/1.
    Toolpath,
}

/// Which surface normal a 5-axis axis follows.
#[derive(Clone, Copy, ValueEnum, PartialEq)]
pub enum NormalsArg {
    /// The normal of the facet under the contact.
    Facet,
    /// Vertex normals interpolated across the facet (creases kept).
    Smooth,
}

/// What the 5-axis gouge check does.
#[derive(Clone, Copy, ValueEnum, PartialEq)]
pub enum GougeArg {
    /// Lift a gouging location along its tool axis until the tool only touches the part.
    Lift,
    /// Keep every location as computed; only report the gouges.
    Report,
    /// Try other orientations first: lead or tilt changed in steps of
    /// --turn-step up to --max-turn; lift where none clears the part.
    Tilt,
    /// No check.
    Off,
}

/// What --max-axis-change does where the tool axis would turn more.
#[derive(Clone, Copy, ValueEnum, PartialEq)]
pub enum AxisChangeArg {
    /// Turn in steps of at most the limit, each set down on the part and
    /// checked; lift where a step cannot be made.
    Steps,
    /// End the run: the tool is drawn back to the safe Z, turned and put
    /// down again.
    Lift,
}

/// Units of the mesh file.
#[derive(Clone, Copy, ValueEnum)]
pub enum UnitsArg {
    Mm,
    Inch,
    Um,
}

#[derive(ClapArgs)]
pub struct DropcutterArgs {
    /// Mesh (STL or OBJ; '-' for stdin).
    file: Option<PathBuf>,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
    /// Cutter: flat:D, ball:D or torus:D:RC (mm).
    #[arg(long = "tool", alias = "cutter", value_name = "TOOL")]
    cutter: String,
    /// Units of the mesh coordinates.
    #[arg(long, value_enum, default_value = "mm")]
    units: UnitsArg,
    /// Largest distance between raster lines (mm).
    #[arg(long)]
    step_over: Option<f64>,
    /// Largest distance between points along a pass (mm; default: the step-over).
    #[arg(long)]
    step_forward: Option<f64>,
    /// Axis the raster lines run along.
    #[arg(long, value_enum, default_value = "x")]
    direction: DirArg,
    /// Zigzag (lines joined at the edge) or one-way (up to safe Z between lines).
    #[arg(long, value_enum, default_value = "zigzag")]
    pattern: PatternArg,
    /// Raster rectangle XMIN,YMIN,XMAX,YMAX (default: the mesh's XY box).
    #[arg(long, value_parser = parse_region, allow_hyphen_values = true)]
    region: Option<[f64; 4]>,
    /// Drop along these chains (microcam.chains/1, '-' for stdin) instead of a raster.
    #[arg(long, value_name = "FILE")]
    chains: Option<PathBuf>,
    /// Add points where the surface bends so the CL polyline is within this of the true CL curve (mm); with waterlines, points between fibres.
    #[arg(long)]
    chord_tol: Option<f64>,
    /// Adaptive sampling splits no span shorter than this (mm; default chord-tol).
    #[arg(long)]
    min_step: Option<f64>,
    /// Height of links between passes (default: mesh top + clearance).
    #[arg(long, allow_hyphen_values = true)]
    safe_z: Option<f64>,
    /// Safe Z above the mesh top when --safe-z is not given (mm).
    #[arg(long, default_value_t = 1.0)]
    clearance: f64,
    /// The tip never goes below this (mm; default: the mesh bottom, the table).
    #[arg(long, allow_hyphen_values = true)]
    floor: Option<f64>,
    /// Output format (G-code with --gcode).
    #[arg(long, value_enum, default_value = "cl")]
    format: FormatArg,
    /// Write G-code of this dialect instead.
    #[arg(long, value_parser = ["iso", "pmac"])]
    gcode: Option<String>,
    /// Cutting feed (mm/s) for toolpath and G-code output.
    #[arg(long, default_value_t = 1.0)]
    feed: f64,
    /// Plunge feed (mm/s; default: the cutting feed).
    #[arg(long)]
    plunge_feed: Option<f64>,
    /// Waterlines at these tip heights (Z1,Z2,...; mm) instead of a raster.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "Z", conflicts_with_all = ["chains", "five_axis", "waterline_step", "region", "min_step", "step_forward", "direction", "pattern"])]
    waterline: Option<Vec<f64>>,
    /// Waterlines every DZ down from the mesh top to the floor.
    #[arg(long, value_name = "DZ", conflicts_with_all = ["chains", "five_axis", "region", "min_step", "step_forward", "direction", "pattern"])]
    waterline_step: Option<f64>,
    /// Waterlines as toolpath or G-code: fit arcs (G2/G3) to each loop,
    /// staying within this of its chords both ways (mm), instead of a line
    /// per point.
    #[arg(long, value_name = "T")]
    arc_fit: Option<f64>,
    /// 5-axis CL data: flat or torus cutter along the surface normal.
    #[arg(long)]
    five_axis: bool,
    /// 5-axis: lean of the axis towards the feed direction (degrees).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    lead: f64,
    /// 5-axis: lean of the axis to the left of the feed direction (degrees).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    tilt: f64,
    /// 5-axis: distance from the tip to the second point on the axis (mm);
    /// also the length of tool the gouge check tests against the part.
    #[arg(long, default_value_t = 50.0)]
    axis_length: f64,
    /// 5-axis: check the whole tool, not only its contact point, against
    /// the part, and lift or report the locations where it cuts in.
    #[arg(long, value_enum, default_value_t = GougeArg::Lift, requires = "five_axis")]
    gouge: GougeArg,
    /// 5-axis, --gouge tilt: the largest change of lead or tilt tried
    /// (degrees; default 30).
    #[arg(long, requires = "five_axis")]
    max_turn: Option<f64>,
    /// 5-axis, --gouge tilt: the step of the changes tried (degrees;
    /// default 5).
    #[arg(long, requires = "five_axis")]
    turn_step: Option<f64>,
    /// 5-axis, --gouge tilt: ease each turn in and out over this distance
    /// along the pass, so the axis turns gradually (mm; default the
    /// cutter's diameter; 0 turns only the locations that need it).
    #[arg(long, value_name = "MM", requires = "five_axis")]
    turn_ramp: Option<f64>,
    /// 5-axis: where the tool axis would turn by more than this between
    /// two neighbouring locations, turn it in steps of at most this, each
    /// set down on the part and checked; where a step cannot be made, end
    /// the run there (the tool is drawn back along its axis to the safe Z,
    /// turned and put down again) instead of swinging it in the cut
    /// (degrees, 0.1 to 180; `off` or 180 keeps every change as computed).
    #[arg(long, value_name = "DEG|off", default_value = "20", value_parser = axis_limit_arg, requires = "five_axis")]
    max_axis_change: f64,
    /// 5-axis: where the axis would turn more than --max-axis-change, turn
    /// it in checked steps where they can be made, else lift (steps, the
    /// default), or always lift (lift).
    #[arg(long, value_enum, default_value_t = AxisChangeArg::Steps, requires = "five_axis")]
    axis_change: AxisChangeArg,
    /// 5-axis: check the tool holder too, a cylinder of diameter D whose
    /// face is H mm up the axis from the tool tip (the stick-out), up to
    /// --axis-length (D:H, mm; D at least the cutter's). A stepped holder
    /// (collet nut, body, spindle nose) is several: D1:H1,D2:H2 or the
    /// option again.
    #[arg(long, value_name = "D:H", value_parser = parse_holder, value_delimiter = ',', requires = "five_axis")]
    holder: Vec<Holder>,
    /// 5-axis: the surface normal the axis follows: each facet's own
    /// (the axis turns in steps at facet edges), or one interpolated
    /// across each facet from its corners' vertex normals (the axis turns
    /// smoothly; each tool is then set down on the mesh along its axis).
    #[arg(long, value_enum, default_value_t = NormalsArg::Facet, requires = "five_axis")]
    normals: NormalsArg,
    /// 5-axis, --normals smooth: facets meeting at more than this angle
    /// keep their own normals along their edge (degrees, 0 to 180;
    /// default 30).
    #[arg(long, value_name = "DEG", requires = "five_axis")]
    crease: Option<f64>,
    #[command(flatten)]
    writer: WriterArgs,
    /// Write output here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn parse_holder(s: &str) -> Result<Holder, String> {
    let v: Vec<f64> = s
        .split(':')
        .map(|t| t.trim().parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("expected D:H, two positive lengths in mm, got '{s}'"))?;
    match v[..] {
        [d, h] => Ok(Holder {
            radius: d / 2.0,
            height: h,
        }),
        _ => Err(format!("expected D:H, two positive lengths in mm, got '{s}'")),
    }
}

fn parse_region(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("expected XMIN,YMIN,XMAX,YMAX, got '{s}'"))?;
    match v[..] {
        [a, b, c, d] if a <= c && b <= d => Ok([a, b, c, d]),
        [_, _, _, _] => Err(format!("'{s}': need XMIN <= XMAX and YMIN <= YMAX")),
        _ => Err(format!("expected XMIN,YMIN,XMAX,YMAX, got '{s}'")),
    }
}

fn bad(e: DropError) -> CliError {
    CliError::input(e.to_string())
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
        "gouge check: {} of {} locations cut into the part (up to {:.6} mm along the tool axis); {} turned to clear it (lead or tilt changed by up to {:.1} deg), {} lifted along the axis where no turn within reach cleared it; {} more turned part way to ease the axis in and out (the turn changes by at most {:.1} deg between neighbours)",
        r.gouging,
        r.checked,
        r.deepest,
        t.tilted,
        t.largest_turn.to_degrees(),
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

/// `--max-axis-change`: degrees, or `off` (180: no change is larger).
/// The range is checked with the other options, so that a number out of
/// it gets the same message as the other angles.
fn axis_limit_arg(s: &str) -> Result<f64, String> {
    if s.eq_ignore_ascii_case("off") {
        return Ok(180.0);
    }
    s.parse::<f64>()
        .map_err(|_| format!("{s:?}: degrees (0.1 to 180) or off"))
}

fn positive(name: &str, v: f64) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!("--{name} must be positive, got {v}")))
    }
}

pub fn run(a: DropcutterArgs) -> Result<(), CliError> {
    let cutter = Cutter::parse(&a.cutter).map_err(|e| CliError::input(format!("--tool: {e}")))?;
    if a.five_axis && (a.gcode.is_some() || a.format != FormatArg::Cl) {
        return Err(CliError::input(
            "--five-axis writes CL data only (toolpaths and G-code here are 3-axis)",
        ));
    }
    let feeds = Feeds {
        cut: positive("feed", a.feed)?,
        plunge: positive("plunge-feed", a.plunge_feed.unwrap_or(a.feed))?,
    };
    let opts = ReadOptions {
        units: match a.units {
            UnitsArg::Mm => Units::Mm,
            UnitsArg::Inch => Units::Inch,
            UnitsArg::Um => Units::Um,
        },
        format: None,
    };
    let (name, loaded) = match a.file.as_deref().filter(|p| p.as_os_str() != "-") {
        Some(p) => (
            p.display().to_string(),
            microcam::mesh::read_path(p, &opts).map_err(|e| CliError::input(format!("{}: {e}", p.display())))?,
        ),
        None => {
            let mut bytes = Vec::new();
            std::io::stdin().read_to_end(&mut bytes)?;
            let m = microcam::mesh::read_bytes(&bytes, &opts).map_err(|e| CliError::input(format!("<stdin>: {e}")))?;
            ("<stdin>".to_string(), m)
        }
    };
    let dc = DropCutter::new(&loaded.mesh, cutter).map_err(|e| CliError::input(format!("{name}: {e}")))?;
    let bb = dc.bbox();
    let floor = a.floor.unwrap_or(bb.min.z);
    let safe_z = a.safe_z.unwrap_or(bb.max.z + a.clearance);
    if !(floor.is_finite() && safe_z.is_finite()) {
        return Err(CliError::input("--floor and --safe-z must be finite"));
    }
    if safe_z < bb.max.z {
        microcam::diag!(
            "pathgen: warning: dropcutter: safe Z {safe_z} is below the mesh top {}",
            bb.max.z
        );
    }
    if a.waterline.is_some() || a.waterline_step.is_some() {
        return run_waterlines(&a, &dc, floor, safe_z, feeds, &name);
    }
    if a.arc_fit.is_some() {
        return Err(CliError::input("--arc-fit goes with --waterline or --waterline-step"));
    }
    // The XY passes.
    let passes: Vec<Vec<P2>> = if let Some(path) = &a.chains {
        let input = cli::open_input(Some(path))?;
        let cname = input.name.clone();
        let (_, chains) = read_chains(input.reader).map_err(|e| CliError::in_file(&cname, e))?;
        let step = positive("step-forward", a.step_forward.or(a.step_over).unwrap_or(f64::NAN))?;
        chain_passes(&chains, step).map_err(bad)?
    } else {
        let so = a
            .step_over
            .ok_or_else(|| CliError::input("--step-over is required for a raster (or give --chains)"))?;
        let region = a.region.unwrap_or([bb.min.x, bb.min.y, bb.max.x, bb.max.y]);
        Raster {
            step_over: so,
            step_forward: a.step_forward.unwrap_or(so),
            direction: match a.direction {
                DirArg::X => Direction::X,
                DirArg::Y => Direction::Y,
            },
            pattern: match a.pattern {
                PatternArg::Zigzag => Pattern::Zigzag,
                PatternArg::OneWay => Pattern::OneWay,
            },
            region,
        }
        .passes()
        .map_err(bad)?
    };
    let mut out = Output::new(a.output.as_deref());
    let n_points: usize;
    if a.five_axis {
        let fa = FiveAxis {
            lead: a.lead.to_radians(),
            tilt: a.tilt.to_radians(),
            axis_length: positive("axis-length", a.axis_length)?,
        };
        let (r, rc) = FiveAxis::radii(&dc).map_err(bad)?;
        let smooth = match (a.normals, a.crease) {
            (NormalsArg::Facet, Some(_)) => return Err(CliError::input("--crease goes with --normals smooth")),
            (NormalsArg::Facet, None) => None,
            (NormalsArg::Smooth, crease) => {
                let deg = crease.unwrap_or(DEFAULT_CREASE_DEG);
                if !(0.0..=180.0).contains(&deg) {
                    return Err(CliError::input(format!("--crease {deg}: degrees, 0 to 180")));
                }
                Some((dc.smooth_normals(deg.to_radians()), deg))
            }
        };
        let contacts: Vec<Vec<Contact>> = passes
            .iter()
            .flat_map(|p| FiveAxis::contacts_with(&dc, p, smooth.as_ref().map(|(n, _)| n)))
            .collect();
        let mut runs: Vec<Vec<Location>> = contacts
            .iter()
            .map(|run| run.iter().map(|c| fa.location(c.cc, c.normal, c.feed, r, rc)).collect())
            .collect();
        n_points = runs.iter().map(Vec::len).sum();
        if a.gouge != GougeArg::Tilt && (a.max_turn.is_some() || a.turn_step.is_some() || a.turn_ramp.is_some()) {
            return Err(CliError::input(
                "--max-turn, --turn-step and --turn-ramp go with --gouge tilt",
            ));
        }
        let turn_ramp = a.turn_ramp.unwrap_or(2.0 * cutter.radius());
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
        let meter = Meter::start(
            "pathgen",
            "checking the tool against the part",
            // Setting down (smoothed normals) and checking count a
            // location each; the tilt search with smoothed normals does
            // both.
            n_points as u64
                * match (a.gouge, smooth.is_some()) {
                    (GougeArg::Off, false) => 0,
                    (GougeArg::Tilt, true) => 2,
                    _ => 1,
                },
            Show::from_flags(a.quiet, false),
        );
        if a.gouge == GougeArg::Off && !a.holder.is_empty() {
            return Err(CliError::input("--holder goes with the gouge check (not --gouge off)"));
        }
        if let Some(h) = a.holder.iter().find(|h| h.height >= fa.axis_length) {
            return Err(CliError::input(format!(
                "--holder: its face at {} mm is not below --axis-length {} (the length of tool checked)",
                h.height, fa.axis_length
            )));
        }
        // Built only when a check or a setting down runs: its 3-D tree
        // takes a quarter of a second on a million triangles.
        let checker = || -> Result<GougeCheck, CliError> {
            a.holder.iter().try_fold(GougeCheck::new(&dc), |c, &h| {
                c.with_holder(h).map_err(|e| CliError::input(format!("--holder: {e}")))
            })
        };
        // With smoothed normals every location is set down on the part
        // (tangent to the smoothed surface, a tool dips into the facets
        // round its contact); the gouges are then what lies beyond that.
        let settling = smooth.is_some();
        let rule = if a.gouge == GougeArg::Lift {
            GougeRule::Lift
        } else {
            GougeRule::Report
        };
        let (summary, settled) = match a.gouge {
            GougeArg::Off if settling => {
                let (_, s) = checker()?.check_settling(&contacts, &mut runs, fa.axis_length, GougeRule::Report);
                (None, Some(s))
            }
            GougeArg::Off => (None, None),
            GougeArg::Lift | GougeArg::Report if settling => {
                let (report, s) = checker()?.check_settling(&contacts, &mut runs, fa.axis_length, rule);
                (Some(gouge_summary(&report, rule, fa.axis_length)), Some(s))
            }
            GougeArg::Lift | GougeArg::Report => {
                let report = checker()?.check(&mut runs, fa.axis_length, rule);
                (Some(gouge_summary(&report, rule, fa.axis_length)), None)
            }
            GougeArg::Tilt => {
                let (report, tilt, s) = checker()?
                    .check_tilting(
                        &fa,
                        &contacts,
                        &mut runs,
                        &TiltSearch {
                            max: max_turn.to_radians(),
                            step: turn_step.to_radians(),
                            ramp: turn_ramp,
                        },
                        if settling {
                            Placement::SetDown
                        } else {
                            Placement::Tangent
                        },
                    )
                    .map_err(bad)?;
                (
                    Some(tilt_summary(&report, &tilt, fa.axis_length)),
                    settling.then_some(s),
                )
            }
        };
        if let (Some(s), Some((_, deg))) = (settled, &smooth) {
            microcam::diag!("pathgen: dropcutter: 5-axis: {}", settle_summary(&s, *deg));
        }
        meter.finish();
        if let Some(line) = summary {
            microcam::diag!("pathgen: dropcutter: 5-axis: {line}");
        }
        // After every check: the steps are set down and checked on their
        // own, and the locations the checks left are kept as they are.
        let limit = AxisLimit {
            max: max_axis_change.unwrap_or(std::f64::consts::PI),
            length: fa.axis_length,
            steps: a.axis_change == AxisChangeArg::Steps,
        };
        let axis_report = match max_axis_change {
            Some(_) if limit.steps => limit.apply(Some(&checker()?), &mut runs),
            _ => limit.apply(None, &mut runs),
        };
        microcam::diag!(
            "pathgen: dropcutter: 5-axis: {}",
            axis_change_summary(&axis_report, max_axis_change)
        );
        let mut w = ClWriter::new(&mut out);
        w.comment(&format!(
            "microcam 5-axis CL data: x y z (tool tip) x1 y1 z1 (point on the tool axis), mm; cutter {cutter}, lead {} deg, tilt {} deg, gouge check {}{}{}{}, from {name}",
            a.lead,
            a.tilt,
            match a.gouge {
                GougeArg::Lift => "lift".to_string(),
                GougeArg::Report => "report".to_string(),
                GougeArg::Off => "off".to_string(),
                GougeArg::Tilt => format!(
                    "tilt up to {max_turn} deg in steps of {turn_step} deg, eased over {turn_ramp} mm"
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
            smooth.as_ref().map_or(String::new(), |(_, deg)| format!(
                ", axes from smoothed normals (crease {deg} deg)"
            )),
            max_axis_change.map_or(String::new(), |_| format!(
                ", axis changes over {} deg {}",
                a.max_axis_change,
                match a.axis_change {
                    AxisChangeArg::Steps => "turned in checked steps (else lifted)",
                    AxisChangeArg::Lift => "lifted",
                }
            ))
        ))?;
        write_cldata5(&mut w, &runs, safe_z)?;
        w.finish()?;
    } else {
        let adaptive = match chord_tol_arg(&a)? {
            Some(t) => {
                let min_step = positive("min-step", a.min_step.unwrap_or(t.max(1e-4)))?;
                if min_step < 1e-4 {
                    return Err(CliError::input(format!(
                        "--min-step {min_step}: below 1e-4 mm (0.1 µm), finer than any stage moves"
                    )));
                }
                Some(Adaptive { chord_tol: t, min_step })
            }
            None => None,
        };
        let flat: Vec<P2> = passes.iter().flatten().copied().collect();
        let meter = Meter::start(
            "pathgen",
            "dropping the cutter",
            flat.len() as u64,
            Show::from_flags(a.quiet, false),
        );
        let dropped = dc.drop_many(&flat, floor);
        meter.finish();
        let mut cl: Vec<Vec<P3>> = Vec::with_capacity(passes.len());
        let mut at = 0;
        for p in &passes {
            let pass = &dropped[at..at + p.len()];
            at += p.len();
            cl.push(match &adaptive {
                Some(ad) => ad.refine(&dc, pass, floor),
                None => pass.to_vec(),
            });
        }
        n_points = cl.iter().map(Vec::len).sum();
        write_passes(&a, cutter, &cl, safe_z, feeds, &name, &mut out)?;
    }
    out.commit()?;
    microcam::diag!(
        "pathgen: dropcutter: {} triangles, {} passes, {n_points} CL points",
        loaded.mesh.triangles.len(),
        passes.len(),
    );
    Ok(())
}

/// 3-axis passes (raster, chains or waterlines) as G-code, toolpath or CL
/// data, as the flags ask.
/// Toolpath records out as G-code (`--gcode`) or toolpath JSON.
fn write_records(a: &DropcutterArgs, recs: Vec<Record>, name: &str, out: &mut Output) -> Result<(), CliError> {
    match &a.gcode {
        Some(d) => {
            let dialect: Dialect = d.parse().map_err(CliError::input)?;
            write_gcode(
                recs.into_iter().map(Ok::<_, CliError>),
                FeedUnit::MmPerS,
                write_options(dialect, &a.writer),
                name,
                out,
            )?;
        }
        None => {
            let mut w = ToolpathWriter::new(out);
            w.header(&Header {
                feed_unit: FeedUnit::MmPerS,
                source: Some(name.to_string()),
            })?;
            for r in &recs {
                w.record(r)?;
            }
            w.finish()?;
        }
    }
    Ok(())
}

fn write_passes(
    a: &DropcutterArgs,
    cutter: Cutter,
    cl: &[Vec<P3>],
    safe_z: f64,
    feeds: Feeds,
    name: &str,
    out: &mut Output,
) -> Result<(), CliError> {
    match (&a.gcode, a.format) {
        (Some(_), _) | (None, FormatArg::Toolpath) => {
            write_records(a, toolpath_records(cl, safe_z, feeds), name, out)?;
        }
        (None, FormatArg::Cl) => {
            let mut w = ClWriter::new(out);
            w.comment(&format!(
                "microcam CL data: x y z (tool tip), mm; cutter {cutter}, safe z {safe_z}, from {name}"
            ))?;
            write_cldata(&mut w, cl, safe_z)?;
            w.finish()?;
        }
    }
    Ok(())
}

/// `--chord-tol`, checked: positive and not below a nanometre.
fn chord_tol_arg(a: &DropcutterArgs) -> Result<Option<f64>, CliError> {
    let Some(t) = a.chord_tol else { return Ok(None) };
    let t = positive("chord-tol", t)?;
    // Below a nanometre the test is below the float precision of an STL
    // mesh, and below 0.1 µm a span is shorter than any stage can move:
    // both would split spans until the depth limit.
    if t < 1e-6 {
        return Err(CliError::input(format!(
            "--chord-tol {t}: below 1e-6 mm, finer than the mesh's float precision"
        )));
    }
    Ok(Some(t))
}

/// `--waterline` / `--waterline-step`: closed loops at each level, top
/// down, sampled on fibres `--step-over` apart.
fn run_waterlines(
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
