//! Feed scheduling from simulated chip volume (Bayesteh 2013 ch. 3), made
//! to pay off on a micro mill's controller.
//!
//! The program is simulated on a height-field stock in steps of a fixed
//! length ([`crate::sim::removal`]); each step's chip cross-section (volume
//! per mm of path) times the feed per tooth is its chip volume per tooth.
//! Feeds per tooth are mapped linearly between f_max at the smallest chip
//! and f_min at the largest (the thesis' eq. 3.2 as its text intends),
//! smoothed by a moving average, and capped so no step's chip exceeds the
//! largest chip at f_min. Then either every block gets one feed
//! ([`Mode::PerBlock`], the thesis' second method) or blocks are split
//! into sub-blocks no shorter in time than the controller's minimum block
//! time ([`Mode::Split`]); the thesis' first method, a new block at every
//! step ([`Mode::Naive`]), is kept for comparison. Cycle times come from
//! gsim's time model, so a split that would lose time is not written.
//!
//! Only F words change (and split mode inserts marked sub-block lines), so
//! comments, N numbers, other words and the dialect survive byte for byte,
//! and a second run gives the same program: the schedule depends on the
//! geometry alone, and marked lines are taken out before simulating.

#![warn(missing_docs)]

pub mod force;
pub mod report;
pub mod sample;
pub mod schedule;
pub mod text;

mod rewrite;

use crate::cutter::Cutter;
use crate::gcode::{Dialect, GcodeError, ReadOptions, detect_dialect, read_str};
use crate::geometry::P3;
use crate::machine::{Controller, Machine};
use crate::model::toolpath::{Header, MotionKind, Record};
use crate::sim::beam::CommandTiming;
use crate::sim::removal::{CutMove, Engine};
use crate::sim::report::{SimError, Simulator};
use crate::sim::stock::{Stock, StockError};
use crate::sim::time::MoveClass;
use force::{Coefficients, Engagement, ForceModel};
use rewrite::FeedPlan;
use schedule::{Band, By, Step, Targets};
use thiserror::Error;

/// Most simulation steps one run may take (each a record in the series).
pub const MAX_STEPS: usize = 20_000_000;

/// Why a program cannot be scheduled.
#[derive(Debug, Error)]
pub enum FeedoptError {
    /// The program does not read (either dialect).
    #[error("{0}")]
    Gcode(#[from] GcodeError),
    /// A feed move on this source line has no spindle speed to turn its
    /// feed into a feed per tooth.
    #[error("line {0}: no spindle speed for this feed move (an S word before it, or --rpm)")]
    NoSpindle(u64),
    /// The feed moves' extent (first text) misses the stock box (second),
    /// both as "lo..hi" per axis.
    #[error("the path (X {0}) does not overlap the stock (X {1}): check --stock")]
    NoOverlap(String, String),
    /// Every feed move runs in air: there is no chip to schedule by.
    #[error("the tool never cuts the stock: no feed move removes material (check --stock, --tool and the program's Z)")]
    NeverCuts,
    /// An ISO program in inches (G20): F words would be in inch/min.
    #[error("inch programs (G20) are not supported: feedopt writes F in mm/min")]
    Inch,
    /// An ISO program in inverse-time or per-revolution feed mode (the
    /// mode's name): its F words are not a speed.
    #[error("{0} programs are not supported: feedopt writes F in mm/min (G94)")]
    FeedMode(&'static str),
    /// The feed path divided by the step length exceeds [`MAX_STEPS`].
    #[error(
        "the simulation would take about {steps:.3e} steps of {step_mm:e} mm (more than {max}): raise --step-mm or --fz-min-um"
    )]
    TooManySteps {
        /// Estimated steps: feed path length over `step_mm`.
        steps: f64,
        /// The step length asked for, mm.
        step_mm: f64,
        /// The limit, [`MAX_STEPS`].
        max: usize,
    },
    /// The stock box or cell size cannot make a height field.
    #[error("--stock: {0}")]
    Stock(#[from] StockError),
    /// An option out of range; the text names the flag.
    #[error("{0}")]
    Options(String),
    /// gsim's time model refused the program (before or after scheduling).
    #[error("simulating the program: {0}")]
    Sim(#[from] SimError),
}

/// How new feeds are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Keep every block; one feed per block.
    PerBlock,
    /// Split blocks into sub-blocks no shorter than the minimum block time.
    Split,
    /// A sub-block at every step, with no minimum (Bayesteh 2013's first
    /// method, for comparison: it loses time on a PMAC).
    Naive,
}

impl Mode {
    /// The name used in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mode::PerBlock => "per-block",
            Mode::Split => "split",
            Mode::Naive => "naive",
        }
    }
}

