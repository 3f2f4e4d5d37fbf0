//! Toolpath model -> G-code text, ISO/RS274 or Turbo PMAC, one record at a
//! time.
//!
//! [`GcodeWriter`] is the only place toolpaths become controller text, so
//! the conventions every reader must undo live here:
//!
//! - **Numbers** are fixed point with [`WriteOptions::decimals`] places,
//!   trailing zeros trimmed (`X1.5`, `Z0`), never `-0`. Internally every
//!   coordinate is rounded once to an integer number of output units and
//!   the writer tracks *that* position, so incremental arc centres are exact
//!   differences of printed numbers: a reader adding `I` to the printed
//!   start recovers the rounded centre, not a doubly rounded one.
//! - **Modal words**: the motion word (`G1`/`LINEAR` ...), the plane, `F`
//!   and the axis words are written only when they change. The first move
//!   writes all three axes because the machine's position before the
//!   program is not known. An arc whose in-plane end equals its start (a full
//!   circle) still writes both in-plane axes, because LinuxCNC rejects G2/G3
//!   without axis words and a bare `I J` line is easy to misread. A feed move
//!   that would carry no axis word at all (zero length at the output
//!   precision) writes `X`, so it stays a move for the controller and for
//!   our readers.
//! - **Beam / shutter**: the beam state comes from each move's `beam`. PMAC
//!   assigns the shutter variable at the start of the move's line, by
//!   default synchronously (`M33==1 LINEAR X..`), so it switches when that
//!   move's motion starts rather than when look-ahead calculates the line.
//!   ISO writes [`WriteOptions::beam_on`] / [`WriteOptions::beam_off`]
//!   (`M3` / `M5`) in the move's block; RS274 runs spindle words before the
//!   block's motion. The default headers close the shutter; when the last
//!   move leaves it open, PMAC output gets a `DWELL 0` before the trailer so
//!   the trailer's immediate `M33=0` waits for the motion to end instead of
//!   firing during look-ahead.
//! - **Line counter** (PMAC): each motion line ends with `P400=n`, n = 1, 2,
//!   ... counting motion lines, so the host can see which block runs.
//! - **Arcs**: centre words are the in-plane components of the centre,
//!   incremental from the arc start (`G91.1` / `INC(R)`) unless
//!   [`WriteOptions::absolute_centers`]. Planes are `G17/G18/G19` in ISO and
//!   `NORMAL K-1 / J-1 / I-1` in PMAC, which give CIRCLE1 the same sense as
//!   G2 (clockwise seen from the positive normal). The normal axis in the end
//!   point makes a helix. Extra turns are the ISO `P` word (P = turns + 1);
//!   PMAC has no turn count, so it gets that many full circles (the helix's
//!   normal travel shared in proportion to the sweep) and then the remainder.
//! - **Other records**: `Dwell` is `G4 P<s>` / `DWELL <ms>`. `Spindle` is
//!   `S<rpm>` in ISO; a PMAC motion program does not drive a spindle, so it
//!   becomes a `;` comment that keeps the information visible. `Accel` is
//!   `TA`/`TS` in PMAC and a comment in ISO (no standard word). `Var` is
//!   `P12=3` / `M12==3` in PMAC (sync for M-variables only); in ISO a name starting with `#` is a
//!   parameter assignment (`#100=3`), anything else (a PMAC variable) a
//!   comment, because mapping `P12` onto `#12` would clobber subroutine
//!   arguments.
//!
//! Memory is constant: one reused `String` holds the text of the record
//! being written, numbers are formatted into it digit by digit.

use super::Dialect;
use crate::geometry::planar::sweep_angle;
use crate::geometry::{P2, P3, Plane};
use crate::model::toolpath::{ArcData, FeedUnit, Motion, MotionKind, Record, Role, ShutterSwitch};
use std::f64::consts::TAU;
use std::io::{self, Write};
use thiserror::Error;

mod blocks;

/// Most decimals the writer prints: nine places is a picometre in mm, and
/// keeps scaled coordinates well inside the exact range of `f64`/`i64`.
pub const MAX_DECIMALS: u8 = 9;

/// Largest scaled magnitude (value x 10^decimals) we print: beyond 2^53
/// integers stop being exact in `f64`, so rounding would lie.
const MAX_SCALED: f64 = 9.007_199_254_740_992e15;

