//! `pathgen pocket`: grid-navigated freeform pockets (the Iowa State
//! grid-pocket thesis (1999)) and the contour-parallel alternative.

use super::common::{GenOutput, parse_pair_f64, write_records};
use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline};
use clap::{Args as ClapArgs, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::cutter::Cutter;
use microcam::formats::read_chains;
use microcam::geometry::P2;
use microcam::machine::Machine;
use microcam::pocket::layers::Feeds;
use microcam::pocket::motion::{FitOptions, MotionMode};
use microcam::pocket::passes::PassKind;
use microcam::pocket::surface::{BezierPatch, GridSurface, Interp, Surface};
use microcam::pocket::{Layers, PocketSpec, Strategy, grid, plan};
use std::io::Write;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
Examples:
  pathgen pocket --polygon 0,0;20,0;20,12;8,12;8,20;0,20 --tool ball:6.35 --grid 3.175,1.5875 \\
      --bezier-z -8,-7,-7,-8,-7,-5,-5,-7,-7,-5,-5,-7,-8,-7,-7,-8 --layers 6 --gcode pmac > pocket.pmc
  pathgen pocket part.chains --surface probe.csv --interp bicubic --tool flat:2 --grid 1,1 --report r.json
  pathgen pocket --polygon ... --tool ball:2 --grid 1,1 --floor-z -2 --strategy offset --svg p.svg
  pathgen pocket --polygon ... --tool ball:2 --grid 1,1 --floor-z -2 --report -     report only

The boundary is the first closed chain of FILE (microcam.chains/1, '-' for
stdin; a warning counts the other closed chains, not pocketed) or --polygon. The bottom is a Bezier patch (--bezier-z, or --surface
FILE.json with {\"x\":[x0,x1],\"y\":[y0,y1],\"z\":[16 heights]}), measured grid
points (--surface FILE.csv, lines x,y,z), or flat (--floor-z). A grid pitch
above D/sqrt(2) is refused unless --force. Output: microcam.toolpath/1 (feeds
in mm/s) or G-code with --gcode; --report writes the JSON report (path
length, cycle time under --machine, thesis scallop and surface-error
estimates, cells, layers, blocks of each final-layer motion). Exit status:
0 ok, 1 failure, 2 bad usage or bad input.";

/// Final-layer motion of the main path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MotionArg {
    Lines,
    ArcLine,
    BezierLine,
}

/// Pocketing strategy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StrategyArg {
    Grid,
    Offset,
}

/// Interpolation of measured points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InterpArg {
    Bilinear,
    Bicubic,
}

/// Pass kinds the preview can be limited to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SvgPass {
    Main,
    Wall,
    XZigzag,
    YZigzag,
    Offset,
}

