//! G-code in both dialects, read into and written from the toolpath model.
//!
//! - [`iso`]: ISO/RS274 (LinuxCNC flavour) interpreter.
//! - [`pmac`]: Turbo PMAC motion-program text interpreter.
//! - [`writer`]: toolpath model -> G-code text in either dialect.
//!
//! Reading is streaming: [`ProgramReader`] pulls one source line at a time
//! and yields toolpath records, so memory stays flat on any program size.
//!
//! Every public item here is documented; the lint below keeps it so (with
//! `clippy -D warnings`, an undocumented item fails the build).

#![warn(missing_docs)]

pub mod expr;
pub mod iso;
pub mod oword;
pub mod pmac;
pub mod tooltable;
pub mod writer;

use crate::geometry::{P2, P3, Plane};
use crate::model::toolpath::{ArcData, FeedUnit, Record};
use std::collections::VecDeque;
use std::io::BufRead;
use thiserror::Error;

/// The two G-code dialects we read and write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dialect {
    /// ISO 6983 / RS274-NGC (LinuxCNC, most CNC controls).
    Iso,
    /// Delta Tau Turbo PMAC motion-program text.
    Pmac,
}

impl Dialect {
    /// The name `--dialect` takes and reports print (`iso`, `pmac`).
    pub fn name(self) -> &'static str {
        match self {
            Dialect::Iso => "iso",
            Dialect::Pmac => "pmac",
        }
    }

    /// The feed unit a program of this dialect carries (PMAC: per second
    /// with the default Isx90 = 1000; ISO: per minute in G94).
    pub fn feed_unit(self) -> FeedUnit {
        match self {
            Dialect::Iso => FeedUnit::MmPerMin,
            Dialect::Pmac => FeedUnit::MmPerS,
        }
    }
}

/// A dialect name that is neither `iso` (`rs274`, `ngc`) nor `pmac`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown dialect '{0}' (iso or pmac)")]
pub struct UnknownDialect(pub String);

/// For callers that take a message (`cli::CliError::input`).
impl From<UnknownDialect> for String {
    fn from(e: UnknownDialect) -> String {
        e.to_string()
    }
}

impl std::str::FromStr for Dialect {
    type Err = UnknownDialect;
    fn from_str(s: &str) -> Result<Self, UnknownDialect> {
        match s.to_ascii_lowercase().as_str() {
            "iso" | "rs274" | "ngc" => Ok(Dialect::Iso),
            "pmac" => Ok(Dialect::Pmac),
            _ => Err(UnknownDialect(s.to_string())),
        }
    }
}

/// An error in a G-code program, with the 1-based source line.
#[derive(Debug, Error)]
pub enum GcodeError {
    /// The program is wrong or asks for something the reader does not
    /// support; `msg` says what, in the reader's words.
    #[error("line {line}: {msg}")]
    Invalid {
        /// The 1-based source line.
        line: u64,
        /// What is wrong, without the line number.
        msg: String,
    },
    /// The input could not be read.
    #[error("line {line}: {source}")]
    Io {
        /// The line being read when it failed.
        line: u64,
        /// The read error.
        #[source]
        source: std::io::Error,
    },
}

impl GcodeError {
    /// An error at `line`: a message, or one of the module's error enums.
    pub fn at(line: u64, msg: impl std::fmt::Display) -> Self {
        GcodeError::Invalid {
            line,
            msg: msg.to_string(),
        }
    }

    /// The 1-based source line the error names.
    pub fn line(&self) -> u64 {
        match self {
            GcodeError::Invalid { line, .. } | GcodeError::Io { line, .. } => *line,
        }
    }
}

