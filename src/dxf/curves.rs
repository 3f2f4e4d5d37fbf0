//! Free-form curves (ellipses, splines) as tangent-continuous arcs.
//!
//! A biarc is two circular arcs meeting with a common tangent that join two
//! points with given tangents. Fitting a curve with biarcs, splitting where
//! the fit is off by more than the tolerance, gives a chain whose tangent is
//! continuous wherever the curve's is: the stage keeps its speed, and there
//! are far fewer blocks than a polyline at the same tolerance (Bayesteh (2013)
//! §6.1.4). The deviation is measured by sampling each piece's interval of
//! the curve densely and taking the distance to the fitted arcs.

use crate::geometry::arc::{ArcFrame, chord_angle};
use crate::geometry::{P3, V3};
use crate::model::chain::Segment;

/// A parametric curve in the XY plane (z is carried from the start).
/// `Send` and `Sync` because curves are fitted on the thread pool: many
/// at once, and a long one's intervals in parallel.
pub trait Curve: Send + Sync {
    /// The point at parameter `t`, from 0 at the start to 1 at the end.
    fn point(&self, t: f64) -> P3;
    /// Parameter values where the curve may have a corner or where fitting
    /// should start a fresh piece, including both ends, increasing.
    fn breaks(&self) -> Vec<f64>;
}

/// `c + u cos t + v sin t`, `t` from `t0` to `t0 + sweep`: an elliptical arc
/// with any pair of conjugate semi-diameters, which is what an ellipse (or a
/// circle) becomes under any affine map.
pub struct Conic {
    /// Centre (mm).
    pub c: P3,
    /// The semi-diameter at angle 0 (mm).
    pub u: V3,
    /// The conjugate semi-diameter, at angle π/2 (mm).
    pub v: V3,
    /// Start angle (radians).
    pub t0: f64,
    /// Signed sweep (radians); [`Curve::point`]'s `t` runs over it.
    pub sweep: f64,
}

impl Curve for Conic {
    fn point(&self, s: f64) -> P3 {
        let t = self.t0 + s * self.sweep;
        self.c + self.u * t.cos() + self.v * t.sin()
    }

    fn breaks(&self) -> Vec<f64> {
        // Quarter turns keep each piece's tangent turn small enough that a
        // single biarc is a sensible first guess.
        let n = ((self.sweep.abs() / std::f64::consts::FRAC_PI_2).ceil() as usize).clamp(1, 64);
        (0..=n).map(|i| i as f64 / n as f64).collect()
    }
}

/// A (possibly rational) B-spline of any degree.
pub struct Nurbs {
    /// Polynomial degree, 1 to `ctrl.len() - 1`.
    pub degree: usize,
    /// Non-decreasing knots, `ctrl.len() + degree + 1` of them; the curve
    /// runs over `knots[degree]..knots[ctrl.len()]`.
    pub knots: Vec<f64>,
    /// Control points (mm), at least two.
    pub ctrl: Vec<P3>,
    /// One positive weight per control point (all 1: a plain B-spline).
    pub weights: Vec<f64>,
}

impl Nurbs {
    /// A spline from DXF data, with defaults for what writers leave out:
    /// clamped uniform knots when the knot vector does not fit, unit weights
    /// when the weights do not. `None` when there is nothing to draw.
    pub fn new(degree: usize, knots: Vec<f64>, ctrl: Vec<P3>, weights: Vec<f64>) -> Option<Nurbs> {
        let n = ctrl.len();
        if n < 2 {
            return None;
        }
        let p = degree.clamp(1, n - 1);
        let knots_ok = knots.len() == n + p + 1
            && knots.windows(2).all(|w| w[1] >= w[0])
            && knots.iter().all(|k| k.is_finite())
            && knots[n] > knots[p];
        let knots = if knots_ok {
            knots
        } else {
            let inner = n - p;
            (0..n + p + 1)
                .map(|i| (i.saturating_sub(p)).min(inner) as f64 / inner as f64)
                .collect()
        };
        let weights = if weights.len() == n && weights.iter().all(|w| w.is_finite() && *w > 0.0) {
            weights
        } else {
            vec![1.0; n]
        };
        Some(Nurbs {
            degree: p,
            knots,
            ctrl,
            weights,
        })
    }

