//! Physics audit of a laser toolpath: what the stage and the shutter will
//! actually do, checked against the machine's limits. Tests use it on every
//! generated drawing; it reads only the toolpath model, so it checks the
//! output, not the planner's intentions.
//!
//! The controller model is the machine's: on a Turbo PMAC a block lasts at
//! least its TA (whole ms, or 2·TS), the blend into a block takes that
//! block's TA and starts TA/2 before the boundary, and a shutter command
//! (`M33==`) on a block acts where that blend starts; a look-ahead
//! controller acts at the boundary.

use super::setup::LaserSetup;
use crate::geometry::P3;
use crate::geometry::Segment;
use crate::machine::Controller;
use crate::model::toolpath::{Motion, MotionKind, Record, Role};
use std::collections::BTreeMap;

/// What the audit found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Audit {
    /// Feed moves.
    pub feed_moves: usize,
    /// Feed moves whose feed is not V.
    pub off_feed_moves: usize,
    /// PMAC: feed moves shorter in time than their acceleration time, which
    /// the controller stretches to it (so they run slower than V).
    /// Look-ahead: feed moves shorter than 1 ms at V, which a control that
    /// computes about 1,000 blocks a second runs slower than V.
    pub stretched_moves: usize,
    /// Joints between feed moves (without a stop between) whose direction
    /// jumps by more than the tangency tolerance: an infinite acceleration
    /// demand at V.
    pub corners_at_speed: usize,
    /// Largest centripetal demand V²/r (mm/s²) on moves that are not cuts
    /// (loops, leads); cuts follow the drawing and are reported separately.
    /// In G-code, which carries no roles, the beam-on moves are the cuts.
    pub max_accel_off_cut: f64,
    /// Largest demand on cut moves (the drawing's own tightest arc).
    pub max_accel_cut: f64,
    /// Beam-on rapids (never acceptable).
    pub beam_on_rapids: usize,
    /// Largest distance (mm) between an edge of where the shutter is fully
    /// open and the matching edge of a run of cut moves; infinite when the
    /// two do not pair up.
    pub exposure_error: f64,
    /// Least path length (mm) from a stop to where an open command acts:
    /// it must not act before the stage has reached V.
    pub min_run_before_open: f64,
    /// Least path length (mm) from where the shutter is fully closed to
    /// where the stage starts to slow down for a stop (negative: the beam
    /// still passes while the speed drops).
    pub min_run_after_close: f64,
    /// Cut length (mm) per chain id.
    pub cut_length: BTreeMap<u64, f64>,
    /// Number of cut runs per chain id.
    pub cut_runs: BTreeMap<u64, usize>,
}

impl Audit {
    /// Whether the toolpath keeps every promise of the laser flow on
    /// machine `m`, with lengths compared at `precision` mm (the printing
    /// precision of the program): feed at V, no corner at speed (counted by
    /// [`audit_at`] with the same precision), no beam-on rapid, no arc
    /// tighter than V²/a, no stretched block, the stage at V
    /// from before the shutter opens until after it closes, and (when cut
    /// runs are marked: G-code carries no roles) the exposure on the cuts.
    pub fn passes(&self, m: &LaserSetup, precision: f64) -> bool {
        let r_min = m.feed * m.feed / self.max_accel_off_cut;
        let exposure_ok = !self.has_roles() || self.exposure_error <= 4.0 * precision;
        self.off_feed_moves == 0
            && self.corners_at_speed == 0
            && self.beam_on_rapids == 0
            // A radius is the distance between two printed points (the
            // centre and an end), each off by up to `precision`.
            && r_min >= m.min_radius() - 2.0 * precision
            && self.stretched_moves == 0
            && self.min_run_after_close >= -precision
            // The run from the lead-in's start to the switch joins two
            // printed points, too.
            && self.min_run_before_open >= m.accel_distance() - 2.0 * precision
            && exposure_ok
    }

    /// Whether the input marked its cut runs (toolpath JSON does, G-code
    /// does not).
    pub fn has_roles(&self) -> bool {
        self.cut_runs.values().sum::<usize>() > 0
    }

