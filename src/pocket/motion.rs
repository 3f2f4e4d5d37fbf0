//! Final-layer motion along the main path: lines, arc + line, or cubic
//! Bezier + line (the Iowa State grid-pocket thesis (1999) §4.1-4.3).
//!
//! The main path is cut into straight runs of cells (along X or along Y);
//! a run's touching points lie in one vertical plane (XZ or YZ), where the
//! curves are fitted:
//!
//! - **arc + line** (§4.2, after Vickers and Bradley): from the first point
//!   of a span, the arc through the first, middle and last point; accepted
//!   when every point of the span is within the tolerance of the circle
//!   (|r - d|), shrunk by one point on failure; an arc of radius above the
//!   limit becomes a line (when the points are within the tolerance of it);
//!   two points make a line.
//! - **Bezier + line** (§4.3): on spans of four or more points, a cubic
//!   with the span's ends as end control points whose inner control points
//!   put P(1/(n-1)) on the second point and P(1 - 1/(n-1)) on the
//!   next-to-last; accepted when every point is within half the tolerance
//!   of the curve, shrunk on failure. Controllers run arcs, not Beziers,
//!   so the curve is written as tangent arcs (biarcs) within the other half
//!   of the tolerance.
//!
//! Every curve is also checked against the surface: sampled along its
//! length, the cutter may not dip more than the gouge tolerance below the
//! touching height. A curve that would is refused like one out of
//! tolerance; lines are split until they comply ([`Contact::safe_line`]).

use super::contact::Contact;
use crate::geometry::Segment;
use crate::geometry::line::point_segment_distance;
use crate::geometry::{Arc3, Line3, P2, P3, Plane};
use crate::laser::arcfit;

/// How the final layer's main path moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionMode {
    /// One straight move per cell (the polyline of the touching points).
    Lines,
    /// Arcs through three cell points in the run's vertical plane, lines
    /// where no arc fits (§4.2).
    ArcLine,
    /// Cubic Beziers written as biarcs, lines where no cubic fits (§4.3).
    BezierLine,
}

impl MotionMode {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            MotionMode::Lines => "lines",
            MotionMode::ArcLine => "arc_line",
            MotionMode::BezierLine => "bezier_line",
        }
    }
}

/// Fitting limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Largest distance (mm) of a cell point from its curve.
    pub tol: f64,
    /// Arcs of larger radius (mm) become lines.
    pub max_radius: f64,
}

/// Longest span tried, in cells (the fit is quadratic in it).
const MAX_SPAN: usize = 48;

/// The vertical plane of a straight run and the fixed coordinate.
fn run_plane(a: &P3, b: &P3) -> (Plane, f64) {
    if (b.x - a.x).abs() >= (b.y - a.y).abs() {
        (Plane::Xz, a.y)
    } else {
        (Plane::Yz, a.x)
    }
}

/// Distance of `p` from an element.
pub fn elem_distance(e: &Segment, p: &P3) -> f64 {
    match e {
        Segment::Line(l) => l.distance(p),
        Segment::Arc(a) => a.distance(p).unwrap_or_else(|| (a.start - p).norm()),
    }
}

/// True when the cutter along `e` stays within the gouge tolerance.
fn no_gouge(c: &Contact, e: &Segment, step: f64) -> bool {
    let len = e.length();
    let n = ((len / step).ceil() as usize).clamp(4, 4096);
    (1..n).all(|k| {
        let p = e.point_at_length(len * k as f64 / n as f64);
        c.tip_z(p.x, p.y) - p.z <= c.gouge_tol
    })
}

fn lines_between(c: &Contact, pts: &[P3], out: &mut Vec<Segment>) {
    for w in pts.windows(2) {
        let mut v = Vec::new();
        c.safe_line(w[0], w[1], &mut v);
        let mut a = w[0];
        for b in v {
            out.push(Segment::line(a, b));
            a = b;
        }
    }
}

