//! plough2d: a 2-D ploughing simulation for micro flat end milling after
//! Bayesteh 2013, chapter 5.
//!
//! The stock is a W × H rectangle held as a dual dexel ([`dexel`]); a
//! circular cutter of diameter D with N teeth is stepped along the
//! program's feed moves (lines and arcs) by the feed per tooth times a
//! scale factor (Bayesteh 2013 eq. 5.1). At each step the chip is what the
//! disc takes from the stock, and the ploughing area is the part of the
//! chip thinner, along the cutter's radius, than the minimum chip
//! thickness ([`polar`]). An exact reference ([`exact`]) computes the same
//! two figures from the geometry of the swept discs, to bound the dexel
//! error.
//!
//! Rapids do not cut (the cutter is above the stock); every feed move cuts
//! and Z is ignored. A feed move that starts where the last step did not
//! end (after a rapid, or the first move) first places the cutter there:
//! that step's chip is whatever the disc holds (a plunge).

#![warn(missing_docs)]

pub mod dexel;
pub mod exact;
pub mod output;
pub mod pocket;
pub mod polar;

#[cfg(test)]
mod checks;

use crate::geometry::segment::Segment;
use crate::geometry::{P3, Plane};
use crate::model::toolpath::{FeedUnit, MotionKind, Record};
use dexel::{DualDexel, Removed};
use exact::Swept;
use polar::Bins;

/// Which computation gives the reported areas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// The dual dexel (Bayesteh 2013's model): any stock history.
    Dexel,
    /// The exact reference alone.
    Exact,
    /// Both; the report carries the exact figures and the differences.
    Both,
}

impl Method {
    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::Dexel => "dexel",
            Method::Exact => "exact",
            Method::Both => "both",
        }
    }
}

/// The simulation's inputs (Bayesteh 2013 Fig. 5-1: W, H, R, D, n,
/// T_min, S, T_p).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Stock outline x0, y0, x1, y1, mm.
    pub stock_mm: [f64; 4],
    /// Dexel spacing R, mm.
    pub resolution_mm: f64,
    /// Cutter diameter D, mm.
    pub diameter_mm: f64,
    /// Teeth (flutes) N.
    pub teeth: u32,
    /// Minimum chip thickness, mm, in the scaled model (see `scale`).
    pub h_min_mm: f64,
    /// Ploughing accuracy T_p: arc length between radii, mm.
    pub accuracy_mm: f64,
    /// Scale factor SF on the feed per tooth.
    pub scale: f64,
    /// Spindle speed overriding the program's S words, rpm.
    pub rpm: Option<f64>,
    /// Which computation gives the reported areas.
    pub method: Method,
    /// Largest memory the stock and the series may take, MiB.
    pub max_memory_mib: f64,
    /// Most cutter steps a run may take: each costs tens of µs, so this
    /// bounds the time (a spindle speed of 1e9 rpm asks for ~1e5x the
    /// thesis pocket's steps). Checked before the move that would pass it.
    pub max_steps: u64,
}

/// Default of [`Params::max_steps`]: 50x the thesis-like pocket at its
/// slowest feed (9,554 steps), a few seconds of work.
pub const DEFAULT_MAX_STEPS: u64 = 500_000;

/// Why a simulation cannot run.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PloughError {
    /// A parameter out of range; the message names it and what it must be.
    #[error("{0}")]
    Param(String),
    /// The cutter is wider than the stock's shorter side.
    #[error("tool diameter {d} mm does not fit the {w} x {h} mm stock")]
    ToolTooLarge {
        /// Cutter diameter, mm.
        d: f64,
        /// Stock width (X), mm.
        w: f64,
        /// Stock height (Y), mm.
        h: f64,
    },
    /// The stock, the bins or the series would pass the memory cap.
    #[error("{what} would need about {need_mib:.0} MiB, over the {cap_mib:.0} MiB cap (--max-memory-mib)")]
    Memory {
        /// What needs the memory, with the figures that size it.
        what: String,
        /// Estimated need, MiB.
        need_mib: f64,
        /// The cap, MiB ([`Params::max_memory_mib`]).
        cap_mib: f64,
    },
    /// The run would pass [`Params::max_steps`] (checked before the move
    /// that would pass it, so no time is spent on it).
    #[error(
        "the series would pass {cap} cutter steps ({steps:.0} by the end of this move, at {step_mm:.3e} mm per step; raise --max-steps or check the feed and spindle speed)"
    )]
    Steps {
        /// Steps the series would hold at the end of the move.
        steps: f64,
        /// The move's step length, mm (feed per tooth × scale factor).
        step_mm: f64,
        /// The cap.
        cap: u64,
    },
    /// A move the simulation cannot take, by its program line: an arc
    /// outside XY or degenerate, a feed move without feed or spindle
    /// speed, or the step cap passed on it.
    #[error("line {line}: {msg}")]
    Line {
        /// The program line of the move.
        line: u64,
        /// What is wrong with it.
        msg: String,
    },
    /// As [`PloughError::Line`], for a record without a program line (a
    /// toolpath file): its place among the records fed.
    #[error("record {index}: {msg}")]
    Record {
        /// 1-based count of the records fed, this one included.
        index: u64,
        /// What is wrong with it.
        msg: String,
    },
}

