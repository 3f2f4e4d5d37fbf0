//! probescan: automated scanning with a rotating wire probe against a
//! simulated part, and the measurements it gives (Bayesteh 2013, ch. 4).

// Diagnostics go through `microcam::diag!` and data through the
// library's writers: `eprintln!`/`println!` panic when stderr or stdout
// is a closed pipe.
#![deny(clippy::print_stderr, clippy::print_stdout)]

use clap::{Parser, ValueEnum};
use microcam::cli::{self, CliError, Output};
use microcam::formats::read_chains;
use microcam::geometry::{P2, V2};
use microcam::probe::job::{self, Measure, ProbeJob};
use microcam::probe::noise::NoiseModel;
use microcam::probe::part::Part;
use microcam::probe::program::{self, ControllerSettings, Dialect};
use microcam::probe::scan::{ScanParams, Stop};
use microcam::probe::tip::Probe;
use microcam::probe::{report, svg};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  probescan --circle 12.7 --points 100                      plug gauge: diameter, centre, roundness (LSQ and minimum zone)
  probescan --gauge 9.525 --face-points 10                  gauge block width from a fitted face and one opposite touch
  dxf2chains part.dxf | probescan --step 0.2 --svg scan.svg deviation from the design, what the probe cannot reach
  probescan --circle 12.7 --noise 0.0005 --quantise --seed 3 --csv pts.csv
  probescan --circle 12.7 --program scan.pmc --dialect pmac the same scan as a Turbo PMAC program
  probescan part.chains --start 5,-2 --dir 0,1 --program scan.ngc --dialect iso

The probe: --de gives D_e directly, or --wire-length and --bend-deg give
D_e = 2 L sin(beta). It touches once per revolution, so a contact is known
to within feed/rpm along the approach (reported as touch_resolution_mm).
The scan takes two contacts along --dir (the second R_s to the left of the
first), then steps R_s (--step) along the line through the last two
contacts, backs off R_o (--offset) and approaches along its normal, until it
is back at the first contact. All moves are guarded: a touch on any move is
a contact. Convex corners are found by searching back from a missed
approach.

The report (JSON, stdout or -o) carries every figure with its unit in its
name; uncertainties are given as standard uncertainties (u_..._mm) and as
99 % intervals (u99_..._mm, k = 2.576). Contacts (--csv) are
probe centres with the compensated surface point. Noise: --noise (sigma,
mm), --delay (trigger delay, s), --quantise (once-per-revolution touch);
their mean over-travel is removed as a calibrated D_e would remove it.

Exit status: 0 ok, 1 the scan did not close (lost surface, contact limit,
no progress; --partial writes the outputs anyway), 2 bad usage or input.";

#[derive(Clone, Copy, ValueEnum)]
enum DialectArg {
    Pmac,
    Iso,
}

#[derive(Clone, Copy, ValueEnum, PartialEq)]
enum FitArg {
    None,
    Circle,
}

