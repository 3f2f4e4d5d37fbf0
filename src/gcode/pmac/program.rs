//! Motion-program statements: moves, modes, assignments and the words of
//! one line, turned into toolpath records.

use super::expr::{VAR_MAX, Var, VarKind};
use super::lexer::{Cursor, Kw, is_ws, letter_name, match_keyword};
use super::{Buffer, GcodeError, PmacInterpreter, make_arc};
use crate::geometry::planar::center_from_radius;
use crate::geometry::{Arc3, EPS_LEN, P2, P3, Plane};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record, ShutterSwitch, arc_end_tolerance};
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
    axes: [Option<f64>; 3],
    /// A B C U V W: accepted only where they stay put.
    extra: [Option<f64>; 6],
    center: [Option<f64>; 3],
    radius: Option<f64>,
    pub(super) active: bool,
}

/// The axes besides X Y Z, in the order of `PendingMove::extra`.
pub(super) const EXTRA_AXES: [u8; 6] = *b"ABCUVW";

impl PmacInterpreter {
    pub(super) fn command(
        &mut self,
        c: u8,
        cur: &mut Cursor,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        if c.is_ascii_alphabetic() {
            let start = cur.i;
            let end = cur.letters_end(start);
            if end - start == 1 {
                cur.i = end;
                return self.letter_word(c.to_ascii_uppercase(), start, cur, lineno, out);
            }
            let run = cur.b.get(start..end).unwrap_or(&[]);
            let Some((name, kw)) = match_keyword(run) else {
                return Err(GcodeError::at(lineno, format!("unknown word '{}'", cur.snippet(start))));
            };
            cur.i = start + name.len();
            return self.keyword(name, kw, cur, lineno, out);
        }
        match c {
            b'%' => {
                // Feed-rate override (`%100`) or a tape delimiter: no motion.
                cur.i += 1;
                cur.skip_ws();
                cur.number();
                Ok(())
            }
            b'&' | b'#' if self.buffer == Buffer::Bare => {
                // On-line addressing (`&1B1R`, `#1J/`) in a bare file: sent to
                // the controller, not part of the program.
                self.online(cur, lineno)
            }
            b'&' | b'#' => Err(GcodeError::at(
                lineno,
                format!(
                    "on-line command '{}' inside an open program buffer (CLOSE it first)",
                    cur.snippet(cur.i)
                ),
            )),
            b'(' => Err(GcodeError::at(
                lineno,
                "'(' starts an expression in PMAC text; comments start with ';'",
            )),
            c if c.is_ascii_digit() || c == b'.' || c == b'-' || c == b'+' => Err(GcodeError::at(
                lineno,
                format!("value '{}' without a word before it", cur.snippet(cur.i)),
            )),
            _ => Err(GcodeError::at(
                lineno,
                format!(
                    "unexpected character '{}'",
                    cur.snippet(cur.i).chars().next().unwrap_or('?')
                ),
            )),
        }
    }

