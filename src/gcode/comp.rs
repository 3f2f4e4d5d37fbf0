//! Cutter radius compensation (G40, G41, G42, G41.1, G42.1) of the ISO
//! reader, as LinuxCNC 2.9's interpreter computes it.
//!
//! The tool centre runs one tool radius to the left (G41) or right (G42)
//! of the programmed path, in the XY, XZ or YZ plane. LinuxCNC refuses
//! the YZ plane ("allowed only in XY, XZ planes"); we compensate there by
//! the same rules, left and right seen from +X as G2/G3 are, which is the
//! XY plane's result turned by the axis cycle X→Y→Z→X (tested):
//!
//! - The first move after G41/G42 (the entry) goes from where the tool is
//!   to the programmed end point offset perpendicular to the entry
//!   direction (an entry arc ends offset along its radius, on a new centre
//!   so that it stays an arc from the tool's position).
//! - At a convex corner the tool goes round the programmed corner point on
//!   an arc of the tool radius (a rapid goes straight there instead).
//! - At a concave corner the end of the previous move is pulled back to
//!   where the two offset paths meet (line-line, line-arc, arc-line,
//!   arc-arc); a corner the tool cannot reach without gouging is an error.
//! - Nearly tangent joins (within 0.05 radian) need neither.
//! - G40 ends compensation; the next move goes from the offset point to
//!   the programmed one.
//!
//! Like LinuxCNC we hold the last compensated move back until the next one
//! shows whether its end must move (a queue), and emit it then. A radius
//! of zero (D naming a tool of no diameter) compensates nothing.

use super::arcs::ArcTolerances;
use super::{GcodeError, IsoInterpreter};
use crate::geometry::{P2, P3, Plane, V2};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record};
use std::collections::VecDeque;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Corners within this angle (radians) of tangent need no corner arc
/// (LinuxCNC's `TOLERANCE_CONCAVE_CORNER`).
const SMALL: f64 = 0.05;
/// LinuxCNC's `TOLERANCE_EQUAL`, for the entry arc's geometry.
const TOLERANCE_EQUAL: f64 = 0.0001;

/// Which side of the programmed path the tool runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Left,
    Right,
}

/// What a held-back record is, for moving its end point.
#[derive(Debug, Clone, Copy)]
enum Kind {
    /// A line or rapid, with its programmed direction in the plane.
    Straight(V2),
    /// An arc: centre, signed turns (+ counter-clockwise), and the sweep of
    /// the programmed arc (0: a corner arc, whose end never moves).
    Arc {
        center: P2,
        turn: i32,
        sweep: f64,
    },
    Other,
}

/// Compensation state carried from block to block.
#[derive(Debug, Clone)]
pub(super) struct CompState {
    /// The side compensated (G41 left, G42 right); `None` when off.
    pub side: Option<Side>,
    /// Tool radius, mm.
    pub radius: f64,
    /// The plane compensation works in, fixed from G41/G42 to G40.
    pub plane: Plane,
    /// No compensated move yet since G41/G42.
    pub first: bool,
    /// The last programmed (uncompensated) point, machine frame mm.
    pub programmed: P3,
    queue: Vec<(Record, Kind)>,
    /// Where the first held-back move starts (LinuxCNC's `endpoint`).
    endpoint: Option<P2>,
    /// G40 came and no move yet: see [`IsoInterpreter::comp_off`].
    pub exit: bool,
}

impl CompState {
    pub(super) fn new() -> Self {
        CompState {
            side: None,
            radius: 0.0,
            plane: Plane::Xy,
            first: true,
            programmed: P3::origin(),
            queue: Vec::new(),
            endpoint: None,
            exit: false,
        }
    }

    /// True when moves are offset: a side is chosen and the radius is not 0.
    pub(super) fn active(&self) -> bool {
        self.side.is_some() && self.radius > 0.0
    }

    /// True when records must wait behind a held-back move.
    pub(super) fn holding(&self) -> bool {
        !self.queue.is_empty()
    }

