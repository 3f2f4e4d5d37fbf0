//! The look-ahead planner model (grbl, Klipper): constant acceleration,
//! junction-deviation corner speeds, centripetal limits on arcs, and a
//! planner buffer of `lookahead_blocks` that must be able to stop at its
//! end.

use super::{Event, Limit, MAX_PIECES, MotionBlock, MoveClass, Piece, TimedBlock, add_piece};
use crate::geometry::V3;
use crate::machine::Machine;
use std::collections::VecDeque;

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

pub(super) struct Lookahead {
    accel: f64,
    jd: f64,
    n_max: usize,
    max_feed: f64,
    rapid: f64,
    block_time: f64,
    /// Time the path has reached (end of the last emitted block).
    pub(super) t: f64,
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
    pub(super) fn new(m: &Machine) -> Lookahead {
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

    pub(super) fn push_move(&mut self, b: MotionBlock, out: &mut VecDeque<Event>) {
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

    pub(super) fn stop(&mut self, out: &mut VecDeque<Event>) {
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
