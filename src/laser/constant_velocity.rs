//! One cut path -> constant-velocity moves: lead-in, cut pieces with a
//! beam-off loop at every non-tangent corner, lead-out, and the shutter
//! commands moved earlier by its latencies so the shutter is fully open
//! exactly over the cut.
//!
//! For a Turbo PMAC every piece also gets its pace: the path's first and
//! last blocks ramp from and to rest over the machine's TA, and every block
//! between runs at V with a short TA of whole milliseconds no longer than
//! the block itself or the one before it. A Turbo PMAC stretches a block
//! shorter than its TA to TA, and blends two moves over the
//! incoming move's TA, starting TA/2 before the boundary, which is also
//! where an `M33==` takes effect (Turbo PMAC User Manual, synchronous
//! M-variable assignment). So each shutter switch is placed V·t/2 after
//! the point where the command must act, with t the TA of the block that
//! carries it, chosen so that no block is stretched.

use super::dubins::corner_loop;
use super::elem::MIN_PIECE;
use super::setup::LaserSetup;
use crate::geometry::Segment;
use crate::geometry::{P3, Plane, V2};
use crate::machine::Controller;
use crate::model::toolpath::{Motion, MotionKind, Record, Role};

/// A path whose pieces carry their role (cut, or a beam-off connection).
pub type Tagged = Vec<(Segment, Role)>;

/// One planned piece: geometry, why it is there, the commanded beam and,
/// for a PMAC, its pace.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    /// The geometry (mm), in travel order; consecutive pieces join.
    pub elem: Segment,
    /// Why the piece is there: cut, lead-in, lead-out, corner loop, link.
    pub role: Role,
    /// The shutter state commanded for this piece. It differs from `role
    /// == Cut` near the ends of a cut: the commands go early by the
    /// shutter's latencies.
    pub beam: bool,
    /// `None` for look-ahead controllers, which pace themselves.
    pub pace: Option<Pace>,
}

/// How a Turbo PMAC is told to pace one block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// The path's first or last block: from or to rest over the machine's
    /// TA and TS.
    Ramp,
    /// A block at V, blended into from the previous one over this TA (whole
    /// ms, TS 0); never longer than the block or the block before it.
    Cruise(u32),
}

/// Something the user should know about a planned path.
#[derive(Debug, Clone, PartialEq)]
pub enum Note {
    /// A cut shorter than the shutter's minimum exposure at V.
    ShortCut {
        /// The cut's length (mm).
        length: f64,
        /// The least length the shutter can expose at V (mm).
        min: f64,
    },
    /// Drawing arcs tighter than V²/a: the stage cannot follow them at V
    /// within its acceleration. One note per path.
    TightArc {
        /// The tightest radius (mm).
        radius: f64,
        /// The acceleration it demands at V (mm/s²).
        demand: f64,
        /// How many arcs of the path are too tight.
        count: usize,
    },
    /// A corner between pieces whose turn could not be looped (the
    /// direction has no component in the loop plane).
    UnloopedCorner {
        /// The corner (mm).
        at: P3,
    },
    /// Shutter commands that act off the point they must: the pieces next
    /// to the switch point are only a few ms long at V, so no block
    /// boundary fits exactly (PMAC: with a whole-ms TA; look-ahead: without
    /// a block shorter than V·1 ms).
    SwitchOff {
        /// How many commands are off.
        count: usize,
        /// The worst distance off (mm, at most V·1 ms).
        worst: f64,
    },
}

impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Note::ShortCut { length, min } => write!(
                f,
                "cut of {length:.6} mm is shorter than the minimum exposure ({min:.6} mm at this feed)"
            ),
            Note::TightArc { radius, demand, count } => write!(
                f,
                "{count} arc(s) tighter than V²/a; the tightest, radius {radius:.6} mm, asks {demand:.3} mm/s² at this feed"
            ),
            Note::UnloopedCorner { at } => write!(f, "corner at ({}, {}, {}) could not be looped", at.x, at.y, at.z),
            Note::SwitchOff { count, worst } => write!(
                f,
                "{count} shutter switch(es) act up to {:.3} µm off their point: the pieces there last only a few ms \
                 at V, too short for a block boundary exactly there",
                worst * 1000.0
            ),
        }
    }
}