    pub(super) fn letter_word(
        &mut self,
        letter: u8,
        start: usize,
        cur: &mut Cursor,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        match letter {
            b'X' | b'Y' | b'Z' => {
                let k = usize::from(letter - b'X');
                let v = self.vars.data(cur, letter_name(letter), lineno)?;
                if self.pending.axes[k].replace(v).is_some() {
                    return Err(GcodeError::at(
                        lineno,
                        format!("{} given twice in one move", letter as char),
                    ));
                }
                self.pending.active = true;
                Ok(())
            }
            b'I' | b'J' | b'K' => {
                if letter == b'I'
                    && let Some(var) = self.assign_target(VarKind::I, cur, lineno)?
                {
                    return self.assign(var, cur, lineno, out);
                }
                let k = usize::from(letter - b'I');
                let v = self.vars.data(cur, letter_name(letter), lineno)?;
                if self.pending.center[k].replace(v).is_some() {
                    return Err(GcodeError::at(
                        lineno,
                        format!("{} given twice in one move", letter as char),
                    ));
                }
                self.pending.active = true;
                Ok(())
            }
            b'R' => {
                let v = self.vars.data(cur, letter_name(letter), lineno)?;
                if self.pending.radius.replace(v).is_some() {
                    return Err(GcodeError::at(lineno, "R given twice in one move"));
                }
                self.pending.active = true;
                Ok(())
            }
            b'F' => {
                let v = self.vars.data(cur, letter_name(letter), lineno)?;
                if v <= 0.0 {
                    return Err(GcodeError::at(lineno, format!("feed rate F{v} must be positive")));
                }
                self.feed = Some(v);
                self.move_time = None;
                Ok(())
            }
            b'P' | b'Q' | b'M' => {
                let kind = VarKind::from_letter(letter).unwrap_or(VarKind::P);
                if let Some(var) = self.assign_target(kind, cur, lineno)? {
                    return self.assign(var, cur, lineno, out);
                }
                if kind != VarKind::M {
                    return Err(GcodeError::at(
                        lineno,
                        format!(
                            "'{}' is not an assignment (expected {}n=value)",
                            cur.snippet(start),
                            letter as char
                        ),
                    ));
                }
                // M{data}: a call of PROG 1001; none exists, so nothing happens.
                self.flush(lineno, out)?;
                self.vars.data(cur, letter_name(letter), lineno)?;
                Ok(())
            }
            b'G' | b'T' | b'D' => {
                // Calls of PROG 1000/1002/1003, absent here: no effect.
                self.flush(lineno, out)?;
                self.vars.data(cur, letter_name(letter), lineno)?;
                Ok(())
            }
            b'N' | b'O' => {
                self.flush(lineno, out)?;
                cur.skip_ws();
                if cur.uint().is_none() {
                    return Err(GcodeError::at(
                        lineno,
                        format!("label {} needs a number", letter as char),
                    ));
                }
                Ok(())
            }
            b'A' | b'B' | b'C' | b'U' | b'V' | b'W' => {
                // A, B, C are rotary axes (degrees) carried on the move;
                // U, V, W are checked at the move to stay where they are.
                let k = EXTRA_AXES.iter().position(|&a| a == letter).unwrap_or(0);
                let v = self.vars.data(cur, letter_name(letter), lineno)?;
                if self.pending.extra[k].replace(v).is_some() {
                    return Err(GcodeError::at(
                        lineno,
                        format!("{} given twice in one move", letter as char),
                    ));
                }
                self.pending.active = true;
                Ok(())
            }
            _ => Err(GcodeError::at(lineno, format!("unknown word '{}'", cur.snippet(start)))),
        }
    }

    pub(super) fn keyword(
        &mut self,
        name: &'static str,
        kw: Kw,
        cur: &mut Cursor,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        match kw {
            Kw::Ta | Kw::Ts => {
                let v = self.vars.data(cur, name, lineno)?;
                if v < 0.0 {
                    return Err(GcodeError::at(lineno, format!("{name}{v}: time must not be negative")));
                }
                if kw == Kw::Ta {
                    self.ta = Some(v);
                } else {
                    self.ts = Some(v);
                }
                return Ok(());
            }
            Kw::Tm => {
                // Move time, ms: later feed moves take it until an F.
                let v = self.vars.data(cur, name, lineno)?;
                if v < 0.0 {
                    return Err(GcodeError::at(lineno, format!("TM{v}: time must not be negative")));
                }
                self.move_time = Some(v);
                return Ok(());
            }
            Kw::Frax => {
                self.frax(cur, lineno)?;
                return Ok(());
            }
            Kw::Flow => {
                return Err(GcodeError::at(
                    lineno,
                    format!("{name}: program flow control is not supported (straight-line programs only)"),
                ));
            }
            Kw::Unsupported => {
                return Err(GcodeError::at(
                    lineno,
                    format!("{name} is not supported by the PMAC reader"),
                ));
            }
            _ => {}
        }
        // Everything else ends the move being collected.
        self.flush(lineno, out)?;
        match kw {
            Kw::Linear => self.mode = MoveMode::Linear,
            Kw::Rapid => self.mode = MoveMode::Rapid,
            Kw::Circle => {
                self.mode = match cur.peek() {
                    Some(b'1') => MoveMode::Circle1,
                    Some(b'2') => MoveMode::Circle2,
                    _ => return Err(GcodeError::at(lineno, "CIRCLE must be CIRCLE1 or CIRCLE2")),
                };
                cur.i += 1;
                if cur.peek().is_some_and(|c| c.is_ascii_digit() || c == b'.') {
                    return Err(GcodeError::at(lineno, "CIRCLE must be CIRCLE1 or CIRCLE2"));
                }
            }
            Kw::Abs | Kw::Inc => self.abs_inc(kw == Kw::Abs, cur, lineno)?,
            Kw::Normal => self.normal(cur, lineno)?,
            Kw::Dwell | Kw::Delay => {
                let v = self.vars.data(cur, name, lineno)?;
                if v < 0.0 {
                    return Err(GcodeError::at(lineno, format!("{name} {v}: time must not be negative")));
                }
                self.push(
                    out,
                    Record::Dwell {
                        seconds: v / 1000.0,
                        block: Some(lineno),
                    },
                );
            }
            Kw::Open => self.open(cur, lineno)?,
            Kw::Close => self.close(lineno)?,
            Kw::Clear => {
                if self.buffer_has_records {
                    return Err(GcodeError::at(
                        lineno,
                        "CLEAR after program lines would erase them; put it right after OPEN PROG",
                    ));
                }
            }
            Kw::Delete | Kw::Define => {
                // On-line buffer management (DELETE GATHER, DEFINE ROT 100):
                // executed at download time, no part of the motion.
                cur.skip_ws();
                cur.i = cur.letters_end(cur.i);
                while cur
                    .peek()
                    .is_some_and(|c| is_ws(c) || c.is_ascii_digit() || c == b',' || c == b'.')
                {
                    cur.i += 1;
                }
            }
            Kw::Return => {
                if self.buffer == Buffer::Open {
                    self.buffer = Buffer::Skip;
                } else {
                    self.ended = true;
                    cur.i = cur.b.len();
                }
            }
            Kw::Ta | Kw::Ts | Kw::Tm | Kw::Frax | Kw::Flow | Kw::Unsupported => {}
        }
        Ok(())
    }

