//! The program as pmac-send uploads it: read (either dialect), rewritten
//! by the project's G-code writer into PMAC text, and cut into chunks.
//!
//! A chunk is self-contained: it restates ABS, the centre mode, the shutter
//! closed, TA, the motion mode and the feed (a fresh writer writes them on
//! first use), and ends with the shutter closed. Chunks are cut only where
//! the stage may stop without burning the part: between two moves that both
//! have the beam off. The line counter (`P400`) runs on across chunks, so a
//! counter read back from the controller names one line of the whole job.

use crate::gcode::writer::{GcodeWriter, WriteOptions};
use crate::gcode::{Dialect, ReadOptions, read_str};
use crate::geometry::P3;
use crate::geometry::arc::Arc3;
use crate::model::toolpath::{FeedUnit, MotionKind, Record};
use crate::pmac::controller::{DEFAULT_FEED, DEFAULT_TA_MS, RAPID_MM_S};
use crate::pmac::protocol::line_words;
use serde::Serialize;
use thiserror::Error;

/// Why a program cannot be planned for upload.
#[derive(Debug, Error)]
pub enum PlanError {
    /// The program text does not read as ISO G-code or PMAC text.
    #[error("{0}")]
    Read(#[from] crate::gcode::GcodeError),
    /// Starts "line N: " when the record came from a source line, so the
    /// caller's file name makes it "file:N: ..." (`cli::CliError::in_file`).
    #[error("{}", write_message(.0))]
    Write(#[from] crate::gcode::writer::WriteError),
    #[error(
        "no place to cut within {budget} words after line counter {counter}: the beam stays on for longer than a \
         buffer holds (use rotary mode or a larger buffer)"
    )]
    /// A strict (split-mode) plan found no point where the beam is off
    /// between two moves within `budget` words after the move whose line
    /// counter is `counter`: no buffer of that size can hold the stretch.
    NoCut {
        /// The buffer budget, memory words.
        budget: usize,
        /// Line counter of the last move already planned.
        counter: u64,
    },
    #[error("the program has no moves{}", if *.lines > 0 { format!(" (no motion line in its {lines} lines)") } else { String::new() })]
    /// The program has no motion at all (nothing to upload).
    Empty {
        /// Lines of program text read (0 when a plan came out empty).
        lines: usize,
    },
}

fn write_message(e: &crate::gcode::writer::WriteError) -> String {
    use crate::gcode::writer::WriteError;
    match e {
        WriteError::Invalid {
            record,
            block: Some(line),
            msg,
        } => format!("line {line}: writing PMAC text: toolpath record {record}: {msg}"),
        other => format!("writing PMAC text: {other}"),
    }
}

/// The controller variables the uploaded text uses; the defaults are the
/// laser stage's (`M33` shutter, `P400`..`P402`, `M7400`).
#[derive(Debug, Clone)]
pub struct Names {
    /// The shutter output: 1 opens the beam, 0 closes it. Read from the
    /// program as each move's beam state; every chunk ends closing it
    /// synchronously (`M33==0`).
    pub shutter: String,
    /// The line counter P-variable: the writer numbers motion lines 1, 2, ...
    /// on it, so a value read back names the move the stage is on.
    pub counter: String,
    /// Set to the chunk number at the very end of a buffer chunk, after
    /// `DWELL0` (which stops look-ahead): it changes only once all motion
    /// of the chunk has ended, so it confirms the chunk even after an abort.
    pub done: String,
    /// The M-variable pointed at the counter's P register: the program
    /// assigns it synchronously (`M7400==n` after move n), so the counter
    /// follows motion, not look-ahead.
    pub counter_m: String,
    /// Holds the job's session number, so counters read back are known to
    /// be this job's (a reset zeroes it).
    pub session: String,
}

impl Names {
    /// `M7400->L:$6190`: the counter M-variable pointed at the counter's
    /// P register (Turbo PMAC P-variables live at $6000 + n).
    pub fn counter_definition(&self) -> Option<String> {
        let n: u32 = self.counter.strip_prefix('P')?.parse().ok()?;
        (n < 8192).then(|| format!("{}->L:${:04X}", self.counter_m, 0x6000 + n))
    }
}

