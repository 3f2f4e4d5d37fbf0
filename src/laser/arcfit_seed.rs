//! The thesis' way of turning a curve into arcs (Bayesteh (2013) §6.1.4: arcs found
//! by matching the curve's radius of curvature, with the input tolerance
//! setting the resolution), kept as a baseline for [`super::arcfit`].
//!
//! Our reading of the method (see docs/arcfit.md for why):
//!
//! 1. Interpolate the points with a cubic spline (chord-length parameter;
//!    not-a-knot ends, so the spline is fourth-order accurate up to the ends).
//! 2. Walk the spline in equal parameter steps of about `tol` of arc length
//!    (the thesis' loop step), at most [`SeedParams::max_steps`] steps.
//! 3. Round the curvature at each step to two decimals (bins of
//!    0.01 mm⁻¹, the thesis' `Math.Round(curvature, 2)`); a run of steps with
//!    the same rounded curvature becomes one arc through the run's first
//!    point, its parameter midpoint and its last point.
//!
//! The thesis' tolerance only sets the step, so step 3 alone does not keep
//! the arcs within `tol`. We enforce it the way the method allows, by
//! shrinking spans: a run whose arc strays more than `tol` from the spline
//! (checked at every input point in it and along the spline between) is
//! halved in parameter until it fits. [`SeedStats`] tells how many arcs came
//! from curvature runs and how many from those splits.

use super::arcfit::dist_to_elem;
use crate::geometry::Segment;
use crate::geometry::arc::Arc3;
use crate::geometry::{P2, P3, Plane, V2};

/// The thesis' curvature rounding: two decimals, in mm⁻¹.
pub const SEED_CURVATURE_QUANTUM: f64 = 0.01;

/// Tolerances below this (mm) are raised to it: the output is written with
/// nanometre resolution, and a finer target would only multiply splits.
pub const MIN_TOLERANCE: f64 = 1e-9;

/// Knobs of the baseline. The defaults are the thesis' method plus the
/// tolerance enforcement.
#[derive(Debug, Clone, Copy)]
pub struct SeedParams {
    /// Width of a curvature bin (mm⁻¹).
    pub quantum: f64,
    /// Cap on the number of parameter steps (the thesis steps by `tol`, which
    /// at 1e-7 mm over a long curve would be billions of spline evaluations).
    pub max_steps: usize,
    /// Halve runs whose arc strays beyond `tol` (off: the raw seed method).
    pub enforce_tolerance: bool,
}

impl Default for SeedParams {
    fn default() -> Self {
        SeedParams {
            quantum: SEED_CURVATURE_QUANTUM,
            max_steps: 1 << 20,
            enforce_tolerance: true,
        }
    }
}

/// What the fit did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SeedStats {
    /// Parameter steps walked.
    pub steps: usize,
    /// Runs of equal rounded curvature (the raw method's arc count).
    pub runs: usize,
    /// Halvings needed to bring runs within tolerance.
    pub splits: usize,
    /// Pieces that stayed beyond tolerance after halving down to 1/64 of a
    /// step (0 in every case we know of).
    pub unmet: usize,
}

/// Interpolating cubic spline through points in the plane, parameter =
/// cumulative chord length, stored as values and slopes at the knots
/// (piecewise cubic Hermite).
struct Spline {
    s: Vec<f64>,
    p: Vec<P2>,
    m: Vec<V2>,
}