    /// `ABS`/`INC` with an optional axis list; `R` in the list is the centre
    /// vector mode, which a bare ABS/INC leaves alone (as PMAC does).
    pub(super) fn abs_inc(&mut self, abs: bool, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        let word = if abs { "ABS" } else { "INC" };
        cur.skip_ws();
        if !cur.eat(b'(') {
            self.abs_axes = [abs; 3];
            self.abs_extra = [abs; 6];
            return Ok(());
        }
        let mut any = false;
        loop {
            cur.skip_ws();
            let Some(c) = cur.peek() else {
                return Err(GcodeError::at(lineno, format!("{word}( without ')'")));
            };
            cur.i += 1;
            match c.to_ascii_uppercase() {
                b')' => break,
                b',' => continue,
                b'X' => self.abs_axes[0] = abs,
                b'Y' => self.abs_axes[1] = abs,
                b'Z' => self.abs_axes[2] = abs,
                b'R' => self.abs_center = abs,
                c @ (b'A' | b'B' | b'C' | b'U' | b'V' | b'W') => {
                    let k = EXTRA_AXES.iter().position(|&a| a == c).unwrap_or(0);
                    self.abs_extra[k] = abs;
                }
                _ => {
                    return Err(GcodeError::at(
                        lineno,
                        format!(
                            "{word}(...): expected an axis (X Y Z A B C U V W) or R, found '{}'",
                            c as char
                        ),
                    ));
                }
            }
            any = true;
        }
        if !any {
            return Err(GcodeError::at(lineno, format!("{word}() with an empty list")));
        }
        Ok(())
    }

    /// `NORMAL` with an I/J/K vector along one axis.
    pub(super) fn normal(&mut self, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        let mut v = [0.0f64; 3];
        let mut given = 0;
        loop {
            cur.skip_ws();
            let Some(c) = cur.peek().map(|c| c.to_ascii_uppercase()) else {
                break;
            };
            if !matches!(c, b'I' | b'J' | b'K') || cur.peek_at(1).is_some_and(|n| n.is_ascii_alphabetic()) {
                break;
            }
            cur.i += 1;
            v[usize::from(c - b'I')] = self.vars.data(cur, letter_name(c), lineno)?;
            given += 1;
        }
        if given == 0 {
            return Err(GcodeError::at(lineno, "NORMAL needs a vector, e.g. NORMAL K-1"));
        }
        let mut axis = None;
        let mut nonzero = 0;
        for (k, c) in v.iter().enumerate() {
            if *c != 0.0 {
                axis = Some(k);
                nonzero += 1;
            }
        }
        let (Some(k), 1) = (axis, nonzero) else {
            return Err(GcodeError::at(
                lineno,
                "NORMAL must lie along I, J or K (tilted arc planes are not supported)",
            ));
        };
        self.plane = match k {
            0 => Plane::Yz,
            1 => Plane::Xz,
            _ => Plane::Xy,
        };
        self.normal_positive = v[k] > 0.0;
        Ok(())
    }