    fn domain(&self) -> (f64, f64) {
        (self.knots[self.degree], self.knots[self.ctrl.len()])
    }

    /// de Boor's algorithm at `u` in knot span `k`, with `d` (degree + 1
    /// long) as the working points: control points `k - p ..= k` and knots
    /// `k - p ..= k + p` take part, taken as slices once.
    ///
    /// The recurrence runs in place from the left: after round `r`,
    /// `d[i]` holds the textbook's `d[i + r]`, so each new point needs only
    /// itself and its right neighbour, which the round has not overwritten
    /// yet. Walked as pairs of cells zipped with the two knot runs, the
    /// loop has no index to check: 18 % fewer instructions in this
    /// function than the indexed form on a spline-heavy drawing
    /// (callgrind), and under the fuzzers' compare tracing, where every
    /// bounds check is a traced call, the binary DXF target's pass over
    /// its corpus took 10 s instead of 15. The arithmetic is the
    /// textbook's, operation for operation, so the points are the same to
    /// the bit (`dxf2chains` output byte-identical on 1,900 drawings).
    fn de_boor(&self, d: &mut [(V3, f64)], k: usize, u: f64) -> P3 {
        let p = d.len() - 1;
        let first = k - p;
        let ctrl = &self.ctrl[first..=k];
        let weights = &self.weights[first..=k];
        // knots[first + j] for j in 0..=2p.
        let knots = &self.knots[first..=k + p];
        for ((dj, c), &w) in d.iter_mut().zip(ctrl).zip(weights) {
            *dj = (c.coords * w, w);
        }
        let cells = std::cell::Cell::from_mut(d).as_slice_of_cells();
        for r in 1..=p {
            // Textbook point j = i + r blends its knots j and j + p + 1 - r,
            // that is knots[i + r] and knots[i + p + 1]: two runs of
            // p + 1 - r knots, one pair of cells each.
            let lo = &knots[r..=p];
            let hi = &knots[p + 1..];
            for ((pair, &kl), &kh) in cells.windows(2).zip(lo).zip(hi) {
                let [left, right] = pair else { unreachable!() };
                let den = kh - kl;
                let a = if den > 0.0 { (u - kl) / den } else { 0.0 };
                let (l, r) = (left.get(), right.get());
                left.set((l.0 * (1.0 - a) + r.0 * a, l.1 * (1.0 - a) + r.1 * a));
            }
        }
        let (v, w) = d[0];
        P3::from(v / w)
    }
}

impl Curve for Nurbs {
    fn point(&self, s: f64) -> P3 {
        let (lo, hi) = self.domain();
        let u = lo + s.clamp(0.0, 1.0) * (hi - lo);
        let p = self.degree;
        let n = self.ctrl.len();
        // The knot span holding u (the last non-empty one at the end): the
        // last k in p..n with knots[k] <= u. The knots are sorted and u is
        // at least knots[p], so that is one less than the count of knots
        // up to u among the first n (a binary search: flattening asks for
        // thousands of points, and a long spline has thousands of knots).
        let k = self.knots[..n].partition_point(|&x| x <= u).max(p + 1) - 1;
        // de Boor in homogeneous coordinates, on the stack for the degrees
        // drawings use: 11-14 % fewer instructions on spline-heavy inputs
        // than a heap buffer per point (callgrind, the chains identical).
        const ON_STACK: usize = 16;
        if p < ON_STACK {
            let mut d = [(V3::zeros(), 0.0); ON_STACK];
            self.de_boor(&mut d[..=p], k, u)
        } else {
            let mut d = vec![(V3::zeros(), 0.0); p + 1];
            self.de_boor(&mut d, k, u)
        }
    }

    fn breaks(&self) -> Vec<f64> {
        let (lo, hi) = self.domain();
        let mut b: Vec<f64> = vec![0.0];
        for &k in &self.knots[self.degree + 1..self.ctrl.len()] {
            let s = (k - lo) / (hi - lo);
            if s > *b.last().unwrap_or(&0.0) + 1e-12 && s < 1.0 - 1e-12 {
                b.push(s);
            }
        }
        b.push(1.0);
        b
    }
}

/// A smooth interpolant (Catmull-Rom) through fit points, for splines that
/// carry fit points but no control points.
pub struct FitPoints {
    /// The points the curve passes through, in order (mm), at least two;
    /// they are equally spaced in the curve's parameter.
    pub pts: Vec<P3>,
}

