//! Beam timing: where along the path the shutter really passes the beam,
//! compared with where the program means it to (its beam-on moves).
//!
//! A change of the commanded beam state is a shutter command issued at a
//! controller-dependent instant:
//! - PMAC `M33==` (synchronous, what pathgen writes): when the controller
//!   starts executing the first move with the new state, i.e. at the start
//!   of the blend into it, half an acceleration time before its nominal
//!   start;
//! - PMAC `M33=` (immediate): when the line is calculated, which on a
//!   blended program is when the move *before* it starts executing, one move
//!   early; after a DWELL, when the dwell ends (DWELL stops look-ahead);
//! - look-ahead controllers (ISO `M3`/`M5` in laser mode): at the block
//!   boundary.
//!
//! The shutter then passes the beam from `open_delay + open_transfer/2`
//! after an open command until `close_delay + close_transfer/2` after a
//! close command (see [`Shutter`]). Path length covered while the beam
//! passes is exposed; exposed length on beam-off moves is over-exposure,
//! unexposed length on beam-on moves is the drawing left uncut.
//!
//! Cuts: beam-on moves are grouped by their `chain` id when the toolpath
//! carries one, else into runs of consecutive beam-on moves (a G-code
//! program read back has no chain ids; each run is one chain cut with the
//! beam on). Over-exposure is charged to the cut whose open command let the
//! beam through.
//!
//! Streaming: commands can only fall at or after the execution start of the
//! latest move, so moves that ended before that (plus the shortest latency)
//! are settled and dropped; memory holds a few moves and one record per cut.

use super::time::{MAX_PIECES, Piece, TimedBlock};
use crate::geometry::P3;
use crate::machine::Shutter;
use crate::model::chain::{Chain, Segment};
use crate::model::toolpath::ShutterSwitch;
use std::collections::{HashMap, VecDeque};

/// When a program's shutter commands take effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandTiming {
    /// PMAC `M33==`: at the start of the next move's execution.
    Sync,
    /// PMAC `M33=`: when the line is calculated (one move ahead).
    Immediate,
    /// At the block boundary (look-ahead controllers).
    Boundary,
}

impl CommandTiming {
    /// The name in gsim's report and on its command line.
    pub fn name(self) -> &'static str {
        match self {
            CommandTiming::Sync => "sync",
            CommandTiming::Immediate => "immediate",
            CommandTiming::Boundary => "boundary",
        }
    }
}

/// One cut: a chain or a run of beam-on moves.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cut {
    /// The chain id its moves carry, or `None` for a run of beam-on moves
    /// without one.
    pub chain: Option<u64>,
    /// Source line of its first beam-on move.
    pub first_line: Option<u64>,
    /// Source line of its last beam-on move.
    pub last_line: Option<u64>,
    /// Beam-on path length, mm.
    pub length_mm: f64,
    /// Of that, exposed, mm.
    pub exposed_mm: f64,
    /// Beam-off path exposed by this cut's shutter window, mm.
    pub overexposed_mm: f64,
    /// Time the beam passed while the machine stood still (dwells), s.
    pub stationary_exposure_s: f64,
    /// End points of the first few beam-on moves, to find the drawing
    /// chain this cut belongs to.
    pub probes: Vec<P3>,
}

impl Cut {
    /// Beam-on length the beam did not reach: drawing left uncut, mm.
    pub fn unexposed_mm(&self) -> f64 {
        (self.length_mm - self.exposed_mm).max(0.0)
    }
}

/// A time window in which the shutter passes the beam.
#[derive(Debug, Clone, Copy)]
struct Light {
    on: f64,
    off: f64,
    cut: usize,
}

enum Item {
    Move {
        t0: f64,
        pieces: [Piece; MAX_PIECES],
        n: usize,
        beam: bool,
        cut: Option<usize>,
    },
    Dwell {
        t0: f64,
        t1: f64,
    },
}

impl Item {
    fn t0(&self) -> f64 {
        match self {
            Item::Move { t0, .. } | Item::Dwell { t0, .. } => *t0,
        }
    }

    fn t1(&self) -> f64 {
        match self {
            Item::Move { t0, pieces, n, .. } => t0 + pieces[..*n].iter().map(|p| p.dt).sum::<f64>(),
            Item::Dwell { t1, .. } => *t1,
        }
    }
}

