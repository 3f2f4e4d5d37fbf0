//! G5.2/G5.3 NURBS blocks of the ISO reader, as LinuxCNC 2.9 runs them.
//!
//! ```text
//! G5.2 X0 Y1 P1 L3     open a block: the current point is the first
//!      X2 Y2 P1        control point, each X Y P line adds one (P: weight)
//!      X2 Y0 P1
//! G5.3                 close it: the curve is cut now
//! ```
//!
//! The interpreter side follows `convert_nurbs` (LinuxCNC's
//! `interp_convert.cc`): the order is 3 unless an L word above 3 sets it
//! (on any line of the block); a first line without X and Y may give the
//! start point's weight in P; every control point after the first needs
//! X and Y together and a positive P; G5.3 needs as many control points as
//! the order and leaves no motion mode in effect. Control points are read
//! against the block's start point (LinuxCNC moves its current point only
//! at G5.3), so in G91 each one is an offset from the start.
//!
//! The motion side follows `NURBS_FEED` in LinuxCNC's `emccanon.cc`, which
//! is what a LinuxCNC machine cuts (its standalone `rs274` only prints
//! `NURBS_FEED(n, ...)`): a clamped uniform knot vector
//! (`knot_vector_creator`: k zeros, 1 .. n-k+1, k times n-k+2), the
//! parameter range [0, n-k+2] cut into 4(n+1) equal steps, and each step
//! joined by a biarc (two tangent arcs, equal tangent lengths) between the
//! curve points (`nurbs_point`, the rational Cox-de Boor sum) with
//! tangents taken by the central difference over ±1e-5 of the parameter
//! (`nurbs_tangent`, one-sided at the ends). An arc whose chord is nearly
//! along its start tangent (LinuxCNC's `2·(chord × tangent)` within 1e-6
//! program units) is a straight feed, as in `emccanon.cc`'s `arc()`.
//!
//! Where LinuxCNC's arithmetic breaks down we go straight: when the two
//! tangents of a step are parallel its biarc equation has no finite root
//! (LinuxCNC then computes NaN, or emits nothing for the step), and we cut
//! the step as one line. We also cut an arc whose chord is under 1 µm as a
//! line (at most half a micron off), so no arc in the output is so short
//! that rounding its end points makes it a full circle, and one that bulges
//! less than a nanometre from its chord (its centre could lie beyond any
//! machine's travel).
//!
//! Refused, naming the line, where LinuxCNC would cut something other
//! than the curve or drop it silently: a plane other than G17 (LinuxCNC
//! does not check, and its arcs would then turn in the wrong plane),
//! cutter compensation, G93, Z/A/B/C or polar words on a control point
//! (LinuxCNC ignores them), a first control point without P (LinuxCNC
//! weighs it -1), another motion, a unit, plane or offset change or a
//! program end before G5.3 (LinuxCNC drops the block's points or reads
//! them in the new frame), and an order above [`MAX_ORDER`].

use super::{FeedMode, GcodeError, IsoInterpreter};
use crate::geometry::{P2, P3, Plane, V2};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record};
use std::collections::VecDeque;

/// Highest order (L) we evaluate. LinuxCNC has no limit, but its basis
/// recursion doubles its work with each order, so it could not run much
/// higher orders either; real programs use 3 or 4.
pub const MAX_ORDER: u32 = 20;

/// LinuxCNC's `DU`: the parameter step of the tangent's central difference.
const DU: f64 = 1e-5;

/// `emccanon.cc`'s `small`: below this `2·(chord × tangent)` (program
/// units) a biarc half is a straight feed.
const ARC_DEN_MIN: f64 = 1e-6;

/// Arcs with a chord under this (mm) are cut as lines (see the module
/// notes); the sagitta of such an arc is at most half of it.
const MIN_ARC_CHORD_MM: f64 = 1e-3;

/// Arcs that bulge less than this (mm) from their chord are cut as lines:
/// a nearly straight step can give a radius beyond any machine's travel.
const MIN_ARC_BULGE_MM: f64 = 1e-6;

/// One control point: X, Y in program units and program coordinates, and
/// its weight (> 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ControlPoint {
    pub(super) p: P2,
    pub(super) w: f64,
}

/// A G5.2 block being read: its control points so far (the start point
/// first), its order, and the line that opened it (for errors).
#[derive(Debug, Clone)]
pub(super) struct NurbsBlock {
    pub(super) opened: u64,
    pub(super) order: u32,
    pub(super) points: Vec<ControlPoint>,
}