/// Options shared by both readers.
#[derive(Debug, Clone)]
pub struct ReadOptions {
    /// `None`: detect from the text.
    pub dialect: Option<Dialect>,
    /// The PMAC variable that drives the shutter (`M33`).
    pub shutter_var: String,
    /// The PMAC variable that counts blocks (`P400`); assignments to it are
    /// bookkeeping, not part of the toolpath.
    pub line_counter_var: String,
    /// Where the machine is when the program starts.
    pub start: P3,
    /// LinuxCNC tool table, for cutter radius compensation by D word and
    /// tool changes (ISO programs). `None`: no table.
    pub tool_table: Option<std::sync::Arc<tooltable::ToolTable>>,
    /// Folders searched, in order, for `name.ngc` when an ISO program
    /// calls `o<name>` it does not define (LinuxCNC's SUBROUTINE_PATH).
    pub subroutine_path: Vec<std::path::PathBuf>,
    /// The program's file, when it is one: PMAC `#include` names are
    /// relative to it (to the working directory when `None`).
    pub source_path: Option<std::path::PathBuf>,
    /// PMAC download files: read `OPEN PROG n` for this n; `None` reads
    /// the first motion program in the file.
    pub pmac_program: Option<u32>,
    /// Where a reader leaves remarks on input it accepted without acting
    /// on it (PMAC on-line commands, skipped PLC buffers).
    pub notes: Notes,
    /// Most loop iterations an ISO program may run (`while`, `do`,
    /// `repeat`, all loops together) before reading stops with an error
    /// naming the line: a loop whose condition never changes is a
    /// mistake, not a program. The default, 1,000,000, is far past any
    /// real part program; a caller that reads untrusted text under a
    /// time budget (the fuzz targets) sets it lower.
    pub max_loop_iterations: u64,
}

/// Remarks a reader makes on text it accepted but did not act on, each
/// with its 1-based line; shared by clones, so a tool keeps one handle
/// and prints what the reader left after reading. At most
/// [`Notes::MAX`] are kept (then one saying how many more there were).
#[derive(Debug, Clone, Default)]
pub struct Notes(std::sync::Arc<std::sync::Mutex<NoteList>>);

/// The notes kept (line, text) and how many more were left out.
type NoteList = (Vec<(u64, String)>, u64);

impl Notes {
    /// Notes kept at most; later ones are only counted, so a program of
    /// a million ignored commands cannot fill memory.
    pub const MAX: usize = 1000;

    /// Leave a note on 1-based `line`.
    pub fn push(&self, line: u64, text: impl Into<String>) {
        if let Ok(mut g) = self.0.lock() {
            if g.0.len() < Self::MAX {
                g.0.push((line, text.into()));
            } else {
                g.1 += 1;
            }
        }
    }

    /// The notes so far (emptied), the last one counting any left out.
    pub fn take(&self) -> Vec<(u64, String)> {
        let Ok(mut g) = self.0.lock() else {
            return Vec::new();
        };
        let mut v = std::mem::take(&mut g.0);
        // In line order (a reader may leave a note on a held line late).
        v.sort_by_key(|n| n.0);
        let more = std::mem::take(&mut g.1);
        if more > 0 {
            let line = v.last().map_or(0, |n| n.0);
            v.push((line, format!("{more} more notes not shown")));
        }
        v
    }
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            dialect: None,
            shutter_var: "M33".into(),
            line_counter_var: "P400".into(),
            start: P3::origin(),
            tool_table: None,
            subroutine_path: Vec::new(),
            source_path: None,
            pmac_program: None,
            notes: Notes::default(),
            max_loop_iterations: DEFAULT_MAX_LOOP_ITERATIONS,
        }
    }
}

/// [`ReadOptions::max_loop_iterations`] unless a caller sets it.
pub const DEFAULT_MAX_LOOP_ITERATIONS: u64 = 1_000_000;