/// Plan one cut path. `path` is continuous; `closed` paths end where they
/// start (the seam gets a lead-out and the next pass its own lead-in).
pub fn plan_path(path: &[Segment], m: &LaserSetup, notes: &mut Vec<Note>) -> Vec<Piece> {
    let tagged: Vec<(Segment, Role)> = path.iter().map(|e| (*e, Role::Cut)).collect();
    plan_tagged(&tagged, m, notes)
}

/// Plan a path whose pieces are cuts or beam-off connections the caller
/// already shaped (zigzag turnarounds: role `Loop` or `Link`, tangent to
/// their neighbours). Loops are added only between two cut pieces.
pub fn plan_tagged(path: &[(Segment, Role)], m: &LaserSetup, notes: &mut Vec<Note>) -> Vec<Piece> {
    let path: Vec<(Segment, Role)> = path.iter().copied().filter(|e| e.0.length() > MIN_PIECE).collect();
    let (Some((first, _)), Some((last, _))) = (path.first(), path.last()) else {
        return Vec::new();
    };
    let r = m.min_radius();
    let cos_tol = m.tangent_cos();
    let mut out = Vec::with_capacity(path.len() + 2);
    // Count of drawing arcs tighter than V²/a and the tightest radius:
    // one note per path, not one per arc.
    let mut tight = (0usize, f64::INFINITY);
    let pmac = m.controller == Controller::Pmac;
    let ramp = pmac.then_some(Pace::Ramp);
    let s0 = first.start();
    out.push(Piece {
        elem: Segment::line(s0 - first.start_tangent() * m.lead_in(), s0),
        role: Role::LeadIn,
        beam: false,
        pace: ramp,
    });
    for (i, (e, role)) in path.iter().enumerate() {
        if *role != Role::Cut {
            out.push(Piece {
                elem: *e,
                role: *role,
                beam: false,
                pace: None,
            });
            continue;
        }
        if e.curvature_radius() < r * (1.0 - 1e-9) {
            tight.0 += 1;
            tight.1 = tight.1.min(e.curvature_radius());
        }
        out.push(Piece {
            elem: *e,
            role: Role::Cut,
            beam: true,
            pace: None,
        });
        let Some((next, Role::Cut)) = path.get(i + 1) else {
            continue;
        };
        let (din, dout) = (e.end_tangent(), next.start_tangent());
        if din.dot(&dout) >= cos_tol {
            continue;
        }
        let plane = loop_plane(e, next);
        let (a, b, _) = plane.axes();
        let d2 = |v: crate::geometry::V3| V2::new(v[a], v[b]);
        let corner = e.end();
        let lp = (d2(din).norm() > 1e-9 && d2(dout).norm() > 1e-9)
            .then(|| {
                corner_loop(
                    corner,
                    d2(din).normalize(),
                    d2(dout).normalize(),
                    r,
                    m.connection_shape(),
                    plane,
                )
            })
            .flatten();
        match lp {
            Some(lp) => out.extend(lp.into_iter().map(|elem| Piece {
                elem,
                role: Role::Loop,
                beam: false,
                pace: None,
            })),
            None => notes.push(Note::UnloopedCorner { at: corner }),
        }
    }
    if tight.0 > 0 {
        notes.push(Note::TightArc {
            radius: tight.1,
            demand: m.feed * m.feed / tight.1,
            count: tight.0,
        });
    }
    let e = last.end();
    let dir = last.end_tangent();
    let lead_out = |a: P3, b: P3, pace: Option<Pace>| Piece {
        elem: Segment::line(a, b),
        role: Role::LeadOut,
        beam: false,
        pace,
    };
    let end = e + dir * m.lead_out();
    if pmac {
        // At V until the shutter is closed and the blend into the stopping
        // block is over, then the stopping block.
        let mid = e + dir * m.lead_out_cruise();
        out.push(lead_out(e, mid, None));
        out.push(lead_out(mid, end, ramp));
        time_shutter_pmac(out, m, notes)
    } else {
        out.push(lead_out(e, end, None));
        time_shutter(out, m, notes)
    }
}

