//! ISO/RS274-NGC interpreter (the LinuxCNC flavour), one line at a time.
//!
//! Each line is normalised (comments and blanks dropped, letters upper-cased),
//! split into words, checked (one code per modal group, no repeated words)
//! and executed in RS274's order of execution. Positions are kept in the
//! machine frame in millimetres: program coordinates plus the G5x and G92
//! offsets, so every move starts where the previous one ended, whatever
//! offsets the program sets. Inch programs (G20) become millimetres.
//!
//! O-word subroutines and control flow (LinuxCNC's `sub`/`call`, `if`,
//! `while`, `do`, `repeat`, `break`, `continue`, `return`) are executed:
//! a structure's lines are held in memory from its opening line to its
//! closing line, then run; straight-line code streams through untouched.
//!
//! G5.2/G5.3 NURBS blocks (`nurbs.rs`), cutter compensation (`comp.rs`),
//! canned cycles (`cycles.rs`), rotary
//! axes A/B/C and the G93/G94/G95 feed modes are interpreted as LinuxCNC's
//! `rs274` does. What it cannot honour (lathe cycles, probing, threading)
//! is an error naming the line.
//!
//! This file holds the modal state and the order of execution; the parts
//! are beside it: `words.rs` (normalising, splitting and checking a
//! block), `flow.rs` (O-word control flow and subroutines), `moves.rs`
//! (motion, targets, feeds, offsets, homing), `arcs.rs`, `splines.rs`,
//! `nurbs.rs`, `comp.rs`, `cycles.rs`; tests in `iso_tests.rs`.

#[path = "arcs.rs"]
mod arcs;
#[path = "comp.rs"]
mod comp;
#[path = "cycles.rs"]
mod cycles;
#[path = "flow.rs"]
mod flow;
#[path = "moves.rs"]
mod moves;
#[path = "nurbs.rs"]
mod nurbs;
#[path = "splines.rs"]
pub(crate) mod splines;
#[path = "words.rs"]
mod words;

use flow::{Capture, closer_of, label_text};
use words::{Block, fmt_code};

use super::expr::{Cursor, ParamRef, Params};
use super::oword::{self, OKeyword, OLine};
use super::tooltable::ToolTable;
use super::{GcodeError, LineInterpreter, ReadOptions};
use crate::geometry::{P3, Plane, V3};
use crate::model::toolpath::{Motion, MotionKind, Record, ToolState};
use std::collections::HashMap;
use std::collections::VecDeque;
use std::rc::Rc;

const MM_PER_INCH: f64 = 25.4;

/// True when radii `r0` and `r1` (mm) differ by no more than LinuxCNC
/// accepts from an I/J/K arc in any program (the inch limits are the wider).
pub(crate) fn spiral_accepted(r0: f64, r1: f64) -> bool {
    arcs::ArcTolerances::new(true).radii_agree(r0, r1)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MotionMode {
    Rapid,
    Feed,
    Cw,
    Ccw,
    /// A canned cycle, by its G code times ten (G81 -> 810).
    Cycle(u16),
    /// G5 (50) or G5.1 (51).
    Spline(u16),
    /// G5.2: the lines add control points to an open NURBS block.
    Nurbs,
}

/// How F is read (G93, G94, G95).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FeedMode {
    /// G94: length units per minute.
    PerMinute,
    /// G93: inverse time, F is 1 / minutes for each move.
    InverseTime,
    /// G95: length units per spindle revolution.
    PerRevolution,
}

