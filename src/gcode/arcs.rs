//! G2/G3 arcs of the ISO reader, with LinuxCNC's tolerances.
//!
//! CAM posts print arc centres rounded to 3 or 4 decimals, so the end of an
//! I/J/K arc is rarely exactly on the circle through its start, and an R
//! arc across a diameter asks for a chord a hair longer than 2R. LinuxCNC's
//! interpreter (`rs274`, version 2.9) accepts these within the limits below,
//! measured in the program's length unit, and so do we. An I/J/K arc whose
//! two radii differ is kept as it is written: centre and end point as given,
//! which the toolpath model reads as a spiral (the radius changes linearly
//! with the angle), as LinuxCNC's motion planner does.
//!
//! The limits, found in LinuxCNC's interpreter and checked against `rs274`
//! (see `docs/gcode.md`):
//! - a radius smaller than 0.00005 inch (0.00127 mm) is a zero-radius arc;
//! - the end radius may differ from the start radius by up to 0.002·√2
//!   inch or 0.02·√2 mm (about 28 µm) whatever the radius, and by more when
//!   that is at most 0.1 % of the larger radius, but never by 100 times the
//!   absolute figure;
//! - an R arc's half chord may exceed |R| by up to 0.00127 mm (0.00005
//!   inch); the centre is then the chord's midpoint.

use super::{GcodeError, IsoInterpreter};
use crate::geometry::{P2, P3, Plane, V2};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record};
use std::collections::VecDeque;

/// Smallest arc radius, inch (LinuxCNC's `RADIUS_TOLERANCE_INCH`); also how
/// far an R arc's half chord may exceed |R|.
const RADIUS_TOL_INCH: f64 = 0.00005;
/// How far the end radius may differ from the start radius with no other
/// condition, inch and mm (LinuxCNC's `CENTER_ARC_RADIUS_TOLERANCE_*`).
const SPIRAL_ABS_INCH: f64 = 0.002 * std::f64::consts::SQRT_2;
const SPIRAL_ABS_MM: f64 = 0.02 * std::f64::consts::SQRT_2;
/// Relative radius difference allowed beyond the absolute figure.
const SPIRAL_REL: f64 = 0.001;
/// The ratio under which a chord counts as a diameter (LinuxCNC's `TINY`).
const TINY: f64 = 1e-12;

/// Tolerances in millimetres for a program in inches or millimetres.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ArcTolerances {
    /// Smallest radius, and an R arc's allowed excess of half chord, mm.
    pub radius_mm: f64,
    /// Radius difference always allowed, mm.
    pub spiral_abs_mm: f64,
}

impl ArcTolerances {
    pub(crate) fn new(inch: bool) -> Self {
        let radius_mm = RADIUS_TOL_INCH * 25.4;
        if inch {
            ArcTolerances {
                radius_mm,
                spiral_abs_mm: SPIRAL_ABS_INCH * 25.4,
            }
        } else {
            ArcTolerances {
                radius_mm,
                spiral_abs_mm: SPIRAL_ABS_MM,
            }
        }
    }

    /// True when radii `r0` and `r1` (mm) are close enough for rs274.
    pub(crate) fn radii_agree(&self, r0: f64, r1: f64) -> bool {
        let abs = (r0 - r1).abs();
        let rel = abs / r0.max(r1);
        !(abs > 100.0 * self.spiral_abs_mm || (rel > SPIRAL_REL && abs > self.spiral_abs_mm))
    }
}

/// Centre of an R-form arc as LinuxCNC finds it: on the perpendicular
/// bisector of the chord, the long way round for a negative R; a chord up
/// to `tol` longer than the diameter puts the centre at its midpoint.
/// Why an R-form arc has no centre.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum RArcError {
    #[error("radius-format arc (R) with its end point equal to its start: use I/J/K for a full circle")]
    EndIsStart,
    #[error("arc radius R{r} is too small to reach the end point ({chord:.6} mm away)")]
    TooSmall { r: f64, chord: f64 },
}