/// What the schedule holds constant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A chip-volume band: the linear map of eq. 3.2.
    Chip,
    /// A constant mean cutting force: the force of the largest chip at
    /// f_min, everywhere (within f_min..f_max).
    Force,
}

/// Everything feedopt needs besides the program.
#[derive(Debug, Clone)]
pub struct Options {
    /// How new feeds are written (one per block, or split).
    pub mode: Mode,
    /// How a block's feed is taken from its steps' targets.
    pub by: By,
    /// What the schedule holds constant (chip volume band or force).
    pub target: Target,
    /// Feed per tooth at the largest chip, mm.
    pub fz_min_mm: f64,
    /// Feed per tooth at the smallest chip, mm.
    pub fz_max_mm: f64,
    /// Teeth of the cutter (feed per tooth = feed / (rpm / 60 × flutes)).
    pub flutes: u32,
    /// Spindle speed overriding the program's S words, rpm.
    pub rpm: Option<f64>,
    /// The cutter's shape for the removal simulation.
    pub cutter: Cutter,
    /// Stock box, lowest corner, mm.
    pub stock_min: P3,
    /// Stock box, highest corner, mm; its Z is the top the force model's
    /// axial depth is measured from.
    pub stock_max: P3,
    /// Cell size of the height-field stock, mm.
    pub cell_mm: f64,
    /// Simulation step, mm (default: f_min per tooth × 10, the thesis'
    /// scale factor).
    pub step_mm: Option<f64>,
    /// Moving-average window, mm of path.
    pub window_mm: f64,
    /// Feed of feed moves that cut nothing, in the program's feed unit
    /// (default: f_max).
    pub air_feed: Option<f64>,
    /// Shortest sub-block, s (default: the PMAC acceleration time, or the
    /// planner's block time on a look-ahead controller).
    pub min_block_s: Option<f64>,
    /// Neighbouring sub-blocks whose feeds differ by less than this
    /// (relative) are merged.
    pub merge_tol: f64,
    /// The machine profile: controller kind, TA/TS or block time for the
    /// minimum block time, and gsim's time model for cycle times.
    pub machine: Machine,
    /// How the program is read (dialect, or `None` to sniff it; the start
    /// point).
    pub read: ReadOptions,
    /// The force model's coefficients; `None` = no force figures.
    pub force: Option<Coefficients>,
}

/// One step of the per-step series (feed moves only, in program order).
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesRow {
    /// Source line of the move the step belongs to.
    pub line: Option<u64>,
    /// Where the step ends, mm.
    pub end: P3,
    /// Path distance at the step's end over all feed moves, mm.
    pub s_mm: f64,
    /// Chip cross-section: volume removed per mm of path, mm².
    pub area_mm2: f64,
    /// The step is scheduled: it moves in XY and takes more than a
    /// thousandth of the largest chip.
    pub cutting: bool,
    /// Feed per tooth as programmed, mm.
    pub fz_before_mm: f64,
    /// Feed per tooth as written, mm.
    pub fz_after_mm: f64,
    /// Mean cutting force at the programmed feed, N (with a force model).
    pub force_before_n: Option<f64>,
    /// Mean cutting force at the written feed, N (with a force model).
    pub force_after_n: Option<f64>,
}

/// The result: the new program, the report and the series.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The program with new F words (and, in split mode, marked sub-block
    /// lines), otherwise byte for byte the input.
    pub program: String,
    /// What was done and what it gains.
    pub report: report::FeedoptReport,
    /// One row per simulation step.
    pub series: Vec<SeriesRow>,
}

/// A feed move as simulated.
struct MoveInfo {
    line: Option<u64>,
    kind: MotionKind,
    from: P3,
    to: P3,
    /// Feed as programmed, program units.
    feed: f64,
    rpm: f64,
    plunge: bool,
    /// Its steps in the series: `first..first + n`, each `step_mm` long.
    first: usize,
    n: usize,
    step_mm: f64,
}

