//! stlverify: simulate 3- or 5-axis cutter locations on a tri-dexel stock,
//! write the machined part, and verify it against the design (Singh 2014).

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::{Parser, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::cutter::Cutter;
use microcam::dexel::tool::ToolShape;
use microcam::geometry::P3;
use microcam::mesh::read::{ReadOptions as MeshOptions, read_path};
use microcam::progress::{Meter, Show};
use microcam::sim::picture::write_png;
use microcam::sim::stl::{Heights, write_heights_stl};
use microcam::source::ToolpathSource;
use microcam::verify::compare::{Design, Sample, Stats, points_csv, profiles_csv, sample, steps};
use microcam::verify::{VerifyJob, cl, plot, simulate};
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  stlverify --stock 0,0,-40,25,50,0 --tool flat:6 --flute-length 10 cl.txt
  stlverify --stock 0,0,-40,25,50,0 --tool flat:6 --flute-length 10 \\
      --stl part.stl --design design.stl --region 0,4,10,30 \\
      --step-forward 0.1 --step-over 0.25 --band 0.1 --svg map.svg cl5.txt
  stlverify --stock -2,-5,-2,14,2,0 --tool ball:2 --format gcode prog.ngc
  stlverify ... --design d.stl --profile-y 10 --profile-y 20 \\
      --profiles prof.csv --profiles-svg prof.svg cl.txt

CL data: one location per line, 'x y z' (tool along +Z) or 'x y z x1 y1 z1'
(a second point on the tool axis towards the holder), the layouts of Singh
2014's Annexures 1 and 2; header lines, blank lines, '#' comments and a
leading row number are skipped. With --format gcode (or a .nc/.ngc/.gcode/
.tap/.pmc/.cnc file) the program's moves are read (3-axis; arcs as chords).

Every move removes the volume the tool sweeps (exact for a fixed axis; a
turning axis is split so no tool point is off by more than --sweep-tol).
With --design, vertical rays on the grid over --region compare the tops:
deviation = machined - design, > +band is excess material (under-cut),
< -band a gouge (over-cut). The report (JSON, microcam.stlverify/1) goes to
stdout or -o. Exit status: 0 ok, 1 points outside the band or a failure,
2 bad usage or bad input (the message names the file and line).";

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Format {
    /// CL data text (3- or 5-axis).
    Cl,
    /// G-code (ISO or Turbo PMAC) through the program interpreter.
    Gcode,
}

/// Simulate cutter locations and verify the machined part against a design.
#[derive(Parser)]
#[command(name = "stlverify", version, about, after_help = EXAMPLES)]
struct Args {
    /// CL data or program ('-' for stdin).
    file: Option<PathBuf>,
    /// No progress bar on stderr (warnings and errors still appear).
    #[arg(short, long)]
    quiet: bool,
    /// Input format (default: from the extension, else CL data).
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Stock box, mm: X0,Y0,Z0,X1,Y1,Z1.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    stock: String,
    /// Cutter: flat:D, ball:D or torus:D:RC (mm).
    #[arg(long)]
    tool: String,
    /// Flute length L: the tool's cutting part above the tip, mm (default
    /// 3 x diameter).
    #[arg(long)]
    flute_length: Option<f64>,
    /// Dexel spacing, mm (default: tool diameter / 40).
    #[arg(long)]
    spacing: Option<f64>,
    /// Largest distance between the true swept volume and the one cut
    /// (turning axes, torus corners), mm (default: spacing / 2). With
    /// --design, a torus corner is held to a tenth of --band as well.
    #[arg(long)]
    sweep_tol: Option<f64>,
    /// Write the machined part as binary STL.
    #[arg(long, value_name = "FILE.stl")]
    stl: Option<PathBuf>,
    /// Merge tolerance of the STL: squares within this of a plane become
    /// one piece, mm (default: spacing / 4, so at most half a cell off).
    #[arg(long)]
    stl_tol: Option<f64>,
    /// Design part (STL or OBJ) to verify against.
    #[arg(long, value_name = "FILE")]
    design: Option<PathBuf>,
    /// Region of the verification grid, mm: X0,X1,Y0,Y1 (default: the stock).
    #[arg(long, value_name = "X0,X1,Y0,Y1", allow_hyphen_values = true)]
    region: Option<String>,
    /// Ray spacing along X, mm.
    #[arg(long, default_value_t = 0.1)]
    step_forward: f64,
    /// Ray spacing along Y, mm.
    #[arg(long, default_value_t = 0.25)]
    step_over: f64,
    /// Tolerance band, ± mm.
    #[arg(long, default_value_t = 0.1)]
    band: f64,
    /// A scallop profile along X at this Y (repeatable).
    #[arg(long, value_name = "Y", allow_hyphen_values = true)]
    profile_y: Vec<f64>,
    /// Every grid ray as CSV (x, y, design and machined tops, deviation).
    #[arg(long, value_name = "FILE.csv")]
    points: Option<PathBuf>,
    /// Profiles as CSV.
    #[arg(long, value_name = "FILE.csv")]
    profiles: Option<PathBuf>,
    /// Profiles as an SVG plot.
    #[arg(long, value_name = "FILE.svg")]
    profiles_svg: Option<PathBuf>,
    /// Deviation map as SVG.
    #[arg(long, value_name = "FILE.svg")]
    svg: Option<PathBuf>,
    /// Deviation map as PNG.
    #[arg(long, value_name = "FILE.png")]
    png: Option<PathBuf>,
    /// Write the report here instead of stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("stlverify", || run(args))
}
fn positive(v: f64, opt: &str) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!("{opt} must be positive")))
    }
}