/// Scan a simulated part with a rotating wire probe and measure it.
#[derive(Parser)]
#[command(name = "probescan", version, about, after_help = EXAMPLES)]
struct Args {
    /// Chains (microcam.chains/1, dxf2chains output) of the part ('-' for stdin).
    file: Option<PathBuf>,
    /// Simulate a round plug of this diameter (mm) instead.
    #[arg(long, value_name = "D", conflicts_with_all = ["file", "gauge"])]
    circle: Option<f64>,
    /// Centre of --circle (mm).
    #[arg(long, value_name = "X,Y", default_value = "0,0", allow_hyphen_values = true)]
    center: String,
    /// Simulate a gauge block of this width (mm, along X) and measure it.
    #[arg(long, value_name = "W", conflicts_with = "file")]
    gauge: Option<f64>,
    /// Length of the gauge block's face (mm, along Y).
    #[arg(long, value_name = "L", default_value_t = 9.0)]
    gauge_length: f64,
    /// Contacts on the gauge block's first face.
    #[arg(long, value_name = "N", default_value_t = 10)]
    face_points: usize,
    /// Compare with this design (chains) instead of the simulated part.
    #[arg(long, value_name = "FILE")]
    design: Option<PathBuf>,
    /// Also fit a circle to the contacts of a chains part.
    #[arg(long, value_enum, default_value_t = FitArg::None)]
    fit: FitArg,
    /// Effective probe diameter D_e (mm).
    #[arg(long, value_name = "MM", conflicts_with = "wire_length")]
    de: Option<f64>,
    /// Wire length L (mm): D_e = 2 L sin(beta).
    #[arg(long, value_name = "MM")]
    wire_length: Option<f64>,
    /// Wire bend angle beta (degrees).
    #[arg(long, value_name = "DEG", default_value_t = 45.0)]
    bend_deg: f64,
    /// Spindle speed (rev/min).
    #[arg(long, default_value_t = 30000.0)]
    rpm: f64,
    /// Approach feed f_p (mm/s).
    #[arg(long, value_name = "MM_S", default_value_t = 0.05)]
    feed: f64,
    /// Step along the surface R_s (mm).
    #[arg(long, value_name = "MM", default_value_t = 0.2)]
    step: f64,
    /// Back-off from the surface R_o (mm).
    #[arg(long, value_name = "MM", default_value_t = 0.1)]
    offset: f64,
    /// For --circle: choose the step for about N contacts round it.
    #[arg(long, value_name = "N", conflicts_with = "step")]
    points: Option<usize>,
    /// Start of the probe centre (mm); default: left of the part, mid-height.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true)]
    start: Option<String>,
    /// Initial approach direction.
    #[arg(long, value_name = "DX,DY", default_value = "1,0", allow_hyphen_values = true)]
    dir: String,
    /// Stop after this many contacts.
    #[arg(long, value_name = "N", default_value_t = 5000)]
    max_points: usize,
    /// Longest initial approach (mm).
    #[arg(long, value_name = "MM", default_value_t = 5.0)]
    max_approach: f64,
    /// Touch scatter, standard deviation (mm).
    #[arg(long, value_name = "MM", default_value_t = 0.0)]
    noise: f64,
    /// Trigger delay (s).
    #[arg(long, value_name = "S", default_value_t = 0.0)]
    delay: f64,
    /// Touch once per revolution (the contact lags by up to feed/rpm).
    #[arg(long)]
    quantise: bool,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the report here instead of stdout.
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
    /// Write the contacts as CSV here.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// Write a picture of the scan here.
    #[arg(long, value_name = "FILE")]
    svg: Option<PathBuf>,
    /// Deviation exaggeration in the picture (default: automatic).
    #[arg(long, value_name = "K")]
    exaggerate: Option<f64>,
    /// Write the probing program for the machine here.
    #[arg(long, value_name = "FILE")]
    program: Option<PathBuf>,
    /// Dialect of --program.
    #[arg(long, value_enum, default_value_t = DialectArg::Pmac)]
    dialect: DialectArg,
    /// Encoder counts per mm of the X and Y motors (PMAC program).
    #[arg(long, default_value_t = 5000.0)]
    counts_per_mm: f64,
    /// Write the outputs even when the scan did not close (exit 0).
    #[arg(long)]
    partial: bool,
}

fn main() -> ExitCode {
    let args = microcam::cli::parse::<Args>();
    cli::run("probescan", || run(args))
}

fn pair(s: &str, name: &str) -> Result<(f64, f64), CliError> {
    let v: Vec<&str> = s.split(',').map(str::trim).collect();
    let parse = |t: &str| t.parse::<f64>().ok().filter(|x| x.is_finite());
    match v.as_slice() {
        [a, b] => match (parse(a), parse(b)) {
            (Some(a), Some(b)) => Ok((a, b)),
            _ => Err(CliError::input(format!("{name}: expected two numbers X,Y, got '{s}'"))),
        },
        _ => Err(CliError::input(format!("{name}: expected two numbers X,Y, got '{s}'"))),
    }
}

fn read_part(path: Option<&Path>) -> Result<Part, CliError> {
    let input = cli::open_input(path)?;
    let name = input.name.clone();
    let (_, chains) = read_chains(input.reader).map_err(|e| CliError::in_file(&name, e))?;
    Part::from_chains(&chains).map_err(|e| CliError::input(format!("{name}: {e}")))
}

fn bad(e: impl std::fmt::Display) -> CliError {
    CliError::input(e.to_string())
}

