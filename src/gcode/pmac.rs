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

use super::{GcodeError, LineInterpreter, ReadOptions, make_arc};
use crate::geometry::planar::center_from_radius;
use crate::geometry::{EPS_LEN, P2, P3, Plane};
use crate::model::toolpath::{ArcData, Motion, MotionKind, Record, ShutterSwitch, arc_end_tolerance};
use std::collections::VecDeque;

/// Highest variable number of each kind (P, Q, M, I) on a Turbo PMAC.
const VAR_MAX: u32 = 8191;
const VAR_SLOTS: usize = VAR_MAX as usize + 1;
/// Deepest nesting of parentheses, functions and unary signs in one
/// expression; deeper text is refused instead of overflowing the stack.
const MAX_DEPTH: u32 = 64;

/// The four PMAC variable families.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum VarKind {
    P,
    Q,
    M,
    I,
}

impl VarKind {
    fn from_letter(c: u8) -> Option<VarKind> {
        match c.to_ascii_uppercase() {
            b'P' => Some(VarKind::P),
            b'Q' => Some(VarKind::Q),
            b'M' => Some(VarKind::M),
            b'I' => Some(VarKind::I),
            _ => None,
        }
    }

    fn letter(self) -> char {
        match self {
            VarKind::P => 'P',
            VarKind::Q => 'Q',
            VarKind::M => 'M',
            VarKind::I => 'I',
        }
    }
}

/// One controller variable, such as `M33` or `P400`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Var {
    kind: VarKind,
    index: u32,
}

impl Var {
    /// Index into the interpreter's variable store.
    fn slot(self) -> usize {
        self.kind as usize * VAR_SLOTS + self.index as usize
    }

    /// Parse a configured name such as `M33` (any case, spaces around).
    fn parse(name: &str) -> Option<Var> {
        let b = name.trim().as_bytes();
        let (&first, digits) = b.split_first()?;
        let kind = VarKind::from_letter(first)?;
        if digits.is_empty() || digits.len() > 5 || !digits.iter().all(u8::is_ascii_digit) {
            return None;
        }
        let index = digits.iter().fold(0u32, |n, d| n * 10 + u32::from(d - b'0'));
        (index <= VAR_MAX).then_some(Var { kind, index })
    }

    fn name(self) -> String {
        format!("{}{}", self.kind.letter(), self.index)
    }
}

/// The modal move mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MoveMode {
    Rapid,
    Linear,
    /// CIRCLE1: clockwise about the NORMAL vector.
    Circle1,
    /// CIRCLE2: counter-clockwise about the NORMAL vector.
    Circle2,
}

impl MoveMode {
    fn name(self) -> &'static str {
        match self {
            MoveMode::Rapid => "RAPID",
            MoveMode::Linear => "LINEAR",
            MoveMode::Circle1 => "CIRCLE1",
            MoveMode::Circle2 => "CIRCLE2",
        }
    }
}

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

/// The words of one move collected on a line; the move is made when a
/// command that is not part of it (or the end of the line) arrives, so `F`,
/// `TA` and `TS` anywhere on the move's line apply to it.
#[derive(Debug, Clone, Copy, Default)]
struct PendingMove {
    axes: [Option<f64>; 3],
    center: [Option<f64>; 3],
    radius: Option<f64>,
    active: bool,
}

/// What a multi-letter word means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kw {
    Linear,
    Rapid,
    Circle,
    Abs,
    Inc,
    Normal,
    Dwell,
    Delay,
    Ta,
    Ts,
    Tm,
    Open,
    Close,
    Clear,
    Delete,
    Define,
    Return,
    /// Program flow: needs a real interpreter with jumps.
    Flow,
    /// A PMAC command this reader does not model.
    Unsupported,
}

/// Program words with PMAC's short forms, grouped by first letter so a
/// lookup compares a handful of candidates, not the whole vocabulary.
fn keywords_for(first: u8) -> &'static [(&'static str, Kw)] {
    match first.to_ascii_uppercase() {
        b'A' => &[("ABS", Kw::Abs), ("ADDRESS", Kw::Unsupported), ("ADR", Kw::Unsupported)],
        b'B' => &[
            ("BLOCKSTART", Kw::Unsupported),
            ("BSTART", Kw::Unsupported),
            ("BLOCKSTOP", Kw::Unsupported),
            ("BSTOP", Kw::Unsupported),
        ],
        b'C' => &[
            ("CIRCLE", Kw::Circle),
            ("CIR", Kw::Circle),
            ("CLOSE", Kw::Close),
            ("CLEAR", Kw::Clear),
            ("CALL", Kw::Flow),
            ("CC", Kw::Unsupported),
            ("COMMAND", Kw::Unsupported),
            ("CMD", Kw::Unsupported),
        ],
        b'D' => &[
            ("DWELL", Kw::Dwell),
            ("DWE", Kw::Dwell),
            ("DELAY", Kw::Delay),
            ("DLY", Kw::Delay),
            ("DELETE", Kw::Delete),
            ("DEL", Kw::Delete),
            ("DEFINE", Kw::Define),
            ("DEF", Kw::Define),
            ("DISPLAY", Kw::Unsupported),
            ("DISP", Kw::Unsupported),
            ("DISABLE", Kw::Unsupported),
            ("DIS", Kw::Unsupported),
        ],
        b'E' => &[
            ("ELSE", Kw::Flow),
            ("ENDIF", Kw::Flow),
            ("ENDI", Kw::Flow),
            ("ENDWHILE", Kw::Flow),
            ("ENDW", Kw::Flow),
            ("ENABLE", Kw::Unsupported),
            ("ENA", Kw::Unsupported),
        ],
        b'F' => &[("FRAX", Kw::Unsupported)],
        b'G' => &[("GOTO", Kw::Flow), ("GOSUB", Kw::Flow)],
        b'H' => &[("HOME", Kw::Unsupported), ("HOMEZ", Kw::Unsupported)],
        b'I' => &[("INC", Kw::Inc), ("IF", Kw::Flow)],
        b'L' => &[("LINEAR", Kw::Linear), ("LIN", Kw::Linear), ("LOCK", Kw::Unsupported)],
        b'N' => &[("NORMAL", Kw::Normal), ("NRM", Kw::Normal)],
        b'O' => &[("OPEN", Kw::Open)],
        b'P' => &[
            ("PVT", Kw::Unsupported),
            ("PSET", Kw::Unsupported),
            ("PRELUDE", Kw::Unsupported),
            ("PAUSE", Kw::Unsupported),
        ],
        b'R' => &[
            ("RAPID", Kw::Rapid),
            ("RPD", Kw::Rapid),
            ("RETURN", Kw::Return),
            ("RET", Kw::Return),
            ("READ", Kw::Unsupported),
        ],
        b'S' => &[
            ("STOP", Kw::Flow),
            ("SPLINE", Kw::Unsupported),
            ("SEND", Kw::Unsupported),
        ],
        b'T' => &[
            ("TA", Kw::Ta),
            ("TS", Kw::Ts),
            ("TM", Kw::Tm),
            ("TSELECT", Kw::Unsupported),
            ("TSEL", Kw::Unsupported),
            ("TINIT", Kw::Unsupported),
        ],
        b'U' => &[("UNLOCK", Kw::Unsupported)],
        b'W' => &[("WHILE", Kw::Flow), ("WAIT", Kw::Flow)],
        _ => &[],
    }
}

