//! The Turbo PMAC model: blended LINEAR/CIRCLE moves of at least the
//! acceleration time each, ramps centred on the nominal boundaries, RAPID
//! as per-axis trapezoids from rest to rest (the rules in the parent
//! module's documentation).

use super::{Event, Limit, MAX_PIECES, MotionBlock, MoveClass, Piece, TimedBlock, add_piece};
use crate::geometry::V3;
use crate::machine::Machine;
use std::collections::VecDeque;

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

pub(super) struct Pmac {
    max_feed: f64,
    rapid: f64,
    rapid_accel: f64,
    block_time: f64,
    pub(super) ta_ms: f64,
    pub(super) ts_ms: f64,
    /// Time the path has reached (end of the last emitted block).
    pub(super) t: f64,
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
    pub(super) fn new(m: &Machine) -> Pmac {
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

    pub(super) fn push_move(&mut self, b: MotionBlock, out: &mut VecDeque<Event>) {
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

    pub(super) fn stop(&mut self, out: &mut VecDeque<Event>) {
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
