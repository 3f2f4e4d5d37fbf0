//! The emulator's program execution: a discrete-event simulation of
//! look-ahead calculation and motion in simulated time.

use super::{DEFAULT_FEED, Emulator, LOOKAHEAD, Pointer, RAPID_MM_S, Run, Seg, SegKind, Source, err};
use crate::gcode::pmac::PmacInterpreter;
use crate::gcode::{LineInterpreter, ReadOptions};
use crate::model::toolpath::{MotionKind, Record};
use std::collections::VecDeque;

impl Emulator {
    /// Execute everything due by the current simulated time, as a
    /// discrete-event simulation: calculation (look-ahead) and motion.
    ///
    /// Calculation runs while fewer than [`LOOKAHEAD`] calculated segments
    /// wait to start and no calculated DWELL waits (a dwell stops
    /// look-ahead); plain variable assignments act when their line is
    /// calculated, synchronous ones (`M..==`) are queued on the next
    /// calculated segment and act when it starts. Motion runs segments in
    /// order, each for its duration.
    pub fn advance(&mut self) {
        let now = self.now();
        // Each pass handles one record, line or motion event: bounded by
        // the work queued, but guard anyway against a runaway.
        for _ in 0..10_000_000u32 {
            let Some(run) = self.run.as_ref() else { return };
            let unstarted = run.segs.iter().filter(|s| s.start.is_none()).count();
            let dwell_wait = run
                .segs
                .iter()
                .any(|s| s.start.is_none() && matches!(s.kind, SegKind::Dwell { .. }));
            // When the next calculation input is available.
            let t_in: Option<f64> = if run.quit || run.eof || unstarted >= LOOKAHEAD || dwell_wait {
                None
            } else if !run.pending.is_empty() {
                Some(self.t_evt)
            } else {
                match &run.source {
                    Source::Prog { .. } => Some(self.t_evt),
                    Source::Rot => self
                        .rotary
                        .as_ref()
                        .and_then(|r| r.lines.front())
                        .map(|q| q.arrival.max(self.t_evt)),
                }
            };
            // When the next motion event happens.
            let t_m: Option<f64> = run.segs.front().map(|s| match s.start {
                Some(_) => self.t_free,
                None => self.t_free.max(s.ready),
            });
            let calc_first = match (t_in, t_m) {
                (Some(a), Some(b)) => a <= b,
                (Some(_), None) => true,
                _ => false,
            };
            if calc_first && t_in.is_some_and(|t| t <= now) {
                self.t_evt = t_in.unwrap_or(self.t_evt);
                if !self.calculate() {
                    return;
                }
                continue;
            }
            if let Some(t) = t_m.filter(|t| *t <= now) {
                self.t_evt = self.t_evt.max(t);
                self.motion_event();
                continue;
            }
            // Nothing due: a program with no more lines and no motion ends.
            let run = self.run.as_ref().expect("checked above");
            if run.segs.is_empty() && (run.eof || run.quit) && run.pending.is_empty() | run.quit {
                self.t_evt = self.t_evt.max(self.t_free);
                self.finish_run("done");
            }
            return;
        }
    }

