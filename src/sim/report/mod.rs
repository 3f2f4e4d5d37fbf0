//! The gsim simulation: one pass over a toolpath through the path summary,
//! the time model, the beam model and the removal engine
//! ([`super::removal`]), with the per-block series written as it goes.
//! Constant memory apart from one record per cut. The JSON report is
//! written by [`super::gsim_json`].

use super::beam::{BeamModel, CommandTiming, EXAMPLES};
use super::picture::Overlay;
use super::removal::{CutBlock, CutMove, Engine};
use super::stock::Stock;
use super::summary::PathSummary;
use super::time::{Event, Limit, MotionBlock, MoveClass, TimeModel, TimedBlock};
use crate::cutter::Cutter;
use crate::formats::{push_num, push_uint};
use crate::geometry::{BBox3, P3, V3};
use crate::machine::{Controller, Machine};
use crate::model::toolpath::{Header, MotionKind, Record};
use std::io::Write;
use thiserror::Error;

pub use super::gsim_json::{GsimReport, SCHEMA};

/// A program the machine must not run, or a failed write of the series.
#[derive(Debug, Error)]
pub enum SimError {
    /// A record read from a source line the machine must not run.
    #[error("line {line}: {msg}")]
    Line {
        /// The source line (1-based).
        line: u64,
        /// What is wrong with it.
        msg: String,
    },
    /// The same for a record with no source line (a toolpath record).
    #[error("record {index}: {msg}")]
    Record {
        /// The record's position in the input, 1-based.
        index: u64,
        /// What is wrong with it.
        msg: String,
    },
    /// Writing a CSV series failed.
    #[error("block series: {0}")]
    Io(#[from] std::io::Error),
}

/// The header row of the `--blocks` CSV.
pub const BLOCKS_HEADER: &str = "line,kind,length_mm,commanded_feed_mm_s,achieved_feed_mm_s,time_s,limited_by\n";

/// A block that did not reach its feed, for the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Example {
    /// Its source line.
    pub line: Option<u64>,
    /// Its path length, mm.
    pub length_mm: f64,
    /// The feed it was meant to run at, mm/s.
    pub commanded_feed_mm_s: f64,
    /// The feed it peaked at, mm/s.
    pub achieved_feed_mm_s: f64,
    /// Why it fell short.
    pub limited_by: Limit,
}

/// Time figures.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TimeStats {
    /// Time from the program's start to rest after its last move or dwell,
    /// s: cutting, rapid and dwell times add up to it.
    pub cycle_time_s: f64,
    /// Time in feed moves (lines and arcs), s.
    pub cutting_time_s: f64,
    /// Time in rapids, s.
    pub rapid_time_s: f64,
    /// Time in dwells, s.
    pub dwell_time_s: f64,
    /// Feed-move length over commanded feed: the time a program "should" take.
    pub ideal_cutting_time_s: f64,
    /// Feed moves timed.
    pub feed_blocks: u64,
    /// Of those, the ones that did not reach their commanded feed.
    pub limited_blocks: u64,
    /// Limited blocks per reason, indexed as [`Limit::ALL`].
    pub limited_by: [u64; Limit::ALL.len()],
    /// The first [`EXAMPLES`] limited blocks.
    pub examples: Vec<Example>,
    /// The lowest peak feed of a feed move with length, mm/s (`None`
    /// without one).
    pub min_achieved_feed_mm_s: Option<f64>,
}

/// Material removal figures.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RemovalStats {
    /// Stock volume before the program, mm³.
    pub initial_volume_mm3: f64,
    /// Volume the program removed, mm³.
    pub removed_volume_mm3: f64,
    /// The most one block removed, mm³.
    pub max_block_volume_mm3: f64,
    /// That block's source line.
    pub max_block_line: Option<u64>,
    /// Rapids that removed material (a crash on a real machine).
    pub rapids_in_material: u64,
    /// Source lines of the first [`EXAMPLES`] of those rapids.
    pub rapid_lines: Vec<u64>,
}