/// More extra turns than this on one PMAC arc is a broken toolpath, not a
/// part: each turn is one line of output.
pub const MAX_PMAC_TURNS: u32 = 100_000;

/// How the writer formats a program. Build with [`WriteOptions::for_dialect`]
/// and change fields; `Default` is the PMAC setup of the laser stage.
#[derive(Debug, Clone, PartialEq)]
pub struct WriteOptions {
    /// Output dialect.
    pub dialect: Dialect,
    /// Decimal places of coordinates, centres, feeds, dwells and values
    /// (default 4 = 0.1 um; clamped to [`MAX_DECIMALS`]).
    pub decimals: u8,
    /// Always print a decimal point (`X1.` instead of `X1`), for controls
    /// that read a number without a point in least increments. Default off.
    pub decimal_point: bool,
    /// Unit of the `F` words written (default: the dialect's, mm/s for
    /// PMAC, mm/min for ISO). Input feeds are converted from the unit given
    /// to [`GcodeWriter::new`].
    pub feed_unit: FeedUnit,
    /// Write the motion word on every motion block instead of only when it
    /// changes. Default off (modal, like the thesis' programs).
    pub repeat_motion: bool,
    /// PMAC variable driving the shutter (default `M33`).
    pub shutter_var: String,
    /// Assign the shutter synchronously (`M33==1`, executed when the move's
    /// motion starts) rather than immediately (`M33=1`, executed when
    /// look-ahead calculates the line). Default on.
    pub shutter_sync: bool,
    /// ISO words that switch the beam on / off (default `M3` / `M5`). An
    /// empty string writes nothing (a control without beam switching).
    pub beam_on: String,
    /// The word that switches the beam off (see `beam_on`).
    pub beam_off: String,
    /// PMAC line-counter variable (default `P400`); `None` disables it.
    /// Ignored for ISO, which has N numbers instead.
    pub line_counter: Option<String>,
    /// Lines before the program body; `None` uses
    /// [`WriteOptions::default_header`]. A custom header leaves the beam and
    /// plane state unknown, so the first move writes both.
    pub header: Option<Vec<String>>,
    /// Lines after the body; `None` uses [`WriteOptions::default_trailer`].
    /// A custom trailer should close the shutter itself.
    pub trailer: Option<Vec<String>>,
    /// ISO only: number blocks `N10`, `N20`, ... with this step (`None`:
    /// no N words). Comment lines and `%` lines are not numbered.
    pub line_numbers: Option<u32>,
    /// Write arc centres as absolute coordinates (`G90.1` / `ABS(R)`)
    /// instead of offsets from the arc start. Default off.
    pub absolute_centers: bool,
    /// Where the machine is when the program starts: the first arc's start.
    pub start: P3,
    /// Write a comment line whenever the source chain or role changes
    /// (debugging aid). Default off.
    pub comments: bool,
    /// Largest difference (mm) between an arc's start and end radius that is
    /// written rather than refused (default 0.001 mm), on top of the
    /// rounding of the output precision.
    pub arc_tolerance: f64,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions::for_dialect(Dialect::Pmac)
    }
}

impl WriteOptions {
    /// The defaults of one dialect: 4 decimals, modal words, the dialect's
    /// feed unit, shutter `M33==` / beam `M3`-`M5`, counter `P400`.
    pub fn for_dialect(dialect: Dialect) -> Self {
        WriteOptions {
            dialect,
            decimals: 4,
            decimal_point: false,
            feed_unit: dialect.feed_unit(),
            repeat_motion: false,
            shutter_var: "M33".into(),
            shutter_sync: true,
            beam_on: "M3".into(),
            beam_off: "M5".into(),
            line_counter: Some("P400".into()),
            header: None,
            trailer: None,
            line_numbers: None,
            absolute_centers: false,
            start: P3::origin(),
            comments: false,
            arc_tolerance: 1e-3,
        }
    }