    /// Calculate one record or fetch one line. `false`: the run ended.
    fn calculate(&mut self) -> bool {
        let t = self.t_evt;
        let Some(run) = self.run.as_mut() else { return false };
        if let Some(rec) = run.pending.pop_front() {
            match rec {
                Record::Move(m) => {
                    let from = run.calc_pos;
                    let (len, kind) = match m.kind {
                        MotionKind::Rapid => ((m.to - from).norm(), "rapid"),
                        MotionKind::Line => ((m.to - from).norm(), "line"),
                        MotionKind::Arc(a) => (a.arc(from, m.to).map_or(0.0, |a| a.length()), "arc"),
                    };
                    let speed = match m.kind {
                        MotionKind::Rapid => RAPID_MM_S,
                        _ => m.feed.filter(|f| *f > 0.0 && f.is_finite()).unwrap_or(DEFAULT_FEED),
                    };
                    let dur = (len / speed).max(self.ta_ms / 1000.0);
                    run.calc_pos = m.to;
                    let sync = std::mem::take(&mut run.sync_pending);
                    run.segs.push_back(Seg {
                        kind: SegKind::Move {
                            from,
                            to: m.to,
                            kind: m.kind,
                            name: kind,
                            feed: m.feed,
                            dur,
                        },
                        sync,
                        start: None,
                        ready: t,
                    });
                }
                Record::Dwell { seconds, .. } => {
                    let s = if seconds.is_finite() { seconds.max(0.0) } else { 0.0 };
                    let sync = std::mem::take(&mut run.sync_pending);
                    run.segs.push_back(Seg {
                        kind: SegKind::Dwell { s },
                        sync,
                        start: None,
                        ready: t,
                    });
                }
                Record::Accel { ta_ms, .. } => {
                    if let Some(ta) = ta_ms.filter(|v| v.is_finite() && *v >= 0.0) {
                        self.ta_ms = ta;
                    }
                }
                Record::Var { name, value, sync, .. } => {
                    let b = name.as_bytes();
                    if let (Some(&l), Ok(n)) = (b.first(), name.get(1..).unwrap_or("").parse::<usize>()) {
                        if sync {
                            run.sync_pending.push((l, n, value));
                        } else {
                            // A plain assignment acts when calculated.
                            self.set_var(l, n, value, t);
                        }
                    }
                }
                Record::Spindle { .. } => {}
            }
            return true;
        }
        let text = match &mut run.source {
            Source::Prog { n, next } => match self.programs.get(n).and_then(|p| p.lines.get(*next)) {
                Some(l) => {
                    *next += 1;
                    l.clone()
                }
                None => {
                    run.eof = true;
                    return true;
                }
            },
            Source::Rot => {
                let Some(q) = self.rotary.as_mut().and_then(|r| r.lines.pop_front()) else {
                    return true;
                };
                if let Some(r) = self.rotary.as_mut() {
                    r.used -= q.words;
                }
                q.text
            }
        };
        let Some(run) = self.run.as_mut() else { return false };
        run.lineno += 1;
        let lineno = run.lineno;
        if let Err(e) = run.interp.line(text.as_bytes(), lineno, &mut run.pending) {
            let id = run.id;
            self.event(serde_json::json!({"ev": "error", "t": t, "run": id, "msg": e.to_string()}));
            self.stop_run(t, None);
            return false;
        }
        true
    }

    /// Start the first calculated segment, or end it.
    fn motion_event(&mut self) {
        let Some(run) = self.run.as_mut() else { return };
        let Some(seg) = run.segs.front_mut() else { return };
        let id = run.id;
        if seg.start.is_some() {
            // Ends now.
            if let Some(seg) = run.segs.pop_front()
                && let SegKind::Move { to, .. } = seg.kind
            {
                self.pos = to;
            }
            return;
        }
        let t = self.t_free.max(seg.ready);
        if t > self.t_free && run.moved {
            let from = self.t_free;
            self.event(serde_json::json!({"ev": "idle", "t": from, "run": id, "until": t}));
        }
        let Some(run) = self.run.as_mut() else { return };
        let Some(seg) = run.segs.front_mut() else { return };
        seg.start = Some(t);
        let sync = std::mem::take(&mut seg.sync);
        let kind = seg.kind.clone();
        run.moved |= matches!(kind, SegKind::Move { .. });
        // Queued synchronous assignments act as this segment starts (those
        // left over from a stopped program first, unless MFLUSHed).
        for (l, n, v) in std::mem::take(&mut self.sync_left).into_iter().chain(sync) {
            self.set_var(l, n, v, t);
        }
        match kind {
            SegKind::Move {
                from,
                to,
                kind,
                name,
                feed,
                dur,
            } => {
                let beam = self.shutter().is_some_and(|(l, n)| self.var(l, n) != 0.0);
                let mut ev = serde_json::json!({
                    "ev": "move", "t": t, "run": id, "kind": name,
                    "x": to.x, "y": to.y, "z": to.z, "from": [from.x, from.y, from.z],
                    "beam": beam, "feed": feed, "dur": dur,
                });
                if let MotionKind::Arc(a) = kind {
                    ev["center"] = serde_json::json!([a.center.x, a.center.y, a.center.z]);
                    ev["ccw"] = serde_json::json!(a.ccw);
                }
                self.event(ev);
                self.t_free = t + dur;
            }
            SegKind::Dwell { s } => {
                self.event(serde_json::json!({"ev": "dwell", "t": t, "run": id, "s": s}));
                self.t_free = t + s;
            }
        }
    }