/// Loops turn in the plane of the arcs around them, else XY.
fn loop_plane(a: &Segment, b: &Segment) -> Plane {
    match (a, b) {
        (Segment::Arc(x), _) => x.plane,
        (_, Segment::Arc(y)) => y.plane,
        _ => Plane::Xy,
    }
}

/// Where along the path (arc length) the shutter commands must act: each
/// run of cut pieces [s0, s1] becomes [s0 - open lead, s1 - close lead], so
/// that the shutter, commanded at V, is fully open from s0 and starts to
/// close at s1. Cuts shorter than the minimum exposure are noted.
fn commanded_on(pieces: &[Piece], lens: &[f64], m: &LaserSetup, notes: &mut Vec<Note>) -> Vec<(f64, f64)> {
    let mut on: Vec<(f64, f64)> = Vec::new();
    let mut s = 0.0;
    let mut run: Option<f64> = None;
    for (p, &len) in pieces.iter().zip(lens) {
        match (p.role == Role::Cut, run) {
            (true, None) => run = Some(s),
            (false, Some(s0)) => {
                on.push((s0, s));
                run = None;
            }
            _ => {}
        }
        s += len;
    }
    if let Some(s0) = run {
        on.push((s0, s));
    }
    for &(a, b) in &on {
        // `b - a` is a difference of path lengths summed from the start:
        // a cut exactly the minimum long comes out a few ulps short.
        if b - a < m.min_cut() - 1e-9 * (1.0 + b.abs()) {
            notes.push(Note::ShortCut {
                length: b - a,
                min: m.min_cut(),
            });
        }
    }
    on.iter()
        .map(|&(a, b)| (a - m.open_lead(), (b - m.close_lead()).max(a - m.open_lead())))
        .collect()
}

/// Look-ahead controllers switch at the block boundary: split the pieces
/// exactly where the commands must act, unless a split would leave a piece
/// shorter than the least block (V·1 ms: a look-ahead control computes
/// about 1,000 blocks a second and slows down for shorter ones). Then the
/// piece is not split, and the command acts at its nearer end, less than
/// a least block off (counted in a [`Note::SwitchOff`]).
fn time_shutter(pieces: Vec<Piece>, m: &LaserSetup, notes: &mut Vec<Note>) -> Vec<Piece> {
    // Arc lengths cost an atan2 each; a million-segment job asks them once.
    let lens: Vec<f64> = pieces.iter().map(|p| p.elem.length()).collect();
    let cmd = commanded_on(&pieces, &lens, m, notes);
    let mut cuts: Vec<f64> = cmd.iter().flat_map(|&(a, b)| [a, b]).collect();
    cuts.sort_by(f64::total_cmp);
    // Intervals come in path order, so the one that may hold x is the last
    // starting before it (overlaps, if a loop were too short, are checked
    // one step back).
    let inside = |x: f64| {
        let k = cmd.partition_point(|&(a, _)| a < x);
        cmd[..k].iter().rev().take(2).any(|&(a, b)| x > a && x < b)
    };
    let mut out = Vec::with_capacity(pieces.len() + 2 * cmd.len());
    let mut s = 0.0;
    let mut k = 0;
    let min_block = m.min_block();
    // Commands that act off their point: count, worst (mm).
    let mut off = (0usize, 0.0f64);
    for (p, len) in pieces.into_iter().zip(lens) {
        let end = s + len;
        let mut rest = p.elem;
        let mut rest_s = s;
        while k < cuts.len() && cuts[k] <= s + MIN_PIECE {
            k += 1;
        }
        if k >= cuts.len() || cuts[k] >= end - MIN_PIECE {
            // No switching inside this piece: the common case.
            let beam = inside(s + 0.5 * len);
            out.push(Piece { beam, ..p });
            s = end;
            continue;
        }
        while k < cuts.len() && cuts[k] < end - MIN_PIECE {
            let (before, after) = (cuts[k] - rest_s, end - cuts[k]);
            if before < min_block || after < min_block {
                // Too near an end of what is left of the piece: no split;
                // the piece takes the state at its middle, so the switch
                // acts at one of its ends.
                off.0 += 1;
                off.1 = off.1.max(before.min(after));
                k += 1;
                continue;
            }
            if let Some((a, b)) = rest.split_at_length(cuts[k] - rest_s, MIN_PIECE) {
                let mid = rest_s + 0.5 * a.length();
                out.push(Piece {
                    elem: a,
                    beam: inside(mid),
                    ..p
                });
                rest_s += a.length();
                rest = b;
            }
            k += 1;
        }
        let mid = rest_s + 0.5 * rest.length();
        out.push(Piece {
            elem: rest,
            beam: inside(mid),
            ..p
        });
        s = end;
    }
    if off.0 > 0 {
        notes.push(Note::SwitchOff {
            count: off.0,
            worst: off.1,
        });
    }
    out
}

