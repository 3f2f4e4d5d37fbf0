//! G5 (cubic) and G5.1 (quadratic) splines of the ISO reader, in the XY
//! plane, as LinuxCNC defines them:
//!
//! - `G5 X Y I J P Q`: a cubic Bézier from the current point P0 to the end
//!   P3 = (X, Y); the first control point is P0 + (I, J), the second
//!   P3 + (P, Q). On a G5 that follows a G5, I and J may be left out: they
//!   are then minus the previous P and Q, so the curves join smoothly.
//! - `G5.1 X Y I J`: a quadratic Bézier whose control point is
//!   P0 + (I, J).
//!
//! LinuxCNC's interpreter hands the curve to its motion planner (its
//! `rs274` prints `NURBS_FEED(...)` with no points), which follows the
//! exact curve. We turn it into straight feed moves by adaptive
//! subdivision: a piece is emitted as a line once every control point of
//! it lies within [`SPLINE_TOL_MM`] of its chord, and a Bézier lies in the
//! convex hull of its control points, so no point of the line is further
//! than that from the curve. G5.2/G5.3 NURBS blocks are `nurbs.rs`'s,
//! cut by LinuxCNC's biarcs; G5/G5.1 keep these lines, which stay within
//! 0.1 µm of the Bézier.

use super::{FeedMode, GcodeError, IsoInterpreter};
use crate::geometry::{P2, Plane};
use crate::model::toolpath::{Motion, MotionKind, Record};
use std::collections::VecDeque;

/// Largest distance (mm) between a spline and the lines that stand for it.
pub const SPLINE_TOL_MM: f64 = 1e-4;

/// Deepest subdivision: 2^20 pieces per block at most.
const MAX_DEPTH: u32 = 20;

/// Distance from `p` to the segment `a`-`b`.
fn seg_dist(p: P2, a: P2, b: P2) -> f64 {
    crate::geometry::line::point_segment_distance(&p, &a, &b)
}

/// End points of the lines standing for the cubic Bézier `c` (the start
/// point excluded), pushed in order.
pub(crate) fn flatten_cubic(c: [P2; 4], tol: f64, out: &mut Vec<P2>) {
    fn go(c: [P2; 4], tol: f64, depth: u32, out: &mut Vec<P2>) {
        let flat = seg_dist(c[1], c[0], c[3]).max(seg_dist(c[2], c[0], c[3])) <= tol;
        if flat || depth >= MAX_DEPTH {
            out.push(c[3]);
            return;
        }
        // de Casteljau at t = 1/2.
        let m = |a: P2, b: P2| P2::from((a.coords + b.coords) * 0.5);
        let (p01, p12, p23) = (m(c[0], c[1]), m(c[1], c[2]), m(c[2], c[3]));
        let (p012, p123) = (m(p01, p12), m(p12, p23));
        let mid = m(p012, p123);
        go([c[0], p01, p012, mid], tol, depth + 1, out);
        go([mid, p123, p23, c[3]], tol, depth + 1, out);
    }
    go(c, tol, 0, out);
}

/// The quadratic Bézier `q` as the cubic that traces the same curve.
pub(crate) fn quadratic_as_cubic(q: [P2; 3]) -> [P2; 4] {
    let k = 2.0 / 3.0;
    [
        q[0],
        P2::from(q[0].coords + (q[1] - q[0]) * k),
        P2::from(q[2].coords + (q[1] - q[2]) * k),
        q[2],
    ]
}