impl Default for Names {
    fn default() -> Self {
        Names {
            shutter: "M33".into(),
            counter: "P400".into(),
            done: "P401".into(),
            counter_m: "M7400".into(),
            session: "P402".into(),
        }
    }
}

/// One chunk of the job: the lines one buffer fill (split mode) or one unit
/// of resume (rotary stream) holds. It starts and ends with the beam off and
/// restates every modal setting it relies on, so it runs alone.
#[derive(Debug, Clone, Serialize)]
pub struct Chunk {
    /// Lines to store in a buffer (no OPEN / CLOSE).
    pub lines: Vec<String>,
    /// Memory words the lines take (as `SIZE` counts).
    pub words: usize,
    /// Line counter value of its first motion line (1-based over the job).
    pub first_counter: u64,
    /// Line counter value of its last motion line; the next chunk's
    /// `first_counter` is one more.
    pub last_counter: u64,
    /// Where the stage is when the chunk starts, X Y Z in mm.
    pub start: [f64; 3],
    /// Where the stage is when the chunk's last move ends, X Y Z in mm.
    pub end: [f64; 3],
    /// Estimated run time, s: gsim's Turbo PMAC time model ([`estimate`]).
    pub seconds: f64,
}

/// The program read and ready to cut into chunks: its toolpath records,
/// which are rewritten as PMAC text chunk by chunk.
pub struct UploadPlan {
    /// The program as toolpath records (moves, dwells, TA/TS, ...); holds at
    /// least one move.
    pub records: Vec<Record>,
    /// The unit of the program's F words, from its dialect: mm/min for ISO,
    /// mm/s for PMAC text.
    pub feed_unit: FeedUnit,
    /// The dialect the text was read as (ISO G-code or PMAC).
    pub dialect: Dialect,
    /// The controller variables the chunks use.
    pub names: Names,
}

impl UploadPlan {
    /// Read program text in either dialect, the shutter and line counter
    /// recognised by `names`. A text without a single move is
    /// [`PlanError::Empty`].
    pub fn read(text: &str, names: &Names) -> Result<UploadPlan, PlanError> {
        let opts = ReadOptions {
            shutter_var: names.shutter.clone(),
            line_counter_var: names.counter.clone(),
            ..ReadOptions::default()
        };
        let (dialect, records) = read_str(text, &opts)?;
        if !records.iter().any(|r| matches!(r, Record::Move(_))) {
            return Err(PlanError::Empty {
                lines: text.lines().count(),
            });
        }
        Ok(UploadPlan {
            records,
            feed_unit: dialect.feed_unit(),
            dialect,
            names: names.clone(),
        })
    }

    /// Cut points: record indices `i` (a move) such that the move before
    /// and the move at `i` both have the beam off. Index `records.len()` is
    /// always a cut.
    fn cuts(&self) -> Vec<usize> {
        let mut v = Vec::new();
        let mut prev_beam: Option<bool> = None;
        for (i, r) in self.records.iter().enumerate() {
            if let Record::Move(m) = r {
                if prev_beam == Some(false) && !m.beam {
                    v.push(i);
                }
                prev_beam = Some(m.beam);
            }
        }
        v.push(self.records.len());
        v
    }

