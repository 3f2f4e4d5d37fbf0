//! The emulated Turbo PMAC: memory, program and rotary buffers, one
//! coordinate system with three axes, I/P/M/Q variables, and program
//! execution in simulated time.
//!
//! Buffered program lines are executed by the project's PMAC interpreter
//! ([`crate::gcode::pmac::PmacInterpreter`]), so the emulator moves exactly
//! as `gsim` reads a program. Time is simulated: a move lasts
//! `max(length / F, TA)` (rapids at [`RAPID_MM_S`]), dwells their time.
//! The clock is read on every command, and everything due by then is
//! executed; a move is logged when its motion starts.
//!
//! Every executed move, variable change, run start, end, abort and idle
//! gap goes to the event log (JSON Lines) so tests can check what the
//! stage and shutter did without trusting the client.

use crate::gcode::pmac::PmacInterpreter;
use crate::gcode::{LineInterpreter, ReadOptions};
use crate::geometry::P3;
use crate::geometry::arc::Arc3;
use crate::model::toolpath::{MotionKind, Record};
use crate::pmac::protocol::line_words;
use std::collections::{BTreeMap, VecDeque};
use std::io::Write;
use std::time::Instant;

/// Speed of RAPID moves, mm/s (Ixx16 on a real controller).
pub const RAPID_MM_S: f64 = 50.0;
/// Feed before the program sets one, mm/s (Isx89).
pub const DEFAULT_FEED: f64 = 10.0;
/// Acceleration time before the program sets one, ms (Isx87).
pub const DEFAULT_TA_MS: f64 = 10.0;
/// Variables per letter (0..=8191, as on a Turbo PMAC).
const VARS: usize = 8192;

/// The ERR numbers the emulator answers (Turbo PMAC Software Reference, "Error codes"; docs/pmac-send.md).
pub mod err {
    pub const RUNNING: u16 = 1;
    pub const DATA: u16 = 3;
    pub const NEEDS_OPEN_BUFFER: u16 = 5;
    pub const NO_ROOM: u16 = 6;
    pub const IN_USE: u16 = 7;
    pub const NO_MOTORS: u16 = 14;
    pub const BAD_POINTER: u16 = 15;
}

/// Where simulated time comes from.
#[derive(Debug, Clone, Copy)]
pub enum Clock {
    /// Real time since `t0` times `scale` (simulated s per real s).
    Scaled { t0: Instant, scale: f64 },
    /// Set by hand ([`Controller::set_time`]); unit tests.
    Manual(f64),
}

impl Clock {
    pub fn scaled(scale: f64) -> Clock {
        Clock::Scaled {
            t0: Instant::now(),
            scale: if scale.is_finite() && scale > 0.0 { scale } else { 1.0 },
        }
    }

    fn now(&self) -> f64 {
        match *self {
            Clock::Scaled { t0, scale } => t0.elapsed().as_secs_f64() * scale,
            Clock::Manual(t) => t,
        }
    }
}