    fn finish_run(&mut self, how: &str) {
        let t = self.t_evt.max(self.t_free);
        self.stop_run(t, Some(how));
    }

    /// End the run at time `t`: motion stops where it is, calculated
    /// segments are dropped, their synchronous assignments stay queued.
    pub(super) fn stop_run(&mut self, t: f64, how: Option<&str>) {
        let p = self.position_at(t);
        if let Some(r) = self.run.take() {
            if let Some(how) = how {
                self.event(serde_json::json!({"ev": how, "t": t, "run": r.id, "x": p.x, "y": p.y, "z": p.z}));
            }
            for s in r.segs.into_iter().filter(|s| s.start.is_none()) {
                self.sync_left.extend(s.sync);
            }
            self.sync_left.extend(r.sync_pending);
        }
        self.pos = p;
        self.t_free = self.t_free.min(t);
        self.t_evt = t;
    }

    pub(super) fn start_run(&mut self, p: Pointer) -> Result<(), u16> {
        let source = match p {
            Pointer::Prog(n) => {
                if !self.programs.contains_key(&n) {
                    return Err(err::BAD_POINTER);
                }
                Source::Prog { n, next: 0 }
            }
            Pointer::Rot => {
                if self.rotary.is_none() {
                    return Err(err::BAD_POINTER);
                }
                Source::Rot
            }
        };
        let opts = ReadOptions {
            dialect: Some(crate::gcode::Dialect::Pmac),
            // The interpreter folds its shutter and counter variables into
            // the moves; here every assignment must reach the variables
            // (P400 advances, M33 toggles, `==` waits for the next move),
            // so give it variables no program uses.
            shutter_var: "Q8190".into(),
            line_counter_var: "Q8191".into(),
            start: self.pos,
            tool_table: None,
            subroutine_path: Vec::new(),
            ..ReadOptions::default()
        };
        self.runs += 1;
        let id = self.runs;
        let now = self.now();
        self.t_free = self.t_free.max(now);
        self.t_evt = self.t_evt.max(now);
        let prog = match p {
            Pointer::Prog(n) => serde_json::json!(n),
            Pointer::Rot => serde_json::json!("rot"),
        };
        let t = self.t_free;
        self.event(serde_json::json!({"ev": "run", "t": t, "run": id, "prog": prog}));
        self.run = Some(Run {
            id,
            source,
            interp: PmacInterpreter::program_body(&opts),
            pending: VecDeque::new(),
            lineno: 0,
            moved: false,
            quit: false,
            eof: false,
            segs: VecDeque::new(),
            calc_pos: self.pos,
            sync_pending: Vec::new(),
        });
        Ok(())
    }

    pub(super) fn abort(&mut self) {
        let now = self.now();
        if self.run.is_some() {
            // Motion stops where it is (deceleration within TA ignored);
            // look-ahead is dropped. Queued `==` assignments stay queued
            // until MFLUSH.
            self.stop_run(now, Some("abort"));
        }
    }
}