    /// Write records `s..e` as a chunk starting at `start`, with TA
    /// restated and counters offset by `counter0`.
    fn write(
        &self,
        s: usize,
        e: usize,
        start: P3,
        ta: Option<(Option<f64>, Option<f64>)>,
        counter0: u64,
    ) -> Result<Chunk, PlanError> {
        let mut opts = WriteOptions::for_dialect(Dialect::Pmac);
        opts.shutter_var = self.names.shutter.clone();
        // `M7400=` + `=n`: the writer's counter word becomes the
        // synchronous `M7400==n`, performed where the next move starts.
        let counter_word = format!("{}=", self.names.counter_m);
        opts.line_counter = Some(counter_word.clone());
        opts.start = start;
        // Synchronous: an immediate close would run at look-ahead time,
        // during the last beam-on move.
        let close = format!("{}==0", self.names.shutter);
        opts.trailer = Some(vec![close.clone()]);
        let mut w = GcodeWriter::new(Vec::new(), opts, self.feed_unit);
        if let Some((ta_ms, ts_ms)) = ta {
            w.record(&Record::Accel {
                ta_ms,
                ts_ms,
                block: None,
            })?;
        }
        for r in &self.records[s..e] {
            w.record(r)?;
        }
        let blocks = w.motion_blocks();
        let end = w.position();
        let out = w.finish()?;
        let text = String::from_utf8_lossy(&out);
        let lines: Vec<String> = text
            .lines()
            .filter(|l| !l.trim_start().to_ascii_uppercase().starts_with("OPEN PROG"))
            .map(|l| offset_counter(l, &counter_word, counter0))
            .map(|l| {
                if l == format!("{}=0", self.names.shutter) {
                    close.clone()
                } else {
                    l
                }
            })
            .collect();
        let words = lines.iter().map(|l| line_words(l)).sum();
        Ok(Chunk {
            lines,
            words,
            first_counter: counter0 + 1,
            last_counter: counter0 + blocks,
            start: [start.x, start.y, start.z],
            end: [end.x, end.y, end.z],
            seconds: estimate(&self.records[s..e], start, self.feed_unit),
        })
    }

    /// Cut the job into chunks of at most `budget` words (`None`: one
    /// chunk with everything).
    pub fn chunks(&self, budget: Option<usize>) -> Result<Vec<Chunk>, PlanError> {
        self.cut(budget, true)
    }

    /// Chunks of about `budget` words for a stream, where a chunk is only
    /// the unit of resume: a beam-on stretch longer than the budget makes
    /// one longer chunk instead of an error.
    pub fn stream_chunks(&self, budget: usize) -> Result<Vec<Chunk>, PlanError> {
        self.cut(Some(budget), false)
    }

    /// The moves as the counter numbers them (move n has counter n).
    pub fn moves(&self) -> Vec<MoveGeom> {
        let mut pos = P3::origin();
        let mut v = Vec::new();
        for r in &self.records {
            if let Record::Move(m) = r {
                let arc = match m.kind {
                    MotionKind::Arc(a) => Some((a.center, a.ccw, a.plane, a.extra_turns)),
                    _ => None,
                };
                v.push(MoveGeom {
                    from: pos,
                    to: m.to,
                    arc,
                    beam: m.beam,
                });
                pos = m.to;
            }
        }
        v
    }

    /// The job from move `next` (1-based) on; with `at`, move `next` runs
    /// only from `at` (a point on it) to its end. Answers the job, where it
    /// starts, the TA in force and the counter before its first move.
    pub fn rest(&self, next: u64, at: Option<P3>) -> Option<Rest> {
        let mut k = 0u64;
        let mut pos = P3::origin();
        let mut ta: Option<(Option<f64>, Option<f64>)> = None;
        let mut from_idx = 0usize;
        for (i, r) in self.records.iter().enumerate() {
            match r {
                Record::Move(m) => {
                    k += 1;
                    if k == next {
                        let (s, start) = match at {
                            Some(p) => (i, p),
                            None => (from_idx, pos),
                        };
                        let job = UploadPlan {
                            records: self.records[s..].to_vec(),
                            feed_unit: self.feed_unit,
                            dialect: self.dialect,
                            names: self.names.clone(),
                        };
                        return Some(Rest {
                            job,
                            start,
                            ta,
                            counter0: next - 1,
                        });
                    }
                    pos = m.to;
                    from_idx = i + 1;
                }
                Record::Accel { ta_ms, ts_ms, .. } if k + 1 < next || at.is_some() => {
                    let (a0, s0) = ta.unwrap_or((None, None));
                    ta = Some((ta_ms.or(a0), ts_ms.or(s0)));
                }
                _ => {}
            }
        }
        None
    }