/// Slopes of the not-a-knot cubic spline through `(s[i], y[i])` (n ≥ 2,
/// `s` strictly increasing). Two points: the line; three: the parabola.
fn spline_slopes(s: &[f64], y: &[V2]) -> Vec<V2> {
    let n = s.len();
    let h: Vec<f64> = s.windows(2).map(|w| w[1] - w[0]).collect();
    let d: Vec<V2> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / h[i]).collect();
    match n {
        2 => return vec![d[0], d[0]],
        3 => {
            let c = (d[1] - d[0]) / (h[0] + h[1]);
            return vec![d[0] - c * h[0], d[0] + c * h[0], d[0] + c * (h[0] + 2.0 * h[1])];
        }
        _ => {}
    }
    // Tridiagonal rows: sub a, diagonal b, super c, right-hand side r.
    let mut a = vec![0.0; n];
    let mut b = vec![0.0; n];
    let mut c = vec![0.0; n];
    let mut r = vec![V2::zeros(); n];
    let w0 = h[0] + h[1];
    b[0] = h[1];
    c[0] = w0;
    r[0] = (d[0] * ((h[0] + 2.0 * w0) * h[1]) + d[1] * (h[0] * h[0])) / w0;
    for i in 1..n - 1 {
        a[i] = h[i];
        b[i] = 2.0 * (h[i - 1] + h[i]);
        c[i] = h[i - 1];
        r[i] = (d[i - 1] * h[i] + d[i] * h[i - 1]) * 3.0;
    }
    let (hp, hl) = (h[n - 3], h[n - 2]);
    let wn = hp + hl;
    a[n - 1] = wn;
    b[n - 1] = hp;
    r[n - 1] = (d[n - 3] * (hl * hl) + d[n - 2] * ((2.0 * wn + hl) * hp)) / wn;
    // Thomas algorithm.
    for i in 1..n {
        let f = a[i] / b[i - 1];
        b[i] -= f * c[i - 1];
        let prev = r[i - 1];
        r[i] -= prev * f;
    }
    let mut m = vec![V2::zeros(); n];
    m[n - 1] = r[n - 1] / b[n - 1];
    for i in (0..n - 1).rev() {
        m[i] = (r[i] - m[i + 1] * c[i]) / b[i];
    }
    m
}

impl Spline {
    /// `pts`: at least two points, consecutive ones distinct.
    fn new(pts: &[P2]) -> Spline {
        let mut s = Vec::with_capacity(pts.len());
        let mut acc = 0.0;
        s.push(0.0);
        for w in pts.windows(2) {
            acc += (w[1] - w[0]).norm();
            s.push(acc);
        }
        let y: Vec<V2> = pts.iter().map(|p| p.coords).collect();
        let m = spline_slopes(&s, &y);
        Spline { s, p: pts.to_vec(), m }
    }

    fn end(&self) -> f64 {
        *self.s.last().unwrap_or(&0.0)
    }

    fn interval(&self, u: f64) -> usize {
        let n = self.s.len();
        self.s.partition_point(|&k| k <= u).clamp(1, n - 1) - 1
    }

    /// Point, first and second derivative at `u` on interval `i`. Knots
    /// give their input point exactly.
    fn eval_on(&self, i: usize, u: f64) -> (P2, V2, V2) {
        let h = self.s[i + 1] - self.s[i];
        let d = (self.p[i + 1] - self.p[i]) / h;
        let (m0, m1) = (self.m[i], self.m[i + 1]);
        let c2 = (d * 3.0 - m0 * 2.0 - m1) / h;
        let c3 = (m0 + m1 - d * 2.0) / (h * h);
        let t = u - self.s[i];
        let p = if t <= 0.0 {
            self.p[i]
        } else if t >= h {
            self.p[i + 1]
        } else {
            self.p[i] + m0 * t + c2 * (t * t) + c3 * (t * t * t)
        };
        (p, m0 + c2 * (2.0 * t) + c3 * (3.0 * t * t), c2 * 2.0 + c3 * (6.0 * t))
    }

    fn point(&self, u: f64) -> P2 {
        self.eval_on(self.interval(u), u).0
    }

    /// Unsigned curvature from first and second derivatives.
    fn curvature(d1: V2, d2: V2) -> f64 {
        let sp = d1.norm();
        (d1.perp(&d2)).abs() / (sp * sp * sp)
    }

    /// Arc length (3-point Gauss-Legendre per interval).
    fn length(&self) -> f64 {
        let g = [
            (-(0.6f64).sqrt(), 5.0 / 9.0),
            (0.0, 8.0 / 9.0),
            ((0.6f64).sqrt(), 5.0 / 9.0),
        ];
        (0..self.s.len() - 1)
            .map(|i| {
                let (a, b) = (self.s[i], self.s[i + 1]);
                let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
                g.iter()
                    .map(|&(x, w)| w * half * self.eval_on(i, mid + half * x).1.norm())
                    .sum::<f64>()
            })
            .sum()
    }
}

fn lift(p: &P2, z: f64) -> P3 {
    P3::new(p.x, p.y, z)
}

/// The arc from `a` through `m` to `b`, or the line `a`–`b` when the three
/// are collinear (radius beyond 1e9 mm).
fn three_point_piece(a: P2, m: P2, b: P2, z: f64) -> Segment {
    match Arc3::from_three_points(&lift(&a, z), &lift(&m, z), &lift(&b, z), Plane::Xy) {
        Some(arc) if arc.radius() <= 1e9 => Segment::Arc(arc),
        _ => Segment::line(lift(&a, z), lift(&b, z)),
    }
}