    /// Hold a non-motion record behind the held-back moves.
    pub(super) fn hold(&mut self, r: Record) {
        self.queue.push((r, Kind::Other));
    }

    /// Emit every held-back record unchanged.
    pub(super) fn dequeue(&mut self, out: &mut VecDeque<Record>) {
        self.endpoint = None;
        out.extend(self.queue.drain(..).map(|(r, _)| r));
    }

    fn set_endpoint(&mut self, p: P2) {
        self.endpoint = Some(p);
    }

    /// Move the end of every held-back move to `p` (in the plane), check
    /// that none turns round, and emit them.
    fn move_endpoint_and_flush(
        &mut self,
        p: P2,
        unit: f64,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let plane = self.plane;
        let ep = self.endpoint;
        for (rec, kind) in self.queue.iter_mut() {
            let Record::Move(m) = rec else { continue };
            match *kind {
                Kind::Arc { center, turn, sweep } => {
                    let r1 = (plane.project(&m.to) - center).norm();
                    let r2 = (p - center).norm();
                    if (r1 - r2).abs() > 0.01 * unit {
                        return Err(GcodeError::at(
                            lineno,
                            format!("cutter compensation made an arc with mismatched radii {r1:.4} and {r2:.4} mm"),
                        ));
                    }
                    if let Some(e) = ep {
                        let l2 = find_turn(e, center, turn, p);
                        if sweep != 0.0 && l2.abs() > sweep.abs() + 0.001 {
                            return Err(GcodeError::at(
                                lineno,
                                "arc move in concave corner cannot be reached by the tool without gouging",
                            ));
                        }
                    }
                }
                Kind::Straight(dir) => {
                    if let Some(e) = ep
                        && dir.dot(&(p - e)) < 0.0
                    {
                        let what = if m.kind == MotionKind::Rapid {
                            "straight traverse"
                        } else {
                            "straight feed"
                        };
                        return Err(GcodeError::at(
                            lineno,
                            format!("{what} in concave corner cannot be reached by the tool without gouging"),
                        ));
                    }
                }
                Kind::Other => continue,
            }
            m.to = plane.lift(&p, plane.normal_coord(&m.to));
        }
        self.dequeue(out);
        self.set_endpoint(p);
        Ok(())
    }

    /// The held-back move at the front of the queue, if it is an arc:
    /// (centre, compensated end, turn).
    fn front_arc(&self) -> Option<(P2, P2, i32)> {
        match self.queue.first() {
            Some((Record::Move(m), Kind::Arc { center, turn, .. })) => {
                Some((*center, self.plane.project(&m.to), *turn))
            }
            _ => None,
        }
    }
}

/// Signed sweep (radians, + counter-clockwise) of an arc of `turn` turns
/// from `a` to `b` about `c`, as LinuxCNC's `find_turn`.
fn find_turn(a: P2, c: P2, turn: i32, b: P2) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (a.y - c.y).atan2(a.x - c.x);
    let mut beta = (b.y - c.y).atan2(b.x - c.x);
    if turn > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        (beta - alpha) + (turn - 1) as f64 * TAU
    } else {
        if alpha <= beta {
            alpha += TAU;
        }
        (beta - alpha) + (turn + 1) as f64 * TAU
    }
}

fn dir(a: f64) -> V2 {
    V2::new(a.cos(), a.sin())
}

fn angle(v: V2) -> f64 {
    v.y.atan2(v.x)
}

/// Tool inside the arc: left of a counter-clockwise arc, right of a
/// clockwise one.
fn inside(side: Side, turn: i32) -> bool {
    (side == Side::Left && turn > 0) || (side == Side::Right && turn < 0)
}

impl IsoInterpreter {
    /// Where a move's unspecified and incremental coordinates count from:
    /// the programmed point while compensating, else the tool position.
    pub(super) fn base_point(&self) -> P3 {
        if (self.comp.active() && !self.comp.first) || self.comp.exit {
            self.comp.programmed
        } else {
            self.pos
        }
    }