impl Curve for FitPoints {
    fn point(&self, s: f64) -> P3 {
        let n = self.pts.len();
        let x = s.clamp(0.0, 1.0) * (n - 1) as f64;
        let i = (x.floor() as usize).min(n - 2);
        let t = x - i as f64;
        let p = |j: isize| self.pts[j.clamp(0, n as isize - 1) as usize].coords;
        let i = i as isize;
        let (p0, p1, p2, p3) = (p(i - 1), p(i), p(i + 1), p(i + 2));
        let t2 = t * t;
        let t3 = t2 * t;
        P3::from(
            (p1 * 2.0
                + (p2 - p0) * t
                + (p0 * 2.0 - p1 * 5.0 + p2 * 4.0 - p3) * t2
                + (p1 * 3.0 - p0 - p2 * 3.0 + p3) * t3)
                * 0.5,
        )
    }

    fn breaks(&self) -> Vec<f64> {
        let n = self.pts.len() - 1;
        (0..=n).map(|i| i as f64 / n as f64).collect()
    }
}

/// The outcome of fitting one curve.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct FitStats {
    /// Segments (arcs and the odd line) emitted.
    pub pieces: u64,
    /// Lines a polyline would need at the same tolerance.
    pub chords: u64,
    /// The work bound ([`MAX_STEPS`]) was reached: the rest of the curve
    /// was drawn with chords.
    pub truncated: bool,
    /// The pieces reached the number allowed before the curve was done:
    /// fitting stopped there, short of the curve's end.
    pub over_budget: bool,
}

const SAMPLES: usize = 16;
/// The sample points `1..SAMPLES` of an interval, coarse to fine (halves,
/// quarters, eighths, sixteenths).
const SAMPLE_ORDER: [usize; SAMPLES - 1] = [8, 4, 12, 2, 6, 10, 14, 1, 3, 5, 7, 9, 11, 13, 15];
const MAX_DEPTH: u32 = 30;
/// Intervals tried per curve: whatever the curve and the tolerance,
/// fitting one curve is bounded work (about 5 million curve evaluations).
pub const MAX_STEPS: u64 = 1 << 18;

/// Fit `curve` with biarcs within `tol`, appending segments (all at the
/// start's z) to `out`, stopping once `max_pieces` are out (the last
/// biarc's second arc may pass it by one): a caller with a bound on the
/// drawing's size (the import's guard against bombs) passes what is left
/// of it, so one curve cannot do the work of fitting far past the bound
/// before the bound is looked at.
pub fn fit_biarcs(curve: &dyn Curve, tol: f64, max_pieces: usize, out: &mut Vec<Segment>) -> FitStats {
    let parallel = rayon::current_num_threads() > 1;
    fit_with(curve, tol, max_pieces, MAX_STEPS, parallel, out)
}

/// [`fit_biarcs`] on the calling thread only: for callers that fit many
/// curves at once, one a thread.
pub fn fit_biarcs_one_by_one(curve: &dyn Curve, tol: f64, max_pieces: usize, out: &mut Vec<Segment>) -> FitStats {
    fit_with(curve, tol, max_pieces, MAX_STEPS, false, out)
}

/// [`fit_biarcs`] with the step bound given, and the waves on or off (the
/// same result either way: the tests compare them).
fn fit_with(
    curve: &dyn Curve,
    tol: f64,
    max_pieces: usize,
    max_steps: u64,
    parallel: bool,
    out: &mut Vec<Segment>,
) -> FitStats {
    let tol = tol.max(1e-9);
    let z = curve.point(0.0).z;
    let before = out.len();
    let mut budget = Budget {
        steps: max_steps,
        end: before.saturating_add(max_pieces),
        over: false,
    };
    let breaks = curve.breaks();
    let intervals = breaks.len().saturating_sub(1);
    let fit = |k: usize, budget: &mut Budget, out: &mut Vec<Segment>| {
        let ends = [
            (breaks[k], curve.point(breaks[k])),
            (breaks[k + 1], curve.point(breaks[k + 1])),
        ];
        fit_interval(curve, ends, tol, z, 0, budget, out);
    };
    let mut k = 0;
    if parallel && intervals >= PARALLEL_INTERVALS {
        k = fit_waves(intervals, &fit, &mut budget, out);
    }
    // What is left after the waves (all of it for a short curve) one
    // interval after the other.
    while k < intervals && !budget.over {
        fit(k, &mut budget, out);
        k += 1;
    }
    let pieces = &out[before..];
    FitStats {
        pieces: pieces.len() as u64,
        chords: pieces.iter().map(|s| chords_for(s, tol)).sum(),
        truncated: budget.steps == 0,
        over_budget: budget.over,
    }
}