/// A dialect's interpreter, fed one source line at a time.
pub trait LineInterpreter {
    /// Interpret one line (without its newline), pushing any records. The
    /// line is raw bytes: a reader checks the characters it cares about
    /// itself, so the common all-ASCII line is not validated twice.
    fn line(&mut self, text: &[u8], lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError>;
    /// End of input: check the program is complete.
    fn finish(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError>;
    /// True once the program has ended (M2/M30, `%` after a `%`); later
    /// lines are not read.
    fn ended(&self) -> bool;
}

/// Guess the dialect from the first lines of a program: any PMAC-only
/// evidence (motion-mode words, buffer commands, a bare variable assignment
/// such as `M33=1`) means PMAC, otherwise ISO. Lines that both dialects
/// share (`G90`, `N10`, `X1 Y2`) decide nothing, so a PMAC program that
/// starts with `G90` (a PROG 1000 call) is still recognised.
pub fn detect_dialect<'a>(lines: impl IntoIterator<Item = &'a str>) -> Dialect {
    const PMAC_WORDS: [&str; 14] = [
        "OPENPROG",
        "OPENROT",
        "LINEAR",
        "RAPID",
        "CIRCLE1",
        "CIRCLE2",
        "CLOSE",
        "DWELL",
        "NORMAL",
        "ABS(",
        "INC(",
        "&1",
        "DELAY",
        "DELETEGATHER",
    ];
    for l in lines {
        let code = strip_comments_for_detect(l).to_ascii_uppercase();
        let compact: String = code.chars().filter(|c| !c.is_whitespace()).collect();
        if compact.is_empty() {
            continue;
        }
        // Skip a leading N label, which both dialects allow.
        let body = match compact.strip_prefix('N') {
            Some(rest) => rest.trim_start_matches(|c: char| c.is_ascii_digit()),
            None => compact.as_str(),
        };
        if PMAC_WORDS.iter().any(|w| body.contains(w)) {
            return Dialect::Pmac;
        }
        // A variable assignment such as M33=1 or P400=7 without a leading
        // '#' is PMAC; ISO parameters are '#'.
        let b = body.as_bytes();
        if b.len() > 2
            && matches!(b[0], b'M' | b'P' | b'Q' | b'I')
            && b[1].is_ascii_digit()
            && body
                .find('=')
                .is_some_and(|eq| body[1..eq].chars().all(|c| c.is_ascii_digit()))
        {
            return Dialect::Pmac;
        }
    }
    Dialect::Iso
}

/// The line without `;` comments and without ISO `( )` comments, so a
/// comment that mentions a PMAC word decides nothing. (PMAC uses `(` for
/// expressions, but never at the start of a motion word.)
fn strip_comments_for_detect(l: &str) -> String {
    let l = l.split(';').next().unwrap_or("");
    let mut out = String::with_capacity(l.len());
    let mut depth = 0u32;
    for c in l.chars() {
        match c {
            '(' if depth > 0 || out.trim_end().ends_with(|c: char| c.is_ascii_alphabetic()) => {
                // ABS( / INC( / X( : PMAC expressions, keep
                if depth == 0 {
                    out.push(c);
                } else {
                    depth += 1;
                }
            }
            '(' => depth += 1,
            ')' if depth > 0 => depth -= 1,
            _ if depth > 0 => {}
            _ => out.push(c),
        }
    }
    out
}

/// True when an arc whose start and end lie `r0` and `r1` mm from its
/// centre is one a reader accepts: within the model's arc end tolerance, or
/// a spiral within what LinuxCNC accepts from an inch or a millimetre
/// program (the ISO reader keeps such arcs as written). Readers of the
/// toolpath model use this, so what `gsim --moves` writes reads back.
pub fn arc_radii_accepted(r0: f64, r1: f64) -> bool {
    (r0 - r1).abs() <= crate::model::toolpath::arc_end_tolerance(r0.max(r1)) || iso::spiral_accepted(r0, r1)
}

/// Build arc data from an in-plane centre, checking that the radius is
/// not zero and that the start and end lie on one circle as far as
/// [`arc_radii_accepted`] asks. A Turbo PMAC runs any I/J/K arc whose end is
/// off the circle as a spiral (the radius changes evenly over the move),
/// and so does the model's arc ([`crate::geometry::arc::ArcFrame`] blends
/// the radii): a program printed with 2 or 3 decimals, whose rounded centre
/// misses the rounded end by a micrometre or more, is read as the controller
/// runs it. A larger miss is a wrong centre, the usual writer bug, and an
/// error naming the line.
pub(crate) fn make_arc(
    start: &P3,
    end: &P3,
    center: P2,
    ccw: bool,
    plane: Plane,
    extra_turns: u32,
    lineno: u64,
) -> Result<ArcData, GcodeError> {
    let s = plane.project(start);
    let e = plane.project(end);
    let r0 = (s - center).norm();
    let r1 = (e - center).norm();
    if r0 < 1e-12 || r1 < 1e-12 {
        return Err(GcodeError::at(
            lineno,
            "arc of zero radius (the centre is on its start or end point)",
        ));
    }
    if !arc_radii_accepted(r0, r1) {
        return Err(GcodeError::at(
            lineno,
            format!(
                "arc end is not on the circle: radius to start {r0:.6} mm, to end {r1:.6} mm (difference {:.6} mm)",
                (r0 - r1).abs()
            ),
        ));
    }
    Ok(ArcData {
        center: plane.lift(&center, plane.normal_coord(start)),
        ccw,
        plane,
        extra_turns,
    })
}

/// Streaming program reader: yields toolpath records from G-code text.
pub struct ProgramReader<R> {
    input: R,
    interp: Box<dyn LineInterpreter>,
    dialect: Dialect,
    /// Lines read ahead for dialect detection, replayed first.
    replay: VecDeque<Vec<u8>>,
    pending: VecDeque<Record>,
    buf: Vec<u8>,
    lineno: u64,
    done: bool,
}

impl<R: BufRead> ProgramReader<R> {
    /// A reader of `input` with `opts`. Unless `opts.dialect` names one,
    /// the first 200 lines are read ahead to detect the dialect (and
    /// replayed); an I/O error there is returned with its line.
    pub fn new(mut input: R, opts: &ReadOptions) -> Result<Self, GcodeError> {
        let mut replay = VecDeque::new();
        let dialect = match opts.dialect {
            Some(d) => d,
            None => {
                // Look at the first 200 lines, or fewer if the file is short.
                let mut buf = Vec::new();
                for n in 1..=200u64 {
                    buf.clear();
                    let k = crate::cli::read_line_any_ending(&mut input, &mut buf)
                        .map_err(|e| GcodeError::Io { line: n, source: e })?;
                    if k == 0 {
                        break;
                    }
                    replay.push_back(std::mem::take(&mut buf));
                }
                let text: Vec<std::borrow::Cow<str>> = replay.iter().map(|l| String::from_utf8_lossy(l)).collect();
                detect_dialect(text.iter().map(|s| s.as_ref()))
            }
        };
        let interp: Box<dyn LineInterpreter> = match dialect {
            Dialect::Iso => Box::new(iso::IsoInterpreter::new(opts)),
            Dialect::Pmac => Box::new(pmac::PmacInterpreter::new(opts)),
        };
        Ok(ProgramReader {
            input,
            interp,
            dialect,
            replay,
            pending: VecDeque::new(),
            buf: Vec::new(),
            lineno: 0,
            done: false,
        })
    }