/// A piece on its way through [`time_shutter_pmac`].
struct Slot {
    piece: Piece,
    start: f64,
    len: f64,
    /// Carries a shutter command: its TA and the beam state it sets.
    switch: Option<(u32, bool)>,
}

impl Slot {
    fn end(&self) -> f64 {
        self.start + self.len
    }
}

/// Append a piece of length `len` at path length `end`, and move `end`.
fn push_slot(slots: &mut Vec<Slot>, end: &mut f64, (piece, len): (Piece, f64)) {
    slots.push(Slot {
        piece,
        start: *end,
        len,
        switch: None,
    });
    *end += len;
}

/// Where one command goes: on the boundary before `slots[at]`, or inside
/// `slots[at]` at `b`, carried by a block of TA `t`.
struct Placement {
    at: usize,
    b: f64,
    inside: bool,
    t: u32,
}

/// Turbo PMAC: each command acts V·t/2 before the boundary of the block
/// carrying it (t = that block's TA), so the boundary goes there, with t
/// the largest whole TA (up to the cut TA) for which neither block around
/// the boundary is shorter than t and the block before allows it. Then
/// every block gets its TA: min(cut TA, its own time, the time of the block
/// before), so that no block is stretched and two blends never overlap.
fn time_shutter_pmac(pieces: Vec<Piece>, m: &LaserSetup, notes: &mut Vec<Note>) -> Vec<Piece> {
    let lens: Vec<f64> = pieces.iter().map(|p| p.elem.length()).collect();
    let cmd = commanded_on(&pieces, &lens, m, notes);
    let v = m.feed;
    let tac = m.cut_ta();
    let margin = m.block_margin();
    let ms = |len: f64| (len - margin) / v * 1000.0;
    let mut slots: Vec<Slot> = Vec::with_capacity(pieces.len() + 2 * cmd.len());
    let mut input = pieces.into_iter().zip(lens);
    let mut end = 0.0;
    let mut last_b = f64::NEG_INFINITY;
    // Commands that could not act exactly where they must: count, worst (mm).
    let mut off = (0usize, 0.0f64);
    let commands = cmd.iter().flat_map(|&(a, b)| [(a, true), (b, false)]);
    for (c, on) in commands {
        // Load the pieces up to the farthest candidate, plus one for the
        // block after a boundary candidate.
        let reach = c + v * tac as f64 / 2000.0 + MIN_PIECE;
        while end <= reach {
            let Some(next) = input.next() else { break };
            push_slot(&mut slots, &mut end, next);
        }
        if let Some(next) = input.next() {
            push_slot(&mut slots, &mut end, next);
        }
        let Some((p, err)) = place(&slots, c, last_b, m) else {
            off.0 += 1;
            off.1 = f64::INFINITY;
            continue;
        };
        if err > 1e-9 {
            off.0 += 1;
            off.1 = off.1.max(err);
        }
        let at = if p.inside {
            let s = &slots[p.at];
            match s.piece.elem.split_at_length(p.b - s.start, MIN_PIECE) {
                Some((a, rest)) => {
                    let start = s.start;
                    let (la, lr) = (a.length(), rest.length());
                    let front_pace = s.piece.pace;
                    let piece = s.piece.clone();
                    slots[p.at] = Slot {
                        piece: Piece {
                            elem: a,
                            pace: front_pace,
                            ..piece.clone()
                        },
                        start,
                        len: la,
                        switch: s.switch,
                    };
                    slots.insert(
                        p.at + 1,
                        Slot {
                            piece: Piece {
                                elem: rest,
                                pace: None,
                                ..piece
                            },
                            start: start + la,
                            len: lr,
                            switch: None,
                        },
                    );
                    p.at + 1
                }
                None => continue,
            }
        } else {
            p.at
        };
        slots[at].switch = Some((p.t, on));
        last_b = slots[at].start;
    }
    if off.0 > 0 {
        notes.push(Note::SwitchOff {
            count: off.0,
            worst: off.1,
        });
    }
    for next in input {
        push_slot(&mut slots, &mut end, next);
    }
    let mut beam = false;
    let mut prev_ms = f64::INFINITY;
    let mut out = Vec::with_capacity(slots.len());
    for s in slots {
        let d = ms(s.len);
        let pace = match (s.piece.pace, s.switch) {
            (Some(Pace::Ramp), _) => Pace::Ramp,
            (_, Some((t, _))) => Pace::Cruise(t),
            _ => Pace::Cruise(whole_ta(tac, d.min(prev_ms))),
        };
        if let Some((_, on)) = s.switch {
            beam = on;
        }
        prev_ms = d;
        out.push(Piece {
            beam,
            pace: Some(pace),
            ..s.piece
        });
    }
    out
}