    /// G41/G42 (`side`), from the block's D word: a tool number (G41,
    /// G42) or a diameter (G41.1, G42.1).
    pub(super) fn comp_on(
        &mut self,
        b: &super::Block,
        side: Side,
        dynamic: bool,
        lineno: u64,
    ) -> Result<(), GcodeError> {
        let err = |m: String| GcodeError::at(lineno, m);
        let name = match (side, dynamic) {
            (Side::Left, false) => "G41",
            (Side::Right, false) => "G42",
            (Side::Left, true) => "G41.1",
            (Side::Right, true) => "G42.1",
        };
        if self.comp.side.is_some() {
            return Err(err(format!(
                "{name}: cutter radius compensation is already on (G40 first)"
            )));
        }
        let diameter = if dynamic {
            let d = b
                .word(b'D')
                .ok_or_else(|| err(format!("{name} needs a D word (the tool diameter)")))?;
            d.abs() * self.unit()
        } else {
            let tool = match b.word(b'D') {
                Some(d) if d.fract() == 0.0 && (0.0..=1e9).contains(&d) => d as u32,
                Some(d) => return Err(err(format!("{name} D{d}: D must be a tool number"))),
                None => self.tool_current,
            };
            match (&self.tool_table, tool) {
                (_, 0) => 0.0,
                (Some(t), n) => t
                    .get(n)
                    .ok_or_else(|| err(format!("{name}: tool {n} is not in the tool table")))?
                    .diameter_mm
                    .abs(),
                (None, n) => {
                    return Err(err(format!(
                        "{name}: cutter radius compensation needs the diameter of tool {n}: \
                         give a tool table (--tool-table) or use {name}.1 D<diameter>"
                    )));
                }
            }
        };
        self.comp.side = Some(side);
        self.comp.radius = diameter / 2.0;
        self.comp.plane = self.plane;
        self.comp.first = true;
        Ok(())
    }

    /// G40: emit what is held back and stop compensating. As in LinuxCNC,
    /// the next move counts its unspecified and incremental coordinates
    /// from the last programmed point (the tool is still offset from it),
    /// and may not be an arc.
    pub(super) fn comp_off(&mut self, out: &mut VecDeque<Record>) {
        if self.comp.active() && !self.comp.first {
            self.comp.exit = true;
        }
        self.comp.dequeue(out);
        self.comp.side = None;
        self.comp.first = true;
    }

    fn comp_record(&self, kind: MotionKind, to: P3, rapid: bool, lineno: u64) -> Result<Record, GcodeError> {
        let feed = if rapid {
            None
        } else {
            Some(self.feed_mm_per_min(lineno)?)
        };
        let mut m = Motion::from_block(kind, to, feed, self.beam, lineno);
        m.tool = self.tool_state();
        Ok(Record::Move(m))
    }

    fn comp_line_record(&self, rapid: bool, to: P3, lineno: u64) -> Result<Record, GcodeError> {
        let kind = if rapid { MotionKind::Rapid } else { MotionKind::Line };
        self.comp_record(kind, to, rapid, lineno)
    }

    fn comp_arc_record(&self, to: P3, center: P2, turn: i32, lineno: u64) -> Result<Record, GcodeError> {
        let plane = self.comp.plane;
        let arc = ArcData {
            center: plane.lift(&center, plane.normal_coord(&self.pos)),
            ccw: turn > 0,
            plane,
            extra_turns: turn.unsigned_abs().max(1) - 1,
        };
        self.comp_record(MotionKind::Arc(arc), to, false, lineno)
    }