/// The longest keyword that starts the letter run `w`, so that `LINEARX1`
/// reads as `LINEAR X1` and `DELAY` is not `DEL` + `AY`.
fn match_keyword(w: &[u8]) -> Option<(&'static str, Kw)> {
    let mut best: Option<(&'static str, Kw)> = None;
    for &(name, kw) in keywords_for(*w.first()?) {
        let n = name.as_bytes();
        if w.get(..n.len()).is_some_and(|p| p.eq_ignore_ascii_case(n)) && best.is_none_or(|(b, _)| b.len() < n.len()) {
            best = Some((name, kw));
        }
    }
    best
}

/// Expression functions (PMAC's set). `ATAN2` is matched as `ATAN` + `2`.
#[derive(Debug, Clone, Copy)]
enum Func {
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Atan2,
    Ln,
    Exp,
    Sqrt,
    Abs,
    Int,
}

fn is_ws(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

/// A position in one line of text.
struct Cursor<'a> {
    text: &'a str,
    b: &'a [u8],
    i: usize,
}

impl<'a> Cursor<'a> {
    fn new(text: &'a str) -> Self {
        Cursor {
            text,
            b: text.as_bytes(),
            i: 0,
        }
    }

    #[inline]
    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    #[inline]
    fn peek_at(&self, k: usize) -> Option<u8> {
        self.b.get(self.i + k).copied()
    }

    #[inline]
    fn skip_ws(&mut self) {
        while self.peek().is_some_and(is_ws) {
            self.i += 1;
        }
    }

    #[inline]
    fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    /// End of the run of ASCII letters starting at `from`.
    fn letters_end(&self, from: usize) -> usize {
        let mut j = from;
        while self.b.get(j).is_some_and(u8::is_ascii_alphabetic) {
            j += 1;
        }
        j
    }

    /// Unsigned integer (digits only); `None` when there is no digit. Values
    /// saturate, so a long digit string cannot overflow.
    fn uint(&mut self) -> Option<u64> {
        let start = self.i;
        let mut n: u64 = 0;
        while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
            n = n.saturating_mul(10).saturating_add(u64::from(c - b'0'));
            self.i += 1;
        }
        (self.i > start).then_some(n)
    }

    /// Unsigned decimal constant (`12`, `1.5`, `.5`, `5.`); `None` when no
    /// digit. PMAC has no exponent notation, so none is read.
    fn number(&mut self) -> Option<f64> {
        let start = self.i;
        let mut mant: u64 = 0;
        let mut digits = 0u32;
        let mut frac = 0u32;
        while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
            mant = mant.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
            digits += 1;
            self.i += 1;
        }
        if self.peek() == Some(b'.') {
            self.i += 1;
            while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
                mant = mant.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
                digits += 1;
                frac += 1;
                self.i += 1;
            }
        }
        if digits == 0 {
            self.i = start;
            return None;
        }
        // Exact and correctly rounded: both operands are exact doubles.
        const POW10: [f64; 16] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
        ];
        if digits <= 15
            && let Some(p) = POW10.get(frac as usize)
        {
            return Some(mant as f64 / p);
        }
        // Long constants: let the standard library round them.
        self.text.get(start..self.i).and_then(|s| s.parse::<f64>().ok())
    }

    /// `$` hexadecimal integer constant, after the `$`.
    fn hex(&mut self) -> Option<f64> {
        let start = self.i;
        let mut n: u64 = 0;
        while let Some(d) = self.peek().and_then(|c| (c as char).to_digit(16)) {
            if self.i - start >= 16 {
                return None;
            }
            n = (n << 4) | u64::from(d);
            self.i += 1;
        }
        (self.i > start).then_some(n as f64)
    }

    /// A short excerpt at `at` for error messages.
    fn snippet(&self, at: usize) -> String {
        let rest = self.text.get(at..).unwrap_or("");
        rest.chars()
            .take_while(|c| !c.is_whitespace() && *c != ';')
            .take(16)
            .collect()
    }
}

/// The first letter run at or after `from` that begins with one of `words`
/// (upper case), outside `;` comments and `"` strings: its start and which
/// word it is.
fn find_word(b: &[u8], from: usize, words: &[&str]) -> Option<(usize, usize)> {
    let mut i = from;
    let mut quoted = false;
    while let Some(&c) = b.get(i) {
        if quoted {
            quoted = c != b'"';
            i += 1;
            continue;
        }
        match c {
            b';' => return None,
            b'"' => {
                quoted = true;
                i += 1;
            }
            c if c.is_ascii_alphabetic() => {
                let start = i;
                while b.get(i).is_some_and(u8::is_ascii_alphabetic) {
                    i += 1;
                }
                let run = b.get(start..i).unwrap_or(&[]);
                if let Some(k) = words
                    .iter()
                    .position(|w| run.get(..w.len()).is_some_and(|p| p.eq_ignore_ascii_case(w.as_bytes())))
                {
                    return Some((start, k));
                }
            }
            _ => i += 1,
        }
    }
    None
}

/// Words looked for between buffers: OPEN starts the next buffer; a move
/// mode word there means program text outside its buffer (a CLOSE too
/// early), and a second CLOSE is unbalanced. Other on-line text (`&1B1R`,
/// `#1->1000X`, `I5=2`) is sent at download time and ignored.
const OUTSIDE_WORDS: &[&str] = &["OPEN", "CLOSE", "LINEAR", "RAPID", "CIRCLE"];

/// PMAC bit-by-bit operators work on the integer and fractional bits of
/// their operands; 32 fractional bits in an `i128` reproduce that for any
/// value a program can sensibly hold.
fn bitwise(a: f64, b: f64, op: u8) -> f64 {
    const SCALE: f64 = 4_294_967_296.0;
    if !(a.abs() < 1e18 && b.abs() < 1e18) {
        return f64::NAN;
    }
    let x = (a * SCALE).floor() as i128;
    let y = (b * SCALE).floor() as i128;
    let r = match op {
        b'&' => x & y,
        b'|' => x | y,
        _ => x ^ y,
    };
    r as f64 / SCALE
}

/// The Turbo PMAC motion-program interpreter.
pub struct PmacInterpreter {
    shutter: Option<Var>,
    counter: Option<Var>,
    /// A bad option, reported on the first line (construction cannot fail).
    config_error: Option<String>,
    /// P, Q, M and I variables, 0..=8191 each, as assigned so far.
    vars: Vec<f64>,
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
            vars: vec![0.0; 4 * VAR_SLOTS],
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