/// One move of the cut curve, in program units and coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Piece {
    /// A straight feed to the point.
    Line(P2),
    /// An arc to `to` about `center`, counter-clockwise when `ccw`.
    Arc { to: P2, center: P2, ccw: bool },
}

/// LinuxCNC's `knot_vector_creator(n, k)`: n + 1 control points, order k;
/// clamped and uniform, from 0 to n - k + 2.
pub(super) fn knot_vector(n: usize, k: usize) -> Vec<f64> {
    (0..=n + k)
        .map(|i| {
            if i < k {
                0.0
            } else if i <= n {
                (i - k + 1) as f64
            } else {
                (n + 2 - k) as f64
            }
        })
        .collect()
}

/// The curve point at parameter `u` (0 ..= n - k + 2): the rational sum
/// of the order-`k` B-spline basis (Cox-de Boor) over the control points.
/// Equal, up to rounding, to LinuxCNC's `nurbs_point`, whose basis counts
/// a parameter on a knot in both neighbouring spans and divides the
/// doubling out again.
pub(super) fn curve_point(u: f64, k: usize, pts: &[ControlPoint], knots: &[f64]) -> P2 {
    let n = pts.len() - 1;
    // The span [knots[s], knots[s+1]) holding u; the last span is closed.
    let s = if u >= knots[n + 1] {
        n
    } else {
        (knots[..=n].partition_point(|&t| t <= u).max(1) - 1).max(k - 1)
    };
    // Basis functions of orders 1..=k that are non-zero on the span
    // (The NURBS Book, A2.2): b[j] is N(s - (k-1) + j).
    let mut b = vec![0.0; k];
    let mut left = vec![0.0; k];
    let mut right = vec![0.0; k];
    b[0] = 1.0;
    for j in 1..k {
        left[j] = u - knots[s + 1 - j];
        right[j] = knots[s + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            let den = right[r + 1] + left[j - r];
            let t = if den == 0.0 { 0.0 } else { b[r] / den };
            b[r] = saved + right[r + 1] * t;
            saved = left[j - r] * t;
        }
        b[j] = saved;
    }
    let (mut num, mut den) = (V2::zeros(), 0.0);
    for (j, nb) in b.iter().enumerate() {
        let cp = &pts[s + 1 - k + j];
        num += cp.p.coords * (nb * cp.w);
        den += nb * cp.w;
    }
    P2::from(num / den)
}

/// LinuxCNC's `nurbs_tangent`: the unit direction of the chord between the
/// curve points at u ± 1e-5, clamped to the parameter range.
fn curve_tangent(u: f64, k: usize, pts: &[ControlPoint], knots: &[f64], umax: f64) -> V2 {
    let (lo, hi) = ((u - DU).max(0.0), (u + DU).min(umax));
    let d = (curve_point(hi, k, pts, knots) - curve_point(lo, k, pts, knots)) / (hi - lo);
    unit(d)
}

/// `emccanon.cc`'s `unit`: the vector scaled to length 1 (zero stays zero).
fn unit(v: V2) -> V2 {
    let h = v.x.hypot(v.y);
    if h != 0.0 { v / h } else { v }
}

/// `emccanon.cc`'s `arc()`: from `p0` to `p1`, leaving `p0` along the unit
/// tangent `t`: an arc tangent to `t`, or a line when the chord runs along
/// `t`.
fn arc_piece(p0: P2, p1: P2, t: V2, out: &mut Vec<Piece>) {
    let c = p1 - p0;
    let den = 2.0 * (c.y * t.x - c.x * t.y);
    if den.abs() > ARC_DEN_MIN {
        // r < 0: the centre is on the left, counter-clockwise.
        let r = -(c.x * c.x + c.y * c.y) / den;
        out.push(Piece::Arc {
            to: p1,
            center: p0 + V2::new(t.y * r, -t.x * r),
            ccw: r < 0.0,
        });
    } else {
        out.push(Piece::Line(p1));
    }
}