/// Curves of at least this many intervals (between breaks) are fitted
/// in parallel waves; shorter ones cost less than handing them out.
const PARALLEL_INTERVALS: usize = 4;
/// Intervals fitted at once in a wave.
const WAVE: usize = 64;

/// One interval fitted on its own, ahead of its turn.
struct Trial {
    pieces: Vec<Segment>,
    /// Steps it took.
    used: u64,
    /// It took every step it was given.
    exhausted: bool,
    /// It stopped because its pieces ran out.
    over: bool,
}

/// Fit the intervals of a curve in waves of [`WAVE`], each interval of a
/// wave on its own (rayon), then taken in order: a trial whose budget
/// checks would have gone the same way with the budget its turn actually
/// leaves is exactly what the one-by-one fit gives, and is used as it is;
/// any other interval is fitted again, in turn, with the real budget. So
/// the pieces, the stats and the stopping point are those of the
/// sequential fit, bit for bit, on any number of threads.
///
/// Work stays bounded: a trial gets at most `steps / WAVE` steps, so a
/// wave wastes at most the steps left, and only a trial that ran out of
/// them (and whose interval then takes at least as many in turn) or a
/// wave near the end of the budget wastes any. Returns the number of
/// intervals done (all of them, or up to where the budget ended the fit,
/// or where too few steps are left to be worth a wave).
fn fit_waves(
    intervals: usize,
    fit: &(dyn Fn(usize, &mut Budget, &mut Vec<Segment>) + Sync),
    budget: &mut Budget,
    out: &mut Vec<Segment>,
) -> usize {
    use rayon::prelude::*;
    let mut k = 0;
    while k < intervals && !budget.over {
        let wave = (intervals - k).min(WAVE);
        let cap = budget.steps / wave as u64;
        if cap == 0 {
            break;
        }
        // Pieces each trial may make: what is left for the whole curve.
        let room = budget.end.saturating_sub(out.len());
        let trials: Vec<Trial> = (k..k + wave)
            .into_par_iter()
            .map(|i| {
                let mut b = Budget {
                    steps: cap,
                    end: room,
                    over: false,
                };
                let mut pieces = Vec::new();
                fit(i, &mut b, &mut pieces);
                Trial {
                    pieces,
                    used: cap - b.steps,
                    exhausted: b.steps == 0,
                    over: b.over,
                }
            })
            .collect();
        for (i, t) in (k..).zip(trials) {
            // The same run as in turn when no check could differ: the
            // steps never ran out in the trial and do not in turn (each
            // call sees at least one left), and the pieces never reached
            // what is left in turn (the trial's end is at least that).
            let left = budget.end.saturating_sub(out.len());
            if !t.exhausted && !t.over && t.used < budget.steps && t.pieces.len() < left {
                budget.steps -= t.used;
                out.extend(t.pieces);
            } else {
                fit(i, budget, out);
            }
            if budget.over {
                return i + 1;
            }
        }
        k += wave;
    }
    k
}

/// What one curve's fit may still spend.
struct Budget {
    /// Intervals that may still be tried ([`MAX_STEPS`] at the start).
    steps: u64,
    /// `out` may grow to this length; reaching it sets `over`.
    end: usize,
    /// The pieces ran out: stop.
    over: bool,
}

/// Lines a polyline needs to follow `piece` within `tol`: one for a line,
/// for an arc of radius r the fewest equal chords whose sagitta
/// r·(1 − cos(φ/2)) stays within `tol`. The fitted pieces lie within `tol`
/// of the curve, so their chord count is the polyline's at the same
/// tolerance, found in one pass over the pieces. (Counting by bisecting
/// the curve itself cost four times the fit: chords converge as h², arcs
/// as h³, so the bisection went far deeper than the fit.)
fn chords_for(piece: &Segment, tol: f64) -> u64 {
    let (Some(r), Some(sweep)) = (piece.radius(), piece.sweep()) else {
        return 1;
    };
    if !(r.is_finite() && sweep.is_finite() && r > 0.0) {
        return 1;
    }
    let step = chord_angle(r, tol);
    // A chord per step, bounded: a near-zero step (a huge radius against a
    // tiny tolerance) must not turn into an absurd count.
    (sweep.abs() / step).ceil().clamp(1.0, 1e12) as u64
}