/// One cutter position and what it cut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Program line of the move, when read from G-code.
    pub line: Option<u64>,
    /// Feed path length from the start of the program to here, mm.
    pub path_mm: f64,
    /// Cutter centre X, mm.
    pub x_mm: f64,
    /// Cutter centre Y, mm.
    pub y_mm: f64,
    /// Chip area, mm².
    pub chip_mm2: f64,
    /// Ploughing area, mm².
    pub plough_mm2: f64,
    /// The exact reference's chip and ploughing areas, mm², when computed
    /// beside the dexel.
    pub exact_mm2: Option<(f64, f64)>,
}

/// A move drawn on the stock picture, as points in XY, mm.
#[derive(Debug, Clone, PartialEq)]
pub struct Drawn {
    /// A feed move (drawn as cutting); false for a rapid.
    pub feed: bool,
    /// The move's points in order: a rapid's two ends, a feed move's steps
    /// thinned to at most about 512.
    pub points: Vec<(f64, f64)>,
}

/// The dexel density is averaged over this many R of the cutter circle.
const WINDOW_R: f64 = 3.0;

/// Bytes one dexel line is budgeted: its vector and a few intervals.
const LINE_BYTES: f64 = 24.0 + 4.0 * 16.0;
/// Bytes a stored step takes.
const STEP_BYTES: f64 = std::mem::size_of::<Step>() as f64;

/// The simulation, fed one toolpath record at a time.
pub struct Plough {
    p: Params,
    r: f64,
    unit_mm_s: f64,
    stock: Option<DualDexel>,
    swept: Option<Swept>,
    bins: Bins,
    /// Bins the dexel density is averaged over: the dexel's own angular
    /// resolution, about 1.5 R on the cutter circle.
    window: usize,
    pos: P3,
    /// Where the last step left the cutter, when it is down.
    placed: Option<(f64, f64)>,
    prog_rpm: Option<f64>,
    path_mm: f64,
    index: u64,
    max_steps: usize,
    /// The series.
    pub steps: Vec<Step>,
    /// Moves for the picture.
    pub drawn: Vec<Drawn>,
    rx: Vec<Removed>,
    ry: Vec<Removed>,
    acc_x: Vec<f64>,
    acc_y: Vec<f64>,
    comb: Vec<f64>,
    sm: Vec<f64>,
    thick: Vec<f64>,
}