struct Fitter<'a> {
    sp: &'a Spline,
    tol: f64,
    z: f64,
    step: f64,
    steps: usize,
    params: SeedParams,
    stats: SeedStats,
    out: Vec<Segment>,
}

impl Fitter<'_> {
    fn grid(&self, k: usize) -> f64 {
        if k >= self.steps {
            self.sp.end()
        } else {
            k as f64 * self.step
        }
    }

    /// Largest distance from the piece to the spline over `(ua, ub)`: every
    /// knot inside, up to 1024 of the walk's steps, and 16 even samples.
    fn deviation(&self, e: &Segment, ua: f64, ub: f64) -> f64 {
        let sp = self.sp;
        let mut worst: f64 = 0.0;
        let k0 = sp.s.partition_point(|&k| k <= ua);
        let k1 = sp.s.partition_point(|&k| k < ub);
        for p in &sp.p[k0..k1.max(k0)] {
            worst = worst.max(dist_to_elem(p, e));
        }
        let g0 = (ua / self.step).floor() as usize + 1;
        let g1 = ((ub / self.step).ceil() as usize).min(self.steps);
        let stride = (g1.saturating_sub(g0) / 1024).max(1);
        let mut g = g0;
        while g < g1 {
            worst = worst.max(dist_to_elem(&sp.point(self.grid(g)), e));
            g += stride;
        }
        for k in 1..16 {
            let u = ua + (ub - ua) * k as f64 / 16.0;
            worst = worst.max(dist_to_elem(&sp.point(u), e));
        }
        worst
    }

    fn emit(&mut self, ua: f64, ub: f64) {
        let (pa, pb) = (self.sp.point(ua), self.sp.point(ub));
        let pm = self.sp.point(0.5 * (ua + ub));
        let e = three_point_piece(pa, pm, pb, self.z);
        let can_split = ub - ua > self.step / 64.0;
        let degenerate = e.length() <= 1e-12;
        if degenerate && !can_split {
            return; // nothing to draw between two equal points
        }
        let too_far = self.params.enforce_tolerance && self.deviation(&e, ua, ub) > 0.95 * self.tol;
        if (degenerate || too_far) && can_split {
            self.stats.splits += 1;
            let um = 0.5 * (ua + ub);
            self.emit(ua, um);
            self.emit(um, ub);
            return;
        }
        if too_far {
            self.stats.unmet += 1;
        }
        self.out.push(e);
    }
}

/// The thesis' curvature-matching conversion with the default
/// [`SeedParams`]: lines and arcs through the points, each within `tol`
/// (mm) of the interpolating spline and of every input point, end points
/// exact, consecutive pieces sharing end points.
pub fn fit_curvature_matching(points: &[P2], tol: f64, z: f64) -> Vec<Segment> {
    fit_curvature_matching_with(points, tol, z, &SeedParams::default()).0
}