    fn cut(&self, budget: Option<usize>, strict: bool) -> Result<Vec<Chunk>, PlanError> {
        self.cut_from(budget, strict, P3::origin(), None, 0)
    }

    /// Cut into chunks of at most `budget` words (`None`: one chunk),
    /// starting with the stage at `pos`, TA/TS `ta` (ms) in force and the
    /// line counter at `counter0`, as a resume does with a [`Rest`]. With
    /// `strict`, a beam-on stretch longer than the budget is
    /// [`PlanError::NoCut`]; without, it makes one longer chunk.
    pub fn cut_from(
        &self,
        budget: Option<usize>,
        strict: bool,
        pos: P3,
        ta: Option<(Option<f64>, Option<f64>)>,
        counter0: u64,
    ) -> Result<Vec<Chunk>, PlanError> {
        let cuts = self.cuts();
        let mut out = Vec::new();
        let mut s = 0usize;
        let mut pos = pos;
        let mut ta = ta;
        let mut counter = counter0;
        while s < self.records.len() {
            // Candidate ends: cuts after s. Grow exponentially while the
            // chunk fits, then bisect between the last fit and the first
            // miss: O(m log m) writing per chunk of m records.
            let cand: Vec<usize> = cuts.iter().copied().filter(|&c| c > s).collect();
            let fits = |k: usize| -> Result<Option<Chunk>, PlanError> {
                let c = self.write(s, cand[k], pos, ta, counter)?;
                Ok(match budget {
                    Some(b) if c.words > b => None,
                    _ => Some(c),
                })
            };
            let chosen = if budget.is_none() {
                let k = cand.len() - 1;
                (k, fits(k)?)
            } else {
                let mut lo: Option<(usize, Chunk)> = None;
                let mut hi = cand.len();
                let mut k = 0usize;
                loop {
                    if k >= hi {
                        break;
                    }
                    match fits(k)? {
                        Some(c) => {
                            lo = Some((k, c));
                            if k + 1 >= hi {
                                break;
                            }
                            k = (k * 2 + 1).min(hi - 1);
                        }
                        None => {
                            hi = k;
                            break;
                        }
                    }
                }
                let base = lo.as_ref().map_or(0, |(k, _)| *k + 1);
                let (mut a, mut b) = (base, hi);
                while a < b {
                    let mid = (a + b) / 2;
                    match fits(mid)? {
                        Some(c) => {
                            lo = Some((mid, c));
                            a = mid + 1;
                        }
                        None => b = mid,
                    }
                }
                match lo {
                    Some((k, c)) => (k, Some(c)),
                    None if !strict => (0, Some(self.write(s, cand[0], pos, ta, counter)?)),
                    None => {
                        return Err(PlanError::NoCut {
                            budget: budget.unwrap_or(0),
                            counter,
                        });
                    }
                }
            };
            let (k, Some(chunk)) = chosen else {
                return Err(PlanError::Empty { lines: 0 });
            };
            let e = cand[k];
            for r in &self.records[s..e] {
                match r {
                    Record::Move(m) => pos = m.to,
                    Record::Accel { ta_ms, ts_ms, .. } => {
                        let (a0, s0) = ta.unwrap_or((None, None));
                        ta = Some((ta_ms.or(a0), ts_ms.or(s0)));
                    }
                    _ => {}
                }
            }
            counter = chunk.last_counter;
            out.push(chunk);
            s = e;
        }
        Ok(out)
    }
}

/// A move's geometry, for finding where along the job the stage stopped.
#[derive(Debug, Clone, Copy)]
pub struct MoveGeom {
    /// Where the move starts, mm.
    pub from: P3,
    /// Where the move ends, mm.
    pub to: P3,
    /// For an arc: centre, counter-clockwise, plane, extra turns; `None`
    /// for a line or rapid.
    pub arc: Option<(P3, bool, crate::geometry::Plane, u32)>,
    /// The beam is on during the move.
    pub beam: bool,
}