/// Per-step chip volume (Bayesteh (2013) §3.1): moves are cut in steps of feed
/// per tooth × `scale`.
#[derive(Debug, Clone, PartialEq)]
pub struct StepPlan {
    /// Teeth of the cutter.
    pub flutes: u32,
    /// Step length in feeds per tooth (the thesis uses 10).
    pub scale: f64,
    /// Spindle speed overriding the program's S words, rpm.
    pub rpm: Option<f64>,
}

/// The engine, its stock and the per-block removal series.
pub struct Removal<W: Write> {
    /// The removal engine on a height-field stock.
    pub engine: Engine<Stock>,
    /// Where the per-block removal CSV goes (`--removal`).
    pub csv: Option<W>,
    /// The figures so far.
    pub stats: RemovalStats,
    /// Cut feed moves in steps of feed per tooth, when asked.
    pub steps: Option<StepPlan>,
    /// Where the per-step CSV goes (`--steps`).
    pub steps_csv: Option<W>,
    /// The program's spindle speed so far, rpm.
    pub rpm: Option<f64>,
    /// The CSV header depends on whether steps are on: written with the
    /// first row.
    header_written: bool,
    /// The path drawn for `--png`.
    pub overlay: Option<Overlay>,
    /// The cutter of each tool number, when each section of the program
    /// cuts with its own tool ([`Simulator::with_tool_cutters`]); empty
    /// when one cutter cuts everything.
    pub tools: std::collections::BTreeMap<u32, Cutter>,
    /// The tool whose cutter is in the engine.
    pub tool: Option<u32>,
}

/// Most steps one block may be cut in with `--flutes` (per block, so the
/// work stays proportional to the program).
pub const MAX_STEPS_PER_BLOCK: f64 = 1e6;

/// The header row of the `--steps` CSV.
pub const STEPS_HEADER: &str = "line,step,x_mm,y_mm,z_mm,step_length_mm,chip_volume_mm3\n";

/// The header row of the `--removal` CSV.
pub const REMOVAL_HEADER: &str = "line,kind,length_mm,removed_volume_mm3,removed_per_length_mm2";
/// Columns added to the `--removal` CSV when moves are cut in steps.
pub const REMOVAL_STEP_COLUMNS: &str = ",steps,mean_step_volume_mm3,max_step_volume_mm3";

/// The whole simulation, fed one record at a time.
pub struct Simulator<W: Write> {
    machine: Machine,
    feed_factor: f64,
    pos: P3,
    /// Rotary axes after the last move that carried them (degrees).
    abc: Option<[f64; 3]>,
    index: u64,
    summary: PathSummary,
    time: TimeModel,
    beam: BeamModel,
    stats: TimeStats,
    blocks_csv: Option<W>,
    row: String,
    removal: Option<Removal<W>>,
}

impl<W: Write> Simulator<W> {
    /// `timing` is how the program's shutter commands were written (PMAC);
    /// look-ahead controllers always switch at the block boundary.
    pub fn new(header: &Header, machine: Machine, timing: CommandTiming, start: P3, blocks_csv: Option<W>) -> Self {
        let timing = match machine.controller {
            Controller::Pmac => timing,
            Controller::Lookahead => CommandTiming::Boundary,
        };
        let mut csv = blocks_csv;
        let row = String::with_capacity(128);
        if let Some(w) = csv.as_mut() {
            // A failed header write surfaces on the first row.
            let _ = w.write_all(BLOCKS_HEADER.as_bytes());
        }
        Simulator {
            feed_factor: header.feed_unit.to_mm_per_s(),
            pos: start,
            abc: None,
            index: 0,
            summary: PathSummary::new(header.feed_unit, start),
            time: TimeModel::new(&machine),
            beam: BeamModel::new(&machine.shutter_or_instant(), timing),
            stats: TimeStats::default(),
            blocks_csv: csv,
            row,
            machine,
            removal: None,
        }
    }

    /// Also remove material from `stock` with `cutter`, writing the
    /// per-block volumes to `csv`.
    pub fn with_removal(mut self, stock: Stock, cutter: Cutter, csv: Option<W>) -> Self {
        let stats = RemovalStats {
            initial_volume_mm3: stock.volume(),
            ..Default::default()
        };
        self.removal = Some(Removal {
            engine: Engine::new(stock, cutter),
            csv,
            stats,
            steps: None,
            steps_csv: None,
            rpm: None,
            header_written: false,
            overlay: None,
            tools: std::collections::BTreeMap::new(),
            tool: None,
        });
        self
    }