fn is_program(p: Option<&Path>) -> bool {
    let ext = p
        .and_then(|p| p.extension())
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    matches!(ext.as_deref(), Some("nc" | "ngc" | "gcode" | "tap" | "pmc" | "cnc"))
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    let mut o = Output::new(Some(path));
    o.write_all(bytes)?;
    o.commit()
}

fn run(args: Args) -> Result<(), CliError> {
    let cutter = Cutter::parse(&args.tool).map_err(|e| CliError::input(format!("--tool: {e}")))?;
    let length = positive(args.flute_length.unwrap_or(3.0 * cutter.diameter()), "--flute-length")?;
    let spacing = positive(args.spacing.unwrap_or(cutter.diameter() / 40.0), "--spacing")?;
    let sweep_tol = positive(args.sweep_tol.unwrap_or(spacing / 2.0), "--sweep-tol")?;
    let stl_tol = args.stl_tol.unwrap_or(spacing / 4.0);
    if !(stl_tol.is_finite() && stl_tol >= 0.0) {
        return Err(CliError::input("--stl-tol must be zero or positive"));
    }
    let b = microcam::cli::parse_numbers::<6>(&args.stock, "--stock", "X0,Y0,Z0,X1,Y1,Z1")?;
    let (smin, smax) = (P3::new(b[0], b[1], b[2]), P3::new(b[3], b[4], b[5]));
    let band = args.band;
    if !(band.is_finite() && band >= 0.0) {
        return Err(CliError::input("--band must be zero or positive"));
    }
    positive(args.step_forward, "--step-forward")?;
    if args.design.is_none()
        && (args.svg.is_some()
            || args.png.is_some()
            || args.profiles.is_some()
            || args.profiles_svg.is_some()
            || args.points.is_some())
    {
        return Err(CliError::input("--svg, --png and --profiles need --design"));
    }
    positive(args.step_over, "--step-over")?;
    let format = args.format.unwrap_or(if is_program(args.file.as_deref()) {
        Format::Gcode
    } else {
        Format::Cl
    });
    // With a design, what the simulation's own approximations may take:
    // a tenth of the band (arcs' chords and a torus corner's ring, both
    // of which would otherwise read as the part's gouge or excess); a
    // band of 0 leaves them to the spacing.
    let band_tenth = (args.design.is_some() && band > 0.0).then_some(0.1 * band);
    let input = cli::open_input(args.file.as_deref())?;
    let name = input.name.clone();
    let (locations, five_axis) = match format {
        Format::Cl => cl::read_cl(input.reader).map_err(|e| CliError::in_file(&name, e))?,
        Format::Gcode => {
            let src = ToolpathSource::open(input, &cl::program_options())?;
            // Arcs as chords: within a quarter of the spacing and the band's
            // tenth (a chord cuts a convex arc's inside by its sag).
            let sag = band_tenth.map_or(0.25 * spacing, |b| b.min(0.25 * spacing));
            let v = cl::program_locations(src, sag).map_err(|e| CliError::in_file(&name, e))?;
            (v, false)
        }
    };
    let tool = ToolShape { cutter, length };
    let job = VerifyJob {
        stock_min: smin,
        stock_max: smax,
        tool,
        spacing,
        sweep_tol,
        // The ring leaves material, which would read as excess when the
        // band is near the spacing.
        ring_tol: band_tenth,
        locations,
    };
    let meter = Meter::start(
        "stlverify",
        "cutting (tile, move) pairs",
        0,
        Show::from_flags(args.quiet, false),
    );
    let sim = simulate(&job).map_err(|e| CliError::input(format!("--stock/--spacing: {e}")))?;
    meter.finish();
    let vols = sim.dexels.volumes();
    let bv = sim.dexels.box_volume();
    let buried = job
        .locations
        .iter()
        .filter(|l| {
            let top = l.tip + l.axis * length;
            top.z < smax.z && (smin.x..=smax.x).contains(&top.x) && (smin.y..=smax.y).contains(&top.y)
        })
        .count();
    let mut report = json!({
        "schema": "microcam.stlverify/1",
        "input": if name == "<stdin>" { serde_json::Value::Null } else { json!(name) },
        "locations": job.locations.len(),
        "five_axis": five_axis,
        "tool": {"cutter": cutter.to_string(), "radius_mm": cutter.radius(),
                 "corner_radius_mm": cutter.corner_radius(), "flute_length_mm": length},
        "stock_mm": [b[0], b[1], b[2], b[3], b[4], b[5]],
        "stock_volume_mm3": bv,
        "dexel_spacing_mm": spacing,
        "dexels": sim.dexels.dexel_count(),
        "dexel_memory_bytes": sim.dexels.bytes(),
        "sub_moves": sim.sub_moves,
        "sweep_shape_error_mm": sim.shape_error_mm,
        "ray_move_tests": sim.stats.ray_tests,
        "ray_submove_tests": sim.stats.fine_tests,
        "removed_volume_mm3": bv - vols[2],
        "removed_volume_by_family_mm3": {"x": bv - vols[0], "y": bv - vols[1], "z": bv - vols[2]},
        "locations_flute_top_below_stock_top": buried,
    });
    if let Some(p) = args.stl.as_deref() {
        let h = sim.dexels.heights();
        let hf = Heights {
            x0: h.x0,
            y0: h.y0,
            dx: h.dx,
            dy: h.dy,
            nx: h.nx,
            ny: h.ny,
            z: &h.z,
            bottom: h.bottom,
        };
        let mut o = Output::new(Some(p));
        let st = write_heights_stl(&hf, stl_tol, "microcam stlverify machined part (mm)", &mut o)
            .map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?;
        o.commit()?;
        report["stl"] = json!({
            "triangles": st.triangles, "per_cell_triangles": st.per_cell_triangles,
            "pieces": st.pieces, "max_deviation_bound_mm": st.max_deviation_bound_mm,
        });
    }
    let mut failed = false;
    if let Some(dp) = args.design.as_deref() {
        let loaded =
            read_path(dp, &MeshOptions::default()).map_err(|e| CliError::in_file(&dp.display().to_string(), e))?;
        let design = Design::new(&loaded.mesh);
        let r = match args.region.as_deref() {
            Some(s) => microcam::cli::parse_numbers::<4>(s, "--region", "X0,X1,Y0,Y1")?,
            None => [smin.x, smax.x, smin.y, smax.y],
        };
        if !(r[0] <= r[1] && r[2] <= r[3]) {
            return Err(CliError::input("--region: X0 <= X1 and Y0 <= Y1"));
        }
        let xs = steps(r[0], r[1], args.step_forward);
        let ys = steps(r[2], r[3], args.step_over);
        // The machined top at each point is cut exactly by the moves near
        // it: at fine steps that takes longer than the cut itself.
        let meter = Meter::start(
            "stlverify",
            "comparing points with the design",
            (xs.len() * ys.len()) as u64,
            Show::from_flags(args.quiet, false),
        );
        let samples = sample(&sim, &design, &xs, &ys);
        meter.finish();
        let st = Stats::of(&samples, band);
        failed = !st.passed();
        let profiles: Vec<(f64, Vec<Sample>)> = args
            .profile_y
            .iter()
            .map(|&y| (y, sample(&sim, &design, &xs, &[y])))
            .collect();
        report["verification"] = json!({
            "design": dp.display().to_string(),
            "design_triangles": loaded.mesh.triangles.len(),
            "design_notes": loaded.notes,
            "region_mm": r, "step_forward_mm": args.step_forward, "step_over_mm": args.step_over,
            "band_mm": band, "points": st.points, "not_compared": st.not_compared,
            "in_band": st.in_band, "excess": st.excess, "gouge": st.gouge,
            "max_excess_mm": st.max_excess_mm, "max_gouge_mm": st.max_gouge_mm,
            "rms_mm": st.rms_mm, "mean_mm": st.mean_mm, "passed": st.passed(),
            "profiles": profiles.iter().map(|(y, v)| {
                let s = Stats::of(v, band);
                json!({"y_mm": y, "points": v.len(), "max_excess_mm": s.max_excess_mm,
                       "max_gouge_mm": s.max_gouge_mm, "rms_mm": s.rms_mm})
            }).collect::<Vec<_>>(),
        });
        if let Some(p) = args.points.as_deref() {
            write_file(p, points_csv(&samples).as_bytes())?;
        }
        if let Some(p) = args.profiles.as_deref() {
            write_file(p, profiles_csv(&profiles).as_bytes())?;
        }
        if let Some(p) = args.profiles_svg.as_deref() {
            write_file(p, plot::profiles_svg(&profiles, band).as_bytes())?;
        }
        if let Some(p) = args.svg.as_deref() {
            write_file(
                p,
                plot::map_svg(&samples, &xs, &ys, band, "stlverify deviation map").as_bytes(),
            )?;
        }
        if let Some(p) = args.png.as_deref() {
            let (w, h, rgb) = plot::map_rgb(&samples, &xs, &ys, band);
            let mut o = Output::new(Some(p));
            write_png(&mut o, w, h, &rgb).map_err(|e| CliError::failure(format!("{}: {e}", p.display())))?;
            o.commit()?;
        }
    }
    let mut out = Output::new(args.output.as_deref());
    writeln!(
        out,
        "{}",
        serde_json::to_string_pretty(&report).map_err(|e| CliError::failure(e.to_string()))?
    )?;
    out.commit()?;
    if failed {
        return Err(CliError::verdict("points outside the tolerance band (see the report)"));
    }
    Ok(())
}