fn xy(p: P3, z: f64) -> P3 {
    P3::new(p.x, p.y, z)
}

fn unit_xy(v: V3) -> Option<V3> {
    V3::new(v.x, v.y, 0.0).try_normalize(1e-300)
}

/// Unit tangents at the ends of `[t0, t1]`, given the curve's points
/// there (`c0`, `c1`: each is evaluated once for the whole fit).
fn tangents(curve: &dyn Curve, (t0, c0): (f64, P3), (t1, c1): (f64, P3)) -> (Option<V3>, Option<V3>) {
    // Second-order one-sided differences: the tangent error is O(h^2), so a
    // circle given as a spline fits with arcs on the circle itself.
    let h = (t1 - t0) * 1e-4;
    let d = |t: f64, p0: P3, h: f64| {
        let p0 = p0.coords;
        let p1 = curve.point(t + h).coords;
        let p2 = curve.point(t + 2.0 * h).coords;
        (p1 * 4.0 - p0 * 3.0 - p2) * h.signum()
    };
    (unit_xy(d(t0, c0, h)), unit_xy(d(t1, c1, -h)))
}

/// Fit `[t0, t1]` (given with the curve's points there) with one biarc
/// within `tol`, or halve it.
fn fit_interval(
    curve: &dyn Curve,
    [(t0, c0), (t1, c1)]: [(f64, P3); 2],
    tol: f64,
    z: f64,
    depth: u32,
    budget: &mut Budget,
    out: &mut Vec<Segment>,
) {
    if out.len() >= budget.end {
        budget.over = true;
    }
    if budget.over {
        return;
    }
    let p0 = xy(c0, z);
    let p1 = xy(c1, z);
    if budget.steps == 0 {
        if p0 != p1 {
            out.push(Segment::line(p0, p1));
        }
        return;
    }
    budget.steps -= 1;
    if let (Some(d0), Some(d1)) = tangents(curve, (t0, c0), (t1, c1))
        && let Some(pieces) = biarc(p0, d0, p1, d1)
    {
        // Each arc's frame once, not once per sample (its angles cost two
        // atan2): the same verdicts as `Segment::distance_xy(q) <= tol`,
        // whose arcs go through the same frame (the samples are at the
        // pieces' z); `ArcFrame::within` settles most of them without
        // trigonometry.
        let frames = pieces.each_ref().map(|s| s.arc().map(ArcFrame::new));
        let within = |k: usize, q: &P3| match &frames[k] {
            Some(f) => f.within(q, tol),
            None => pieces[k].distance_xy(q) <= tol,
        };
        // Within the tolerance when every sample is near one of the two
        // arcs. Most trials that fail do so at a few samples, so the
        // samples are taken coarse to fine and the first one too far
        // decides; a sample is first measured against the arc of its half.
        // Only the work changes: the same samples, the same distances, the
        // same verdict (a distance that is NaN counts as too far, as it did
        // when the largest distance was taken). On a spline-heavy input
        // (a fuzz input, 6 splines fitted with 9,402 arcs) the whole import
        // took 407 M instructions instead of 642 M (callgrind).
        let near = |k: usize| {
            let q = xy(curve.point(t0 + (t1 - t0) * k as f64 / SAMPLES as f64), z);
            let (a, b) = if k < SAMPLES / 2 { (0, 1) } else { (1, 0) };
            within(a, &q) || within(b, &q)
        };
        if SAMPLE_ORDER.iter().all(|&k| near(k)) {
            out.extend(pieces.into_iter().filter(|s| s.start() != s.end()));
            return;
        }
    }
    if depth >= MAX_DEPTH || (p1 - p0).norm() <= tol * 1e-3 {
        if p0 != p1 {
            out.push(Segment::line(p0, p1));
        }
        return;
    }
    // The halves share the middle point: evaluated once.
    let tm = 0.5 * (t0 + t1);
    let m = (tm, curve.point(tm));
    fit_interval(curve, [(t0, c0), m], tol, z, depth + 1, budget, out);
    fit_interval(curve, [m, (t1, c1)], tol, z, depth + 1, budget, out);
}

