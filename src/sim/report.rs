//! The gsim report: one pass over a toolpath through the path summary, the
//! time model and the beam model, with the per-block series written as it
//! goes. Constant memory apart from one record per cut.

use super::beam::{BeamModel, ChainExposure, CommandTiming, EXAMPLES, match_chains};
use super::machine::{Controller, Machine};
use super::stock::{Cutter, Stock};
use super::summary::Summary;
use super::time::{Block, Event, Limit, MoveClass, TimeModel, TimedBlock};
use crate::formats::{push_num, push_str_lit, push_uint};
use crate::geometry::{Arc3, BBox3, P3, V3};
use crate::model::chain::Chain;
use crate::model::toolpath::{Header, MotionKind, Record};
use std::io::Write;
use thiserror::Error;

pub const SCHEMA: &str = "microcam.gsim/1";

/// A program the machine must not run, or a failed write of the series.
#[derive(Debug, Error)]
pub enum SimError {
    #[error("line {line}: {msg}")]
    Line { line: u64, msg: String },
    #[error("record {index}: {msg}")]
    Record { index: u64, msg: String },
    #[error("block series: {0}")]
    Io(#[from] std::io::Error),
}

/// The header row of the `--blocks` CSV.
pub const BLOCKS_HEADER: &str = "line,kind,length_mm,commanded_feed_mm_s,achieved_feed_mm_s,time_s,limited_by\n";

/// A block that did not reach its feed, for the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Example {
    pub line: Option<u64>,
    pub length_mm: f64,
    pub commanded_feed_mm_s: f64,
    pub achieved_feed_mm_s: f64,
    pub limited_by: Limit,
}

/// Time figures.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TimeStats {
    pub cycle_time_s: f64,
    pub cutting_time_s: f64,
    pub rapid_time_s: f64,
    pub dwell_time_s: f64,
    /// Feed-move length over commanded feed: the time a program "should" take.
    pub ideal_cutting_time_s: f64,
    pub feed_blocks: u64,
    pub limited_blocks: u64,
    pub limited_by: [u64; Limit::ALL.len()],
    pub examples: Vec<Example>,
    pub min_achieved_feed_mm_s: Option<f64>,
}

/// Material removal figures.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RemovalStats {
    pub initial_volume_mm3: f64,
    pub removed_volume_mm3: f64,
    pub max_block_volume_mm3: f64,
    pub max_block_line: Option<u64>,
    /// Rapids that removed material (a crash on a real machine).
    pub rapids_in_material: u64,
    pub rapid_lines: Vec<u64>,
}

/// Stock, cutter and the per-block removal series.
pub struct Removal<W: Write> {
    pub stock: Stock,
    pub cutter: Cutter,
    pub csv: Option<W>,
    pub stats: RemovalStats,
}

/// The header row of the `--removal` CSV.
pub const REMOVAL_HEADER: &str = "line,kind,length_mm,removed_volume_mm3,removed_per_length_mm2\n";

/// The whole simulation, fed one record at a time.
pub struct Simulator<W: Write> {
    machine: Machine,
    feed_factor: f64,
    pos: P3,
    index: u64,
    summary: Summary,
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
            index: 0,
            summary: Summary::new(header.feed_unit, start),
            time: TimeModel::new(&machine),
            beam: BeamModel::new(&machine.shutter, timing),
            stats: TimeStats::default(),
            blocks_csv: csv,
            row,
            machine,
            removal: None,
        }
    }

    /// Also remove material from `stock` with `cutter`, writing the
    /// per-block volumes to `csv`.
    pub fn with_removal(mut self, stock: Stock, cutter: Cutter, mut csv: Option<W>) -> Self {
        if let Some(w) = csv.as_mut() {
            let _ = w.write_all(REMOVAL_HEADER.as_bytes());
        }
        let stats = RemovalStats {
            initial_volume_mm3: stock.volume(),
            ..Default::default()
        };
        self.removal = Some(Removal {
            stock,
            cutter,
            csv,
            stats,
        });
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
                        let arc = Arc3::new(a.center, from, m.to, a.ccw, a.plane, a.extra_turns)
                            .ok_or_else(|| self.err(m.block, "arc of zero radius".into()))?;
                        self.check_limits(&arc.bbox(), m.block)?;
                        let len = arc.length();
                        Block {
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
                            chain: None,
                        }
                    }
                    _ => {
                        self.check_limits(&BBox3::from_points(&[from, m.to]), m.block)?;
                        Block::straight(class, delta, feed)
                    }
                };
                block.line = m.block;
                block.end = m.to;
                block.beam = m.beam;
                block.chain = m.chain;
                if let Some(r) = self.removal.as_mut() {
                    r.cut(&block, &from, &m.to, &m.kind)?;
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
            Record::Spindle { .. } | Record::Var { .. } => {}
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

    /// Bring the machine to rest and close the books.
    /// Returns the report and the two series writers (blocks, removal) for
    /// the caller to commit.
    #[allow(clippy::type_complexity)]
    pub fn finish(mut self) -> Result<(Report, Option<W>, Option<W>), SimError> {
        self.time.finish();
        self.drain()?;
        let t_end = self.time.now_s();
        self.beam.finish();
        self.stats.cycle_time_s = t_end;
        if let Some(w) = self.blocks_csv.as_mut() {
            w.flush()?;
        }
        let (removal, removal_csv) = match self.removal {
            Some(mut r) => {
                if let Some(w) = r.csv.as_mut() {
                    w.flush()?;
                }
                (Some((r.stats, r.stock)), r.csv)
            }
            None => (None, None),
        };
        Ok((
            Report {
                machine: self.machine,
                summary: self.summary,
                time: self.stats,
                beam: self.beam,
                drawing: None,
                removal,
            },
            self.blocks_csv,
            removal_csv,
        ))
    }
}