    /// The header used when [`WriteOptions::header`] is `None`.
    ///
    /// PMAC: `OPEN PROG 1 CLEAR`, `ABS`, the centre mode (`INC(R)`; it is
    /// coordinate-system state a previous program may have changed) and the
    /// shutter closed (immediate: no move follows yet).
    /// ISO: `G21 G90 G17 G94 G91.1` (mm, absolute, XY, per-minute feed,
    /// incremental centres) and the beam off.
    pub fn default_header(&self) -> Vec<String> {
        match self.dialect {
            Dialect::Pmac => vec![
                "OPEN PROG 1 CLEAR".into(),
                "ABS".into(),
                if self.absolute_centers { "ABS(R)" } else { "INC(R)" }.into(),
                format!("{}=0", self.shutter_var),
            ],
            Dialect::Iso => {
                let mut v = vec![format!(
                    "G21 G90 G17 G94 {}",
                    if self.absolute_centers { "G90.1" } else { "G91.1" }
                )];
                if !self.beam_off.is_empty() {
                    v.push(self.beam_off.clone());
                }
                v
            }
        }
    }

    /// The trailer used when [`WriteOptions::trailer`] is `None`: shutter
    /// closed, then `CLOSE` (PMAC) or `M30` (ISO).
    pub fn default_trailer(&self) -> Vec<String> {
        match self.dialect {
            Dialect::Pmac => vec![format!("{}=0", self.shutter_var), "CLOSE".into()],
            Dialect::Iso => {
                let mut v = Vec::new();
                if !self.beam_off.is_empty() {
                    v.push(self.beam_off.clone());
                }
                v.push("M30".into());
                v
            }
        }
    }
}