fn finite_pos(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

impl Plough {
    /// Check `p` and build the stock; `feed_unit` is the program's.
    pub fn new(p: Params, feed_unit: FeedUnit, start: P3) -> Result<Plough, PloughError> {
        let [x0, y0, x1, y1] = p.stock_mm;
        let bad = |m: &str| Err(PloughError::Param(m.to_string()));
        if !([x0, y0, x1, y1].iter().all(|v| v.is_finite()) && x1 > x0 && y1 > y0) {
            return bad("stock: need x0 < x1 and y0 < y1, finite (mm)");
        }
        if !finite_pos(p.resolution_mm) {
            return bad("resolution must be a positive number of mm");
        }
        if !finite_pos(p.diameter_mm) {
            return bad("tool diameter must be a positive number of mm");
        }
        if p.teeth == 0 {
            return bad("teeth must be at least 1");
        }
        if !(p.h_min_mm.is_finite() && p.h_min_mm >= 0.0) {
            return bad("minimum chip thickness must be 0 or more");
        }
        if !finite_pos(p.accuracy_mm) {
            return bad("accuracy must be a positive number of mm");
        }
        if !finite_pos(p.scale) {
            return bad("scale factor must be positive");
        }
        if p.rpm.is_some_and(|r| !finite_pos(r)) {
            return bad("spindle speed must be positive (rpm)");
        }
        if !finite_pos(p.max_memory_mib) {
            return bad("memory cap must be positive (MiB)");
        }
        let (w, h) = (x1 - x0, y1 - y0);
        if p.diameter_mm > w.min(h) {
            return Err(PloughError::ToolTooLarge { d: p.diameter_mm, w, h });
        }
        let r = 0.5 * p.diameter_mm;
        let cap = p.max_memory_mib * 1024.0 * 1024.0;
        let mib = |b: f64| b / (1024.0 * 1024.0);
        let lines = (w / p.resolution_mm).ceil() + (h / p.resolution_mm).ceil();
        let nbins = std::f64::consts::TAU * r / p.accuracy_mm;
        let need = lines * LINE_BYTES + nbins * 8.0 * 8.0;
        if need > cap || nbins > 1e8 {
            let what = format!(
                "{lines:.0} dexel lines (resolution {} mm) and {nbins:.0} angular bins (accuracy {} mm)",
                p.resolution_mm, p.accuracy_mm
            );
            return Err(PloughError::Memory {
                what,
                need_mib: mib(need),
                cap_mib: p.max_memory_mib,
            });
        }
        let max_steps = ((cap - need) / STEP_BYTES).max(0.0) as usize;
        let bins = Bins::new(r, p.accuracy_mm);
        let n = bins.len();
        let window = ((WINDOW_R * p.resolution_mm / p.accuracy_mm).round().max(5.0) as usize) | 1;
        let stock = (p.method != Method::Exact).then(|| DualDexel::new(p.stock_mm, p.resolution_mm));
        let swept = (p.method != Method::Dexel).then(|| Swept::new(r));
        Ok(Plough {
            r,
            unit_mm_s: feed_unit.to_mm_per_s(),
            stock,
            swept,
            window,
            pos: start,
            placed: None,
            prog_rpm: None,
            path_mm: 0.0,
            index: 0,
            max_steps,
            steps: Vec::new(),
            drawn: Vec::new(),
            rx: Vec::new(),
            ry: Vec::new(),
            acc_x: vec![0.0; n],
            acc_y: vec![0.0; n],
            comb: vec![0.0; n],
            sm: Vec::with_capacity(n),
            thick: vec![0.0; n],
            bins,
            p,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &Params {
        &self.p
    }

    /// The dexel stock (absent for `Method::Exact`).
    pub fn stock(&self) -> Option<&DualDexel> {
        self.stock.as_ref()
    }

    fn err(&self, line: Option<u64>, msg: String) -> PloughError {
        match line {
            Some(line) => PloughError::Line { line, msg },
            None => PloughError::Record { index: self.index, msg },
        }
    }

    /// Feed one record.
    pub fn add(&mut self, rec: &Record) -> Result<(), PloughError> {
        self.index += 1;
        let m = match rec {
            Record::Spindle { rpm, .. } => {
                self.prog_rpm = Some(*rpm);
                return Ok(());
            }
            Record::Move(m) => m,
            _ => return Ok(()),
        };
        let from = self.pos;
        self.pos = m.to;
        let (a, b) = ((from.x, from.y), (m.to.x, m.to.y));
        let curve = match &m.kind {
            MotionKind::Rapid => {
                self.placed = None;
                self.drawn.push(Drawn {
                    feed: false,
                    points: vec![a, b],
                });
                return Ok(());
            }
            MotionKind::Line => Segment::line(from, m.to),
            MotionKind::Arc(d) => {
                if d.plane != Plane::Xy {
                    return Err(self.err(m.block, "arcs outside the XY plane (G18/G19) are not supported".into()));
                }
                let arc = d
                    .arc(from, m.to)
                    .ok_or_else(|| self.err(m.block, "degenerate arc".into()))?;
                Segment::Arc(arc)
            }
        };
        let feed = m
            .feed
            .filter(|f| finite_pos(*f))
            .ok_or_else(|| self.err(m.block, "feed move without a positive feed".into()))?;
        let rpm = self.p.rpm.or(self.prog_rpm).filter(|r| finite_pos(*r)).ok_or_else(|| {
            self.err(
                m.block,
                "no spindle speed: give S in the program or --rpm (feed per tooth needs it)".into(),
            )
        })?;
        // Bayesteh 2013 eq. 5.1 with units explicit: f_t [mm/tooth] =
        // f [mm/s] / (n [rev/s] × N [teeth]), stepped at f_t × SF.
        let per_tooth = feed * self.unit_mm_s / (rpm / 60.0 * self.p.teeth as f64);
        let step = per_tooth * self.p.scale;
        // The length in XY, Z being ignored here (Segment::length would add
        // a helix's rise and average the start and end radii).
        let len = match &curve {
            Segment::Line(_) => (b.0 - a.0).hypot(b.1 - a.1),
            Segment::Arc(arc) => arc.radius() * arc.sweep().abs(),
        };
        let n = if len > 1e-12 {
            (len / step - 1e-9).ceil().max(1.0)
        } else {
            0.0
        };
        if self.steps.len() as f64 + n + 1.0 > self.p.max_steps as f64 {
            let steps = PloughError::Steps {
                steps: self.steps.len() as f64 + n,
                step_mm: step,
                cap: self.p.max_steps,
            };
            return Err(self.err(m.block, steps.to_string()));
        }
        if self.steps.len() as f64 + n + 1.0 > self.max_steps as f64 {
            return Err(PloughError::Memory {
                what: format!(
                    "the series ({:.0} steps so far at {step:.3e} mm per step)",
                    self.steps.len() as f64 + n
                ),
                need_mib: (self.steps.len() as f64 + n) * STEP_BYTES / (1024.0 * 1024.0),
                cap_mib: self.p.max_memory_mib,
            });
        }
        let n = n as usize;
        // Points of the move for the picture.
        let mut pts = Vec::with_capacity(n.min(512) + 2);
        if self.placed != Some(a) {
            self.cut_at(a, None, m.block);
        }
        pts.push(a);
        let draw_every = n.div_ceil(512).max(1);
        for k in 1..=n {
            let c = if k == n {
                b
            } else {
                let p = curve.point_at(k as f64 / n as f64);
                (p.x, p.y)
            };
            self.path_mm += len / n as f64;
            // Only the exact reference asks what the move swept so far.
            let done = self
                .swept
                .is_some()
                .then(|| exact::travelled(&curve, (k - 1) as f64 / n as f64));
            self.cut_at(c, done.as_ref(), m.block);
            if k % draw_every == 0 || k == n {
                pts.push(c);
            }
        }
        if n == 0 {
            pts.push(b);
        }
        if let Some(sw) = self.swept.as_mut() {
            sw.push(&if n == 0 { Segment::line(from, from) } else { curve });
        }
        self.drawn.push(Drawn {
            feed: true,
            points: pts,
        });
        self.placed = Some(b);
        Ok(())
    }

    /// One step: the cutter at `c`; `done` is what the current move swept
    /// before it (for the exact reference), `None` when the cutter is
    /// placed (a plunge: nothing of this move is cut yet) or when there is
    /// no exact reference.
    fn cut_at(&mut self, c: (f64, f64), done: Option<&Segment>, line: Option<u64>) {
        let (r, h_min, dth) = (self.r, self.p.h_min_mm, self.bins.dtheta);
        let mut dex = None;
        if let Some(stock) = self.stock.as_mut() {
            let (ax, ay) = stock.cut(c.0, c.1, r, &mut self.rx, &mut self.ry);
            let chip = 0.5 * (ax + ay);
            let mut plough = 0.0;
            if chip > 0.0 {
                self.acc_x.iter_mut().for_each(|v| *v = 0.0);
                self.acc_y.iter_mut().for_each(|v| *v = 0.0);
                let (sx, sy) = (stock.x.spacing, stock.y.spacing);
                self.bins.add_strips(&mut self.acc_x, &self.rx, sx, true, c.0, c.1);
                self.bins.add_strips(&mut self.acc_y, &self.ry, sy, false, c.0, c.1);
                // Each family where its lines cross the cutter edge most
                // steeply: lines along X near 0 and π, along Y near ±π/2.
                for (k, &(co, si)) in self.bins.dir.iter().enumerate() {
                    self.comb[k] = co * co * self.acc_x[k] + si * si * self.acc_y[k];
                }
                polar::smooth(&self.comb, self.window, &mut self.sm);
                let sm = &self.sm;
                let (a, p) = polar::split(sm, |k| polar::thickness(sm[k], r), h_min, dth);
                if a > 0.0 {
                    plough = chip * (p / a).min(1.0);
                }
            }
            dex = Some((chip, plough));
        }
        let mut ex = None;
        if let Some(sw) = self.swept.as_mut() {
            let stock = self.p.stock_mm;
            sw.chip(c, done, stock, &self.bins.dir, &mut self.comb, &mut self.thick);
            let th = &self.thick;
            ex = Some(polar::split(&self.comb, |k| th[k], h_min, dth));
        }
        let (chip, plough) = dex.or(ex).unwrap_or((0.0, 0.0));
        self.steps.push(Step {
            line,
            path_mm: self.path_mm,
            x_mm: c.0,
            y_mm: c.1,
            chip_mm2: chip,
            plough_mm2: plough,
            exact_mm2: if dex.is_some() { ex } else { None },
        });
        self.placed = Some(c);
    }
}