/// `emccanon.cc`'s `biarc()` with r = 1 (equal tangent lengths): two
/// tangent arcs from `p0` (tangent `ts`) to `p4` (tangent `te`). When the
/// tangents are parallel the equation has no finite root: one line.
fn biarc(p0: P2, ts: V2, p4: P2, te: V2, out: &mut Vec<Piece>) {
    let (ts, te) = (unit(ts), unit(te));
    let v = p0 - p4;
    let c = v.dot(&v);
    let b = 2.0 * v.dot(&(ts + te));
    let a = 2.0 * (ts.dot(&te) - 1.0);
    let disc = b * b - 4.0 * a * c;
    // a < 0 whenever the tangents differ, and then the roots have
    // opposite signs; LinuxCNC takes the larger.
    if a >= 0.0 || a.is_nan() || disc < 0.0 {
        out.push(Piece::Line(p4));
        return;
    }
    let sq = disc.sqrt();
    let beta = ((-b - sq) / 2.0 / a).max((-b + sq) / 2.0 / a);
    let alpha = beta;
    let p1 = p0 + ts * alpha;
    let p3 = p4 - te * beta;
    let p2 = P2::from((p1.coords * beta + p3.coords * alpha) / (alpha + beta));
    if !(p2.x.is_finite() && p2.y.is_finite()) {
        out.push(Piece::Line(p4));
        return;
    }
    let tm = unit(p3 - p2);
    arc_piece(p0, p2, ts, out);
    arc_piece(p2, p4, tm, out);
}

/// LinuxCNC's `NURBS_FEED` (`emccanon.cc`): the moves that cut the curve
/// of order `k` through `pts` (at least `k` of them), in program units.
pub(super) fn nurbs_feed(pts: &[ControlPoint], k: usize) -> Vec<Piece> {
    let n = pts.len() - 1;
    let umax = (n + 2 - k) as f64;
    let div = 4 * pts.len();
    let knots = knot_vector(n, k);
    let mut out = Vec::with_capacity(2 * div);
    let mut p0 = curve_point(0.0, k, pts, &knots);
    let mut t0 = curve_tangent(0.0, k, pts, &knots, umax);
    for i in 1..=div {
        let u = umax * i as f64 / div as f64;
        let p1 = curve_point(u, k, pts, &knots);
        let t1 = curve_tangent(u, k, pts, &knots, umax);
        biarc(p0, t0, p1, t1, &mut out);
        (p0, t0) = (p1, t1);
    }
    out
}