/// Emulator settings.
#[derive(Debug, Clone)]
pub struct Config {
    /// User memory for buffers, long words.
    pub memory_words: i64,
    /// Words a gather buffer holds at power-on (it eats memory until
    /// `DELETE GATHER`, as on a controller left with one defined).
    pub gather_words: i64,
    /// Answer ERR006 to the Nth program line stored (1-based), once.
    pub err006_at_line: Option<u64>,
    /// The shutter variable whose value follows the moves' beam state.
    pub shutter_var: String,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            memory_words: 65_536,
            gather_words: 0,
            err006_at_line: None,
            shutter_var: "M33".into(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Open {
    Prog(u32),
    Rot,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pointer {
    Prog(u32),
    Rot,
}

#[derive(Debug, Default)]
struct Program {
    lines: Vec<String>,
    words: i64,
}

struct QueuedLine {
    text: String,
    words: i64,
    arrival: f64,
}

struct Rotary {
    capacity: i64,
    used: i64,
    lines: VecDeque<QueuedLine>,
}

enum Source {
    Prog { n: u32, next: usize },
    Rot,
}

struct Run {
    id: u64,
    source: Source,
    interp: PmacInterpreter,
    pending: VecDeque<Record>,
    lineno: u64,
    moved: bool,
    /// `Q` given: stop when the current line's moves are done.
    quit: bool,
}

/// The controller state. Wrap it in a mutex to share between connections.
pub struct Controller {
    cfg: Config,
    clock: Clock,
    log: Option<Box<dyn Write + Send>>,
    programs: BTreeMap<u32, Program>,
    rotary: Option<Rotary>,
    gather: i64,
    pointer: Option<Pointer>,
    run: Option<Run>,
    runs: u64,
    /// Simulated time when the stage finishes what it has been given.
    t_free: f64,
    pos: P3,
    ta_ms: f64,
    vars: [Vec<f64>; 4],
    lines_stored: u64,
    /// Synchronous assignments (`==`) waiting for the next move.
    sync_vars: Vec<(u8, usize, f64)>,
    /// Resets so far (see [`Session`]).
    epoch: u64,
}

fn var_index(letter: u8) -> Option<usize> {
    match letter.to_ascii_uppercase() {
        b'I' => Some(0),
        b'P' => Some(1),
        b'Q' => Some(2),
        b'M' => Some(3),
        _ => None,
    }
}

/// Format a variable value as the controller prints it.
pub fn fmt_value(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{}", v as i64)
    } else {
        format!("{v}")
    }
}

/// The status words of `&1??`: word 1 bit 0 running, word 2 bit 17 in
/// position.
pub fn status_word(running: bool, in_position: bool) -> String {
    let w1: u32 = u32::from(running);
    let w2: u32 = if in_position { 1 << 17 } else { 0 };
    format!("{w1:06X}{w2:06X}{:06X}", 0)
}

/// Decode `&1??` text into (running, in position); `None` if malformed.
pub fn parse_status(s: &str) -> Option<(bool, bool)> {
    let s = s.trim();
    if s.len() != 18 || !s.is_ascii() {
        return None;
    }
    let w1 = u32::from_str_radix(&s[0..6], 16).ok()?;
    let w2 = u32::from_str_radix(&s[6..12], 16).ok()?;
    Some((w1 & 1 != 0, w2 & (1 << 17) != 0))
}

/// What `command_line` needs from the connection: the addressed
/// coordinate system persists per connection, as per port on a controller.
#[derive(Debug, Clone)]
pub struct Session {
    pub cs: u32,
    /// The buffer this port has open: each port of a Turbo PMAC has its
    /// own, so a second connection (a safety stop) is not caught in a
    /// buffer another one left open.
    open: Option<Open>,
    /// The controller's reset count when this session last spoke: a reset
    /// closes every port's buffer.
    epoch: u64,
}

impl Default for Session {
    fn default() -> Self {
        Session {
            cs: 1,
            open: None,
            epoch: 0,
        }
    }
}

/// A tiny cursor over an upper-cased command line.
struct Cur<'a> {
    b: &'a [u8],
    i: usize,
}

impl<'a> Cur<'a> {
    fn ws(&mut self) {
        while self.i < self.b.len() && self.b[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }
    fn done(&mut self) -> bool {
        self.ws();
        self.i >= self.b.len()
    }
    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }
    /// Consume `word` if it comes next (spaces inside commands optional).
    fn kw(&mut self, word: &str) -> bool {
        let save = self.i;
        self.ws();
        for &c in word.as_bytes() {
            if c == b' ' {
                self.ws();
                continue;
            }
            if self.peek() != Some(c) {
                self.i = save;
                return false;
            }
            self.i += 1;
        }
        true
    }
    fn int(&mut self) -> Option<u32> {
        self.ws();
        let s = self.i;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.i += 1;
        }
        std::str::from_utf8(&self.b[s..self.i]).ok()?.parse().ok()
    }
    fn number(&mut self) -> Option<f64> {
        self.ws();
        if self.peek() == Some(b'$') {
            self.i += 1;
            let s = self.i;
            while self.peek().is_some_and(|c| c.is_ascii_hexdigit()) {
                self.i += 1;
            }
            return i64::from_str_radix(std::str::from_utf8(&self.b[s..self.i]).ok()?, 16)
                .ok()
                .map(|v| v as f64);
        }
        let s = self.i;
        if matches!(self.peek(), Some(b'-' | b'+')) {
            self.i += 1;
        }
        while self.peek().is_some_and(|c| c.is_ascii_digit() || c == b'.') {
            self.i += 1;
        }
        let v: f64 = std::str::from_utf8(&self.b[s..self.i]).ok()?.parse().ok()?;
        v.is_finite().then_some(v)
    }
}