#[derive(ClapArgs)]
pub struct PocketArgs {
    /// Chains with the boundary ('-' for stdin); or use --polygon.
    file: Option<PathBuf>,
    /// Boundary vertices X,Y;X,Y;... (mm), instead of a chains file.
    #[arg(long, allow_hyphen_values = true)]
    polygon: Option<String>,
    /// Cutter: flat:D, ball:D or torus:D:RC (mm).
    #[arg(long)]
    tool: String,
    /// Grid pitch DX,DY (mm); at most D/sqrt(2) unless --force.
    #[arg(long, value_parser = parse_pair_f64)]
    grid: (f64, f64),
    /// Lower-left corner of the grid (default: the boundary's).
    #[arg(long, value_parser = parse_pair_f64, allow_hyphen_values = true)]
    origin: Option<(f64, f64)>,
    /// Accept a grid pitch above D/sqrt(2) (material is left between centres).
    #[arg(long)]
    force: bool,
    /// Top of the stock (mm).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    top_z: f64,
    /// Clearance height of links (default: top + 1 mm).
    #[arg(long, allow_hyphen_values = true)]
    safe_z: Option<f64>,
    /// Bottom surface: a Bezier patch as JSON (.json) or measured points x,y,z (CSV).
    #[arg(long, value_name = "FILE")]
    surface: Option<PathBuf>,
    /// Bottom surface: 16 Bezier control heights, rows of increasing Y, each of increasing X.
    #[arg(long, allow_hyphen_values = true, value_name = "Z00,...,Z33")]
    bezier_z: Option<String>,
    /// Rectangle of the --bezier-z patch X0,Y0,X1,Y1 (default: the boundary's box).
    #[arg(long, allow_hyphen_values = true)]
    patch: Option<String>,
    /// Flat bottom at this height.
    #[arg(long, allow_hyphen_values = true)]
    floor_z: Option<f64>,
    /// Interpolation of measured points.
    #[arg(long, value_enum, default_value = "bicubic")]
    interp: InterpArg,
    /// Layers of equal depth (the last is the finish layer).
    #[arg(long, default_value_t = 1)]
    layers: usize,
    /// Floors of the roughing layers Z1,Z2,... (mm, descending) instead of --layers.
    #[arg(long, allow_hyphen_values = true)]
    layer_floors: Option<String>,
    /// Finishing feed (mm/s).
    #[arg(long, default_value_t = 2.0)]
    feed: f64,
    /// Roughing feed (mm/s).
    #[arg(long, default_value_t = 3.0)]
    rough_feed: f64,
    /// Plunge feed (mm/s).
    #[arg(long, default_value_t = 0.5)]
    plunge_feed: f64,
    /// Final-layer motion of the main path.
    #[arg(long, value_enum, default_value = "lines")]
    motion: MotionArg,
    /// Largest distance of a grid point from its arc or Bezier (mm).
    #[arg(
        long = "arc-tol",
        alias = "tolerance",
        value_name = "ARC_TOL",
        default_value_t = 0.001
    )]
    tolerance: f64,
    /// Arcs of larger radius become lines (mm).
    #[arg(long, default_value_t = 1000.0)]
    max_radius: f64,
    /// Largest dip of a move below the cutter's touching height (mm).
    #[arg(long, default_value_t = 0.0005)]
    gouge_tol: f64,
    /// grid (the thesis) or offset (contour-parallel).
    #[arg(long, value_enum, default_value = "grid")]
    strategy: StrategyArg,
    /// Offset strategy: distance between loops (default: the smaller grid pitch).
    #[arg(long = "step-over", alias = "stepover", value_name = "STEP_OVER")]
    stepover: Option<f64>,
    /// Machine for the predicted cycle time: micro-mill, laser-stage, lookahead or a profile file.
    #[arg(long, default_value = "micro-mill")]
    machine: String,
    /// Write the JSON report here ('-': stdout, instead of the program).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Draw only this pass kind in the --svg preview.
    #[arg(long, value_enum)]
    svg_pass: Option<SvgPass>,
    #[command(flatten)]
    out: GenOutput,
}

fn numbers(s: &str, what: &str) -> Result<Vec<f64>, CliError> {
    s.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| CliError::input(format!("{what}: '{t}' is not a finite number")))
        })
        .collect()
}

fn boundary(a: &PocketArgs) -> Result<Polyline<f64>, CliError> {
    if let Some(p) = &a.polygon {
        if a.file.is_some() {
            return Err(CliError::input("give a chains FILE or --polygon, not both"));
        }
        let mut pl = Polyline::new_closed();
        for v in p.split(';').filter(|s| !s.trim().is_empty()) {
            let (x, y) = parse_pair_f64(v).map_err(|e| CliError::input(format!("--polygon: {e}")))?;
            pl.add(x, y, 0.0);
        }
        if pl.vertex_count() < 3 {
            return Err(CliError::input("--polygon needs at least three vertices"));
        }
        return Ok(pl);
    }
    let input = cli::open_input(a.file.as_deref())?;
    let name = input.name.clone();
    let (_, chains) = read_chains(input.reader).map_err(|e| CliError::in_file(&name, e))?;
    let c = chains
        .iter()
        .find(|c| c.closed)
        .ok_or_else(|| CliError::input(format!("{name}: no closed chain to pocket")))?;
    // One region a run: say so when the file holds more, rather than
    // leave the others uncut without a word.
    let others = chains.iter().filter(|c| c.closed).count() - 1;
    if others > 0 {
        microcam::diag!(
            "pathgen: pocket: {name}: warning: pocketing chain {} (the first closed chain); {others} other closed chain{} not pocketed (one region a run: split the file, e.g. with jq, to pocket each)",
            c.id,
            if others == 1 { " is" } else { "s are" }
        );
    }
    Ok(microcam::laser::offset::to_polyline(c))
}