pub(crate) fn center_from_r(start: P2, end: P2, r: f64, ccw: bool, tol: f64) -> Result<P2, RArcError> {
    if start == end {
        return Err(RArcError::EndIsStart);
    }
    let rad = r.abs();
    let mid = P2::new((start.x + end.x) / 2.0, (start.y + end.y) / 2.0);
    let mut half = (mid - end).norm();
    if half - rad > tol {
        return Err(RArcError::TooSmall {
            r,
            chord: (end - start).norm(),
        });
    }
    if half / rad > 1.0 - TINY {
        half = rad;
    }
    let d = end - start;
    let base = d.y.atan2(d.x);
    let right = (!ccw && r > 0.0) || (ccw && r < 0.0);
    let theta = if right {
        base - std::f64::consts::FRAC_PI_2
    } else {
        base + std::f64::consts::FRAC_PI_2
    };
    let offset = rad * (half / rad).asin().cos();
    Ok(mid + V2::new(theta.cos(), theta.sin()) * offset)
}

impl IsoInterpreter {
    /// A G2 (`ccw` false) or G3 arc to the block's end point.
    pub(super) fn arc(
        &mut self,
        b: &super::Block,
        ccw: bool,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let feed = self.feed_mm_per_min(lineno)?;
        let to = self.target(b, b.has_g(530), lineno)?;
        let plane = self.plane;
        let turns = b.word(b'P').unwrap_or(1.0);
        if turns < 1.0 || turns.fract() != 0.0 || turns > 1e6 {
            return Err(err(format!(
                "arc P word must be a whole number of turns of at least 1, got {turns}"
            )));
        }
        let extra_turns = turns as u32 - 1;
        let end2 = plane.project(&to);
        // LinuxCNC's `arc_not_allowed`: only a straight move clears it,
        // so a G41/G42 between G40 and the arc does not.
        if self.comp.exit {
            return Err(err(
                "the first move after G40 (cutter radius compensation off) cannot be an arc".into(),
            ));
        }
        if self.comp.active() {
            if self.feed_mode == super::FeedMode::InverseTime {
                return Err(err(
                    "inverse time feed (G93) with cutter radius compensation on is not supported".into(),
                ));
            }
            if b.has_g(530) {
                return Err(err("G53 cannot be used with cutter radius compensation on".into()));
            }
            let start2 = self.comp_arc_start();
            let center = self.arc_center(b, start2, end2, ccw, lineno)?;
            let turn = if ccw { turns as i32 } else { -(turns as i32) };
            let r = b.word(b'R').map(|r| r * self.unit());
            return self.comp_arc(to, turn, center, r, lineno, out);
        }
        let start2 = plane.project(&self.pos);
        let center = self.arc_center(b, start2, end2, ccw, lineno)?;
        let arc = ArcData {
            center: plane.lift(&center, plane.normal_coord(&self.pos)),
            ccw,
            plane,
            extra_turns,
        };
        let feed = if self.feed_mode == super::FeedMode::InverseTime {
            let len = crate::geometry::Arc3::new(arc.center, self.pos, to, ccw, plane, extra_turns)
                .map_or(0.0, |a| a.length());
            self.inverse_time_feed(len)
        } else {
            feed
        };
        let mut m = Motion::from_block(MotionKind::Arc(arc), to, Some(feed), self.beam, lineno);
        m.tool = self.tool_state();
        out.push_back(Record::Move(m));
        self.pos = to;
        Ok(())
    }

