//! Motion time: how long each block really takes and how fast it really
//! goes, under one of two controller models.
//!
//! Both models turn the program into a continuous speed-versus-time curve
//! made of linear pieces ([`Piece`]: constant acceleration or cruise), cut
//! at the instants the path crosses block boundaries, so each block's
//! pieces integrate exactly to its length and the block times add up to the
//! cycle time. Both stream: the PMAC model holds one block, the look-ahead
//! model its planner buffer, so memory stays flat however long the program.
//!
//! **PMAC** (Turbo PMAC LINEAR/CIRCLE with blending): a move of length L at
//! feed F lasts T = max(L/F, Ta) where Ta = max(TA, 2·TS) is the
//! acceleration time; it runs at the plateau speed L/T. Between two blended
//! moves the speed ramps linearly over the acceleration time of the move
//! blended into (the TA/TS in force when it is calculated), centred on the
//! nominal boundary; a move from or to rest adds half a ramp at each end.
//! That is why short segments never reach their feed: the plateau of a
//! stretched move is L/Ta, proportional to L (Bayesteh (2013) Fig. 3-20). RAPID
//! moves are not blended: each axis runs its own trapezoid at the rapid
//! speed and acceleration, the slowest axis sets the time. DWELL stops
//! motion.
//!
//! **Look-ahead** (grbl/Klipper): constant acceleration, corner speeds from
//! the junction-deviation rule, arcs limited by centripetal acceleration,
//! and a planner that sees `lookahead_blocks` blocks ahead and must be able
//! to stop at the end of what it sees (so a small buffer costs speed on
//! short segments, as on the real machine).
//!
//! The shared vocabulary (blocks, pieces, events) and [`TimeModel`] are
//! here; each controller's model is in its own file (`pmac.rs`,
//! `lookahead.rs`).

use crate::geometry::V3;
use crate::machine::{Controller, Machine};
use std::collections::VecDeque;

mod lookahead;
mod pmac;
#[cfg(test)]
mod tests;

use lookahead::Lookahead;
pub use lookahead::{junction_speed, trapezoid};
use pmac::Pmac;

/// Why a block did not reach its commanded feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Limit {
    /// Reached it.
    None,
    /// The commanded feed is above the machine's maximum.
    MaxFeed,
    /// PMAC: shorter in time than the acceleration time, so stretched to it.
    Ta,
    /// The controller cannot compute blocks this short fast enough.
    BlockRate,
    /// Arc too tight for its feed at the machine's acceleration.
    Centripetal,
    /// A corner speed (junction deviation) held it back.
    Junction,
    /// Too short to accelerate to the feed and back (from or to rest, or
    /// within the planner's view).
    Acceleration,
}

impl Limit {
    /// Every limit but [`Limit::None`], in the order reports count them.
    pub const ALL: [Limit; 6] = [
        Limit::MaxFeed,
        Limit::Ta,
        Limit::BlockRate,
        Limit::Centripetal,
        Limit::Junction,
        Limit::Acceleration,
    ];

    /// The name in reports and the per-block CSV (empty for
    /// [`Limit::None`]).
    pub fn name(self) -> &'static str {
        match self {
            Limit::None => "",
            Limit::MaxFeed => "max_feed",
            Limit::Ta => "ta",
            Limit::BlockRate => "block_rate",
            Limit::Centripetal => "centripetal",
            Limit::Junction => "junction",
            Limit::Acceleration => "acceleration",
        }
    }
}

/// What kind of block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveClass {
    /// A positioning move at the machine's rapid speed (not blended on a
    /// PMAC; timed per axis).
    Rapid,
    /// A straight feed move.
    Line,
    /// A circular (or helical) feed move.
    Arc,
}

impl MoveClass {
    /// The name in the moves and per-block CSVs.
    pub fn name(self) -> &'static str {
        match self {
            MoveClass::Rapid => "rapid",
            MoveClass::Line => "line",
            MoveClass::Arc => "arc",
        }
    }
}

/// A move as the time models see it.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionBlock {
    /// Source line.
    pub line: Option<u64>,
    /// Rapid, line or arc.
    pub class: MoveClass,
    /// Path length, mm (0 for a move of the rotary axes alone).
    pub length_mm: f64,
    /// Commanded path feed, mm/s; ignored for rapids.
    pub feed_mm_s: f64,
    /// Unit tangent at the start (zero for a zero-length move).
    pub dir_in: V3,
    /// Unit tangent at the end (zero for a zero-length move).
    pub dir_out: V3,
    /// Arc radius (infinite for straight moves).
    pub radius_mm: f64,
    /// End minus start, for the per-axis rapid model.
    pub delta: V3,
    /// End point (mm), for matching cuts to drawing chains.
    pub end: crate::geometry::P3,
    /// The beam (shutter) is on during the move.
    pub beam: bool,
    /// How a shutter switch before this block was commanded, when the
    /// program says (PMAC `==` / `=`).
    pub beam_switch: Option<crate::model::toolpath::ShutterSwitch>,
    /// The drawing chain the move was generated from, when the toolpath
    /// says (matches cuts to chains).
    pub chain: Option<u64>,
    /// Travel of the rotary axes A, B, C (degrees, the length of their
    /// joint displacement); 0 for a 3-axis move.
    pub rotary_deg: f64,
}