/// The TA (whole ms, at least 1) of a block at V whose own time, or its
/// predecessor's, is `d` ms.
fn whole_ta(tac: u32, d: f64) -> u32 {
    let fl = if d.is_finite() {
        (d + 1e-6).floor()
    } else {
        f64::from(tac)
    };
    (fl.min(f64::from(tac)) as u32).max(1)
}

/// Where to carry the command that must act at `c`: the boundary b (an
/// existing one, or a split) and the TA t of the block after it, so that
/// the command acts at b - V·t/2, as close to `c` as blocks allow. A
/// candidate is feasible when neither block around b is shorter than t
/// (nor than its own TA), the block before allows a TA of at least t (so
/// either reading of which TA a blend takes gives t), and a ramp stays long
/// enough for its ramp. Among the best positions the largest t wins. The
/// answer is exact wherever the pieces near `c` are at least 1 ms long at
/// V; next to shorter drawing pieces it may act up to V·1 ms off.
fn place(slots: &[Slot], c: f64, last_b: f64, m: &LaserSetup) -> Option<(Placement, f64)> {
    let v = m.feed;
    let tac = m.cut_ta();
    let q = m.block_margin();
    let ms = |len: f64| (len - q) / v * 1000.0;
    // Least length of a block of TA t (ms).
    let len_for = |t: f64| v * t / 1000.0 + q;
    let ramp_len = m.ramp_time_s() * v + q;
    // Least length of the part of slot i before a boundary for a command
    // block of TA t, or None when the block before cannot allow t.
    let before = |i: usize, t: f64| -> Option<f64> {
        let s = &slots[i];
        if s.piece.pace == Some(Pace::Ramp) {
            return (s.piece.role == Role::LeadIn).then_some(ramp_len);
        }
        if let Some((tp, _)) = s.switch {
            let tp = f64::from(tp);
            return (tp >= t).then_some(len_for(tp));
        }
        // Its TA is held to the time of the block before it (at least 1).
        let prev_ok = i == 0
            || slots[i - 1].piece.pace == Some(Pace::Ramp)
            || f64::from(whole_ta(tac, ms(slots[i - 1].len))) >= t - 1e-6;
        prev_ok.then_some(len_for(t))
    };
    let window = v * f64::from(tac) / 1000.0;
    let mut best: Option<(f64, Placement)> = None;
    let mut consider = |err: f64, p: Placement| {
        let better = match &best {
            None => true,
            Some((e, bp)) => err < e - 1e-12 || (err <= e + 1e-12 && p.t > bp.t),
        };
        if better && p.b > last_b + MIN_PIECE {
            best = Some((err, p));
        }
    };
    for i in (0..slots.len()).rev() {
        let s = &slots[i];
        if s.end() < c - window {
            break;
        }
        if s.start > c + window + MIN_PIECE {
            continue;
        }
        let carries = s.piece.pace != Some(Pace::Ramp) || s.piece.role == Role::LeadIn;
        for t in 1..=tac {
            let tf = f64::from(t);
            let half = 0.5 * v * tf / 1000.0;
            // On the boundary before slot i: no split.
            if i > 0
                && s.piece.pace != Some(Pace::Ramp)
                && s.switch.is_none()
                && s.len >= len_for(tf) - 1e-12
                && before(i - 1, tf).is_some_and(|need| slots[i - 1].len >= need - 1e-12)
            {
                let acts = s.start - half;
                consider(
                    (acts - c).abs(),
                    Placement {
                        at: i,
                        b: s.start,
                        inside: false,
                        t,
                    },
                );
            }
            // Inside slot i: the front keeps its pace, the rest carries.
            if carries && let Some(need) = before(i, tf) {
                let (lo, hi) = (s.start + need, s.end() - len_for(tf));
                if lo <= hi {
                    let b = (c + half).clamp(lo, hi);
                    consider(
                        (b - half - c).abs(),
                        Placement {
                            at: i,
                            b,
                            inside: true,
                            t,
                        },
                    );
                }
            }
        }
    }
    best.map(|(e, p)| (p, e))
}

