//! Physics audit of a laser toolpath: what the stage and the shutter will
//! actually do, checked against the machine's limits. Tests use it on every
//! generated drawing; it reads only the toolpath model, so it checks the
//! output, not the planner's intentions.

use super::elem::Elem;
use super::machine::Machine;
use crate::geometry::P3;
use crate::geometry::arc::Arc3;
use crate::model::toolpath::{MotionKind, Record, Role};
use std::collections::BTreeMap;

/// What the audit found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Audit {
    /// Feed moves whose feed is not V.
    pub off_feed_moves: usize,
    /// Joints between feed moves (without a stop between) whose direction
    /// jumps by more than the tangency tolerance: an infinite acceleration
    /// demand at V.
    pub corners_at_speed: usize,
    /// Largest centripetal demand V²/r (mm/s²) on moves that are not cuts
    /// (loops, leads); cuts follow the drawing and are reported separately.
    pub max_accel_off_cut: f64,
    /// Largest demand on cut moves (the drawing's own tightest arc).
    pub max_accel_cut: f64,
    /// Beam-on rapids (never acceptable).
    pub beam_on_rapids: usize,
    /// Largest distance (mm) between an edge of where the shutter is fully
    /// open and the matching edge of a run of cut moves; infinite when the
    /// two do not pair up.
    pub exposure_error: f64,
    /// Fully-open stretches (mm) that do not start at V: the stage must be
    /// at V from (open command - lead-in's acceleration) on; here: the
    /// shutter command must not come before the lead-in's acceleration is
    /// over, measured as the distance from the last stop.
    pub min_run_before_open: f64,
    /// Cut length (mm) per chain id.
    pub cut_length: BTreeMap<u64, f64>,
    /// Number of cut runs per chain id.
    pub cut_runs: BTreeMap<u64, usize>,
}

/// Audit `records` (starting at `start`) against `m`.
pub fn audit(records: &[Record], m: &Machine, start: P3) -> Audit {
    let mut a = Audit {
        min_run_before_open: f64::INFINITY,
        ..Default::default()
    };
    let v = m.feed;
    let cos_tol = m.tangent_cos();
    let mut pos = start;
    let mut s = 0.0; // path length since the last stop
    let mut prev_dir: Option<crate::geometry::V3> = None;
    let mut beam = false;
    let mut cmd_on_at = 0.0;
    let mut cut_run: Option<(f64, u64)> = None;
    let mut open: Vec<(f64, f64)> = Vec::new(); // physical fully-open, in global length
    let mut cuts: Vec<(f64, f64)> = Vec::new();
    let mut g = 0.0; // global feed length; stops add a gap so intervals never merge across them
    for r in records {
        let Record::Move(mv) = r else {
            prev_dir = None;
            continue;
        };
        let elem = match mv.kind {
            MotionKind::Rapid => {
                if mv.beam {
                    a.beam_on_rapids += 1;
                }
                pos = mv.to;
                prev_dir = None;
                s = 0.0;
                g += 1e6;
                continue;
            }
            MotionKind::Line => Elem::line(pos, mv.to),
            MotionKind::Arc(d) => match Arc3::new(d.center, pos, mv.to, d.ccw, d.plane, d.extra_turns) {
                Some(arc) => Elem::Arc(arc),
                None => Elem::line(pos, mv.to),
            },
        };
        if mv.feed.is_none_or(|f| (f - v).abs() > 1e-9 * v) {
            a.off_feed_moves += 1;
        }
        if let Some(pd) = prev_dir
            && pd.dot(&elem.dir_start()) < cos_tol
        {
            a.corners_at_speed += 1;
        }
        let demand = v * v / elem.curvature_radius();
        if mv.role == Some(Role::Cut) {
            a.max_accel_cut = a.max_accel_cut.max(demand);
        } else {
            a.max_accel_off_cut = a.max_accel_off_cut.max(demand);
        }
        if mv.beam != beam {
            if mv.beam {
                cmd_on_at = g;
                a.min_run_before_open = a.min_run_before_open.min(s);
            } else {
                open.push((cmd_on_at + m.open_lead(), g + m.close_lead()));
            }
            beam = mv.beam;
        }
        let len = elem.length();
        let is_cut = mv.role == Some(Role::Cut);
        match (is_cut, cut_run) {
            (true, None) => cut_run = Some((g, mv.chain.unwrap_or(0))),
            (false, Some((c0, id))) => {
                cuts.push((c0, g));
                *a.cut_runs.entry(id).or_default() += 1;
                cut_run = None;
            }
            _ => {}
        }
        if is_cut {
            *a.cut_length.entry(mv.chain.unwrap_or(0)).or_default() += len;
        }
        s += len;
        g += len;
        pos = mv.to;
        prev_dir = Some(elem.dir_end());
    }
    if let Some((c0, id)) = cut_run {
        cuts.push((c0, g));
        *a.cut_runs.entry(id).or_default() += 1;
    }
    if beam {
        // Never closed: the shutter stays open to the end.
        open.push((cmd_on_at + m.open_lead(), f64::INFINITY));
    }
    a.exposure_error = if open.len() != cuts.len() {
        f64::INFINITY
    } else {
        open.iter()
            .zip(&cuts)
            .map(|(o, c)| (o.0 - c.0).abs().max((o.1 - c.1).abs()))
            .fold(0.0, f64::max)
    };
    a
}

/// Feed moves that last less than the acceleration time TA at V. A Turbo
/// PMAC that is not in segmentation mode stretches such a LINEAR/CIRCLE
/// block to TA (PMAC.md; seed 000 Fig. 3-20), so the stage slows on it
/// and the beam dwells: the count says how much of a program depends on
/// the controller running segmented with look-ahead.
pub fn short_blocks(records: &[Record], m: &Machine, start: P3) -> (usize, usize) {
    let min_len = m.feed * m.ta_ms / 1000.0;
    let mut pos = start;
    let (mut short, mut feed_moves) = (0, 0);
    for r in records {
        let Record::Move(mv) = r else { continue };
        let len = match mv.kind {
            MotionKind::Rapid => {
                pos = mv.to;
                continue;
            }
            MotionKind::Line => (mv.to - pos).norm(),
            MotionKind::Arc(d) => Arc3::new(d.center, pos, mv.to, d.ccw, d.plane, d.extra_turns)
                .map_or((mv.to - pos).norm(), |a| a.length()),
        };
        feed_moves += 1;
        if len < min_len {
            short += 1;
        }
        pos = mv.to;
    }
    (short, feed_moves)
}