impl MotionBlock {
    /// A straight move (rapid or line) by its axis displacement.
    pub fn straight(class: MoveClass, delta: V3, feed_mm_s: f64) -> MotionBlock {
        let l = delta.norm();
        let dir = if l > 0.0 { delta / l } else { V3::zeros() };
        MotionBlock {
            line: None,
            class,
            length_mm: l,
            feed_mm_s,
            dir_in: dir,
            dir_out: dir,
            radius_mm: f64::INFINITY,
            delta,
            end: crate::geometry::P3::from(delta),
            beam: false,
            beam_switch: None,
            chain: None,
            rotary_deg: 0.0,
        }
    }
}

/// A stretch of constant acceleration: speed goes linearly from `v0` to
/// `v1` (mm/s) over `dt` seconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Piece {
    /// Duration, s (>= 0).
    pub dt: f64,
    /// Speed at its start, mm/s.
    pub v0: f64,
    /// Speed at its end, mm/s.
    pub v1: f64,
}

impl Piece {
    /// Distance covered between `a` and `b` seconds into the piece.
    pub fn distance_between(&self, a: f64, b: f64) -> f64 {
        let (a, b) = (a.clamp(0.0, self.dt), b.clamp(0.0, self.dt));
        if b <= a || self.dt <= 0.0 {
            return 0.0;
        }
        let k = (self.v1 - self.v0) / self.dt;
        self.v0 * (b - a) + 0.5 * k * (b * b - a * a)
    }

    /// Distance covered over the whole piece, mm.
    pub fn distance(&self) -> f64 {
        0.5 * (self.v0 + self.v1) * self.dt
    }
}

/// Most pieces a block is cut into (ramp in, cruise, ramp out).
pub const MAX_PIECES: usize = 3;

/// A block with its timing.
#[derive(Debug, Clone, PartialEq)]
pub struct TimedBlock {
    /// The move as given.
    pub block: MotionBlock,
    /// When the path crosses into this block (s from program start).
    pub t_start_s: f64,
    /// How long the path stays in it, s: the sum of its pieces.
    pub time_s: f64,
    /// When the controller starts executing the move: the start of the
    /// blend into it on a PMAC (where `M33==` takes effect), `t_start_s` on a
    /// look-ahead planner.
    pub exec_start_s: f64,
    /// The speed curve over the block, the first `n_pieces` used (see
    /// [`TimedBlock::pieces`]); they cover exactly `block.length_mm`.
    pub pieces: [Piece; MAX_PIECES],
    /// Pieces in use, 0..=[`MAX_PIECES`].
    pub n_pieces: usize,
    /// The block's peak feed, mm/s: the top of its trapezoid (look-ahead)
    /// or its plateau speed (PMAC).
    pub achieved_feed_mm_s: f64,
    /// The feed the block was meant to run at (commanded, or the rapid
    /// speed), mm/s.
    pub commanded_feed_mm_s: f64,
    /// Why `achieved_feed_mm_s` is below `commanded_feed_mm_s`, if it is.
    pub limited_by: Limit,
}

impl TimedBlock {
    /// The pieces in use, in time order.
    pub fn pieces(&self) -> &[Piece] {
        &self.pieces[..self.n_pieces]
    }

    /// Path length covered between absolute times `a` and `b` (s from
    /// program start), mm.
    pub fn distance_between(&self, a: f64, b: f64) -> f64 {
        let mut t = self.t_start_s;
        let mut d = 0.0;
        for p in self.pieces() {
            if t >= b {
                break;
            }
            d += p.distance_between(a - t, b - t);
            t += p.dt;
        }
        d
    }
}

/// What the time models put out, in time order.
// Boxing the block would cost an allocation per block on the hot path;
// events live only in a short queue.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A move, timed.
    Block(TimedBlock),
    /// A dwell: the stage at rest for `seconds`.
    Dwell {
        /// When it starts, s from program start (motion has stopped).
        t_start_s: f64,
        /// How long it lasts, s.
        seconds: f64,
        /// Source line.
        line: Option<u64>,
    },
}

/// A controller model fed one record at a time; timed events come out of
/// [`TimeModel::pop`] as soon as what follows can no longer change them.
pub struct TimeModel {
    inner: Inner,
    out: VecDeque<Event>,
    rotary: crate::machine::Rotary,
}

enum Inner {
    Pmac(Pmac),
    Lookahead(Lookahead),
}

