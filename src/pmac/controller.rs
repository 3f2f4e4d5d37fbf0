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

/// The ERR numbers the emulator answers, as the Turbo PMAC Software
/// Reference numbers them (docs/pmac-send.md lists where each arises).
pub mod err {
    /// ERR001: not allowed while a program runs (OPEN PROG, DEFINE ROT, B,
    /// R during a run).
    pub const RUNNING: u16 = 1;
    /// ERR003: a data error or an unrecognised command.
    pub const DATA: u16 = 3;
    /// ERR004: a character above ASCII 127.
    pub const ILLEGAL_CHAR: u16 = 4;
    /// ERR005: a program word or CLEAR with no buffer open.
    pub const NEEDS_OPEN_BUFFER: u16 = 5;
    /// ERR006: no room in the buffer (or user memory) for the line.
    pub const NO_ROOM: u16 = 6;
    /// ERR007: the buffer is already open or defined.
    pub const IN_USE: u16 = 7;
    /// ERR014: the addressed coordinate system has no motors (only &1 has).
    pub const NO_MOTORS: u16 = 14;
    /// ERR015: R with the coordinate system not pointed at a valid buffer.
    pub const BAD_POINTER: u16 = 15;
}

/// Where simulated time comes from.
#[derive(Debug, Clone, Copy)]
pub enum Clock {
    /// Real time since `t0` times `scale`.
    Scaled {
        /// The real instant simulated time 0 stands for.
        t0: Instant,
        /// Simulated seconds per real second (> 0).
        scale: f64,
    },
    /// Set by hand ([`Emulator::set_time`]); unit tests.
    Manual(f64),
}

impl Clock {
    /// A clock starting now that runs `scale` simulated seconds per real
    /// second; a scale that is not a positive number means 1.
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
    /// User memory for program, rotary and gather buffers, long words
    /// (`SIZE` answers what is free).
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
    /// Records of the line being calculated.
    pending: VecDeque<Record>,
    lineno: u64,
    moved: bool,
    /// `Q` given: calculate no more; end when motion has.
    quit: bool,
    /// A program buffer's last line has been calculated.
    eof: bool,
    /// Calculated segments; the first may be in motion.
    segs: VecDeque<Seg>,
    /// Where the last calculated move ends.
    calc_pos: P3,
    /// `==` assignments waiting for the next calculated segment.
    sync_pending: Vec<(u8, usize, f64)>,
}

#[derive(Clone)]
enum SegKind {
    Move {
        from: P3,
        to: P3,
        kind: MotionKind,
        name: &'static str,
        feed: Option<f64>,
        dur: f64,
    },
    Dwell {
        s: f64,
    },
}

/// A calculated move or dwell.
struct Seg {
    kind: SegKind,
    /// Synchronous assignments performed as it starts.
    sync: Vec<(u8, usize, f64)>,
    /// When its motion started.
    start: Option<f64>,
    /// When it was calculated (it cannot start before).
    ready: f64,
}

/// Segments calculated ahead of motion (besides the one moving).
pub const LOOKAHEAD: usize = 2;

/// An M-variable definition: its text as given, and the P-variable it
/// points at when its address is in P-variable memory (Turbo PMAC:
/// P0..P8191 at $6000..$7FFF, read as floating point with `L:`/`D:`).
#[derive(Debug, Clone)]
struct MDef {
    text: String,
    p: Option<usize>,
}

/// Counts per millimetre of the emulated motors #1..#3 (`#n->` answers
/// `10000X` etc.).
pub const COUNTS_PER_MM: f64 = 10_000.0;