/// The ISO interpreter's modal state.
pub struct IsoInterpreter {
    /// Current position, machine frame, mm.
    pos: P3,
    inch: bool,
    incremental: bool,
    arc_absolute: bool,
    plane: Plane,
    motion: Option<MotionMode>,
    /// Feed in mm/min. LinuxCNC converts F to its internal unit when F is
    /// set (before a G20/G21 on the same line takes effect) and keeps that
    /// speed across later unit changes; so do we.
    feed_mm_per_min: f64,
    beam: bool,
    spindle_rpm: Option<f64>,
    params: Params,
    /// G54..G59.3 origins (mm); `cs` selects one.
    g5x: [V3; 9],
    cs: usize,
    g92: V3,
    g92_saved: Option<V3>,
    percent_seen: bool,
    any_code_seen: bool,
    ended: bool,
    norm: Vec<u8>,
    assigns: Vec<(ParamRef, f64)>,
    /// Subroutine bodies by label (the lines between `sub` and `endsub`).
    subs: HashMap<Vec<u8>, Rc<Vec<(u64, String)>>>,
    /// A top-level control structure or subroutine being read in.
    capture: Option<Capture>,
    /// Loop iterations run so far, to stop runaway loops.
    iterations: u64,
    /// The bound on `iterations` (`ReadOptions::max_loop_iterations`).
    max_iterations: u64,
    /// Canned-cycle settings carried from block to block.
    cycle: cycles::CycleState,
    /// Cutter radius compensation state and held-back moves.
    comp: comp::CompState,
    tool_table: Option<std::sync::Arc<ToolTable>>,
    /// Folders searched for subroutine files.
    sub_path: Vec<std::path::PathBuf>,
    /// Tool in the spindle (M6, M61), and the one a T word selected.
    tool_current: u32,
    tool_selected: Option<u32>,
    /// Rotary axes A, B, C (degrees), and whether the program has moved
    /// any of them (then every move carries them).
    abc: [f64; 3],
    abc_used: bool,
    /// Rotary travel (degrees) of the block being run, for G93.
    abc_step: f64,
    feed_mode: FeedMode,
    /// P and Q of the last G5, for a following G5 without I and J.
    spline_pq: Option<(f64, f64)>,
    /// The G5.2 NURBS block being read, until its G5.3.
    nurbs: Option<nurbs::NurbsBlock>,
}

impl IsoInterpreter {
    /// An interpreter in LinuxCNC's start-up state (G17 G21 G90 G94,
    /// G54, no offsets, no tool in the spindle, no motion mode), at
    /// `opts.start`, with the tool table and subroutine path of `opts`.
    pub fn new(opts: &ReadOptions) -> Self {
        IsoInterpreter {
            pos: opts.start,
            inch: false,
            incremental: false,
            arc_absolute: false,
            plane: Plane::Xy,
            motion: None,
            feed_mm_per_min: 0.0,
            beam: false,
            spindle_rpm: None,
            params: Params::default(),
            g5x: [V3::zeros(); 9],
            cs: 0,
            g92: V3::zeros(),
            g92_saved: None,
            percent_seen: false,
            any_code_seen: false,
            ended: false,
            norm: Vec::with_capacity(128),
            assigns: Vec::new(),
            subs: HashMap::new(),
            capture: None,
            iterations: 0,
            max_iterations: opts.max_loop_iterations,
            cycle: cycles::CycleState::new(),
            comp: comp::CompState::new(),
            tool_table: opts.tool_table.clone(),
            sub_path: opts.subroutine_path.clone(),
            tool_current: 0,
            tool_selected: None,
            abc: [0.0; 3],
            abc_used: false,
            abc_step: 0.0,
            feed_mode: FeedMode::PerMinute,
            spline_pq: None,
            nurbs: None,
        }
    }

    fn unit(&self) -> f64 {
        if self.inch { MM_PER_INCH } else { 1.0 }
    }

    /// Total origin offset (machine = program + offset), mm.
    fn offset(&self) -> V3 {
        self.g5x[self.cs] + self.g92
    }