impl TimeModel {
    /// The model `m.controller` names, with `m`'s speeds, accelerations,
    /// TA/TS, block rate and rotary limits, at time 0 and at rest.
    pub fn new(m: &Machine) -> TimeModel {
        let inner = match m.controller {
            Controller::Pmac => Inner::Pmac(Pmac::new(m)),
            Controller::Lookahead => Inner::Lookahead(Lookahead::new(m)),
        };
        TimeModel {
            inner,
            out: VecDeque::new(),
            rotary: m.rotary_or_linear(),
        }
    }

    /// A move. Rotary axes (the documented rule, docs/gsim.md): a move that
    /// turns only rotary axes (an indexing move) stops the linear axes and
    /// takes the rotary trapezoid's time (feed in degrees per unit time, at
    /// most the rotary maximum, or the rotary rapid speed; the rotary
    /// acceleration), covering no path; a move that turns them while the
    /// linear axes move has its feed lowered so that no rotary axis turns
    /// faster than its maximum. A rapid's rotary travel beside linear
    /// travel is not timed.
    pub fn push_move(&mut self, mut b: MotionBlock) {
        if b.rotary_deg > 0.0 {
            if b.length_mm <= 0.0 {
                self.push_rotary_only(b);
                return;
            }
            if b.class != MoveClass::Rapid {
                let cap = b.length_mm * self.rotary.max_deg_s / b.rotary_deg;
                if cap < b.feed_mm_s {
                    b.feed_mm_s = cap;
                }
            }
        }
        match &mut self.inner {
            Inner::Pmac(p) => p.push_move(b, &mut self.out),
            Inner::Lookahead(l) => l.push_move(b, &mut self.out),
        }
    }

    /// A move of the rotary axes alone: motion stops, the axes turn.
    fn push_rotary_only(&mut self, b: MotionBlock) {
        let r = self.rotary;
        let v = if b.class == MoveClass::Rapid {
            r.rapid_deg_s
        } else {
            b.feed_mm_s.min(r.max_deg_s)
        };
        let (theta, a) = (b.rotary_deg, r.accel_deg_s2);
        // Trapezoid from rest to rest, or a triangle when too short.
        let time = if theta >= v * v / a {
            theta / v + v / a
        } else {
            2.0 * (theta / a).sqrt()
        };
        let t = self.stop_then_hold(time);
        let mut pieces = [Piece::default(); MAX_PIECES];
        pieces[0].dt = time;
        self.out.push_back(Event::Block(TimedBlock {
            t_start_s: t,
            time_s: time,
            exec_start_s: t,
            pieces,
            n_pieces: 1,
            achieved_feed_mm_s: 0.0,
            commanded_feed_mm_s: v,
            limited_by: Limit::None,
            block: b,
        }));
    }

    /// Bring motion to a stop (flushing what the controller model holds),
    /// then let `seconds` pass on its clock; returns when they began. A
    /// dwell and a rotary-only move are timed alone this way.
    fn stop_then_hold(&mut self, seconds: f64) -> f64 {
        let clock = match &mut self.inner {
            Inner::Pmac(p) => {
                p.stop(&mut self.out);
                &mut p.t
            }
            Inner::Lookahead(l) => {
                l.stop(&mut self.out);
                &mut l.t
            }
        };
        let t = *clock;
        *clock += seconds;
        t
    }

    /// A dwell: motion stops, then waits.
    pub fn push_dwell(&mut self, seconds: f64, line: Option<u64>) {
        let t = self.stop_then_hold(seconds);
        self.out.push_back(Event::Dwell {
            t_start_s: t,
            seconds,
            line,
        });
    }

    /// New PMAC TA / TS (ms) for the moves that follow; the look-ahead
    /// model has no such thing.
    pub fn set_accel(&mut self, ta_ms: Option<f64>, ts_ms: Option<f64>) {
        if let Inner::Pmac(p) = &mut self.inner {
            if let Some(ta) = ta_ms {
                p.ta_ms = ta;
            }
            if let Some(ts) = ts_ms {
                p.ts_ms = ts;
            }
        }
    }

    /// End of program: bring everything to rest.
    pub fn finish(&mut self) {
        match &mut self.inner {
            Inner::Pmac(p) => p.stop(&mut self.out),
            Inner::Lookahead(l) => l.stop(&mut self.out),
        }
    }

    /// The next finished event, if any.
    pub fn pop(&mut self) -> Option<Event> {
        self.out.pop_front()
    }

    /// Time when everything emitted so far has finished, s from program
    /// start.
    pub fn now_s(&self) -> f64 {
        match &self.inner {
            Inner::Pmac(p) => p.t,
            Inner::Lookahead(l) => l.t,
        }
    }
}

/// Push a piece unless it is empty.
fn add_piece(p: &mut [Piece; MAX_PIECES], n: &mut usize, piece: Piece) {
    if piece.dt > 0.0 && *n < MAX_PIECES {
        p[*n] = piece;
        *n += 1;
    }
}