/// Fit one straight run of touching points with `mode`.
pub fn fit_run(c: &Contact, pts: &[P3], mode: MotionMode, o: &FitOptions, step: f64) -> Vec<Segment> {
    let mut out = Vec::new();
    if mode == MotionMode::Lines || pts.len() < 3 {
        lines_between(c, pts, &mut out);
        return out;
    }
    let (plane, _) = run_plane(&pts[0], &pts[pts.len() - 1]);
    let n = pts.len() - 1;
    let min_pts = if mode == MotionMode::ArcLine { 3 } else { 4 };
    let mut i = 0;
    while i < n {
        let mut done = false;
        let hi = n.min(i + MAX_SPAN);
        if hi + 1 >= i + min_pts {
            for j in (i + min_pts - 1..=hi).rev() {
                let span = &pts[i..=j];
                let fit = match mode {
                    MotionMode::ArcLine => arc_span(span, plane, o),
                    _ => bezier_span(span, plane, o),
                };
                if let Some(f) = fit
                    && f.iter().all(|e| no_gouge(c, e, step))
                {
                    out.extend(f);
                    i = j;
                    done = true;
                    break;
                }
            }
        }
        if !done {
            lines_between(c, &pts[i..=i + 1], &mut out);
            i += 1;
        }
    }
    out
}

/// Thesis §4.2 on one span: an arc through first, middle and last point,
/// or a line when the radius is beyond the limit.
fn arc_span(span: &[P3], plane: Plane, o: &FitOptions) -> Option<Vec<Segment>> {
    let (a, b) = (span[0], span[span.len() - 1]);
    let m = span[span.len() / 2];
    let line = || {
        let l = Line3::new(a, b);
        span.iter()
            .all(|p| l.distance(p) <= o.tol)
            .then(|| vec![Segment::Line(l)])
    };
    let Some(arc) = Arc3::from_three_points(&a, &m, &b, plane) else {
        return line();
    };
    let r = arc.radius();
    if r > o.max_radius {
        return line();
    }
    if arc.sweep().abs() > std::f64::consts::FRAC_PI_2 {
        return None;
    }
    let c2 = plane.project(&arc.center);
    let ok = span.iter().all(|p| ((plane.project(p) - c2).norm() - r).abs() <= o.tol);
    ok.then(|| vec![Segment::Arc(arc)])
}

fn bez(p: &[P2; 4], u: f64) -> P2 {
    let s = 1.0 - u;
    let w = [s * s * s, 3.0 * u * s * s, 3.0 * u * u * s, u * u * u];
    P2::from(p[0].coords * w[0] + p[1].coords * w[1] + p[2].coords * w[2] + p[3].coords * w[3])
}

/// Thesis §4.3 on one span: the cubic through the span's ends whose
/// inner control points put P(u1) and P(u2) on the second and the
/// next-to-last points, u1 = 1/(n-1), u2 = 1 - u1; then tangent arcs.
fn bezier_span(span: &[P3], plane: Plane, o: &FitOptions) -> Option<Vec<Segment>> {
    let (cubic, fixed) = bezier_controls(span, plane)?;
    let n = span.len();
    // Points within tol/2 of the curve, and the curve monotone along the run.
    let samples: Vec<P2> = (0..=32 * (n - 1))
        .map(|k| bez(&cubic, k as f64 / (32 * (n - 1)) as f64))
        .collect();
    let along = |p: &P2| if plane == Plane::Xz { p.y } else { p.x };
    let dir = (along(&samples[samples.len() - 1]) - along(&samples[0])).signum();
    if samples.windows(2).any(|w| (along(&w[1]) - along(&w[0])) * dir < 0.0) {
        return None;
    }
    for p in span {
        let q = plane.project(p);
        let d = samples
            .windows(2)
            .map(|w| point_segment_distance(&q, &w[0], &w[1]))
            .fold(f64::INFINITY, f64::min);
        if d > 0.5 * o.tol {
            return None;
        }
    }
    let fit = arcfit::fit_points(&samples, 0.5 * o.tol, 0.0, false);
    let lift = |p: &P3| plane.lift(&P2::new(p.x, p.y), fixed);
    let mut out = Vec::with_capacity(fit.len());
    for e in &fit {
        match e {
            Segment::Line(l) => out.push(Segment::line(lift(&l.start), lift(&l.end))),
            Segment::Arc(a) => out.push(Segment::Arc(Arc3::new(
                lift(&a.center),
                lift(&a.start),
                lift(&a.end),
                a.ccw,
                plane,
                0,
            )?)),
        }
    }
    // Exact ends: the span's points, not their round trip.
    if let Some(f) = out.first_mut() {
        f.set_start(span[0]);
    }
    if let Some(l) = out.last_mut() {
        l.set_end(span[n - 1]);
    }
    Some(out)
}