/// Why a record could not be written.
#[derive(Debug, Error)]
pub enum WriteError {
    /// The output could not be written.
    #[error("writing G-code: {0}")]
    Io(#[from] io::Error),
    /// A record (1-based count; 0 = the options) that has no G-code form:
    /// NaN, out of range, a broken arc, a bad variable name.
    #[error("toolpath record {record}{}: {msg}", source_block(.block))]
    Invalid {
        /// 1-based count of the record in the input; 0 for the options.
        record: u64,
        /// The source line the record came from, when it has one.
        block: Option<u64>,
        /// Why it cannot be written.
        msg: String,
    },
}

/// Why one record (or the start point) has no G-code form; carried as the
/// message of [`WriteError::Invalid`].
#[derive(Debug, Clone, PartialEq, Error)]
enum RecordError {
    #[error("{what} is not a finite number ({x})")]
    NotFinite { what: &'static str, x: f64 },
    #[error("{what} {x} is too large to write with {decimals} decimals")]
    TooLarge { what: &'static str, x: f64, decimals: u32 },
    #[error("feed must be a positive number, not {0}")]
    BadFeed(f64),
    #[error("feed {feed} {unit} rounds to zero with {decimals} decimals")]
    FeedRoundsToZero {
        feed: f64,
        unit: &'static str,
        decimals: u32,
    },
    #[error("arc of zero radius: its centre is on its start point at the output precision")]
    ZeroRadiusAtStart,
    #[error("arc of zero radius: its centre is on its end point at the output precision")]
    ZeroRadiusAtEnd,
    #[error("arc end is not on its circle: radius {r0} mm at the start, {r1} mm at the end")]
    EndOffCircle { r0: f64, r1: f64 },
    #[error("an arc of more than one turn that also turns a rotary axis cannot be written for a PMAC")]
    TurnsWithRotary,
    #[error("arc with {0} extra turns: more than {MAX_PMAC_TURNS} full circles")]
    TooManyTurns(u32),
    #[error("dwell must be zero or more seconds, not {0}")]
    BadDwell(f64),
    #[error("spindle speed must be zero or more rpm, not {0}")]
    BadSpindle(f64),
    #[error("{name} must be zero or more milliseconds, not {t}")]
    BadAccel { name: &'static str, t: f64 },
    #[error("'{0}' is not a PMAC variable name")]
    NotPmacVariable(String),
    #[error("variable {0} is the shutter or line counter; the writer drives it from the moves")]
    DrivenVariable(String),
    #[error("{0}==: synchronous assignment exists for M-variables only on a Turbo PMAC")]
    SyncNotM(String),
    #[error("'{0}' is not a variable name")]
    NotVariable(String),
}

fn source_block(b: &Option<u64>) -> String {
    match b {
        Some(n) => format!(" (source line {n})"),
        None => String::new(),
    }
}

/// The four motion modes, both dialects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Rapid,
    Line,
    Cw,
    Ccw,
}

impl Mode {
    fn word(self, d: Dialect) -> &'static str {
        match (d, self) {
            (Dialect::Iso, Mode::Rapid) => "G0",
            (Dialect::Iso, Mode::Line) => "G1",
            (Dialect::Iso, Mode::Cw) => "G2",
            (Dialect::Iso, Mode::Ccw) => "G3",
            (Dialect::Pmac, Mode::Rapid) => "RAPID",
            (Dialect::Pmac, Mode::Line) => "LINEAR",
            (Dialect::Pmac, Mode::Cw) => "CIRCLE1",
            (Dialect::Pmac, Mode::Ccw) => "CIRCLE2",
        }
    }
}

fn plane_word(d: Dialect, p: Plane) -> &'static str {
    match (d, p) {
        (Dialect::Iso, Plane::Xy) => "G17",
        (Dialect::Iso, Plane::Xz) => "G18",
        (Dialect::Iso, Plane::Yz) => "G19",
        (Dialect::Pmac, Plane::Xy) => "NORMAL K-1",
        (Dialect::Pmac, Plane::Xz) => "NORMAL J-1",
        (Dialect::Pmac, Plane::Yz) => "NORMAL I-1",
    }
}

const AXIS: [&str; 3] = ["X", "Y", "Z"];
const CENTRE: [&str; 3] = ["I", "J", "K"];
const ROTARY: [&str; 3] = ["A", "B", "C"];

/// The arc words of one motion block, already validated and scaled.
#[derive(Clone, Copy)]
struct ArcWords {
    plane: Plane,
    /// (axis index, scaled value) of the two in-plane centre words.
    centre: [(usize, i64); 2],
    /// ISO `P` word (turns), when above 1.
    turns: Option<u64>,
}

/// Streaming G-code writer: `begin`, `record` for each record, `finish`.
///
/// Output goes straight to `out` one record at a time; give it a
/// `BufWriter` when writing to a file or pipe.
pub struct GcodeWriter<W: Write> {
    out: W,
    opts: WriteOptions,
    in_unit: FeedUnit,
    /// 10^decimals.
    scale: f64,
    decimals: u32,
    /// Text of the record being written.
    buf: String,
    /// How the move being written wants its shutter switch written, when
    /// it says (PMAC `==` or `=`); otherwise `opts.shutter_sync` decides.
    switch: Option<ShutterSwitch>,
    /// Byte index in `buf` where the current line starts.
    line_start: usize,
    begun: bool,
    /// Position as written, in output units (value x 10^decimals).
    pos: [i64; 3],
    /// False until the first move: then all three axes are written.
    positioned: bool,
    mode: Option<Mode>,
    plane: Option<Plane>,
    /// Last `F` written, scaled.
    feed: Option<i64>,
    beam: Option<bool>,
    /// Motion lines written (the line counter's value).
    blocks: u64,
    /// Next N number (ISO).
    next_n: u64,
    /// Last (chain, role) commented.
    tag: Option<(Option<u64>, Option<Role>)>,
    /// Records seen, for error messages.
    records: u64,
    /// Rotary axes A, B, C as written (scaled degrees), once a move has
    /// carried them; and those of the move being written.
    abc: Option<[i64; 3]>,
    abc_next: Option<[i64; 3]>,
    /// Tool number last written (ISO `T.. M6`).
    tool: Option<u32>,
}

impl<W: Write> GcodeWriter<W> {
    /// A writer to `out`; `input_feed_unit` is the unit of the feeds in the
    /// records (the toolpath header's `feed_unit`).
    pub fn new(out: W, opts: WriteOptions, input_feed_unit: FeedUnit) -> Self {
        let decimals = u32::from(opts.decimals.min(MAX_DECIMALS));
        let next_n = u64::from(opts.line_numbers.unwrap_or(0));
        GcodeWriter {
            out,
            in_unit: input_feed_unit,
            scale: 10f64.powi(decimals as i32),
            decimals,
            buf: String::with_capacity(256),
            switch: None,
            line_start: 0,
            begun: false,
            pos: [0; 3],
            positioned: false,
            mode: None,
            plane: None,
            feed: None,
            beam: None,
            blocks: 0,
            next_n,
            tag: None,
            records: 0,
            abc: None,
            abc_next: None,
            tool: None,
            opts,
        }
    }