    /// A compensated G0/G1 to the programmed point `p`.
    pub(super) fn comp_straight(
        &mut self,
        rapid: bool,
        p: P3,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let plane = self.comp.plane;
        let r = self.comp.radius;
        let side = self.comp.side.unwrap_or(Side::Left);
        // Just after a G40 that ended an offset path, LinuxCNC's current
        // point is the programmed one, not where the tool is: a new entry
        // starts there. Any straight move ends that state.
        let c = if self.comp.first && self.comp.exit {
            plane.project(&self.comp.programmed)
        } else {
            plane.project(&self.pos)
        };
        self.comp.exit = false;
        let pp = plane.project(&p);
        let pn = plane.normal_coord(&p);
        let u = self.unit();
        if self.comp.first {
            let distance = (pp - c).norm();
            if distance <= r {
                return Err(GcodeError::at(
                    lineno,
                    "length of cutter compensation entry move is not greater than the tool radius",
                ));
            }
            let a = angle(pp - c) + if side == Side::Left { FRAC_PI_2 } else { -FRAC_PI_2 };
            let end = pp + dir(a) * r;
            self.comp.set_endpoint(c);
            let to = plane.lift(&end, pn);
            let rec = self.comp_line_record(rapid, to, lineno)?;
            self.comp.queue.push((rec, Kind::Straight(dir(a))));
            self.comp.first = false;
            self.pos = to;
            self.comp.programmed = p;
            return Ok(());
        }
        let op = plane.project(&self.comp.programmed);
        let mut end = c;
        if pp == op {
            // No motion in the plane: the tool moves along the normal only.
            let to = plane.lift(&c, pn);
            let rec = self.comp_line_record(rapid, to, lineno)?;
            self.comp.queue.push((rec, Kind::Straight(V2::zeros())));
        } else {
            let mut theta = angle(c - op);
            let mut alpha = angle(pp - op);
            let (beta, gamma) = match side {
                Side::Left => {
                    if theta < alpha {
                        theta += TAU;
                    }
                    (theta - alpha - FRAC_PI_2, FRAC_PI_2)
                }
                Side::Right => {
                    if alpha < theta {
                        alpha += TAU;
                    }
                    (alpha - theta - FRAC_PI_2, -FRAC_PI_2)
                }
            };
            end = pp + dir(alpha + gamma) * r;
            let mid = op + dir(alpha + gamma) * r;
            let concave = !(-SMALL..=PI + SMALL).contains(&beta)
                || (beta > PI - SMALL
                    && self
                        .comp
                        .front_arc()
                        .is_some_and(|(_, _, t)| (side == Side::Right && t > 0) || (side == Side::Left && t < 0)));
            if !concave && beta > SMALL {
                // Convex: round the programmed corner on the tool radius.
                self.comp.move_endpoint_and_flush(c, u, lineno, out)?;
                let cn = plane.normal_coord(&self.pos);
                let to = plane.lift(&mid, cn);
                let rec = if rapid {
                    self.comp_line_record(true, to, lineno)?
                } else {
                    self.comp_arc_record(to, op, if side == Side::Left { -1 } else { 1 }, lineno)?
                };
                out.push_back(rec);
                self.comp.set_endpoint(mid);
            } else if concave {
                let mid = match self.comp.front_arc() {
                    None => {
                        // Line to line: back up along the previous move.
                        let half = (beta + PI) / 2.0;
                        if half == 0.0 {
                            return Err(GcodeError::at(
                                lineno,
                                "zero degree inside corner is invalid for cutter compensation",
                            ));
                        }
                        c + dir(theta + gamma) * (r / half.tan())
                    }
                    Some((pc, pend, pturn)) => {
                        // Arc to line.
                        let oldrad = (pc - pend).norm();
                        let base = angle(pp - op);
                        let th = if pturn > 0 { base + FRAC_PI_2 } else { base - FRAC_PI_2 };
                        let phi = angle(pc - op);
                        let uncomp = if inside(side, pturn) { oldrad + r } else { oldrad - r };
                        let d = uncomp * (th - phi).cos();
                        let gouge = || {
                            GcodeError::at(
                                lineno,
                                "arc to straight motion makes a corner the compensated tool can't fit in without gouging",
                            )
                        };
                        let a = if inside(side, pturn) {
                            let l = (d - r) / oldrad;
                            if !(-1.0..=1.0).contains(&l) {
                                return Err(gouge());
                            }
                            if pturn > 0 {
                                -l.acos() + th + PI
                            } else {
                                l.acos() + th + PI
                            }
                        } else {
                            let l = (d + r) / oldrad;
                            if !(-1.0..=1.0).contains(&l) {
                                return Err(gouge());
                            }
                            if pturn > 0 {
                                l.acos() + th + PI
                            } else {
                                -l.acos() + th + PI
                            }
                        };
                        pc + dir(a) * oldrad
                    }
                };
                self.comp.move_endpoint_and_flush(mid, u, lineno, out)?;
            } else {
                self.comp.dequeue(out);
                self.comp.set_endpoint(c);
            }
            let to = plane.lift(&end, pn);
            let rec = self.comp_line_record(rapid, to, lineno)?;
            self.comp.queue.push((rec, Kind::Straight(pp - op)));
        }
        self.pos = plane.lift(&end, pn);
        self.comp.programmed = p;
        Ok(())
    }