/// Words that only make sense inside a program buffer.
const PROGRAM_WORDS: &[&str] = &[
    "LINEAR", "LIN", "RAPID", "RPD", "CIRCLE", "CIR", "DWELL", "DELAY", "ABS", "INC", "NORMAL", "TA", "TS", "TM", "F",
    "X", "Y", "Z",
];

impl Controller {
    pub fn new(cfg: Config, clock: Clock, log: Option<Box<dyn Write + Send>>) -> Self {
        let gather = cfg.gather_words.max(0);
        Controller {
            cfg,
            clock,
            log,
            programs: BTreeMap::new(),
            rotary: None,
            gather,
            pointer: None,
            run: None,
            runs: 0,
            t_free: 0.0,
            pos: P3::origin(),
            ta_ms: DEFAULT_TA_MS,
            vars: [vec![0.0; VARS], vec![0.0; VARS], vec![0.0; VARS], vec![0.0; VARS]],
            lines_stored: 0,
            sync_vars: Vec::new(),
            epoch: 0,
        }
    }

    /// Set the manual clock (no effect on a scaled clock).
    pub fn set_time(&mut self, t: f64) {
        if let Clock::Manual(old) = &mut self.clock {
            *old = t.max(*old);
        }
    }

    pub fn now(&self) -> f64 {
        self.clock.now()
    }

    pub fn running(&self) -> bool {
        self.run.is_some()
    }

    pub fn in_position(&self) -> bool {
        self.now() >= self.t_free
    }

    pub fn var(&self, letter: u8, n: usize) -> f64 {
        var_index(letter)
            .and_then(|k| self.vars[k].get(n))
            .copied()
            .unwrap_or(0.0)
    }

    fn free_words(&self) -> i64 {
        let progs: i64 = self.programs.values().map(|p| p.words).sum();
        let rot = self.rotary.as_ref().map_or(0, |r| r.capacity);
        self.cfg.memory_words - progs - rot - self.gather
    }

    fn event(&mut self, json: serde_json::Value) {
        if let Some(w) = self.log.as_mut() {
            // A log write failure must not take the controller down; the
            // test reading the log will see the gap.
            let _ = writeln!(w, "{json}");
            let _ = w.flush();
        }
    }

    fn set_var(&mut self, letter: u8, n: usize, value: f64, t: f64) {
        let Some(k) = var_index(letter) else { return };
        let Some(slot) = self.vars[k].get_mut(n) else { return };
        if *slot != value {
            *slot = value;
            let name = format!("{}{n}", letter.to_ascii_uppercase() as char);
            let run = self.run.as_ref().map(|r| r.id);
            self.event(serde_json::json!({"ev": "var", "t": t, "run": run, "name": name, "value": value}));
        }
    }

    fn shutter(&self) -> Option<(u8, usize)> {
        let s = self.cfg.shutter_var.as_bytes();
        let letter = *s.first()?;
        var_index(letter)?;
        let n = std::str::from_utf8(&s[1..]).ok()?.parse().ok()?;
        Some((letter, n))
    }