/// The arc from `a`, leaving along unit tangent `t`, to `b` (a line when
/// `b` lies straight ahead).
fn arc_from_tangent(a: P3, t: V3, b: P3) -> Segment {
    let c = b - a;
    let n = V3::new(-t.y, t.x, 0.0);
    let den = 2.0 * n.dot(&c);
    let cc = c.norm_squared();
    if den.abs() <= 1e-12 * cc.sqrt() || cc / den.abs() > 1e7 * cc.sqrt() {
        return Segment::line(a, b);
    }
    let r = cc / den;
    Segment::arc_xy(a, b, a + n * r, r > 0.0)
}

/// Two tangent-continuous arcs from `p0` (tangent `t0`) to `p1` (tangent
/// `t1`), with equal tangent lengths. `None` when no such biarc exists.
pub fn biarc(p0: P3, t0: V3, p1: P3, t1: V3) -> Option<[Segment; 2]> {
    let v = p1 - p0;
    let vv = v.norm_squared();
    if vv == 0.0 {
        return None;
    }
    let t = t0 + t1;
    let vt = v.dot(&t);
    let denom = 2.0 * (1.0 - t0.dot(&t1));
    let d = if denom < 1e-12 {
        if vt <= 0.0 {
            return None;
        }
        vv / (2.0 * vt)
    } else {
        (-vt + (vt * vt + denom * vv).sqrt()) / denom
    };
    if !(d.is_finite() && d > 0.0) {
        return None;
    }
    let j = P3::from((p0.coords + t0 * d + p1.coords - t1 * d) * 0.5);
    let first = arc_from_tangent(p0, t0, j);
    let second = arc_from_tangent(p1, -t1, j).reversed();
    Some([first, second])
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn max_dev(curve: &dyn Curve, segs: &[Segment]) -> f64 {
        (0..=4000)
            .map(|i| {
                let q = curve.point(i as f64 / 4000.0);
                segs.iter().map(|s| s.distance_xy(&q)).fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    fn tangent_continuous(segs: &[Segment]) -> bool {
        let dir = |s: &Segment, at_end: bool| -> V3 { if at_end { s.end_tangent() } else { s.start_tangent() } };
        segs.windows(2)
            .all(|w| (dir(&w[0], true) - dir(&w[1], false)).norm() < 1e-3)
    }

    #[test]
    fn ellipse_within_tolerance_and_smooth() {
        let e = Conic {
            c: P3::new(1.0, 2.0, 0.0),
            u: V3::new(10.0, 0.0, 0.0),
            v: V3::new(0.0, 4.0, 0.0),
            t0: 0.0,
            sweep: TAU,
        };
        let mut out = Vec::new();
        let st = fit_biarcs(&e, 0.001, usize::MAX, &mut out);
        assert!(max_dev(&e, &out) <= 0.0011, "{}", max_dev(&e, &out));
        assert!(tangent_continuous(&out));
        assert!(st.pieces < st.chords / 2, "{st:?}");
        // Ends meet exactly.
        assert_eq!(out.first().unwrap().start(), e.point(0.0));
        for w in out.windows(2) {
            assert!((w[0].end() - w[1].start()).norm() < 1e-12);
        }
    }

    #[test]
    fn chord_count_is_the_fewest_within_tolerance() {
        let sagitta = |r: f64, sweep: f64, n: u64| r * (1.0 - (sweep / n as f64 / 2.0).cos());
        for (r, sweep, tol) in [
            (5.0f64, 1.0f64, 0.001),
            (0.3, -2.5, 1e-4),
            (100.0, 0.01, 1e-6),
            (2.0, 3.0, 0.5),
        ] {
            let c = P3::new(1.0, 1.0, 0.0);
            let a = c + V3::new(r, 0.0, 0.0);
            let b = c + V3::new(r * sweep.cos(), r * sweep.sin(), 0.0);
            let arc = Segment::arc_xy(a, b, c, sweep > 0.0);
            let n = chords_for(&arc, tol);
            assert!(
                sagitta(r, sweep.abs(), n) <= tol * (1.0 + 1e-9),
                "{r} {sweep} {tol}: {n}"
            );
            assert!(n == 1 || sagitta(r, sweep.abs(), n - 1) > tol, "{r} {sweep} {tol}: {n}");
        }
        // A line is one chord, and so is an arc within tolerance of its chord.
        let line = Segment::line(P3::origin(), P3::new(3.0, 4.0, 0.0));
        assert_eq!(chords_for(&line, 1e-6), 1);
        let flat = Segment::arc_xy(P3::new(1.0, 0.0, 0.0), P3::new(0.0, 1.0, 0.0), P3::origin(), true);
        assert_eq!(chords_for(&flat, 2.0), 1);
    }

    #[test]
    fn circle_as_spline_gives_few_arcs() {
        // A rational quadratic quarter circle is exactly a circle.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let n = Nurbs::new(
            2,
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            vec![P3::new(5.0, 0.0, 0.0), P3::new(5.0, 5.0, 0.0), P3::new(0.0, 5.0, 0.0)],
            vec![1.0, s, 1.0],
        )
        .unwrap();
        assert!((n.point(0.5).coords.norm() - 5.0).abs() < 1e-12);
        let mut out = Vec::new();
        let st = fit_biarcs(&n, 1e-6, usize::MAX, &mut out);
        assert!(st.pieces <= 2, "{st:?}");
        assert!(max_dev(&n, &out) < 1e-6);
    }

    #[test]
    fn cubic_spline_with_corner_knot() {
        let n = Nurbs::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0],
            (0..7).map(|i| P3::new(i as f64, ((i * 7) % 5) as f64, 0.0)).collect(),
            vec![],
        )
        .unwrap();
        let mut out = Vec::new();
        fit_biarcs(&n, 0.001, usize::MAX, &mut out);
        assert!(max_dev(&n, &out) <= 0.0011);
    }

    #[test]
    fn the_samples_are_every_inner_sample_once() {
        let mut k = SAMPLE_ORDER.to_vec();
        k.sort_unstable();
        assert_eq!(k, (1..SAMPLES).collect::<Vec<_>>());
    }

    #[test]
    fn a_fit_stops_once_its_pieces_run_out() {
        let zigzag = Nurbs::new(
            3,
            vec![],
            (0..60).map(|i| P3::new(i as f64, (i % 2) as f64 * 3.0, 0.0)).collect(),
            vec![],
        )
        .unwrap();
        let mut all = Vec::new();
        let st = fit_biarcs(&zigzag, 0.001, usize::MAX, &mut all);
        assert!(!st.over_budget && all.len() > 200, "{st:?}");
        // Exactly enough: the same pieces.
        let mut out = Vec::new();
        let st = fit_biarcs(&zigzag, 0.001, all.len(), &mut out);
        assert!(!st.over_budget, "{st:?}");
        assert_eq!(out, all);
        // Far too few: the fit stops there (a biarc may pass the bound by
        // its second arc), and the pieces it gave are the curve's first.
        let mut out = vec![Segment::line(P3::origin(), P3::new(0.0, -1.0, 0.0))];
        let st = fit_biarcs(&zigzag, 0.001, 20, &mut out);
        assert!(st.over_budget, "{st:?}");
        assert!((20..=21).contains(&st.pieces), "{st:?}");
        assert_eq!(&out[1..], &all[..out.len() - 1]);
    }

    #[test]
    fn bad_knots_fall_back_to_clamped_uniform() {
        let n = Nurbs::new(
            3,
            vec![1.0, 0.0],
            (0..5).map(|i| P3::new(i as f64, 0.0, 0.0)).collect(),
            vec![],
        )
        .unwrap();
        assert_eq!(n.point(0.0), P3::new(0.0, 0.0, 0.0));
        assert_eq!(n.point(1.0), P3::new(4.0, 0.0, 0.0));
    }
    /// The rational B-spline from its definition: every basis function
    /// raised from degree 0 by the Cox-de Boor recursion and summed over
    /// every control point, with no knot span search and no recurrence
    /// over control points (`u` inside the domain).
    fn nurbs_by_basis(n: &Nurbs, u: f64) -> P3 {
        let k = &n.knots;
        let hi = n.domain().1;
        // Degree 0: the half-open spans, except that the domain's last
        // non-empty span also holds its right end.
        let last = n.ctrl.len();
        let mut basis: Vec<f64> = (0..k.len() - 1)
            .map(|i| {
                let inside = k[i] <= u && u < k[i + 1];
                let at_end = u == hi && k[i] < k[i + 1] && k[i + 1] == hi && i < last;
                if inside || at_end { 1.0 } else { 0.0 }
            })
            .collect();
        for q in 1..=n.degree {
            basis = (0..basis.len() - 1)
                .map(|i| {
                    let mut b = 0.0;
                    if k[i + q] > k[i] {
                        b += (u - k[i]) / (k[i + q] - k[i]) * basis[i];
                    }
                    if k[i + q + 1] > k[i + 1] {
                        b += (k[i + q + 1] - u) / (k[i + q + 1] - k[i + 1]) * basis[i + 1];
                    }
                    b
                })
                .collect();
        }
        let (mut sum, mut w) = (V3::zeros(), 0.0);
        for ((c, &wi), &b) in n.ctrl.iter().zip(&n.weights).zip(&basis) {
            sum += c.coords * (b * wi);
            w += b * wi;
        }
        P3::from(sum / w)
    }

    proptest::proptest! {
        /// The parallel waves give the one-by-one fit's pieces, stats and
        /// stopping point exactly, with bounds small enough that trials
        /// run out of steps (chords follow), run out of pieces, or stop
        /// mid-wave: long zigzag splines (more intervals than a wave) and
        /// short ones.
        #[test]
        fn waves_fit_what_one_by_one_fits(
            count in 4usize..150,
            ys in proptest::collection::vec(-5.0f64..5.0, 150),
            tol in proptest::sample::select(vec![1e-4, 1e-3, 0.05]),
            max_steps in proptest::sample::select(vec![0u64, 1, 7, 64, 65, 300, 2_000, MAX_STEPS]),
            max_pieces in proptest::sample::select(vec![0usize, 1, 5, 40, 400, usize::MAX]),
        ) {
            let ctrl: Vec<P3> = (0..count).map(|i| P3::new(i as f64, ys[i], 0.0)).collect();
            let n = Nurbs::new(3, vec![], ctrl, vec![]).unwrap();
            let (mut one, mut waves) = (vec![Segment::line(P3::origin(), P3::new(1.0, 0.0, 0.0))], Vec::new());
            waves.clone_from(&one);
            let a = fit_with(&n, tol, max_pieces, max_steps, false, &mut one);
            let b = fit_with(&n, tol, max_pieces, max_steps, true, &mut waves);
            proptest::prop_assert_eq!(a, b);
            proptest::prop_assert_eq!(one, waves);
        }

        /// de Boor's recurrence, run in place from the left, is the curve
        /// the basis functions define: any degree (the stack and the heap
        /// working buffers), repeated knots (corners), any positive
        /// weights, at the domain's ends and at the knots themselves.
        #[test]
        fn de_boor_is_the_basis_function_sum(
            degree in 1usize..=18,
            extra in 0usize..6,
            steps in proptest::collection::vec(0u8..3, 24),
            coords in proptest::collection::vec(-50.0f64..50.0, 72),
            weights in proptest::collection::vec(0.2f64..5.0, 24),
            at in proptest::collection::vec(0.0f64..=1.0, 8),
        ) {
            let count = degree + 1 + extra;
            let ctrl: Vec<P3> = (0..count)
                .map(|i| P3::new(coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]))
                .collect();
            // Clamped ends; inner knots that step by 0 (a repeated knot),
            // 1 or 2.
            let mut knots = vec![0.0; degree + 1];
            let mut t = 0.0;
            for s in &steps[..count - degree - 1] {
                t += f64::from(*s);
                knots.push(t);
            }
            let end = t + 1.0;
            knots.extend(std::iter::repeat_n(end, degree + 1));
            let n = Nurbs::new(degree, knots.clone(), ctrl, weights[..count].to_vec()).unwrap();
            proptest::prop_assert_eq!(&n.knots, &knots);
            let inner = knots[degree + 1..count].iter().map(|k| k / end);
            for s in at.iter().copied().chain([0.0, 1.0]).chain(inner) {
                let got = n.point(s);
                let want = nurbs_by_basis(&n, s * end);
                proptest::prop_assert!((got - want).norm() < 1e-9, "s {}: {} against {}", s, got, want);
            }
        }
    }
}