    /// The `microcam.pathgen-audit/1` report: one JSON object, every figure
    /// with its unit in its name, `null` where a figure does not apply.
    pub fn report_json(&self, m: &LaserSetup, precision: f64) -> String {
        let num = |x: f64| {
            if x.is_finite() {
                format!("{x:.9}")
            } else {
                "null".into()
            }
        };
        let exposure = if self.has_roles() {
            self.exposure_error
        } else {
            f64::NAN
        };
        format!(
            "{{\"schema\":\"microcam.pathgen-audit/1\",\"ok\":{},\"feed_moves\":{},\"off_feed_moves\":{},\"corners_at_speed\":{},\"beam_on_rapids\":{},\"max_accel_off_cut_mm_s2\":{},\"max_accel_cut_mm_s2\":{},\"accel_limit_mm_s2\":{},\"exposure_error_mm\":{},\"stretched_moves\":{},\"min_run_before_open_mm\":{},\"min_run_after_close_mm\":{},\"controller\":\"{}\",\"cut_runs\":{}}}",
            self.passes(m, precision),
            self.feed_moves,
            self.off_feed_moves,
            self.corners_at_speed,
            self.beam_on_rapids,
            num(self.max_accel_off_cut),
            num(self.max_accel_cut),
            num(m.accel()),
            num(exposure),
            self.stretched_moves,
            num(self.min_run_before_open),
            num(self.min_run_after_close),
            m.controller.name(),
            self.cut_runs.values().sum::<usize>()
        )
    }
}

/// The TA/TS (ms) a Turbo PMAC has in force while it reads a program, and
/// what they do to a block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PmacTa {
    /// Acceleration time in force (ms).
    pub ta_ms: f64,
    /// S-curve time in force (ms).
    pub ts_ms: f64,
}

impl PmacTa {
    /// At the start of a job: the machine's ramps.
    pub fn new(m: &LaserSetup) -> PmacTa {
        PmacTa {
            ta_ms: m.program_ta_ms(),
            ts_ms: m.ts_ms,
        }
    }

    /// Take in an `accel` record; false for any other record.
    pub fn read(&mut self, r: &Record) -> bool {
        let Record::Accel { ta_ms, ts_ms, .. } = r else {
            return false;
        };
        self.ta_ms = ta_ms.unwrap_or(self.ta_ms);
        self.ts_ms = ts_ms.unwrap_or(self.ts_ms);
        true
    }

    /// The acceleration time (s): TA rounded to whole ms (at least 1), or
    /// 2·TS when that is longer.
    pub fn accel_s(&self) -> f64 {
        crate::machine::pmac::accel_time_s(self.ta_ms, self.ts_ms)
    }

    /// Whether a block `len` mm long at `feed` mm/s lasts less than the
    /// acceleration time, so that the controller stretches it.
    pub fn stretches(&self, len: f64, feed: f64) -> bool {
        crate::machine::pmac::stretches(len, feed, self.ta_ms, self.ts_ms)
    }
}

/// The path a feed move draws from `pos` (a degenerate arc as its chord);
/// `None` for a rapid.
pub fn feed_elem(pos: P3, mv: &Motion) -> Option<Segment> {
    match mv.kind {
        MotionKind::Rapid => None,
        _ => Some(mv.segment(pos)),
    }
}

/// Audit `records` (starting at `start`) against `m`, taking every
/// coordinate as exact (a toolpath from the planner).
pub fn audit(records: &[Record], m: &LaserSetup, start: P3) -> Audit {
    audit_at(records, m, start, 0.0)
}

/// How far (radians) an element's end directions may turn when its points
/// move by up to `precision` mm: a line's by the angle whose sine is twice
/// that over its length, an arc's by that over its radius (its centre and
/// ends each rounded).
fn direction_slack(e: &Segment, precision: f64) -> f64 {
    if precision <= 0.0 {
        return 0.0;
    }
    let ext = e.radius().map_or(e.length(), |r| r.min(e.length()));
    (2.0 * precision / ext).min(1.0).asin()
}

