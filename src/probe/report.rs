//! The contact CSV and the report JSON (`microcam.probescan/1`); every
//! figure carries its unit in its name. Uncertainties come twice: the
//! standard uncertainty (`u_..._mm`, k = 1) and the 99 % interval of a
//! normal estimate (`u99_..._mm`, k = 2.576).

use super::job::{Outcome, ProbeJob};
use super::measure::K99;
use crate::geometry::P2;
use serde::Serialize;

/// Schema name of the report.
pub const SCHEMA: &str = "microcam.probescan/1";

/// Round to 0.1 pm so printing round-off never shows as a figure.
fn r(x: f64) -> f64 {
    let y = (x * 1e10).round() / 1e10;
    if y == 0.0 { 0.0 } else { y }
}

fn rp(p: P2) -> [f64; 2] {
    [r(p.x), r(p.y)]
}

#[derive(Serialize)]
struct ProbeR {
    effective_diameter_mm: f64,
    rpm: f64,
    feed_mm_s: f64,
    touch_resolution_mm: f64,
}

#[derive(Serialize)]
struct NoiseR {
    sigma_mm: f64,
    trigger_delay_s: f64,
    quantise: bool,
    seed: u64,
    bias_removed_mm: f64,
    u_point_mm: f64,
}

#[derive(Serialize)]
struct ScanR {
    step_mm: f64,
    offset_mm: f64,
    start_mm: [f64; 2],
    direction: [f64; 2],
    contacts: usize,
    moves: usize,
    path_length_mm: f64,
    stop: &'static str,
    stop_message: String,
}

#[derive(Serialize)]
struct CircleR {
    kind: &'static str,
    diameter_lsq_mm: f64,
    center_lsq_mm: [f64; 2],
    roundness_lsq_mm: f64,
    diameter_mz_mm: f64,
    center_mz_mm: [f64; 2],
    roundness_mz_mm: f64,
    u_diameter_mm: f64,
    u99_diameter_mm: f64,
    u_center_mm: [f64; 2],
    u99_center_mm: [f64; 2],
}

#[derive(Serialize)]
struct WidthR {
    width_mm: f64,
    u_width_mm: f64,
    u99_width_mm: f64,
    face_points: usize,
    straightness_mm: f64,
    other_face_contact_mm: [f64; 2],
}

#[derive(Serialize)]
struct DeviationR {
    max_mm: f64,
    min_mm: f64,
    rms_mm: f64,
    u_max_mm: f64,
}

#[derive(Serialize)]
struct StretchR {
    from_mm: [f64; 2],
    to_mm: [f64; 2],
    length_mm: f64,
}

#[derive(Serialize)]
struct CoverageR {
    pieces_touched: usize,
    missed_pieces: Vec<usize>,
    unreachable: Vec<StretchR>,
}

#[derive(Serialize)]
struct ProbeReport {
    schema: &'static str,
    probe: ProbeR,
    noise: NoiseR,
    scan: ScanR,
    #[serde(skip_serializing_if = "Option::is_none")]
    circle: Option<CircleR>,
    #[serde(skip_serializing_if = "Option::is_none")]
    width: Option<WidthR>,
    deviation: DeviationR,
    coverage: CoverageR,
}