/// The beam model, fed the timed moves in order.
pub struct BeamModel {
    /// When shutter switches the program does not qualify take effect.
    pub timing: CommandTiming,
    open_lat: f64,
    close_lat: f64,
    min_exposure: f64,
    cmd_on: bool,
    cmd_on_since: f64,
    cmd_on_line: Option<u64>,
    last_exec_start: Option<f64>,
    dwell_end: Option<f64>,
    motion_end: f64,
    prev_beam: bool,
    prev_chain: Option<u64>,
    current: Option<usize>,
    items: VecDeque<Item>,
    lights: VecDeque<Light>,
    /// The cuts so far, in order of their first beam-on move; final after
    /// [`BeamModel::finish`].
    pub cuts: Vec<Cut>,
    by_chain: HashMap<u64, usize>,
    /// Shutter open commands.
    pub opens: u64,
    /// Command windows (open to close) shorter than the shutter's minimum
    /// exposure.
    pub short_exposures: u64,
    /// Source lines of the first [`EXAMPLES`] of those open commands.
    pub short_exposure_lines: Vec<u64>,
    /// Open commands whose close came before the beam got through.
    pub missed_exposures: u64,
    /// Total time the shutter passes the beam, s.
    pub light_time_s: f64,
    /// Keep probe points for matching cuts to a drawing (`--chains`);
    /// off by default, since they cost a few hundred bytes per cut.
    pub keep_probes: bool,
}

/// How many example lines a report lists.
pub const EXAMPLES: usize = 20;

/// Move end points per cut used to match it to a drawing chain.
const PROBES: usize = 16;

impl BeamModel {
    /// A model with `shutter`'s latencies and minimum exposure, shutter
    /// closed, no cuts.
    pub fn new(shutter: &Shutter, timing: CommandTiming) -> BeamModel {
        BeamModel {
            timing,
            open_lat: shutter.open_latency_s(),
            close_lat: shutter.close_latency_s(),
            min_exposure: shutter.min_exposure_ms * 1e-3,
            cmd_on: false,
            cmd_on_since: 0.0,
            cmd_on_line: None,
            last_exec_start: None,
            dwell_end: None,
            motion_end: 0.0,
            prev_beam: false,
            prev_chain: None,
            current: None,
            items: VecDeque::new(),
            lights: VecDeque::new(),
            cuts: Vec::new(),
            by_chain: HashMap::new(),
            opens: 0,
            short_exposures: 0,
            short_exposure_lines: Vec::new(),
            missed_exposures: 0,
            light_time_s: 0.0,
            keep_probes: false,
        }
    }

    fn new_cut(&mut self, chain: Option<u64>) -> usize {
        self.cuts.push(Cut {
            chain,
            ..Default::default()
        });
        self.cuts.len() - 1
    }

    /// The next timed move: assigns it to a cut, issues a shutter command
    /// where its beam state changes, and settles what no later command can
    /// change.
    pub fn add_block(&mut self, tb: &TimedBlock) {
        let b = &tb.block;
        let cut = if b.beam {
            let continuing = self.prev_beam && self.dwell_end.is_none() && self.prev_chain == b.chain;
            let idx = match (b.chain, self.current) {
                (Some(c), _) => match self.by_chain.get(&c) {
                    Some(&i) => i,
                    None => {
                        let i = self.new_cut(Some(c));
                        self.by_chain.insert(c, i);
                        i
                    }
                },
                (None, Some(i)) if continuing => i,
                (None, _) => self.new_cut(None),
            };
            let cut = &mut self.cuts[idx];
            cut.length_mm += b.length_mm;
            if cut.first_line.is_none() {
                cut.first_line = b.line;
            }
            cut.last_line = b.line.or(cut.last_line);
            if self.keep_probes && cut.probes.len() < PROBES {
                cut.probes.push(b.end);
            }
            self.current = Some(idx);
            Some(idx)
        } else {
            None
        };
        self.prev_beam = b.beam;
        self.prev_chain = b.chain;
        if b.beam != self.cmd_on {
            // A PMAC program says per statement how each switch was written;
            // the model's timing is the default for those that do not, and a
            // look-ahead controller always switches at the block boundary.
            let timing = match (self.timing, b.beam_switch) {
                (CommandTiming::Boundary, _) | (_, None) => self.timing,
                (_, Some(ShutterSwitch::Sync)) => CommandTiming::Sync,
                (_, Some(ShutterSwitch::Immediate)) => CommandTiming::Immediate,
            };
            let t = match timing {
                CommandTiming::Sync => tb.exec_start_s,
                CommandTiming::Boundary => tb.t_start_s,
                CommandTiming::Immediate => self.dwell_end.or(self.last_exec_start).unwrap_or(tb.exec_start_s),
            };
            self.command(t, b.beam, cut, b.line);
        }
        self.last_exec_start = Some(tb.exec_start_s);
        self.dwell_end = None;
        self.motion_end = tb.t_start_s + tb.time_s;
        self.items.push_back(Item::Move {
            t0: tb.t_start_s,
            pieces: tb.pieces,
            n: tb.n_pieces,
            beam: b.beam,
            cut,
        });
        self.settle(tb.exec_start_s.min(tb.t_start_s) + self.open_lat.min(self.close_lat));
    }