/// [`fit_curvature_matching`] with explicit knobs and statistics.
pub fn fit_curvature_matching_with(points: &[P2], tol: f64, z: f64, params: &SeedParams) -> (Vec<Segment>, SeedStats) {
    let mut pts: Vec<P2> = Vec::with_capacity(points.len());
    for p in points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()) {
        if pts.last().is_none_or(|q: &P2| (p - q).norm() > 1e-12) {
            pts.push(*p);
        }
    }
    let mut stats = SeedStats::default();
    if pts.len() < 2 {
        return (Vec::new(), stats);
    }
    if !(tol.is_finite() && tol > 0.0) {
        // No usable tolerance: the polyline is the only exact answer.
        let lines = pts
            .windows(2)
            .map(|w| Segment::line(lift(&w[0], z), lift(&w[1], z)))
            .collect();
        return (lines, stats);
    }
    let tol = tol.max(MIN_TOLERANCE);
    let sp = Spline::new(&pts);
    let length = sp.length();
    let steps = ((length / tol).ceil().max(1.0) as usize).clamp(1, params.max_steps.max(1));
    let step = sp.end() / steps as f64;
    stats.steps = steps;
    // Rounded curvature at each step; a change starts a new run.
    let quantum = if params.quantum > 0.0 {
        params.quantum
    } else {
        SEED_CURVATURE_QUANTUM
    };
    let mut bounds = vec![0usize];
    let mut prev: Option<i64> = None;
    let mut i = 0;
    for k in 0..=steps {
        let u = if k == steps { sp.end() } else { k as f64 * step };
        while i + 2 < sp.s.len() && sp.s[i + 1] <= u {
            i += 1;
        }
        let (_, d1, d2) = sp.eval_on(i, u);
        let kappa = Spline::curvature(d1, d2);
        let bin = if kappa.is_finite() {
            (kappa / quantum).round().min(1e15) as i64
        } else {
            i64::MAX
        };
        if prev.is_some_and(|b| b != bin) && k > 0 && k < steps {
            bounds.push(k);
        }
        prev = Some(bin);
    }
    bounds.push(steps);
    stats.runs = bounds.len() - 1;
    let mut f = Fitter {
        sp: &sp,
        tol,
        z,
        step,
        steps,
        params: *params,
        stats,
        out: Vec::with_capacity(bounds.len()),
    };
    for w in bounds.windows(2) {
        let (ua, ub) = (f.grid(w[0]), f.grid(w[1]));
        f.emit(ua, ub);
    }
    (f.out, f.stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laser::arcfit::point_deviation;
    use std::f64::consts::TAU;

    /// Largest distance from `n` samples per piece to the true curve, given
    /// as a distance function.
    fn dense_dev(fit: &[Segment], n: usize, dist: impl Fn(P2) -> f64) -> f64 {
        fit.iter()
            .flat_map(|e| (0..=n).map(move |k| e.point_at_length(e.length() * k as f64 / n as f64).xy()))
            .map(dist)
            .fold(0.0, f64::max)
    }

    fn check_path(fit: &[Segment], pts: &[P2]) {
        assert!(!fit.is_empty());
        assert!((fit[0].start().xy() - pts[0]).norm() == 0.0, "start not exact");
        assert!(
            (fit.last().unwrap().end().xy() - pts[pts.len() - 1]).norm() == 0.0,
            "end not exact"
        );
        for w in fit.windows(2) {
            assert!((w[0].end() - w[1].start()).norm() < 1e-12, "gap");
        }
    }

    #[test]
    fn not_a_knot_slopes_reproduce_a_cubic() {
        let s = [0.0, 0.3, 1.1, 1.5, 2.6, 3.0];
        let f = |x: f64| V2::new(1.0 - 2.0 * x + 0.5 * x * x - 0.25 * x * x * x, 3.0 * x * x);
        let df = |x: f64| V2::new(-2.0 + x - 0.75 * x * x, 6.0 * x);
        let y: Vec<V2> = s.iter().map(|&x| f(x)).collect();
        let m = spline_slopes(&s, &y);
        for (x, mi) in s.iter().zip(&m) {
            assert!((mi - df(*x)).norm() < 1e-9, "{x}: {mi:?} vs {:?}", df(*x));
        }
    }

    #[test]
    fn a_circle_within_tolerance_in_few_arcs() {
        let r = 10.0;
        let pts: Vec<P2> = (0..=720)
            .map(|i| {
                let a = TAU * i as f64 / 720.0;
                P2::new(r * a.cos(), r * a.sin())
            })
            .collect();
        for tol in [1e-3, 1e-5] {
            let f = fit_curvature_matching(&pts, tol, 0.0);
            check_path(&f, &pts);
            let dev = dense_dev(&f, 256, |p| ((p.coords.norm()) - r).abs());
            assert!(dev <= tol, "circle {tol}: {dev}");
            assert!(f.len() <= 8, "{} pieces", f.len());
        }
    }

    #[test]
    fn a_sine_within_tolerance() {
        let pts: Vec<P2> = (0..=400)
            .map(|i| {
                let x = i as f64 * 0.025;
                P2::new(x, x.sin())
            })
            .collect();
        for tol in [1e-3, 1e-4, 1e-5] {
            let (f, st) = fit_curvature_matching_with(&pts, tol, 0.0, &SeedParams::default());
            check_path(&f, &pts);
            assert_eq!(st.unmet, 0);
            assert!(point_deviation(&f, &pts) <= tol);
            // Against the true sine: first-order distance |y - sin x| cos(atan(cos x)).
            let dev = dense_dev(&f, 256, |p| (p.y - p.x.sin()).abs() / (1.0 + p.x.cos().powi(2)).sqrt());
            assert!(dev <= tol, "sine {tol}: {dev}");
            // Curvature spans 0..1 mm⁻¹: some 100 bins per quarter wave, so
            // hundreds of arcs whatever the tolerance.
            assert!(
                st.runs > 400 && f.len() < 2 * pts.len(),
                "{} runs, {} pieces",
                st.runs,
                f.len()
            );
        }
    }

    #[test]
    fn an_archimedean_spiral_within_tolerance() {
        // r = 1 + 0.5 θ over three turns.
        let (a, b) = (1.0, 0.5);
        let pts: Vec<P2> = (0..=1500)
            .map(|i| {
                let t = 3.0 * TAU * i as f64 / 1500.0;
                let r = a + b * t;
                P2::new(r * t.cos(), r * t.sin())
            })
            .collect();
        let dist = |p: P2| {
            let (r, phi) = (p.coords.norm(), p.y.atan2(p.x));
            let k = ((r - a - b * phi) / (b * TAU)).round();
            let t = phi + TAU * k;
            (r - a - b * t).abs() / (1.0 + (b / r).powi(2)).sqrt()
        };
        for tol in [1e-3, 1e-4] {
            let f = fit_curvature_matching(&pts, tol, 0.5);
            check_path(&f, &pts);
            assert!(f.iter().all(|e| e.start().z == 0.5 && e.end().z == 0.5));
            let dev = dense_dev(&f, 256, dist);
            assert!(dev <= tol, "spiral {tol}: {dev}");
        }
    }

    #[test]
    fn raw_runs_follow_rounded_curvature() {
        // A circle of curvature 0.1 is one bin: the raw method makes one run,
        // one arc through start, far side and end (end = start: halved).
        let pts: Vec<P2> = (0..=64)
            .map(|i| {
                let a = TAU * i as f64 / 64.0;
                P2::new(10.0 * a.cos(), 10.0 * a.sin())
            })
            .collect();
        let raw = SeedParams {
            enforce_tolerance: false,
            ..SeedParams::default()
        };
        let (f, st) = fit_curvature_matching_with(&pts, 1e-2, 0.0, &raw);
        assert_eq!(st.runs, 1);
        assert!(f.len() <= 2 && f.iter().all(|e| matches!(e, Segment::Arc(_))));
        let sweep: f64 = f
            .iter()
            .map(|e| if let Segment::Arc(a) = e { a.sweep().abs() } else { 0.0 })
            .sum();
        assert!((sweep - TAU).abs() < 1e-6, "{sweep}");
    }

    #[test]
    fn degenerate_input_does_not_panic() {
        let p = |x: f64, y: f64| P2::new(x, y);
        assert!(fit_curvature_matching(&[], 1e-3, 0.0).is_empty());
        assert!(fit_curvature_matching(&[p(1.0, 2.0)], 1e-3, 0.0).is_empty());
        assert!(fit_curvature_matching(&[p(1.0, 2.0), p(1.0, 2.0), p(1.0, 2.0)], 1e-3, 0.0).is_empty());
        let two = fit_curvature_matching(&[p(0.0, 0.0), p(1.0, 0.0)], 1e-3, 0.0);
        assert_eq!(two.len(), 1);
        check_path(&two, &[p(0.0, 0.0), p(1.0, 0.0)]);
        // Duplicates and collinear points: one line.
        let col = [
            p(0.0, 0.0),
            p(0.5, 0.5),
            p(0.5, 0.5),
            p(1.0, 1.0),
            p(2.0, 2.0),
            p(3.0, 3.0),
        ];
        let f = fit_curvature_matching(&col, 1e-4, 0.0);
        check_path(&f, &col);
        assert!(f.iter().all(|e| matches!(e, Segment::Line(_))), "{f:?}");
        assert!(point_deviation(&f, &col) <= 1e-4);
        // Three points, a hairpin, NaNs and a useless tolerance.
        let three = [p(0.0, 0.0), p(1.0, 1.0), p(2.0, 0.0)];
        check_path(&fit_curvature_matching(&three, 1e-4, 0.0), &three);
        let hairpin = [p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1e-6), p(1.0, 2e-6)];
        let f = fit_curvature_matching(&hairpin, 1e-4, 0.0);
        check_path(&f, &hairpin);
        assert!(point_deviation(&f, &hairpin) <= 1e-4);
        let with_nan = [p(0.0, 0.0), p(f64::NAN, 1.0), p(1.0, 0.0)];
        assert_eq!(fit_curvature_matching(&with_nan, 1e-3, 0.0).len(), 1);
        for tol in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(fit_curvature_matching(&three, tol, 0.0).len(), 2);
        }
        // A tiny tolerance is floored, not a runaway.
        let f = fit_curvature_matching(&three, 1e-30, 0.0);
        check_path(&f, &three);
    }
}
