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
//! neither I/J/K nor R, `R` full circles and unknown words are errors naming
//! the line: a reader that guessed would hand the simulator a toolpath the
//! controller never runs. An arc whose end is off its circle is read as the
//! spiral the controller makes of it when the miss is within LinuxCNC's
//! rule for I/J/K arcs (rounding: a program printed with 3 decimals misses
//! by a micrometre or more on small arcs), and is an error beyond it (a
//! wrong centre).
//!
//! Parsing is a hand-written byte scanner with no allocation per line (a
//! [`Record::Var`] name is the only `String` made), bounded recursion in
//! expressions and no panicking index, so any input yields records or an
//! error.

mod buffers;
mod expr;
mod lexer;
mod motion;
mod online;
mod preprocess;
mod program;

use super::{GcodeError, LineInterpreter, Notes, ReadOptions, make_arc};
use crate::geometry::{P3, Plane};
use crate::model::toolpath::{Record, ShutterSwitch};
use expr::{Var, VarKind, Vars};
use lexer::{Cursor, find_word, is_ws, match_keyword};
use motion::{MoveMode, PendingMove};
use preprocess::{Defines, Directive, MAX_INCLUDE_DEPTH};
use std::collections::VecDeque;
use std::path::PathBuf;

/// Lines held while the reader cannot yet tell a bare program from a
/// download file's preamble; past this many it reads them as a program.
const HOLD_MAX: usize = 10_000;

/// Where in the file's buffer structure the reader is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Buffer {
    /// Nothing yet tells a bare program from a download file: on-line
    /// commands (`&1`, `#1->`, `DELETE GATHER`, ranges) are executed,
    /// variable assignments held until an `OPEN` (a download file: they
    /// were on-line) or program text (a bare program: they are its first
    /// lines) decides.
    Undecided,
    /// A bare motion program, interpreted.
    Bare,
    /// A download file between buffers: on-line commands until the next
    /// OPEN.
    Outside,
    /// Inside OPEN PROG / OPEN ROT: interpreted.
    Open,
    /// Inside a buffer that is not a motion program (PLC, kinematics) or
    /// after RETURN: ignored until CLOSE.
    Skip,
}

/// How a line read before the file's kind is known counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LineClass {
    Blank,
    /// Opens a buffer: a download file.
    Open,
    /// Only an on-line command starts so (`&`, `#`, `Mn->`, `I1,8=`,
    /// `DELETE`, `CLOSE` ...).
    Online,
    /// A variable assignment (`P1=2`, `NAME = 3`): on-line or program.
    Held,
    /// Program text: a bare program.
    Program,
}