    /// A dwell from `t0` for `seconds` (s): the stage stands still, and an
    /// immediate shutter command after it acts when it ends.
    pub fn add_dwell(&mut self, t0: f64, seconds: f64) {
        self.items.push_back(Item::Dwell { t0, t1: t0 + seconds });
        self.dwell_end = Some(t0 + seconds);
        self.settle(t0 + seconds + self.open_lat.min(self.close_lat));
    }

    /// End of program: a shutter still open is closed when the last move
    /// has ended (pathgen's trailer stops look-ahead, then closes). A dwell
    /// after the last move is taken to come after the close: the model does
    /// not say on which side of it the program closed.
    pub fn finish(&mut self) {
        if self.cmd_on {
            self.command(self.motion_end, false, None, None);
        }
        self.settle(f64::INFINITY);
    }

    fn command(&mut self, t: f64, on: bool, cut: Option<usize>, line: Option<u64>) {
        if on {
            self.cmd_on = true;
            self.cmd_on_since = t;
            self.cmd_on_line = line;
            self.opens += 1;
            let mut t_on = t + self.open_lat;
            // Still passing light from the previous window: the new window
            // starts where that one ends, so no length counts twice.
            if let Some(last) = self.lights.back() {
                t_on = t_on.max(last.off);
            }
            self.lights.push_back(Light {
                on: t_on,
                off: f64::INFINITY,
                cut: cut.unwrap_or(0),
            });
        } else {
            self.cmd_on = false;
            if t - self.cmd_on_since < self.min_exposure * (1.0 - 1e-12) {
                self.short_exposures += 1;
                if let Some(l) = self.cmd_on_line
                    && self.short_exposure_lines.len() < EXAMPLES
                {
                    self.short_exposure_lines.push(l);
                }
            }
            let off = t + self.close_lat;
            if let Some(last) = self.lights.back_mut() {
                if off <= last.on {
                    self.lights.pop_back();
                    self.missed_exposures += 1;
                } else {
                    last.off = off;
                    self.light_time_s += off - last.on;
                }
            }
        }
    }

    /// Account every item that ends before `horizon`: no later command can
    /// change what the beam did there.
    fn settle(&mut self, horizon: f64) {
        while let Some(item) = self.items.front() {
            let (t0, t1) = (item.t0(), item.t1());
            if t1 > horizon {
                break;
            }
            for l in &self.lights {
                if l.on >= t1 {
                    break;
                }
                let (a, b) = (l.on.max(t0), l.off.min(t1));
                if b <= a {
                    continue;
                }
                match item {
                    Item::Move {
                        pieces, n, beam, cut, ..
                    } => {
                        let mut t = t0;
                        let mut d = 0.0;
                        for p in &pieces[..*n] {
                            d += p.distance_between(a - t, b - t);
                            t += p.dt;
                        }
                        match (beam, cut) {
                            (true, Some(c)) => self.cuts[*c].exposed_mm += d,
                            _ => {
                                if let Some(c) = self.cuts.get_mut(l.cut) {
                                    c.overexposed_mm += d;
                                }
                            }
                        }
                    }
                    Item::Dwell { .. } => {
                        if let Some(c) = self.cuts.get_mut(l.cut) {
                            c.stationary_exposure_s += b - a;
                        }
                    }
                }
            }
            self.items.pop_front();
            while self.lights.len() > 1 && self.lights.front().is_some_and(|l| l.off <= t1) {
                self.lights.pop_front();
            }
        }
    }

    /// Beam-on path length of all cuts: what the program means to cut, mm.
    pub fn intended_mm(&self) -> f64 {
        self.cuts.iter().map(|c| c.length_mm).sum()
    }

    /// Of that, the length the beam reached, mm.
    pub fn exposed_mm(&self) -> f64 {
        self.cuts.iter().map(|c| c.exposed_mm).sum()
    }

    /// Beam-on length the beam did not reach, mm.
    pub fn unexposed_mm(&self) -> f64 {
        self.cuts.iter().map(|c| c.unexposed_mm()).sum()
    }

    /// Beam-off length the beam reached, mm.
    pub fn overexposed_mm(&self) -> f64 {
        self.cuts.iter().map(|c| c.overexposed_mm).sum()
    }