impl IsoInterpreter {
    /// A G5.2 line: open the block (its first line) or add a control point.
    pub(super) fn nurbs_g52(&mut self, b: &super::Block, lineno: u64) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        if self.plane != Plane::Xy {
            return Err(err(
                "G5.2 NURBS blocks work in the XY plane (G17) only (LinuxCNC would turn its arcs in the selected plane)",
            ));
        }
        if self.comp.side.is_some() || self.comp.exit {
            return Err(err(
                "G5.2 cannot be used with cutter radius compensation on or as the first move after G40",
            ));
        }
        if self.feed_mode == FeedMode::InverseTime {
            return Err(err("G5.2 in inverse time feed (G93) is not supported"));
        }
        if [b'Z', b'A', b'B', b'C'].iter().any(|&l| b.word(l).is_some()) || b.polar.iter().any(Option::is_some) {
            return Err(err(
                "G5.2 control points take X, Y, P and L only (LinuxCNC ignores Z, A, B, C and polar words there)",
            ));
        }
        let (x, y, p) = (b.word(b'X'), b.word(b'Y'), b.word(b'P'));
        let first = self.nurbs.is_none();
        if x.is_some() != y.is_some() {
            return Err(err("G5.2: give both X and Y for a control point"));
        }
        let has_xy = x.is_some();
        if !first && !has_xy && p.is_some_and(|p| p > 0.0) {
            return Err(err(
                "G5.2: P without X and Y (the start point's weight) is allowed on the first line of the block only",
            ));
        }
        if !first && p.is_none_or(|p| p <= 0.0) {
            return Err(err("G5.2: every control point needs a positive weight P"));
        }
        if first && has_xy && p.is_none_or(|p| p <= 0.0) {
            // LinuxCNC takes the missing P as a weight of -1.
            return Err(err("G5.2: every control point needs a positive weight P"));
        }
        if self.feed_mode == FeedMode::PerMinute && self.feed_mm_per_min <= 0.0 {
            return Err(err("G5.2 NURBS block with no feed rate set (F is zero or missing)"));
        }
        let order = match b.word(b'L') {
            None => None,
            Some(l) if (l - l.round()).abs() <= 1e-4 && l.round() >= 0.0 => Some(l.round()),
            Some(l) => return Err(err(&format!("G5.2: L{l} must be a whole number (the order)"))),
        };
        if let Some(l) = order
            && l > f64::from(MAX_ORDER)
        {
            return Err(err(&format!(
                "G5.2: order L{l} is above {MAX_ORDER}, the highest supported"
            )));
        }
        let (u, off) = (self.unit(), self.offset());
        let to_program = |m: P3| P2::new((m.x - off.x) / u, (m.y - off.y) / u);
        let block = self.nurbs.get_or_insert_with(|| NurbsBlock {
            opened: lineno,
            order: 3,
            points: Vec::new(),
        });
        if first {
            let w = match p {
                Some(p) if !has_xy && p > 0.0 => p,
                _ => 1.0,
            };
            block.points.push(ControlPoint {
                p: to_program(self.pos),
                w,
            });
        }
        // LinuxCNC: only an L above 3 changes the order.
        if let Some(l) = order
            && l > 3.0
        {
            block.order = l as u32;
        }
        if has_xy {
            let w = p.unwrap_or(1.0);
            // The target from the block's start (LinuxCNC's current point
            // stays there until G5.3).
            let to = self.target(b, false, lineno)?;
            let block = self.nurbs.as_mut().expect("opened above");
            block.points.push(ControlPoint { p: to_program(to), w });
        }
        Ok(())
    }

    /// G5.3: cut the curve of the block opened by G5.2 and close it.
    pub(super) fn nurbs_g53(
        &mut self,
        b: &super::Block,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |m: String| GcodeError::at(lineno, m);
        let Some(block) = self.nurbs.take() else {
            return Err(err("G5.3 without G5.2 first (no NURBS block is open)".into()));
        };
        if [b'X', b'Y', b'Z', b'A', b'B', b'C']
            .iter()
            .any(|&l| b.word(l).is_some())
            || b.polar.iter().any(Option::is_some)
        {
            return Err(err("G5.3 takes no axis words: it only closes the NURBS block".into()));
        }
        let k = block.order as usize;
        if block.points.len() < k {
            return Err(err(format!(
                "G5.3: the NURBS block opened on line {} has {} control points (the start point included), fewer than its order L = {k}",
                block.opened,
                block.points.len()
            )));
        }
        let feed = self.feed_mm_per_min(lineno)?;
        let (u, off) = (self.unit(), self.offset());
        let z = self.pos.z;
        let to_machine = |p: P2| P3::new(p.x * u + off.x, p.y * u + off.y, z);
        let mut from = self.pos;
        for piece in nurbs_feed(&block.points, k) {
            let (kind, to) = match piece {
                Piece::Line(p) => (MotionKind::Line, to_machine(p)),
                Piece::Arc { to, center, ccw } => {
                    let to = to_machine(to);
                    let center = to_machine(center);
                    let chord = (to - from).xy().norm();
                    let radius = (from - center).xy().norm();
                    if chord < MIN_ARC_CHORD_MM || chord * chord / (8.0 * radius) < MIN_ARC_BULGE_MM {
                        (MotionKind::Line, to)
                    } else {
                        let arc = ArcData {
                            center,
                            ccw,
                            plane: Plane::Xy,
                            extra_turns: 0,
                        };
                        (MotionKind::Arc(arc), to)
                    }
                }
            };
            let mut m = Motion::from_block(kind, to, Some(feed), self.beam, lineno);
            m.tool = self.tool_state();
            out.push_back(Record::Move(m));
            from = to;
        }
        // LinuxCNC's current point becomes the last control point exactly.
        let last = block.points.last().expect("at least the order's count").p;
        self.pos = to_machine(last);
        self.motion = None;
        Ok(())
    }

    /// While a G5.2 block is open, refuse what LinuxCNC would not cut as
    /// the curve: another motion, a change of units, plane, coordinate
    /// system or offsets, compensation, G93, or the program's end.
    pub(super) fn nurbs_guard(&self, b: &super::Block, lineno: u64) -> Result<(), GcodeError> {
        let Some(block) = &self.nurbs else {
            return Ok(());
        };
        let refuse = |what: String| {
            Err(GcodeError::at(
                lineno,
                format!(
                    "{what} inside the G5.2 NURBS block opened on line {}: close it with G5.3 first",
                    block.opened
                ),
            ))
        };
        for &code in &b.g[..b.ng] {
            let same = match code {
                // The block's own codes, and what does not move or reframe.
                52 | 53 | 40 | 170 | 430 | 431 | 432 | 490 | 610 | 611 | 640 | 900 | 910 | 901 | 911 | 940 | 950
                | 970 | 980 | 990 => true,
                200 => self.inch,
                210 => !self.inch,
                400 => self.comp.side.is_none(),
                540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => {
                    [540u16, 550, 560, 570, 580, 590, 591, 592, 593][self.cs] == code
                }
                _ => false,
            };
            if !same {
                return refuse(super::fmt_code('G', code));
            }
        }
        if b.has_m(20) || b.has_m(300) {
            return refuse("the program end".into());
        }
        Ok(())
    }
}

#[cfg(test)]
#[path = "nurbs_tests.rs"]
mod tests;