    fn execute(&mut self, b: &Block, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        for (letter, name) in [(b'U', "U"), (b'V', "V"), (b'W', "W")] {
            if b.word(letter).is_some() {
                return Err(err(format!(
                    "extra axis word {name} is not supported (X, Y, Z and the rotary A, B, C only)"
                )));
            }
        }
        for code in b.g[..b.ng].iter().filter(|_| b.other_g) {
            let unsupported = match code {
                330 | 331 => Some("spindle-synchronised motion (G33)"),
                382..=385 => Some("probing (G38.x)"),
                760 => Some("the lathe threading cycle (G76)"),
                700..=722 => Some("the lathe turning cycles (G70-G72)"),
                171 | 181 | 191 => Some("the planes G17.1-G19.1"),
                70 | 80 => Some("lathe diameter/radius modes (G7/G8)"),
                960 => Some("constant surface speed (G96)"),
                _ => None,
            };
            if let Some(what) = unsupported {
                return Err(err(format!("{} is not supported: {what}", fmt_code('G', *code))));
            }
        }
        if b.word(b'E').is_some() {
            return Err(err("E word is not supported".into()));
        }
        if let Some(m) = b.m[..b.nm].iter().find(|m| (620..=680).contains(*m)) {
            return Err(err(format!(
                "{} is not supported: HAL pin input/output (M62-M68) acts on the machine's HAL, which a simulation has not",
                fmt_code('M', *m)
            )));
        }
        self.check_words(b).map_err(|m| err(m.to_string()))?;
        self.nurbs_guard(b, lineno)?;
        if b.other_g
            && (b.word(b'A').is_some() || b.word(b'B').is_some() || b.word(b'C').is_some())
            && [100u16, 280, 300, 520, 920].iter().any(|&c| b.has_g(c))
        {
            return Err(err(
                "rotary axis words (A, B, C) with G10, G28, G30, G52 or G92 are not supported: no rotary offsets or homes"
                    .into(),
            ));
        }
        // Parameters take their new values once the whole line is read.
        for (r, v) in self.assigns.drain(..) {
            self.params.set(&r, v);
        }
        // RS274 order of execution: feed mode, then F.
        if b.other_g {
            let mode = if b.has_g(930) {
                Some(FeedMode::InverseTime)
            } else if b.has_g(940) {
                Some(FeedMode::PerMinute)
            } else if b.has_g(950) {
                Some(FeedMode::PerRevolution)
            } else {
                None
            };
            if let Some(mode) = mode {
                if mode != self.feed_mode && self.comp.side.is_some() {
                    return Err(err(
                        "cannot change the feed mode with cutter radius compensation on".into()
                    ));
                }
                // LinuxCNC sets the feed rate to zero on every feed mode
                // code: a feed move needs a new F.
                self.feed_mode = mode;
                self.feed_mm_per_min = 0.0;
            }
        }
        if let Some(f) = b.word(b'F') {
            if f < 0.0 {
                return Err(err(format!("negative feed rate F{f}")));
            }
            // Inverse time has no length unit: F is 1/minutes.
            self.feed_mm_per_min = if self.feed_mode == FeedMode::InverseTime {
                f
            } else {
                f * self.unit()
            };
        }
        if let Some(s) = b.word(b'S') {
            if s < 0.0 {
                return Err(err(format!("negative spindle speed S{s}")));
            }
            if self.spindle_rpm != Some(s) {
                self.spindle_rpm = Some(s);
                self.emit(
                    out,
                    Record::Spindle {
                        rpm: s,
                        block: Some(lineno),
                    },
                );
            }
        }
        self.tools(b, lineno)?;
        if b.has_m(30) || b.has_m(40) {
            self.beam = true;
        }
        if b.has_m(50) {
            self.beam = false;
        }
        let axes_used = b.other_g && self.modal_settings(b, lineno, out)?;
        let before = self.motion;
        for &code in &b.g[..b.ng] {
            match code {
                0 => self.motion = Some(MotionMode::Rapid),
                10 => self.motion = Some(MotionMode::Feed),
                20 => self.motion = Some(MotionMode::Cw),
                30 => self.motion = Some(MotionMode::Ccw),
                800 => self.motion = None,
                50 | 51 => self.motion = Some(MotionMode::Spline(code)),
                52 => self.motion = Some(MotionMode::Nurbs),
                c if cycles::is_cycle(c) => self.motion = Some(MotionMode::Cycle(c)),
                _ => {}
            }
        }
        if self.motion != before && !matches!(self.motion, Some(MotionMode::Cycle(_))) {
            // Leaving the cycles: the next cycle takes a new initial level.
            self.cycle.initial_level = None;
        }
        self.motion_step(b, before, axes_used, lineno, out)
    }

    /// A non-motion record, behind any compensated move held back.
    fn emit(&mut self, out: &mut VecDeque<Record>, r: Record) {
        if self.comp.holding() {
            self.comp.hold(r);
        } else {
            out.push_back(r);
        }
    }