    /// Cut each move with the cutter of its tool number (`tool` in the
    /// toolpath): a tool change switches the cutter. Moves before the
    /// first tool number cut with the cutter given to
    /// [`Self::with_removal`]; a move of a tool not in `tools` is an error
    /// naming its line. Call after [`Self::with_removal`].
    pub fn with_tool_cutters(mut self, tools: std::collections::BTreeMap<u32, Cutter>) -> Self {
        if let Some(r) = self.removal.as_mut() {
            r.tools = tools;
        }
        self
    }

    /// Draw the path for a picture. Call after [`Self::with_removal`].
    pub fn with_picture(mut self) -> Self {
        if let Some(r) = self.removal.as_mut() {
            r.overlay = Some(Overlay::for_stock(&r.engine.stock));
        }
        self
    }

    /// Cut feed moves in steps of feed per tooth × scale and write each
    /// step's chip volume to `csv`. Call after [`Self::with_removal`].
    pub fn with_steps(mut self, plan: StepPlan, mut csv: Option<W>) -> Self {
        if let Some(r) = self.removal.as_mut() {
            if let Some(w) = csv.as_mut() {
                let _ = w.write_all(STEPS_HEADER.as_bytes());
            }
            r.steps = Some(plan);
            r.steps_csv = csv;
        }
        self
    }

    fn err(&self, line: Option<u64>, msg: String) -> SimError {
        match line {
            Some(line) => SimError::Line { line, msg },
            None => SimError::Record { index: self.index, msg },
        }
    }

    /// Check that `bb` lies within the machine's travel.
    fn check_limits(&self, bb: &BBox3, line: Option<u64>) -> Result<(), SimError> {
        let (Some(lo), Some(hi)) = (self.machine.limits_min_mm, self.machine.limits_max_mm) else {
            return Ok(());
        };
        const TOL: f64 = 1e-9;
        for i in 0..3 {
            let axis = "XYZ".as_bytes()[i] as char;
            let (a, b) = (bb.min[i], bb.max[i]);
            if a < lo[i] - TOL || b > hi[i] + TOL {
                let v = if a < lo[i] - TOL { a } else { b };
                let mut s = String::new();
                push_num(&mut s, v);
                let mut r = String::new();
                push_num(&mut r, lo[i]);
                r.push_str("..");
                push_num(&mut r, hi[i]);
                return Err(self.err(
                    line,
                    format!("move reaches {axis}{s}, outside the machine's travel {axis} {r} mm"),
                ));
            }
        }
        Ok(())
    }