    /// The start of the programmed arc of the next compensated move: the
    /// tool position for the entry move, else the last programmed point.
    pub(super) fn comp_arc_start(&self) -> P2 {
        let p = if self.comp.first {
            self.pos
        } else {
            self.comp.programmed
        };
        self.comp.plane.project(&p)
    }

    /// A compensated G2/G3 (`turn` signed, + counter-clockwise) to the
    /// programmed point `p`, about `center` (found from
    /// [`Self::comp_arc_start`]); `r_word` is the arc's R in mm, if given.
    #[allow(clippy::too_many_arguments)] // each is one fact about the arc
    pub(super) fn comp_arc(
        &mut self,
        p: P3,
        turn: i32,
        center: P2,
        r_word: Option<f64>,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        let plane = self.comp.plane;
        let r = self.comp.radius;
        let side = self.comp.side.unwrap_or(Side::Left);
        let c = plane.project(&self.pos);
        let pp = plane.project(&p);
        let pn = plane.normal_coord(&p);
        let u = self.unit();
        let too_small = "tool radius not less than arc radius with cutter radius compensation";
        let spiral = ArcTolerances::new(self.inch).spiral_abs_mm;
        if self.comp.first {
            if (pp - c).norm() <= r {
                return Err(err(
                    "radius of cutter compensation entry arc is not greater than the tool radius",
                ));
            }
            let arc_r = r_word.map_or((c - center).norm(), f64::abs);
            if arc_r <= r && inside(side, turn) {
                return Err(err(too_small));
            }
            let gamma = if inside(side, turn) {
                angle(center - pp)
            } else {
                angle(pp - center)
            };
            let end = pp + dir(gamma) * r;
            let b_len = (c - end).norm() / 2.0;
            let ab = angle(center - end);
            let a = angle(c - end) - ab;
            if a.cos().abs() < TOLERANCE_EQUAL {
                return Err(err(too_small));
            }
            let new_center = end + dir(ab) * (b_len / a.cos());
            if ((new_center - end).norm() - (new_center - c).norm()).abs() > spiral {
                return Err(err("cutter compensation made an entry arc with mismatched radii"));
            }
            self.comp.set_endpoint(c);
            let to = plane.lift(&end, pn);
            let sweep = find_turn(c, new_center, turn, end);
            let rec = self.comp_arc_record(to, new_center, turn, lineno)?;
            self.comp.queue.push((
                rec,
                Kind::Arc {
                    center: new_center,
                    turn,
                    sweep,
                },
            ));
            self.comp.first = false;
            self.pos = to;
            self.comp.programmed = p;
            return Ok(());
        }
        let op = plane.project(&self.comp.programmed);
        let arc_radius = (center - pp).norm();
        let mut theta = angle(c - op);
        theta = if side == Side::Left {
            theta - FRAC_PI_2
        } else {
            theta + FRAC_PI_2
        };
        let mut delta = angle(center - op);
        let alpha = if turn > 0 { delta - FRAC_PI_2 } else { delta + FRAC_PI_2 };
        let mut beta = if side == Side::Left {
            theta - alpha
        } else {
            alpha - theta
        };
        if beta > 1.5 * PI {
            beta -= TAU;
        } else if beta < -FRAC_PI_2 {
            beta += TAU;
        }
        let ins = inside(side, turn);
        let gamma = if ins {
            if arc_radius <= r {
                return Err(err(too_small));
            }
            angle(center - pp)
        } else {
            delta += PI;
            angle(pp - center)
        };
        let new_end = pp + dir(gamma) * r;
        let sweep = find_turn(op, center, turn, pp);
        if !(-SMALL..=PI + SMALL).contains(&beta) || ((beta - PI).abs() < SMALL && !ins) {
            // Concave: meet the previous offset path.
            let mid = match self.comp.front_arc() {
                None => {
                    let cy = arc_radius * (beta - FRAC_PI_2).sin();
                    let gouge = || err("arc move in concave corner cannot be reached by the tool without gouging");
                    let (dist, a) = if ins {
                        let dist = arc_radius - r;
                        let l = (cy + r) / dist;
                        if !(-1.0..=1.0).contains(&l) {
                            return Err(gouge());
                        }
                        (dist, if turn > 0 { theta + l.asin() } else { theta - l.asin() })
                    } else {
                        let dist = arc_radius + r;
                        let l = (cy - r) / dist;
                        if !(-1.0..=1.0).contains(&l) {
                            return Err(gouge());
                        }
                        (
                            dist,
                            if turn > 0 {
                                theta + PI - l.asin()
                            } else {
                                theta + PI + l.asin()
                            },
                        )
                    };
                    center + dir(a) * dist
                }
                Some((pc, pend, pturn)) => {
                    let oldrad = (pc - pend).norm();
                    let newrad = if ins { arc_radius - r } else { arc_radius + r };
                    let cc = (pc - center).norm();
                    if oldrad == 0.0 || cc == 0.0 {
                        return Err(err(
                            "arc to arc motion is invalid because the arcs have the same center",
                        ));
                    }
                    let a = (oldrad * oldrad + cc * cc - newrad * newrad) / (2.0 * oldrad * cc);
                    if !(-1.0..=1.0).contains(&a) {
                        return Err(err(
                            "arc to arc motion makes a corner the compensated tool can't fit in without gouging",
                        ));
                    }
                    let pull = a.acos();
                    let cc_dir = angle(center - pc);
                    let d = if inside(side, pturn) == (turn > 0) {
                        cc_dir + pull
                    } else {
                        cc_dir - pull
                    };
                    pc + dir(d) * oldrad
                }
            };
            self.comp.move_endpoint_and_flush(mid, u, lineno, out)?;
        } else if beta > SMALL {
            // Convex: an arc round the programmed corner first.
            let mid = op + dir(delta) * r;
            self.comp.dequeue(out);
            let cn = plane.normal_coord(&self.pos);
            let rec = self.comp_arc_record(
                plane.lift(&mid, cn),
                op,
                if side == Side::Left { -1 } else { 1 },
                lineno,
            )?;
            out.push_back(rec);
            self.comp.set_endpoint(mid);
        } else {
            self.comp.dequeue(out);
            self.comp.set_endpoint(c);
        }
        let to = plane.lift(&new_end, pn);
        let rec = self.comp_arc_record(to, center, turn, lineno)?;
        self.comp.queue.push((rec, Kind::Arc { center, turn, sweep }));
        self.pos = to;
        self.comp.programmed = p;
        Ok(())
    }
}

#[cfg(test)]
#[path = "comp_tests.rs"]
mod tests;