    /// The centre (in the plane) of the block's arc from `start2` to
    /// `end2`, with LinuxCNC's checks.
    fn arc_center(&self, b: &super::Block, start2: P2, end2: P2, ccw: bool, lineno: u64) -> Result<P2, GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let plane = self.plane;
        let u = self.unit();
        let tol = ArcTolerances::new(self.inch);
        // Offset words of the plane, in (first, second) order, and the one
        // that belongs to the normal axis (an error if given).
        let (first, second, normal_word) = match plane {
            Plane::Xy => (b'I', b'J', b'K'),
            Plane::Xz => (b'K', b'I', b'J'),
            Plane::Yz => (b'J', b'K', b'I'),
        };
        let center = if let Some(r) = b.word(b'R') {
            if b.word(b'I').is_some() || b.word(b'J').is_some() || b.word(b'K').is_some() {
                return Err(err("arc has both R and I/J/K words".into()));
            }
            center_from_r(start2, end2, r * u, ccw, tol.radius_mm).map_err(|e| err(e.to_string()))?
        } else {
            if b.word(first).is_none() && b.word(second).is_none() {
                return Err(err(format!(
                    "arc needs R or at least one of {} {} in plane {}",
                    first as char,
                    second as char,
                    plane.name().to_uppercase()
                )));
            }
            if b.word(normal_word).is_some() {
                return Err(err(format!(
                    "{} word given for an arc in plane {}",
                    normal_word as char,
                    plane.name().to_uppercase()
                )));
            }
            let i = b.word(first).unwrap_or(0.0) * u;
            let j = b.word(second).unwrap_or(0.0) * u;
            let center = if self.arc_absolute {
                let off = plane.project(&P3::from(self.offset()));
                P2::new(i + off.x, j + off.y)
            } else {
                P2::new(start2.x + i, start2.y + j)
            };
            let r0 = (start2 - center).norm();
            let r1 = (end2 - center).norm();
            if r0 < tol.radius_mm || r1 < tol.radius_mm {
                return Err(err(format!(
                    "arc of zero radius: radius to start {r0:.6} mm, to end {r1:.6} mm"
                )));
            }
            if !tol.radii_agree(r0, r1) {
                return Err(err(format!(
                    "arc end is not on the circle: radius to start {r0:.6} mm, to end {r1:.6} mm (difference {:.6} mm)",
                    (r0 - r1).abs()
                )));
            }
            center
        };
        Ok(center)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spiral_limits_are_linuxcncs() {
        let mm = ArcTolerances::new(false);
        let inch = ArcTolerances::new(true);
        // Checked against rs274 (LinuxCNC 2.9): G3 from X r to X -(r + d).
        assert!(mm.radii_agree(10.0, 10.028));
        assert!(!mm.radii_agree(10.0, 10.0285));
        assert!(mm.radii_agree(100.0, 100.029));
        assert!(mm.radii_agree(5000.0, 5002.8));
        assert!(!mm.radii_agree(5000.0, 5002.9));
        assert!(inch.radii_agree(10.0 * 25.4, 10.0028 * 25.4));
        assert!(inch.radii_agree(10.0 * 25.4, 10.0029 * 25.4));
        assert!(mm.radii_agree(1.0, 1.0011));
    }

    #[test]
    fn r_arcs_a_hair_over_the_diameter_centre_on_the_midpoint() {
        let tol = ArcTolerances::new(false).radius_mm;
        let s = P2::new(0.0, 0.0);
        let c = center_from_r(s, P2::new(2.00252, 0.0), 1.0, true, tol).unwrap();
        assert!((c - P2::new(1.00126, 0.0)).norm() < 1e-12);
        assert!(center_from_r(s, P2::new(2.00256, 0.0), 1.0, true, tol).is_err());
        // Short and long ways round.
        let c = center_from_r(s, P2::new(2.0, 0.0), 2.0, true, tol).unwrap();
        assert!(c.y > 0.0 && ((c - s).norm() - 2.0).abs() < 1e-12);
        let c = center_from_r(s, P2::new(2.0, 0.0), -2.0, true, tol).unwrap();
        assert!(c.y < 0.0);
        let c = center_from_r(s, P2::new(2.0, 0.0), 2.0, false, tol).unwrap();
        assert!(c.y < 0.0);
    }
}