    fn var(&self, v: Var) -> f64 {
        self.vars.get(v.slot()).copied().unwrap_or(0.0)
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

    fn command(&mut self, c: u8, cur: &mut Cursor, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
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
                cur.i = cur.b.len();
                Ok(())
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

    fn letter_word(
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
                let v = self.data(cur, letter_name(letter), lineno)?;
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
                let v = self.data(cur, letter_name(letter), lineno)?;
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
                let v = self.data(cur, letter_name(letter), lineno)?;
                if self.pending.radius.replace(v).is_some() {
                    return Err(GcodeError::at(lineno, "R given twice in one move"));
                }
                self.pending.active = true;
                Ok(())
            }
            b'F' => {
                let v = self.data(cur, letter_name(letter), lineno)?;
                if v <= 0.0 {
                    return Err(GcodeError::at(lineno, format!("feed rate F{v} must be positive")));
                }
                self.feed = Some(v);
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
                self.data(cur, letter_name(letter), lineno)?;
                Ok(())
            }
            b'G' | b'T' | b'D' => {
                // Calls of PROG 1000/1002/1003, absent here: no effect.
                self.flush(lineno, out)?;
                self.data(cur, letter_name(letter), lineno)?;
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
            b'A' | b'B' | b'C' | b'U' | b'V' | b'W' => Err(GcodeError::at(
                lineno,
                format!(
                    "axis {} is not supported (the toolpath has X, Y and Z only){}",
                    letter as char,
                    if letter == b'B' && self.buffer == Buffer::Bare {
                        "; an on-line B{n} (point to a program) belongs after CLOSE"
                    } else {
                        ""
                    }
                ),
            )),
            _ => Err(GcodeError::at(lineno, format!("unknown word '{}'", cur.snippet(start)))),
        }
    }

    fn keyword(
        &mut self,
        name: &'static str,
        kw: Kw,
        cur: &mut Cursor,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        match kw {
            Kw::Ta | Kw::Ts => {
                let v = self.data(cur, name, lineno)?;
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
                return Err(GcodeError::at(
                    lineno,
                    "TM (move time) is not supported: give the speed with F",
                ));
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
                let v = self.data(cur, name, lineno)?;
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
            Kw::Close => {
                // CLOSE before any OPEN and before any program text is the
                // safe download preamble: the file may still be a bare
                // program, so stay in it. Any other CLOSE with no buffer
                // open is unbalanced.
                match self.buffer {
                    Buffer::Bare if self.buffer_has_records => {
                        return Err(GcodeError::at(
                            lineno,
                            "CLOSE without OPEN: the program text above it is in no buffer (OPEN PROG n first)",
                        ));
                    }
                    Buffer::Bare => {}
                    Buffer::Outside => {
                        return Err(GcodeError::at(
                            lineno,
                            format!(
                                "CLOSE without OPEN: the buffer opened at line {} is closed already",
                                self.opened_at
                            ),
                        ));
                    }
                    Buffer::Open | Buffer::Skip => self.buffer = Buffer::Outside,
                }
            }
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
            Kw::Ta | Kw::Ts | Kw::Tm | Kw::Flow | Kw::Unsupported => {}
        }
        Ok(())
    }

    fn open(&mut self, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        if matches!(self.buffer, Buffer::Open | Buffer::Skip) {
            return Err(GcodeError::at(
                lineno,
                format!(
                    "OPEN while the buffer opened at line {} is still open (CLOSE missing)",
                    self.opened_at
                ),
            ));
        }
        cur.skip_ws();
        let start = cur.i;
        let end = cur.letters_end(start);
        let w = cur.b.get(start..end).unwrap_or(&[]);
        cur.i = end;
        let is = |s: &str| w.eq_ignore_ascii_case(s.as_bytes());
        self.buffer = if is("PROG") || is("PROGRAM") {
            cur.skip_ws();
            if cur.uint().is_none() {
                return Err(GcodeError::at(lineno, "OPEN PROG needs a program number"));
            }
            Buffer::Open
        } else if is("ROT") || is("ROTARY") {
            Buffer::Open
        } else if ["PLC", "PLCC", "FORWARD", "FWD", "INVERSE", "INV", "BIN", "BINARY"]
            .iter()
            .any(|s| is(s))
        {
            Buffer::Skip
        } else {
            return Err(GcodeError::at(
                lineno,
                format!("OPEN {}: expected OPEN PROG n or OPEN ROT", cur.snippet(start)),
            ));
        };
        self.opened_at = lineno;
        self.buffer_has_records = false;
        Ok(())
    }

    /// `ABS`/`INC` with an optional axis list; `R` in the list is the centre
    /// vector mode, which a bare ABS/INC leaves alone (as PMAC does).
    fn abs_inc(&mut self, abs: bool, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        let word = if abs { "ABS" } else { "INC" };
        cur.skip_ws();
        if !cur.eat(b'(') {
            self.abs_axes = [abs; 3];
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
                    return Err(GcodeError::at(
                        lineno,
                        format!("{word}({}): axis not supported (X, Y, Z and R only)", c as char),
                    ));
                }
                _ => {
                    return Err(GcodeError::at(
                        lineno,
                        format!("{word}(...): expected X, Y, Z or R, found '{}'", c as char),
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
    fn normal(&mut self, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
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
            v[usize::from(c - b'I')] = self.data(cur, letter_name(c), lineno)?;
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
    fn assign_target(&self, kind: VarKind, cur: &mut Cursor, lineno: u64) -> Result<Option<Var>, GcodeError> {
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
    fn assign(
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
        let value = self.expr(cur, 0, lineno)?;
        if !value.is_finite() {
            return Err(GcodeError::at(
                lineno,
                format!("{} is assigned a value that is not a finite number", var.name()),
            ));
        }
        if let Some(slot) = self.vars.get_mut(var.slot()) {
            *slot = value;
        }
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

    /// `{data}` after a word: a constant or a parenthesised expression, with
    /// an optional sign.
    fn data(&self, cur: &mut Cursor, word: &str, lineno: u64) -> Result<f64, GcodeError> {
        cur.skip_ws();
        let neg = if cur.eat(b'-') {
            true
        } else {
            cur.eat(b'+');
            false
        };
        let v = match cur.peek() {
            Some(b'(') => {
                cur.i += 1;
                let v = self.expr(cur, 1, lineno)?;
                cur.skip_ws();
                if !cur.eat(b')') {
                    return Err(GcodeError::at(lineno, "expression without closing ')'"));
                }
                v
            }
            Some(b'$') => {
                cur.i += 1;
                cur.hex()
                    .ok_or_else(|| GcodeError::at(lineno, "bad hexadecimal constant after '$'"))?
            }
            _ => cur.number().ok_or_else(|| {
                GcodeError::at(
                    lineno,
                    format!("{word} needs a value (a number or a parenthesised expression)"),
                )
            })?,
        };
        let v = if neg { -v } else { v };
        if !v.is_finite() {
            return Err(GcodeError::at(
                lineno,
                format!("value of {word} is not a finite number"),
            ));
        }
        Ok(v)
    }

    /// expr := term (('+' | '-' | '|' | '^') term)*
    fn expr(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        let mut v = self.term(cur, depth, lineno)?;
        loop {
            cur.skip_ws();
            let Some(op @ (b'+' | b'-' | b'|' | b'^')) = cur.peek() else {
                return Ok(v);
            };
            cur.i += 1;
            let r = self.term(cur, depth, lineno)?;
            v = match op {
                b'+' => v + r,
                b'-' => v - r,
                _ => bitwise(v, r, op),
            };
        }
    }

    /// term := unary (('*' | '/' | '%' | '&') unary)*
    fn term(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        let mut v = self.unary(cur, depth, lineno)?;
        loop {
            cur.skip_ws();
            let Some(op @ (b'*' | b'/' | b'%' | b'&')) = cur.peek() else {
                return Ok(v);
            };
            cur.i += 1;
            let r = self.unary(cur, depth, lineno)?;
            v = match op {
                b'*' => v * r,
                b'/' => v / r,
                // Remainder with the divisor's sign for positive divisors
                // (unconfirmed for negative ones on a controller).
                b'%' => {
                    if r > 0.0 {
                        v.rem_euclid(r)
                    } else {
                        v % r
                    }
                }
                _ => bitwise(v, r, op),
            };
        }
    }

    fn unary(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        if depth > MAX_DEPTH {
            return Err(GcodeError::at(lineno, "expression nested too deeply"));
        }
        cur.skip_ws();
        if cur.eat(b'-') {
            return Ok(-self.unary(cur, depth + 1, lineno)?);
        }
        if cur.eat(b'+') {
            return self.unary(cur, depth + 1, lineno);
        }
        self.primary(cur, depth, lineno)
    }

    fn primary(&self, cur: &mut Cursor, depth: u32, lineno: u64) -> Result<f64, GcodeError> {
        let Some(c) = cur.peek() else {
            return Err(GcodeError::at(lineno, "expression ends where a value is expected"));
        };
        if c == b'(' {
            cur.i += 1;
            let v = self.expr(cur, depth + 1, lineno)?;
            cur.skip_ws();
            if !cur.eat(b')') {
                return Err(GcodeError::at(lineno, "expression without closing ')'"));
            }
            return Ok(v);
        }
        if c == b'$' {
            cur.i += 1;
            return cur
                .hex()
                .ok_or_else(|| GcodeError::at(lineno, "bad hexadecimal constant after '$'"));
        }
        if c.is_ascii_digit() || c == b'.' {
            return cur
                .number()
                .ok_or_else(|| GcodeError::at(lineno, format!("bad number '{}'", cur.snippet(cur.i))));
        }
        if !c.is_ascii_alphabetic() {
            return Err(GcodeError::at(
                lineno,
                format!("expected a value in the expression, found '{}'", cur.snippet(cur.i)),
            ));
        }
        let start = cur.i;
        let end = cur.letters_end(start);
        let run = cur.b.get(start..end).unwrap_or(&[]);
        cur.i = end;
        if let [letter] = run
            && let Some(kind) = VarKind::from_letter(*letter)
        {
            cur.skip_ws();
            let index = if cur.peek() == Some(b'(') {
                cur.i += 1;
                let v = self.expr(cur, depth + 1, lineno)?;
                cur.skip_ws();
                if !cur.eat(b')') {
                    return Err(GcodeError::at(lineno, "expression without closing ')'"));
                }
                if !(v >= 0.0 && v < f64::from(VAR_MAX + 1)) {
                    return Err(GcodeError::at(
                        lineno,
                        format!("variable {}({v}) is out of range", kind.letter()),
                    ));
                }
                v as u64
            } else {
                cur.uint()
                    .ok_or_else(|| GcodeError::at(lineno, format!("variable {} needs a number", kind.letter())))?
            };
            if index > u64::from(VAR_MAX) {
                return Err(GcodeError::at(
                    lineno,
                    format!("variable {}{index} is out of range (0 to {VAR_MAX})", kind.letter()),
                ));
            }
            return Ok(self.var(Var {
                kind,
                index: index as u32,
            }));
        }
        let is = |s: &str| run.eq_ignore_ascii_case(s.as_bytes());
        let func = if is("SIN") {
            Func::Sin
        } else if is("COS") {
            Func::Cos
        } else if is("TAN") {
            Func::Tan
        } else if is("ASIN") {
            Func::Asin
        } else if is("ACOS") {
            Func::Acos
        } else if is("ATAN") {
            if cur.eat(b'2') { Func::Atan2 } else { Func::Atan }
        } else if is("LN") {
            Func::Ln
        } else if is("EXP") {
            Func::Exp
        } else if is("SQRT") {
            Func::Sqrt
        } else if is("ABS") {
            Func::Abs
        } else if is("INT") {
            Func::Int
        } else {
            return Err(GcodeError::at(
                lineno,
                format!("unknown function or variable '{}' in expression", cur.snippet(start)),
            ));
        };
        cur.skip_ws();
        if !cur.eat(b'(') {
            return Err(GcodeError::at(
                lineno,
                format!("function '{}' needs its argument in parentheses", cur.snippet(start)),
            ));
        }
        let a = self.expr(cur, depth + 1, lineno)?;
        cur.skip_ws();
        if !cur.eat(b')') {
            return Err(GcodeError::at(lineno, "expression without closing ')'"));
        }
        // Angles in degrees, as on a controller with I15 = 0 (the default).
        Ok(match func {
            Func::Sin => a.to_radians().sin(),
            Func::Cos => a.to_radians().cos(),
            Func::Tan => a.to_radians().tan(),
            Func::Asin => a.asin().to_degrees(),
            Func::Acos => a.acos().to_degrees(),
            Func::Atan => a.atan().to_degrees(),
            // PMAC's ATAN2 takes the cosine argument from Q0.
            Func::Atan2 => a
                .atan2(self.var(Var {
                    kind: VarKind::Q,
                    index: 0,
                }))
                .to_degrees(),
            Func::Ln => a.ln(),
            Func::Exp => a.exp(),
            Func::Sqrt => a.sqrt(),
            Func::Abs => a.abs(),
            // Truncation towards minus infinity, per the Turbo PMAC manual.
            Func::Int => a.floor(),
        })
    }

    /// Turn the collected move words into a motion record.
    fn emit_move(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
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
        let feed = if self.mode == MoveMode::Rapid {
            None
        } else {
            Some(self.feed.ok_or_else(|| {
                GcodeError::at(
                    lineno,
                    format!("no feed rate: set F before the first {} move", self.mode.name()),
                )
            })?)
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
        let mut motion = Motion::from_block(kind, to, feed, self.beam, lineno);
        if self.beam != self.moved_beam {
            motion.beam_switch = Some(self.last_switch);
        }
        self.moved_beam = self.beam;
        self.push(out, Record::Move(motion));
        self.pos = to;
        Ok(())
    }

    fn arc(&self, pm: &PendingMove, to: &P3, ccw: bool, lineno: u64) -> Result<ArcData, GcodeError> {
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

/// The name of a one-letter word, for messages.
fn letter_name(letter: u8) -> &'static str {
    const NAMES: [&str; 26] = [
        "A", "B", "C", "D", "E", "F", "G", "H", "I", "J", "K", "L", "M", "N", "O", "P", "Q", "R", "S", "T", "U", "V",
        "W", "X", "Y", "Z",
    ];
    NAMES
        .get(usize::from(letter.to_ascii_uppercase().wrapping_sub(b'A')))
        .copied()
        .unwrap_or("?")
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
mod tests {
    use super::*;
    use crate::gcode::{Dialect, ProgramReader, read_str};

    fn pmac_opts() -> ReadOptions {
        ReadOptions {
            dialect: Some(Dialect::Pmac),
            ..ReadOptions::default()
        }
    }

    fn read(text: &str) -> Vec<Record> {
        match read_str(text, &pmac_opts()) {
            Ok((_, recs)) => recs,
            Err(e) => panic!("unexpected error: {e}"),
        }
    }

    fn read_err(text: &str) -> (u64, String) {
        match read_str(text, &pmac_opts()) {
            Ok((_, recs)) => panic!("expected an error, got {recs:?}"),
            Err(e) => (e.line(), e.to_string()),
        }
    }

    fn moves(recs: &[Record]) -> Vec<&Motion> {
        recs.iter().filter_map(Record::motion).collect()
    }

    fn p(x: f64, y: f64, z: f64) -> P3 {
        P3::new(x, y, z)
    }

    fn assert_pt(a: &P3, b: &P3) {
        assert!((a - b).norm() < 1e-9, "{a:?} != {b:?}");
    }

    fn arc(m: &Motion) -> ArcData {
        match m.kind {
            MotionKind::Arc(a) => a,
            ref k => panic!("not an arc: {k:?}"),
        }
    }

    #[test]
    fn bare_program_in_the_style_of_the_seed() {
        let text = include_str!("../../testdata/pmac/bare_shutter_contour.pmac");
        let (dialect, recs) = read_str(text, &ReadOptions::default()).unwrap();
        assert_eq!(dialect, Dialect::Pmac);
        // Only moves: M33 is the beam, P400 bookkeeping, M30 a no-op call.
        assert_eq!(recs.len(), 8);
        let m = moves(&recs);
        assert_eq!(m.len(), 8);
        assert_eq!(m[0].kind, MotionKind::Line);
        assert_pt(&m[0].to, &p(2.5, 4.0, 0.0));
        assert_eq!(m[0].feed, Some(2.0));
        assert_eq!(m[0].block, Some(2));
        assert_pt(&m[1].to, &p(2.5, 4.8, 0.0));
        let a = arc(m[2]);
        assert!(!a.ccw);
        assert_eq!(a.plane, Plane::Xy);
        assert_pt(&a.center, &p(2.55, 4.8, 0.0));
        assert_pt(&m[2].to, &p(2.55, 4.75, 0.0));
        assert_pt(&m[3].to, &p(2.5, 4.75, 0.0));
        // CIRCLE2 I0 J-0.75 with no end point: a full counter-clockwise circle.
        let full = arc(m[4]);
        assert!(full.ccw);
        assert_pt(&full.center, &p(2.5, 4.0, 0.0));
        assert_pt(&m[4].to, &m[3].to);
        assert_eq!(m[4].block, Some(10));
        assert_pt(&m[5].to, &p(2.45, 4.75, 0.0));
        assert_pt(&arc(m[6]).center, &p(2.45, 4.8, 0.0));
        assert_pt(&m[7].to, &p(2.5, 4.0, 0.0));
        let beams: Vec<bool> = m.iter().map(|m| m.beam).collect();
        assert_eq!(beams, [false, false, false, false, false, true, false, false]);
        assert!(
            m.iter()
                .all(|m| m.feed == Some(2.0) && m.role.is_none() && m.chain.is_none())
        );
    }

    #[test]
    fn download_file_with_buffer_commands() {
        let text = include_str!("../../testdata/pmac/slot_and_hole.pmac");
        let (dialect, recs) = read_str(text, &ReadOptions::default()).unwrap();
        assert_eq!(dialect, Dialect::Pmac);
        assert_eq!(recs.len(), 10, "{recs:#?}");
        assert_eq!(
            recs[0],
            Record::Accel {
                ta_ms: Some(20.0),
                ts_ms: Some(10.0),
                block: Some(7)
            }
        );
        let m = moves(&recs);
        assert_eq!(m[0].kind, MotionKind::Rapid);
        assert_eq!(m[0].feed, None);
        assert_pt(&m[0].to, &p(0.0, 0.0, 0.5));
        assert_eq!((m[1].beam, m[1].feed, m[1].block), (false, Some(2.0), Some(9)));
        assert_eq!((m[2].beam, m[2].block), (true, Some(11)));
        assert_pt(&m[2].to, &p(2.0, 0.0, 0.0));
        let slot_end = arc(m[3]);
        assert!(slot_end.ccw);
        assert_pt(&slot_end.center, &p(2.0, 0.5, 0.0));
        assert_pt(&m[4].to, &p(0.0, 1.0, 0.0));
        assert!(m[4].beam);
        assert_eq!((m[5].kind, m[5].beam, m[5].feed), (MotionKind::Rapid, false, None));
        let hole = arc(m[6]);
        assert!(!hole.ccw);
        assert_pt(&hole.center, &p(1.0, -0.75, 0.0));
        assert_pt(&m[6].to, &p(1.0, -1.0, 0.0));
        assert_eq!((m[6].feed, m[6].beam, m[6].block), (Some(1.5), true, Some(19)));
        assert_eq!(
            recs[8],
            Record::Dwell {
                seconds: 0.05,
                block: Some(21)
            }
        );
        assert_eq!(
            recs[9],
            Record::Var {
                name: "P401".into(),
                value: 12.0,
                sync: false,
                block: Some(22)
            }
        );
    }

    #[test]
    fn planes_helix_and_radius_arcs() {
        let text = include_str!("../../testdata/pmac/planes_helix_radius.pmac");
        let m_recs = read(text);
        let m = moves(&m_recs);
        assert_eq!(m.len(), 6);
        let helix = arc(m[1]);
        assert!(helix.ccw);
        assert_eq!(helix.plane, Plane::Xy);
        assert_pt(&helix.center, &p(0.0, 0.0, 0.0));
        assert_pt(&m[1].to, &p(0.0, 1.0, -0.2));
        let zx = arc(m[2]);
        assert_eq!(zx.plane, Plane::Xz);
        assert!(!zx.ccw);
        assert_pt(&zx.center, &p(0.0, 1.0, -1.2));
        assert_pt(&m[2].to, &p(1.0, 1.0, -1.2));
        let yz = arc(m[3]);
        assert_eq!(yz.plane, Plane::Yz);
        assert!(yz.ccw);
        assert_pt(&yz.center, &p(1.0, 2.0, -1.2));
        let short = arc(m[4]);
        assert_eq!(short.plane, Plane::Xy);
        assert!(short.ccw, "NORMAL K1 flips CIRCLE1");
        assert_pt(&short.center, &p(1.0, 3.0, -0.2));
        let long = arc(m[5]);
        assert!(long.ccw);
        assert_pt(&long.center, &p(2.0, 2.0, -0.2));
        assert_pt(&m[5].to, &p(3.0, 2.0, -0.2));
    }

    #[test]
    fn arc_off_its_circle_is_an_error_on_its_line() {
        let text = include_str!("../../testdata/pmac/arc_off_circle.pmac");
        let (line, msg) = read_err(text);
        assert_eq!(line, 3);
        assert!(msg.contains("not on the circle"), "{msg}");
    }

    #[test]
    fn move_modes_are_modal_and_map_to_the_model() {
        let recs = read("RAPID X1 Y1\nX2\nLINEAR X3 F4\nY5\nCIRCLE1 X4 Y6 I1\nX5 Y5 I1 J0\nCIRCLE2 X7 Y5 R1\n");
        let m = moves(&recs);
        assert_eq!(m.len(), 7);
        assert_eq!((m[0].kind, m[0].feed), (MotionKind::Rapid, None));
        assert_eq!((m[1].kind, m[1].feed), (MotionKind::Rapid, None));
        assert_pt(&m[1].to, &p(2.0, 1.0, 0.0));
        assert_eq!((m[2].kind, m[2].feed), (MotionKind::Line, Some(4.0)));
        assert_eq!(m[3].kind, MotionKind::Line);
        assert_pt(&m[3].to, &p(3.0, 5.0, 0.0));
        // CIRCLE1 under the default NORMAL K-1 is G2 in G17.
        let a = arc(m[4]);
        assert!(!a.ccw);
        assert_eq!(a.plane, Plane::Xy);
        assert_pt(&a.center, &p(4.0, 5.0, 0.0));
        assert_eq!(m[4].feed, Some(4.0));
        let b = arc(m[5]);
        assert!(!b.ccw, "CIRCLE1 stays modal");
        assert_pt(&b.center, &p(5.0, 6.0, 0.0));
        let c = arc(m[6]);
        assert!(c.ccw);
        assert_pt(&c.center, &p(6.0, 5.0, 0.0));
    }

    #[test]
    fn compact_and_lower_case_text() {
        let recs = read("linearx1y2f3\nCIR2X0Y3I-1J0 m33=1\nRPDZ1\nLIN X 4 Y 4 Z 0");
        let m = moves(&recs);
        assert_eq!(m.len(), 4);
        assert_pt(&m[0].to, &p(1.0, 2.0, 0.0));
        assert_eq!(m[0].feed, Some(3.0));
        assert!(arc(m[1]).ccw);
        assert_pt(&arc(m[1]).center, &p(0.0, 2.0, 0.0));
        assert_eq!((m[2].kind, m[2].beam), (MotionKind::Rapid, true));
        assert_pt(&m[3].to, &p(4.0, 4.0, 0.0));
    }

    #[test]
    fn abs_inc_and_axis_lists() {
        let recs = read("LINEAR F1\nX1 Y1 Z1\nINC\nX1 Y-2\nABS(X)\nX0 Y1 Z-1\nABS\nINC(Y,Z)\nX5 Y1\n");
        let m = moves(&recs);
        assert_pt(&m[0].to, &p(1.0, 1.0, 1.0));
        assert_pt(&m[1].to, &p(2.0, -1.0, 1.0));
        assert_pt(&m[2].to, &p(0.0, 0.0, 0.0));
        assert_pt(&m[3].to, &p(5.0, 1.0, 0.0));
    }

    #[test]
    fn centre_vector_incremental_and_absolute() {
        // Default INC(R): centre relative to the start point.
        let recs = read("LINEAR F1 X10 Y10\nCIRCLE2 X12 Y12 I2 J0\nABS(R)\nX10 Y10 I12 J10\nINC(R)\nX12 Y12 J2");
        let m = moves(&recs);
        assert_pt(&arc(m[1]).center, &p(12.0, 10.0, 0.0));
        assert_pt(&arc(m[2]).center, &p(12.0, 10.0, 0.0));
        assert_pt(&arc(m[3]).center, &p(10.0, 12.0, 0.0));
        assert!(arc(m[3]).ccw);
    }

    #[test]
    fn radius_arcs_short_and_long_in_both_senses() {
        // From (1,0) to (0,1) with radius 1.
        let cases = [
            ("CIRCLE2 X0 Y1 R1", true, (0.0, 0.0)),
            ("CIRCLE2 X0 Y1 R-1", true, (1.0, 1.0)),
            ("CIRCLE1 X0 Y1 R1", false, (1.0, 1.0)),
            ("CIRCLE1 X0 Y1 R-1", false, (0.0, 0.0)),
        ];
        for (line, ccw, (cx, cy)) in cases {
            let recs = read(&format!("LINEAR X1 Y0 F1\n{line}"));
            let a = arc(moves(&recs)[1]);
            assert_eq!(a.ccw, ccw, "{line}");
            assert_pt(&a.center, &p(cx, cy, 0.0));
        }
        // Rounded half circle: the chord exceeds the diameter by 0.00005.
        let recs = read("LINEAR F1\nCIRCLE2 X1.00005 Y0 R0.5");
        let half = arc(moves(&recs)[0]);
        assert_pt(&half.center, &p(0.500025, 0.0, 0.0));
        let (line, msg) = read_err("LINEAR F1\nCIRCLE1 X1 Y0 R0.4");
        assert_eq!(line, 2);
        assert!(msg.contains("cannot reach"), "{msg}");
        let (line, msg) = read_err("LINEAR F1 X1\nCIRCLE1 X1 Y0 R0.5");
        assert_eq!(line, 2);
        assert!(msg.contains("full circle"), "{msg}");
    }

    #[test]
    fn full_circles_and_helices() {
        let recs = read("LINEAR X1 F2\nCIRCLE1 I-1\nCIRCLE2 X1 Y0 Z-0.5 I-1 J0\nINC\nCIRCLE2 Z-0.5 I-1");
        let m = moves(&recs);
        assert_pt(&m[1].to, &p(1.0, 0.0, 0.0));
        assert_pt(&arc(m[1]).center, &p(0.0, 0.0, 0.0));
        assert!(!arc(m[1]).ccw);
        // Full-turn helix: the end equals the start in the plane only.
        assert_pt(&m[2].to, &p(1.0, 0.0, -0.5));
        assert_pt(&arc(m[2]).center, &p(0.0, 0.0, 0.0));
        assert_pt(&m[3].to, &p(1.0, 0.0, -1.0));
        assert_pt(&arc(m[3]).center, &p(0.0, 0.0, -0.5));
    }

    #[test]
    fn normal_vectors_choose_plane_and_sense() {
        let cases = [
            ("NORMAL K-1", Plane::Xy, false),
            ("NORMAL K1", Plane::Xy, true),
            ("NORMAL J-1", Plane::Xz, false),
            ("NORMAL J1", Plane::Xz, true),
            ("NORMAL I-1", Plane::Yz, false),
            ("NRM I0 J0 K-2", Plane::Xy, false),
            ("NORMAL I1", Plane::Yz, true),
        ];
        for (normal, plane, ccw) in cases {
            let recs = read(&format!("{normal}\nCIRCLE1 F1 I1 J1 K1"));
            let a = arc(moves(&recs)[0]);
            assert_eq!((a.plane, a.ccw), (plane, ccw), "{normal}");
        }
        let (line, msg) = read_err("LINEAR F1\nNORMAL I0.7 J0.7");
        assert_eq!(line, 2);
        assert!(msg.contains("NORMAL"), "{msg}");
        assert_eq!(read_err("NORMAL").0, 1);
    }

    #[test]
    fn shutter_states_with_immediate_and_synchronous_assignment() {
        let recs = read("LINEAR F1\nX1\nM33=1\nX2\nX3 M33==0\nM33 == 1\nX4 M33=0\nX5\nM33=(P1+2)\nX6\nM33=0 X7");
        let beams: Vec<bool> = moves(&recs).iter().map(|m| m.beam).collect();
        // `X3` comes before `M33==0` on its line: still open for it; `X7`
        // comes after `M33=0`: closed.
        assert_eq!(beams, [false, true, true, true, false, true, false]);
        assert_eq!(recs.len(), 7, "shutter assignments make no records");
        // Each move whose beam differs from the one before carries how the
        // switch was written.
        use ShutterSwitch::{Immediate, Sync};
        let switches: Vec<Option<ShutterSwitch>> = moves(&recs).iter().map(|m| m.beam_switch).collect();
        assert_eq!(
            switches,
            [
                None,
                Some(Immediate),
                None,
                None,
                Some(Immediate),
                Some(Immediate),
                Some(Immediate)
            ]
        );
        let recs = read("LINEAR F1\nM33==1 X1\nX2\nM33==0 X3\n");
        let switches: Vec<Option<ShutterSwitch>> = moves(&recs).iter().map(|m| m.beam_switch).collect();
        assert_eq!(switches, [Some(Sync), None, Some(Sync)]);
        // A configured shutter variable.
        let opts = ReadOptions {
            shutter_var: "m7".into(),
            ..pmac_opts()
        };
        let (_, recs) = read_str("LINEAR F1\nM7=1 X1\nM33=1", &opts).unwrap();
        assert!(recs[0].motion().unwrap().beam);
        assert_eq!(
            recs[1],
            Record::Var {
                name: "M33".into(),
                value: 1.0,
                sync: false,
                block: Some(3)
            }
        );
    }

    #[test]
    fn variables_are_recorded_except_shutter_and_counter() {
        let recs = read("P400=1 P12=3.5 Q3=-2\nM40==1 I5193=$2000\nm41=0 p400=P400+1");
        let vars: Vec<(String, f64, bool, Option<u64>)> = recs
            .iter()
            .map(|r| match r {
                Record::Var {
                    name,
                    value,
                    sync,
                    block,
                } => (name.clone(), *value, *sync, *block),
                other => panic!("not a var: {other:?}"),
            })
            .collect();
        assert_eq!(
            vars,
            [
                ("P12".to_string(), 3.5, false, Some(1)),
                ("Q3".to_string(), -2.0, false, Some(1)),
                ("M40".to_string(), 1.0, true, Some(2)),
                ("I5193".to_string(), 8192.0, false, Some(2)),
                ("M41".to_string(), 0.0, false, Some(3)),
            ]
        );
        let (line, msg) = read_err("P1==2");
        assert_eq!(line, 1);
        assert!(msg.contains("M-variables only"), "{msg}");
        assert!(read_err("P9000=1").1.contains("out of range"));
        assert!(read_err("P12").1.contains("not an assignment"));
        assert!(read_err("P(P1+1) = 2").1.contains("indirect"));
    }

    fn value_of(expr: &str) -> f64 {
        let recs = read(&format!("P1=2 Q0=-1 M5=3\nP2={expr}"));
        match recs.last() {
            Some(Record::Var { name, value, .. }) if name == "P2" => *value,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn expressions_follow_pmac_precedence_and_functions() {
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert_eq!(value_of("1+2*3"), 7.0);
        assert_eq!(value_of("(1+2)*3"), 9.0);
        assert_eq!(value_of("P1*M5-P99"), 6.0);
        assert_eq!(value_of("-P1--3"), 1.0);
        assert_eq!(value_of("10/4"), 2.5);
        assert_eq!(value_of("7%3"), 1.0);
        assert_eq!(value_of("-7%3"), 2.0);
        assert!(close(value_of("SIN(30)"), 0.5));
        assert!(close(value_of("COS(60)+TAN(45)"), 1.5));
        assert!(close(value_of("ASIN(1)"), 90.0));
        assert!(close(value_of("ACOS(0)+ATAN(1)"), 135.0));
        // ATAN2 takes its cosine argument from Q0 (-1 here).
        assert!(close(value_of("ATAN2(1)"), 135.0));
        assert_eq!(value_of("SQRT(16)+ABS(-2)"), 6.0);
        assert_eq!(value_of("INT(2.7)"), 2.0);
        assert_eq!(value_of("INT(-2.5)"), -3.0);
        assert!(close(value_of("LN(EXP(2))"), 2.0));
        assert_eq!(value_of("$FF"), 255.0);
        assert_eq!(value_of("$AA^$55"), 255.0);
        assert_eq!(value_of("3^-3"), -2.0);
        assert_eq!(value_of("0.5^0.875"), 0.375);
        assert_eq!(value_of("6&3|8"), 10.0);
        assert_eq!(value_of("P(P1-1)+1"), 3.0);
        assert_eq!(value_of(" ( P1 + 1 ) * 2 "), 6.0);
        // Unassigned variables read as zero.
        assert_eq!(value_of("Q77+M8000"), 0.0);
        // Axis values may be expressions too.
        let recs = read("P1=2\nLINEAR F(P1*3) X(P1+2) Y-(P1) Z(SIN(90))");
        let m = moves(&recs)[0];
        assert_pt(&m.to, &p(4.0, -2.0, 1.0));
        assert_eq!(m.feed, Some(6.0));
    }

    #[test]
    fn bad_expressions_are_errors() {
        assert!(read_err("P1=1/0").1.contains("not a finite number"));
        assert!(read_err("P1=SQRT(-1)").1.contains("not a finite number"));
        assert!(read_err("P1=(1+2").1.contains("closing"));
        assert!(read_err("P1=FOO(2)").1.contains("unknown function"));
        assert!(read_err("P1=SIN 30").1.contains("parentheses"));
        assert!(read_err("P1=").1.contains("value is expected"));
        let deep = format!("P1={}1{}", "(".repeat(500), ")".repeat(500));
        assert!(read_err(&deep).1.contains("too deeply"));
        let minus = format!("P1={}1", "-".repeat(500));
        assert!(read_err(&minus).1.contains("too deeply"));
        let huge = format!("LINEAR F1 X{}", "9".repeat(400));
        assert!(read_err(&huge).1.contains("not a finite number"));
    }

    #[test]
    fn accel_times_and_dwells() {
        let recs = read("TA10\nTS5 TA(2*10)\nLINEAR X1 F1 TA30\nDWELL100\nDELAY 2.5\nDWE(P1+1) DLY0");
        assert_eq!(
            recs[..4],
            [
                Record::Accel {
                    ta_ms: Some(10.0),
                    ts_ms: None,
                    block: Some(1)
                },
                Record::Accel {
                    ta_ms: Some(20.0),
                    ts_ms: Some(5.0),
                    block: Some(2)
                },
                // TA on a move's line applies to that move: it comes first.
                Record::Accel {
                    ta_ms: Some(30.0),
                    ts_ms: None,
                    block: Some(3)
                },
                recs[3].clone(),
            ]
        );
        assert_eq!(recs[3].motion().unwrap().block, Some(3));
        let dwells: Vec<(f64, Option<u64>)> = recs[4..]
            .iter()
            .map(|r| match r {
                Record::Dwell { seconds, block } => (*seconds, *block),
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(
            dwells,
            [(0.1, Some(4)), (0.0025, Some(5)), (0.001, Some(6)), (0.0, Some(6))]
        );
        assert!(read_err("DWELL -5").1.contains("negative"));
        assert!(read_err("TA-1").1.contains("negative"));
        assert!(read_err("TM100").1.contains("TM"));
    }

    #[test]
    fn calls_labels_and_delimiters_do_nothing() {
        let recs = read("%\nN10 G90 G54 T1 D0\nLINEAR X1 F2 M3\nM30\nO20 X2\nM(P1+5)\n%100\n");
        let m = moves(&recs);
        assert_eq!(recs.len(), 2);
        assert_pt(&m[1].to, &p(2.0, 0.0, 0.0));
        assert_eq!(m[1].block, Some(5));
    }

    #[test]
    fn error_cases_name_their_line() {
        let cases: [(&str, u64, &str); 15] = [
            ("LINEAR X1", 1, "no feed rate"),
            ("RAPID X1\nCIRCLE1 X2", 2, "no feed rate"),
            ("LINEAR F1\nX1\nFOO3", 3, "unknown word 'FOO3'"),
            ("LINEAR F1\nX1 A2", 2, "axis A"),
            ("F1\nCIRCLE1 X1 Y1", 2, "without a centre"),
            ("F1\nLINEAR X1 I1", 2, "CIRCLE1 or CIRCLE2"),
            ("F1\nCIRCLE1 X1 R1 I1", 2, "not both"),
            ("F1 X1 X2", 1, "twice"),
            ("P1=1\nWHILE(P1<2)", 2, "flow control"),
            ("GOTO 10", 1, "flow control"),
            ("LINEAR F1 (comment)", 1, "comments start with ';'"),
            ("CIRCLE3 X1", 1, "CIRCLE1 or CIRCLE2"),
            ("F0", 1, "positive"),
            ("X1 @", 1, "unexpected character '@'"),
            ("X1 5", 1, "without a word"),
        ];
        for (text, line, needle) in cases {
            let (l, msg) = read_err(text);
            assert_eq!(l, line, "{text}: {msg}");
            assert!(msg.contains(needle), "{text}: {msg}");
        }
    }

    #[test]
    fn buffer_structure() {
        // On-line commands outside buffers are ignored, several buffers read
        // in order, a PLC skipped, and RETURN ends a program.
        let text = "&1 #1J/ I5=2\nCLOSE DELETE GATHER DEFINE ROT 100 OPEN PROG 5 CLEAR LINEAR X1 F1\nCLOSE\n\
                    I6=1 X9 garbage\nOPEN PLC 1 CLEAR\nIF (M1=1) CMD\"CLOSE\" ENDIF\nCLOSE\nOPEN ROT\nX2\nRETURN\n\
                    N100 WHILE(1) ENDWHILE\nCLOSE &1B0R\n";
        let recs = read(text);
        let m = moves(&recs);
        assert_eq!(recs.len(), 2, "{recs:?}");
        assert_eq!(m[0].block, Some(2));
        assert_pt(&m[1].to, &p(2.0, 0.0, 0.0));
        assert_eq!(m[1].block, Some(9));
        // Unclosed buffers, nested OPEN, CLEAR after records, on-line text inside.
        let (line, msg) = read_err("OPEN PROG 1\nLINEAR X1 F1\n");
        assert_eq!(line, 2);
        assert!(msg.contains("opened at line 1"), "{msg}");
        assert_eq!(read_err("OPEN PROG 1\nOPEN PROG 2").0, 2);
        assert!(read_err("OPEN PROG 1\nLINEAR X1 F1\nCLEAR").1.contains("CLEAR"));
        assert!(read_err("OPEN PROG 1\n&1B1R").1.contains("on-line command"));
        assert!(read_err("OPEN PROG\nCLOSE").1.contains("program number"));
        assert!(read_err("OPEN GATHER").1.contains("OPEN PROG"));
        // The download preamble alone does not hide a bare program ...
        let recs = read("CLOSE\nDELETE GATHER\nLINEAR X1 F1\n");
        assert_eq!(moves(&recs)[0].block, Some(3));
        // ... but motion after a buffer's CLOSE is outside the program.
        let (line, msg) = read_err("OPEN PROG 1\nLINEAR X1 F1\nCLOSE\n&1B1R\nLINEAR X2\n");
        assert_eq!(line, 5);
        assert!(msg.contains("outside a program buffer"), "{msg}");
        // A bare program: &-lines ignored, RETURN ends reading.
        let recs = read("&1\nLINEAR X1 F1\nRETURN\nthis is never read");
        assert_eq!(recs.len(), 1);
    }

    #[test]
    fn dialect_detection_sees_typical_programs_as_pmac() {
        for text in [
            "OPEN PROG 1 CLEAR\nG54 G90\nLINEAR X1 F1\nCLOSE\n",
            "CLOSE\nDELETE GATHER\nOPEN PROG 1 CLEAR\nRAPID X0\nCLOSE\n",
            "; generated\nLINEAR X1.8 Y5.4 Z0 F2\nM33=0 P400=1\n",
            "M33=0\nF1 X1\n",
            "CIRCLE2 I0 J-0.9 F1\n",
        ] {
            let (d, recs) = read_str(text, &ReadOptions::default()).unwrap();
            assert_eq!(d, Dialect::Pmac, "{text}");
            assert!(!recs.is_empty(), "{text}");
        }
    }

    #[test]
    fn bad_options_are_reported() {
        let opts = ReadOptions {
            shutter_var: "shutter".into(),
            ..pmac_opts()
        };
        let e = read_str("X1", &opts).unwrap_err();
        assert!(e.to_string().contains("shutter variable 'shutter'"), "{e}");
        assert_eq!(
            Var::parse(" p400 "),
            Some(Var {
                kind: VarKind::P,
                index: 400
            })
        );
        assert_eq!(Var::parse("M8192"), None);
        assert_eq!(Var::parse("M"), None);
    }

    #[test]
    fn start_position_and_streaming_reader() {
        let mut text = String::from("OPEN PROG 1 CLEAR\nLINEAR F10 INC\n");
        for i in 0..5000 {
            text.push_str(&format!("X0.1 M33={} P400={i}\n", i % 2));
        }
        text.push_str("CLOSE\n");
        let opts = ReadOptions {
            start: p(1.0, 2.0, 3.0),
            ..ReadOptions::default()
        };
        let reader = ProgramReader::new(text.as_bytes(), &opts).unwrap();
        assert_eq!(reader.dialect(), Dialect::Pmac);
        let recs: Vec<Record> = reader.collect::<Result<_, _>>().unwrap();
        assert_eq!(recs.len(), 5000);
        let last = recs[4999].motion().unwrap();
        assert!((last.to.x - 501.0).abs() < 1e-6);
        assert_eq!((last.to.y, last.to.z), (2.0, 3.0));
        assert_eq!(last.block, Some(5002));
        // M33 is set after the move on each line: move i sees line i-1's value.
        assert!(!recs[0].motion().unwrap().beam);
        assert!(!recs[1].motion().unwrap().beam);
        assert!(recs[2].motion().unwrap().beam);
    }

    proptest::proptest! {
        /// Any text gives records or an error, never a panic or a hang.
        #[test]
        fn arbitrary_text_never_panics(lines in proptest::collection::vec(
            proptest::prop_oneof![
                "[A-Z0-9=().;+*/%&|^$ ,#@\"-]{0,60}",
                "(LINEAR|RAPID|CIRCLE[12]|X|Y|Z|I|J|K|R|F|TA|TS|M33=|M33==|P400=|P1=|ABS|INC|NORMAL|OPEN PROG 1|CLOSE|DWELL|\\(|\\)|-|[0-9.]{1,8}| ){0,24}",
                proptest::prelude::any::<String>(),
            ],
            0..12,
        )) {
            let text = lines.join("\n");
            let _ = read_str(&text, &pmac_opts());
            let _ = read_str(&text, &ReadOptions::default());
        }
    }

    /// Throughput check: `cargo test --release --lib pmac::tests::throughput
    /// -- --ignored --nocapture` prints lines per second (the target is
    /// millions in release builds).
    #[test]
    #[ignore]
    fn throughput() {
        let mut text = String::from("OPEN PROG 1 CLEAR\nLINEAR F2\n");
        for i in 0..200_000u32 {
            let x = f64::from((i / 4) % 1000) * 0.0013;
            match i % 4 {
                0 => text.push_str(&format!("LINEAR X{x:.4} Y5.455 Z0 F2\n")),
                1 => text.push_str(&format!("M33=1 P400={i}\n")),
                2 => text.push_str(&format!("CIRCLE1 X{:.4} Y5.455 I0.05 J0\n", x + 0.1)),
                _ => text.push_str(&format!("M33=0 P400={i}\n")),
            }
        }
        text.push_str("CLOSE\n");
        let lines = text.lines().count();
        let t = std::time::Instant::now();
        let reader = ProgramReader::new(text.as_bytes(), &ReadOptions::default()).unwrap();
        let n = reader.collect::<Result<Vec<_>, _>>().unwrap().len();
        let s = t.elapsed().as_secs_f64();
        assert_eq!(n, 100_000);
        println!("{lines} lines in {s:.3} s: {:.0} lines/s", lines as f64 / s);
    }

    #[test]
    fn numbers_parse_exactly() {
        let mut c = Cursor::new("1.8183 .5 5. 12345678901234567.25 0.1");
        let mut got = Vec::new();
        while c.peek().is_some() {
            c.skip_ws();
            got.push(c.number().unwrap());
        }
        assert_eq!(got, [1.8183, 0.5, 5.0, 12345678901234567.25, 0.1]);
        assert_eq!(Cursor::new("x").number(), None);
        assert_eq!(Cursor::new("FFFFFFFFFFFFFFFFF").hex(), None);
    }
}
