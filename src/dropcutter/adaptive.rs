//! Adaptive sampling along a pass: more CL points where the CL curve
//! bends, the idea of OpenCAMLib's AdaptivePathDropCutter.
//!
//! Between two CL points the machine moves in a straight line. The span is
//! accepted when the true CL curve, probed at its quarter points and
//! midpoint (three extra drops), stays within 3/4 of the chordal tolerance
//! of that line: if the curve bends one way over the span (its distance
//! from the chord concave), concavity bounds the distance between the
//! probes by 4/3 of theirs, so the whole span is within the tolerance;
//! otherwise it is split at the midpoint and each half is judged the
//! same way, down to a smallest step (vertical walls make the CL curve
//! jump, and no number of points straightens a jump).

use super::DropCutter;
use crate::geometry::line::point_segment_distance;
use crate::geometry::{P2, P3};
use rayon::prelude::*;

/// How finely to refine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adaptive {
    /// Largest distance of the true CL curve from the straight move
    /// between consecutive CL points (mm).
    pub chord_tol: f64,
    /// Spans this short (XY, mm) are not split further.
    pub min_step: f64,
}

impl Adaptive {
    /// Refine one pass whose points `cl` were dropped at `xy`, with the
    /// same floor. Spans are refined in parallel; the output starts and
    /// ends where the input does and keeps every input point.
    pub fn refine(&self, dc: &DropCutter, cl: &[P3], floor: f64) -> Vec<P3> {
        if cl.len() < 2 {
            return cl.to_vec();
        }
        let mut pieces: Vec<Vec<P3>> = cl
            .par_windows(2)
            .map(|w| {
                let mut out = vec![w[0]];
                self.span(dc, w[0], w[1], floor, 0, &mut out);
                out
            })
            .collect();
        let mut out: Vec<P3> = Vec::with_capacity(pieces.iter().map(Vec::len).sum::<usize>() + 1);
        for p in pieces.iter_mut() {
            out.append(p);
        }
        out.push(cl[cl.len() - 1]);
        out
    }

    /// Append the points strictly between `a` and `b` (not `b` itself).
    fn span(&self, dc: &DropCutter, a: P3, b: P3, floor: f64, depth: u32, out: &mut Vec<P3>) {
        let at = |t: f64| {
            let q: P2 = a.xy() + (b.xy() - a.xy()) * t;
            P3::new(q.x, q.y, dc.drop_above(q.x, q.y, floor))
        };
        let len = (b.xy() - a.xy()).norm();
        if len <= self.min_step || depth > 60 {
            return;
        }
        let mid = at(0.5);
        let probe = 0.75 * self.chord_tol;
        let ok = point_segment_distance(&mid, &a, &b) <= probe
            && point_segment_distance(&at(0.25), &a, &b) <= probe
            && point_segment_distance(&at(0.75), &a, &b) <= probe;
        if ok {
            return;
        }
        self.span(dc, a, mid, floor, depth + 1, out);
        out.push(mid);
        self.span(dc, mid, b, floor, depth + 1, out);
    }
}