    /// The next record: summarised, timed, and cut from the stock when
    /// removal is on; finished blocks' rows go to the series. A move outside
    /// the machine's travel, a feed move without a positive feed, an arc of
    /// zero radius, a negative dwell or a tool with no cutter is an error
    /// naming its line.
    pub fn add(&mut self, rec: &Record) -> Result<(), SimError> {
        self.index += 1;
        self.summary.add(rec);
        match rec {
            Record::Move(m) => {
                let from = self.pos;
                let delta = m.to - from;
                let (class, feed) = match m.kind {
                    MotionKind::Rapid => (MoveClass::Rapid, 0.0),
                    MotionKind::Line | MotionKind::Arc(_) => {
                        let class = if matches!(m.kind, MotionKind::Line) {
                            MoveClass::Line
                        } else {
                            MoveClass::Arc
                        };
                        match m.feed {
                            Some(f) if f > 0.0 && f.is_finite() => (class, f * self.feed_factor),
                            Some(f) => return Err(self.err(m.block, format!("feed move with feed {f}"))),
                            None => return Err(self.err(m.block, "feed move without a feed".into())),
                        }
                    }
                };
                let mut block = match m.kind {
                    MotionKind::Arc(a) => {
                        let arc = a
                            .arc(from, m.to)
                            .ok_or_else(|| self.err(m.block, "arc of zero radius".into()))?;
                        self.check_limits(&arc.bbox(), m.block)?;
                        let len = arc.length();
                        MotionBlock {
                            line: None,
                            class,
                            length_mm: len,
                            feed_mm_s: feed,
                            dir_in: arc.tangent_at(0.0).unwrap_or(V3::zeros()),
                            dir_out: arc.tangent_at(1.0).unwrap_or(V3::zeros()),
                            radius_mm: arc.radius(),
                            delta,
                            end: m.to,
                            beam: false,
                            beam_switch: None,
                            chain: None,
                            rotary_deg: 0.0,
                        }
                    }
                    _ => {
                        self.check_limits(&BBox3::from_points(&[from, m.to]), m.block)?;
                        MotionBlock::straight(class, delta, feed)
                    }
                };
                block.line = m.block;
                block.end = m.to;
                block.beam = m.beam;
                block.beam_switch = m.beam_switch;
                block.chain = m.chain;
                if let Some(abc) = m.tool.abc {
                    let old = self.abc.unwrap_or([0.0; 3]);
                    block.rotary_deg = ((0..3).map(|k| (abc[k] - old[k]).powi(2)).sum::<f64>()).sqrt();
                    self.abc = Some(abc);
                }
                if let Some(n) = m.tool.number {
                    let switch = match self.removal.as_ref() {
                        Some(r) if !r.tools.is_empty() && r.tool != Some(n) => Some(r.tools.get(&n).copied()),
                        _ => None,
                    };
                    match switch {
                        Some(Some(c)) => {
                            if let Some(r) = self.removal.as_mut() {
                                // Cut what the old tool has queued with it.
                                r.flush()?;
                                r.engine.cutter = c;
                                r.tool = Some(n);
                            }
                        }
                        Some(None) => {
                            return Err(self.err(
                                m.block,
                                format!(
                                    "tool T{n} has no cutter: it is neither in the tool table (with a diameter) nor in the program's tool comments; --tool sets one cutter for the whole program"
                                ),
                            ));
                        }
                        None => {}
                    }
                }
                if let Some(r) = self.removal.as_mut() {
                    let index = self.index;
                    r.cut(&block, &from, &m.to, &m.kind).map_err(|e| match e {
                        SimError::Record { msg, .. } => SimError::Record { index, msg },
                        e => e,
                    })?;
                }
                self.pos = m.to;
                self.time.push_move(block);
            }
            Record::Dwell { seconds, block } => {
                if !(seconds.is_finite() && *seconds >= 0.0) {
                    return Err(self.err(*block, format!("dwell of {seconds} s")));
                }
                self.time.push_dwell(*seconds, *block);
            }
            Record::Accel { ta_ms, ts_ms, .. } => self.time.set_accel(*ta_ms, *ts_ms),
            Record::Spindle { rpm, .. } => {
                if let Some(r) = self.removal.as_mut() {
                    r.rpm = Some(*rpm);
                }
            }
            Record::Var { .. } => {}
        }
        self.drain()
    }

    fn drain(&mut self) -> Result<(), SimError> {
        while let Some(ev) = self.time.pop() {
            match &ev {
                Event::Block(tb) => {
                    self.account(tb);
                    self.beam.add_block(tb);
                }
                Event::Dwell { t_start_s, seconds, .. } => {
                    self.stats.dwell_time_s += seconds;
                    self.beam.add_dwell(*t_start_s, *seconds);
                }
            }
            if let Some(w) = self.blocks_csv.as_mut() {
                self.row.clear();
                csv_row(&mut self.row, &ev);
                w.write_all(self.row.as_bytes())?;
            }
        }
        Ok(())
    }