    /// Time the beam passed with the stage at rest (dwells), s.
    pub fn stationary_exposure_s(&self) -> f64 {
        self.cuts.iter().map(|c| c.stationary_exposure_s).sum()
    }
}

/// Exposure of one chain of the drawing (`--chains`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ChainExposure {
    /// The chain's id in the drawing.
    pub id: u64,
    /// The chain's length, mm.
    pub drawing_length_mm: f64,
    /// Cuts matched to this chain.
    pub cuts: u64,
    /// Their beam-on length, mm.
    pub cut_length_mm: f64,
    /// Of that, exposed, mm.
    pub exposed_mm: f64,
    /// Beam-off path their shutter windows exposed, mm.
    pub overexposed_mm: f64,
}

impl ChainExposure {
    /// Drawing length the beam did not cover (never negative).
    pub fn unexposed_mm(&self) -> f64 {
        (self.drawing_length_mm - self.exposed_mm).max(0.0)
    }
}

fn segment_length(s: &Segment) -> f64 {
    s.checked().map_or(0.0, |s| s.length())
}

/// Match each cut to the drawing chain most of its probe points lie on
/// (within `tol` mm in XY), and total the exposure per chain. Chains no cut
/// matched are wholly unexposed. Returns the chain index per cut and the
/// per-chain figures in the drawing's order.
pub fn match_chains(cuts: &[Cut], chains: &[Chain], tol: f64) -> (Vec<Option<usize>>, Vec<ChainExposure>) {
    let mut out: Vec<ChainExposure> = chains
        .iter()
        .map(|c| ChainExposure {
            id: c.id,
            drawing_length_mm: c.segments.iter().map(segment_length).sum(),
            ..Default::default()
        })
        .collect();
    let mut which = Vec::with_capacity(cuts.len());
    let mut votes = vec![0u32; chains.len()];
    for cut in cuts {
        votes.iter_mut().for_each(|v| *v = 0);
        for p in &cut.probes {
            let mut best = (f64::INFINITY, usize::MAX);
            for (i, c) in chains.iter().enumerate() {
                for s in &c.segments {
                    let d = s.checked().map_or(f64::INFINITY, |s| s.distance_xy(p));
                    if d < best.0 {
                        best = (d, i);
                    }
                }
            }
            if best.0 <= tol {
                votes[best.1] += 1;
            }
        }
        // Most votes wins; the first chain on a tie, so output is stable.
        let m = votes
            .iter()
            .enumerate()
            .filter(|(_, v)| **v > 0)
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
            .map(|(i, _)| i);
        if let Some(i) = m {
            let e = &mut out[i];
            e.cuts += 1;
            e.cut_length_mm += cut.length_mm;
            e.exposed_mm += cut.exposed_mm;
            e.overexposed_mm += cut.overexposed_mm;
        }
        which.push(m);
    }
    (which, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::V3;
    use crate::machine::{Controller, Machine};
    use crate::sim::time::{Event, MotionBlock, MoveClass, TimeModel};

    fn machine(c: Controller) -> Machine {
        let mut m = Machine::builtin("lookahead");
        m.controller = c;
        m.accel_mm_s2 = 100.0;
        m.block_rate_hz = 0.0;
        m.ta_ms = 100.0;
        m.ts_ms = 0.0;
        m
    }

    /// Collinear moves along X: (length, feed, beam).
    fn run(m: &Machine, timing: CommandTiming, moves: &[(f64, f64, bool)]) -> BeamModel {
        let mut tm = TimeModel::new(m);
        let mut bm = BeamModel::new(&m.shutter_or_instant(), timing);
        bm.keep_probes = true;
        let mut x = 0.0;
        for (i, &(l, f, beam)) in moves.iter().enumerate() {
            let mut b = MotionBlock::straight(MoveClass::Line, V3::new(l, 0.0, 0.0), f);
            x += l;
            b.end = P3::new(x, 0.0, 0.0);
            b.beam = beam;
            b.line = Some(i as u64 + 1);
            tm.push_move(b);
        }
        tm.finish();
        while let Some(e) = tm.pop() {
            match e {
                Event::Block(tb) => bm.add_block(&tb),
                Event::Dwell { t_start_s, seconds, .. } => bm.add_dwell(t_start_s, seconds),
            }
        }
        bm.finish();
        bm
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn boundary_switching_loses_the_open_latency_and_overruns_the_close() {
        // At a steady 10 mm/s the beam comes 7.5 ms late (0.075 mm) and
        // goes 10 ms late (0.1 mm).
        let m = machine(Controller::Lookahead);
        let b = run(
            &m,
            CommandTiming::Boundary,
            &[(10.0, 10.0, false), (10.0, 10.0, true), (10.0, 10.0, false)],
        );
        assert_eq!(b.cuts.len(), 1);
        assert!(close(b.unexposed_mm(), 0.075), "{}", b.unexposed_mm());
        assert!(close(b.overexposed_mm(), 0.1), "{}", b.overexposed_mm());
        assert_eq!((b.opens, b.short_exposures), (1, 0));
        assert_eq!((b.cuts[0].first_line, b.cuts[0].last_line), (Some(2), Some(2)));
    }

    #[test]
    fn pmac_sync_switches_half_a_blend_early() {
        // M33== acts at the start of the blend, 50 ms before the nominal
        // boundary (TA 100 ms): the beam arrives 42.5 ms early (over-exposing
        // 0.1275 mm at 3 mm/s) and leaves 40 ms early (0.12 mm uncut).
        let m = machine(Controller::Pmac);
        let b = run(
            &m,
            CommandTiming::Sync,
            &[(3.0, 3.0, false), (3.0, 3.0, true), (3.0, 3.0, false)],
        );
        assert!(close(b.overexposed_mm(), 0.1275), "{}", b.overexposed_mm());
        assert!(close(b.unexposed_mm(), 0.12), "{}", b.unexposed_mm());
    }

    #[test]
    fn pmac_immediate_switches_one_move_early() {
        // M33=1 before the beam-on move runs when the move before it starts:
        // the whole previous move is exposed (but its first 7.5 ms of ramp)
        // and the close, one move early too, leaves the cut dark.
        let m = machine(Controller::Pmac);
        let b = run(
            &m,
            CommandTiming::Immediate,
            &[(3.0, 3.0, false), (3.0, 3.0, true), (3.0, 3.0, false)],
        );
        let ramp = 0.5 * 30.0 * 0.0075 * 0.0075; // from rest at 30 mm/s²
        assert!(close(b.unexposed_mm(), 3.0), "{}", b.unexposed_mm());
        assert!(close(b.overexposed_mm(), 3.0 - ramp - 0.12), "{}", b.overexposed_mm());
    }

    #[test]
    fn runs_split_cuts_and_short_windows_are_flagged() {
        let m = machine(Controller::Lookahead);
        let b = run(
            &m,
            CommandTiming::Boundary,
            &[
                (1.0, 10.0, true),
                (1.0, 10.0, true),
                (1.0, 10.0, false),
                (0.1, 10.0, true),
                (1.0, 10.0, false),
            ],
        );
        assert_eq!(b.cuts.len(), 2);
        assert!(close(b.cuts[0].length_mm, 2.0) && close(b.cuts[1].length_mm, 0.1));
        // The second window is 10 ms, under the 15 ms minimum exposure.
        assert_eq!(b.short_exposures, 1);
        assert_eq!(b.short_exposure_lines, [4]);
        let exposed: f64 = b.cuts.iter().map(|c| c.exposed_mm + c.unexposed_mm()).sum();
        assert!(close(exposed, b.intended_mm()));
    }

    #[test]
    fn cuts_match_the_drawing_chains_they_lie_on() {
        let m = machine(Controller::Lookahead);
        // Cut 1 runs along y = 0 from x = 0 to 2, then a beam-off move, then
        // cut 2 from x = 3 to 3.1.
        let b = run(
            &m,
            CommandTiming::Boundary,
            &[
                (1.0, 10.0, true),
                (1.0, 10.0, true),
                (1.0, 10.0, false),
                (0.1, 10.0, true),
            ],
        );
        let line = |id, x0: f64, x1: f64| Chain {
            id,
            segments: vec![Segment::line(P3::new(x0, 0.0, 0.0), P3::new(x1, 0.0, 0.0))],
            ..Default::default()
        };
        let chains = [line(7, 0.0, 2.0), line(8, 2.95, 3.2), line(9, 10.0, 11.0)];
        let (which, per) = match_chains(&b.cuts, &chains, 0.01);
        assert_eq!(which, [Some(0), Some(1)]);
        assert_eq!(per.iter().map(|c| c.cuts).collect::<Vec<_>>(), [1, 1, 0]);
        assert!(close(per[0].unexposed_mm(), 2.0 - b.cuts[0].exposed_mm));
        // The drawing's chain 8 is 0.25 mm, of which at most 0.1 was cut.
        assert!(per[1].unexposed_mm() >= 0.15);
        assert!(close(per[2].unexposed_mm(), 1.0));
    }
}
