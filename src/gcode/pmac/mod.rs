//! Turbo PMAC motion-program text interpreter.
//!
//! Reads the text a host downloads into a Turbo PMAC (a bare motion program,
//! or a download file with `CLOSE` / `OPEN PROG n CLEAR` / ... / `CLOSE`) and
//! turns it into toolpath records, one source line at a time.
//!
//! # What is understood
//!
//! - Case-insensitive text, optional spaces, several commands per line
//!   (`LINEAR X1 Y2 F3 M33=1 P400=7`), `;` comments, the thesis' trailing `%`.
//! - Modal move modes `RAPID`/`RPD`, `LINEAR`/`LIN`, `CIRCLE1`/`CIR1`
//!   (clockwise), `CIRCLE2`/`CIR2`; an axis word alone (`X1 Y2`) continues the
//!   mode. Axes X, Y, Z; `ABS`, `INC`, `ABS(X,Y)`, `ABS(R)`/`INC(R)` for the
//!   centre vector (incremental from the start point by default); `R` radius
//!   (negative = long arc); full circles when I/J/K is given and the end equals
//!   the start; helices when the normal axis moves; `NORMAL K-1` (XY, the
//!   default), `J-1` (ZX), `I-1` (YZ) and their positive forms, which flip the
//!   sense. `CIRCLE1` under `NORMAL K-1` is G2 in G17: `ccw = false`, plane xy.
//! - `F` (user units per second: the toolpath feed unit is mm/s), `TA`, `TS`
//!   (ms, one [`Record::Accel`] per line), `DWELL` and `DELAY` (ms, a
//!   [`Record::Dwell`] in seconds).
//! - `Pn=`, `Qn=`, `Mn=`, `In=` assignments with full expressions (`+ - * / %
//!   & | ^`, P/Q/M/I references, `SIN COS TAN ASIN ACOS ATAN ATAN2 LN EXP SQRT
//!   ABS INT`, degrees as with I15=0, `$` hex constants) and `Mn==` synchronous
//!   assignments. The shutter variable (`M33`) sets `beam` of later moves; the
//!   line counter (`P400`) is bookkeeping; every other assignment becomes a
//!   [`Record::Var`]. Axis and other values may be `(expressions)`.
//! - `G`, `M`, `T`, `D` without `=` are subroutine calls into PROG 1000-1003 on
//!   a controller; no such program exists here, so they do nothing (`M30` is
//!   not an end of program). `N`/`O` labels are accepted.
//!
//! # Buffers
//!
//! Until the first `OPEN` the file is read as a bare motion program (a file
//! with no `OPEN` at all is interpreted whole); the download preamble
//! `CLOSE`, `DELETE GATHER`, `DEFINE ROT n` does nothing there, and text from
//! an `&` or `#` on (on-line addressing such as `&1B1R`) is skipped. After a
//! `CLOSE` that ends a buffer, text up to the next `OPEN` is on-line commands
//! sent at download time (`&1B1R`, `I5=2`): it is ignored, except that a
//! move-mode word there (`LINEAR`, `RAPID`, `CIRCLE`) is an error, since it
//! would not be part of the program. Several program buffers (`OPEN PROG`,
//! `OPEN ROT`) are read in file order as one toolpath; PLC and kinematic
//! buffers (`OPEN PLC`, `OPEN FORWARD`, ...) are skipped. `RETURN` ends the
//! program: the rest of its buffer (subroutines reachable only by `GOSUB`) is
//! skipped. A buffer left open at the end of the file is an error.
//!
//! Words on a move's line: `F`, `TA` and `TS` anywhere on the line apply to
//! that move (as the generated programs assume: `LINEAR X1 Y2 F2`); any other
//! command after the axis words ends the move first, so `X1 M33=1` moves with
//! the shutter as it was and opens it afterwards.
//!
//! # Deliberate errors
//!
//! Flow control (`IF`, `WHILE`, `GOTO`, `GOSUB`, `CALL`), `TM` move times,
//! other axes (A B C U V W), tilted `NORMAL` planes, `CIRCLE` moves with
//! neither I/J/K nor R, `R` full circles, unknown words, and arcs whose end is
//! not on the circle are errors naming the line: a reader that guessed would
//! hand the simulator a toolpath the controller never runs.
//!
//! Parsing is a hand-written byte scanner with no allocation per line (a
//! [`Record::Var`] name is the only `String` made), bounded recursion in
//! expressions and no panicking index, so any input yields records or an
//! error.

mod expr;
mod lexer;
mod program;

use super::{GcodeError, LineInterpreter, ReadOptions, make_arc};
use crate::geometry::{P3, Plane};
use crate::model::toolpath::{Record, ShutterSwitch};
use expr::{Var, Vars};
use lexer::{Cursor, find_word};
use program::{MoveMode, PendingMove};
use std::collections::VecDeque;

/// Where in the file's buffer structure the reader is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Buffer {
    /// No buffer command seen yet: a bare motion program, interpreted.
    Bare,
    /// After CLOSE (or another on-line buffer command): on-line commands,
    /// ignored until the next OPEN.
    Outside,
    /// Inside OPEN PROG / OPEN ROT: interpreted.
    Open,
    /// Inside a buffer that is not a motion program (PLC, kinematics) or
    /// after RETURN: ignored until CLOSE.
    Skip,
}

