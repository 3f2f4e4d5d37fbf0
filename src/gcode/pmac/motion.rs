//! Moves: the words of one move collected on a line (`PendingMove`),
//! then turned into a motion record: end point, feed (with `FRAX`), arc
//! centre or radius, shutter switch.

use super::{GcodeError, PmacInterpreter, make_arc};
use crate::gcode::arc_radii_accepted;
use crate::geometry::planar::center_from_radius;
use crate::geometry::{Arc3, EPS_LEN, P2, P3};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record};
use std::collections::VecDeque;

/// The modal move mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum MoveMode {
    Rapid,
    Linear,
    /// CIRCLE1: clockwise about the NORMAL vector.
    Circle1,
    /// CIRCLE2: counter-clockwise about the NORMAL vector.
    Circle2,
}

impl MoveMode {
    pub(super) fn name(self) -> &'static str {
        match self {
            MoveMode::Rapid => "RAPID",
            MoveMode::Linear => "LINEAR",
            MoveMode::Circle1 => "CIRCLE1",
            MoveMode::Circle2 => "CIRCLE2",
        }
    }
}

/// The words of one move collected on a line; the move is made when a
/// command that is not part of it (or the end of the line) arrives, so `F`,
/// `TA` and `TS` anywhere on the move's line apply to it.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct PendingMove {
    pub(super) axes: [Option<f64>; 3],
    /// A B C U V W: accepted only where they stay put.
    pub(super) extra: [Option<f64>; 6],
    pub(super) center: [Option<f64>; 3],
    pub(super) radius: Option<f64>,
    pub(super) active: bool,
}

/// The axes besides X Y Z, in the order of `PendingMove::extra`.
pub(super) const EXTRA_AXES: [u8; 6] = *b"ABCUVW";

impl PmacInterpreter {
    /// Turn the collected move words into a motion record.
    pub(super) fn emit_move(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        let pm = std::mem::take(&mut self.pending);
        let mut to = self.pos;
        for (k, v) in pm.axes.iter().enumerate() {
            if let Some(v) = *v {
                to[k] = if self.abs_axes[k] { v } else { self.pos[k] + v };
            }
        }
        if !(to.x.is_finite() && to.y.is_finite() && to.z.is_finite()) {
            return Err(GcodeError::at(lineno, "move end point is not a finite number"));
        }
        // Rotary axes A, B, C (degrees, as the program gives them).
        let mut abc = [self.extra_pos[0], self.extra_pos[1], self.extra_pos[2]];
        let mut abc_given = false;
        for (k, v) in pm.extra.iter().enumerate().take(3) {
            let Some(v) = *v else { continue };
            let end = if self.abs_extra[k] { v } else { abc[k] + v };
            if !end.is_finite() {
                return Err(GcodeError::at(lineno, "rotary axis position is not a finite number"));
            }
            abc[k] = end;
            abc_given = true;
        }
        let rotary_deg = (0..3).map(|k| (abc[k] - self.extra_pos[k]).powi(2)).sum::<f64>().sqrt();
        if rotary_deg > EPS_LEN && self.frax_rotary && self.move_time.is_none() && self.mode != MoveMode::Rapid {
            return Err(GcodeError::at(
                lineno,
                "a rotary axis in FRAX moves: F would be the speed of X, Y, Z and the rotary axes together                  (not modelled); leave A, B, C out of FRAX",
            ));
        }
        for (k, v) in pm.extra.iter().enumerate().skip(3) {
            let Some(v) = *v else { continue };
            let at = self.extra_pos[k];
            let end = if self.abs_extra[k] { v } else { at + v };
            if (end - at).abs() > EPS_LEN {
                let letter = EXTRA_AXES[k] as char;
                return Err(GcodeError::at(
                    lineno,
                    format!(
                        "axis {letter} moves (from {at} to {end}): the toolpath has X, Y, Z and the \
                         rotary axes A, B, C, so axes U V W are read only where they stay put"
                    ),
                ));
            }
        }
        let feed = if self.mode == MoveMode::Rapid || self.move_time.is_some() {
            None
        } else if (to - self.pos).norm() <= EPS_LEN && rotary_deg > EPS_LEN {
            // Only rotary axes move: none of the default feedrate axes
            // (X, Y, Z), so the controller times the move by Isx86.
            return Err(GcodeError::at(
                lineno,
                "the move turns rotary axes only: no FRAX axis moves, so a controller times it by Isx86 \
                 (not modelled); give the move a time (TM) or move X, Y or Z with it",
            ));
        } else {
            let f = self.feed.ok_or_else(|| {
                GcodeError::at(
                    lineno,
                    format!("no feed rate: set F (or TM) before the first {} move", self.mode.name()),
                )
            })?;
            Some(self.frax_feed(f, &to, lineno)?)
        };
        let has_center = pm.center.iter().any(Option::is_some);
        let kind = match self.mode {
            MoveMode::Rapid | MoveMode::Linear => {
                if has_center || pm.radius.is_some() {
                    return Err(GcodeError::at(
                        lineno,
                        format!(
                            "arc centre (I/J/K) or radius (R) in {} mode; CIRCLE1 or CIRCLE2 is needed",
                            self.mode.name()
                        ),
                    ));
                }
                if self.mode == MoveMode::Rapid {
                    MotionKind::Rapid
                } else {
                    MotionKind::Line
                }
            }
            MoveMode::Circle1 | MoveMode::Circle2 => {
                let ccw = (self.mode == MoveMode::Circle2) != self.normal_positive;
                MotionKind::Arc(self.arc(&pm, &to, ccw, lineno)?)
            }
        };
        let feed = match (self.mode, self.move_time) {
            (MoveMode::Rapid, _) | (_, None) => feed,
            (_, Some(tm)) => {
                let length = match &kind {
                    MotionKind::Arc(a) => {
                        Arc3::new(a.center, self.pos, to, a.ccw, a.plane, a.extra_turns).map_or(0.0, |a| a.length())
                    }
                    _ => (to - self.pos).norm(),
                };
                // A rotary-only move: its speed in degrees per second, as
                // the ISO reader takes F of a rotary-only move.
                let length = if length <= EPS_LEN { rotary_deg } else { length };
                if length <= EPS_LEN {
                    // Nowhere to go: the move is its time in place.
                    self.push(
                        out,
                        Record::Dwell {
                            seconds: tm / 1000.0,
                            block: Some(lineno),
                        },
                    );
                    self.pos = to;
                    return Ok(());
                }
                if tm <= 0.0 {
                    return Err(GcodeError::at(
                        lineno,
                        format!(
                            "TM{tm}: a {length:.6} mm move in no time (a controller stretches it to its \
                             acceleration time, which the program does not give); set TM > 0 or F"
                        ),
                    ));
                }
                Some(length / (tm / 1000.0))
            }
        };
        let mut motion = Motion::from_block(kind, to, feed, self.beam, lineno);
        if abc_given {
            self.abc_used = true;
        }
        if self.abc_used {
            motion.tool.abc = Some(abc);
        }
        self.extra_pos[..3].copy_from_slice(&abc);
        if self.beam != self.moved_beam {
            motion.beam_switch = Some(self.last_switch);
        }
        self.moved_beam = self.beam;
        self.push(out, Record::Move(motion));
        self.pos = to;
        Ok(())
    }