/// Predicted cycle time of a program under gsim's time model, s.
pub fn cycle_time_s(text: &str, opts: &ReadOptions, machine: &Machine) -> Result<f64, FeedoptError> {
    let (d, recs) = read_str(text, opts)?;
    let header = Header {
        feed_unit: d.feed_unit(),
        source: None,
    };
    let mut sim: Simulator<Vec<u8>> = Simulator::new(&header, machine.clone(), CommandTiming::Sync, opts.start, None);
    for r in &recs {
        sim.add(r)?;
    }
    Ok(sim.finish()?.0.time.cycle_time_s)
}

/// The program without the sub-block lines an earlier run inserted.
pub fn strip_marked(text: &str, dialect: Dialect) -> String {
    text::lines(text)
        .iter()
        .filter(|l| !text::is_marked(l.body, dialect))
        .flat_map(|l| [l.body, l.eol])
        .collect()
}

/// Schedule the feeds of `input` (G-code of either dialect): simulate,
/// map chips to feeds, write the program in the chosen mode (falling back
/// to one feed per block where a split would not save time).
pub fn optimise(input: &str, o: &Options) -> Result<Outcome, FeedoptError> {
    check(o)?;
    let dialect = o
        .read
        .dialect
        .unwrap_or_else(|| detect_dialect(input.lines().take(200)));
    let mut ropts = o.read.clone();
    ropts.dialect = Some(dialect);
    if dialect == Dialect::Iso && text::has_inch(input) {
        return Err(FeedoptError::Inch);
    }
    if dialect == Dialect::Iso
        && let Some(mode) = text::feed_mode(input)
    {
        return Err(FeedoptError::FeedMode(mode));
    }
    let base = strip_marked(input, dialect);
    let (_, recs) = read_str(&base, &ropts)?;

    // Simulate.
    let stock = Stock::new(o.stock_min, o.stock_max, o.cell_mm)?;
    let mut engine = Engine::new(stock, o.cutter);
    let step_mm = o.step_mm.unwrap_or(o.fz_min_mm * 10.0);
    let mut pos = o.read.start;
    let mut rpm = o.rpm;
    let mut ta = (o.machine.ta_ms, o.machine.ts_ms);
    let mut moves: Vec<Option<MoveInfo>> = Vec::new();
    let (mut lo, mut hi) = (
        P3::new(f64::MAX, f64::MAX, f64::MAX),
        P3::new(f64::MIN, f64::MIN, f64::MIN),
    );
    let mut steps_total = 0usize;
    let mut steps: Vec<Step> = Vec::new();
    // The series holds one record per step: estimate it from the program's
    // feed length before allocating anything.
    {
        let mut at = o.read.start;
        let mut length = 0.0;
        for r in &recs {
            if let Record::Move(m) = r {
                length += match m.kind {
                    MotionKind::Rapid => 0.0,
                    _ => m.segment(at).length(),
                };
                at = m.to;
            }
        }
        let est = length / step_mm;
        if step_mm.is_nan() || step_mm <= 0.0 || !est.is_finite() || est > MAX_STEPS as f64 {
            return Err(FeedoptError::TooManySteps {
                steps: est,
                step_mm,
                max: MAX_STEPS,
            });
        }
    }
    // Progress (a tool's bar): one unit per move simulated.
    crate::progress::add_total(recs.iter().filter(|r| matches!(r, Record::Move(_))).count() as u64);
    for r in &recs {
        match r {
            Record::Spindle { rpm: s, .. } if o.rpm.is_none() => rpm = Some(*s),
            Record::Accel { ta_ms, ts_ms, .. } => {
                ta = (ta_ms.unwrap_or(ta.0).max(ta.0), ts_ms.unwrap_or(ta.1).max(ta.1));
            }
            Record::Move(m) => {
                let from = pos;
                pos = m.to;
                let arc = match m.kind {
                    MotionKind::Arc(a) => a.arc(from, m.to),
                    _ => None,
                };
                let length_mm = arc.map_or((m.to - from).norm(), |a| a.length());
                let class = match m.kind {
                    MotionKind::Rapid => MoveClass::Rapid,
                    MotionKind::Line => MoveClass::Line,
                    MotionKind::Arc(_) => MoveClass::Arc,
                };
                let mut info = None;
                let mut step = None;
                if class != MoveClass::Rapid {
                    for p in [from, m.to] {
                        lo = lo.inf(&p);
                        hi = hi.sup(&p);
                    }
                    let line = m.block.unwrap_or(0);
                    let s = rpm.filter(|v| *v > 0.0).ok_or(FeedoptError::NoSpindle(line))?;
                    let plunge = arc.is_none() && (m.to.xy() - from.xy()).norm() < 1e-9;
                    let n = if length_mm > 0.0 {
                        ((length_mm / step_mm).ceil() as usize).clamp(1, 1 << 24)
                    } else {
                        1
                    };
                    let n = match &arc {
                        Some(a) if n > 1 => n.max(4 * (a.extra_turns as usize + 1)),
                        _ => n,
                    };
                    step = Some(step_mm);
                    info = Some(MoveInfo {
                        line: m.block,
                        kind: m.kind,
                        from,
                        to: m.to,
                        feed: m.feed.unwrap_or(0.0),
                        rpm: s,
                        plunge,
                        first: steps_total,
                        n,
                        step_mm: length_mm / n as f64,
                    });
                    steps_total += n;
                }
                engine.push(&CutMove {
                    line: m.block,
                    class,
                    from,
                    to: m.to,
                    arc,
                    length_mm,
                    step_mm: step.filter(|s| *s > 0.0),
                });
                crate::progress::advance(1);
                moves.push(info);
            }
            _ => {}
        }
    }
    engine.flush();
    let r = o.cutter.radius();
    let overlap = lo.x - r < o.stock_max.x
        && hi.x + r > o.stock_min.x
        && lo.y - r < o.stock_max.y
        && hi.y + r > o.stock_min.y
        && lo.z < o.stock_max.z;
    if steps_total == 0 || !overlap {
        let ext = if steps_total == 0 {
            "no feed moves".to_string()
        } else {
            format!(
                "{}..{} Y {}..{} Z {}..{}",
                text::format_coord(lo.x),
                text::format_coord(hi.x),
                text::format_coord(lo.y),
                text::format_coord(hi.y),
                text::format_coord(lo.z),
                text::format_coord(hi.z)
            )
        };
        let st = format!(
            "{}..{} Y {}..{} Z {}..{}",
            text::format_coord(o.stock_min.x),
            text::format_coord(o.stock_max.x),
            text::format_coord(o.stock_min.y),
            text::format_coord(o.stock_max.y),
            text::format_coord(o.stock_min.z),
            text::format_coord(o.stock_max.z)
        );
        return Err(FeedoptError::NoOverlap(ext, st));
    }

    // The per-step series.
    steps.reserve(steps_total);
    let mut rows: Vec<SeriesRow> = Vec::with_capacity(steps_total);
    let mut s_acc = 0.0;
    let mut rapids_cutting = 0u64;
    for info in moves.iter_mut() {
        let b = engine.pop().expect("one block per move");
        let Some(mi) = info else {
            if b.volume_mm3 > 0.0 {
                rapids_cutting += 1;
            }
            continue;
        };
        // The engine's step count is the truth (it is computed the same way;
        // this keeps the series aligned whatever the rounding).
        mi.first = steps.len();
        mi.n = b.steps.len();
        mi.step_mm = b.length_mm / mi.n as f64;
        let fz_before = to_fz(mi.feed, mi.rpm, o.flutes, dialect);
        for st in &b.steps {
            s_acc += mi.step_mm;
            let area = if mi.step_mm > 0.0 {
                st.volume_mm3 / mi.step_mm
            } else {
                0.0
            };
            steps.push(Step {
                s_mm: s_acc,
                area_mm2: area,
                cutting: !mi.plunge && area > 0.0,
            });
            rows.push(SeriesRow {
                line: mi.line,
                end: st.end,
                s_mm: s_acc,
                area_mm2: area,
                cutting: false,
                fz_before_mm: fz_before,
                fz_after_mm: fz_before,
                force_before_n: None,
                force_after_n: None,
            });
        }
    }
    // Slivers (a cell's rounding at the edge of a pass) are air: a step
    // counts as cutting above a thousandth of the largest chip.
    let amax = steps
        .iter()
        .filter(|s| s.cutting)
        .map(|s| s.area_mm2)
        .fold(0.0, f64::max);
    for s in steps.iter_mut() {
        s.cutting &= s.area_mm2 > 1e-3 * amax;
    }
    let band = Band::of(&steps).ok_or(FeedoptError::NeverCuts)?;
    let model = o.force.map(|k| ForceModel { k, flutes: o.flutes });
    let eng: Vec<Engagement> = rows
        .iter()
        .zip(&steps)
        .map(|(row, s)| Engagement::new(s.area_mm2, o.stock_max.z - row.end.z, r))
        .collect();

    // Targets per step, feed per tooth in mm.
    let cap_chip = band.area_max_mm2 * o.fz_min_mm;
    let (raw, cap): (Vec<f64>, Vec<f64>) = match (o.target, model) {
        (Target::Force, Some(m)) => {
            let f_target = steps
                .iter()
                .zip(&eng)
                .filter(|(s, _)| s.cutting)
                .map(|(_, e)| m.mean_n(e, o.fz_min_mm))
                .fold(0.0, f64::max);
            let u: Vec<f64> = eng
                .iter()
                .map(|e| m.feed_for(e, f_target, o.fz_min_mm, o.fz_max_mm))
                .collect();
            (u.clone(), u)
        }
        _ => steps
            .iter()
            .map(|s| {
                let u = band.map(s.area_mm2, o.fz_min_mm, o.fz_max_mm);
                let cap = if s.area_mm2 > 0.0 {
                    cap_chip / s.area_mm2
                } else {
                    f64::INFINITY
                };
                (u, cap.max(o.fz_min_mm))
            })
            .unzip(),
    };
    let smooth = schedule::moving_average(&steps, &raw, o.window_mm);
    let cutting: Vec<bool> = steps.iter().map(|s| s.cutting).collect();
    let targets = Targets {
        smooth: &smooth,
        raw: &raw,
        cap: &cap,
        cutting: &cutting,
    };
    let t_min = o.min_block_s.unwrap_or(match o.machine.controller {
        Controller::Pmac => crate::machine::pmac::accel_time_s(ta.0, ta.1),
        Controller::Lookahead => o.machine.block_time_s(),
    });

    // Feeds per move (program units), then the program.
    let plan = FeedPlan {
        o,
        dialect,
        targets: &targets,
        moves: &moves,
        t_min,
    };
    let incremental = text::has_incremental(&base, dialect);
    let per_block = plan.segments(Mode::PerBlock, incremental);
    let per_block_text = plan.write(&base, &recs, &per_block);
    let before_s = cycle_time_s(input, &ropts, &o.machine)?;
    let per_block_s = cycle_time_s(&per_block_text.0, &ropts, &o.machine)?;
    let mut notes = Vec::new();
    if rapids_cutting > 0 {
        notes.push(format!(
            "{rapids_cutting} rapid moves remove material (a crash on a real machine)"
        ));
    }
    let (chosen, program, added, changed, after_s, mode_used) = match o.mode {
        Mode::PerBlock => (
            per_block,
            per_block_text.0,
            0,
            per_block_text.1,
            per_block_s,
            Mode::PerBlock,
        ),
        m => {
            let segs = plan.segments(m, incremental);
            let (txt, changed, added) = {
                let (t, c) = plan.write(&base, &recs, &segs);
                let added = segs.iter().flatten().map(|s| s.len().saturating_sub(1)).sum::<usize>();
                (t, c, added)
            };
            let s = cycle_time_s(&txt, &ropts, &o.machine)?;
            if incremental {
                notes.push("the program uses incremental positions: no block was split".into());
            }
            if m == Mode::Split && s >= per_block_s {
                notes.push(format!(
                    "split mode cannot beat one feed per block here ({:.3} s vs {:.3} s): the per-block program was written",
                    s, per_block_s
                ));
                (
                    per_block,
                    per_block_text.0,
                    0,
                    per_block_text.1,
                    per_block_s,
                    Mode::PerBlock,
                )
            } else {
                (segs, txt, added, changed, s, m)
            }
        }
    };

    // Per-step feeds after, and the figures.
    for (mi, segs) in moves.iter().zip(&chosen) {
        let (Some(mi), Some(segs)) = (mi, segs) else { continue };
        for sg in segs {
            for k in sg.start..sg.end {
                rows[mi.first + k].fz_after_mm = to_fz(sg.feed, mi.rpm, o.flutes, dialect);
            }
        }
    }
    for ((row, s), e) in rows.iter_mut().zip(&steps).zip(&eng) {
        row.cutting = s.cutting;
        if let Some(m) = model {
            row.force_before_n = Some(m.mean_n(e, row.fz_before_mm));
            row.force_after_n = Some(m.mean_n(e, row.fz_after_mm));
        }
    }
    let peak = |after: bool| -> Option<f64> {
        let m = model?;
        Some(
            rows.iter()
                .zip(&eng)
                .filter(|(r, _)| r.cutting)
                .map(|(r, e)| m.peak_n(e, if after { r.fz_after_mm } else { r.fz_before_mm }))
                .fold(0.0, f64::max),
        )
    };
    let rep = report::FeedoptReport {
        mode: o.mode,
        mode_used,
        target: o.target,
        by: o.by,
        dialect,
        machine: o.machine.name.clone(),
        min_block_s: t_min,
        fz_min_mm: o.fz_min_mm,
        fz_max_mm: o.fz_max_mm,
        flutes: o.flutes,
        step_mm,
        cell_mm: o.cell_mm,
        window_mm: o.window_mm,
        band,
        chip_cap_mm3: cap_chip,
        cycle_time_before_s: before_s,
        cycle_time_after_s: after_s,
        per_block_cycle_time_s: per_block_s,
        chip_before: report::Stats::of(rows.iter().filter(|r| r.cutting).map(|r| r.area_mm2 * r.fz_before_mm)),
        chip_after: report::Stats::of(rows.iter().filter(|r| r.cutting).map(|r| r.area_mm2 * r.fz_after_mm)),
        force: model.map(|m| report::ForceFigures {
            coefficients: m.k,
            mean_before_n: time_mean(&rows, false),
            mean_after_n: time_mean(&rows, true),
            peak_before_n: peak(false).unwrap_or(0.0),
            peak_after_n: peak(true).unwrap_or(0.0),
        }),
        feed_moves: moves.iter().flatten().count() as u64,
        blocks_changed: changed as u64,
        blocks_added: added as u64,
        notes,
    };
    Ok(Outcome {
        program,
        report: rep,
        series: rows,
    })
}