/// The controller state: buffers, variables, the running program and the
/// stage. Wrap it in a mutex to share between connections.
pub struct Emulator {
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
    /// Synchronous assignments (`==`) left queued by a stopped program:
    /// they act at the next segment's start unless `MFLUSH` clears them.
    sync_left: Vec<(u8, usize, f64)>,
    /// Simulated time of the last calculation or motion event.
    t_evt: f64,
    /// M-variable definitions (`M7400->L:$6190`); absent: self-referenced.
    mdefs: BTreeMap<usize, MDef>,
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

/// An M-variable definition `X:$addr`, `Y:$addr,bit`, `L:$addr`,
/// `D:$addr`; `L`/`D` at $6000..$7FFF point at P-variables.
fn parse_mdef(def: &str) -> Option<MDef> {
    let (ty, rest) = def.split_once(':')?;
    if !matches!(ty, "X" | "Y" | "L" | "D" | "DP" | "F" | "TWD" | "TWB" | "TWS" | "TWR") {
        return None;
    }
    let addr = rest.split(',').next()?;
    let a = match addr.strip_prefix('$') {
        Some(h) => i64::from_str_radix(h, 16).ok()?,
        None => addr.parse::<i64>().ok()?,
    };
    let p = (matches!(ty, "L" | "D") && (0x6000..0x8000).contains(&a)).then_some((a - 0x6000) as usize);
    Some(MDef {
        text: def.to_string(),
        p,
    })
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
    /// The addressed coordinate system (`&n`, 1..=16; 1 at first and after
    /// a reset).
    pub cs: u32,
    /// The buffer this port has open: each port of a Turbo PMAC has its
    /// own, so a second connection (a safety stop) is not caught in a
    /// buffer another one left open.
    open: Option<Open>,
    /// The controller's reset count when this session last spoke: a reset
    /// closes every port's buffer.
    epoch: u64,
    /// The addressed motor (`#n`, 1..=8; motors 1-3 are X, Y, Z).
    pub motor: u32,
}

impl Default for Session {
    fn default() -> Self {
        Session {
            cs: 1,
            open: None,
            epoch: 0,
            motor: 1,
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

impl Emulator {
    /// A controller as at power-on with `cfg`, its time from `clock`, its
    /// events written to `log` as JSON Lines (`None`: no log).
    pub fn new(cfg: Config, clock: Clock, log: Option<Box<dyn Write + Send>>) -> Self {
        let gather = cfg.gather_words.max(0);
        Emulator {
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
            sync_left: Vec::new(),
            t_evt: 0.0,
            mdefs: BTreeMap::new(),
            epoch: 0,
        }
    }

    /// Set the manual clock (no effect on a scaled clock).
    pub fn set_time(&mut self, t: f64) {
        if let Clock::Manual(old) = &mut self.clock {
            *old = t.max(*old);
        }
    }

    /// Simulated time now, s.
    pub fn now(&self) -> f64 {
        self.clock.now()
    }

    /// A program runs on &1 (a rotary one waiting for lines still runs).
    pub fn running(&self) -> bool {
        self.run.is_some()
    }

    /// Motors at rest: nothing calculated waits to move (a suspended
    /// rotary program is running and in position).
    pub fn in_position(&self) -> bool {
        self.run.as_ref().is_none_or(|r| r.segs.is_empty())
    }

    /// The value of variable `letter``n` (I, P, Q or M, either case; an
    /// M-variable pointed at a P-variable reads it); 0 for anything else.
    pub fn var(&self, letter: u8, n: usize) -> f64 {
        let (letter, n) = self.resolve(letter, n);
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

    /// An M-variable pointed at a P-variable stands for it.
    fn resolve(&self, letter: u8, n: usize) -> (u8, usize) {
        if letter.eq_ignore_ascii_case(&b'M')
            && let Some(MDef { p: Some(k), .. }) = self.mdefs.get(&n)
        {
            return (b'P', *k);
        }
        (letter, n)
    }

    fn set_var(&mut self, letter: u8, n: usize, value: f64, t: f64) {
        let (letter, n) = self.resolve(letter, n);
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
        if let Some(r) = self.run.as_ref() {
            let p = self.position_at(now);
            self.event(
                serde_json::json!({"ev": "abort", "t": now, "run": r.id, "why": "reset", "x": p.x, "y": p.y, "z": p.z}),
            );
            self.stop_run(now, None);
        }
        self.event(serde_json::json!({"ev": "reset", "t": now}));
        self.programs.clear();
        self.rotary = None;
        self.gather = self.cfg.gather_words.max(0);
        self.pointer = None;
        self.pos = self.position_at(now);
        self.t_free = self.t_free.min(now);
        self.t_evt = self.t_evt.max(now);
        self.ta_ms = DEFAULT_TA_MS;
        self.sync_left.clear();
        self.mdefs.clear();
        self.epoch += 1;
        for v in &mut self.vars {
            v.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// Execute everything due by the current simulated time, as a
    /// discrete-event simulation: calculation (look-ahead) and motion.
    ///
    /// Calculation runs while fewer than [`LOOKAHEAD`] calculated segments
    /// wait to start and no calculated DWELL waits (a dwell stops
    /// look-ahead); plain variable assignments act when their line is
    /// calculated, synchronous ones (`M..==`) are queued on the next
    /// calculated segment and act when it starts. Motion runs segments in
    /// order, each for its duration.
    pub fn advance(&mut self) {
        let now = self.now();
        // Each pass handles one record, line or motion event: bounded by
        // the work queued, but guard anyway against a runaway.
        for _ in 0..10_000_000u32 {
            let Some(run) = self.run.as_ref() else { return };
            let unstarted = run.segs.iter().filter(|s| s.start.is_none()).count();
            let dwell_wait = run
                .segs
                .iter()
                .any(|s| s.start.is_none() && matches!(s.kind, SegKind::Dwell { .. }));
            // When the next calculation input is available.
            let t_in: Option<f64> = if run.quit || run.eof || unstarted >= LOOKAHEAD || dwell_wait {
                None
            } else if !run.pending.is_empty() {
                Some(self.t_evt)
            } else {
                match &run.source {
                    Source::Prog { .. } => Some(self.t_evt),
                    Source::Rot => self
                        .rotary
                        .as_ref()
                        .and_then(|r| r.lines.front())
                        .map(|q| q.arrival.max(self.t_evt)),
                }
            };
            // When the next motion event happens.
            let t_m: Option<f64> = run.segs.front().map(|s| match s.start {
                Some(_) => self.t_free,
                None => self.t_free.max(s.ready),
            });
            let calc_first = match (t_in, t_m) {
                (Some(a), Some(b)) => a <= b,
                (Some(_), None) => true,
                _ => false,
            };
            if calc_first && t_in.is_some_and(|t| t <= now) {
                self.t_evt = t_in.unwrap_or(self.t_evt);
                if !self.calculate() {
                    return;
                }
                continue;
            }
            if let Some(t) = t_m.filter(|t| *t <= now) {
                self.t_evt = self.t_evt.max(t);
                self.motion_event();
                continue;
            }
            // Nothing due: a program with no more lines and no motion ends.
            let run = self.run.as_ref().expect("checked above");
            if run.segs.is_empty() && (run.eof || run.quit) && run.pending.is_empty() | run.quit {
                self.t_evt = self.t_evt.max(self.t_free);
                self.finish_run("done");
            }
            return;
        }
    }

    /// Calculate one record or fetch one line. `false`: the run ended.
    fn calculate(&mut self) -> bool {
        let t = self.t_evt;
        let Some(run) = self.run.as_mut() else { return false };
        if let Some(rec) = run.pending.pop_front() {
            match rec {
                Record::Move(m) => {
                    let from = run.calc_pos;
                    let (len, kind) = match m.kind {
                        MotionKind::Rapid => ((m.to - from).norm(), "rapid"),
                        MotionKind::Line => ((m.to - from).norm(), "line"),
                        MotionKind::Arc(a) => (a.arc(from, m.to).map_or(0.0, |a| a.length()), "arc"),
                    };
                    let speed = match m.kind {
                        MotionKind::Rapid => RAPID_MM_S,
                        _ => m.feed.filter(|f| *f > 0.0 && f.is_finite()).unwrap_or(DEFAULT_FEED),
                    };
                    let dur = (len / speed).max(self.ta_ms / 1000.0);
                    run.calc_pos = m.to;
                    let sync = std::mem::take(&mut run.sync_pending);
                    run.segs.push_back(Seg {
                        kind: SegKind::Move {
                            from,
                            to: m.to,
                            kind: m.kind,
                            name: kind,
                            feed: m.feed,
                            dur,
                        },
                        sync,
                        start: None,
                        ready: t,
                    });
                }
                Record::Dwell { seconds, .. } => {
                    let s = if seconds.is_finite() { seconds.max(0.0) } else { 0.0 };
                    let sync = std::mem::take(&mut run.sync_pending);
                    run.segs.push_back(Seg {
                        kind: SegKind::Dwell { s },
                        sync,
                        start: None,
                        ready: t,
                    });
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
                            run.sync_pending.push((l, n, value));
                        } else {
                            // A plain assignment acts when calculated.
                            self.set_var(l, n, value, t);
                        }
                    }
                }
                Record::Spindle { .. } => {}
            }
            return true;
        }
        let text = match &mut run.source {
            Source::Prog { n, next } => match self.programs.get(n).and_then(|p| p.lines.get(*next)) {
                Some(l) => {
                    *next += 1;
                    l.clone()
                }
                None => {
                    run.eof = true;
                    return true;
                }
            },
            Source::Rot => {
                let Some(q) = self.rotary.as_mut().and_then(|r| r.lines.pop_front()) else {
                    return true;
                };
                if let Some(r) = self.rotary.as_mut() {
                    r.used -= q.words;
                }
                q.text
            }
        };
        let Some(run) = self.run.as_mut() else { return false };
        run.lineno += 1;
        let lineno = run.lineno;
        if let Err(e) = run.interp.line(text.as_bytes(), lineno, &mut run.pending) {
            let id = run.id;
            self.event(serde_json::json!({"ev": "error", "t": t, "run": id, "msg": e.to_string()}));
            self.stop_run(t, None);
            return false;
        }
        true
    }

    /// Start the first calculated segment, or end it.
    fn motion_event(&mut self) {
        let Some(run) = self.run.as_mut() else { return };
        let Some(seg) = run.segs.front_mut() else { return };
        let id = run.id;
        if seg.start.is_some() {
            // Ends now.
            if let Some(seg) = run.segs.pop_front()
                && let SegKind::Move { to, .. } = seg.kind
            {
                self.pos = to;
            }
            return;
        }
        let t = self.t_free.max(seg.ready);
        if t > self.t_free && run.moved {
            let from = self.t_free;
            self.event(serde_json::json!({"ev": "idle", "t": from, "run": id, "until": t}));
        }
        let Some(run) = self.run.as_mut() else { return };
        let Some(seg) = run.segs.front_mut() else { return };
        seg.start = Some(t);
        let sync = std::mem::take(&mut seg.sync);
        let kind = seg.kind.clone();
        run.moved |= matches!(kind, SegKind::Move { .. });
        // Queued synchronous assignments act as this segment starts (those
        // left over from a stopped program first, unless MFLUSHed).
        for (l, n, v) in std::mem::take(&mut self.sync_left).into_iter().chain(sync) {
            self.set_var(l, n, v, t);
        }
        match kind {
            SegKind::Move {
                from,
                to,
                kind,
                name,
                feed,
                dur,
            } => {
                let beam = self.shutter().is_some_and(|(l, n)| self.var(l, n) != 0.0);
                let mut ev = serde_json::json!({
                    "ev": "move", "t": t, "run": id, "kind": name,
                    "x": to.x, "y": to.y, "z": to.z, "from": [from.x, from.y, from.z],
                    "beam": beam, "feed": feed, "dur": dur,
                });
                if let MotionKind::Arc(a) = kind {
                    ev["center"] = serde_json::json!([a.center.x, a.center.y, a.center.z]);
                    ev["ccw"] = serde_json::json!(a.ccw);
                }
                self.event(ev);
                self.t_free = t + dur;
            }
            SegKind::Dwell { s } => {
                self.event(serde_json::json!({"ev": "dwell", "t": t, "run": id, "s": s}));
                self.t_free = t + s;
            }
        }
    }

    /// Where the stage is at simulated time `t` (now or later): on the
    /// segment in motion, at constant speed along it.
    pub fn position_at(&self, t: f64) -> P3 {
        let Some(seg) = self.run.as_ref().and_then(|r| r.segs.front()) else {
            return self.pos;
        };
        let (
            Some(t0),
            SegKind::Move {
                from, to, kind, dur, ..
            },
        ) = (seg.start, &seg.kind)
        else {
            return self.pos;
        };
        let f = if *dur > 0.0 {
            ((t - t0) / dur).clamp(0.0, 1.0)
        } else {
            1.0
        };
        match kind {
            MotionKind::Arc(a) => match a.arc(*from, *to) {
                Some(arc) => arc.point_at(f),
                None => *to,
            },
            _ => *from + (*to - *from) * f,
        }
    }

    /// The stage's position now.
    pub fn position(&self) -> P3 {
        self.position_at(self.now())
    }

    fn finish_run(&mut self, how: &str) {
        let t = self.t_evt.max(self.t_free);
        self.stop_run(t, Some(how));
    }

    /// End the run at time `t`: motion stops where it is, calculated
    /// segments are dropped, their synchronous assignments stay queued.
    fn stop_run(&mut self, t: f64, how: Option<&str>) {
        let p = self.position_at(t);
        if let Some(r) = self.run.take() {
            if let Some(how) = how {
                self.event(serde_json::json!({"ev": how, "t": t, "run": r.id, "x": p.x, "y": p.y, "z": p.z}));
            }
            for s in r.segs.into_iter().filter(|s| s.start.is_none()) {
                self.sync_left.extend(s.sync);
            }
            self.sync_left.extend(r.sync_pending);
        }
        self.pos = p;
        self.t_free = self.t_free.min(t);
        self.t_evt = t;
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
            ..ReadOptions::default()
        };
        self.runs += 1;
        let id = self.runs;
        let now = self.now();
        self.t_free = self.t_free.max(now);
        self.t_evt = self.t_evt.max(now);
        let prog = match p {
            Pointer::Prog(n) => serde_json::json!(n),
            Pointer::Rot => serde_json::json!("rot"),
        };
        let t = self.t_free;
        self.event(serde_json::json!({"ev": "run", "t": t, "run": id, "prog": prog}));
        self.run = Some(Run {
            id,
            source,
            interp: PmacInterpreter::program_body(&opts),
            pending: VecDeque::new(),
            lineno: 0,
            moved: false,
            quit: false,
            eof: false,
            segs: VecDeque::new(),
            calc_pos: self.pos,
            sync_pending: Vec::new(),
        });
        Ok(())
    }

    fn abort(&mut self) {
        let now = self.now();
        if self.run.is_some() {
            // Motion stops where it is (deceleration within TA ignored);
            // look-ahead is dropped. Queued `==` assignments stay queued
            // until MFLUSH.
            self.stop_run(now, Some("abort"));
        }
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
            return Err(err::ILLEGAL_CHAR);
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
        const ONLINE: &[&str] = &[
            "SIZE", "VER", "CID", "PR", "??", "$$$", "&", "OPEN", "CLOSE", "MFLUSH", "#",
        ];
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
        if c.kw("MFLUSH") {
            self.sync_left.clear();
            if let Some(r) = self.run.as_mut() {
                r.sync_pending.clear();
            }
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
            Some(b'#') => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)?;
                if !(1..=8).contains(&n) {
                    return Err(err::DATA);
                }
                sess.motor = n;
                if c.kw("->") {
                    // Query only: X, Y, Z on motors 1-3.
                    out.push(match n {
                        1..=3 => format!("{}{}", fmt_value(COUNTS_PER_MM), ["X", "Y", "Z"][n as usize - 1]),
                        _ => "0".into(),
                    });
                }
                Ok(())
            }
            Some(b'P') if !c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                // Position of the addressed motor, counts.
                c.i += 1;
                let p = self.position();
                let v = match sess.motor {
                    1 => p.x,
                    2 => p.y,
                    3 => p.z,
                    _ => 0.0,
                };
                out.push(fmt_value((v * COUNTS_PER_MM * 10.0).round() / 10.0));
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
                }
                self.advance();
                Ok(())
            }
            Some(l @ (b'I' | b'P' | b'Q' | b'M')) if c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)? as usize;
                if n >= VARS {
                    return Err(err::DATA);
                }
                if l == b'M' && c.kw("->") {
                    c.ws();
                    let s = c.i;
                    while c.peek().is_some_and(|d| !d.is_ascii_whitespace()) {
                        c.i += 1;
                    }
                    let def = std::str::from_utf8(&c.b[s..c.i]).unwrap_or("").to_string();
                    if def.is_empty() {
                        out.push(self.mdefs.get(&n).map_or("*".into(), |d| d.text.clone()));
                    } else if def == "*" {
                        self.mdefs.remove(&n);
                    } else {
                        self.mdefs.insert(n, parse_mdef(&def).ok_or(err::DATA)?);
                    }
                } else if c.kw("=") {
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
            0x10 => {
                let p = self.position();
                Ok(vec![format!(
                    "{} {} {}",
                    fmt_value(p.x),
                    fmt_value(p.y),
                    fmt_value(p.z)
                )])
            }
            0x06 | 0x16 => Ok(vec!["0 0 0".into()]),
            _ => Err(err::DATA),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctl() -> (Emulator, Session) {
        let cfg = Config {
            memory_words: 100,
            ..Config::default()
        };
        (Emulator::new(cfg, Clock::Manual(0.0), None), Session::default())
    }

    fn ok(c: &mut Emulator, s: &mut Session, l: &str) -> Vec<String> {
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
        // P400=2 is a plain assignment: it ran when look-ahead calculated
        // the second line, ahead of its motion.
        assert_eq!(ok(&mut c, &mut s, "P400"), vec!["2"]);
        assert_eq!(ok(&mut c, &mut s, "M33"), vec!["1"]);
        c.set_time(2.5);
        // The immediate `M33=0` after the last move ran at calculation
        // time, before `M33==1` took effect: the shutter stays open. This
        // is why pmac-send closes it synchronously and after every stop.
        assert_eq!(ok(&mut c, &mut s, "M33"), vec!["1"]);
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
    fn synchronous_counter_follows_motion_and_mflush_clears_leftovers() {
        let (mut c, mut s) = ctl();
        ok(&mut c, &mut s, "M7400->L:$6190");
        assert_eq!(ok(&mut c, &mut s, "M7400->"), vec!["L:$6190"]);
        ok(&mut c, &mut s, "OPEN PROG 1 CLEAR");
        ok(&mut c, &mut s, "LINEAR F1 X1 M7400==1");
        ok(&mut c, &mut s, "M33==1 X2 M7400==2");
        ok(&mut c, &mut s, "X3 M7400==3");
        ok(&mut c, &mut s, "M33==0 X4 M7400==4");
        ok(&mut c, &mut s, "CLOSE &1B1R");
        c.set_time(0.5);
        // The counter (through M7400, in P400) is set where the next move
        // starts: still 0 in move 1.
        assert_eq!(ok(&mut c, &mut s, "P400"), vec!["0"]);
        assert_eq!(ok(&mut c, &mut s, "#1P"), vec!["5000"]);
        c.set_time(1.5);
        assert_eq!(ok(&mut c, &mut s, "P400 M7400 M33"), vec!["1", "1", "1"]);
        c.set_time(2.25);
        ok(&mut c, &mut s, "&1A");
        assert_eq!(ok(&mut c, &mut s, "#1P #2P #1->"), vec!["22500", "0", "10000X"]);
        assert!(!c.running() && c.in_position());
        // Queued `==` assignments of dropped look-ahead (M33==0, counters)
        // stay queued: the next move would run them. MFLUSH clears them.
        assert!(!c.sync_left.is_empty());
        ok(&mut c, &mut s, "&1 MFLUSH");
        assert!(c.sync_left.is_empty());
        assert_eq!(c.position().x, 2.25);
    }

    #[test]
    fn dry_rotary_program_is_suspended_not_finished() {
        let (mut c, mut s) = ctl();
        ok(&mut c, &mut s, "&1 DEFINE ROT 50");
        ok(&mut c, &mut s, "&1 B0");
        ok(&mut c, &mut s, "OPEN ROT");
        ok(&mut c, &mut s, "LINEAR X1 F1");
        ok(&mut c, &mut s, "&1R");
        ok(&mut c, &mut s, "CLOSE");
        c.set_time(5.0);
        let st = ok(&mut c, &mut s, "&1??");
        assert_eq!(parse_status(&st[0]), Some((true, true)), "running and in position");
        ok(&mut c, &mut s, "&1Q");
        assert_eq!(parse_status(&ok(&mut c, &mut s, "&1??")[0]), Some((false, true)));
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
