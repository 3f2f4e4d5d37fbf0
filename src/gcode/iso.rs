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
//! Cutter compensation (`comp.rs`), canned cycles (`cycles.rs`), rotary
//! axes A/B/C and the G93/G94/G95 feed modes are interpreted as LinuxCNC's
//! `rs274` does. What it cannot honour (lathe cycles, probing, threading,
//! splines) is an error naming the line.

#[path = "arcs.rs"]
mod arcs;
#[path = "comp.rs"]
mod comp;
#[path = "cycles.rs"]
mod cycles;
#[path = "splines.rs"]
pub(crate) mod splines;

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

/// Codes of one block, G and M codes kept as ten times their value
/// (G91.1 -> 911) so decimal codes compare exactly.
struct Block {
    g: [u16; 16],
    ng: usize,
    m: [u16; 8],
    nm: usize,
    /// Value of each letter word A..Z (G, M, N, O not stored here).
    w: [Option<f64>; 26],
    /// Polar coordinates: `@` radius and `^` angle (degrees).
    polar: [Option<f64>; 2],
    /// Any G code other than G0-G3: most blocks of a large program have
    /// none, and then the modal settings need no looking at.
    other_g: bool,
}

impl Block {
    fn new() -> Self {
        Block {
            g: [0; 16],
            ng: 0,
            m: [0; 8],
            nm: 0,
            w: [None; 26],
            polar: [None; 2],
            other_g: false,
        }
    }

    fn has_g(&self, code: u16) -> bool {
        self.g[..self.ng].contains(&code)
    }

    fn has_m(&self, code: u16) -> bool {
        self.m[..self.nm].contains(&code)
    }

    fn word(&self, letter: u8) -> Option<f64> {
        self.w[(letter - b'A') as usize]
    }
}

/// What each input byte becomes in a normalised line: 0 = dropped (blank),
/// 0xff = not allowed, `(` and `;` = comment starts, anything else = the
/// byte itself, upper-cased. A table keeps the per-byte work to one load.
const NORMALISE: [u8; 256] = {
    let mut t = [0xffu8; 256];
    let mut c = 0x21;
    while c <= 0x7e {
        t[c] = if c >= b'a' as usize && c <= b'z' as usize {
            c as u8 - 32
        } else {
            c as u8
        };
        c += 1;
    }
    t[b' ' as usize] = 0;
    t[b'\t' as usize] = 0;
    t[b'\r' as usize] = 0;
    t
};

/// Modal group of a G code (times ten), or `None` when unknown.
fn g_group(code: u16) -> Option<u8> {
    Some(match code {
        0
        | 10
        | 20
        | 30
        | 50..=53
        | 330
        | 331
        | 382..=385
        | 700
        | 710..=712
        | 720..=722
        | 730
        | 740
        | 760
        | 800..=890 => 1,
        40 | 100 | 280 | 281 | 300 | 301 | 520 | 530 | 920..=923 => 0,
        170 | 171 | 180 | 181 | 190 | 191 => 2,
        900 | 910 => 3,
        901 | 911 => 4,
        930 | 940 | 950 => 5,
        200 | 210 => 6,
        400 | 410 | 411 | 420 | 421 => 7,
        430 | 431 | 432 | 490 => 8,
        980 | 990 => 10,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => 12,
        610 | 611 | 640 => 13,
        960 | 970 => 14,
        70 | 80 => 15,
        _ => return None,
    })
}

/// Modal group of an M code, or `None` when unknown.
fn m_group(code: u16) -> Option<u8> {
    Some(match code {
        0 | 10 | 20 | 300 | 600 => 4,
        30 | 40 | 50 => 7,
        60 | 610 => 6,
        70 | 80 | 90 => 8,
        480 | 490 | 500 | 510 | 520 | 530 => 9,
        620..=680 | 700..=730 => 5,
        1000..=1990 => 10,
        _ => return None,
    })
}

fn fmt_code(letter: char, code: u16) -> String {
    if code.is_multiple_of(10) {
        format!("{letter}{}", code / 10)
    } else {
        format!("{letter}{}.{}", code / 10, code % 10)
    }
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
}

/// Lines of a control structure read so far, from its opening line.
struct Capture {
    label: Vec<u8>,
    opener: OKeyword,
    lines: Vec<(u64, String)>,
}

/// How a block of lines finished.
#[derive(Debug, PartialEq)]
enum Flow {
    Normal,
    Return,
    Break(Vec<u8>),
    Continue(Vec<u8>),
}

/// Most loop iterations a program may run, so a loop that never ends is an
/// error rather than a hang.
const MAX_ITERATIONS: u64 = 1_000_000;
/// Deepest subroutine nesting (LinuxCNC allows 10 levels of call).
const MAX_CALL_DEPTH: u32 = 64;

/// The keyword that closes a structure opened by `opener`.
fn closer_of(opener: OKeyword) -> Option<OKeyword> {
    Some(match opener {
        OKeyword::Sub => OKeyword::EndSub,
        OKeyword::While => OKeyword::EndWhile,
        OKeyword::Do => OKeyword::While,
        OKeyword::If => OKeyword::EndIf,
        OKeyword::Repeat => OKeyword::EndRepeat,
        _ => return None,
    })
}

fn label_text(l: &[u8]) -> String {
    String::from_utf8_lossy(l).to_lowercase()
}