    /// The dialect being read (given or detected).
    pub fn dialect(&self) -> Dialect {
        self.dialect
    }

    fn fill(&mut self) -> Result<(), GcodeError> {
        while self.pending.is_empty() && !self.done {
            if self.interp.ended() {
                self.done = true;
                break;
            }
            self.lineno += 1;
            let line = if let Some(l) = self.replay.pop_front() {
                self.buf = l;
                true
            } else {
                self.buf.clear();
                let n =
                    crate::cli::read_line_any_ending(&mut self.input, &mut self.buf).map_err(|e| GcodeError::Io {
                        line: self.lineno,
                        source: e,
                    })?;
                n > 0
            };
            if !line {
                self.done = true;
                let before = self.pending.len();
                self.interp.finish(self.lineno - 1, &mut self.pending)?;
                check_records(&self.pending, before, self.lineno - 1)?;
                break;
            }
            let mut text = self.buf.as_slice();
            while let [rest @ .., b'\n' | b'\r'] = text {
                text = rest;
            }
            let before = self.pending.len();
            self.interp.line(text, self.lineno, &mut self.pending)?;
            check_records(&self.pending, before, self.lineno)?;
        }
        Ok(())
    }
}

/// No record leaves a reader with a number that overflowed or that no
/// machine can mean (see [`Record::check_numbers`]); the error names the
/// record's own line (compensation emits a move a line late).
fn check_records(pending: &VecDeque<Record>, from: usize, lineno: u64) -> Result<(), GcodeError> {
    for r in pending.range(from..) {
        r.check_numbers()
            .map_err(|m| GcodeError::at(r.block().unwrap_or(lineno), m))?;
    }
    Ok(())
}

impl<R: BufRead> Iterator for ProgramReader<R> {
    type Item = Result<Record, GcodeError>;
    fn next(&mut self) -> Option<Self::Item> {
        if let Err(e) = self.fill() {
            self.done = true;
            self.pending.clear();
            return Some(Err(e));
        }
        self.pending.pop_front().map(Ok)
    }
}

impl<R: BufRead> ProgramReader<R> {
    /// Append up to `max` records to `out`, interpreting lines as needed;
    /// fewer only at the end of the program. The same records and errors as
    /// the iterator, without handing each record through it: a record is a
    /// few hundred bytes, and passing a million of them one by one through
    /// the iterator adapters of a consumer cost about a sixth of the
    /// interpreting thread's time (gsim --moves, scripts/bench/interp).
    pub fn next_batch(&mut self, out: &mut Vec<Record>, max: usize) -> Result<(), GcodeError> {
        while out.len() < max {
            if let Err(e) = self.fill() {
                self.done = true;
                self.pending.clear();
                return Err(e);
            }
            if self.pending.is_empty() {
                break;
            }
            let take = (max - out.len()).min(self.pending.len());
            out.extend(self.pending.drain(..take));
        }
        Ok(())
    }
}

#[cfg(test)]
mod batch_tests {
    use super::*;