/// Control polygon of the span's cubic in plane coordinates, and the
/// run's fixed coordinate.
pub fn bezier_controls(span: &[P3], plane: Plane) -> Option<([P2; 4], f64)> {
    let n = span.len();
    if n < 4 {
        return None;
    }
    let fixed = plane.normal_coord(&span[0]);
    let q: Vec<P2> = span.iter().map(|p| plane.project(p)).collect();
    let u1 = 1.0 / (n - 1) as f64;
    let u2 = 1.0 - u1;
    let b = |u: f64| {
        let s = 1.0 - u;
        [s * s * s, 3.0 * u * s * s, 3.0 * u * u * s, u * u * u]
    };
    let (w1, w2) = (b(u1), b(u2));
    let det = w1[1] * w2[2] - w1[2] * w2[1];
    if det.abs() < 1e-12 {
        return None;
    }
    let (p0, p3) = (q[0].coords, q[n - 1].coords);
    let r1 = q[1].coords - p0 * w1[0] - p3 * w1[3];
    let r2 = q[n - 2].coords - p0 * w2[0] - p3 * w2[3];
    let c1 = (r1 * w2[2] - r2 * w1[2]) / det;
    let c2 = (r2 * w1[1] - r1 * w2[1]) / det;
    Some(([q[0], P2::from(c1), P2::from(c2), q[n - 1]], fixed))
}

/// Largest distance of the run's points from the fitted elements.
pub fn point_deviation(elems: &[Segment], pts: &[P3]) -> f64 {
    pts.iter()
        .map(|p| elems.iter().map(|e| elem_distance(e, p)).fold(f64::INFINITY, f64::min))
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;
    use crate::pocket::surface::Surface;

    #[test]
    fn on_a_circle_arcs_take_whole_spans_and_beziers_fit_a_cubic() {
        let flat = Surface::Flat(-10.0);
        let c = Contact::new(&flat, Cutter::Ball { radius: 1.0 }, 1e-3);
        // Points on a circle of radius 20 in XZ, below the flat surface.
        let pts: Vec<P3> = (0..=10)
            .map(|k| {
                let x = k as f64 * 0.5;
                P3::new(x, 1.0, -(400.0 - (x - 2.5).powi(2)).sqrt() + 10.0)
            })
            .collect();
        let o = FitOptions {
            tol: 1e-4,
            max_radius: 1000.0,
        };
        let arcs = fit_run(&c, &pts, MotionMode::ArcLine, &o, 0.1);
        assert_eq!(arcs.len(), 1);
        assert!(point_deviation(&arcs, &pts) <= 1e-4);
        let lines = fit_run(&c, &pts, MotionMode::Lines, &o, 0.1);
        assert_eq!(lines.len(), 10);
        let bez = fit_run(&c, &pts, MotionMode::BezierLine, &o, 0.1);
        assert!(bez.len() < lines.len(), "{}", bez.len());
        assert!(point_deviation(&bez, &pts) <= 1e-4);
        // A cubic's own points come back within tolerance.
        let cubic: Vec<P3> = (0..7)
            .map(|k| {
                let x = k as f64;
                P3::new(3.0, x, 0.01 * x * x * x - 0.1 * x)
            })
            .collect();
        let (ctl, fixed) = bezier_controls(&cubic, Plane::Yz).unwrap();
        assert_eq!(fixed, 3.0);
        assert!((super::bez(&ctl, 0.5) - Plane::Yz.project(&cubic[3])).norm() < 1e-9);
    }
}
