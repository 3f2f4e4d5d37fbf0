//! Cutting a toolpath's motions into the stock, in steps, with the chip
//! volume of every step: the material-removal side of a simulation.
//!
//! Steps follow seed 000 §3.1: a chip-volume simulation advances the
//! cutter by the feed per tooth times a scale factor and records what each
//! step removes. Arcs are cut as chords whose sagitta stays under a
//! quarter of the grid spacing, so the chord error is below what the grid
//! resolves. Rapids cut too: material removed by a rapid is a collision,
//! and callers report it as one.

use super::cutter::Cutter;
use super::heightfield::{HeightField, StockError};
use crate::geometry::{Arc3, P3};
use crate::model::toolpath::{Motion, MotionKind};

/// Most steps one motion is cut in, so a tiny step on a long move cannot
/// run away; longer steps are taken instead.
pub const MAX_STEPS_PER_MOVE: usize = 1 << 20;

/// Cut `m` from `from`, calling `on_step(step_end, removed_mm3)` for each
/// step; returns the motion's total removed volume (mm^3).
pub fn cut_motion(
    stock: &mut HeightField,
    tool: &Cutter,
    from: P3,
    m: &Motion,
    step_mm: f64,
    mut on_step: impl FnMut(P3, f64),
) -> Result<f64, StockError> {
    let (dx, dy) = stock.spacing();
    let chord_tol = 0.25 * dx.min(dy);
    // Points along the motion, ending at m.to.
    let points: Vec<P3> = match m.kind {
        MotionKind::Rapid | MotionKind::Line => {
            let len = (m.to - from).norm();
            let n = steps(len, step_mm);
            (1..=n).map(|k| from + (m.to - from) * (k as f64 / n as f64)).collect()
        }
        MotionKind::Arc(a) => {
            let Some(arc) = Arc3::new(a.center, from, m.to, a.ccw, a.plane, a.extra_turns) else {
                // A degenerate arc (zero radius) is a straight move.
                return cut_motion(
                    stock,
                    tool,
                    from,
                    &Motion {
                        kind: MotionKind::Line,
                        ..m.clone()
                    },
                    step_mm,
                    on_step,
                );
            };
            let r = arc.radius();
            // Largest angle whose chord deviates by at most chord_tol.
            let dtheta = if r > chord_tol {
                2.0 * (1.0 - chord_tol / r).acos()
            } else {
                std::f64::consts::PI
            };
            let n = steps(arc.length(), step_mm)
                .max((arc.sweep().abs() / dtheta).ceil() as usize)
                .min(MAX_STEPS_PER_MOVE);
            (1..=n)
                .map(|k| {
                    if k == n {
                        m.to
                    } else {
                        arc.point_at(k as f64 / n as f64)
                    }
                })
                .collect()
        }
    };
    let mut total = 0.0;
    let mut p = from;
    for q in points {
        let v = stock.cut(p, q, tool)?;
        on_step(q, v);
        total += v;
        p = q;
    }
    Ok(total)
}

fn steps(len: f64, step_mm: f64) -> usize {
    if step_mm.is_nan() || step_mm <= 0.0 || !len.is_finite() {
        return 1;
    }
    ((len / step_mm).ceil() as usize).clamp(1, MAX_STEPS_PER_MOVE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Plane;
    use crate::model::toolpath::ArcData;

    fn mv(kind: MotionKind, to: P3) -> Motion {
        Motion::from_block(kind, to, Some(60.0), true, 1)
    }

    #[test]
    fn steps_add_up_to_the_move_and_a_second_pass_cuts_nothing() {
        let tool = Cutter::flat(0.5).unwrap();
        let mut s = HeightField::new(P3::new(0.0, 0.0, -2.0), P3::new(10.0, 10.0, 0.0), 0.02).unwrap();
        let m = mv(MotionKind::Line, P3::new(8.0, 5.0, -0.2));
        let mut steps = Vec::new();
        let total = cut_motion(&mut s, &tool, P3::new(2.0, 5.0, -0.2), &m, 0.1, |p, v| {
            steps.push((p, v))
        })
        .unwrap();
        assert_eq!(steps.len(), 60);
        assert!((steps.iter().map(|s| s.1).sum::<f64>() - total).abs() < 1e-9);
        // A full-width slot: each interior step removes width x step x depth.
        let mid = steps[30].1;
        assert!((mid - 1.0 * 0.1 * 0.2).abs() < 0.05 * 0.02, "{mid}");
        let again = cut_motion(&mut s, &tool, P3::new(2.0, 5.0, -0.2), &m, 0.1, |_, _| {}).unwrap();
        assert_eq!(again, 0.0);
    }

    #[test]
    fn arcs_are_cut_along_the_arc() {
        let tool = Cutter::ball(0.25).unwrap();
        let mut s = HeightField::new(P3::new(0.0, 0.0, -2.0), P3::new(10.0, 10.0, 0.0), 0.02).unwrap();
        // A full circle of radius 3 around (5, 5), 0.1 deep.
        let arc = ArcData {
            center: P3::new(5.0, 5.0, -0.1),
            ccw: true,
            plane: Plane::Xy,
            extra_turns: 0,
        };
        let from = P3::new(8.0, 5.0, -0.1);
        let v = cut_motion(&mut s, &tool, from, &mv(MotionKind::Arc(arc), from), 0.05, |_, _| {}).unwrap();
        // Groove cross-section of a ball 0.1 deep: circular segment area.
        let (r, h): (f64, f64) = (0.25, 0.1);
        let seg = r * r * ((r - h) / r).acos() - (r - h) * (2.0 * r * h - h * h).sqrt();
        let want = seg * 2.0 * std::f64::consts::PI * 3.0;
        assert!((v - want).abs() / want < 0.02, "{v} vs {want}");
        // The groove is on the circle, not on a chord: the point at 45
        // degrees is cut to the groove's bottom.
        let (i, j) = (
            ((5.0 + 3.0 * 0.5f64.sqrt()) / 0.02) as usize,
            ((5.0 + 3.0 * 0.5f64.sqrt()) / 0.02) as usize,
        );
        assert!(s.height(i, j) < -0.09, "{}", s.height(i, j));
    }
}