    /// T (select), M6 (change) and M61 (set the tool number).
    fn tools(&mut self, b: &Block, lineno: u64) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let whole = |letter: char, v: f64| {
            if v.fract() == 0.0 && (0.0..=1e9).contains(&v) {
                Ok(v as u32)
            } else {
                Err(err(format!(
                    "{letter}{v}: a tool number must be a whole number of at least 0"
                )))
            }
        };
        if let Some(t) = b.word(b'T') {
            let t = whole('T', t)?;
            if let Some(table) = &self.tool_table
                && t != 0
                && table.get(t).is_none()
            {
                return Err(err(format!("tool T{t} is not in the tool table")));
            }
            self.tool_selected = Some(t);
        }
        // G43/G43.2 H: the length offset of any tool in the table, loaded
        // or not (H0 is the empty spindle's, zero). It does not move the
        // tool tip, but LinuxCNC refuses a tool its table lacks.
        if let Some(h) = b.word(b'H') {
            if (h - h.round()).abs() > 1e-4 {
                return Err(err(format!("H{h}: a tool number must be a whole number")));
            }
            let n = h.round();
            let missing = n < 0.0
                || self
                    .tool_table
                    .as_ref()
                    .is_some_and(|table| n != 0.0 && (n > 1e9 || table.get(n as u32).is_none()));
            if missing {
                return Err(err(format!("H{n}: tool {n} is not in the tool table")));
            }
        }
        if b.has_m(60) {
            if self.comp.side.is_some() {
                return Err(err(
                    "cannot change tools with cutter radius compensation on (G40 first)".into(),
                ));
            }
            if let Some(t) = self.tool_selected {
                self.tool_current = t;
            }
        }
        if b.has_m(610) {
            let q = b
                .word(b'Q')
                .ok_or_else(|| err("M61 needs a Q word (the tool number)".into()))?;
            self.tool_current = whole('Q', q)?;
        }
        Ok(())
    }

    /// Steps 12-21 of the order of execution: dwell, plane, units,
    /// coordinate system, distance modes, and the non-modal G10/G28/G30/G92
    /// family. True when the block's axis words were used up by one of those.
    fn modal_settings(&mut self, b: &Block, lineno: u64, out: &mut VecDeque<Record>) -> Result<bool, GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        if b.has_g(40) {
            let p = b.word(b'P').ok_or_else(|| err("G4 needs a P word (seconds)".into()))?;
            if p < 0.0 {
                return Err(err(format!("negative dwell time P{p}")));
            }
            self.emit(
                out,
                Record::Dwell {
                    seconds: p,
                    block: Some(lineno),
                },
            );
        }
        let plane = self.plane;
        if b.has_g(170) {
            self.plane = Plane::Xy;
        } else if b.has_g(180) {
            self.plane = Plane::Xz;
        } else if b.has_g(190) {
            self.plane = Plane::Yz;
        }
        if self.plane != plane && self.comp.side.is_some() {
            return Err(err("cannot change planes with cutter radius compensation on".into()));
        }
        if b.has_g(200) {
            self.inch = true;
        } else if b.has_g(210) {
            self.inch = false;
        }
        if b.has_g(400) {
            self.comp_off(out);
        } else if b.has_g(410) || b.has_g(420) || b.has_g(411) || b.has_g(421) {
            let side = if b.has_g(410) || b.has_g(411) {
                comp::Side::Left
            } else {
                comp::Side::Right
            };
            self.comp_on(b, side, b.has_g(411) || b.has_g(421), lineno)?;
        }
        if self.comp.side.is_some()
            && [280, 281, 300, 301, 520, 920, 921, 922, 923, 100, 530]
                .iter()
                .any(|&c| b.has_g(c))
        {
            return Err(err(
                "G10, G28, G30, G53 and G92 cannot be used with cutter radius compensation on (G40 first)".into(),
            ));
        }
        for (i, code) in [540u16, 550, 560, 570, 580, 590, 591, 592, 593].iter().enumerate() {
            if b.has_g(*code) {
                self.cs = i;
            }
        }
        if b.has_g(900) {
            self.incremental = false;
        } else if b.has_g(910) {
            self.incremental = true;
        }
        if b.has_g(980) {
            self.cycle.r_plane_retract = false;
        } else if b.has_g(990) {
            self.cycle.r_plane_retract = true;
        }
        if b.has_g(901) {
            self.arc_absolute = true;
        } else if b.has_g(911) {
            self.arc_absolute = false;
        }
        let mut axes_used = false;
        if b.has_g(100) {
            self.set_coordinate_data(b, lineno)?;
            axes_used = true;
        } else if b.has_g(280) || b.has_g(300) {
            let home = self.home_position(if b.has_g(280) { 5161 } else { 5181 });
            self.go_home(b, home, lineno, out)?;
            axes_used = true;
        } else if b.has_g(281) || b.has_g(301) {
            let base = if b.has_g(281) { 5161 } else { 5181 };
            for k in 0..3 {
                self.params.set(&ParamRef::Num(base + k), self.pos[k] / self.unit());
            }
        } else if b.has_g(920) {
            self.set_g92(b, lineno)?;
            axes_used = true;
        } else if b.has_g(520) {
            // G52: a local offset. LinuxCNC keeps it in the G92 offsets and
            // sets each named axis' offset to the value given.
            let u = self.unit();
            for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                if let Some(v) = b.word(letter) {
                    self.g92[k] = v * u;
                }
            }
            axes_used = true;
        } else if b.has_g(921) {
            self.g92 = V3::zeros();
            self.g92_saved = None;
        } else if b.has_g(922) {
            self.g92_saved = Some(self.g92);
            self.g92 = V3::zeros();
        } else if b.has_g(923)
            && let Some(s) = self.g92_saved.take()
        {
            self.g92 = s;
        }
        // G5.3 is in LinuxCNC's group 0: it closes the block (cutting the
        // curve) before a G5.2 on the same line could open another.
        if b.has_g(53) {
            self.nurbs_g53(b, lineno, out)?;
        }
        Ok(axes_used)
    }
}

