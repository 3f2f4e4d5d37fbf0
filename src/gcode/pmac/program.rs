//! Motion-program statements: the words of one line, modes and
//! assignments, turned into toolpath records (a move's words go to
//! `PendingMove`, made into a record in `motion.rs`).

use super::expr::{VAR_MAX, Var, VarKind};
use super::lexer::{Cursor, Kw, is_ws, letter_name, match_keyword};
use super::motion::{EXTRA_AXES, MoveMode};
use super::{Buffer, GcodeError, PmacInterpreter};
use crate::geometry::Plane;
use crate::model::toolpath::{Record, ShutterSwitch};
use std::collections::VecDeque;

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
}