/// Words looked for between buffers: OPEN starts the next buffer; a move
/// mode word there means program text outside its buffer (a CLOSE too
/// early), and a second CLOSE is unbalanced. Other on-line text (`&1B1R`,
/// `#1->1000X`, `I5=2`) is sent at download time and ignored.
const OUTSIDE_WORDS: &[&str] = &["OPEN", "CLOSE", "LINEAR", "RAPID", "CIRCLE"];

/// The Turbo PMAC motion-program interpreter.
pub struct PmacInterpreter {
    shutter: Option<Var>,
    counter: Option<Var>,
    /// A bad option, reported on the first line (construction cannot fail).
    config_error: Option<String>,
    /// P, Q, M and I variables, 0..=8191 each, as assigned so far.
    vars: Vars,
    pos: P3,
    mode: MoveMode,
    abs_axes: [bool; 3],
    abs_center: bool,
    plane: Plane,
    /// NORMAL points along the positive axis: CIRCLE1/2 senses swap.
    normal_positive: bool,
    feed: Option<f64>,
    beam: bool,
    /// The beam state of the last move written, and how the shutter was
    /// last switched (`==` or `=`): the next move carries the switch when
    /// its beam differs.
    moved_beam: bool,
    last_switch: ShutterSwitch,
    buffer: Buffer,
    opened_at: u64,
    /// Records made since the buffer opened (CLEAR would erase them).
    buffer_has_records: bool,
    ended: bool,
    pending: PendingMove,
    ta: Option<f64>,
    ts: Option<f64>,
}

impl PmacInterpreter {
    pub fn new(opts: &ReadOptions) -> Self {
        let shutter = Var::parse(&opts.shutter_var);
        let counter = Var::parse(&opts.line_counter_var);
        let config_error = if shutter.is_none() {
            Some(format!(
                "shutter variable '{}' is not a PMAC variable (such as M33)",
                opts.shutter_var
            ))
        } else if counter.is_none() {
            Some(format!(
                "line counter variable '{}' is not a PMAC variable (such as P400)",
                opts.line_counter_var
            ))
        } else {
            None
        };
        PmacInterpreter {
            shutter,
            counter,
            config_error,
            vars: Vars::new(),
            pos: opts.start,
            mode: MoveMode::Linear,
            abs_axes: [true; 3],
            abs_center: false,
            plane: Plane::Xy,
            normal_positive: false,
            feed: None,
            beam: false,
            moved_beam: false,
            last_switch: ShutterSwitch::Sync,
            buffer: Buffer::Bare,
            opened_at: 0,
            buffer_has_records: false,
            ended: false,
            pending: PendingMove::default(),
            ta: None,
            ts: None,
        }
    }

    fn push(&mut self, out: &mut VecDeque<Record>, rec: Record) {
        self.buffer_has_records = true;
        out.push_back(rec);
    }

    fn run(&mut self, cur: &mut Cursor, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        loop {
            match self.buffer {
                Buffer::Outside => match find_word(cur.b, cur.i, OUTSIDE_WORDS) {
                    Some((p, 0 | 1)) => cur.i = p,
                    Some((p, _)) => {
                        return Err(GcodeError::at(
                            lineno,
                            format!(
                                "'{}' after CLOSE and before the next OPEN: motion outside a program buffer \
                                 is not part of the program",
                                cur.snippet(p)
                            ),
                        ));
                    }
                    None => break,
                },
                Buffer::Skip => match find_word(cur.b, cur.i, &["CLOSE"]) {
                    Some((p, _)) => {
                        cur.i = p + 5;
                        self.buffer = Buffer::Outside;
                        continue;
                    }
                    None => break,
                },
                Buffer::Bare | Buffer::Open => {}
            }
            cur.skip_ws();
            match cur.peek() {
                None | Some(b';') => break,
                Some(c) => self.command(c, cur, lineno, out)?,
            }
        }
        self.flush(lineno, out)
    }

    /// Make what the line has collected: the TA/TS record, then the move.
    #[inline]
    fn flush(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if self.ta.is_some() || self.ts.is_some() {
            let rec = Record::Accel {
                ta_ms: self.ta.take(),
                ts_ms: self.ts.take(),
                block: Some(lineno),
            };
            self.push(out, rec);
        }
        if self.pending.active {
            self.emit_move(lineno, out)?;
        }
        Ok(())
    }
}

impl LineInterpreter for PmacInterpreter {
    fn line(&mut self, text: &[u8], lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if let Some(msg) = self.config_error.take() {
            return Err(GcodeError::at(lineno, msg));
        }
        let text = std::str::from_utf8(text).map_err(|e| {
            GcodeError::at(
                lineno,
                format!("not UTF-8 text (byte {} of the line)", e.valid_up_to() + 1),
            )
        })?;
        let mut cur = Cursor::new(text);
        let r = self.run(&mut cur, lineno, out);
        if r.is_err() {
            self.pending = PendingMove::default();
            self.ta = None;
            self.ts = None;
        }
        r
    }

    fn finish(&mut self, lineno: u64, _out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if matches!(self.buffer, Buffer::Open | Buffer::Skip) {
            return Err(GcodeError::at(
                lineno,
                format!(
                    "the buffer opened at line {} is never closed (CLOSE missing)",
                    self.opened_at
                ),
            ));
        }
        Ok(())
    }

    fn ended(&self) -> bool {
        self.ended
    }
}

#[cfg(test)]
mod tests;