/// Turn planned pieces into toolpath moves at feed V, preceded by a rapid
/// link to the lead-in start. For a PMAC, an `accel` record goes before
/// every block whose pace differs from the one before; every path starts
/// and ends on the machine's ramps, so the state between paths is those.
pub fn to_records(pieces: &[Piece], m: &LaserSetup, chain: Option<u64>, out: &mut Vec<Record>) {
    let Some(first) = pieces.first() else { return };
    out.push(Record::Move(Motion {
        kind: MotionKind::Rapid,
        to: first.elem.start(),
        feed: None,
        beam: false,
        beam_switch: None,
        role: Some(Role::Link),
        chain,
        block: None,
        tool: Default::default(),
    }));
    let mut pace = Pace::Ramp;
    for p in pieces {
        if let Some(next) = p.pace
            && next != pace
        {
            out.push(match next {
                Pace::Ramp => ramps_record(m),
                Pace::Cruise(t) => Record::Accel {
                    ta_ms: Some(f64::from(t)),
                    ts_ms: Some(0.0),
                    block: None,
                },
            });
            pace = next;
        }
        out.push(Record::Move(Motion {
            kind: MotionKind::of_segment(&p.elem),
            to: p.elem.end(),
            feed: Some(m.feed),
            beam: p.beam,
            beam_switch: None,
            role: Some(p.role),
            chain,
            block: None,
            tool: Default::default(),
        }));
    }
}

/// The program's TA/TS, first in every generated job: the lead-in and
/// lead-out lengths assume these ramps, so the controller must not run
/// with whatever Isx87/Isx88 it happens to hold.
pub fn ramps_record(m: &LaserSetup) -> Record {
    Record::Accel {
        ta_ms: Some(m.program_ta_ms()),
        ts_ms: Some(m.ts_ms),
        block: None,
    }
}

/// Plan several tagged paths in order, each with its own leads and shutter
/// timing, joined by rapids. Pattern generators use this.
pub fn plan_paths(paths: &[Vec<(Segment, Role)>], m: &LaserSetup, chain: Option<u64>) -> (Vec<Record>, Vec<Note>) {
    let mut notes = Vec::new();
    let mut recs = vec![ramps_record(m)];
    for p in paths {
        let pieces = plan_tagged(p, m, &mut notes);
        to_records(&pieces, m, chain, &mut recs);
    }
    (recs, notes)
}

/// Tag every piece of a path as a cut.
pub fn all_cut(path: Vec<Segment>) -> Vec<(Segment, Role)> {
    path.into_iter().map(|e| (e, Role::Cut)).collect()
}