/// Mean force over machining time (a step's weight is its time).
fn time_mean(rows: &[SeriesRow], after: bool) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for r in rows.iter().filter(|r| r.cutting) {
        let (fz, f) = if after {
            (r.fz_after_mm, r.force_after_n)
        } else {
            (r.fz_before_mm, r.force_before_n)
        };
        let w = 1.0 / fz.max(1e-12);
        num += w * f.unwrap_or(0.0);
        den += w;
    }
    if den > 0.0 { num / den } else { 0.0 }
}

fn check(o: &Options) -> Result<(), FeedoptError> {
    let pos = |v: f64| v.is_finite() && v > 0.0;
    if !(pos(o.fz_min_mm) && pos(o.fz_max_mm) && o.fz_min_mm <= o.fz_max_mm) {
        return Err(FeedoptError::Options(
            "feeds per tooth must be positive with f_min <= f_max".into(),
        ));
    }
    if o.flutes == 0 {
        return Err(FeedoptError::Options("--flutes must be at least 1".into()));
    }
    if let Some(r) = o.rpm
        && !pos(r)
    {
        return Err(FeedoptError::Options("--rpm must be positive".into()));
    }
    if o.step_mm.is_some_and(|s| !pos(s)) || !(o.window_mm.is_finite() && o.window_mm >= 0.0) {
        return Err(FeedoptError::Options(
            "--step-mm must be positive and --window-mm not negative".into(),
        ));
    }
    if o.air_feed.is_some_and(|s| !pos(s)) || o.min_block_s.is_some_and(|s| !(s.is_finite() && s >= 0.0)) {
        return Err(FeedoptError::Options(
            "--air-feed must be positive and --min-block-ms not negative".into(),
        ));
    }
    if !(o.merge_tol.is_finite() && o.merge_tol >= 0.0) {
        return Err(FeedoptError::Options("--merge-tol must not be negative".into()));
    }
    if o.force.is_none() && o.target == Target::Force {
        return Err(FeedoptError::Options(
            "--target force needs the force model (--force)".into(),
        ));
    }
    Ok(())
}

/// Feed per tooth (mm) from a feed in the dialect's unit.
fn to_fz(feed: f64, rpm: f64, flutes: u32, d: Dialect) -> f64 {
    feed * d.feed_unit().to_mm_per_s() / (rpm / 60.0 * flutes as f64)
}

/// Feed in the dialect's unit from feed per tooth, on the printed grid.
fn from_fz(fz: f64, rpm: f64, flutes: u32, d: Dialect) -> f64 {
    text::floor_feed(fz * rpm / 60.0 * flutes as f64 / d.feed_unit().to_mm_per_s(), d)
}