    /// Reset as at power-on with nothing saved: buffers, variables and
    /// motion are gone.
    pub fn reset(&mut self) {
        let now = self.now();
        if let Some(r) = self.run.take() {
            self.event(serde_json::json!({"ev": "abort", "t": now, "run": r.id, "why": "reset"}));
        }
        self.event(serde_json::json!({"ev": "reset", "t": now}));
        self.programs.clear();
        self.rotary = None;
        self.gather = self.cfg.gather_words.max(0);
        self.pointer = None;
        self.t_free = self.t_free.min(now);
        self.ta_ms = DEFAULT_TA_MS;
        self.sync_vars.clear();
        self.epoch += 1;
        for v in &mut self.vars {
            v.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// Execute everything due by the current simulated time.
    pub fn advance(&mut self) {
        let now = self.now();
        // Each pass consumes a record or a line, or stops: bounded by the
        // work queued, but guard anyway against a runaway.
        for _ in 0..10_000_000u32 {
            let Some(run) = self.run.as_mut() else { return };
            if run.pending.is_empty() {
                if run.quit && run.lineno > 0 {
                    self.finish_run("done");
                    return;
                }
                let text = match &mut run.source {
                    Source::Prog { n, next } => match self.programs.get(n).and_then(|p| p.lines.get(*next)) {
                        Some(l) => {
                            *next += 1;
                            l.clone()
                        }
                        None => {
                            self.finish_run("done");
                            return;
                        }
                    },
                    Source::Rot => {
                        if self.t_free > now {
                            return; // calculate only when the stage needs it
                        }
                        let Some(q) = self.rotary.as_mut().and_then(|r| r.lines.pop_front()) else {
                            return; // a dry rotary buffer waits
                        };
                        if let Some(r) = self.rotary.as_mut() {
                            r.used -= q.words;
                        }
                        if q.arrival > self.t_free {
                            if run.moved {
                                let (id, from, to) = (run.id, self.t_free, q.arrival);
                                self.event(serde_json::json!({"ev": "idle", "t": from, "run": id, "until": to}));
                            }
                            self.t_free = q.arrival;
                        }
                        q.text
                    }
                };
                let Some(run) = self.run.as_mut() else { return };
                run.lineno += 1;
                let lineno = run.lineno;
                if let Err(e) = run.interp.line(text.as_bytes(), lineno, &mut run.pending) {
                    let id = run.id;
                    let t = self.t_free;
                    self.event(serde_json::json!({"ev": "error", "t": t, "run": id, "msg": e.to_string()}));
                    self.run = None;
                    return;
                }
                continue;
            }
            if self.t_free > now {
                return;
            }
            let Some(rec) = run.pending.pop_front() else { continue };
            let id = run.id;
            self.execute(id, rec);
        }
    }

    fn execute(&mut self, id: u64, rec: Record) {
        let t = self.t_free;
        match rec {
            Record::Move(m) => {
                // `M33==1` takes effect as this move's motion starts.
                for (l, n, v) in std::mem::take(&mut self.sync_vars) {
                    self.set_var(l, n, v, t);
                }
                let beam = self.shutter().is_some_and(|(l, n)| self.var(l, n) != 0.0);
                let (len, kind) = match m.kind {
                    MotionKind::Rapid => ((m.to - self.pos).norm(), "rapid"),
                    MotionKind::Line => ((m.to - self.pos).norm(), "line"),
                    MotionKind::Arc(a) => (
                        Arc3::new(a.center, self.pos, m.to, a.ccw, a.plane, a.extra_turns).map_or(0.0, |a| a.length()),
                        "arc",
                    ),
                };
                let speed = match m.kind {
                    MotionKind::Rapid => RAPID_MM_S,
                    _ => m.feed.filter(|f| *f > 0.0 && f.is_finite()).unwrap_or(DEFAULT_FEED),
                };
                let d = (len / speed).max(self.ta_ms / 1000.0);
                self.event(serde_json::json!({
                    "ev": "move", "t": t, "run": id, "kind": kind,
                    "x": m.to.x, "y": m.to.y, "z": m.to.z, "beam": beam, "feed": m.feed, "dur": d,
                }));
                self.pos = m.to;
                self.t_free = t + d;
                if let Some(r) = self.run.as_mut() {
                    r.moved = true;
                }
            }
            Record::Dwell { seconds, .. } => {
                let s = if seconds.is_finite() { seconds.max(0.0) } else { 0.0 };
                self.event(serde_json::json!({"ev": "dwell", "t": t, "run": id, "s": s}));
                self.t_free = t + s;
            }
            Record::Accel { ta_ms, .. } => {
                if let Some(ta) = ta_ms.filter(|v| v.is_finite() && *v >= 0.0) {
                    self.ta_ms = ta;
                }
            }
            Record::Var { name, value, sync, .. } => {
                let b = name.as_bytes();
                if let (Some(&l), Ok(n)) = (b.first(), name.get(1..).unwrap_or("").parse::<usize>()) {
                    if sync {
                        self.sync_vars.push((l, n, value));
                    } else {
                        self.set_var(l, n, value, t);
                    }
                }
            }
            Record::Spindle { .. } => {}
        }
    }

    fn finish_run(&mut self, how: &str) {
        if let Some(r) = self.run.take() {
            let t = self.t_free;
            self.event(serde_json::json!({"ev": how, "t": t, "run": r.id}));
        }
    }

    fn start_run(&mut self, p: Pointer) -> Result<(), u16> {
        let source = match p {
            Pointer::Prog(n) => {
                if !self.programs.contains_key(&n) {
                    return Err(err::BAD_POINTER);
                }
                Source::Prog { n, next: 0 }
            }
            Pointer::Rot => {
                if self.rotary.is_none() {
                    return Err(err::BAD_POINTER);
                }
                Source::Rot
            }
        };
        let opts = ReadOptions {
            dialect: Some(crate::gcode::Dialect::Pmac),
            // The interpreter folds its shutter and counter variables into
            // the moves; here every assignment must reach the variables
            // (P400 advances, M33 toggles, `==` waits for the next move),
            // so give it variables no program uses.
            shutter_var: "Q8190".into(),
            line_counter_var: "Q8191".into(),
            start: self.pos,
            tool_table: None,
            subroutine_path: Vec::new(),
        };
        self.runs += 1;
        let id = self.runs;
        let now = self.now();
        self.t_free = self.t_free.max(now);
        let prog = match p {
            Pointer::Prog(n) => serde_json::json!(n),
            Pointer::Rot => serde_json::json!("rot"),
        };
        let t = self.t_free;
        self.event(serde_json::json!({"ev": "run", "t": t, "run": id, "prog": prog}));
        self.run = Some(Run {
            id,
            source,
            interp: PmacInterpreter::new(&opts),
            pending: VecDeque::new(),
            lineno: 0,
            moved: false,
            quit: false,
        });
        Ok(())
    }

    fn abort(&mut self) {
        let now = self.now();
        if let Some(r) = self.run.take() {
            self.event(serde_json::json!({"ev": "abort", "t": now, "run": r.id}));
        }
        // Motion stops where it is (decelerating within TA; ignored).
        self.t_free = self.t_free.min(now);
        self.sync_vars.clear();
    }

    /// Store one program line into the open buffer.
    fn store(&mut self, open: Option<Open>, text: &str) -> Result<(), u16> {
        let words = line_words(text) as i64;
        self.lines_stored += 1;
        if self.cfg.err006_at_line == Some(self.lines_stored) {
            self.cfg.err006_at_line = None;
            return Err(err::NO_ROOM);
        }
        let now = self.now();
        match open {
            Some(Open::Prog(n)) => {
                if self.free_words() < words {
                    return Err(err::NO_ROOM);
                }
                let p = self.programs.entry(n).or_default();
                p.lines.push(text.to_string());
                p.words += words;
                Ok(())
            }
            Some(Open::Rot) => {
                let Some(r) = self.rotary.as_mut() else {
                    return Err(err::NEEDS_OPEN_BUFFER);
                };
                if r.used + words > r.capacity {
                    return Err(err::NO_ROOM);
                }
                r.used += words;
                r.lines.push_back(QueuedLine {
                    text: text.to_string(),
                    words,
                    arrival: now,
                });
                Ok(())
            }
            None => Err(err::NEEDS_OPEN_BUFFER),
        }
    }

    /// Execute one command line as the controller would from any port and
    /// answer its data lines, or the ERR number of the first failing
    /// command (commands before it have taken effect, as on a controller).
    pub fn command_line(&mut self, sess: &mut Session, line: &str) -> Result<Vec<String>, u16> {
        self.advance();
        if sess.epoch != self.epoch {
            sess.epoch = self.epoch;
            sess.open = None;
            sess.cs = 1;
        }
        if !line.is_ascii() {
            return Err(4);
        }
        let up = line.to_ascii_uppercase();
        // Strip a comment; the controller never stores it.
        let up = up.split(';').next().unwrap_or("").trim().to_string();
        if sess.open.is_some() {
            return self.buffered_line(sess, &up);
        }
        let mut out = Vec::new();
        let mut c = Cur { b: up.as_bytes(), i: 0 };
        while !c.done() {
            self.online_command(sess, &mut c, &mut out)?;
        }
        Ok(out)
    }

    /// A line while a buffer is open: a few on-line commands act at once,
    /// the rest is stored.
    fn buffered_line(&mut self, sess: &mut Session, up: &str) -> Result<Vec<String>, u16> {
        let compact: String = up.chars().filter(|c| !c.is_whitespace()).collect();
        if compact.is_empty() {
            return Ok(vec![]);
        }
        // On-line commands act at once even with a buffer open; the rest
        // of the line follows them on-line too (`PR &1?? P400`).
        const ONLINE: &[&str] = &["SIZE", "VER", "CID", "PR", "??", "$$$", "&", "OPEN", "CLOSE"];
        let b = compact.as_bytes();
        let var_query =
            b.len() > 1 && matches!(b[0], b'P' | b'M' | b'I' | b'Q') && b[1..].iter().all(u8::is_ascii_digit);
        let online =
            ONLINE.iter().any(|w| compact.starts_with(w)) || ["A", "Q", "R"].contains(&compact.as_str()) || var_query;
        if online {
            let mut out = Vec::new();
            let mut c = Cur { b: up.as_bytes(), i: 0 };
            while !c.done() {
                self.online_command(sess, &mut c, &mut out)?;
            }
            return Ok(out);
        }
        // `... CLOSE` at the end of a program line: store, then close.
        if let Some(body) = compact.strip_suffix("CLOSE")
            && !body.is_empty()
        {
            let body = up.trim_end().strip_suffix("CLOSE").unwrap_or(up).trim_end();
            self.store(sess.open, body)?;
            sess.open = None;
            return Ok(vec![]);
        }
        if compact == "CLEAR" {
            match sess.open {
                Some(Open::Prog(n)) => {
                    self.programs.insert(n, Program::default());
                }
                Some(Open::Rot) => {
                    if let Some(r) = self.rotary.as_mut() {
                        r.lines.clear();
                        r.used = 0;
                    }
                }
                None => {}
            }
            return Ok(vec![]);
        }
        self.store(sess.open, up)?;
        Ok(vec![])
    }

    fn online_command(&mut self, sess: &mut Session, c: &mut Cur, out: &mut Vec<String>) -> Result<(), u16> {
        let running = self.run.is_some();
        if c.kw("OPEN PROG") {
            let n = c.int().ok_or(err::DATA)?;
            let clear = c.kw("CLEAR");
            if sess.open.is_some() {
                return Err(err::IN_USE);
            }
            if let Some(Run {
                source: Source::Prog { n: rn, .. },
                ..
            }) = &self.run
                && *rn == n
            {
                return Err(err::RUNNING);
            }
            if running {
                return Err(err::RUNNING);
            }
            sess.open = Some(Open::Prog(n));
            // Any OPEN PROG invalidates the coordinate system's pointer.
            self.pointer = None;
            let p = self.programs.entry(n).or_default();
            if clear {
                *p = Program::default();
            }
            return Ok(());
        }
        if c.kw("OPEN ROT") {
            if sess.open.is_some() {
                return Err(err::IN_USE);
            }
            if self.rotary.is_none() {
                return Err(err::DATA);
            }
            sess.open = Some(Open::Rot);
            return Ok(());
        }
        if c.kw("OPEN") {
            return Err(err::DATA);
        }
        if c.kw("CLOSE") {
            sess.open = None;
            return Ok(());
        }
        if c.kw("CLEAR") {
            return Err(err::NEEDS_OPEN_BUFFER);
        }
        if c.kw("DELETE GATHER") || c.kw("DEL GAT") {
            self.gather = 0;
            return Ok(());
        }
        if c.kw("DELETE ROT") || c.kw("DEL ROT") {
            if matches!(self.run.as_ref().map(|r| &r.source), Some(Source::Rot)) {
                return Err(err::RUNNING);
            }
            if sess.open == Some(Open::Rot) {
                return Err(err::IN_USE);
            }
            self.rotary = None;
            if self.pointer == Some(Pointer::Rot) {
                self.pointer = None;
            }
            return Ok(());
        }
        if c.kw("DEFINE ROT") || c.kw("DEF ROT") {
            let n = i64::from(c.int().ok_or(err::DATA)?);
            if running {
                return Err(err::RUNNING);
            }
            if self.rotary.is_some() {
                return Err(err::IN_USE);
            }
            if self.free_words() < n {
                return Err(err::NO_ROOM);
            }
            self.rotary = Some(Rotary {
                capacity: n,
                used: 0,
                lines: VecDeque::new(),
            });
            return Ok(());
        }
        if c.kw("DEFINE GATHER") || c.kw("DEF GAT") {
            let free = self.free_words();
            let n = c.int().map_or(free, i64::from);
            if n > free {
                return Err(err::NO_ROOM);
            }
            self.gather = n;
            return Ok(());
        }
        if c.kw("SIZE") {
            let free = self.free_words();
            out.push(format!("{}", if sess.open.is_some() { -free } else { free }));
            return Ok(());
        }
        if c.kw("VER") {
            out.push("1.945  ".into());
            return Ok(());
        }
        if c.kw("CID") {
            out.push("603382".into());
            return Ok(());
        }
        if c.kw("TYPE") {
            out.push("TURBO2, X4".into());
            return Ok(());
        }
        if c.kw("SAVE") {
            return Ok(());
        }
        if c.kw("$$$") {
            self.reset();
            return Ok(());
        }
        if c.kw("???") {
            out.push(format!("{:06X}{:06X}", 0, 0));
            return Ok(());
        }
        if c.kw("??") {
            out.push(self.status(sess.cs));
            return Ok(());
        }
        if c.kw("PR") {
            let n = if sess.cs == 1 {
                self.rotary.as_ref().map_or(0, |r| r.lines.len())
            } else {
                0
            };
            out.push(n.to_string());
            return Ok(());
        }
        c.ws();
        match c.peek() {
            Some(b'&') => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)?;
                if !(1..=16).contains(&n) {
                    return Err(err::DATA);
                }
                sess.cs = n;
                Ok(())
            }
            Some(b'B') if c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit() || *d == b' ') => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)?;
                if running {
                    return Err(err::RUNNING);
                }
                self.cs1(sess)?;
                self.pointer = Some(if n == 0 { Pointer::Rot } else { Pointer::Prog(n) });
                Ok(())
            }
            Some(b'R') => {
                c.i += 1;
                self.cs1(sess)?;
                if running {
                    return Err(err::RUNNING);
                }
                if sess.open.is_some() && self.pointer != Some(Pointer::Rot) {
                    return Err(err::IN_USE);
                }
                let p = self.pointer.ok_or(err::BAD_POINTER)?;
                self.start_run(p)?;
                self.advance();
                Ok(())
            }
            Some(b'A') => {
                c.i += 1;
                self.abort();
                Ok(())
            }
            Some(b'Q') if !c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                c.i += 1;
                if let Some(r) = self.run.as_mut() {
                    r.quit = true;
                    if r.pending.is_empty() {
                        self.finish_run("done");
                    }
                }
                Ok(())
            }
            Some(l @ (b'I' | b'P' | b'Q' | b'M')) if c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)? as usize;
                if n >= VARS {
                    return Err(err::DATA);
                }
                if c.kw("=") {
                    let v = c.number().ok_or(err::DATA)?;
                    let t = self.now();
                    self.set_var(l, n, v, t);
                } else {
                    out.push(fmt_value(self.var(l, n)));
                }
                Ok(())
            }
            _ => {
                if PROGRAM_WORDS.iter().any(|w| c.kw(w)) {
                    return Err(err::NEEDS_OPEN_BUFFER);
                }
                Err(err::DATA)
            }
        }
    }

    fn cs1(&self, sess: &Session) -> Result<(), u16> {
        if sess.cs == 1 { Ok(()) } else { Err(err::NO_MOTORS) }
    }

    fn status(&self, cs: u32) -> String {
        if cs != 1 {
            return status_word(false, true);
        }
        status_word(self.running(), self.in_position())
    }

    /// Answer a control character (VR_CTRL_RESPONSE / on-line ^G etc.).
    pub fn control(&mut self, ch: u8) -> Result<Vec<String>, u16> {
        self.advance();
        match ch {
            // ^B / ^C: coordinate system and motor status words.
            0x02 | 0x03 => Ok(vec![self.status(1)]),
            // ^G: global status.
            0x07 => Ok(vec![format!("{:06X}{:06X}", 0, 0)]),
            // ^P positions, ^F following errors, ^V velocities (motors 1-3).
            0x10 => Ok(vec![format!(
                "{} {} {}",
                fmt_value(self.pos.x),
                fmt_value(self.pos.y),
                fmt_value(self.pos.z)
            )]),
            0x06 | 0x16 => Ok(vec!["0 0 0".into()]),
            _ => Err(err::DATA),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctl() -> (Controller, Session) {
        let cfg = Config {
            memory_words: 100,
            ..Config::default()
        };
        (Controller::new(cfg, Clock::Manual(0.0), None), Session::default())
    }

    fn ok(c: &mut Controller, s: &mut Session, l: &str) -> Vec<String> {
        c.command_line(s, l).unwrap_or_else(|e| panic!("{l}: ERR{e:03}"))
    }

    #[test]
    fn download_run_and_status() {
        let (mut c, mut s) = ctl();
        assert_eq!(ok(&mut c, &mut s, "i6=1 i3=2 ver"), vec!["1.945  "]);
        assert_eq!(ok(&mut c, &mut s, "cid"), vec!["603382"]);
        ok(&mut c, &mut s, "CLOSE DELETE GATHER");
        ok(&mut c, &mut s, "OPEN PROG 1 CLEAR");
        assert_eq!(ok(&mut c, &mut s, "SIZE"), vec!["-100"]);
        assert_eq!(c.command_line(&mut s, "OPEN PROG 2"), Err(err::IN_USE));
        ok(&mut c, &mut s, "LINEAR X1 F1 P400=1");
        ok(&mut c, &mut s, "M33==1 X2 P400=2");
        ok(&mut c, &mut s, "M33=0 CLOSE");
        assert_eq!(ok(&mut c, &mut s, "SIZE"), vec!["86"]);
        assert_eq!(c.command_line(&mut s, "&1R"), Err(err::BAD_POINTER));
        ok(&mut c, &mut s, "&1B1R");
        let st = ok(&mut c, &mut s, "&1??");
        assert_eq!(parse_status(&st[0]), Some((true, false)));
        assert_eq!(c.command_line(&mut s, "OPEN PROG 1 CLEAR"), Err(err::RUNNING));
        c.set_time(1.5);
        assert_eq!(ok(&mut c, &mut s, "P400"), vec!["1"]);
        assert_eq!(ok(&mut c, &mut s, "M33"), vec!["1"]);
        c.set_time(2.5);
        assert_eq!(ok(&mut c, &mut s, "M33"), vec!["0"]);
        assert_eq!(parse_status(&ok(&mut c, &mut s, "&1??")[0]), Some((false, true)));
    }

    #[test]
    fn memory_and_error_codes() {
        let (mut c, mut s) = ctl();
        assert_eq!(c.command_line(&mut s, "LINEAR X1"), Err(err::NEEDS_OPEN_BUFFER));
        assert_eq!(c.command_line(&mut s, "HELLO"), Err(err::DATA));
        ok(&mut c, &mut s, "OPEN PROG 1 CLEAR");
        let mut stored = 0;
        let e = loop {
            match c.command_line(&mut s, "X1 Y2 Z3 F4 P5=6") {
                Ok(_) => stored += 1,
                Err(e) => break e,
            }
            assert!(stored < 100);
        };
        assert_eq!(e, err::NO_ROOM);
        assert_eq!(stored, 100 / 7);
        ok(&mut c, &mut s, "CLOSE");
        assert_eq!(c.command_line(&mut s, "&2B1R"), Err(err::NO_MOTORS));
    }

    #[test]
    fn rotary_idles_when_dry_and_logs_it() {
        let (mut c, mut s) = ctl();
        ok(&mut c, &mut s, "&1 DEFINE ROT 50");
        ok(&mut c, &mut s, "&1 B0");
        ok(&mut c, &mut s, "OPEN ROT");
        ok(&mut c, &mut s, "LINEAR X1 F1");
        assert_eq!(ok(&mut c, &mut s, "PR"), vec!["1"]);
        ok(&mut c, &mut s, "&1R");
        assert_eq!(ok(&mut c, &mut s, "PR"), vec!["0"]);
        c.set_time(3.0);
        ok(&mut c, &mut s, "X2");
        c.set_time(10.0);
        assert!(c.running());
        assert!(c.in_position());
        ok(&mut c, &mut s, "CLOSE");
        ok(&mut c, &mut s, "&1Q");
        assert!(!c.running());
        assert_eq!(c.pos.x, 2.0);
    }

    #[test]
    fn no_panic_on_garbage() {
        let (mut c, mut s) = ctl();
        for l in [
            "",
            "&",
            "&99",
            "B",
            "P99999",
            "P1=",
            "P1=$",
            "OPEN PROG",
            "DEFINE ROT 99999999999",
            "\u{e9}",
            "M33=1e999",
            "?",
        ] {
            let _ = c.command_line(&mut s, l);
        }
        ok(&mut c, &mut s, "OPEN PROG 3");
        for l in ["CIRCLE1 X1", "X(", "))))", "LINEAR X1 Y1 F0"] {
            let _ = c.command_line(&mut s, l);
        }
        ok(&mut c, &mut s, "CLOSE &1B3R");
        c.set_time(100.0);
        c.advance();
        assert!(!c.running());
    }
}