impl MoveGeom {
    /// Length, mm.
    pub fn length(&self) -> f64 {
        match self.arc3() {
            Some(a) => a.length(),
            None => (self.to - self.from).norm(),
        }
    }

    fn arc3(&self) -> Option<Arc3> {
        let (c, ccw, plane, turns) = self.arc?;
        Arc3::new(c, self.from, self.to, ccw, plane, turns)
    }

    /// The point of the move nearest `p`: (distance from `p`, length along
    /// the move from its start), both mm.
    pub fn project(&self, p: P3) -> (f64, f64) {
        if let Some(a) = self.arc3() {
            if let Some((q, t)) = a.closest_point(&p) {
                return ((q - p).norm(), t * a.length());
            }
            return ((self.to - p).norm(), a.length());
        }
        let d = self.to - self.from;
        let l2 = d.dot(&d);
        let t = if l2 > 0.0 {
            ((p - self.from).dot(&d) / l2).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let q = self.from + d * t;
        ((q - p).norm(), t * l2.sqrt())
    }

    /// The point `s` mm along the move (clamped to the move).
    pub fn point_at(&self, s: f64) -> P3 {
        let len = self.length();
        let t = if len > 0.0 { (s / len).clamp(0.0, 1.0) } else { 1.0 };
        match self.arc3() {
            Some(a) => a.point_at(t),
            None => self.from + (self.to - self.from) * t,
        }
    }
}

/// The rest of a job, from a resume point ([`UploadPlan::rest`]), with
/// what [`UploadPlan::cut_from`] needs to continue it.
pub struct Rest {
    /// The records still to run (the first may be a partial move).
    pub job: UploadPlan,
    /// Where the stage is when the rest starts, mm.
    pub start: P3,
    /// TA and TS (ms) set by the part already run, restated in the first
    /// chunk; `None` when none was set.
    pub ta: Option<(Option<f64>, Option<f64>)>,
    /// The line counter before the rest's first move, so counters go on
    /// numbering moves of the whole job.
    pub counter0: u64,
}

/// Words the completion marker of a buffer chunk takes (with margin).
pub const MARKER_WORDS: usize = 8;

/// The completion marker ending buffer chunk `number` (1-based). Not used
/// in rotary streams: `DWELL0` would stop the stage between chunks.
pub fn marker_lines(done_var: &str, number: usize) -> [String; 2] {
    ["DWELL0".into(), format!("{done_var}={number}")]
}

/// Replace `VAR=n` (the line counter) by `VAR=n+offset` in a line.
pub fn offset_counter(line: &str, var: &str, offset: u64) -> String {
    if offset == 0 {
        return line.to_string();
    }
    let pat = format!("{var}=");
    let mut out = String::with_capacity(line.len() + 4);
    let mut rest = line;
    while let Some(p) = rest.find(&pat) {
        // `P4000=` must not match `P400=`: require a non-digit before.
        let before_ok = p == 0 || !rest.as_bytes()[p - 1].is_ascii_alphanumeric();
        out.push_str(&rest[..p + pat.len()]);
        rest = &rest[p + pat.len()..];
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        if before_ok
            && digits > 0
            && let Ok(n) = rest[..digits].parse::<u64>()
        {
            out.push_str(&(n + offset).to_string());
            rest = &rest[digits..];
        }
    }
    out.push_str(rest);
    out
}

/// Run time (s) of `records` from `start` under gsim's Turbo PMAC time
/// model on the laser stage's profile (TA/TS records in the program apply),
/// so the time left that pmac-send shows is the simulator's prediction. A
/// program the model refuses (outside the profile's travel, say) falls back
/// to a plain sum of max(L/F, TA) per move.
pub fn estimate(records: &[Record], start: P3, unit: FeedUnit) -> f64 {
    use crate::machine::Machine;
    use crate::model::toolpath::Header;
    use crate::sim::beam::CommandTiming;
    use crate::sim::report::Simulator;
    let header = Header {
        feed_unit: unit,
        source: None,
    };
    let Ok(machine) = Machine::load("laser-stage") else {
        return trapezoid_estimate(records, start, unit);
    };
    let mut sim = Simulator::<std::io::Sink>::new(&header, machine, CommandTiming::Sync, start, None);
    if records.iter().all(|r| sim.add(r).is_ok())
        && let Ok((report, _)) = sim.finish()
    {
        return report.time.cycle_time_s;
    }
    trapezoid_estimate(records, start, unit)
}

/// max(L/F, TA) per move: the fallback estimate, the emulator's trapezoid
/// model (rapids at [`RAPID_MM_S`], dwells their time).
fn trapezoid_estimate(records: &[Record], start: P3, unit: FeedUnit) -> f64 {
    let mut pos = start;
    let mut ta = DEFAULT_TA_MS / 1000.0;
    let mut t = 0.0;
    for r in records {
        match r {
            Record::Move(m) => {
                let len = match m.kind {
                    MotionKind::Arc(a) => a.arc(pos, m.to).map_or(0.0, |a| a.length()),
                    _ => (m.to - pos).norm(),
                };
                let v = match m.kind {
                    MotionKind::Rapid => RAPID_MM_S,
                    _ => m
                        .feed
                        .map(|f| unit.convert(f, FeedUnit::MmPerS))
                        .filter(|f| *f > 0.0)
                        .unwrap_or(DEFAULT_FEED),
                };
                t += (len / v).max(ta);
                pos = m.to;
            }
            Record::Dwell { seconds, .. } => t += seconds.max(0.0),
            Record::Accel { ta_ms: Some(a), .. } => ta = a / 1000.0,
            _ => {}
        }
    }
    t
}

#[cfg(test)]
mod tests {
    #[test]
    fn errors_name_the_line() {
        let names = super::Names::default();
        let e = super::UploadPlan::read("; nothing\nM33=0\n", &names).err().unwrap();
        assert_eq!(
            e.to_string(),
            "the program has no moves (no motion line in its 2 lines)"
        );
        let job = super::UploadPlan::read("G21 G90\nG1 X1 F0.0000000001\nG1 X2 F10\n", &names).unwrap();
        let e = job.chunks(None).err().unwrap().to_string();
        assert!(
            e.starts_with("line 2: writing PMAC text: toolpath record 1: feed"),
            "{e}"
        );
    }

