//! Moves of the ISO reader: the block's motion (straight, arc, cycle,
//! spline), its target in the machine frame (G90/G91, polar words, G53,
//! rotary axes), feeds in the three feed modes, and the offsets and
//! homing blocks (G10, G28/G30, G52/G92).

use super::*;

impl IsoInterpreter {
    /// Step 22 and 23: the motion itself, then program stops.
    pub(super) fn motion_step(
        &mut self,
        b: &Block,
        before: Option<MotionMode>,
        axes_used: bool,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let rotary = [b.word(b'A'), b.word(b'B'), b.word(b'C')];
        let has_rotary = rotary.iter().any(Option::is_some);
        let has_axes = b.word(b'X').is_some()
            || b.word(b'Y').is_some()
            || b.word(b'Z').is_some()
            || b.polar.iter().any(Option::is_some)
            || has_rotary;
        let g53 = b.has_g(530);
        self.abc_step = 0.0;
        if has_axes && self.motion != Some(MotionMode::Spline(50)) {
            // Only a G5 right after a G5 may leave out I and J.
            self.spline_pq = None;
        }
        if has_rotary {
            self.rotary_target(rotary, axes_used, g53, lineno)?;
        }
        if self.feed_mode == FeedMode::InverseTime
            && !axes_used
            && has_axes
            && matches!(self.motion, Some(MotionMode::Feed | MotionMode::Cw | MotionMode::Ccw))
            && b.word(b'F').is_none()
        {
            return Err(err("F word missing with an inverse time (G93) feed move".into()));
        }
        let arc_words =
            b.word(b'I').is_some() || b.word(b'J').is_some() || b.word(b'K').is_some() || b.word(b'R').is_some();
        if !axes_used {
            let explicit_motion = b.g[..b.ng].iter().any(|c| matches!(c, 0 | 10 | 20 | 30));
            match self.motion {
                Some(MotionMode::Cycle(code)) if has_axes || b.has_g(code) => {
                    let same = before == Some(MotionMode::Cycle(code));
                    self.canned_cycle(b, code, same, lineno, out)?;
                }
                Some(MotionMode::Spline(code)) if has_axes => {
                    self.spline(b, code, lineno, out)?;
                }
                // An explicit G5.2 runs without axis words too (`G5.2 P2 L4`
                // weighs the start point, `G5.2` after G5.3 reopens).
                Some(MotionMode::Nurbs) if has_axes || b.has_g(52) => {
                    self.nurbs_g52(b, lineno)?;
                }
                Some(m @ (MotionMode::Cw | MotionMode::Ccw)) if has_axes || (explicit_motion && arc_words) => {
                    self.arc(b, m == MotionMode::Ccw, lineno, out)?;
                }
                Some(m) if has_axes => {
                    let to = self.target(b, g53, lineno)?;
                    self.straight(m == MotionMode::Rapid, to, lineno, out)?;
                }
                None if has_axes => {
                    return Err(err("axis words with no motion mode in effect (G80 or none set)".into()));
                }
                _ => {}
            }
        }
        if b.has_m(20) || b.has_m(300) {
            self.beam = false;
            self.ended = true;
            // The program end turns compensation off.
            self.comp_off(out);
        }
        Ok(())
    }