/// The report JSON, pretty-printed, ending in a newline.
pub fn json(job: &ProbeJob, out: &Outcome) -> String {
    let s = &out.scan;
    let path_length: f64 = s.path.iter().map(|m| (m.to - m.from).norm()).sum();
    let d = job.params.dir / job.params.dir.norm();
    let devs = &out.deviations;
    let nd = devs.len().max(1) as f64;
    let rep = ProbeReport {
        schema: SCHEMA,
        probe: ProbeR {
            effective_diameter_mm: r(job.probe.effective_diameter_mm),
            rpm: job.probe.rpm,
            feed_mm_s: job.probe.feed_mm_s,
            touch_resolution_mm: r(job.probe.touch_resolution_mm()),
        },
        noise: NoiseR {
            sigma_mm: job.noise.sigma_mm,
            trigger_delay_s: job.noise.delay_s,
            quantise: job.noise.quantise,
            seed: job.seed,
            bias_removed_mm: r(job.noise.bias_mm(&job.probe)),
            u_point_mm: r(out.u_point_mm),
        },
        scan: ScanR {
            step_mm: job.params.step_mm,
            offset_mm: job.params.offset_mm,
            start_mm: rp(job.params.start),
            direction: [r(d.x), r(d.y)],
            contacts: s.contacts.len(),
            moves: s.path.len(),
            path_length_mm: r(path_length),
            stop: s.stop.code(),
            stop_message: s.stop.message(),
        },
        circle: out.circle.as_ref().map(|c| CircleR {
            kind: if c.plug { "plug" } else { "bore" },
            diameter_lsq_mm: r(c.diameter_lsq_mm),
            center_lsq_mm: rp(c.lsq.center),
            roundness_lsq_mm: r(c.lsq.roundness_mm),
            diameter_mz_mm: r(c.diameter_mz_mm),
            center_mz_mm: rp(c.zone.center),
            roundness_mz_mm: r(c.zone.zone()),
            u_diameter_mm: r(c.u_diameter_mm),
            u99_diameter_mm: r(K99 * c.u_diameter_mm),
            u_center_mm: [r(c.u_center_mm[0]), r(c.u_center_mm[1])],
            u99_center_mm: [r(K99 * c.u_center_mm[0]), r(K99 * c.u_center_mm[1])],
        }),
        width: out.width.as_ref().map(|w| WidthR {
            width_mm: r(w.width_mm),
            u_width_mm: r(w.u_width_mm),
            u99_width_mm: r(K99 * w.u_width_mm),
            face_points: w.face.n,
            straightness_mm: r(w.face.straightness_mm),
            other_face_contact_mm: rp(w.other),
        }),
        deviation: DeviationR {
            max_mm: r(devs
                .iter()
                .map(|d| d.deviation_mm)
                .fold(f64::NEG_INFINITY, f64::max)
                .max(-1e300)),
            min_mm: r(devs
                .iter()
                .map(|d| d.deviation_mm)
                .fold(f64::INFINITY, f64::min)
                .min(1e300)),
            rms_mm: r((devs.iter().map(|d| d.deviation_mm.powi(2)).sum::<f64>() / nd).sqrt()),
            u_max_mm: r(devs.iter().map(|d| d.u_mm).fold(0.0, f64::max)),
        },
        coverage: CoverageR {
            pieces_touched: out.coverage.per_piece.iter().filter(|&&n| n > 0).count(),
            missed_pieces: out.coverage.missed.clone(),
            unreachable: out
                .coverage
                .unreachable
                .iter()
                .map(|u| StretchR {
                    from_mm: rp(u.from),
                    to_mm: rp(u.to),
                    length_mm: r(u.length_mm),
                })
                .collect(),
        },
    };
    let mut text = serde_json::to_string_pretty(&rep).unwrap_or_default();
    text.push('\n');
    text
}

/// The contacts as CSV: probe centre, touch direction, compensated surface
/// point, deviation from the design and its expanded uncertainty.
pub fn csv(out: &Outcome) -> String {
    let mut s =
        String::from("index,move,center_x_mm,center_y_mm,dir_x,dir_y,surface_x_mm,surface_y_mm,deviation_mm,u_mm\n");
    for (i, (c, d)) in out.scan.contacts.iter().zip(&out.deviations).enumerate() {
        let f = |x: f64| {
            let mut t = String::new();
            crate::formats::push_num(&mut t, r(x));
            t
        };
        s.push_str(&format!(
            "{i},{},{},{},{},{},{},{},{},{}\n",
            c.kind.name(),
            f(c.center.x),
            f(c.center.y),
            f(c.dir.x),
            f(c.dir.y),
            f(d.surface.x),
            f(d.surface.y),
            f(d.deviation_mm),
            f(d.u_mm),
        ));
    }
    s
}