    fn program(n: usize, bad_line: Option<usize>) -> String {
        let mut s = String::from("G21 G90 F600\n");
        let mut x = 0;
        for i in 0..n {
            if Some(i) == bad_line {
                s.push_str("G1 X1 Q\n");
            } else if i % 5 == 0 {
                // A half circle to the right: its end is on the circle.
                x += 1;
                s.push_str(&format!("G2 X{x} I0.5 J0\n"));
            } else {
                s.push_str(&format!("G1 Y{}\n", i % 7));
            }
        }
        s
    }

    /// `next_batch` yields the iterator's records in the iterator's order,
    /// in batches of exactly `max` until the last, and the same error.
    #[test]
    fn batches_equal_the_iterator() {
        let opts = ReadOptions::default();
        for (n, bad) in [(0, None), (1, None), (999, None), (5000, None), (5000, Some(3210))] {
            let text = program(n, bad);
            let want: Vec<Result<Record, String>> = ProgramReader::new(text.as_bytes(), &opts)
                .unwrap()
                .map(|r| r.map_err(|e| e.to_string()))
                .collect();
            let mut r = ProgramReader::new(text.as_bytes(), &opts).unwrap();
            let mut got: Vec<Result<Record, String>> = Vec::new();
            loop {
                let mut batch = Vec::new();
                match r.next_batch(&mut batch, 1000) {
                    Ok(()) => {
                        let full = batch.len() == 1000;
                        got.extend(batch.into_iter().map(Ok));
                        if !full {
                            break;
                        }
                    }
                    Err(e) => {
                        // The records of lines before the failing one come
                        // first, as from the iterator.
                        got.extend(batch.into_iter().map(Ok));
                        got.push(Err(e.to_string()));
                        break;
                    }
                }
            }
            assert_eq!(got, want, "{n} lines, bad line {bad:?}");
            if bad.is_some() {
                assert!(
                    matches!(want.last(), Some(Err(m)) if m.contains("line 3212")),
                    "{:?}",
                    want.last()
                );
            }
        }
    }
}

/// Read a whole program from a string (tests, small programs).
pub fn read_str(text: &str, opts: &ReadOptions) -> Result<(Dialect, Vec<Record>), GcodeError> {
    let r = ProgramReader::new(text.as_bytes(), opts)?;
    let d = r.dialect();
    Ok((d, r.collect::<Result<Vec<_>, _>>()?))
}

#[cfg(test)]
mod detect_tests {
    use super::*;

    #[test]
    fn dialects_are_told_apart_by_evidence_not_by_the_first_line() {
        let cases: [(&str, Dialect); 9] = [
            ("G90\nLINEAR X1 F2\n", Dialect::Pmac),
            ("N10 G90\nN20 M33=1\n", Dialect::Pmac),
            ("OPEN PROG 1 CLEAR\nX1\nCLOSE\n", Dialect::Pmac),
            ("ABS(X,Y)\nX1\n", Dialect::Pmac),
            ("G21 G90\nG1 X1 F100 (LINEAR move)\n", Dialect::Iso),
            ("(RAPID to start)\nG0 X1\n", Dialect::Iso),
            ("#1=2\nG0 X#1\n", Dialect::Iso),
            ("G0 X[ABS[-1]]\n", Dialect::Iso),
            ("", Dialect::Iso),
        ];
        for (text, want) in cases {
            assert_eq!(detect_dialect(text.lines()), want, "{text:?}");
        }
    }
}