fn classify(text: &str) -> LineClass {
    let b = text.as_bytes();
    let mut i = 0;
    while b.get(i).copied().is_some_and(is_ws) {
        i += 1;
    }
    let Some(&c) = b.get(i) else {
        return LineClass::Blank;
    };
    if c == b';' {
        return LineClass::Blank;
    }
    if find_word(b, i, &["OPEN"]).is_some() {
        return LineClass::Open;
    }
    if c == b'&' || c == b'#' {
        return LineClass::Online;
    }
    if !c.is_ascii_alphabetic() {
        return LineClass::Program;
    }
    let letters = b[i..]
        .iter()
        .position(|c| !c.is_ascii_alphabetic())
        .map_or(b.len(), |k| i + k);
    let ident = b[i..]
        .iter()
        .position(|c| !(c.is_ascii_alphanumeric() || *c == b'_'))
        .map_or(b.len(), |k| i + k);
    let assignment_at = |mut j: usize| {
        while b.get(j).copied().is_some_and(is_ws) {
            j += 1;
        }
        b.get(j) == Some(&b'=') && b.get(j + 1) != Some(&b'=')
    };
    if letters == i + 1 && VarKind::from_letter(c).is_some() {
        let mut j = letters;
        if b.get(j).is_some_and(u8::is_ascii_digit) {
            while b.get(j).is_some_and(u8::is_ascii_digit) {
                j += 1;
            }
        } else if b.get(j) == Some(&b'(') {
            let mut depth = 0usize;
            while let Some(&c) = b.get(j) {
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
        } else {
            return LineClass::Program;
        }
        if b.get(j) == Some(&b',') || b.get(j..j + 2) == Some(b"..") {
            return LineClass::Online;
        }
        let mut k = j;
        while b.get(k).copied().is_some_and(is_ws) {
            k += 1;
        }
        if b.get(k..k + 2) == Some(b"->") {
            return LineClass::Online;
        }
        if b.get(k..k + 2) == Some(b"==") {
            // Synchronous assignment: program text only.
            return LineClass::Program;
        }
        return if assignment_at(j) {
            LineClass::Held
        } else if c.eq_ignore_ascii_case(&b'M') {
            // M30: a subroutine call in a program.
            LineClass::Program
        } else {
            // P1, I130 alone: a query (no program text reads so).
            LineClass::Online
        };
    }
    let run = &b[i..letters];
    if online::is_setup_word(run) {
        return LineClass::Online;
    }
    if ident > i + 1
        && assignment_at(ident)
        && !(ident == letters && match_keyword(run).is_some_and(|(k, _)| k.len() == run.len()))
    {
        return LineClass::Held;
    }
    LineClass::Program
}

/// `e` with `prefix` (where in an #include the line is) before its message.
fn located(e: GcodeError, prefix: &str) -> GcodeError {
    if prefix.is_empty() {
        return e;
    }
    match e {
        GcodeError::Invalid { line, msg } => GcodeError::at(line, format!("{prefix}{msg}")),
        GcodeError::Io { line, source } => GcodeError::at(line, format!("{prefix}{source}")),
    }
}

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
    /// A B C U V W: where they are (they never move) and ABS/INC.
    extra_pos: [f64; 6],
    abs_extra: [bool; 6],
    /// FRAX: which of X Y Z the feed F is the vector speed of.
    frax_axes: [bool; 3],
    /// A rotary axis A, B or C is in the FRAX list (its speed would count in F).
    frax_rotary: bool,
    /// A rotary axis has moved: every later move carries A, B, C.
    abc_used: bool,
    /// TM: feed moves take this many ms each (until an F).
    move_time: Option<f64>,
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
    /// `#define`s made so far.
    defines: Defines,
    /// Where the line being read is when it comes from an `#include`
    /// (`in defs.pmc:3: `, nested ones in turn), for notes and errors.
    loc: String,
    /// The files being read, outermost first (the program's own file when
    /// known): `#include` names are relative to the last.
    include_stack: Vec<PathBuf>,
    notes: Notes,
    /// `--program n`.
    program_choice: Option<u32>,
    /// The motion buffer read (`PROG 10`), once one is.
    program_read: Option<String>,
    /// Every motion buffer met, for messages.
    buffers_seen: Vec<String>,
    /// Lines held while undecided: line, `loc`, text.
    held: Vec<(u64, String, String)>,
}

