//! `pathgen dropcutter`: CL data, a toolpath or G-code from a mesh by
//! dropping a flat, ball or torus cutter (the library's `dropcutter`).

#[path = "dropcutter/five.rs"]
mod five;
#[path = "dropcutter/waterline.rs"]
mod waterline;

use super::common::{WriterArgs, write_gcode, write_options};
use clap::{Args as ClapArgs, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::cutter::Cutter;
use microcam::dropcutter::adaptive::Adaptive;
use microcam::dropcutter::arcs::fit_pass;
use microcam::dropcutter::gouge::Holder;
use microcam::dropcutter::output::{Feeds, toolpath_records, toolpath_records_of_segments, write_cldata};
use microcam::dropcutter::raster::{Direction, Pattern, Raster, chain_passes};
use microcam::dropcutter::{DropCutter, DropError};
use microcam::formats::cldata::ClWriter;
use microcam::formats::read_chains;
use microcam::formats::toolpath::ToolpathWriter;
use microcam::gcode::Dialect;
use microcam::geometry::{P2, P3};
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
  pathgen dropcutter part.stl --tool ball:0.5 --step-over 0.05 --step-forward 0.01 --arc-fit 0.001 --gcode iso > finish.ngc

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
    /// --turn-step up to --max-turn (both, where neither alone clears);
    /// lift where none clears the part.
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
    /// Waterlines or a raster as toolpath or G-code: fit arcs (G2/G3) to
    /// each loop or pass in its own plane (G17 for a waterline, G18 for a
    /// pass along X, G19 along Y), staying within this of its chords both
    /// ways (mm), instead of a line per point.
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
        return waterline::run(&a, &dc, floor, safe_z, feeds, &name);
    }
    // Checked before the drop: it is most of the work.
    let arc_fit = arc_fit_arg(&a)?;
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
    let mut fit_line = None;
    if a.five_axis {
        n_points = five::run(&a, &dc, &passes, safe_z, &name, &mut out)?;
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
        match arc_fit {
            Some(t) => {
                let fitted = fit_passes(&a, &cl, |p| fit_pass(p, t));
                write_records(
                    &a,
                    toolpath_records_of_segments(&fitted, safe_z, feeds),
                    &name,
                    &mut out,
                )?;
                fit_line = Some(fit_summary(&fitted, t, "passes", &cl));
            }
            None => write_passes(&a, cutter, &cl, safe_z, feeds, &name, &mut out)?,
        }
    }
    out.commit()?;
    microcam::diag!(
        "pathgen: dropcutter: {} triangles, {} passes, {n_points} CL points",
        loaded.mesh.triangles.len(),
        passes.len(),
    );
    if let Some(line) = fit_line {
        microcam::diag!("pathgen: dropcutter: {line}");
    }
    Ok(())
}

/// `--arc-fit`, checked: only where the output can hold arcs (a toolpath
/// or G-code) and the passes lie in planes G2/G3 can name (waterlines, a
/// raster; not the points along a drawn chain).
fn arc_fit_arg(a: &DropcutterArgs) -> Result<Option<f64>, CliError> {
    let Some(t) = a.arc_fit else { return Ok(None) };
    if a.chains.is_some() {
        return Err(CliError::input(
            "--arc-fit goes with a raster or waterlines (the points along a chain lie in no one plane of G17/G18/G19)",
        ));
    }
    if a.gcode.is_none() && a.format == FormatArg::Cl {
        return Err(CliError::input(
            "--arc-fit: CL data holds points only; use --format toolpath or --gcode",
        ));
    }
    Ok(Some(positive("arc-fit", t)?))
}

/// Each pass (or loop) fitted with lines and arcs by `fit`, on the pool,
/// with a meter: seconds on a large job, about as long again as the drop.
fn fit_passes(a: &DropcutterArgs, passes: &[Vec<P3>], fit: impl Fn(&[P3]) -> Vec<Segment> + Sync) -> Vec<Vec<Segment>> {
    let points = passes.iter().map(Vec::len).sum::<usize>() as u64;
    let meter = Meter::start("pathgen", "fitting arcs", points, Show::from_flags(a.quiet, false));
    let fitted = passes
        .par_iter()
        .map(|p| {
            let f = fit(p);
            microcam::progress::advance(p.len() as u64);
            f
        })
        .collect();
    meter.finish();
    fitted
}

/// The stderr line on a fit: moves and arcs written for the points.
fn fit_summary(fitted: &[Vec<Segment>], t: f64, what: &str, points: &[Vec<P3>]) -> String {
    let arcs = fitted.iter().flatten().filter(|s| matches!(s, Segment::Arc(_))).count();
    format!(
        "arcs fitted within {t} mm of the {what}' chords: {} moves ({arcs} arcs) for {} points",
        fitted.iter().map(Vec::len).sum::<usize>(),
        points.iter().map(Vec::len).sum::<usize>()
    )
}

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

/// 3-axis passes (raster, chains or waterlines) as G-code, toolpath or CL
/// data, as the flags ask.
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