    /// After the letter of a P/Q/M/I word: the variable when the word is an
    /// assignment (`P12=`, `M33 ==`), with the cursor on the `=`; otherwise
    /// `None` and the cursor unmoved.
    pub(super) fn assign_target(
        &self,
        kind: VarKind,
        cur: &mut Cursor,
        lineno: u64,
    ) -> Result<Option<Var>, GcodeError> {
        let save = cur.i;
        cur.skip_ws();
        if cur.peek() == Some(b'(') && kind != VarKind::I {
            // `M(expr)` is a call; `P(expr)=` an indirect assignment.
            let mut depth = 0usize;
            let mut j = cur.i;
            while let Some(&c) = cur.b.get(j) {
                j += 1;
                depth = match c {
                    b'(' => depth + 1,
                    b')' => depth.saturating_sub(1),
                    _ => depth,
                };
                if depth == 0 {
                    break;
                }
            }
            while cur.b.get(j).copied().is_some_and(is_ws) {
                j += 1;
            }
            if cur.b.get(j) == Some(&b'=') {
                return Err(GcodeError::at(
                    lineno,
                    format!("indirect {}(...) assignments are not supported", kind.letter()),
                ));
            }
            cur.i = save;
            return Ok(None);
        }
        let Some(n) = cur.uint() else {
            cur.i = save;
            return Ok(None);
        };
        cur.skip_ws();
        match cur.peek() {
            Some(b'=') => {}
            Some(op @ (b'&' | b'|' | b'^')) if cur.peek_at(1) == Some(b'=') => {
                return Err(GcodeError::at(
                    lineno,
                    format!(
                        "{}{n}{}= (synchronous bit operation) is not supported",
                        kind.letter(),
                        op as char
                    ),
                ));
            }
            _ => {
                cur.i = save;
                return Ok(None);
            }
        }
        if n > u64::from(VAR_MAX) {
            return Err(GcodeError::at(
                lineno,
                format!("variable {}{n} is out of range (0 to {VAR_MAX})", kind.letter()),
            ));
        }
        Ok(Some(Var { kind, index: n as u32 }))
    }

    /// `= value` or `== value` for `var`, the cursor on the first `=`.
    pub(super) fn assign(
        &mut self,
        var: Var,
        cur: &mut Cursor,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        self.flush(lineno, out)?;
        cur.eat(b'=');
        let sync = cur.eat(b'=');
        if sync && var.kind != VarKind::M {
            return Err(GcodeError::at(
                lineno,
                format!("{}==: synchronous assignment is for M-variables only", var.name()),
            ));
        }
        let value = self.vars.expr(cur, 0, lineno)?;
        if !value.is_finite() {
            return Err(GcodeError::at(
                lineno,
                format!("{} is assigned a value that is not a finite number", var.name()),
            ));
        }
        self.vars.set(var, value);
        if Some(var) == self.shutter {
            self.beam = value != 0.0;
            self.last_switch = if sync {
                ShutterSwitch::Sync
            } else {
                ShutterSwitch::Immediate
            };
        } else if Some(var) != self.counter {
            self.push(
                out,
                Record::Var {
                    name: var.name(),
                    value,
                    sync,
                    block: Some(lineno),
                },
            );
        }
        Ok(())
    }

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

    /// `FRAX(X,Y,...)`: the axes whose vector speed F is.
    fn frax(&mut self, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        cur.skip_ws();
        if !cur.eat(b'(') {
            return Err(GcodeError::at(lineno, "FRAX needs an axis list, e.g. FRAX(X,Y,Z)"));
        }
        let mut set = [false; 3];
        let mut rotary = false;
        loop {
            cur.skip_ws();
            let Some(c) = cur.peek() else {
                return Err(GcodeError::at(lineno, "FRAX( without ')'"));
            };
            cur.i += 1;
            match c.to_ascii_uppercase() {
                b')' => break,
                b',' => {}
                c @ (b'X' | b'Y' | b'Z') => set[usize::from(c - b'X')] = true,
                b'A' | b'B' | b'C' => rotary = true,
                b'U' | b'V' | b'W' => {}
                _ => {
                    return Err(GcodeError::at(
                        lineno,
                        format!("FRAX(...): expected axes (X Y Z A B C U V W), found '{}'", c as char),
                    ));
                }
            }
        }
        self.frax_axes = set;
        self.frax_rotary = rotary;
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
                    // arc tolerance its centre is the chord's midpoint.
                    None if (e - s).norm() / 2.0 - r.abs() <= arc_end_tolerance(r) && r != 0.0 => {
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
        let tol = arc_end_tolerance((s - center).norm());
        make_arc(&self.pos, to, center, ccw, plane, 0, tol, lineno)
    }
}