impl IsoInterpreter {
    /// A G5 (`code` 50) or G5.1 (51) block.
    pub(super) fn spline(
        &mut self,
        b: &super::Block,
        code: u16,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        let name = super::fmt_code('G', code);
        if self.plane != Plane::Xy {
            return Err(err(&format!("{name} splines work in the XY plane (G17) only")));
        }
        if self.comp.side.is_some() {
            return Err(err(&format!(
                "{name} splines cannot be used with cutter radius compensation on"
            )));
        }
        if self.feed_mode == FeedMode::InverseTime {
            return Err(err(&format!(
                "{name} splines in inverse time feed (G93) are not supported"
            )));
        }
        if b.word(b'Z').is_some() || b.word(b'A').is_some() || b.word(b'B').is_some() || b.word(b'C').is_some() {
            return Err(err(&format!("{name} splines move X and Y only (no Z, A, B, C words)")));
        }
        let feed = self.feed_mm_per_min(lineno)?;
        let to = self.target(b, false, lineno)?;
        let u = self.unit();
        let p0 = P2::new(self.pos.x, self.pos.y);
        let p3 = P2::new(to.x, to.y);
        let word = |l: u8| b.word(l).map(|v| v * u);
        let curve = if code == 50 {
            let (i, j) = match (word(b'I'), word(b'J'), self.spline_pq) {
                (Some(i), Some(j), _) => (i, j),
                (None, None, Some((p, q))) => (-p, -q),
                (None, None, None) => {
                    return Err(err("G5 needs I and J unless it follows another G5"));
                }
                _ => return Err(err("G5 needs both I and J, or neither after another G5")),
            };
            let (Some(p), Some(q)) = (word(b'P'), word(b'Q')) else {
                return Err(err("G5 needs P and Q (the second control point from the end)"));
            };
            self.spline_pq = Some((p, q));
            [
                p0,
                p0 + crate::geometry::V2::new(i, j),
                p3 + crate::geometry::V2::new(p, q),
                p3,
            ]
        } else {
            let (Some(i), Some(j)) = (word(b'I'), word(b'J')) else {
                return Err(err("G5.1 needs I and J (the control point from the start)"));
            };
            self.spline_pq = None;
            quadratic_as_cubic([p0, p0 + crate::geometry::V2::new(i, j), p3])
        };
        let mut pts = Vec::new();
        flatten_cubic(curve, SPLINE_TOL_MM, &mut pts);
        let z = self.pos.z;
        for p in pts {
            let mut m = Motion::from_block(
                MotionKind::Line,
                crate::geometry::P3::new(p.x, p.y, z),
                Some(feed),
                self.beam,
                lineno,
            );
            m.tool = self.tool_state();
            out.push_back(Record::Move(m));
        }
        self.pos = crate::geometry::P3::new(p3.x, p3.y, z);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cubic_at(c: &[P2; 4], t: f64) -> P2 {
        let s = 1.0 - t;
        P2::from(
            c[0].coords * (s * s * s)
                + c[1].coords * (3.0 * s * s * t)
                + c[2].coords * (3.0 * s * t * t)
                + c[3].coords * (t * t * t),
        )
    }

    #[test]
    fn flattened_splines_stay_within_the_tolerance() {
        let curves = [
            [
                P2::new(0.0, 0.0),
                P2::new(0.0, 3.0),
                P2::new(1.0, -2.0),
                P2::new(1.0, 1.0),
            ],
            [
                P2::new(10.0, 10.0),
                P2::new(30.0, 70.0),
                P2::new(30.0, -30.0),
                P2::new(30.0, 30.0),
            ],
            quadratic_as_cubic([P2::new(0.0, 0.0), P2::new(5.0, 10.0), P2::new(10.0, 0.0)]),
        ];
        for c in curves {
            let mut pts = vec![c[0]];
            flatten_cubic(c, SPLINE_TOL_MM, &mut pts);
            assert_eq!(*pts.last().unwrap(), c[3]);
            assert!(pts.len() > 10, "{} points", pts.len());
            // Every curve point is within the tolerance of the polyline.
            for k in 0..=2000 {
                let p = cubic_at(&c, k as f64 / 2000.0);
                let d = pts
                    .windows(2)
                    .map(|w| seg_dist(p, w[0], w[1]))
                    .fold(f64::INFINITY, f64::min);
                assert!(d <= SPLINE_TOL_MM * (1.0 + 1e-9), "{d} at t = {}", k as f64 / 2000.0);
            }
        }
        // The quadratic's cubic form traces the same curve.
        let q = [P2::new(0.0, 0.0), P2::new(5.0, 10.0), P2::new(10.0, 0.0)];
        let c = quadratic_as_cubic(q);
        for k in 0..=10 {
            let t = k as f64 / 10.0;
            let s = 1.0 - t;
            let want = q[0].coords * (s * s) + q[1].coords * (2.0 * s * t) + q[2].coords * (t * t);
            assert!((cubic_at(&c, t).coords - want).norm() < 1e-12);
        }
    }

    #[test]
    fn g5_and_g5_1_read_as_linuxcnc_defines_them() {
        let opts = crate::gcode::ReadOptions {
            dialect: Some(crate::gcode::Dialect::Iso),
            ..Default::default()
        };
        let text =
            "G0 X10 Y10 Z-1\nG1 F100\nG5 I0 J60 P0 Q-60 X30 Y30\nG5 P0 Q-60 X50 Y50\nG5.1 X0 I-50 J-150\nG1 X1\n";
        let (_, recs) = crate::gcode::read_str(text, &opts).unwrap();
        let lines: Vec<&Motion> = recs.iter().filter_map(Record::motion).collect();
        let end_of = |block: u64| lines.iter().rev().find(|m| m.block == Some(block)).unwrap().to;
        assert_eq!((end_of(3).x, end_of(3).y, end_of(3).z), (30.0, 30.0, -1.0));
        assert_eq!((end_of(4).x, end_of(4).y), (50.0, 50.0));
        assert_eq!((end_of(5).x, end_of(5).y), (0.0, 50.0));
        // The second G5 continues smoothly: its first piece leaves (30, 30)
        // along the first one's end tangent, (0, 60) for P0 Q-60.
        let first4 = lines.iter().find(|m| m.block == Some(4)).unwrap().to;
        assert!((first4.x - 30.0).abs() < 0.02 * (first4.y - 30.0).abs(), "{first4:?}");
        assert!(
            lines[1..]
                .iter()
                .all(|m| m.kind == MotionKind::Line && m.feed == Some(100.0)),
            "every piece is a feed line at the block's feed"
        );
        for (text, needle) in [
            ("G1 F1\nG5 X1 Y1 P0 Q1\n", "needs I and J"),
            ("G1 F1\nG5 X1 Y1 I1 J1\n", "needs P and Q"),
            ("G1 F1\nG18 G5 X1 Y1 I1 J1 P1 Q1\n", "XY plane"),
            ("G1 F1\nG5.1 X1 Y1 Z1 I1 J1\n", "X and Y only"),
            ("G1 F1\nG5.2 X1 Y1 P1 L3\n", "no G5.3"),
        ] {
            let e = crate::gcode::read_str(text, &opts).unwrap_err();
            assert_eq!(e.line(), 2, "{text}: {e}");
            assert!(e.to_string().contains(needle), "{text}: {e}");
        }
    }
}