    /// The options in use.
    pub fn options(&self) -> &WriteOptions {
        &self.opts
    }

    /// Motion lines written so far (the line counter's last value).
    pub fn motion_blocks(&self) -> u64 {
        self.blocks
    }

    /// Where the last move ended, as written (rounded to the output
    /// precision); the start point before any move.
    pub fn position(&self) -> P3 {
        P3::new(
            self.pos[0] as f64 / self.scale,
            self.pos[1] as f64 / self.scale,
            self.pos[2] as f64 / self.scale,
        )
    }

    /// Write the header. Called by the first `record` or `finish` if not
    /// called before; calling it again does nothing.
    pub fn begin(&mut self) -> Result<(), WriteError> {
        if self.begun {
            return Ok(());
        }
        self.begun = true;
        let start = self.opts.start;
        self.pos = self.point(&start, "start point").map_err(|e| WriteError::Invalid {
            record: 0,
            block: None,
            msg: e.to_string(),
        })?;
        self.buf.clear();
        let custom = self.opts.header.take();
        match &custom {
            Some(lines) => {
                for l in lines {
                    self.text_line(l);
                }
            }
            None => {
                for l in self.opts.default_header() {
                    self.text_line(&l);
                }
                // What the default header established.
                self.beam = Some(false);
                if self.opts.dialect == Dialect::Iso {
                    self.plane = Some(Plane::Xy);
                }
            }
        }
        self.opts.header = custom;
        self.out.write_all(self.buf.as_bytes())?;
        Ok(())
    }

    /// Write one record. A record that cannot be written (NaN, broken arc,
    /// ...) is refused with [`WriteError::Invalid`] before anything of it is
    /// written or the modal state changes, so the caller may skip it.
    pub fn record(&mut self, r: &Record) -> Result<(), WriteError> {
        self.begin()?;
        self.records += 1;
        self.buf.clear();
        let res = match r {
            Record::Move(m) => {
                self.switch = m.beam_switch;
                let r = self.write_move(m);
                self.switch = None;
                r
            }
            Record::Dwell { seconds, .. } => self.write_dwell(*seconds),
            Record::Spindle { rpm, .. } => self.write_spindle(*rpm),
            Record::Accel { ta_ms, ts_ms, .. } => self.write_accel(*ta_ms, *ts_ms),
            Record::Var { name, value, sync, .. } => self.write_var(name, *value, *sync),
        };
        res.map_err(|e| WriteError::Invalid {
            record: self.records,
            block: r.block(),
            msg: e.to_string(),
        })?;
        self.out.write_all(self.buf.as_bytes())?;
        Ok(())
    }

    /// Write the trailer, flush, and hand back the output.
    pub fn finish(mut self) -> Result<W, WriteError> {
        self.begin()?;
        self.buf.clear();
        if self.opts.dialect == Dialect::Pmac && self.beam == Some(true) {
            // Stop look-ahead so the trailer's immediate shutter close runs
            // after the last (beam-on) move, not during it.
            self.text_line("DWELL 0");
        }
        let trailer = self.opts.trailer.take().unwrap_or_else(|| self.opts.default_trailer());
        for l in &trailer {
            self.text_line(l);
        }
        self.out.write_all(self.buf.as_bytes())?;
        self.out.flush()?;
        Ok(self.out)
    }

    // ---- numbers -------------------------------------------------------

    /// Round `x` to output units, refusing NaN, infinities and magnitudes
    /// the fixed-point form cannot hold.
    fn scaled(&self, x: f64, what: &'static str) -> Result<i64, RecordError> {
        if !x.is_finite() {
            return Err(RecordError::NotFinite { what, x });
        }
        let s = (x * self.scale).round();
        if s.abs() >= MAX_SCALED {
            return Err(RecordError::TooLarge {
                what,
                x,
                decimals: self.decimals,
            });
        }
        Ok(s as i64)
    }

    fn point(&self, p: &P3, what: &'static str) -> Result<[i64; 3], RecordError> {
        Ok([
            self.scaled(p.x, what)?,
            self.scaled(p.y, what)?,
            self.scaled(p.z, what)?,
        ])
    }

    /// Append a scaled number: integer part, then the fraction without
    /// trailing zeros. Zero is always `0`, never `-0`.
    fn push_num(&mut self, v: i64) {
        push_fixed(&mut self.buf, v, self.decimals, self.opts.decimal_point);
    }

