//! A whole probing job: scan a simulated part and measure what was touched.
//!
//! Three jobs: a contour (any closed chains; deviation from the design and
//! coverage), a circle (a plug gauge: diameter, centre, roundness by least
//! squares and minimum zone) and a gauge block (the width from a line fitted
//! to one face and one touch on the opposite face, Bayesteh 2013 section 4.4).

use super::ProbeError;
use super::measure::{self, CircleMeasure, Coverage, Deviation, WidthMeasure};
use super::noise::{NoiseModel, Rng};
use super::part::Part;
use super::scan::{self, Contact, MoveKind, PathMove, Scan, ScanParams};
use super::tip::Probe;
use crate::geometry::{P2, V2};

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub enum Measure {
    /// Only the scan, deviations and coverage.
    Contour,
    /// Fit a circle too.
    Circle,
    /// A gauge block's width: scan `face_points` contacts along the first
    /// face, then touch the opposite face, `nominal_mm` away.
    Width {
        /// The gauge's nominal width, mm.
        nominal_mm: f64,
        /// Contacts along the first face.
        face_points: usize,
    },
}

/// A job to run.
#[derive(Debug, Clone)]
pub struct ProbeJob {
    /// The simulated part.
    pub part: Part,
    /// The design to compare with (usually the part itself).
    pub design: Part,
    /// The probe.
    pub probe: Probe,
    /// The touch model.
    pub noise: NoiseModel,
    /// The scan.
    pub params: ScanParams,
    /// What to measure.
    pub measure: Measure,
    /// Seed of the noise.
    pub seed: u64,
}

/// What a job found.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The scan (for a width: the face scan and the opposite touch).
    pub scan: Scan,
    /// Per-contact standard uncertainty along the approach (mm).
    pub u_point_mm: f64,
    /// The circle, when measured.
    pub circle: Option<CircleMeasure>,
    /// The width, when measured.
    pub width: Option<WidthMeasure>,
    /// Every contact against the design.
    pub deviations: Vec<Deviation>,
    /// What the probe could not reach and what it skipped.
    pub coverage: Coverage,
}

/// Run a job.
pub fn run(job: &ProbeJob) -> Result<Outcome, ProbeError> {
    job.noise.check()?;
    let re = job.probe.radius();
    let u = job.noise.point_sigma_mm(&job.probe);
    let mut params = job.params;
    if let Measure::Width { face_points, .. } = job.measure {
        params.max_points = face_points;
    }
    let mut scan = scan::run(&job.part, &job.probe, &job.noise, &params, job.seed)?;
    let mut circle = None;
    let mut width = None;
    match job.measure {
        Measure::Contour => {}
        Measure::Circle => circle = Some(measure::circle(&scan.contacts, re, u)?),
        Measure::Width { nominal_mm, .. } => {
            let other = touch_other_face(job, &mut scan, nominal_mm)?;
            let n = scan.contacts.len();
            width = Some(measure::width(&scan.contacts[..n - 1], &other, re, u)?);
        }
    }
    let deviations = measure::deviations(&job.design, &scan.contacts, re, u);
    let coverage = measure::coverage(&job.design, &scan.contacts, re, params.step_mm);
    Ok(Outcome {
        scan,
        u_point_mm: u,
        circle,
        width,
        deviations,
        coverage,
    })
}

/// The single touch on the face opposite the scanned one: from the fitted
/// face's centroid, `nominal + D_e + R_o` across into (and through) the
/// block, lifted over it in Z, then a guarded approach back.
fn touch_other_face(job: &ProbeJob, scan: &mut Scan, nominal_mm: f64) -> Result<Contact, ProbeError> {
    let re = job.probe.radius();
    let pts: Vec<P2> = scan.contacts.iter().map(|c| c.center).collect();
    let line = super::fit::line(&pts)?;
    // The normal into the material: the side the contacts approached.
    let mut n = line.normal;
    if n.dot(&scan.contacts[0].dir) < 0.0 {
        n = -n;
    }
    let ro = job.params.offset_mm;
    let start = line.point + n * (nominal_mm + 2.0 * re + ro);
    let from = scan.path.last().map(|m| m.to).unwrap_or(job.params.start);
    scan.path.push(PathMove {
        from,
        to: start,
        kind: MoveKind::Travel,
        touched: false,
    });
    if job.part.in_material(start) || job.part.distance(start).0 <= re {
        return Err(ProbeError::Start(format!(
            "the start on the opposite face ({}, {}) is in the part: is the nominal width {nominal_mm} mm right?",
            start.x, start.y
        )));
    }
    let d: V2 = -n;
    let len = job.params.max_approach_mm;
    let t = job.part.guarded(start, d, re, len).ok_or_else(|| {
        ProbeError::NoSurface(format!(
            "no opposite face within the maximum approach of {len} mm from ({}, {})",
            start.x, start.y
        ))
    })?;
    let exact = start + d * t.t;
    // A seed apart from the scan's, so the face scan is unchanged.
    let mut rng = Rng::new(job.seed ^ 0x5EED_0F0F_F5E7);
    let c = Contact {
        center: exact + d * job.noise.draw(&job.probe, &mut rng),
        exact,
        dir: d,
        kind: MoveKind::Approach,
        prim: t.prim,
        run_mm: t.t,
    };
    scan.path.push(PathMove {
        from: start,
        to: exact,
        kind: MoveKind::Approach,
        touched: true,
    });
    scan.path.push(PathMove {
        from: exact,
        to: exact - d * ro.min(t.t),
        kind: MoveKind::Retract,
        touched: false,
    });
    scan.contacts.push(c);
    Ok(c)
}

/// The gauge-block scan: first face at x = 0 from the left, the block
/// `width` wide in X and `length` long in Y, `n` contacts `rs` apart
/// centred on the face.
pub fn gauge_params(
    width: f64,
    length: f64,
    n: usize,
    rs: f64,
    ro: f64,
    re: f64,
) -> Result<(Part, ScanParams), ProbeError> {
    for (name, v) in [("gauge width", width), ("gauge length", length)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(ProbeError::Param(format!("{name} must be a positive number, got {v}")));
        }
    }
    let span = (n.max(2) - 1) as f64 * rs;
    if span + 2.0 * re >= length {
        return Err(ProbeError::Param(format!(
            "{n} contacts {rs} mm apart do not fit on a face {length} mm long"
        )));
    }
    let part = Part::rectangle(P2::new(0.0, 0.0), P2::new(width, length));
    let params = ScanParams {
        step_mm: rs,
        offset_mm: ro,
        start: P2::new(-(re + 2.0 * ro), (length - span) / 2.0),
        dir: V2::new(1.0, 0.0),
        max_points: n,
        max_approach_mm: 4.0 * ro + 1.0,
    };
    Ok((part, params))
}

/// The step that gives about `n` contacts round a circle of centre-path
/// radius `rho`: in steady state the scan advances by the angle `phi` with
/// `R_s = 2 rho cos(phi) sin(phi / 2)`.
pub fn step_for_points(rho: f64, n: usize) -> f64 {
    let phi = std::f64::consts::TAU / n.max(3) as f64;
    2.0 * rho * phi.cos() * (phi / 2.0).sin()
}