fn run(a: Args) -> Result<(), CliError> {
    let probe = match a.wire_length {
        Some(l) => Probe::from_wire(l, a.bend_deg, a.rpm, a.feed),
        None => Probe::new(a.de.unwrap_or(0.1), a.rpm, a.feed),
    }
    .map_err(bad)?;
    let re = probe.radius();
    let noise = NoiseModel {
        sigma_mm: a.noise,
        delay_s: a.delay,
        quantise: a.quantise,
    };
    noise.check().map_err(bad)?;
    if !(a.counts_per_mm.is_finite() && a.counts_per_mm > 0.0) {
        return Err(CliError::input(format!(
            "--counts-per-mm: must be a positive number, got {}",
            a.counts_per_mm
        )));
    }
    let (dx, dy) = pair(&a.dir, "--dir")?;
    let start = a.start.as_deref().map(|s| pair(s, "--start")).transpose()?;
    let mut params = ScanParams {
        step_mm: a.step,
        offset_mm: a.offset,
        start: P2::origin(),
        dir: V2::new(dx, dy),
        max_points: a.max_points,
        max_approach_mm: a.max_approach,
    };
    let (part, measure) = if let Some(w) = a.gauge {
        let (part, p) = job::gauge_params(w, a.gauge_length, a.face_points, a.step, a.offset, re).map_err(bad)?;
        params = ScanParams {
            max_approach_mm: a.max_approach,
            ..p
        };
        (
            part,
            Measure::Width {
                nominal_mm: w,
                face_points: a.face_points,
            },
        )
    } else if let Some(d) = a.circle {
        if !(d.is_finite() && d > 0.0) {
            return Err(CliError::input(format!(
                "--circle: must be a positive diameter, got {d}"
            )));
        }
        let (cx, cy) = pair(&a.center, "--center")?;
        if let Some(n) = a.points {
            params.step_mm = job::step_for_points(d / 2.0 + re, n);
        }
        (Part::circle(P2::new(cx, cy), d), Measure::Circle)
    } else {
        if a.points.is_some() {
            return Err(CliError::input("--points: only with --circle"));
        }
        let part = read_part(a.file.as_deref())?;
        let m = if a.fit == FitArg::Circle {
            Measure::Circle
        } else {
            Measure::Contour
        };
        (part, m)
    };
    if a.gauge.is_none() {
        params.start = match start {
            Some((x, y)) => P2::new(x, y),
            None => default_start(&part, re, a.offset),
        };
    } else if let Some((x, y)) = start {
        params.start = P2::new(x, y);
    }
    let design = match &a.design {
        Some(p) => read_part(Some(p))?,
        None => part.clone(),
    };
    let job = ProbeJob {
        part,
        design,
        probe,
        noise,
        params,
        measure,
        seed: a.seed,
    };
    let out = job::run(&job).map_err(bad)?;
    let closed = out.scan.stop == Stop::Closed;
    let gauge_done = a.gauge.is_some() && matches!(out.scan.stop, Stop::MaxPoints(_));
    if !closed && !gauge_done && !a.partial {
        return Err(CliError::failure(format!(
            "{} ({} contacts); nothing written (--partial writes the outputs anyway)",
            out.scan.stop.message(),
            out.scan.contacts.len()
        )));
    }
    if !closed && !gauge_done {
        microcam::diag!("probescan: warning: {}", out.scan.stop.message());
    }
    let cov = &out.coverage;
    if let Some(l) = cov
        .unreachable
        .iter()
        .max_by(|x, y| x.length_mm.total_cmp(&y.length_mm))
    {
        microcam::diag!(
            "probescan: {} stretch(es) of the design are out of reach of a {} mm probe (corners and gaps narrower than D_e); longest {:.4} mm from ({:.4}, {:.4}) to ({:.4}, {:.4})",
            cov.unreachable.len(),
            probe.effective_diameter_mm,
            l.length_mm,
            l.from.x,
            l.from.y,
            l.to.x,
            l.to.y
        );
    }
    if !cov.missed.is_empty() && closed {
        microcam::diag!(
            "probescan: warning: {} design piece(s) longer than R_s got no contact: {:?}",
            cov.missed.len(),
            cov.missed
        );
    }
    let mut outputs = Vec::new();
    let mut put = |path: &Path, text: String| -> Result<(), CliError> {
        let mut o = Output::new(Some(path));
        o.write_all(text.as_bytes())?;
        outputs.push(o);
        Ok(())
    };
    if let Some(p) = &a.csv {
        put(p, report::csv(&out))?;
    }
    if let Some(p) = &a.svg {
        put(p, svg::render(&job.design, &out, re, a.exaggerate))?;
    }
    if let Some(p) = &a.program {
        let d = match a.dialect {
            DialectArg::Pmac => Dialect::Pmac,
            DialectArg::Iso => Dialect::Iso,
        };
        let machine = ControllerSettings {
            counts_per_mm: a.counts_per_mm,
            ..ControllerSettings::default()
        };
        put(p, program::write(d, &probe, &job.params, &machine))?;
    }
    let mut main = Output::new(a.output.as_deref());
    main.write_all(report::json(&job, &out).as_bytes())?;
    for o in outputs {
        o.commit()?;
    }
    main.commit()
}

/// Left of the part's bounding box at mid-height, clear by 2 R_o, pointing
/// right.
fn default_start(part: &Part, re: f64, ro: f64) -> P2 {
    let (mut xmin, mut ymin, mut ymax) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in &part.prims {
        let len = p.length();
        for i in 0..=16 {
            let q = p.at(len * i as f64 / 16.0);
            xmin = xmin.min(q.x);
            ymin = ymin.min(q.y);
            ymax = ymax.max(q.y);
        }
    }
    P2::new(xmin - re - 2.0 * ro, (ymin + ymax) / 2.0)
}