    // ---- lines ---------------------------------------------------------

    /// Start a block line, with its N number in ISO when numbering.
    fn start_block(&mut self) {
        self.line_start = self.buf.len();
        if self.opts.dialect == Dialect::Iso
            && let Some(step) = self.opts.line_numbers
        {
            self.buf.push('N');
            push_fixed(&mut self.buf, self.next_n.min(i64::MAX as u64) as i64, 0, false);
            self.next_n = self.next_n.saturating_add(u64::from(step));
        }
    }

    /// Separator before the next word, unless the line is empty.
    fn sep(&mut self) {
        sep(&mut self.buf, self.line_start);
    }

    fn push_word(&mut self, w: &str) {
        if !w.is_empty() {
            self.sep();
            self.buf.push_str(w);
        }
    }

    fn push_value(&mut self, letter: &str, v: i64) {
        self.sep();
        self.buf.push_str(letter);
        self.push_num(v);
    }

    fn end_line(&mut self) {
        self.buf.push('\n');
        self.line_start = self.buf.len();
    }

    /// A header/trailer/fixed line: numbered in ISO unless it is empty, a
    /// comment or a `%` tape mark.
    fn text_line(&mut self, l: &str) {
        let t = l.trim_start();
        if t.is_empty() || t.starts_with(['%', '(', ';']) {
            self.line_start = self.buf.len();
        } else {
            self.start_block();
        }
        self.push_word(l);
        self.end_line();
    }

    /// A comment line in the dialect's style. `text` must not hold `)`.
    fn comment_line(&mut self, text: impl FnOnce(&mut String)) {
        self.line_start = self.buf.len();
        match self.opts.dialect {
            Dialect::Iso => {
                self.buf.push('(');
                text(&mut self.buf);
                self.buf.push(')');
            }
            Dialect::Pmac => {
                self.buf.push_str("; ");
                text(&mut self.buf);
            }
        }
        self.end_line();
    }
}

/// A space before the next word unless the line (from `line_start`) is empty.
fn sep(buf: &mut String, line_start: usize) {
    if buf.len() > line_start {
        buf.push(' ');
    }
}

/// Finite and not negative (NaN fails).
fn non_negative(x: f64) -> bool {
    x.is_finite() && x >= 0.0
}

/// Append `v / 10^decimals` in fixed point without trailing zeros and
/// without allocating; `point` forces a decimal point on whole numbers.
fn push_fixed(out: &mut String, v: i64, decimals: u32, point: bool) {
    let pow = 10u64.pow(decimals);
    let u = v.unsigned_abs();
    let (int, mut frac) = (u / pow, u % pow);
    if v < 0 {
        out.push('-');
    }
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    let mut n = int;
    loop {
        i -= 1;
        digits[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    for &d in &digits[i..] {
        out.push(d as char);
    }
    if frac == 0 {
        if point {
            out.push('.');
        }
        return;
    }
    out.push('.');
    let mut width = decimals;
    while frac % 10 == 0 {
        frac /= 10;
        width -= 1;
    }
    let mut i = digits.len();
    for _ in 0..width {
        i -= 1;
        digits[i] = b'0' + (frac % 10) as u8;
        frac /= 10;
    }
    for &d in &digits[i..] {
        out.push(d as char);
    }
}

/// Write a whole program to `out` (small programs, tests).
pub fn write_program<'a, W: Write>(
    out: W,
    opts: WriteOptions,
    input_feed_unit: FeedUnit,
    records: impl IntoIterator<Item = &'a Record>,
) -> Result<W, WriteError> {
    let mut w = GcodeWriter::new(out, opts, input_feed_unit);
    w.begin()?;
    for r in records {
        w.record(r)?;
    }
    w.finish()
}

/// Write a whole program into a `String`.
pub fn write_string<'a>(
    opts: WriteOptions,
    input_feed_unit: FeedUnit,
    records: impl IntoIterator<Item = &'a Record>,
) -> Result<String, WriteError> {
    let bytes = write_program(Vec::new(), opts, input_feed_unit, records)?;
    // Every byte we write comes from &str pieces.
    Ok(String::from_utf8(bytes).unwrap_or_default())
}

#[cfg(test)]
mod tests;