impl PmacInterpreter {
    /// An interpreter at `opts.start` in the controller's power-on modes
    /// (ABS, LINEAR, incremental arc centres, XY plane), reading the program
    /// `opts.pmac_program` of a download file (the first one when `None`),
    /// with `opts.shutter_var` as the shutter and `opts.line_counter_var`
    /// as the block counter. A variable name that cannot be parsed is
    /// reported by the first line read.
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
            extra_pos: [0.0; 6],
            abs_extra: [true; 6],
            frax_axes: [true; 3],
            frax_rotary: false,
            abc_used: false,
            move_time: None,
            abs_center: false,
            plane: Plane::Xy,
            normal_positive: false,
            feed: None,
            beam: false,
            moved_beam: false,
            last_switch: ShutterSwitch::Sync,
            buffer: Buffer::Undecided,
            opened_at: 0,
            buffer_has_records: false,
            ended: false,
            pending: PendingMove::default(),
            ta: None,
            ts: None,
            defines: Defines::default(),
            loc: String::new(),
            include_stack: opts.source_path.iter().cloned().collect(),
            notes: opts.notes.clone(),
            program_choice: opts.pmac_program,
            program_read: None,
            buffers_seen: Vec::new(),
            held: Vec::new(),
        }
    }

    /// An interpreter for the lines of one program buffer (what a
    /// controller runs), not a file: no download-file preamble to tell
    /// apart, so every line is program text from the first.
    pub fn program_body(opts: &ReadOptions) -> Self {
        let mut p = Self::new(opts);
        p.buffer = Buffer::Bare;
        p
    }

    /// Leave a note on `lineno` (prefixed with where in an #include).
    fn note(&self, lineno: u64, text: impl AsRef<str>) {
        self.notes.push(lineno, format!("{}{}", self.loc, text.as_ref()));
    }

    /// One line of a source file (the program's or an included one's), as
    /// the downloader sees it: a directive, or text with defines
    /// substituted. `lineno` is the program file's line.
    fn source_line(&mut self, text: &str, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if let Some(d) = preprocess::directive(text) {
            let r = match d {
                Err(m) => Err(GcodeError::at(lineno, m)),
                Ok(Directive::Define { name, text }) => {
                    self.defines.define(name, text);
                    Ok(())
                }
                Ok(Directive::Undefine(name)) => {
                    self.defines.undefine(name);
                    Ok(())
                }
                Ok(Directive::Include(name)) => return self.include(name, lineno, out),
            };
            return r.map_err(|e| located(e, &self.loc));
        }
        let expanded = match self.defines.expand(text) {
            Ok(t) => t,
            Err(m) => return Err(located(GcodeError::at(lineno, m), &self.loc)),
        };
        self.logical_line(&expanded, lineno, out)
    }

    /// `#include "name"` on line `lineno`: the file's lines in place.
    fn include(&mut self, name: &str, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        let fail = |s: &Self, msg: String| Err(located(GcodeError::at(lineno, msg), &s.loc));
        if self.include_stack.len() > MAX_INCLUDE_DEPTH {
            return fail(
                self,
                format!("#include \"{name}\": includes nested deeper than {MAX_INCLUDE_DEPTH}"),
            );
        }
        let dir = self
            .include_stack
            .last()
            .and_then(|p| p.parent())
            .map(PathBuf::from)
            .unwrap_or_default();
        let path = dir.join(name);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) => {
                return fail(
                    self,
                    format!("#include \"{name}\": cannot read {}: {e}", path.display()),
                );
            }
        };
        let same = |a: &PathBuf| match (a.canonicalize(), path.canonicalize()) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        };
        if let Some(k) = self.include_stack.iter().position(same) {
            let chain: Vec<String> = self.include_stack[k..]
                .iter()
                .map(|p| p.display().to_string())
                .chain(std::iter::once(path.display().to_string()))
                .collect();
            return fail(
                self,
                format!("#include \"{name}\": a cycle ({})", chain.join(" includes ")),
            );
        }
        let Ok(text) = String::from_utf8(bytes) else {
            return fail(
                self,
                format!("#include \"{name}\": {} is not UTF-8 text", path.display()),
            );
        };
        let outer = std::mem::take(&mut self.loc);
        self.include_stack.push(path.clone());
        let mut r = Ok(());
        for (k, l) in text.lines().enumerate() {
            self.loc = format!("{outer}in {}:{}: ", path.display(), k + 1);
            r = self.source_line(l, lineno, out);
            if r.is_err() || self.ended {
                break;
            }
        }
        self.include_stack.pop();
        self.loc = outer;
        r
    }

    /// A line after the preprocessor.
    fn logical_line(&mut self, text: &str, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if self.buffer == Buffer::Undecided {
            match classify(text) {
                LineClass::Blank => return Ok(()),
                LineClass::Held if self.held.len() < HOLD_MAX => {
                    self.held.push((lineno, self.loc.clone(), text.to_string()));
                    return Ok(());
                }
                LineClass::Online => {
                    let mut cur = Cursor::new(text);
                    return self.online(&mut cur, lineno).map_err(|e| located(e, &self.loc));
                }
                LineClass::Open => self.decide(true, out)?,
                LineClass::Held | LineClass::Program => self.decide(false, out)?,
            }
        }
        let mut cur = Cursor::new(text);
        let r = self.run(&mut cur, lineno, out);
        if r.is_err() {
            self.pending = PendingMove::default();
            self.ta = None;
            self.ts = None;
        }
        r.map_err(|e| located(e, &self.loc))
    }

    /// The file is a download file (`download`) or a bare program: read
    /// the held lines as what they are.
    fn decide(&mut self, download: bool, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        self.buffer = if download { Buffer::Outside } else { Buffer::Bare };
        let held = std::mem::take(&mut self.held);
        let here = std::mem::take(&mut self.loc);
        for (l, loc, t) in held {
            self.loc = loc;
            let mut cur = Cursor::new(&t);
            let r = if download {
                self.online(&mut cur, l)
            } else {
                self.run(&mut cur, l, out)
            };
            if let Err(e) = r {
                let e = located(e, &self.loc);
                self.loc = here;
                return Err(e);
            }
        }
        self.loc = here;
        Ok(())
    }

    fn push(&mut self, out: &mut VecDeque<Record>, rec: Record) {
        self.buffer_has_records = true;
        out.push_back(rec);
    }

    fn run(&mut self, cur: &mut Cursor, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        loop {
            match self.buffer {
                Buffer::Outside | Buffer::Undecided => {
                    self.online(cur, lineno)?;
                    if matches!(self.buffer, Buffer::Outside | Buffer::Undecided) {
                        break;
                    }
                    continue;
                }
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
        self.source_line(text, lineno, out)
    }

    fn finish(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if self.buffer == Buffer::Undecided {
            // Assignments only, or nothing: a bare program.
            self.decide(false, out)?;
        }
        if matches!(self.buffer, Buffer::Open | Buffer::Skip) {
            return Err(GcodeError::at(
                lineno,
                format!(
                    "the buffer opened at line {} is never closed (CLOSE missing)",
                    self.opened_at
                ),
            ));
        }
        self.check_program_found(lineno)
    }

    fn ended(&self) -> bool {
        self.ended
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_download;