impl LineInterpreter for IsoInterpreter {
    fn line(&mut self, bytes: &[u8], lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        self.normalise(bytes, lineno)?;
        // Lines held for O-word structures are kept as text (comments may
        // hold any bytes; they are dropped when the line is run again).
        let text = || String::from_utf8_lossy(bytes).into_owned();
        if let Some(mut cap) = self.capture.take() {
            cap.lines.push((lineno, text()));
            let closes = match self.oline(lineno)? {
                Some(ol) => ol.label == cap.label && Some(ol.keyword) == closer_of(cap.opener),
                None => false,
            };
            if !closes {
                self.capture = Some(cap);
                return Ok(());
            }
            if cap.opener == OKeyword::Sub {
                let n = cap.lines.len();
                self.subs.insert(cap.label, Rc::new(cap.lines[1..n - 1].to_vec()));
            } else {
                self.exec_block(&cap.lines, out, 0)?;
            }
            return Ok(());
        }
        if self.norm.is_empty() {
            return Ok(());
        }
        if self.norm[0] != b'%'
            && let Some(ol) = self.oline(lineno)?
        {
            self.any_code_seen = true;
            return match ol.keyword {
                OKeyword::Call => self.call(&ol, lineno, out, 0),
                kw if closer_of(kw).is_some() => {
                    self.capture = Some(Capture {
                        label: ol.label,
                        opener: kw,
                        lines: vec![(lineno, text())],
                    });
                    Ok(())
                }
                kw => Err(GcodeError::at(
                    lineno,
                    format!("o{} {kw:?} without its opening line", label_text(&ol.label)).to_lowercase(),
                )),
            };
        }
        if self.norm[0] == b'%' {
            if self.norm.len() > 1 {
                // '%' with text after it is not the tape's delimiter but a
                // remark: Fusion 360's MPCNC post writes "% vfd enable" and
                // "% LED ON" between the code (LinuxCNC refuses the line).
                // Read as a delimiter, the first such line ended the
                // program before its first move.
                return Ok(());
            }
            // A '%' before any code opens the program; one after code ends it.
            if self.any_code_seen || self.percent_seen {
                self.ended = true;
                self.comp.dequeue(out);
            }
            self.percent_seen = true;
            return Ok(());
        }
        self.any_code_seen = true;
        let mut b = Block::new();
        self.parse_block(&mut b, lineno)?;
        self.execute(&b, lineno, out)
    }

    fn finish(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        self.comp.dequeue(out);
        if let Some(block) = &self.nurbs {
            // LinuxCNC would drop the block's control points unseen.
            return Err(GcodeError::at(
                lineno,
                format!(
                    "program ends inside the G5.2 NURBS block opened on line {} (no G5.3)",
                    block.opened
                ),
            ));
        }
        match &self.capture {
            Some(cap) if !self.ended => Err(GcodeError::at(
                lineno,
                format!(
                    "program ends inside o{} {:?} opened on line {}",
                    label_text(&cap.label),
                    cap.opener,
                    cap.lines.first().map_or(0, |l| l.0)
                )
                .to_lowercase(),
            )),
            _ => Ok(()),
        }
    }

    fn ended(&self) -> bool {
        self.ended
    }
}

#[cfg(test)]
#[path = "iso_tests.rs"]
mod tests;