/// [`audit`] of a program printed to `precision` mm (G-code read back):
/// a joint counts as a corner only when its direction jumps by more than
/// the tangency tolerance plus what rounding the points of the two
/// elements by `precision` can turn them. A 4-decimal program of a
/// drawing with pieces of a few micrometres otherwise shows hundreds of
/// "corners" of a degree that the exact toolpath does not have.
pub fn audit_at(records: &[Record], m: &LaserSetup, start: P3, precision: f64) -> Audit {
    let mut a = Audit {
        min_run_before_open: f64::INFINITY,
        min_run_after_close: f64::INFINITY,
        ..Default::default()
    };
    let v = m.feed;
    let pmac = m.controller == Controller::Pmac;
    let cos_tol = m.tangent_cos();
    let tol_rad = m.tangent_tol_deg.to_radians();
    let mut ta = PmacTa::new(m);
    let mut pos = start;
    let mut s = 0.0; // path length since the last stop
    // The end direction of the previous feed move and its rounding slack.
    let mut prev_dir: Option<(crate::geometry::V3, f64)> = None;
    let mut blended = false; // a feed move precedes without a stop
    let mut acc_last = 0.0; // acceleration time of the last feed move (s)
    let mut beam = false;
    let mut cmd_on_at = 0.0;
    let mut closed_at: Option<f64> = None; // fully closed, global length
    let mut cut_run: Option<(f64, u64)> = None;
    let mut open: Vec<(f64, f64)> = Vec::new(); // physical fully-open, in global length
    let mut cuts: Vec<(f64, f64)> = Vec::new();
    let mut g = 0.0; // global feed length; stops add a gap so intervals never merge across them
    // A stop: the last feed move slows down over its final V·acc/2.
    let stop = |a: &mut Audit, g: f64, acc: f64, closed_at: &mut Option<f64>| {
        if let Some(c) = closed_at.take() {
            a.min_run_after_close = a.min_run_after_close.min(g - 0.5 * v * acc - c);
        }
    };
    for r in records {
        if ta.read(r) {
            continue;
        }
        let mv = match r {
            Record::Move(mv) => mv,
            _ => {
                // Dwells and other statements stop look-ahead and blending.
                if blended {
                    stop(&mut a, g, acc_last, &mut closed_at);
                }
                prev_dir = None;
                blended = false;
                continue;
            }
        };
        let Some(elem) = feed_elem(pos, mv) else {
            // A rapid.
            if mv.beam {
                a.beam_on_rapids += 1;
            }
            if blended {
                stop(&mut a, g, acc_last, &mut closed_at);
            }
            pos = mv.to;
            prev_dir = None;
            blended = false;
            s = 0.0;
            g += 1e6;
            continue;
        };
        a.feed_moves += 1;
        if mv.feed.is_none_or(|f| (f - v).abs() > 1e-9 * v) {
            a.off_feed_moves += 1;
        }
        // A move of no length has no direction: the joint is between the
        // moves on either side of it.
        let len = elem.length();
        let slack = direction_slack(&elem, precision);
        if let Some((pd, pslack)) = prev_dir.filter(|_| len > 0.0) {
            let dot = pd.dot(&elem.start_tangent());
            if dot < cos_tol && dot.clamp(-1.0, 1.0).acos() > tol_rad + pslack + slack {
                a.corners_at_speed += 1;
            }
        }
        let demand = v * v / elem.curvature_radius();
        // Without roles (G-code) a beam-on move is a cut: it follows the
        // drawing's own radii at V, as every cut does; loops and leads run
        // with the beam off.
        if mv.role == Some(Role::Cut) || (mv.role.is_none() && mv.beam) {
            a.max_accel_cut = a.max_accel_cut.max(demand);
        } else {
            a.max_accel_off_cut = a.max_accel_off_cut.max(demand);
        }
        let acc = if pmac { ta.accel_s() } else { m.ramp_time_s() };
        if runs_slow(&ta, pmac, len, v) {
            a.stretched_moves += 1;
        }
        if mv.beam != beam {
            // Where the command acts: PMAC M33== at the start of the blend
            // into this move (none from rest), else at the boundary.
            let acts = if pmac && blended { g - 0.5 * v * acc } else { g };
            if mv.beam {
                cmd_on_at = acts;
                a.min_run_before_open = a.min_run_before_open.min(s - (g - acts));
            } else {
                open.push((cmd_on_at + m.open_lead(), acts + m.close_lead()));
                closed_at = Some(acts + m.close_lead() + m.close_travel());
            }
            beam = mv.beam;
        }
        let is_cut = mv.role == Some(Role::Cut);
        match (is_cut, cut_run) {
            (true, None) => cut_run = Some((g, mv.chain.unwrap_or(0))),
            (false, Some((c0, id))) => {
                cuts.push((c0, g));
                *a.cut_runs.entry(id).or_default() += 1;
                cut_run = None;
            }
            _ => {}
        }
        if is_cut {
            *a.cut_length.entry(mv.chain.unwrap_or(0)).or_default() += len;
        }
        s += len;
        g += len;
        pos = mv.to;
        if len > 0.0 {
            prev_dir = Some((elem.end_tangent(), slack));
        }
        blended = true;
        acc_last = acc;
    }
    if blended {
        stop(&mut a, g, acc_last, &mut closed_at);
    }
    if let Some((c0, id)) = cut_run {
        cuts.push((c0, g));
        *a.cut_runs.entry(id).or_default() += 1;
    }
    if beam {
        // Never closed: the shutter stays open to the end.
        open.push((cmd_on_at + m.open_lead(), f64::INFINITY));
    }
    a.exposure_error = if open.len() != cuts.len() {
        f64::INFINITY
    } else {
        open.iter()
            .zip(&cuts)
            .map(|(o, c)| (o.0 - c.0).abs().max((o.1 - c.1).abs()))
            .fold(0.0, f64::max)
    };
    a
}