    /// The model's path feed for F when some moving axes are not feedrate
    /// axes (FRAX): F is the speed of the FRAX axes alone, so the whole
    /// move goes faster by |move| / |FRAX part of the move|.
    fn frax_feed(&self, f: f64, to: &P3, lineno: u64) -> Result<f64, GcodeError> {
        if self.frax_axes == [true; 3] {
            return Ok(f);
        }
        let d = to - self.pos;
        let all = d.norm();
        if all <= EPS_LEN {
            return Ok(f);
        }
        let part = (0..3)
            .filter(|&k| self.frax_axes[k])
            .map(|k| d[k] * d[k])
            .sum::<f64>()
            .sqrt();
        if (all - part).abs() <= EPS_LEN {
            return Ok(f);
        }
        if self.mode != MoveMode::Linear {
            return Err(GcodeError::at(
                lineno,
                "a CIRCLE move along an axis FRAX leaves out: its speed is not modelled (LINEAR only)",
            ));
        }
        if part <= EPS_LEN {
            return Err(GcodeError::at(
                lineno,
                "the move has no FRAX axis: a controller times it by Isx86 (not modelled); add the axis to FRAX",
            ));
        }
        Ok(f * all / part)
    }

    pub(super) fn arc(&self, pm: &PendingMove, to: &P3, ccw: bool, lineno: u64) -> Result<ArcData, GcodeError> {
        let plane = self.plane;
        let s = plane.project(&self.pos);
        let e = plane.project(to);
        let has_center = pm.center.iter().any(Option::is_some);
        let center: P2 = match (pm.radius, has_center) {
            (Some(_), true) => {
                return Err(GcodeError::at(lineno, "give either R or I/J/K for an arc, not both"));
            }
            (Some(r), false) => {
                if (e - s).norm() <= EPS_LEN {
                    return Err(GcodeError::at(
                        lineno,
                        "R cannot describe a full circle (end = start); give the centre with I/J/K",
                    ));
                }
                match center_from_radius(&s, &e, r, ccw) {
                    Some(c) => c,
                    // A half circle written with rounded end points can have
                    // a chord a little longer than the diameter: within the
                    // tolerance of an I/J/K arc's radii its centre is the
                    // chord's midpoint.
                    None if r != 0.0 && arc_radii_accepted(r.abs(), (e - s).norm() / 2.0) => {
                        P2::from((s.coords + e.coords) / 2.0)
                    }
                    None => {
                        return Err(GcodeError::at(
                            lineno,
                            format!(
                                "radius R{r} cannot reach the end: the chord is {:.6} mm long",
                                (e - s).norm()
                            ),
                        ));
                    }
                }
            }
            (None, true) => {
                // Components not given are zero; the one along the normal
                // does not matter (the centre lies in the start's plane).
                let mut c = P3::origin();
                for (k, v) in pm.center.iter().enumerate() {
                    let v = v.unwrap_or(0.0);
                    c[k] = if self.abs_center { v } else { self.pos[k] + v };
                }
                plane.project(&c)
            }
            (None, false) => {
                return Err(GcodeError::at(
                    lineno,
                    format!("{} move without a centre (I/J/K) or radius (R)", self.mode.name()),
                ));
            }
        };
        make_arc(&self.pos, to, center, ccw, plane, 0, lineno)
    }
}