    fn account(&mut self, tb: &TimedBlock) {
        let s = &mut self.stats;
        if tb.block.class == MoveClass::Rapid {
            s.rapid_time_s += tb.time_s;
            return;
        }
        s.cutting_time_s += tb.time_s;
        s.ideal_cutting_time_s += tb.block.length_mm / tb.block.feed_mm_s;
        s.feed_blocks += 1;
        if tb.block.length_mm > 0.0 {
            let f = tb.achieved_feed_mm_s;
            s.min_achieved_feed_mm_s = Some(s.min_achieved_feed_mm_s.map_or(f, |m| m.min(f)));
        }
        if tb.limited_by != Limit::None {
            s.limited_blocks += 1;
            if let Some(i) = Limit::ALL.iter().position(|l| *l == tb.limited_by) {
                s.limited_by[i] += 1;
            }
            if s.examples.len() < EXAMPLES {
                s.examples.push(Example {
                    line: tb.block.line,
                    length_mm: tb.block.length_mm,
                    commanded_feed_mm_s: tb.commanded_feed_mm_s,
                    achieved_feed_mm_s: tb.achieved_feed_mm_s,
                    limited_by: tb.limited_by,
                });
            }
        }
    }

    /// Keep what [`GsimReport::with_drawing`] needs to match cuts to chains.
    pub fn with_chain_probes(mut self) -> Self {
        self.beam.keep_probes = true;
        self
    }

    /// Machine time simulated so far, s (for progress reports).
    pub fn machine_time_s(&self) -> f64 {
        self.time.now_s()
    }

    /// Bring the machine to rest and close the books.
    /// Returns the report and the series writers (blocks, removal, steps)
    /// for the caller to commit.
    pub fn finish(mut self) -> Result<(GsimReport, [Option<W>; 3]), SimError> {
        self.time.finish();
        self.drain()?;
        let t_end = self.time.now_s();
        self.beam.finish();
        self.stats.cycle_time_s = t_end;
        if let Some(w) = self.blocks_csv.as_mut() {
            w.flush()?;
        }
        let (removal, removal_csv, steps_csv, picture) = match self.removal {
            Some(mut r) => {
                r.flush()?;
                for w in [r.csv.as_mut(), r.steps_csv.as_mut()].into_iter().flatten() {
                    w.flush()?;
                }
                (Some((r.stats, r.engine.stock)), r.csv, r.steps_csv, r.overlay)
            }
            None => (None, None, None, None),
        };
        Ok((
            GsimReport {
                machine: self.machine,
                summary: self.summary,
                time: self.stats,
                beam: self.beam,
                drawing: None,
                removal,
                picture,
            },
            [self.blocks_csv, removal_csv, steps_csv],
        ))
    }
}

impl<W: Write> Removal<W> {
    /// Length of one step for `block`, when steps are asked for.
    fn step_length(&self, block: &MotionBlock) -> Result<Option<f64>, SimError> {
        let Some(plan) = &self.steps else { return Ok(None) };
        if block.class == MoveClass::Rapid {
            return Ok(None);
        }
        let rpm = plan.rpm.or(self.rpm).filter(|r| *r > 0.0).ok_or_else(|| {
            let msg = "chip volume per step needs a spindle speed (S in the program, or --rpm)".to_string();
            match block.line {
                Some(line) => SimError::Line { line, msg },
                None => SimError::Record { index: 0, msg },
            }
        })?;
        let per_tooth = block.feed_mm_s / (rpm / 60.0 * plan.flutes as f64);
        let step = per_tooth * plan.scale;
        // Bounded work: estimate the steps before cutting them and refuse,
        // with the estimate, what no one could want (a 1e-12 scale would
        // otherwise run for ever).
        let n = block.length_mm / step;
        if n.is_nan() || n > MAX_STEPS_PER_BLOCK {
            let msg = format!(
                "chip volume per step: this block needs about {n:.3e} steps of {step:.3e} mm, more than {MAX_STEPS_PER_BLOCK:e} (raise --step-scale)"
            );
            return Err(match block.line {
                Some(line) => SimError::Line { line, msg },
                None => SimError::Record { index: 0, msg },
            });
        }
        Ok(Some(step))
    }

    fn cut(&mut self, block: &MotionBlock, from: &P3, to: &P3, kind: &MotionKind) -> Result<(), SimError> {
        let arc = match kind {
            MotionKind::Arc(a) => a.arc(*from, *to),
            _ => None,
        };
        if let Some(o) = self.overlay.as_mut() {
            let feed = block.class != MoveClass::Rapid;
            match &arc {
                Some(a) => {
                    let n = ((a.length() / (0.5 * self.engine.stock.cell)).ceil() as usize).clamp(1, 1 << 16);
                    let mut p0 = *from;
                    for k in 1..=n {
                        let p1 = a.point_at(k as f64 / n as f64);
                        o.line(&p0, &p1, feed);
                        p0 = p1;
                    }
                }
                None => o.line(from, to, feed),
            }
        }
        let step_mm = self.step_length(block)?;
        self.engine.push(&CutMove {
            line: block.line,
            class: block.class,
            from: *from,
            to: *to,
            arc,
            length_mm: block.length_mm,
            step_mm,
        });
        self.drain()
    }