/// Whether a feed move of `len` mm at `feed` mm/s runs slower than V: on
/// a Turbo PMAC (`pmac`) when it is shorter than its TA (`ta`), which
/// the controller stretches it to; on a look-ahead control when it takes
/// less than the 1 ms the control needs to compute a block (about 1,000
/// blocks a second).
fn runs_slow(ta: &PmacTa, pmac: bool, len: f64, feed: f64) -> bool {
    if pmac {
        ta.stretches(len, feed)
    } else {
        len < feed / 1000.0 * (1.0 - 1e-9)
    }
}

/// Feed moves a Turbo PMAC would stretch, or a look-ahead control run
/// slower than V (see [`Audit::stretched_moves`])
/// and all feed moves: `records` must start where the machine's ramps are
/// in force (a job, or a chunk of whole paths, which end on them). Only
/// lengths and TAs are looked at, so this is cheap enough to run on every
/// generated chunk.
pub fn stretched_blocks(records: &[Record], m: &LaserSetup, start: P3) -> (usize, usize) {
    let mut ta = PmacTa::new(m);
    let pmac = m.controller == Controller::Pmac;
    let mut pos = start;
    let (mut stretched, mut feed_moves) = (0, 0);
    for r in records {
        if ta.read(r) {
            continue;
        }
        let Record::Move(mv) = r else { continue };
        if let Some(e) = feed_elem(pos, mv) {
            feed_moves += 1;
            if runs_slow(&ta, pmac, e.length(), m.feed) {
                stretched += 1;
            }
        }
        pos = mv.to;
    }
    (stretched, feed_moves)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::toolpath::Motion;

    fn line(to: P3, beam: bool) -> Record {
        Record::Move(Motion {
            kind: MotionKind::Line,
            to,
            feed: Some(2.0),
            beam,
            beam_switch: None,
            role: None,
            chain: None,
            block: None,
            tool: Default::default(),
        })
    }

    #[test]
    fn a_pmac_block_shorter_than_its_ta_is_stretched_and_m33_acts_at_the_blend() {
        let m = LaserSetup::default();
        let accel = |ta: f64| Record::Accel {
            ta_ms: Some(ta),
            ts_ms: Some(0.0),
            block: None,
        };
        // 0.3 mm from rest (TA100: 150 ms >= 100), then TA6 and a beam-on
        // block: its M33== acts V·3 ms = 6 µm before its start.
        let recs = vec![
            accel(100.0),
            line(P3::new(0.3, 0.0, 0.0), false),
            accel(6.0),
            line(P3::new(1.3, 0.0, 0.0), true),
            line(P3::new(1.305, 0.0, 0.0), true),
        ];
        let a = audit(&recs, &m, P3::origin());
        assert_eq!(a.stretched_moves, 1, "5 µm at TA6 lasts 2.5 ms < 6 ms");
        assert_eq!(stretched_blocks(&recs, &m, P3::origin()), (1, 3));
        assert!((a.min_run_before_open - (0.3 - 0.006)).abs() < 1e-12);
        // A look-ahead controller acts at the boundary and stretches nothing.
        let l = LaserSetup {
            controller: Controller::Lookahead,
            ..LaserSetup::default()
        };
        let a = audit(&recs, &l, P3::origin());
        assert_eq!(a.stretched_moves, 0);
        assert!((a.min_run_before_open - 0.3).abs() < 1e-12);
    }

    #[test]
    fn a_direction_jump_that_rounding_explains_is_no_corner_at_that_precision() {
        let m = LaserSetup::default();
        // Two 5 µm pieces meeting at 1.15°: 0.1 µm across the second, what
        // rounding a 4-decimal program's points by 5e-5 mm can do.
        let jitter = vec![
            line(P3::new(1.0, 0.0, 0.0), false),
            line(P3::new(1.005, 0.0, 0.0), false),
            line(P3::new(1.010, 0.0001, 0.0), false),
        ];
        assert_eq!(audit(&jitter, &m, P3::origin()).corners_at_speed, 1, "exact: a corner");
        assert_eq!(audit_at(&jitter, &m, P3::origin(), 1e-4).corners_at_speed, 0);
        // A 10° turn between millimetre lines is a corner at any precision
        // a program is printed with.
        let bend = vec![
            line(P3::new(1.0, 0.0, 0.0), false),
            line(P3::new(2.0, 10f64.to_radians().tan(), 0.0), false),
        ];
        assert_eq!(audit_at(&bend, &m, P3::origin(), 1e-3).corners_at_speed, 1);
        // A move of no length between two lines: one joint, the turn
        // between the lines, whatever the precision.
        let through_nothing = vec![
            line(P3::new(1.0, 0.0, 0.0), false),
            line(P3::new(1.0, 0.0, 0.0), false),
            line(P3::new(1.0, 1.0, 0.0), false),
        ];
        for p in [0.0, 1e-4] {
            assert_eq!(
                audit_at(&through_nothing, &m, P3::origin(), p).corners_at_speed,
                1,
                "{p}"
            );
        }
        let straight_on = vec![
            line(P3::new(1.0, 0.0, 0.0), false),
            line(P3::new(1.0, 0.0, 0.0), false),
            line(P3::new(2.0, 0.0, 0.0), false),
        ];
        assert_eq!(audit(&straight_on, &m, P3::origin()).corners_at_speed, 0);
    }

    #[test]
    fn without_roles_beam_on_moves_are_the_cuts() {
        let m = LaserSetup::default();
        // A 0.05 mm arc at 2 mm/s asks 80 mm/s²: allowed on a cut (the
        // drawing's own radius), not on a loop.
        let arc = |beam: bool| {
            Record::Move(Motion {
                kind: MotionKind::Arc(crate::model::toolpath::ArcData {
                    center: P3::new(1.0, 0.05, 0.0),
                    ccw: true,
                    plane: crate::geometry::Plane::Xy,
                    extra_turns: 0,
                }),
                to: P3::new(1.0, 0.1, 0.0),
                ..match line(P3::origin(), beam) {
                    Record::Move(mv) => mv,
                    _ => unreachable!(),
                }
            })
        };
        for beam in [true, false] {
            let recs = vec![line(P3::new(1.0, 0.0, 0.0), beam), arc(beam)];
            let a = audit(&recs, &m, P3::origin());
            let (cut, off) = if beam { (80.0, 0.0) } else { (0.0, 80.0) };
            assert!((a.max_accel_cut - cut).abs() < 1e-9, "beam {beam}: {a:?}");
            assert!((a.max_accel_off_cut - off).abs() < 1e-9, "beam {beam}: {a:?}");
        }
    }

    #[test]
    fn the_run_before_the_shutter_opens_is_read_between_two_printed_points() {
        // A program printed at 1e-4 whose lead-in (exactly the distance
        // to reach V) reads 1.2e-4 short: both its ends were rounded, so
        // it passes at that precision; 2.5e-4 short does not.
        let m = LaserSetup::default();
        let a = |short: f64| Audit {
            feed_moves: 1,
            max_accel_off_cut: m.accel(),
            min_run_before_open: m.accel_distance() - short,
            ..Default::default()
        };
        assert!(a(1.2e-4).passes(&m, 1e-4));
        assert!(!a(2.5e-4).passes(&m, 1e-4));
    }
}
