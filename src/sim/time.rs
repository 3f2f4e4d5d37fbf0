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

use crate::geometry::V3;
use crate::machine::{Controller, Machine};
use std::collections::VecDeque;

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
        let t = match &mut self.inner {
            Inner::Pmac(p) => {
                p.stop(&mut self.out);
                let t = p.t;
                p.t += time;
                t
            }
            Inner::Lookahead(l) => {
                l.stop(&mut self.out);
                let t = l.t;
                l.t += time;
                t
            }
        };
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

    /// A dwell: motion stops, then waits.
    pub fn push_dwell(&mut self, seconds: f64, line: Option<u64>) {
        let t = match &mut self.inner {
            Inner::Pmac(p) => {
                p.stop(&mut self.out);
                let t = p.t;
                p.t += seconds;
                t
            }
            Inner::Lookahead(l) => {
                l.stop(&mut self.out);
                let t = l.t;
                l.t += seconds;
                t
            }
        };
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

/// Where, in a linear ramp of `d` seconds from `va` to `vb`, the path has
/// covered `va·d/2`: the nominal boundary of two blended moves. Solving
/// `va·τ + (vb−va)·τ²/(2d) = va·d/2` gives `τ = d·√va/(√va+√vb)`, where the
/// speed is `√(va·vb)`.
fn boundary_in_ramp(d: f64, va: f64, vb: f64) -> f64 {
    let (sa, sb) = (va.max(0.0).sqrt(), vb.max(0.0).sqrt());
    if sa + sb > 0.0 { d * sa / (sa + sb) } else { 0.5 * d }
}

/// Per-axis trapezoid of a PMAC rapid: time, and the path pieces of the
/// slowest axis scaled onto the straight path.
fn rapid_pieces(delta: &V3, length: f64, v: f64, a: f64) -> (f64, [Piece; MAX_PIECES], usize, f64) {
    let mut best = (0.0, 0.0);
    for i in 0..3 {
        let d = delta[i].abs();
        let t = if d >= v * v / a {
            d / v + v / a
        } else {
            2.0 * (d / a).sqrt()
        };
        if t > best.0 {
            best = (t, d);
        }
    }
    let (t, d) = best;
    let mut pieces = [Piece::default(); MAX_PIECES];
    if t <= 0.0 || d <= 0.0 {
        return (0.0, pieces, 0, 0.0);
    }
    let scale = length / d;
    let vp = v.min((a * d).sqrt());
    let ta = vp / a;
    let cruise = (t - 2.0 * ta).max(0.0);
    pieces[0] = Piece {
        dt: ta,
        v0: 0.0,
        v1: vp * scale,
    };
    let mut n = 1;
    if cruise > 0.0 {
        pieces[n] = Piece {
            dt: cruise,
            v0: vp * scale,
            v1: vp * scale,
        };
        n += 1;
    }
    pieces[n] = Piece {
        dt: ta,
        v0: vp * scale,
        v1: 0.0,
    };
    (t, pieces, n + 1, vp * scale)
}

/// Push a piece unless it is empty.
fn add_piece(p: &mut [Piece; MAX_PIECES], n: &mut usize, piece: Piece) {
    if piece.dt > 0.0 && *n < MAX_PIECES {
        p[*n] = piece;
        *n += 1;
    }
}

// ---------------------------------------------------------------------------
// PMAC

struct Pmac {
    max_feed: f64,
    rapid: f64,
    rapid_accel: f64,
    block_time: f64,
    ta_ms: f64,
    ts_ms: f64,
    /// Time the path has reached (end of the last emitted block).
    t: f64,
    /// The feed move waiting for its successor (to know whether it blends).
    pending: Option<Planned>,
    /// The blend into `pending`: previous plateau speed and ramp time, or
    /// `None` when `pending` starts from rest.
    entry: Option<(f64, f64)>,
}

struct Planned {
    block: MotionBlock,
    /// Nominal move time and plateau speed.
    time: f64,
    v: f64,
    /// Acceleration time of this move.
    acc: f64,
    commanded: f64,
    limit: Limit,
}

impl Pmac {
    fn new(m: &Machine) -> Pmac {
        Pmac {
            max_feed: m.max_feed_mm_s,
            rapid: m.rapid_mm_s,
            rapid_accel: m.rapid_accel_mm_s2,
            block_time: m.block_time_s(),
            ta_ms: m.ta_ms,
            ts_ms: m.ts_ms,
            t: 0.0,
            pending: None,
            entry: None,
        }
    }

    fn plan(&self, block: MotionBlock) -> Planned {
        let acc = crate::machine::pmac::accel_time_s(self.ta_ms, self.ts_ms);
        let commanded = block.feed_mm_s;
        let f = commanded.min(self.max_feed);
        let t_feed = block.length_mm / f;
        // The longest of the three lower bounds on the move time wins, and
        // names the limit (feed first, so a tie is not a limit).
        let mut time = t_feed;
        let mut limit = if f < commanded { Limit::MaxFeed } else { Limit::None };
        if acc > time {
            time = acc;
            limit = Limit::Ta;
        }
        if self.block_time > time {
            time = self.block_time;
            limit = Limit::BlockRate;
        }
        let v = if time > 0.0 { block.length_mm / time } else { 0.0 };
        Planned {
            block,
            time,
            v,
            acc,
            commanded,
            limit,
        }
    }

    fn push_move(&mut self, b: MotionBlock, out: &mut VecDeque<Event>) {
        if b.class == MoveClass::Rapid {
            // RAPID is not blended with LINEAR/CIRCLE: stop, jog, stop.
            self.stop(out);
            let (time, pieces, n, peak) = rapid_pieces(&b.delta, b.length_mm, self.rapid, self.rapid_accel);
            out.push_back(Event::Block(TimedBlock {
                t_start_s: self.t,
                time_s: time,
                exec_start_s: self.t,
                pieces,
                n_pieces: n,
                achieved_feed_mm_s: peak,
                commanded_feed_mm_s: self.rapid,
                limited_by: Limit::None,
                block: b,
            }));
            self.t += time;
            return;
        }
        let next = self.plan(b);
        if let Some(p) = self.pending.take() {
            // The blend takes the incoming move's acceleration time (the TA
            // in force when it is calculated), clamped so that it fits in
            // what is left of the move before it after its own entry blend.
            let d_in = self.entry.map_or(p.acc, |(_, d)| d);
            let d_out = next.acc.min(2.0 * p.time - d_in).max(0.0);
            let v_prev = p.v;
            self.emit(p, Some((next.v, d_out)), out);
            self.entry = Some((v_prev, d_out));
        } else {
            self.entry = None;
        }
        self.pending = Some(next);
    }

    fn stop(&mut self, out: &mut VecDeque<Event>) {
        if let Some(p) = self.pending.take() {
            self.emit(p, None, out);
        }
        self.entry = None;
    }

    /// Cut `p` out of the blended speed curve. `exit` is the next move's
    /// plateau speed and the blend time, or `None` for a stop.
    fn emit(&mut self, p: Planned, exit: Option<(f64, f64)>, out: &mut VecDeque<Event>) {
        let v = p.v;
        let mut pieces = [Piece::default(); MAX_PIECES];
        let mut n = 0;
        // Entry: the part of the incoming ramp after the boundary.
        let (d_in, tau_in) = match self.entry {
            Some((vp, d)) => {
                let tau = boundary_in_ramp(d, vp, v);
                let vb = (vp * v).sqrt();
                add_piece(
                    &mut pieces,
                    &mut n,
                    Piece {
                        dt: d - tau,
                        v0: vb,
                        v1: v,
                    },
                );
                (d, tau)
            }
            None => {
                add_piece(
                    &mut pieces,
                    &mut n,
                    Piece {
                        dt: p.acc,
                        v0: 0.0,
                        v1: v,
                    },
                );
                (p.acc, 0.0)
            }
        };
        let d_out = exit.map_or(p.acc, |(_, d)| d);
        // T >= acc >= each half ramp, so the cruise is never negative.
        let cruise = (p.time - 0.5 * d_in - 0.5 * d_out).max(0.0);
        add_piece(
            &mut pieces,
            &mut n,
            Piece {
                dt: cruise,
                v0: v,
                v1: v,
            },
        );
        match exit {
            Some((vn, d)) => {
                let tau = boundary_in_ramp(d, v, vn);
                let vb = (v * vn).sqrt();
                add_piece(&mut pieces, &mut n, Piece { dt: tau, v0: v, v1: vb });
            }
            None => add_piece(
                &mut pieces,
                &mut n,
                Piece {
                    dt: d_out,
                    v0: v,
                    v1: 0.0,
                },
            ),
        }
        let time: f64 = pieces[..n].iter().map(|p| p.dt).sum();
        out.push_back(Event::Block(TimedBlock {
            t_start_s: self.t,
            time_s: time,
            exec_start_s: self.t - tau_in,
            pieces,
            n_pieces: n,
            // A PMAC blend is the sum of each move's own profile, whose
            // peak is the plateau: the feed this block ran at. The speed at
            // its ends belongs to the neighbours' ramps.
            achieved_feed_mm_s: v,
            commanded_feed_mm_s: p.commanded,
            limited_by: p.limit,
            block: p.block,
        }));
        self.t += time;
    }
}

// ---------------------------------------------------------------------------
// Look-ahead planner

/// Largest corner speed (mm/s) between directions `d0` (end of the previous
/// block) and `d1` (start of the next) by the junction-deviation rule: the
/// speed at which a circle of deviation `jd` tangent to both directions is
/// taken at acceleration `a`. Straight on is unlimited, a reversal stops.
pub fn junction_speed(a: f64, jd: f64, d0: &V3, d1: &V3) -> f64 {
    let cos = -d0.dot(d1);
    if cos > 0.999_999 {
        return 0.0;
    }
    if cos < -0.999_999 {
        return f64::INFINITY;
    }
    let s = (0.5 * (1.0 - cos)).sqrt();
    (a * jd * s / (1.0 - s)).sqrt()
}

/// Constant-acceleration profile over `l` mm from `v0` to `v1` with cruise
/// speed at most `vn`: pieces, time and peak speed. Callers guarantee that
/// `v0` and `v1` are reachable from each other within `l`.
pub fn trapezoid(v0: f64, vn: f64, v1: f64, a: f64, l: f64) -> ([Piece; MAX_PIECES], usize, f64, f64) {
    let mut pieces = [Piece::default(); MAX_PIECES];
    if l <= 0.0 {
        return (pieces, 0, 0.0, v0.max(v1));
    }
    let vp = (a * l + 0.5 * (v0 * v0 + v1 * v1)).sqrt().min(vn).max(v0).max(v1);
    let t_acc = (vp - v0) / a;
    let t_dec = (vp - v1) / a;
    let d_ramps = (2.0 * vp * vp - v0 * v0 - v1 * v1) / (2.0 * a);
    let cruise = if vp > 0.0 { (l - d_ramps).max(0.0) / vp } else { 0.0 };
    let mut n = 0;
    add_piece(&mut pieces, &mut n, Piece { dt: t_acc, v0, v1: vp });
    add_piece(
        &mut pieces,
        &mut n,
        Piece {
            dt: cruise,
            v0: vp,
            v1: vp,
        },
    );
    add_piece(&mut pieces, &mut n, Piece { dt: t_dec, v0: vp, v1 });
    (pieces, n, t_acc + cruise + t_dec, vp)
}

struct Lookahead {
    accel: f64,
    jd: f64,
    n_max: usize,
    max_feed: f64,
    rapid: f64,
    block_time: f64,
    t: f64,
    buf: VecDeque<LBlock>,
    /// Entry speed of `buf[0]`: the exit speed of the block before it.
    entry: f64,
    /// End direction and cruise speed of the last block with length, or
    /// `None` after a stop.
    prev: Option<(V3, f64)>,
}

struct LBlock {
    block: MotionBlock,
    nominal: f64,
    commanded: f64,
    nominal_limit: Limit,
    /// Largest entry speed (junction, both cruise speeds).
    entry_max: f64,
    /// The junction rule, not the cruise speeds, set `entry_max`.
    junction: bool,
}

impl Lookahead {
    fn new(m: &Machine) -> Lookahead {
        Lookahead {
            accel: m.accel_mm_s2,
            jd: m.junction_deviation_mm,
            n_max: m.lookahead_blocks,
            max_feed: m.max_feed_mm_s,
            rapid: m.rapid_mm_s,
            block_time: m.block_time_s(),
            t: 0.0,
            buf: VecDeque::new(),
            entry: 0.0,
            prev: None,
        }
    }

    fn push_move(&mut self, b: MotionBlock, out: &mut VecDeque<Event>) {
        let commanded = if b.class == MoveClass::Rapid {
            self.rapid
        } else {
            b.feed_mm_s
        };
        let mut nominal = commanded;
        let mut nominal_limit = Limit::None;
        if b.class != MoveClass::Rapid && nominal > self.max_feed {
            nominal = self.max_feed;
            nominal_limit = Limit::MaxFeed;
        }
        if b.radius_mm.is_finite() {
            let vc = (self.accel * b.radius_mm).sqrt();
            if vc < nominal {
                nominal = vc;
                nominal_limit = Limit::Centripetal;
            }
        }
        let l = b.length_mm;
        if self.block_time > 0.0 && l / self.block_time < nominal {
            nominal = l / self.block_time;
            nominal_limit = Limit::BlockRate;
        }
        let (entry_max, junction) = if l <= 0.0 {
            // A zero-length block neither turns nor limits.
            (f64::INFINITY, false)
        } else {
            let r = match self.prev {
                None => (0.0, false),
                Some((d0, nom0)) => {
                    let vj = junction_speed(self.accel, self.jd, &d0, &b.dir_in);
                    let cap = nominal.min(nom0);
                    if vj < cap { (vj, true) } else { (cap, false) }
                }
            };
            self.prev = Some((b.dir_out, nominal));
            r
        };
        self.buf.push_back(LBlock {
            block: b,
            nominal,
            commanded,
            nominal_limit,
            entry_max,
            junction,
        });
        while self.buf.len() >= self.n_max {
            self.pop_front(out);
        }
    }

    fn stop(&mut self, out: &mut VecDeque<Event>) {
        while !self.buf.is_empty() {
            self.pop_front(out);
        }
        self.prev = None;
        self.entry = 0.0;
    }

    /// Run the oldest block: its exit speed is the fastest from which the
    /// rest of the buffer can still stop at its end.
    fn pop_front(&mut self, out: &mut VecDeque<Event>) {
        let a = self.accel;
        let mut v = 0.0_f64;
        for j in (1..self.buf.len()).rev() {
            let bj = &self.buf[j];
            v = bj.entry_max.min((v * v + 2.0 * a * bj.block.length_mm).sqrt());
        }
        let next_junction = self.buf.get(1).is_some_and(|b| b.junction);
        let Some(b0) = self.buf.pop_front() else { return };
        let l = b0.block.length_mm;
        let v0 = self.entry;
        let exit = v.min((v0 * v0 + 2.0 * a * l).sqrt()).min(b0.nominal.max(v0));
        let (pieces, n, time, peak) = trapezoid(v0, b0.nominal.max(v0), exit, a, l);
        let limited_by = if l <= 0.0 {
            Limit::None
        } else if peak < b0.nominal * (1.0 - 1e-9) {
            if b0.junction || next_junction {
                Limit::Junction
            } else {
                Limit::Acceleration
            }
        } else {
            b0.nominal_limit
        };
        out.push_back(Event::Block(TimedBlock {
            t_start_s: self.t,
            time_s: time,
            exec_start_s: self.t,
            pieces,
            n_pieces: n,
            achieved_feed_mm_s: peak,
            commanded_feed_mm_s: b0.commanded,
            limited_by,
            block: b0.block,
        }));
        self.t += time;
        self.entry = exit;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine(controller: Controller) -> Machine {
        let mut m = Machine::builtin("lookahead");
        m.controller = controller;
        m.accel_mm_s2 = 100.0;
        m.junction_deviation_mm = 0.01;
        m.max_feed_mm_s = 1000.0;
        m.block_rate_hz = 0.0;
        m.ta_ms = 133.0;
        m.ts_ms = 0.0;
        m
    }

    fn run(m: &Machine, blocks: &[MotionBlock]) -> Vec<TimedBlock> {
        let mut tm = TimeModel::new(m);
        for b in blocks {
            tm.push_move(b.clone());
        }
        drain(tm)
    }

    /// Finish the model and collect its timed blocks.
    fn drain(mut tm: TimeModel) -> Vec<TimedBlock> {
        tm.finish();
        let mut v = Vec::new();
        while let Some(e) = tm.pop() {
            if let Event::Block(b) = e {
                v.push(b);
            }
        }
        v
    }

    fn line(dx: f64, dy: f64, f: f64) -> MotionBlock {
        MotionBlock::straight(MoveClass::Line, V3::new(dx, dy, 0.0), f)
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// Every block's pieces cover its length, blocks follow each other in
    /// time without gaps, and speeds are continuous across boundaries.
    fn check_consistent(t: &[TimedBlock]) {
        let mut now = 0.0;
        let mut v_prev = 0.0;
        for b in t {
            let d: f64 = b.pieces().iter().map(|p| p.distance()).sum();
            assert!(close(d, b.block.length_mm, 1e-9), "{d} vs {}", b.block.length_mm);
            assert!(close(b.t_start_s, now, 1e-9));
            let dt: f64 = b.pieces().iter().map(|p| p.dt).sum();
            assert!(close(dt, b.time_s, 1e-12));
            if let Some(p) = b.pieces().first() {
                assert!(close(p.v0, v_prev, 1e-9), "speed jumps {v_prev} -> {}", p.v0);
                v_prev = b.pieces()[b.n_pieces - 1].v1;
            }
            now += b.time_s;
        }
        assert!(close(v_prev, 0.0, 1e-12), "ends moving");
    }

    #[test]
    fn one_trapezoid() {
        // 10 mm at 10 mm/s, 100 mm/s²: 0.1 s up, 0.1 s down (0.5 mm each),
        // 9 mm cruise in 0.9 s.
        let t = run(&machine(Controller::Lookahead), &[line(10.0, 0.0, 10.0)]);
        check_consistent(&t);
        assert!(close(t[0].time_s, 1.1, 1e-12), "{}", t[0].time_s);
        assert_eq!(t[0].achieved_feed_mm_s, 10.0);
        assert_eq!(t[0].limited_by, Limit::None);
        assert_eq!(t[0].n_pieces, 3);
    }

    #[test]
    fn triangle_profile() {
        // 0.5 mm cannot reach 10 mm/s: peak sqrt(a·L), time 2·peak/a.
        let t = run(&machine(Controller::Lookahead), &[line(0.5, 0.0, 10.0)]);
        check_consistent(&t);
        let vp = 50.0_f64.sqrt();
        assert!(close(t[0].achieved_feed_mm_s, vp, 1e-12));
        assert!(close(t[0].time_s, 2.0 * vp / 100.0, 1e-12));
        assert_eq!(t[0].limited_by, Limit::Acceleration);
    }

    #[test]
    fn junction_at_90_degrees() {
        // sin(θ/2) = √½ for a right angle: v² = a·δ·√½/(1−√½).
        let s = 0.5_f64.sqrt();
        let vj = (100.0 * 0.01 * s / (1.0 - s)).sqrt();
        assert!(close(junction_speed(100.0, 0.01, &V3::x(), &V3::y()), vj, 1e-12));
        assert_eq!(junction_speed(100.0, 0.01, &V3::x(), &V3::x()), f64::INFINITY);
        assert_eq!(junction_speed(100.0, 0.01, &V3::x(), &-V3::x()), 0.0);
        let t = run(
            &machine(Controller::Lookahead),
            &[line(0.5, 0.0, 10.0), line(0.0, 0.5, 10.0)],
        );
        check_consistent(&t);
        let corner = t[0].pieces()[t[0].n_pieces - 1].v1;
        assert!(close(corner, vj, 1e-12), "{corner} vs {vj}");
        // Up from rest, down to the corner speed: v_p² = a·L + v_j²/2.
        let vp = (50.0 + 0.5 * vj * vj).sqrt();
        assert!(close(t[0].achieved_feed_mm_s, vp, 1e-12));
        assert!(close(t[0].time_s, vp / 100.0 + (vp - vj) / 100.0, 1e-12));
        assert_eq!(t[0].limited_by, Limit::Junction);
        assert_eq!(t[1].limited_by, Limit::Junction);
        // Straight on, the same two lengths run as one 1 mm move.
        let t2 = run(
            &machine(Controller::Lookahead),
            &[line(0.5, 0.0, 10.0), line(0.5, 0.0, 10.0)],
        );
        let one = run(&machine(Controller::Lookahead), &[line(1.0, 0.0, 10.0)]);
        assert!(close(t2[0].time_s + t2[1].time_s, one[0].time_s, 1e-12));
    }

    #[test]
    fn planner_buffer_must_be_able_to_stop() {
        // With one block of view, every block stops at its end.
        let mut m = machine(Controller::Lookahead);
        m.lookahead_blocks = 1;
        let t = run(&m, &[line(10.0, 0.0, 10.0), line(10.0, 0.0, 10.0)]);
        check_consistent(&t);
        assert!(close(t[0].time_s, 1.1, 1e-12) && close(t[1].time_s, 1.1, 1e-12));
        m.lookahead_blocks = 2;
        let t = run(&m, &[line(10.0, 0.0, 10.0), line(10.0, 0.0, 10.0)]);
        assert!(close(t[0].time_s + t[1].time_s, 2.1, 1e-12));
    }

    #[test]
    fn pmac_stretched_move() {
        // 0.1 mm at 3 mm/s would take 33 ms; TA = 133 ms stretches it, so
        // the plateau is 0.1/0.133 mm/s and from rest to rest it takes 2·TA.
        let m = machine(Controller::Pmac);
        let t = run(&m, &[line(0.1, 0.0, 3.0)]);
        check_consistent(&t);
        assert!(close(t[0].achieved_feed_mm_s, 0.1 / 0.133, 1e-12));
        assert!(close(t[0].time_s, 0.266, 1e-12));
        assert_eq!(t[0].limited_by, Limit::Ta);
        // A long move reaches F and takes L/F + TA.
        let t = run(&m, &[line(1.0, 0.0, 3.0)]);
        assert!(close(t[0].time_s, 1.0 / 3.0 + 0.133, 1e-12));
        assert_eq!((t[0].achieved_feed_mm_s, t[0].limited_by), (3.0, Limit::None));
    }

    #[test]
    fn pmac_blends_corners_without_slowing() {
        let m = machine(Controller::Pmac);
        let t = run(&m, &[line(1.0, 0.0, 3.0), line(0.0, 1.0, 3.0)]);
        check_consistent(&t);
        assert!(close(t[0].time_s + t[1].time_s, 2.0 / 3.0 + 0.133, 1e-12));
        // Equal speeds: the boundary is the middle of a flat "ramp".
        assert!(close(t[0].time_s, 1.0 / 3.0 + 0.133 / 2.0, 1e-12));
    }

    #[test]
    fn pmac_blend_takes_the_incoming_moves_ta() {
        // 1 mm from rest at TA 133, then TA 6 and 0.03 mm: the second move
        // is not stretched (10 ms >= 6 ms), and the blend into it (at one
        // speed, so flat) starts 3 ms before its nominal start: that is
        // where an M33== on it acts.
        let m = machine(Controller::Pmac);
        let mut tm = TimeModel::new(&m);
        tm.push_move(line(1.0, 0.0, 3.0));
        tm.set_accel(Some(6.0), Some(0.0));
        tm.push_move(line(0.03, 0.0, 3.0));
        let t = drain(tm);
        check_consistent(&t);
        assert_eq!(t[1].limited_by, Limit::None);
        assert!(close(t[1].achieved_feed_mm_s, 3.0, 1e-12));
        assert!(close(t[1].t_start_s - t[1].exec_start_s, 0.003, 1e-12));
        // The other way round the blend is clamped to what the shorter
        // move before it has left, so the curve stays consistent.
        let mut tm = TimeModel::new(&m);
        tm.set_accel(Some(6.0), Some(0.0));
        tm.push_move(line(0.03, 0.0, 3.0));
        tm.set_accel(Some(133.0), Some(0.0));
        tm.push_move(line(1.0, 0.0, 3.0));
        check_consistent(&drain(tm));
    }

    #[test]
    fn pmac_s_curve_time_and_block_rate() {
        let mut m = machine(Controller::Pmac);
        m.ta_ms = 10.0;
        m.ts_ms = 50.0;
        let t = run(&m, &[line(0.01, 0.0, 3.0)]);
        assert!(close(t[0].time_s, 0.2, 1e-12), "2·TS wins over TA");
        let mut tm = TimeModel::new(&m);
        tm.set_accel(Some(20.0), Some(0.0));
        tm.push_move(line(0.01, 0.0, 3.0));
        tm.finish();
        let Some(Event::Block(b)) = tm.pop() else { panic!() };
        assert!(close(b.time_s, 0.04, 1e-12), "TA/TS from the program");
        // TA0 is TA1 on a Turbo PMAC (whole ms, at least 1): the block
        // lasts the block-rate time plus the half ramps at its ends.
        m.ta_ms = 0.0;
        m.ts_ms = 0.0;
        m.block_rate_hz = 100.0;
        let t = run(&m, &[line(0.01, 0.0, 3.0)]);
        assert_eq!(t[0].limited_by, Limit::BlockRate);
        assert!(close(t[0].time_s, 0.011, 1e-12), "{}", t[0].time_s);
    }

    #[test]
    fn rotary_moves_take_the_rotary_axes_time() {
        for c in [Controller::Pmac, Controller::Lookahead] {
            let mut m = machine(c);
            m.rotary = Some(crate::machine::Rotary {
                max_deg_s: 30.0,
                rapid_deg_s: 90.0,
                accel_deg_s2: 300.0,
            });
            // Indexing: 90 degrees at F 60 deg/s capped to 30, 0.1 s ramps.
            let mut index = MotionBlock::straight(MoveClass::Line, V3::zeros(), 60.0);
            index.rotary_deg = 90.0;
            // Rapid indexing: 9 degrees cannot reach 90 deg/s: a triangle.
            let mut rapid = MotionBlock::straight(MoveClass::Rapid, V3::zeros(), 0.0);
            rapid.rotary_deg = 9.0;
            // Both: 1 mm at 3 mm/s while turning 60 degrees: the rotary
            // maximum (30 deg/s) holds the feed to 0.5 mm/s.
            let mut both = line(1.0, 0.0, 3.0);
            both.rotary_deg = 60.0;
            let t = run(&m, &[line(1.0, 0.0, 3.0), index, rapid, both]);
            check_consistent(&t);
            assert!(close(t[1].time_s, 3.0 + 0.1, 1e-12), "{c:?}: {}", t[1].time_s);
            assert!(close(t[2].time_s, 2.0 * (9.0f64 / 300.0).sqrt(), 1e-12), "{c:?}");
            assert!(close(t[2].t_start_s, t[1].t_start_s + t[1].time_s, 1e-12), "{c:?}");
            assert!(close(t[3].block.feed_mm_s, 0.5, 1e-12), "{c:?}");
            assert!(t[3].time_s >= 2.0 - 1e-12, "{c:?}: {}", t[3].time_s);
        }
        // Without a rotary section the linear figures count, as degrees.
        let m = machine(Controller::Pmac);
        let r = m.rotary_or_linear();
        assert_eq!((r.max_deg_s, r.rapid_deg_s), (m.max_feed_mm_s, m.rapid_mm_s));
    }

    #[test]
    fn pmac_rapid_runs_each_axis_and_stops() {
        let mut m = machine(Controller::Pmac);
        m.rapid_mm_s = 10.0;
        m.rapid_accel_mm_s2 = 100.0;
        let rapid = MotionBlock::straight(MoveClass::Rapid, V3::new(10.0, 0.5, 0.0), 0.0);
        let t = run(&m, &[line(1.0, 0.0, 3.0), rapid, line(1.0, 0.0, 3.0)]);
        check_consistent(&t);
        // X: 10 mm at 10 mm/s with 0.1 s ramps = 1.1 s; Y is faster.
        assert!(close(t[1].time_s, 1.1, 1e-12));
        assert!(close(t[0].time_s, 1.0 / 3.0 + 0.133, 1e-12), "stops before the rapid");
    }

    /// Bayesteh (2013) Fig. 3-20: a straight path at 3 mm/s in equal segments on
    /// the micro mill's PMAC (TA ≈ 133 ms): the achieved feed grows
    /// linearly with segment length and reaches 3 mm/s at about 0.4 mm.
    #[test]
    fn fig_3_20_achieved_feed_grows_linearly_with_segment_length() {
        let m = Machine::builtin("micro-mill");
        let ta = crate::machine::pmac::accel_time_s(m.ta_ms, m.ts_ms);
        let mut reached = None;
        for i in 1..=16 {
            let s = 0.05 * i as f64;
            let blocks: Vec<MotionBlock> = (0..40).map(|_| line(s, 0.0, 3.0)).collect();
            let t = run(&m, &blocks);
            check_consistent(&t);
            let mid = &t[20];
            let want = (s / ta).min(3.0);
            assert!(
                close(mid.achieved_feed_mm_s, want, 1e-9),
                "{s}: {}",
                mid.achieved_feed_mm_s
            );
            if s < 0.39 {
                assert_eq!(mid.limited_by, Limit::Ta);
                // Linear: feed per length is the same for every short segment.
                assert!(close(mid.achieved_feed_mm_s / s, 1.0 / ta, 1e-9));
            }
            if reached.is_none() && mid.achieved_feed_mm_s >= 3.0 - 1e-9 {
                reached = Some(s);
            }
        }
        let s = reached.unwrap();
        assert!((0.39..=0.45).contains(&s), "reaches 3 mm/s at {s} mm");
    }

    #[test]
    fn arcs_are_held_to_centripetal_acceleration() {
        let m = machine(Controller::Lookahead);
        let mut b = line(10.0, 0.0, 10.0);
        b.class = MoveClass::Arc;
        b.radius_mm = 0.25;
        let t = run(&m, &[b]);
        // v = sqrt(a·r) = 5 mm/s.
        assert!(close(t[0].achieved_feed_mm_s, 5.0, 1e-12));
        assert_eq!(t[0].limited_by, Limit::Centripetal);
    }

    mod props {
        use super::*;
        use proptest::prelude::*;

        /// (kind, length, heading, feed, radius): kind 0-4 line, 5 rapid,
        /// 6-7 arc, 8 dwell, 9 TA change.
        fn step() -> impl Strategy<Value = (u8, f64, f64, f64, f64)> {
            (
                0u8..10,
                prop_oneof![Just(0.0), 0.0..3.0f64],
                0.0..6.3f64,
                0.1..50.0f64,
                0.05..5.0f64,
            )
        }

        fn check_stream(m: &Machine, steps: &[(u8, f64, f64, f64, f64)]) {
            let mut tm = TimeModel::new(m);
            let mut dir = V3::x();
            for &(k, l, h, f, r) in steps {
                let d = V3::new(h.cos(), h.sin(), 0.0);
                match k {
                    8 => tm.push_dwell(l * 0.01, None),
                    // A PMAC with zero acceleration time jumps in speed; not tested.
                    9 => tm.set_accel(Some(1.0 + l * 50.0), Some(l * 10.0)),
                    5 => tm.push_move(MotionBlock::straight(MoveClass::Rapid, d * l, 0.0)),
                    6 | 7 => {
                        // An arc turning by up to a right angle.
                        let mut b = MotionBlock::straight(MoveClass::Arc, d * l, f);
                        b.dir_in = dir;
                        b.dir_out = d;
                        b.radius_mm = r;
                        if l == 0.0 {
                            b.dir_in = V3::zeros();
                            b.dir_out = V3::zeros();
                        }
                        tm.push_move(b);
                    }
                    _ => tm.push_move(MotionBlock::straight(MoveClass::Line, d * l, f)),
                }
                if l > 0.0 && k != 8 && k != 9 {
                    dir = d;
                }
            }
            tm.finish();
            let (mut now, mut v) = (0.0_f64, 0.0_f64);
            while let Some(e) = tm.pop() {
                match e {
                    Event::Dwell { t_start_s, seconds, .. } => {
                        assert!(close(t_start_s, now, 1e-9) && v.abs() < 1e-9, "dwell while moving");
                        now += seconds;
                    }
                    Event::Block(b) => {
                        assert!(close(b.t_start_s, now, 1e-9));
                        let dist: f64 = b.pieces().iter().map(|p| p.distance()).sum();
                        assert!(close(dist, b.block.length_mm, 1e-9 * (1.0 + b.block.length_mm)));
                        assert!(b.time_s >= 0.0 && b.time_s.is_finite());
                        for p in b.pieces() {
                            assert!(close(p.v0, v, 1e-9 * (1.0 + v)), "speed jumps {v} -> {}", p.v0);
                            assert!(p.v0 >= -1e-12 && p.v1 >= -1e-12 && p.dt > 0.0);
                            if m.controller == Controller::Lookahead {
                                let acc = (p.v1 - p.v0).abs() / p.dt;
                                assert!(acc <= m.accel_mm_s2 * (1.0 + 1e-6), "accel {acc}");
                            }
                            v = p.v1;
                        }
                        // A zero-length block only passes on the speed around it.
                        if b.block.class != MoveClass::Rapid && b.block.length_mm > 0.0 {
                            let cap = b.commanded_feed_mm_s.min(m.max_feed_mm_s);
                            assert!(
                                b.achieved_feed_mm_s <= cap * (1.0 + 1e-9),
                                "{} > {cap}",
                                b.achieved_feed_mm_s
                            );
                            let reached = b.achieved_feed_mm_s >= b.commanded_feed_mm_s * (1.0 - 1e-9);
                            assert!((b.limited_by == Limit::None) == reached, "{b:?}");
                        }
                        now += b.time_s;
                    }
                }
            }
            assert!(v.abs() < 1e-9, "ends moving at {v}");
            assert!(close(now, tm.now_s(), 1e-9));
        }

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(256))]

            #[test]
            fn lookahead_streams_are_consistent(steps in prop::collection::vec(step(), 1..40)) {
                let mut m = machine(Controller::Lookahead);
                m.max_feed_mm_s = 30.0;
                m.block_rate_hz = 200.0;
                m.lookahead_blocks = 4;
                check_stream(&m, &steps);
            }

            #[test]
            fn pmac_streams_are_consistent(steps in prop::collection::vec(step(), 1..40)) {
                let mut m = machine(Controller::Pmac);
                m.max_feed_mm_s = 30.0;
                check_stream(&m, &steps);
            }
        }
    }
}
