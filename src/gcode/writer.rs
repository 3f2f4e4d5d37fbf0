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
    #[error("writing G-code: {0}")]
    Io(#[from] io::Error),
    /// A record (1-based count; 0 = the options) that has no G-code form:
    /// NaN, out of range, a broken arc, a bad variable name.
    #[error("toolpath record {record}{}: {msg}", source_block(.block))]
    Invalid {
        record: u64,
        block: Option<u64>,
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

    // ---- records -------------------------------------------------------

    fn write_move(&mut self, m: &Motion) -> Result<(), RecordError> {
        let to = self.point(&m.to, "end point")?;
        self.abc_next = match &m.tool.abc {
            Some(abc) => Some([
                self.scaled(abc[0], "rotary axis A")?,
                self.scaled(abc[1], "rotary axis B")?,
                self.scaled(abc[2], "rotary axis C")?,
            ]),
            None => None,
        };
        if let (Some(t), Dialect::Iso) = (m.tool.number, self.opts.dialect)
            && self.tool != Some(t)
        {
            // A tool change: ISO `T.. M6` on its own line (PMAC has no
            // tool changer of its own; the number stays in the toolpath).
            self.text_line(&format!("T{t} M6"));
            self.tool = Some(t);
        }
        let feed = match (m.kind, m.feed) {
            (MotionKind::Rapid, _) | (_, None) => None,
            (_, Some(f)) => {
                if !(f.is_finite() && f > 0.0) {
                    return Err(RecordError::BadFeed(f));
                }
                let f = self.in_unit.convert(f, self.opts.feed_unit);
                let s = self.scaled(f, "feed")?;
                if s == 0 {
                    return Err(RecordError::FeedRoundsToZero {
                        feed: f,
                        unit: self.opts.feed_unit.name(),
                        decimals: self.decimals,
                    });
                }
                Some(s)
            }
        };
        match m.kind {
            MotionKind::Rapid => {
                self.tag_comment(m);
                self.block(Mode::Rapid, to, None, None, m.beam);
            }
            MotionKind::Line => {
                self.tag_comment(m);
                self.block(Mode::Line, to, None, feed, m.beam);
            }
            MotionKind::Arc(a) => self.write_arc(m, &a, to, feed)?,
        }
        Ok(())
    }

    fn write_arc(&mut self, m: &Motion, a: &ArcData, to: [i64; 3], feed: Option<i64>) -> Result<(), RecordError> {
        let c = self.point(&a.center, "arc centre")?;
        let (ia, ib, inorm) = a.plane.axes();
        let start = self.pos;
        let (sa, sb) = (c[ia] - start[ia], c[ib] - start[ib]);
        let (ea, eb) = (c[ia] - to[ia], c[ib] - to[ib]);
        if sa == 0 && sb == 0 {
            return Err(RecordError::ZeroRadiusAtStart);
        }
        if ea == 0 && eb == 0 {
            return Err(RecordError::ZeroRadiusAtEnd);
        }
        let r0 = (sa as f64).hypot(sb as f64) / self.scale;
        let r1 = (ea as f64).hypot(eb as f64) / self.scale;
        if (r0 - r1).abs() > self.opts.arc_tolerance + 2.0 / self.scale {
            return Err(RecordError::EndOffCircle { r0, r1 });
        }
        let pmac = self.opts.dialect == Dialect::Pmac;
        if pmac && a.extra_turns > 0 && self.abc_next.is_some() && self.abc_next != self.abc {
            return Err(RecordError::TurnsWithRotary);
        }
        if pmac && a.extra_turns > MAX_PMAC_TURNS {
            return Err(RecordError::TooManyTurns(a.extra_turns));
        }
        let (wa, wb) = if self.opts.absolute_centers {
            (c[ia], c[ib])
        } else {
            (c[ia] - start[ia], c[ib] - start[ib])
        };
        let mut centre = [(ia, wa), (ib, wb)];
        centre.sort_by_key(|&(i, _)| i);
        let mode = if a.ccw { Mode::Ccw } else { Mode::Cw };
        self.tag_comment(m);
        if pmac && a.extra_turns > 0 {
            // Full circles first, each ending over the start point with its
            // share of the normal travel, then the remaining partial sweep.
            let f = |v: i64| v as f64;
            let cp = P2::new(f(c[ia]), f(c[ib]));
            let sp = P2::new(f(start[ia]), f(start[ib]));
            let ep = P2::new(f(to[ia]), f(to[ib]));
            // Scaled units: equal integers are the same printed point.
            let base = sweep_angle(&cp, &sp, &ep, a.ccw, 0, 0.5).abs();
            let n = a.extra_turns;
            let total = base + TAU * f64::from(n);
            let dn = f(to[inorm] - start[inorm]);
            let words = ArcWords {
                plane: a.plane,
                centre,
                turns: None,
            };
            for k in 1..=n {
                let mut t = start;
                t[inorm] = start[inorm] + (dn * TAU * f64::from(k) / total).round() as i64;
                self.block(mode, t, Some(words), feed, m.beam);
            }
            self.block(mode, to, Some(words), feed, m.beam);
        } else {
            let turns = if a.extra_turns > 0 && !pmac {
                Some(u64::from(a.extra_turns) + 1)
            } else {
                None
            };
            let words = ArcWords {
                plane: a.plane,
                centre,
                turns,
            };
            self.block(mode, to, Some(words), feed, m.beam);
        }
        Ok(())
    }

    /// One motion line (plus a PMAC plane line before it when the plane
    /// changes). Everything is validated by now; this only formats and
    /// updates the modal state.
    fn block(&mut self, mode: Mode, to: [i64; 3], arc: Option<ArcWords>, feed: Option<i64>, beam: bool) {
        let d = self.opts.dialect;
        let plane_change = arc.map(|a| a.plane).filter(|p| self.plane != Some(*p));
        if let (Some(p), Dialect::Pmac) = (plane_change, d) {
            self.text_line(plane_word(d, p));
        }
        self.start_block();
        if let Some(p) = plane_change {
            if d == Dialect::Iso {
                self.push_word(plane_word(d, p));
            }
            self.plane = Some(p);
        }
        if self.beam != Some(beam) {
            self.beam_word(beam);
            self.beam = Some(beam);
        }
        if self.opts.repeat_motion || self.mode != Some(mode) {
            self.push_word(mode.word(d));
            self.mode = Some(mode);
        }
        let mut axes = [false; 3];
        for (i, w) in axes.iter_mut().enumerate() {
            *w = !self.positioned || to[i] != self.pos[i];
        }
        // Rotary words: all three the first time, then those that change.
        let mut rot = [false; 3];
        if let Some(n) = self.abc_next {
            for (i, w) in rot.iter_mut().enumerate() {
                *w = self.abc.is_none_or(|o| o[i] != n[i]);
            }
        }
        match &arc {
            Some(a) => {
                let (ia, ib, _) = a.plane.axes();
                if !axes[ia] && !axes[ib] {
                    axes[ia] = true;
                    axes[ib] = true;
                }
            }
            None => {
                if !axes.iter().any(|&w| w) && !rot.iter().any(|&w| w) {
                    axes[0] = true;
                }
            }
        }
        for i in 0..3 {
            if axes[i] {
                self.push_value(AXIS[i], to[i]);
            }
        }
        if let Some(n) = self.abc_next {
            for i in 0..3 {
                if rot[i] {
                    self.push_value(ROTARY[i], n[i]);
                }
            }
            self.abc = Some(n);
        }
        if let Some(a) = &arc {
            for (i, v) in a.centre {
                self.push_value(CENTRE[i], v);
            }
            if let Some(p) = a.turns {
                self.sep();
                self.buf.push('P');
                push_fixed(&mut self.buf, p as i64, 0, false);
            }
        }
        if let Some(f) = feed
            && self.feed != Some(f)
        {
            self.push_value("F", f);
            self.feed = Some(f);
        }
        self.blocks += 1;
        if d == Dialect::Pmac
            && let Some(var) = &self.opts.line_counter
            && !var.is_empty()
        {
            sep(&mut self.buf, self.line_start);
            self.buf.push_str(var);
            self.buf.push('=');
            push_fixed(&mut self.buf, self.blocks.min(i64::MAX as u64) as i64, 0, false);
        }
        self.end_line();
        self.pos = to;
        self.positioned = true;
    }

    fn beam_word(&mut self, on: bool) {
        match self.opts.dialect {
            Dialect::Pmac => {
                self.sep();
                self.buf.push_str(&self.opts.shutter_var);
                let sync = match self.switch {
                    Some(sw) => sw == ShutterSwitch::Sync,
                    None => self.opts.shutter_sync,
                };
                self.buf.push_str(if sync { "==" } else { "=" });
                self.buf.push(if on { '1' } else { '0' });
            }
            Dialect::Iso => {
                let w = if on { &self.opts.beam_on } else { &self.opts.beam_off };
                if !w.is_empty() {
                    sep(&mut self.buf, self.line_start);
                    self.buf.push_str(w);
                }
            }
        }
    }

    fn tag_comment(&mut self, m: &Motion) {
        if !self.opts.comments {
            return;
        }
        let tag = (m.chain, m.role);
        if self.tag == Some(tag) {
            return;
        }
        self.tag = Some(tag);
        self.comment_line(|b| {
            if let Some(c) = m.chain {
                b.push_str("chain ");
                push_fixed(b, c.min(i64::MAX as u64) as i64, 0, false);
            }
            if let Some(r) = m.role {
                if m.chain.is_some() {
                    b.push(' ');
                }
                b.push_str(r.name());
            }
            if m.chain.is_none() && m.role.is_none() {
                b.push_str("untagged");
            }
        });
    }

    fn write_dwell(&mut self, seconds: f64) -> Result<(), RecordError> {
        if !non_negative(seconds) {
            return Err(RecordError::BadDwell(seconds));
        }
        match self.opts.dialect {
            Dialect::Iso => {
                let v = self.scaled(seconds, "dwell")?;
                self.start_block();
                self.push_value("G4 P", v);
            }
            Dialect::Pmac => {
                let v = self.scaled(seconds * 1000.0, "dwell")?;
                self.start_block();
                self.push_value("DWELL ", v);
            }
        }
        self.end_line();
        Ok(())
    }

    fn write_spindle(&mut self, rpm: f64) -> Result<(), RecordError> {
        if !non_negative(rpm) {
            return Err(RecordError::BadSpindle(rpm));
        }
        let v = self.scaled(rpm, "spindle speed")?;
        match self.opts.dialect {
            Dialect::Iso => {
                self.start_block();
                self.push_value("S", v);
                self.end_line();
            }
            Dialect::Pmac => {
                let (dec, pt) = (self.decimals, self.opts.decimal_point);
                self.comment_line(|b| {
                    b.push_str("spindle S");
                    push_fixed(b, v, dec, pt);
                    b.push_str(" rpm (not commanded by the motion program)");
                });
            }
        }
        Ok(())
    }

    fn write_accel(&mut self, ta: Option<f64>, ts: Option<f64>) -> Result<(), RecordError> {
        let mut vals: [Option<(&'static str, i64)>; 2] = [None, None];
        for (slot, (name, t)) in vals.iter_mut().zip([("TA", ta), ("TS", ts)]) {
            if let Some(t) = t {
                if !non_negative(t) {
                    return Err(RecordError::BadAccel { name, t });
                }
                *slot = Some((name, self.scaled(t, name)?));
            }
        }
        if vals.iter().all(Option::is_none) {
            return Ok(());
        }
        match self.opts.dialect {
            Dialect::Pmac => {
                self.start_block();
                for (name, v) in vals.into_iter().flatten() {
                    self.push_value(name, v);
                }
                self.end_line();
            }
            Dialect::Iso => {
                let (dec, pt) = (self.decimals, self.opts.decimal_point);
                self.comment_line(|b| {
                    let mut first = true;
                    for (name, v) in vals.into_iter().flatten() {
                        if !first {
                            b.push(' ');
                        }
                        first = false;
                        b.push_str(name);
                        b.push(' ');
                        push_fixed(b, v, dec, pt);
                        b.push_str(" ms");
                    }
                });
            }
        }
        Ok(())
    }

    fn write_var(&mut self, name: &str, value: f64, sync: bool) -> Result<(), RecordError> {
        let v = self.scaled(value, "variable value")?;
        let plain = name.len() > 1
            && name.as_bytes()[0].is_ascii_alphabetic()
            && name.bytes().all(|c| c.is_ascii_alphanumeric() || c == b'_');
        let (dec, pt) = (self.decimals, self.opts.decimal_point);
        match self.opts.dialect {
            Dialect::Pmac => {
                if !plain {
                    return Err(RecordError::NotPmacVariable(name.to_string()));
                }
                let reserved = std::iter::once(self.opts.shutter_var.as_str())
                    .chain(self.opts.line_counter.as_deref())
                    .any(|r| r.eq_ignore_ascii_case(name));
                if reserved {
                    return Err(RecordError::DrivenVariable(name.to_string()));
                }
                // Turbo PMAC has synchronous assignment for M-variables only.
                if sync && !name.as_bytes()[0].eq_ignore_ascii_case(&b'M') {
                    return Err(RecordError::SyncNotM(name.to_string()));
                }
                self.start_block();
                self.buf.push_str(name);
                self.buf.push_str(if sync { "==" } else { "=" });
                self.push_num(v);
                self.end_line();
            }
            Dialect::Iso => {
                let param = name.strip_prefix('#').is_some_and(|rest| {
                    let b = rest.as_bytes();
                    (!b.is_empty() && b.iter().all(u8::is_ascii_digit))
                        || (b.len() > 2
                            && b[0] == b'<'
                            && b[b.len() - 1] == b'>'
                            && b[1..b.len() - 1]
                                .iter()
                                .all(|c| c.is_ascii_alphanumeric() || *c == b'_'))
                });
                if param {
                    self.start_block();
                    self.buf.push_str(name);
                    self.buf.push('=');
                    self.push_num(v);
                    self.end_line();
                } else if plain {
                    self.comment_line(|b| {
                        b.push_str(name);
                        b.push_str(if sync { "==" } else { "=" });
                        push_fixed(b, v, dec, pt);
                    });
                } else {
                    return Err(RecordError::NotVariable(name.to_string()));
                }
            }
        }
        Ok(())
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
mod tests {
    use super::*;
    use crate::model::toolpath::Role;

    fn mv(kind: MotionKind, to: [f64; 3], feed: Option<f64>, beam: bool) -> Record {
        Record::Move(Motion {
            kind,
            to: P3::new(to[0], to[1], to[2]),
            feed,
            beam,
            beam_switch: None,
            role: None,
            chain: None,
            block: None,
            tool: Default::default(),
        })
    }

    fn rapid(to: [f64; 3]) -> Record {
        mv(MotionKind::Rapid, to, None, false)
    }

    fn line(to: [f64; 3], feed: f64, beam: bool) -> Record {
        mv(MotionKind::Line, to, Some(feed), beam)
    }

    fn arc(to: [f64; 3], center: [f64; 3], ccw: bool, plane: Plane, turns: u32, feed: f64, beam: bool) -> Record {
        mv(
            MotionKind::Arc(ArcData {
                center: P3::new(center[0], center[1], center[2]),
                ccw,
                plane,
                extra_turns: turns,
            }),
            to,
            Some(feed),
            beam,
        )
    }

    fn write(opts: WriteOptions, unit: FeedUnit, recs: &[Record]) -> String {
        write_string(opts, unit, recs).expect("writes")
    }

    fn opts(d: Dialect) -> WriteOptions {
        WriteOptions::for_dialect(d)
    }

    /// Fig. 6-38-like laser program: shutter closed on the lead-in, open on
    /// the cut, closed on the corner loop, a full circle, and the counter on
    /// every motion line.
    fn laser_path() -> Vec<Record> {
        vec![
            rapid([1.8183, 5.0, 0.0]),
            line([1.8183, 5.455, 0.0], 2.0, false),
            line([1.8183, 6.3977, 0.0], 2.0, true),
            arc(
                [1.861, 6.355, 0.0],
                [1.861, 6.3977, 0.0],
                false,
                Plane::Xy,
                0,
                2.0,
                false,
            ),
            line([1.8183, 6.355, 0.0], 2.0, false),
            arc(
                [1.8183, 6.355, 0.0],
                [1.8183, 5.455, 0.0],
                true,
                Plane::Xy,
                0,
                2.0,
                true,
            ),
            line([1.7756, 6.355, 0.0], 2.0, false),
            arc(
                [1.8183, 6.3977, 0.0],
                [1.8183, 6.355, 0.0],
                false,
                Plane::Xy,
                0,
                2.0,
                false,
            ),
            line([1.8183, 5.455, 0.0], 2.0, true),
        ]
    }

    #[test]
    fn pmac_laser_program_golden() {
        let text = write(opts(Dialect::Pmac), FeedUnit::MmPerS, &laser_path());
        let expected = "\
OPEN PROG 1 CLEAR
ABS
INC(R)
M33=0
RAPID X1.8183 Y5 Z0 P400=1
LINEAR Y5.455 F2 P400=2
M33==1 Y6.3977 P400=3
NORMAL K-1
M33==0 CIRCLE1 X1.861 Y6.355 I0.0427 J0 P400=4
LINEAR X1.8183 P400=5
M33==1 CIRCLE2 X1.8183 Y6.355 I0 J-0.9 P400=6
M33==0 LINEAR X1.7756 P400=7
CIRCLE1 X1.8183 Y6.3977 I0.0427 J0 P400=8
M33==1 LINEAR Y5.455 P400=9
DWELL 0
M33=0
CLOSE
";
        assert_eq!(text, expected);
    }

    #[test]
    fn iso_laser_program_golden() {
        let mut o = opts(Dialect::Iso);
        o.line_numbers = Some(10);
        let text = write(o, FeedUnit::MmPerS, &laser_path());
        let expected = "\
N10 G21 G90 G17 G94 G91.1
N20 M5
N30 G0 X1.8183 Y5 Z0
N40 G1 Y5.455 F120
N50 M3 Y6.3977
N60 M5 G2 X1.861 Y6.355 I0.0427 J0
N70 G1 X1.8183
N80 M3 G3 X1.8183 Y6.355 I0 J-0.9
N90 M5 G1 X1.7756
N100 G2 X1.8183 Y6.3977 I0.0427 J0
N110 M3 G1 Y5.455
N120 M5
N130 M30
";
        assert_eq!(text, expected);
    }

    /// Planes, helices, extra turns, dwell, spindle, accel and variables.
    fn mixed_path() -> Vec<Record> {
        vec![
            rapid([0.0, 0.0, 1.0]),
            Record::Spindle {
                rpm: 30000.0,
                block: None,
            },
            Record::Accel {
                ta_ms: Some(100.0),
                ts_ms: Some(20.5),
                block: None,
            },
            // Helix, one extra turn: down 1.5 mm over 1.25 turns.
            arc([1.0, 1.0, -0.5], [0.0, 1.0, 1.0], true, Plane::Xy, 1, 60.0, true),
            Record::Dwell {
                seconds: 0.25,
                block: None,
            },
            // Half circle in ZX (G18), then a quarter in YZ (G19).
            arc([1.0, 1.0, 1.5], [1.0, 1.0, 0.5], false, Plane::Xz, 0, 60.0, true),
            arc([1.0, 0.0, 0.5], [1.0, 1.0, 0.5], true, Plane::Yz, 0, 120.0, true),
            Record::Var {
                name: "M12".into(),
                value: -3.25,
                sync: true,
                block: None,
            },
            line([0.0, 0.0, 0.5], 120.0, false),
        ]
    }

    #[test]
    fn pmac_mixed_golden() {
        let text = write(opts(Dialect::Pmac), FeedUnit::MmPerMin, &mixed_path());
        let expected = "\
OPEN PROG 1 CLEAR
ABS
INC(R)
M33=0
RAPID X0 Y0 Z1 P400=1
; spindle S30000 rpm (not commanded by the motion program)
TA100 TS20.5
NORMAL K-1
M33==1 CIRCLE2 X0 Y0 Z-0.2 I0 J1 F1 P400=2
X1 Y1 Z-0.5 I0 J1 P400=3
DWELL 250
NORMAL J-1
CIRCLE1 Z1.5 I0 K1 P400=4
NORMAL I-1
CIRCLE2 Y0 Z0.5 J0 K-1 F2 P400=5
M12==-3.25
M33==0 LINEAR X0 P400=6
M33=0
CLOSE
";
        assert_eq!(text, expected);
    }

    #[test]
    fn iso_mixed_golden() {
        let text = write(opts(Dialect::Iso), FeedUnit::MmPerMin, &mixed_path());
        let expected = "\
G21 G90 G17 G94 G91.1
M5
G0 X0 Y0 Z1
S30000
(TA 100 ms TS 20.5 ms)
M3 G3 X1 Y1 Z-0.5 I0 J1 P2 F60
G4 P0.25
G18 G2 Z1.5 I0 K1
G19 G3 Y0 Z0.5 J0 K-1 F120
(M12==-3.25)
M5 G1 X0
M5
M30
";
        assert_eq!(text, expected);
    }

    #[test]
    fn output_is_byte_identical_across_runs() {
        let mut recs = laser_path();
        recs.extend(mixed_path());
        for d in [Dialect::Pmac, Dialect::Iso] {
            let a = write(opts(d), FeedUnit::MmPerS, &recs);
            let b = write(opts(d), FeedUnit::MmPerS, &recs);
            assert_eq!(a.as_bytes(), b.as_bytes());
        }
    }

    #[test]
    fn numbers_are_fixed_point_trimmed_and_never_minus_zero() {
        let mut b = String::new();
        for (v, dec, pt, want) in [
            (0i64, 4, false, "0"),
            (0, 4, true, "0."),
            (15000, 4, false, "1.5"),
            (-15000, 4, false, "-1.5"),
            (-5, 4, false, "-0.0005"),
            (12345, 4, false, "1.2345"),
            (10000, 4, true, "1."),
            (-120, 0, false, "-120"),
            (i64::MIN, 9, false, "-9223372036.854775808"),
            (1, 9, false, "0.000000001"),
        ] {
            b.clear();
            push_fixed(&mut b, v, dec, pt);
            assert_eq!(b, want, "{v} with {dec} decimals");
        }
        // Rounding to the output precision: -0.00004 is 0, not -0.
        let text = write(
            opts(Dialect::Iso),
            FeedUnit::MmPerMin,
            &[rapid([-0.00004, 2.00004, -1.99996])],
        );
        assert!(text.contains("G0 X0 Y2 Z-2\n"), "{text}");
    }

    #[test]
    fn feeds_convert_and_stay_modal() {
        let recs = [
            line([1.0, 0.0, 0.0], 2.5, false),
            line([2.0, 0.0, 0.0], 2.5, false),
            rapid([3.0, 0.0, 0.0]),
            line([4.0, 0.0, 0.0], 2.5, false),
            line([5.0, 0.0, 0.0], 1.0 / 3.0, false),
        ];
        let iso = write(opts(Dialect::Iso), FeedUnit::MmPerS, &recs);
        assert!(iso.contains("G1 X1 Y0 Z0 F150\nX2\nG0 X3\nG1 X4\nX5 F20\n"), "{iso}");
        let pmac = write(opts(Dialect::Pmac), FeedUnit::MmPerMin, &recs);
        assert!(
            pmac.contains(
                "LINEAR X1 Y0 Z0 F0.0417 P400=1\nX2 P400=2\nRAPID X3 P400=3\nLINEAR X4 P400=4\nX5 F0.0056 P400=5\n"
            ),
            "{pmac}"
        );
        // Output unit chosen explicitly.
        let mut o = opts(Dialect::Iso);
        o.feed_unit = FeedUnit::MmPerS;
        assert!(write(o, FeedUnit::MmPerMin, &recs[..1]).contains("F0.0417"));
    }

    #[test]
    fn options_change_the_words() {
        let recs = [
            line([1.0, 0.0, 0.0], 2.0, true),
            line([2.0, 0.0, 0.0], 2.0, true),
            line([3.0, 0.0, 0.0], 2.0, false),
        ];
        let mut o = opts(Dialect::Pmac);
        o.shutter_sync = false;
        o.shutter_var = "M1".into();
        o.line_counter = None;
        o.repeat_motion = true;
        o.decimal_point = true;
        o.header = Some(vec!["OPEN PROG 7 CLEAR".into()]);
        o.trailer = Some(vec!["CLOSE".into()]);
        let text = write(o, FeedUnit::MmPerS, &recs);
        assert_eq!(
            text,
            "OPEN PROG 7 CLEAR\nM1=1 LINEAR X1. Y0. Z0. F2.\nLINEAR X2.\nM1=0 LINEAR X3.\nCLOSE\n"
        );

        // A custom ISO header leaves beam and plane unknown: the first move
        // and the first arc say them; other M-codes for the beam.
        let mut o = opts(Dialect::Iso);
        o.header = Some(vec!["%".into(), "(part 1)".into(), "G21 G90".into()]);
        o.trailer = Some(vec!["M30".into(), "%".into()]);
        o.beam_on = "M62 P0".into();
        o.beam_off = "M63 P0".into();
        o.line_numbers = Some(5);
        o.absolute_centers = true;
        let recs = [
            line([1.0, 0.0, 0.0], 1.0, false),
            arc([1.0, 2.0, 0.0], [1.0, 1.0, 0.0], true, Plane::Xy, 0, 1.0, true),
        ];
        let text = write(o, FeedUnit::MmPerMin, &recs);
        assert_eq!(
            text,
            "%\n(part 1)\nN5 G21 G90\nN10 M63 P0 G1 X1 Y0 Z0 F1\nN15 G17 M62 P0 G3 Y2 I1 J1\nN20 M30\n%\n"
        );
    }

    #[test]
    fn comments_mark_chain_and_role_changes() {
        let mut recs = laser_path();
        for (i, r) in recs.iter_mut().enumerate() {
            if let Record::Move(m) = r {
                m.chain = (i > 0).then_some(7);
                m.role = Some(if m.beam { Role::Cut } else { Role::Loop });
            }
        }
        let mut o = opts(Dialect::Pmac);
        o.comments = true;
        let text = write(o.clone(), FeedUnit::MmPerS, &recs[..4]);
        assert!(text.contains("; loop\nRAPID"), "{text}");
        assert!(text.contains("; chain 7 loop\nLINEAR Y5.455"), "{text}");
        assert!(text.contains("; chain 7 cut\nM33==1 Y6.3977"), "{text}");
        o.dialect = Dialect::Iso;
        let text = write(o, FeedUnit::MmPerS, &recs[..3]);
        assert!(text.contains("(chain 7 cut)\nM3 Y6.3977"), "{text}");
    }

    #[test]
    fn rotary_axes_and_tools_are_written_in_both_dialects() {
        let with = |r: Record, abc: [f64; 3], tool: Option<u32>| match r {
            Record::Move(mut m) => {
                m.tool.abc = Some(abc);
                m.tool.number = tool;
                Record::Move(m)
            }
            r => r,
        };
        let recs = [
            with(rapid([0.0, 0.0, 5.0]), [0.0, 0.0, 0.0], Some(2)),
            with(rapid([0.0, 0.0, 5.0]), [90.0, 0.0, 0.0], Some(2)),
            with(line([1.0, 0.0, 5.0], 1.0, true), [90.0, 45.5, 0.0], Some(2)),
            with(line([2.0, 0.0, 5.0], 1.0, true), [90.0, 45.5, 0.0], Some(5)),
        ];
        let iso = write(opts(Dialect::Iso), FeedUnit::MmPerMin, &recs);
        assert!(
            iso.contains("T2 M6\nG0 X0 Y0 Z5 A0 B0 C0\nA90\n") && iso.contains("G1 X1 B45.5 F1\nT5 M6\nX2\n"),
            "{iso}"
        );
        let pmac = write(opts(Dialect::Pmac), FeedUnit::MmPerS, &recs);
        assert!(pmac.contains("RAPID X0 Y0 Z5 A0 B0 C0 P400=1\nA90 P400=2\n"), "{pmac}");
        assert!(!pmac.contains("M6"), "{pmac}");
        // Read back: the same rotary positions and tools.
        let (_, back) = crate::gcode::read_str(
            &iso,
            &crate::gcode::ReadOptions {
                dialect: Some(Dialect::Iso),
                ..Default::default()
            },
        )
        .unwrap();
        let m: Vec<&Motion> = back.iter().filter_map(Record::motion).collect();
        assert_eq!(m.len(), 4);
        for (a, b) in m.iter().zip(&recs) {
            let b = b.motion().unwrap();
            assert_eq!((a.tool.abc, a.tool.number), (b.tool.abc, b.tool.number), "{iso}");
        }
    }

    #[test]
    fn zero_length_moves_stay_moves() {
        let recs = [line([1.0, 2.0, 3.0], 1.0, false), line([1.0, 2.0, 3.00001], 1.0, false)];
        let text = write(opts(Dialect::Pmac), FeedUnit::MmPerS, &recs);
        assert!(text.contains("P400=1\nX1 P400=2\n"), "{text}");
    }

    #[test]
    fn empty_program_is_header_and_trailer() {
        assert_eq!(
            write(opts(Dialect::Pmac), FeedUnit::MmPerS, &[]),
            "OPEN PROG 1 CLEAR\nABS\nINC(R)\nM33=0\nM33=0\nCLOSE\n"
        );
        assert_eq!(
            write(opts(Dialect::Iso), FeedUnit::MmPerS, &[]),
            "G21 G90 G17 G94 G91.1\nM5\nM5\nM30\n"
        );
    }

    #[test]
    fn bad_records_are_errors_and_change_nothing() {
        let bad: Vec<Record> = vec![
            rapid([f64::NAN, 0.0, 0.0]),
            rapid([f64::INFINITY, 0.0, 0.0]),
            rapid([1e300, 0.0, 0.0]),
            line([1.0, 0.0, 0.0], f64::NAN, true),
            line([1.0, 0.0, 0.0], -1.0, true),
            line([1.0, 0.0, 0.0], 1e-9, true),
            arc([1.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], true, Plane::Xy, 0, 1.0, true),
            // centre on the start point
            arc([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], true, Plane::Xy, 0, 1.0, true),
            // end not on the circle
            arc([3.0, 0.0, 0.0], [1.0, 0.0, 0.0], true, Plane::Xy, 0, 1.0, true),
            arc([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], true, Plane::Xy, u32::MAX, 1.0, true),
            Record::Dwell {
                seconds: -1.0,
                block: Some(9),
            },
            Record::Dwell {
                seconds: f64::NAN,
                block: None,
            },
            Record::Spindle {
                rpm: f64::NAN,
                block: None,
            },
            Record::Accel {
                ta_ms: Some(-1.0),
                ts_ms: None,
                block: None,
            },
            Record::Var {
                name: "P1\nCLOSE".into(),
                value: 1.0,
                sync: false,
                block: None,
            },
            Record::Var {
                name: "m33".into(),
                value: 1.0,
                sync: false,
                block: None,
            },
            Record::Var {
                name: "P400".into(),
                value: 1.0,
                sync: false,
                block: None,
            },
            Record::Var {
                name: "P1".into(),
                value: f64::NAN,
                sync: false,
                block: None,
            },
        ];
        for d in [Dialect::Pmac, Dialect::Iso] {
            let mut w = GcodeWriter::new(Vec::new(), opts(d), FeedUnit::MmPerS);
            w.record(&rapid([0.0, 0.0, 0.0])).unwrap();
            let mut refused = 0;
            for r in &bad {
                let before = w.out.len();
                if let Err(e) = w.record(r) {
                    assert!(matches!(e, WriteError::Invalid { .. }), "{e}");
                    assert_eq!(w.out.len(), before, "nothing of a refused record is written: {e}");
                    refused += 1;
                }
            }
            // ISO comments PMAC variables instead of refusing the reserved
            // ones, and has a turn count for any number of turns.
            let expect = if d == Dialect::Pmac { bad.len() } else { bad.len() - 3 };
            assert_eq!(refused, expect, "{d:?}");
            // Still consistent: the next good record follows the last good one.
            w.record(&line([1.0, 0.0, 0.0], 1.0, false)).unwrap();
            let text = String::from_utf8(w.finish().unwrap()).unwrap();
            assert!(
                text.contains(if d == Dialect::Pmac {
                    "LINEAR X1 F1 P400=2\n"
                } else {
                    "M5 G1 X1\n"
                }),
                "{text}"
            );
        }
        let e = GcodeWriter::new(Vec::new(), opts(Dialect::Pmac), FeedUnit::MmPerS)
            .record(&Record::Dwell {
                seconds: -1.0,
                block: Some(9),
            })
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "toolpath record 1 (source line 9): dwell must be zero or more seconds, not -1"
        );
        let mut o = opts(Dialect::Iso);
        o.start = P3::new(f64::NAN, 0.0, 0.0);
        assert!(write_string(o, FeedUnit::MmPerS, &[]).is_err());
    }

    #[test]
    fn iso_variables() {
        let var = |name: &str| Record::Var {
            name: name.into(),
            value: 2.5,
            sync: false,
            block: None,
        };
        let text = write(
            opts(Dialect::Iso),
            FeedUnit::MmPerS,
            &[var("#100"), var("#<depth>"), var("M5")],
        );
        assert!(text.contains("\n#100=2.5\n#<depth>=2.5\n(M5=2.5)\n"), "{text}");
        assert!(write_string(opts(Dialect::Iso), FeedUnit::MmPerS, &[var("#<a)>")]).is_err());
    }
}