fn surface(a: &PocketArgs, pl: &Polyline<f64>) -> Result<Surface, CliError> {
    let given = [a.surface.is_some(), a.bezier_z.is_some(), a.floor_z.is_some()];
    if given.iter().filter(|g| **g).count() != 1 {
        return Err(CliError::input("give exactly one of --surface, --bezier-z, --floor-z"));
    }
    let bad = |e: microcam::pocket::PocketError| CliError::input(e.to_string());
    if let Some(z) = a.floor_z {
        return Ok(Surface::Flat(z));
    }
    if let Some(z) = &a.bezier_z {
        let z = numbers(z, "--bezier-z")?;
        let rect = match &a.patch {
            Some(p) => {
                let v = numbers(p, "--patch")?;
                if v.len() != 4 {
                    return Err(CliError::input("--patch needs X0,Y0,X1,Y1"));
                }
                [v[0], v[1], v[2], v[3]]
            }
            None => {
                let g = grid::polygonize(pl);
                let f = |sel: fn(&P2) -> f64, min: bool| {
                    g.iter()
                        .map(sel)
                        .fold(if min { f64::INFINITY } else { f64::NEG_INFINITY }, |a, b| {
                            if min { a.min(b) } else { a.max(b) }
                        })
                };
                [f(|p| p.x, true), f(|p| p.y, true), f(|p| p.x, false), f(|p| p.y, false)]
            }
        };
        return BezierPatch::new([rect[0], rect[2]], [rect[1], rect[3]], &z)
            .map(Surface::Bezier)
            .map_err(bad);
    }
    let path = a.surface.as_ref().expect("one of three given");
    let text = std::fs::read_to_string(path).map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    let name = path.display().to_string();
    if path.extension().is_some_and(|e| e == "json") {
        BezierPatch::from_json(&text)
            .map(Surface::Bezier)
            .map_err(|e| CliError::input(format!("{name}: {e}")))
    } else {
        let interp = match a.interp {
            InterpArg::Bilinear => Interp::Bilinear,
            InterpArg::Bicubic => Interp::Bicubic,
        };
        GridSurface::from_csv(&text, interp)
            .map(Surface::Grid)
            .map_err(|e| CliError::input(format!("{name}: {e}")))
    }
}

/// Run `pathgen pocket`.
pub fn run(a: PocketArgs) -> Result<(), CliError> {
    let cutter = Cutter::parse(&a.tool).map_err(|e| CliError::input(format!("--tool {e}")))?;
    let pl = boundary(&a)?;
    let surface = surface(&a, &pl)?;
    let machine = Machine::load(&a.machine).map_err(|e| CliError::input(format!("--machine {e}")))?;
    let layers = match &a.layer_floors {
        Some(f) => Layers::Floors(numbers(f, "--layer-floors")?),
        None => Layers::Count(a.layers),
    };
    let spec = PocketSpec {
        boundary: pl.clone(),
        surface,
        cutter,
        top_z: a.top_z,
        dx: a.grid.0,
        dy: a.grid.1,
        origin: a.origin.map(|(x, y)| P2::new(x, y)),
        layers,
        feeds: Feeds {
            rough: a.rough_feed,
            finish: a.feed,
            plunge: a.plunge_feed,
            safe_z: a.safe_z.unwrap_or(a.top_z + 1.0),
        },
        motion: match a.motion {
            MotionArg::Lines => MotionMode::Lines,
            MotionArg::ArcLine => MotionMode::ArcLine,
            MotionArg::BezierLine => MotionMode::BezierLine,
        },
        fit: FitOptions {
            tol: a.tolerance,
            max_radius: a.max_radius,
        },
        gouge_tol: a.gouge_tol,
        strategy: match a.strategy {
            StrategyArg::Grid => Strategy::Grid,
            StrategyArg::Offset => Strategy::Offset,
        },
        stepover: a.stepover.unwrap_or(a.grid.0.min(a.grid.1)),
        force: a.force,
        machine,
    };
    // The cutter's touching heights on a freeform bottom are the work
    // (seconds to minutes at a fine grid); how many a job needs is not known
    // ahead, so the display counts them, stage by stage, without a total.
    let meter = a.out.meter("pocket", 0);
    let job = plan(&spec).map_err(|e| match e {
        microcam::pocket::PocketError::Time(m) => CliError::failure(m),
        e => CliError::input(e.to_string()),
    });
    meter.finish();
    let job = job?;
    if let Some(path) = &a.out.svg {
        let only = a.svg_pass.map(|k| match k {
            SvgPass::Main => PassKind::Main,
            SvgPass::Wall => PassKind::Wall,
            SvgPass::XZigzag => PassKind::XZigzag,
            SvgPass::YZigzag => PassKind::YZigzag,
            SvgPass::Offset => PassKind::Offset,
        });
        let mut svg = Output::new(Some(path));
        microcam::pocket::svg::write_svg(&mut svg, &job.program, &grid::polygonize(&pl), only)?;
        svg.commit()?;
    }
    let report_stdout = a.report.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if let Some(path) = a.report.as_ref().filter(|_| !report_stdout) {
        let mut r = Output::new(Some(path));
        writeln!(r, "{}", job.figures.to_json())?;
        r.commit()?;
    }
    let mut out = Output::new(a.out.output.as_deref());
    if report_stdout {
        writeln!(out, "{}", job.figures.to_json())?;
    } else {
        let source = a
            .file
            .as_ref()
            .map(|p| p.display().to_string())
            .or(Some("pocket".into()));
        write_records(job.program.records.iter().cloned(), &a.out, source, &mut out)?;
    }
    out.commit()
}