    /// Cut what is queued and account it.
    fn flush(&mut self) -> Result<(), SimError> {
        self.engine.flush();
        self.drain()
    }

    /// Account the blocks the engine has finished, in order, writing the
    /// series.
    fn drain(&mut self) -> Result<(), SimError> {
        while let Some(q) = self.engine.pop() {
            let n = q.steps.len();
            if q.stepped
                && let Some(w) = self.steps_csv.as_mut()
            {
                for (k, st) in q.steps.iter().enumerate() {
                    let mut b = String::with_capacity(80);
                    if let Some(l) = q.line {
                        push_uint(&mut b, l);
                    }
                    b.push(',');
                    push_uint(&mut b, k as u64 + 1);
                    for c in [st.end.x, st.end.y, st.end.z, q.length_mm / n as f64, st.volume_mm3] {
                        b.push(',');
                        push_num(&mut b, c);
                    }
                    b.push('\n');
                    w.write_all(b.as_bytes())?;
                }
            }
            self.account(&q)?;
        }
        Ok(())
    }

    fn account(&mut self, q: &CutBlock) -> Result<(), SimError> {
        let (n, v, vmax) = (q.steps.len(), q.volume_mm3, q.max_step_mm3);
        let s = &mut self.stats;
        s.removed_volume_mm3 += v;
        if v > s.max_block_volume_mm3 {
            s.max_block_volume_mm3 = v;
            s.max_block_line = q.line;
        }
        if q.class == MoveClass::Rapid && v > 0.0 {
            s.rapids_in_material += 1;
            if let Some(l) = q.line
                && s.rapid_lines.len() < EXAMPLES
            {
                s.rapid_lines.push(l);
            }
        }
        if let Some(w) = self.csv.as_mut() {
            let mut b = String::with_capacity(64);
            if !self.header_written {
                self.header_written = true;
                b.push_str(REMOVAL_HEADER);
                if self.steps.is_some() {
                    b.push_str(REMOVAL_STEP_COLUMNS);
                }
                b.push('\n');
            }
            if let Some(l) = q.line {
                push_uint(&mut b, l);
            }
            b.push(',');
            b.push_str(q.class.name());
            b.push(',');
            push_num(&mut b, q.length_mm);
            b.push(',');
            push_num(&mut b, v);
            b.push(',');
            push_num(&mut b, if q.length_mm > 0.0 { v / q.length_mm } else { 0.0 });
            if q.stepped {
                b.push(',');
                push_uint(&mut b, n as u64);
                b.push(',');
                push_num(&mut b, v / n as f64);
                b.push(',');
                push_num(&mut b, vmax);
            }
            b.push('\n');
            w.write_all(b.as_bytes())?;
        }
        Ok(())
    }
}

fn csv_row(b: &mut String, ev: &Event) {
    match ev {
        Event::Block(tb) => {
            if let Some(l) = tb.block.line {
                push_uint(b, l);
            }
            b.push(',');
            b.push_str(tb.block.class.name());
            b.push(',');
            push_num(b, tb.block.length_mm);
            b.push(',');
            push_num(b, tb.commanded_feed_mm_s);
            b.push(',');
            push_num(b, tb.achieved_feed_mm_s);
            b.push(',');
            push_num(b, tb.time_s);
            b.push(',');
            b.push_str(tb.limited_by.name());
            b.push('\n');
        }
        Event::Dwell { seconds, line, .. } => {
            if let Some(l) = line {
                push_uint(b, *l);
            }
            b.push_str(",dwell,0,,,");
            push_num(b, *seconds);
            b.push_str(",\n");
        }
    }
}

#[cfg(test)]
mod tests;