impl IsoInterpreter {
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
        }
    }

    /// The O-word of the normalised line, if it is an O-word line (after an
    /// optional block delete and N word).
    fn oline(&self, lineno: u64) -> Result<Option<OLine>, GcodeError> {
        let mut c = Cursor::new(&self.norm);
        if c.peek() == Some(b'/') {
            c.pos += 1;
        }
        if c.peek() == Some(b'N') {
            c.pos += 1;
            if c.number().is_err() {
                return Ok(None);
            }
        }
        if c.peek() != Some(b'O') {
            return Ok(None);
        }
        let mut ol = oword::parse(&self.norm[c.pos..]).map_err(|e| GcodeError::at(lineno, e))?;
        ol.rest += c.pos;
        Ok(Some(ol))
    }

    /// Normalise `text` and evaluate the expression after its O keyword.
    fn o_value(&mut self, text: &str, lineno: u64) -> Result<Option<f64>, GcodeError> {
        self.normalise(text.as_bytes(), lineno)?;
        let ol = self
            .oline(lineno)?
            .ok_or_else(|| GcodeError::at(lineno, "expected an O-word line"))?;
        if ol.rest >= self.norm.len() {
            return Ok(None);
        }
        let mut c = Cursor::new(&self.norm[ol.rest..]);
        let v = c.real_value(&self.params).map_err(|e| GcodeError::at(lineno, e))?;
        if !c.at_end() {
            return Err(GcodeError::at(lineno, "unexpected text after the O-word expression"));
        }
        Ok(Some(v))
    }

    fn o_condition(&mut self, line: &(u64, String)) -> Result<bool, GcodeError> {
        let v = self
            .o_value(&line.1, line.0)?
            .ok_or_else(|| GcodeError::at(line.0, "this O-word needs a condition in [ ]"))?;
        Ok(v != 0.0)
    }

    fn count_iteration(&mut self, lineno: u64) -> Result<(), GcodeError> {
        self.iterations += 1;
        if self.iterations > MAX_ITERATIONS {
            return Err(GcodeError::at(
                lineno,
                format!("more than {MAX_ITERATIONS} loop iterations: is this loop endless?"),
            ));
        }
        Ok(())
    }

    /// Index of the next line after `from` that is an O-word with `label`
    /// and one of `keywords`.
    fn find_o(
        &mut self,
        lines: &[(u64, String)],
        from: usize,
        label: &[u8],
        keywords: &[OKeyword],
    ) -> Result<Option<(usize, OKeyword)>, GcodeError> {
        for (k, (ln, text)) in lines.iter().enumerate().skip(from + 1) {
            self.normalise(text.as_bytes(), *ln)?;
            if let Some(ol) = self.oline(*ln)?
                && ol.label == label
                && keywords.contains(&ol.keyword)
            {
                return Ok(Some((k, ol.keyword)));
            }
        }
        Ok(None)
    }

    fn must_find(
        &mut self,
        lines: &[(u64, String)],
        from: usize,
        label: &[u8],
        kw: OKeyword,
    ) -> Result<usize, GcodeError> {
        self.find_o(lines, from, label, &[kw])?.map(|(k, _)| k).ok_or_else(|| {
            GcodeError::at(
                lines[from].0,
                format!("o{} has no matching {kw:?}", label_text(label)).to_lowercase(),
            )
        })
    }

    /// Run a block of lines with O-word control flow.
    fn exec_block(
        &mut self,
        lines: &[(u64, String)],
        out: &mut VecDeque<Record>,
        depth: u32,
    ) -> Result<Flow, GcodeError> {
        let mut pc = 0;
        while pc < lines.len() {
            if self.ended {
                return Ok(Flow::Normal);
            }
            let (ln, text) = (lines[pc].0, &lines[pc].1);
            self.normalise(text.as_bytes(), ln)?;
            if self.norm.is_empty() || self.norm[0] == b'%' {
                pc += 1;
                continue;
            }
            let Some(ol) = self.oline(ln)? else {
                let b = self.parse_block(ln)?;
                self.execute(&b, ln, out)?;
                pc += 1;
                continue;
            };
            let label = ol.label.clone();
            match ol.keyword {
                OKeyword::Sub => {
                    let end = self.must_find(lines, pc, &label, OKeyword::EndSub)?;
                    self.subs.insert(label, Rc::new(lines[pc + 1..end].to_vec()));
                    pc = end + 1;
                }
                OKeyword::Call => {
                    self.call(&ol, ln, out, depth)?;
                    pc += 1;
                }
                OKeyword::If => {
                    let mut marks = vec![(pc, OKeyword::If)];
                    loop {
                        let last = marks.last().map_or(pc, |m| m.0);
                        match self.find_o(
                            lines,
                            last,
                            &label,
                            &[OKeyword::ElseIf, OKeyword::Else, OKeyword::EndIf],
                        )? {
                            Some((k, OKeyword::EndIf)) => {
                                marks.push((k, OKeyword::EndIf));
                                break;
                            }
                            Some(m) => marks.push(m),
                            None => {
                                return Err(GcodeError::at(ln, format!("o{} if has no endif", label_text(&label))));
                            }
                        }
                    }
                    let end = marks.last().map_or(pc, |m| m.0);
                    for w in marks.windows(2) {
                        let (k, kw) = w[0];
                        let take = kw == OKeyword::Else || self.o_condition(&lines[k])?;
                        if take {
                            let flow = self.exec_block(&lines[k + 1..w[1].0], out, depth)?;
                            if flow != Flow::Normal {
                                return Ok(flow);
                            }
                            break;
                        }
                    }
                    pc = end + 1;
                }
                OKeyword::While => {
                    let end = self.must_find(lines, pc, &label, OKeyword::EndWhile)?;
                    while self.o_condition(&lines[pc])? {
                        self.count_iteration(ln)?;
                        match self.exec_block(&lines[pc + 1..end], out, depth)? {
                            Flow::Break(l) if l == label => break,
                            Flow::Normal => {}
                            Flow::Continue(l) if l == label => {}
                            other => return Ok(other),
                        }
                        if self.ended {
                            break;
                        }
                    }
                    pc = end + 1;
                }
                OKeyword::Do => {
                    let end = self.must_find(lines, pc, &label, OKeyword::While)?;
                    loop {
                        self.count_iteration(ln)?;
                        match self.exec_block(&lines[pc + 1..end], out, depth)? {
                            Flow::Break(l) if l == label => break,
                            Flow::Normal => {}
                            Flow::Continue(l) if l == label => {}
                            other => return Ok(other),
                        }
                        if self.ended || !self.o_condition(&lines[end])? {
                            break;
                        }
                    }
                    pc = end + 1;
                }
                OKeyword::Repeat => {
                    let n = self
                        .o_value(text, ln)?
                        .ok_or_else(|| GcodeError::at(ln, "repeat needs a count in [ ]"))?;
                    let end = self.must_find(lines, pc, &label, OKeyword::EndRepeat)?;
                    let mut i = 0.0;
                    while i < n.round() {
                        self.count_iteration(ln)?;
                        match self.exec_block(&lines[pc + 1..end], out, depth)? {
                            Flow::Break(l) if l == label => break,
                            Flow::Normal => {}
                            Flow::Continue(l) if l == label => {}
                            other => return Ok(other),
                        }
                        if self.ended {
                            break;
                        }
                        i += 1.0;
                    }
                    pc = end + 1;
                }
                OKeyword::Break => return Ok(Flow::Break(label)),
                OKeyword::Continue => return Ok(Flow::Continue(label)),
                OKeyword::Return | OKeyword::EndSub => {
                    if depth == 0 {
                        return Err(GcodeError::at(ln, "return/endsub outside a subroutine"));
                    }
                    if let Some(v) = self.o_value(text, ln)? {
                        self.params.set(&ParamRef::Named(b"_VALUE".to_vec()), v);
                    }
                    return Ok(Flow::Return);
                }
                kw => {
                    return Err(GcodeError::at(
                        ln,
                        format!("o{} {kw:?} without its opening line", label_text(&label)).to_lowercase(),
                    ));
                }
            }
        }
        Ok(Flow::Normal)
    }

    /// `O<label> call [a] [b] ...`: arguments go to #1, #2 ..., which are
    /// local to the call (restored after it), as in LinuxCNC.
    fn call(&mut self, ol: &OLine, lineno: u64, out: &mut VecDeque<Record>, depth: u32) -> Result<(), GcodeError> {
        if depth >= MAX_CALL_DEPTH {
            return Err(GcodeError::at(
                lineno,
                format!("subroutine calls nested deeper than {MAX_CALL_DEPTH}"),
            ));
        }
        // The arguments first: reading a subroutine file reuses the line buffer.
        let mut args = Vec::new();
        let mut c = Cursor::new(&self.norm[ol.rest..]);
        while !c.at_end() {
            if args.len() >= 30 {
                return Err(GcodeError::at(lineno, "more than 30 subroutine arguments"));
            }
            args.push(c.real_value(&self.params).map_err(|e| GcodeError::at(lineno, e))?);
        }
        if !self.subs.contains_key(&ol.label) {
            self.load_sub_file(&ol.label, lineno, out, depth)?;
        }
        let body = self.subs.get(&ol.label).cloned().ok_or_else(|| {
            GcodeError::at(
                lineno,
                format!(
                    "o{} is called before its definition (define subroutines before calling them, or give the folder of {}.ngc with --subroutine-path)",
                    label_text(&ol.label),
                    label_text(&ol.label)
                ),
            )
        })?;
        let saved: Vec<f64> = (1..=30)
            .map(|i| self.params.get(&ParamRef::Num(i)).unwrap_or(0.0))
            .collect();
        for i in 1..=30 {
            self.params
                .set(&ParamRef::Num(i), args.get(i - 1).copied().unwrap_or(0.0));
        }
        self.params.push_frame();
        let flow = self.exec_block(&body, out, depth + 1);
        self.params.pop_frame();
        for (i, v) in saved.into_iter().enumerate() {
            self.params.set(&ParamRef::Num(i + 1), v);
        }
        match flow? {
            Flow::Normal | Flow::Return => Ok(()),
            Flow::Break(l) | Flow::Continue(l) => Err(GcodeError::at(
                lineno,
                format!("break/continue o{} escaped its subroutine", label_text(&l)),
            )),
        }
    }

    /// Define subroutine `label` from `label.ngc` in the first folder of
    /// the subroutine path that has it, as LinuxCNC does: the file's lines
    /// are run (they hold the `sub ... endsub`), so the definition exists
    /// after. Nothing when no folder has the file.
    fn load_sub_file(
        &mut self,
        label: &[u8],
        lineno: u64,
        out: &mut VecDeque<Record>,
        depth: u32,
    ) -> Result<(), GcodeError> {
        let name = format!("{}.ngc", label_text(label));
        let Some(path) = self.sub_path.iter().map(|d| d.join(&name)).find(|p| p.is_file()) else {
            return Ok(());
        };
        let text = std::fs::read(&path).map_err(|e| GcodeError::Io {
            line: lineno,
            source: e,
        })?;
        let lines: Vec<(u64, String)> = String::from_utf8_lossy(&text)
            .lines()
            .enumerate()
            .map(|(k, l)| (k as u64 + 1, l.trim_end_matches('\r').to_string()))
            .collect();
        self.exec_block(&lines, out, depth + 1)
            .map_err(|e| GcodeError::at(lineno, format!("in {}: {e}", path.display())))?;
        Ok(())
    }

    fn unit(&self) -> f64 {
        if self.inch { MM_PER_INCH } else { 1.0 }
    }

    /// Total origin offset (machine = program + offset), mm.
    fn offset(&self) -> V3 {
        self.g5x[self.cs] + self.g92
    }

    /// Fill `self.norm` with the line minus comments and blanks, upper-cased.
    fn normalise(&mut self, bytes: &[u8], lineno: u64) -> Result<(), GcodeError> {
        self.norm.clear();
        let mut i = 0;
        while i < bytes.len() {
            let c = bytes[i];
            i += 1;
            match NORMALISE[c as usize] {
                0 => {}
                b'(' => match bytes[i..].iter().position(|&c| c == b')') {
                    Some(k) => i += k + 1,
                    None => return Err(GcodeError::at(lineno, "comment '(' is not closed on this line")),
                },
                b';' => break,
                0xff => {
                    return Err(GcodeError::at(
                        lineno,
                        format!("character 0x{c:02x} is not allowed in G-code outside comments"),
                    ));
                }
                out => self.norm.push(out),
            }
        }
        Ok(())
    }

    fn parse_block(&mut self, lineno: u64) -> Result<Block, GcodeError> {
        let mut b = Block::new();
        self.assigns.clear();
        let norm = std::mem::take(&mut self.norm);
        let res = self.parse_words(&norm, &mut b, lineno);
        self.norm = norm;
        res.map(|_| b)
    }

    fn parse_words(&mut self, s: &[u8], b: &mut Block, lineno: u64) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let mut c = Cursor::new(s);
        if c.peek() == Some(b'/') {
            // Block delete switch is off (LinuxCNC's default): run the line.
            c.pos += 1;
        }
        if c.peek() == Some(b'N') {
            c.pos += 1;
            c.number().map_err(|e| err(format!("line number N: {e}")))?;
        }
        let mut groups_g = [false; 16];
        let mut groups_m = [false; 11];
        let mut g80 = false;
        while let Some(ch) = c.peek() {
            if ch == b'#' {
                let r = c.param_ref(&self.params).map_err(|e| err(e.to_string()))?;
                if c.peek() != Some(b'=') {
                    return Err(err(
                        "a parameter outside an expression must be assigned: '#n=value'".into()
                    ));
                }
                c.pos += 1;
                let v = c.real_value(&self.params).map_err(|e| err(e.to_string()))?;
                self.assigns.push((r, v));
                continue;
            }
            if ch == b'@' || ch == b'^' {
                c.pos += 1;
                let v = c
                    .real_value(&self.params)
                    .map_err(|e| err(format!("{} word: {e}", ch as char)))?;
                let slot = &mut b.polar[usize::from(ch == b'^')];
                if slot.is_some() {
                    return Err(err(format!("{} word repeated on one line", ch as char)));
                }
                *slot = Some(v);
                continue;
            }
            if !ch.is_ascii_uppercase() {
                return Err(err(format!(
                    "expected a word letter, found '{}'",
                    String::from_utf8_lossy(&s[c.pos..(c.pos + 8).min(s.len())])
                )));
            }
            c.pos += 1;
            let v = c
                .real_value(&self.params)
                .map_err(|e| err(format!("{} word: {e}", ch as char)))?;
            match ch {
                b'G' | b'M' => {
                    let t = (v * 10.0).round();
                    if (v * 10.0 - t).abs() > 1e-6 || !(0.0..=65535.0).contains(&t) {
                        return Err(err(format!("{}{v} is not a valid code", ch as char)));
                    }
                    let code = t as u16;
                    if ch == b'G' && code == 800 {
                        // LinuxCNC lets G80 share a line with another motion
                        // code (CAM preambles write `G0 G80`): the other wins.
                        g80 = true;
                        b.other_g = true;
                    } else if ch == b'G' {
                        let g = g_group(code).ok_or_else(|| err(format!("unknown G code {}", fmt_code('G', code))))?;
                        // Non-modal group 0 codes may share a line with each
                        // other only when they are different (G4 with G92...).
                        if g != 0 && groups_g[g as usize] {
                            return Err(err(format!("two G codes from modal group {g} on one line")));
                        }
                        groups_g[g as usize] = true;
                        if b.ng == b.g.len() {
                            return Err(err("too many G codes on one line".into()));
                        }
                        b.g[b.ng] = code;
                        b.ng += 1;
                        b.other_g |= !matches!(code, 0 | 10 | 20 | 30);
                    } else {
                        let g = m_group(code).ok_or_else(|| err(format!("unknown M code {}", fmt_code('M', code))))?;
                        if g != 10 && groups_m[g as usize] {
                            return Err(err(format!("two M codes from modal group {g} on one line")));
                        }
                        groups_m[g.min(10) as usize] = true;
                        if b.nm == b.m.len() {
                            return Err(err("too many M codes on one line".into()));
                        }
                        b.m[b.nm] = code;
                        b.nm += 1;
                    }
                }
                b'N' => return Err(err("N word must be at the start of the line".into())),
                b'O' => return Err(err("an O word must start the line".into())),
                _ => {
                    let slot = &mut b.w[(ch - b'A') as usize];
                    if slot.is_some() {
                        return Err(err(format!("{} word repeated on one line", ch as char)));
                    }
                    *slot = Some(v);
                }
            }
        }
        if g80 && !groups_g[1] {
            if b.ng == b.g.len() {
                return Err(err("too many G codes on one line".into()));
            }
            b.g[b.ng] = 800;
            b.ng += 1;
        }
        Ok(())
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
                52 | 53 => Some("NURBS blocks (G5.2, G5.3)"),
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

    /// LinuxCNC's check of words that mean nothing on their block
    /// (`G1 X1 I5`, a lone `R5`): each is an error with rs274's message,
    /// never silently ignored. The motion the block will make is its own
    /// group-1 code, or the modal one when it has axis words that no
    /// G10/G28/G30/G52/G92 takes.
    fn check_words(&self, b: &Block) -> Result<(), &'static str> {
        let has = |l: u8| b.word(l).is_some();
        if !(has(b'D')
            || has(b'H')
            || has(b'I')
            || has(b'J')
            || has(b'K')
            || has(b'L')
            || has(b'P')
            || has(b'Q')
            || has(b'R'))
        {
            return Ok(());
        }
        let has_axes = has(b'X') || has(b'Y') || has(b'Z') || b.polar.iter().any(Option::is_some);
        let covets = [100u16, 280, 300, 520, 920].iter().any(|&c| b.has_g(c));
        let motion = b.g[..b.ng]
            .iter()
            .copied()
            .find(|&c| g_group(c) == Some(1))
            .or(match self.motion {
                Some(m) if has_axes && !covets => Some(match m {
                    MotionMode::Rapid => 0,
                    MotionMode::Feed => 10,
                    MotionMode::Cw => 20,
                    MotionMode::Ccw => 30,
                    MotionMode::Cycle(c) | MotionMode::Spline(c) => c,
                }),
                _ => None,
            });
        let motion_in = |codes: &[u16]| motion.is_some_and(|m| codes.contains(&m));
        let cycle = motion.is_some_and(|m| (810..=890).contains(&m) || m == 730);
        let g10 = b.has_g(100);
        let comp = [410u16, 411, 420, 421].iter().any(|&c| b.has_g(c));
        let user_m = b.m[..b.nm].iter().any(|m| (1000..=1990).contains(m));
        let m_in = |codes: &[u16]| codes.iter().any(|&c| b.has_m(c));
        if has(b'D') && !comp && !b.has_g(960) {
            return Err("D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it");
        }
        if has(b'H') && !b.has_g(430) && !b.has_g(432) && !motion_in(&[760]) {
            return Err("H word with no G43 or G76 to use it");
        }
        if has(b'I') && !g10 && !motion_in(&[20, 30, 50, 51, 331, 760, 870]) {
            return Err("I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it");
        }
        if has(b'J') && !g10 && !motion_in(&[20, 30, 50, 51, 760, 870]) {
            return Err("J word with no G2, G3, G5, G5.1, G10, G76 or G87 to use it");
        }
        if has(b'K') && !motion_in(&[20, 30, 330, 331, 760, 870]) {
            return Err("K word with no G2, G3, G33, G33.1, G76, or G87 to use it");
        }
        if has(b'L') && !(cycle || g10 || comp || motion_in(&[760, 52]) || m_in(&[660, 980])) {
            return Err(
                "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code",
            );
        }
        if has(b'P')
            && !(g10
                || b.has_g(40)
                || b.has_g(640)
                || motion_in(&[760, 820, 860, 880, 890, 50, 52, 20, 30])
                || m_in(&[500, 510, 520, 530, 620, 630, 640, 650, 660, 190, 980])
                || user_m)
        {
            return Err(
                "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it",
            );
        }
        if has(b'Q')
            && !(g10 || b.has_g(640) || motion_in(&[830, 730, 50, 760]) || m_in(&[660, 670, 680, 610, 190]) || user_m)
        {
            return Err("Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it");
        }
        if has(b'R') && !(g10 || cycle || b.has_g(411) || b.has_g(421) || motion_in(&[20, 30, 760]) || m_in(&[190])) {
            return Err("R word with no g code that uses it");
        }
        Ok(())
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
        Ok(axes_used)
    }

    /// Step 22 and 23: the motion itself, then program stops.
    fn motion_step(
        &mut self,
        b: &Block,
        before: Option<MotionMode>,
        axes_used: bool,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let rotary = [b.word(b'A'), b.word(b'B'), b.word(b'C')];
        let has_rotary = rotary.iter().any(Option::is_some);
        let has_axes = b.word(b'X').is_some()
            || b.word(b'Y').is_some()
            || b.word(b'Z').is_some()
            || b.polar.iter().any(Option::is_some)
            || has_rotary;
        let g53 = b.has_g(530);
        self.abc_step = 0.0;
        if has_axes && self.motion != Some(MotionMode::Spline(50)) {
            // Only a G5 right after a G5 may leave out I and J.
            self.spline_pq = None;
        }
        if has_rotary {
            self.rotary_target(rotary, axes_used, g53, lineno)?;
        }
        if self.feed_mode == FeedMode::InverseTime
            && !axes_used
            && has_axes
            && matches!(self.motion, Some(MotionMode::Feed | MotionMode::Cw | MotionMode::Ccw))
            && b.word(b'F').is_none()
        {
            return Err(err("F word missing with an inverse time (G93) feed move".into()));
        }
        let arc_words =
            b.word(b'I').is_some() || b.word(b'J').is_some() || b.word(b'K').is_some() || b.word(b'R').is_some();
        if !axes_used {
            let explicit_motion = b.g[..b.ng].iter().any(|c| matches!(c, 0 | 10 | 20 | 30));
            match self.motion {
                Some(MotionMode::Cycle(code)) if has_axes || b.has_g(code) => {
                    let same = before == Some(MotionMode::Cycle(code));
                    self.canned_cycle(b, code, same, lineno, out)?;
                }
                Some(MotionMode::Spline(code)) if has_axes => {
                    self.spline(b, code, lineno, out)?;
                }
                Some(m @ (MotionMode::Cw | MotionMode::Ccw)) if has_axes || (explicit_motion && arc_words) => {
                    self.arc(b, m == MotionMode::Ccw, lineno, out)?;
                }
                Some(m) if has_axes => {
                    let to = self.target(b, g53, lineno)?;
                    self.straight(m == MotionMode::Rapid, to, lineno, out)?;
                }
                None if has_axes => {
                    return Err(err("axis words with no motion mode in effect (G80 or none set)".into()));
                }
                _ => {}
            }
        }
        if b.has_m(20) || b.has_m(300) {
            self.beam = false;
            self.ended = true;
            // The program end turns compensation off.
            self.comp_off(out);
        }
        Ok(())
    }

    /// A block's A, B, C words: where the rotary axes go (degrees; no
    /// offsets apply to them). Only straight and arc moves may turn them.
    fn rotary_target(
        &mut self,
        words: [Option<f64>; 3],
        axes_used: bool,
        g53: bool,
        lineno: u64,
    ) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        if axes_used {
            return Err(err(
                "rotary axis words (A, B, C) with G10, G28, G30, G52 or G92 are not supported: no rotary offsets or homes",
            ));
        }
        if !matches!(
            self.motion,
            Some(MotionMode::Rapid | MotionMode::Feed | MotionMode::Cw | MotionMode::Ccw)
        ) {
            return Err(err(
                "rotary axis words (A, B, C) are supported on G0, G1, G2 and G3 moves only",
            ));
        }
        if self.comp.side.is_some() {
            return Err(err(
                "rotary axis words (A, B, C) with cutter radius compensation on are not supported",
            ));
        }
        let mut to = self.abc;
        for (k, w) in words.iter().enumerate() {
            if let Some(v) = *w {
                to[k] = if self.incremental && !g53 { self.abc[k] + v } else { v };
            }
        }
        self.abc_step =
            ((to[0] - self.abc[0]).powi(2) + (to[1] - self.abc[1]).powi(2) + (to[2] - self.abc[2]).powi(2)).sqrt();
        self.abc = to;
        self.abc_used = true;
        Ok(())
    }

    /// The milling state every move carries: rotary axes once the program
    /// has used one, the tool in the spindle once one is named.
    fn tool_state(&self) -> ToolState {
        ToolState {
            abc: self.abc_used.then_some(self.abc),
            number: (self.tool_current != 0).then_some(self.tool_current),
            axis: None,
        }
    }

    /// The X and Y (machine frame, mm) that a block's polar words `@`
    /// (radius) and `^` (angle, degrees) give, from `base` (machine frame):
    /// about the origin of the coordinate system in use, absolute in G90,
    /// added to `base`'s own radius and angle in G91, as LinuxCNC does.
    fn polar_xy(&self, b: &Block, base: P3, incremental: bool, lineno: u64) -> Result<(f64, f64), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        if b.word(b'X').is_some() || b.word(b'Y').is_some() {
            return Err(err("X and Y words cannot be used with polar coordinates (@ ^)"));
        }
        if self.plane != Plane::Xy {
            return Err(err("polar coordinates (@ ^) work in the XY plane (G17) only"));
        }
        let u = self.unit();
        let off = self.offset();
        let (x, y) = ((base.x - off.x) / u, (base.y - off.y) / u);
        let (r0, a0) = (x.hypot(y), y.atan2(x));
        let [r, a] = b.polar;
        let (r, a) = if incremental {
            (r0 + r.unwrap_or(0.0), a0 + a.unwrap_or(0.0).to_radians())
        } else {
            (r.unwrap_or(r0), a.map_or(a0, f64::to_radians))
        };
        Ok((r * a.cos() * u + off.x, r * a.sin() * u + off.y))
    }

    /// End point of a move in the machine frame (mm).
    fn target(&self, b: &Block, g53: bool, lineno: u64) -> Result<P3, GcodeError> {
        let u = self.unit();
        let off = self.offset();
        let base = self.base_point();
        let mut to = base;
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.word(letter) {
                to[k] = if g53 {
                    if self.incremental {
                        return Err(GcodeError::at(lineno, "G53 cannot be used in incremental mode (G91)"));
                    }
                    v * u
                } else if self.incremental {
                    base[k] + v * u
                } else {
                    v * u + off[k]
                };
            }
        }
        if b.polar.iter().any(Option::is_some) {
            (to.x, to.y) = self.polar_xy(b, base, self.incremental, lineno)?;
        }
        Ok(to)
    }

    /// The feed of a G94/G95 move in mm/min (G95: F times the spindle
    /// speed); in G93 the F word itself (1/min), which the move's length
    /// turns into a feed ([`Self::inverse_time_feed`]).
    fn feed_mm_per_min(&self, lineno: u64) -> Result<f64, GcodeError> {
        let f = self.feed_mm_per_min;
        if f <= 0.0 {
            return Err(GcodeError::at(
                lineno,
                "feed move with no feed rate set (F is zero or missing)",
            ));
        }
        if self.feed_mode == FeedMode::PerRevolution {
            return match self.spindle_rpm {
                Some(rpm) if rpm > 0.0 => Ok(f * rpm),
                _ => Err(GcodeError::at(
                    lineno,
                    "feed per revolution (G95) with no spindle speed: set S first",
                )),
            };
        }
        Ok(f)
    }

    /// G93: the feed (mm/min, or degrees/min for a rotary-only move) that
    /// makes a move of `length_mm` take 1/F minutes, as LinuxCNC computes
    /// it: the XYZ length, or the rotary travel when XYZ do not move.
    fn inverse_time_feed(&self, length_mm: f64) -> f64 {
        let len = if length_mm > 1e-12 { length_mm } else { self.abc_step };
        self.feed_mm_per_min * len
    }

    fn straight(&mut self, rapid: bool, to: P3, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        if self.comp.active() {
            if !rapid {
                self.feed_mm_per_min(lineno)?;
                if self.feed_mode == FeedMode::InverseTime {
                    return Err(GcodeError::at(
                        lineno,
                        "inverse time feed (G93) with cutter radius compensation on is not supported",
                    ));
                }
            }
            return self.comp_straight(rapid, to, lineno, out);
        }
        self.comp.exit = false;
        let (kind, feed) = if rapid {
            (MotionKind::Rapid, None)
        } else {
            let f = self.feed_mm_per_min(lineno)?;
            let f = if self.feed_mode == FeedMode::InverseTime {
                self.inverse_time_feed((to - self.pos).norm())
            } else {
                f
            };
            (MotionKind::Line, Some(f))
        };
        let mut m = Motion::from_block(kind, to, feed, self.beam, lineno);
        m.tool = self.tool_state();
        out.push_back(Record::Move(m));
        self.pos = to;
        Ok(())
    }

    /// G92: make the current point have the given program coordinates.
    fn set_g92(&mut self, b: &Block, lineno: u64) -> Result<(), GcodeError> {
        let u = self.unit();
        let mut any = false;
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.word(letter) {
                any = true;
                // machine = program + g5x + g92  =>  g92 = machine - g5x - v
                self.g92[k] = self.pos[k] - self.g5x[self.cs][k] - v * u;
            }
        }
        if !any {
            return Err(GcodeError::at(lineno, "G92 needs at least one axis word"));
        }
        Ok(())
    }

    /// G10 L2 / L20: set a G5x origin.
    fn set_coordinate_data(&mut self, b: &Block, lineno: u64) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        let l = b.word(b'L').ok_or_else(|| err("G10 needs an L word"))?;
        let p = b.word(b'P').ok_or_else(|| err("G10 needs a P word"))?;
        if l != 2.0 && l != 20.0 {
            return Err(err("only G10 L2 and G10 L20 (coordinate system origins) are supported"));
        }
        // Range first: P is user data, and P0.5 or P-1 must not reach the
        // index arithmetic (found by fuzzing).
        if p.fract() != 0.0 || !(0.0..=9.0).contains(&p) {
            return Err(err("G10 P must be a whole number 0 to 9"));
        }
        let idx = if p == 0.0 { self.cs } else { p as usize - 1 };
        let u = self.unit();
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.word(letter) {
                self.g5x[idx][k] = if l == 2.0 {
                    v * u
                } else {
                    // L20: the current point gets coordinate v in that system.
                    self.pos[k] - self.g92[k] - v * u
                };
            }
        }
        Ok(())
    }

    fn home_position(&self, base: usize) -> P3 {
        let u = self.unit();
        let g = |k: usize| self.params.get(&ParamRef::Num(base + k)).unwrap_or(0.0) * u;
        P3::new(g(0), g(1), g(2))
    }

    /// G28/G30: rapid to the optional intermediate point, then to home on
    /// the axes named (all axes when none are).
    fn go_home(&mut self, b: &Block, home: P3, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        let named = [b'X', b'Y', b'Z'].map(|l| b.word(l).is_some());
        let end = if named.iter().any(|&n| n) {
            let mid = self.target(b, false, lineno)?;
            self.straight(true, mid, lineno, out)?;
            let mut end = mid;
            for k in 0..3 {
                if named[k] {
                    end[k] = home[k];
                }
            }
            end
        } else {
            if self.abc_used {
                // LinuxCNC homes the rotary axes too (#5164-#5166, #5184-#5186).
                let base = if b.has_g(280) { 5164 } else { 5184 };
                let old = self.abc;
                for k in 0..3 {
                    self.abc[k] = self.params.get(&ParamRef::Num(base + k)).unwrap_or(0.0);
                }
                self.abc_step = ((0..3).map(|k| (self.abc[k] - old[k]).powi(2)).sum::<f64>()).sqrt();
            }
            home
        };
        self.straight(true, end, lineno, out)
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
            // A '%' before any code opens the program; one after code ends it.
            if self.any_code_seen || self.percent_seen {
                self.ended = true;
                self.comp.dequeue(out);
            }
            self.percent_seen = true;
            return Ok(());
        }
        self.any_code_seen = true;
        let b = self.parse_block(lineno)?;
        self.execute(&b, lineno, out)
    }

    fn finish(&mut self, lineno: u64, out: &mut VecDeque<Record>) -> Result<(), GcodeError> {
        self.comp.dequeue(out);
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
mod tests {
    use super::*;
    use crate::gcode::{Dialect, read_str};
    use crate::geometry::P2;

    fn read(text: &str) -> Result<Vec<Record>, GcodeError> {
        let opts = ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        };
        read_str(text, &opts).map(|(_, r)| r)
    }

    fn moves(text: &str) -> Vec<Motion> {
        read(text)
            .unwrap()
            .into_iter()
            .filter_map(|r| match r {
                Record::Move(m) => Some(m),
                _ => None,
            })
            .collect()
    }

    fn close(a: &P3, b: [f64; 3]) -> bool {
        (a - P3::new(b[0], b[1], b[2])).norm() < 1e-9
    }

    #[test]
    fn lines_arcs_and_modes() {
        let m = moves("G21 G90 G17\nG0 X1 Y2\nG1 Z-1 F100\nX3\nG91 Y1\nG90 G2 X5 Y3 I1 J0\nG3 X3 Y3 R2\n");
        assert_eq!(m.len(), 6);
        assert!(close(&m[0].to, [1.0, 2.0, 0.0]) && m[0].kind == MotionKind::Rapid && m[0].feed.is_none());
        assert!(close(&m[1].to, [1.0, 2.0, -1.0]) && m[1].feed == Some(100.0));
        assert!(close(&m[2].to, [3.0, 2.0, -1.0]));
        assert!(close(&m[3].to, [3.0, 3.0, -1.0]));
        let MotionKind::Arc(a) = m[4].kind else {
            panic!("not an arc")
        };
        assert!(close(&a.center, [4.0, 3.0, -1.0]) && !a.ccw && a.plane == Plane::Xy);
        assert!(close(&m[4].to, [5.0, 3.0, -1.0]));
        let MotionKind::Arc(a) = m[5].kind else {
            panic!("not an arc")
        };
        assert!(a.ccw);
        assert!(((P2::new(5.0, 3.0) - Plane::Xy.project(&a.center)).norm() - 2.0).abs() < 1e-9);
        assert_eq!(m[5].block, Some(7));
    }

    #[test]
    fn inch_programs_become_millimetres() {
        let m = moves("G20 G0 X1 Y0.5\nG1 X2 F10\n");
        assert!(close(&m[0].to, [25.4, 12.7, 0.0]));
        assert_eq!(m[1].feed, Some(254.0));
    }

    #[test]
    fn feed_keeps_its_speed_across_unit_changes_as_in_linuxcnc() {
        // F is converted when set, before G20/G21 on the same line.
        let m = moves("G21 G1 X1 F600\nG20 X1\nG21 F300 G1 X2\n");
        let feeds: Vec<_> = m.iter().map(|m| m.feed.unwrap()).collect();
        assert!((feeds[0] - 600.0).abs() < 1e-9 && (feeds[1] - 600.0).abs() < 1e-9);
        assert!(
            (feeds[2] - 7620.0).abs() < 1e-9,
            "F300 is read in inches, before G21 applies: {feeds:?}"
        );
    }

    #[test]
    fn named_locals_do_not_leak_through_calls() {
        let m =
            moves("o<f> sub\n#<depth>=[#1*10]\nG0 X#<depth>\no<f> endsub\n#<depth>=5\no<f> call [1]\nG0 X#<depth>\n");
        assert!(close(&m[0].to, [10.0, 0.0, 0.0]) && close(&m[1].to, [5.0, 0.0, 0.0]));
    }

    #[test]
    fn planes_full_circles_helices_and_turns() {
        let m = moves("G0 X1 Y0 Z0\nG18 G2 X1 Z0 I-1 F60\nG19 G3 Y0 Z2 J0 K1\nG17 G2 X1 Y0 Z-1 I-1 P3\n");
        let MotionKind::Arc(a) = m[1].kind else { panic!() };
        assert_eq!(a.plane, Plane::Xz);
        assert!(close(&a.center, [0.0, 0.0, 0.0]) && !a.ccw);
        let MotionKind::Arc(a) = m[2].kind else { panic!() };
        assert_eq!(a.plane, Plane::Yz);
        assert!(close(&a.center, [1.0, 0.0, 1.0]));
        let MotionKind::Arc(a) = m[3].kind else { panic!() };
        assert_eq!(a.extra_turns, 2);
        assert!(close(&m[3].to, [1.0, 0.0, -1.0]));
    }

    #[test]
    fn parameters_expressions_and_named_parameters() {
        let m = moves("#1=2\n#<z_safe>=5\nG0 X#1 Y[#1*3] Z#<z_safe>\n#1=[#1+1] G0 X#1\nG0 X#1\n");
        assert!(close(&m[0].to, [2.0, 6.0, 5.0]));
        // The assignment takes effect after the line is read.
        assert!(close(&m[1].to, [2.0, 6.0, 5.0]));
        assert!(close(&m[2].to, [3.0, 6.0, 5.0]));
    }

    #[test]
    fn beam_follows_spindle_and_program_ends() {
        let recs = read("%\nS1000 M3\nG1 X1 F10\nM5\nG1 X2\nM30\nG1 X9\n%\n").unwrap();
        assert!(matches!(recs[0], Record::Spindle { rpm, .. } if rpm == 1000.0));
        let m: Vec<_> = recs.iter().filter_map(Record::motion).collect();
        assert_eq!(m.len(), 2, "nothing after M30 runs");
        assert!(m[0].beam && !m[1].beam);
    }

    #[test]
    fn offsets_keep_moves_continuous() {
        let m = moves("G0 X10\nG92 X0\nG0 X5\nG92.1\nG0 X1\nG10 L2 P2 X100\nG55 G0 X1\n");
        assert!(close(&m[1].to, [15.0, 0.0, 0.0]));
        assert!(close(&m[2].to, [1.0, 0.0, 0.0]));
        assert!(close(&m[3].to, [101.0, 0.0, 0.0]));
    }

    #[test]
    fn g52_sets_the_g92_offsets_as_linuxcnc() {
        // rs274: G52 X10 Y5 then G0 X1 Y1 is machine (11, 6); G52 X2 keeps Y.
        let m = moves("G0 X1 Y1\nG52 X10 Y5\nG0 X1 Y1\nG52 X2\nG0 X0\nG92 X0\nG0 X1\nG52 X0 Y0\nG0 X0 Y0\n");
        let to: Vec<[f64; 2]> = m.iter().map(|m| [m.to.x, m.to.y]).collect();
        assert_eq!(to, vec![[1.0, 1.0], [11.0, 6.0], [2.0, 6.0], [3.0, 6.0], [0.0, 0.0]]);
    }

    #[test]
    fn absolute_arc_centres() {
        let m = moves("G90.1 G0 X1 Y0\nG3 X-1 Y0 I0 J0 F10\n");
        let MotionKind::Arc(a) = m[1].kind else { panic!() };
        assert!(close(&a.center, [0.0, 0.0, 0.0]));
    }

    #[test]
    fn rotary_axes_are_carried_on_every_later_move() {
        let m = moves("G0 X1 Y0 Z0\nT3 M6\nG0 A90\nG91 G1 X1 B-45 C10 F100\nG90 G3 X3 Y1 I0 J1 A0\nG1 X4\nG28\n");
        assert_eq!(m[0].tool.abc, None, "before any rotary word");
        assert_eq!(m[0].tool.number, None, "no tool before M6");
        assert_eq!(m[1].tool.number, Some(3));
        assert!(close(&m[1].to, [1.0, 0.0, 0.0]) && m[1].tool.abc == Some([90.0, 0.0, 0.0]));
        assert_eq!(m[2].tool.abc, Some([90.0, -45.0, 10.0]), "G91 adds");
        assert!(matches!(m[3].kind, MotionKind::Arc(_)) && m[3].tool.abc == Some([0.0, -45.0, 10.0]));
        assert_eq!(m[4].tool.abc, Some([0.0, -45.0, 10.0]), "unchanged axes are carried");
        assert_eq!(
            m.last().unwrap().tool.abc,
            Some([0.0; 3]),
            "G28 homes the rotary axes too"
        );
        // Degrees stay degrees in an inch program.
        let m = moves("G20 G0 X1 A30\n");
        assert!(close(&m[0].to, [25.4, 0.0, 0.0]) && m[0].tool.abc == Some([30.0, 0.0, 0.0]));
    }

    #[test]
    fn feed_modes_as_linuxcnc() {
        // G93: the feed that makes the move take 1/F minutes; a rotary-only
        // move counts its degrees; F is no length and ignores G20.
        let m = moves("G0 X0 Y0\nG93 G1 X10 F2\nG2 X20 Y0 I5 J0 F4\nG1 A90 F1\nG20 G1 X1 F3\nG21 G94 G1 X0 F50\n");
        let feeds: Vec<f64> = m.iter().skip(1).map(|m| m.feed.unwrap()).collect();
        // F on the G21 line is read in inches, as LinuxCNC does.
        let want = [
            20.0,
            4.0 * 5.0 * std::f64::consts::PI,
            90.0,
            (25.4 - 20.0) * 3.0,
            50.0 * 25.4,
        ];
        for (f, w) in feeds.iter().zip(want) {
            assert!((f - w).abs() < 1e-9, "{feeds:?}");
        }
        // G95: F per revolution times the spindle speed in force.
        let m = moves("S2000 M3\nG95 G1 X1 F0.01\nS500\nG1 X2\nG20\nG1 X1 F0.001\n");
        let feeds: Vec<f64> = m.iter().map(|m| m.feed.unwrap()).collect();
        assert_eq!(feeds.len(), 3);
        assert!(
            (feeds[0] - 20.0).abs() < 1e-9 && (feeds[1] - 5.0).abs() < 1e-9,
            "{feeds:?}"
        );
        assert!((feeds[2] - 0.001 * 25.4 * 500.0).abs() < 1e-9, "{feeds:?}");
    }

    #[test]
    fn what_we_cannot_honour_is_an_error_naming_the_line() {
        let cases = [
            ("G1 X1 F10\nG41 D1\n", 2, "cutter radius compensation"),
            ("G81 X1 Y1 Z-1 R1\n", 1, "no feed rate"),
            ("O100 call\n", 1, "before its definition"),
            ("o1 while [1]\no1 endwhile\n", 1, "endless"),
            ("o1 if [1]\nG0 X1\n", 2, "ends inside o1 if"),
            ("o1 endif\n", 1, "without its opening line"),
            ("G0 W10\n", 1, "W is not supported"),
            ("G92 A10\n", 1, "no rotary offsets"),
            ("G1 X1 F10\nG81 X1 Z-1 R1 A10\n", 2, "G0, G1, G2 and G3 moves only"),
            ("G0 X0\nG41.1 D1\nG1 X5 F10\nG1 X10 A5\n", 4, "compensation on"),
            ("G93 G1 X1 F2\nG1 X2\n", 2, "F word missing"),
            ("G93 G1 X1 F2\nG81 X1 Z-1 R1 F3\n", 2, "inverse time"),
            ("G95 G1 X1 F0.1\n", 1, "no spindle speed"),
            ("G1 X1 F10\nG94\nG1 X2\n", 3, "no feed rate"),
            ("G1 X1\n", 1, "no feed rate"),
            ("G0 X0 Y0\nG2 X2 Y0 I0.5 F10\n", 2, "not on the circle"),
            ("G2 X0 Y1 R0.1 F1\n", 1, "too small"),
            ("G0 G1 X1\n", 1, "modal group 1"),
            ("G0 X1 X2\n", 1, "repeated"),
            ("G0 X[1+\n", 1, "X word"),
            ("G0 X1 (unclosed\n", 1, "not closed"),
            ("G80\nX1\n", 2, "no motion mode"),
            ("G12\n", 1, "unknown G code G12"),
            ("G10 L2 P0.5 X1\n", 1, "G10 P must be"),
            ("G10 L2 P-1 X1\n", 1, "G10 P must be"),
            ("G2 X1 F1\n", 1, "needs R or"),
        ];
        for (text, line, needle) in cases {
            let e = read(text).unwrap_err();
            assert_eq!(e.line(), line, "{text:?}: {e}");
            assert!(e.to_string().contains(needle), "{text:?}: {e}");
        }
    }

    #[test]
    fn stray_bytes_in_comments_are_harmless_and_elsewhere_named() {
        let opts = ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        };
        let ok: &[u8] = b"G0 X1 (caf\xe9 \xff)\nG0 X2 ; \xfe\n";
        let recs: Vec<_> = crate::gcode::ProgramReader::new(ok, &opts).unwrap().collect();
        assert_eq!(recs.len(), 2);
        assert!(recs.iter().all(|r| r.is_ok()));
        let bad: &[u8] = b"G0 X1\nG0 X\xe92\n";
        let e = crate::gcode::ProgramReader::new(bad, &opts)
            .unwrap()
            .find_map(|r| r.err())
            .unwrap();
        assert_eq!(e.line(), 2);
        assert!(e.to_string().contains("0xe9"), "{e}");
    }

    #[test]
    fn subroutines_loops_and_conditions() {
        let text = "o<side> sub\n  G1 X[#1] Y[#2] F100\no<side> endsub\n\
                    #1=99\n#<i>=0\n\
                    o10 while [#<i> LT 3]\n  o<side> call [#<i>] [#<i>*2]\n\
                    o11 if [#<i> EQ 1]\n G0 Z1\n o11 elseif [#<i> EQ 2]\n G0 Z2\n o11 else\n G0 Z9\n o11 endif\n\
                    #<i>=[#<i>+1]\no10 endwhile\n\
                    o20 repeat [2]\n G0 X-1\no20 endrepeat\n\
                    o30 do\n #<i>=[#<i>-1]\n o31 if [#<i> EQ 1]\n  o30 break\n o31 endif\no30 while [#<i> GT 0]\n\
                    G0 X#1 Y#<i>\n";
        let m = moves(text);
        let to: Vec<[f64; 3]> = m.iter().map(|m| [m.to.x, m.to.y, m.to.z]).collect();
        assert_eq!(
            to,
            vec![
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 9.0],
                [1.0, 2.0, 9.0],
                [1.0, 2.0, 1.0],
                [2.0, 4.0, 1.0],
                [2.0, 4.0, 2.0],
                [-1.0, 4.0, 2.0],
                [-1.0, 4.0, 2.0],
                [99.0, 1.0, 2.0],
            ]
        );
    }

    #[test]
    fn subroutines_come_from_files_on_the_subroutine_path() {
        let dir = std::env::temp_dir().join(format!("microcam-subpath-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("side.ngc"), "o<side> sub\nG1 X#1 F10\no<side> endsub\n").unwrap();
        let mut opts = ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        };
        let text = "o<side> call [3]\no<side> call [4]\n";
        let e = read_str(text, &opts).unwrap_err();
        assert!(e.to_string().contains("--subroutine-path") && e.line() == 1, "{e}");
        opts.subroutine_path = vec![dir.join("missing"), dir.clone()];
        let (_, recs) = read_str(text, &opts).unwrap();
        let xs: Vec<f64> = recs.iter().filter_map(Record::motion).map(|m| m.to.x).collect();
        assert_eq!(xs, vec![3.0, 4.0]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_badge_sample_reads_in_every_plane() {
        let text = include_str!("../../testdata/gcode/badge.ngc");
        let recs = read(text).unwrap();
        let arcs = recs
            .iter()
            .filter(|r| {
                matches!(
                    r,
                    Record::Move(Motion {
                        kind: MotionKind::Arc(_),
                        ..
                    })
                )
            })
            .count();
        assert_eq!(arcs, 8, "{arcs} arcs");
    }
}