impl<W: Write> Removal<W> {
    fn cut(&mut self, block: &Block, from: &P3, to: &P3, kind: &MotionKind) -> Result<(), SimError> {
        let v = match kind {
            MotionKind::Arc(a) => match Arc3::new(a.center, *from, *to, a.ccw, a.plane, a.extra_turns) {
                Some(arc) => self.stock.cut_arc(&arc, &self.cutter),
                None => 0.0,
            },
            _ => self.stock.cut_line(from, to, &self.cutter),
        };
        let s = &mut self.stats;
        s.removed_volume_mm3 += v;
        if v > s.max_block_volume_mm3 {
            s.max_block_volume_mm3 = v;
            s.max_block_line = block.line;
        }
        if block.class == MoveClass::Rapid && v > 0.0 {
            s.rapids_in_material += 1;
            if let Some(l) = block.line
                && s.rapid_lines.len() < EXAMPLES
            {
                s.rapid_lines.push(l);
            }
        }
        if let Some(w) = self.csv.as_mut() {
            let mut b = String::with_capacity(64);
            if let Some(l) = block.line {
                push_uint(&mut b, l);
            }
            b.push(',');
            b.push_str(block.class.name());
            b.push(',');
            push_num(&mut b, block.length_mm);
            b.push(',');
            push_num(&mut b, v);
            b.push(',');
            push_num(
                &mut b,
                if block.length_mm > 0.0 {
                    v / block.length_mm
                } else {
                    0.0
                },
            );
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

/// Everything gsim reports.
pub struct Report {
    pub machine: Machine,
    pub summary: Summary,
    pub time: TimeStats,
    pub beam: BeamModel,
    /// With a drawing (`--chains`): the drawing chain index per cut and the
    /// exposure per drawing chain.
    pub drawing: Option<(Vec<Option<usize>>, Vec<ChainExposure>)>,
    /// With a stock (`--stock`): removal figures and the final stock.
    pub removal: Option<(RemovalStats, Stock)>,
}

fn field(b: &mut String, k: &str, v: f64) {
    b.push_str(",\"");
    b.push_str(k);
    b.push_str("\":");
    push_num(b, v);
}

impl Report {
    /// Compare the cuts with the drawing's chains (`tol` mm in XY).
    pub fn with_drawing(mut self, chains: &[Chain], tol: f64) -> Report {
        self.drawing = Some(match_chains(&self.beam.cuts, chains, tol));
        self
    }

    /// The report as one JSON object (`microcam.gsim/1`).
    pub fn to_json(&self, source: Option<&str>) -> String {
        let mut b = format!("{{\"schema\":\"{SCHEMA}\"");
        if let Some(s) = source {
            b.push_str(",\"source\":");
            push_str_lit(&mut b, s);
        }
        b.push_str(",\"machine\":");
        push_str_lit(&mut b, &self.machine.name);
        b.push_str(",\"controller\":\"");
        b.push_str(self.machine.controller.name());
        b.push('"');
        self.summary.push_fields(&mut b);
        let t = &self.time;
        field(&mut b, "cycle_time_s", t.cycle_time_s);
        field(&mut b, "cutting_time_s", t.cutting_time_s);
        field(&mut b, "rapid_time_s", t.rapid_time_s);
        field(&mut b, "dwell_time_s", t.dwell_time_s);
        field(&mut b, "ideal_cutting_time_s", t.ideal_cutting_time_s);
        if let Some(f) = t.min_achieved_feed_mm_s {
            field(&mut b, "min_achieved_feed_mm_s", f);
        }
        field(&mut b, "feed_blocks", t.feed_blocks as f64);
        field(&mut b, "limited_blocks", t.limited_blocks as f64);
        b.push_str(",\"limited_by\":{");
        let mut first = true;
        for (i, l) in Limit::ALL.iter().enumerate() {
            if t.limited_by[i] > 0 {
                if !first {
                    b.push(',');
                }
                first = false;
                b.push('"');
                b.push_str(l.name());
                b.push_str("\":");
                push_uint(&mut b, t.limited_by[i]);
            }
        }
        b.push_str("},\"limited_examples\":[");
        for (i, e) in t.examples.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            b.push('{');
            if let Some(l) = e.line {
                b.push_str("\"line\":");
                push_uint(&mut b, l);
                b.push(',');
            }
            b.push_str("\"length_mm\":");
            push_num(&mut b, e.length_mm);
            field(&mut b, "commanded_feed_mm_s", e.commanded_feed_mm_s);
            field(&mut b, "achieved_feed_mm_s", e.achieved_feed_mm_s);
            b.push_str(",\"limited_by\":\"");
            b.push_str(e.limited_by.name());
            b.push_str("\"}");
        }
        b.push(']');
        self.push_beam(&mut b);
        if let Some((r, stock)) = &self.removal {
            b.push_str(",\"removal\":{\"cells\":[");
            push_uint(&mut b, stock.nx as u64);
            b.push(',');
            push_uint(&mut b, stock.ny as u64);
            b.push(']');
            field(&mut b, "cell_mm", stock.cell);
            field(&mut b, "initial_volume_mm3", r.initial_volume_mm3);
            field(&mut b, "removed_volume_mm3", r.removed_volume_mm3);
            field(&mut b, "final_volume_mm3", stock.volume());
            field(&mut b, "max_block_volume_mm3", r.max_block_volume_mm3);
            if let Some(l) = r.max_block_line {
                b.push_str(",\"max_block_line\":");
                push_uint(&mut b, l);
            }
            field(&mut b, "rapids_in_material", r.rapids_in_material as f64);
            b.push_str(",\"rapid_in_material_lines\":[");
            for (i, l) in r.rapid_lines.iter().enumerate() {
                if i > 0 {
                    b.push(',');
                }
                push_uint(&mut b, *l);
            }
            b.push_str("]}");
        }
        b.push('}');
        b
    }

    fn push_beam(&self, b: &mut String) {
        let m = &self.beam;
        b.push_str(",\"beam\":{\"command_timing\":\"");
        b.push_str(m.timing.name());
        b.push('"');
        field(b, "open_latency_ms", self.machine.shutter.open_latency_s() * 1e3);
        field(b, "close_latency_ms", self.machine.shutter.close_latency_s() * 1e3);
        field(b, "shutter_opens", m.opens as f64);
        field(b, "shutter_open_time_s", m.light_time_s);
        field(b, "intended_length_mm", m.intended_mm());
        field(b, "exposed_length_mm", m.exposed_mm());
        field(b, "unexposed_length_mm", m.unexposed_mm());
        field(b, "overexposed_length_mm", m.overexposed_mm());
        field(b, "stationary_exposure_s", m.stationary_exposure_s());
        field(b, "short_exposures", m.short_exposures as f64);
        field(b, "missed_exposures", m.missed_exposures as f64);
        b.push_str(",\"short_exposure_lines\":[");
        for (i, l) in m.short_exposure_lines.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            push_uint(b, *l);
        }
        b.push_str("],\"cuts\":[");
        for (i, c) in m.cuts.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            b.push_str("{\"cut\":");
            push_uint(b, i as u64 + 1);
            if let Some(ch) = c.chain {
                b.push_str(",\"chain\":");
                push_uint(b, ch);
            }
            if let Some(l) = c.first_line {
                b.push_str(",\"first_line\":");
                push_uint(b, l);
            }
            if let Some(l) = c.last_line {
                b.push_str(",\"last_line\":");
                push_uint(b, l);
            }
            if let Some((which, per)) = &self.drawing
                && let Some(Some(k)) = which.get(i)
            {
                b.push_str(",\"drawing_chain\":");
                push_uint(b, per[*k].id);
            }
            field(b, "length_mm", c.length_mm);
            field(b, "exposed_mm", c.exposed_mm);
            field(b, "unexposed_mm", c.unexposed_mm());
            field(b, "overexposed_mm", c.overexposed_mm);
            field(b, "stationary_exposure_s", c.stationary_exposure_s);
            b.push('}');
        }
        b.push(']');
        if let Some((_, per)) = &self.drawing {
            field(b, "drawing_length_mm", per.iter().map(|c| c.drawing_length_mm).sum());
            field(
                b,
                "drawing_unexposed_length_mm",
                per.iter().map(|c| c.unexposed_mm()).sum(),
            );
            b.push_str(",\"chains\":[");
            for (i, c) in per.iter().enumerate() {
                if i > 0 {
                    b.push(',');
                }
                b.push_str("{\"chain\":");
                push_uint(b, c.id);
                field(b, "drawing_length_mm", c.drawing_length_mm);
                field(b, "cuts", c.cuts as f64);
                field(b, "cut_length_mm", c.cut_length_mm);
                field(b, "exposed_mm", c.exposed_mm);
                field(b, "unexposed_mm", c.unexposed_mm());
                field(b, "overexposed_mm", c.overexposed_mm);
                b.push('}');
            }
            b.push(']');
        }
        b.push('}');
    }
}
