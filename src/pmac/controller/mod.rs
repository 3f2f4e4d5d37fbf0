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
//!
//! The state and its plain accessors are here; `execution.rs` runs the
//! program in simulated time, `commands.rs` answers command lines and
//! control characters.

use crate::gcode::pmac::PmacInterpreter;
use crate::geometry::P3;
use crate::model::toolpath::{MotionKind, Record};
use std::collections::{BTreeMap, VecDeque};
use std::io::Write;
use std::time::Instant;

mod commands;
mod execution;
#[cfg(test)]
mod tests;

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
}