    /// A block's A, B, C words: where the rotary axes go (degrees; no
    /// offsets apply to them). Only straight and arc moves may turn them.
    pub(super) fn rotary_target(
        &mut self,
        words: [Option<f64>; 3],
        axes_used: bool,
        g53: bool,
        lineno: u64,
    ) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        if axes_used {
            return Err(err(
                "rotary axis words (A, B, C) with G10, G28, G30, G52 or G92 are not supported: no rotary offsets or homes",
            ));
        }
        if !matches!(
            self.motion,
            Some(MotionMode::Rapid | MotionMode::Feed | MotionMode::Cw | MotionMode::Ccw)
        ) {
            return Err(err(
                "rotary axis words (A, B, C) are supported on G0, G1, G2 and G3 moves only",
            ));
        }
        if self.comp.side.is_some() {
            return Err(err(
                "rotary axis words (A, B, C) with cutter radius compensation on are not supported",
            ));
        }
        let mut to = self.abc;
        for (k, w) in words.iter().enumerate() {
            if let Some(v) = *w {
                to[k] = if self.incremental && !g53 { self.abc[k] + v } else { v };
            }
        }
        self.abc_step =
            ((to[0] - self.abc[0]).powi(2) + (to[1] - self.abc[1]).powi(2) + (to[2] - self.abc[2]).powi(2)).sqrt();
        self.abc = to;
        self.abc_used = true;
        Ok(())
    }

    /// The milling state every move carries: rotary axes once the program
    /// has used one, the tool in the spindle once one is named.
    pub(super) fn tool_state(&self) -> ToolState {
        ToolState {
            abc: self.abc_used.then_some(self.abc),
            number: (self.tool_current != 0).then_some(self.tool_current),
            axis: None,
        }
    }

    /// The X and Y (machine frame, mm) that a block's polar words `@`
    /// (radius) and `^` (angle, degrees) give, from `base` (machine frame):
    /// about the origin of the coordinate system in use, absolute in G90,
    /// added to `base`'s own radius and angle in G91, as LinuxCNC does.
    pub(super) fn polar_xy(
        &self,
        b: &Block,
        base: P3,
        incremental: bool,
        lineno: u64,
    ) -> Result<(f64, f64), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        if b.word(b'X').is_some() || b.word(b'Y').is_some() {
            return Err(err("X and Y words cannot be used with polar coordinates (@ ^)"));
        }
        if self.plane != Plane::Xy {
            return Err(err("polar coordinates (@ ^) work in the XY plane (G17) only"));
        }
        let u = self.unit();
        let off = self.offset();
        let (x, y) = ((base.x - off.x) / u, (base.y - off.y) / u);
        let (r0, a0) = (x.hypot(y), y.atan2(x));
        let [r, a] = b.polar;
        let (r, a) = if incremental {
            (r0 + r.unwrap_or(0.0), a0 + a.unwrap_or(0.0).to_radians())
        } else {
            (r.unwrap_or(r0), a.map_or(a0, f64::to_radians))
        };
        Ok((r * a.cos() * u + off.x, r * a.sin() * u + off.y))
    }

    /// End point of a move in the machine frame (mm).
    pub(super) fn target(&self, b: &Block, g53: bool, lineno: u64) -> Result<P3, GcodeError> {
        let u = self.unit();
        let off = self.offset();
        let base = self.base_point();
        let mut to = base;
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.word(letter) {
                to[k] = if g53 {
                    if self.incremental {
                        return Err(GcodeError::at(lineno, "G53 cannot be used in incremental mode (G91)"));
                    }
                    v * u
                } else if self.incremental {
                    base[k] + v * u
                } else {
                    v * u + off[k]
                };
            }
        }
        if b.polar.iter().any(Option::is_some) {
            (to.x, to.y) = self.polar_xy(b, base, self.incremental, lineno)?;
        }
        Ok(to)
    }

    /// The feed of a G94/G95 move in mm/min (G95: F times the spindle
    /// speed); in G93 the F word itself (1/min), which the move's length
    /// turns into a feed ([`Self::inverse_time_feed`]).
    pub(super) fn feed_mm_per_min(&self, lineno: u64) -> Result<f64, GcodeError> {
        let f = self.feed_mm_per_min;
        if f <= 0.0 {
            return Err(GcodeError::at(
                lineno,
                "feed move with no feed rate set (F is zero or missing)",
            ));
        }
        if self.feed_mode == FeedMode::PerRevolution {
            return match self.spindle_rpm {
                Some(rpm) if rpm > 0.0 => Ok(f * rpm),
                _ => Err(GcodeError::at(
                    lineno,
                    "feed per revolution (G95) with no spindle speed: set S first",
                )),
            };
        }
        Ok(f)
    }

    /// G93: the feed (mm/min, or degrees/min for a rotary-only move) that
    /// makes a move of `length_mm` take 1/F minutes, as LinuxCNC computes
    /// it: the XYZ length, or the rotary travel when XYZ do not move.
    pub(super) fn inverse_time_feed(&self, length_mm: f64) -> f64 {
        let len = if length_mm > 1e-12 { length_mm } else { self.abc_step };
        self.feed_mm_per_min * len
    }

    pub(super) fn straight(
        &mut self,
        rapid: bool,
        to: P3,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        if self.comp.active() {
            if !rapid {
                self.feed_mm_per_min(lineno)?;
                if self.feed_mode == FeedMode::InverseTime {
                    return Err(GcodeError::at(
                        lineno,
                        "inverse time feed (G93) with cutter radius compensation on is not supported",
                    ));
                }
            }
            return self.comp_straight(rapid, to, lineno, out);
        }
        self.comp.exit = false;
        let (kind, feed) = if rapid {
            (MotionKind::Rapid, None)
        } else {
            let f = self.feed_mm_per_min(lineno)?;
            let f = if self.feed_mode == FeedMode::InverseTime {
                self.inverse_time_feed((to - self.pos).norm())
            } else {
                f
            };
            (MotionKind::Line, Some(f))
        };
        let mut m = Motion::from_block(kind, to, feed, self.beam, lineno);
        m.tool = self.tool_state();
        out.push_back(Record::Move(m));
        self.pos = to;
        Ok(())
    }

    /// G92: make the current point have the given program coordinates.
    pub(super) fn set_g92(&mut self, b: &Block, lineno: u64) -> Result<(), GcodeError> {
        let u = self.unit();
        let mut any = false;
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.word(letter) {
                any = true;
                // machine = program + g5x + g92  =>  g92 = machine - g5x - v
                self.g92[k] = self.pos[k] - self.g5x[self.cs][k] - v * u;
            }
        }
        if !any {
            return Err(GcodeError::at(lineno, "G92 needs at least one axis word"));
        }
        Ok(())
    }

    /// G10 L2 / L20: set a G5x origin.
    pub(super) fn set_coordinate_data(&mut self, b: &Block, lineno: u64) -> Result<(), GcodeError> {
        let err = |m: &str| GcodeError::at(lineno, m.to_string());
        let l = b.word(b'L').ok_or_else(|| err("G10 needs an L word"))?;
        let p = b.word(b'P').ok_or_else(|| err("G10 needs a P word"))?;
        if l != 2.0 && l != 20.0 {
            return Err(err("only G10 L2 and G10 L20 (coordinate system origins) are supported"));
        }
        // Range first: P is user data, and P0.5 or P-1 must not reach the
        // index arithmetic (found by fuzzing).
        if p.fract() != 0.0 || !(0.0..=9.0).contains(&p) {
            return Err(err("G10 P must be a whole number 0 to 9"));
        }
        let idx = if p == 0.0 { self.cs } else { p as usize - 1 };
        let u = self.unit();
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.word(letter) {
                self.g5x[idx][k] = if l == 2.0 {
                    v * u
                } else {
                    // L20: the current point gets coordinate v in that system.
                    self.pos[k] - self.g92[k] - v * u
                };
            }
        }
        Ok(())
    }

    pub(super) fn home_position(&self, base: usize) -> P3 {
        let u = self.unit();
        let g = |k: usize| self.params.get(&ParamRef::Num(base + k)).unwrap_or(0.0) * u;
        P3::new(g(0), g(1), g(2))
    }

    /// G28/G30: rapid to the optional intermediate point, then to home on
    /// the axes named (all axes when none are).
    pub(super) fn go_home(
        &mut self,
        b: &Block,
        home: P3,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let named = [b'X', b'Y', b'Z'].map(|l| b.word(l).is_some());
        let end = if named.iter().any(|&n| n) {
            let mid = self.target(b, false, lineno)?;
            self.straight(true, mid, lineno, out)?;
            let mut end = mid;
            for k in 0..3 {
                if named[k] {
                    end[k] = home[k];
                }
            }
            end
        } else {
            if self.abc_used {
                // LinuxCNC homes the rotary axes too (#5164-#5166, #5184-#5186).
                let base = if b.has_g(280) { 5164 } else { 5184 };
                let old = self.abc;
                for k in 0..3 {
                    self.abc[k] = self.params.get(&ParamRef::Num(base + k)).unwrap_or(0.0);
                }
                self.abc_step = ((0..3).map(|k| (self.abc[k] - old[k]).powi(2)).sum::<f64>()).sqrt();
            }
            home
        };
        self.straight(true, end, lineno, out)
    }
}