    use super::*;

    fn laser() -> UploadPlan {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/testdata/writer/laser.pmac")).unwrap();
        UploadPlan::read(&text, &Names::default()).unwrap()
    }

    #[test]
    fn counter_offset() {
        assert_eq!(offset_counter("LINEAR X1 P400=3", "P400", 10), "LINEAR X1 P400=13");
        assert_eq!(offset_counter("P4000=3 P400=2", "P400", 1), "P4000=3 P400=3");
        assert_eq!(offset_counter("X1", "P400", 1), "X1");
    }

    #[test]
    fn one_chunk_holds_all_and_chunks_cut_with_beam_off() {
        let job = laser();
        let all = job.chunks(None).unwrap();
        assert_eq!(all.len(), 1);
        let n = all[0].last_counter;
        let small = job.chunks(Some(40)).unwrap();
        assert!(small.len() > 1, "{}", small.len());
        let mut next = 1;
        for c in &small {
            assert!(c.words <= 40);
            assert_eq!(c.first_counter, next);
            next = c.last_counter + 1;
            // Closed synchronously: an immediate M33=0 would act at look-ahead,
            // during the last beam-on move.
            assert_eq!(c.lines.last().unwrap(), "M33==0");
            assert!(
                c.lines.iter().any(|l| l.contains(" F") || l.starts_with('F')),
                "{:?}",
                c.lines
            );
        }
        assert_eq!(next - 1, n);
        assert!(matches!(job.chunks(Some(8)), Err(PlanError::NoCut { .. })));
        let stream = job.stream_chunks(8).unwrap();
        assert_eq!(stream.last().unwrap().last_counter, n);
        assert!(stream.len() > small.len());
    }
}
