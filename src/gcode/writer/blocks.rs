//! The records of a toolpath as G-code blocks: moves and arcs (both
//! dialects, PMAC full circles split), beam words, comments, dwell,
//! spindle, acceleration and variable assignments. Each checks its
//! record first and writes nothing of a record it refuses.

use super::*;

impl<W: Write> GcodeWriter<W> {
    pub(super) fn write_move(&mut self, m: &Motion) -> Result<(), RecordError> {
        let to = self.point(&m.to, "end point")?;
        self.abc_next = match &m.tool.abc {
            Some(abc) => Some([
                self.scaled(abc[0], "rotary axis A")?,
                self.scaled(abc[1], "rotary axis B")?,
                self.scaled(abc[2], "rotary axis C")?,
            ]),
            None => None,
        };
        if let (Some(t), Dialect::Iso) = (m.tool.number, self.opts.dialect)
            && self.tool != Some(t)
        {
            // A tool change: ISO `T.. M6` on its own line (PMAC has no
            // tool changer of its own; the number stays in the toolpath).
            self.text_line(&format!("T{t} M6"));
            self.tool = Some(t);
        }
        let feed = match (m.kind, m.feed) {
            (MotionKind::Rapid, _) | (_, None) => None,
            (_, Some(f)) => {
                if !(f.is_finite() && f > 0.0) {
                    return Err(RecordError::BadFeed(f));
                }
                let f = self.in_unit.convert(f, self.opts.feed_unit);
                let s = self.scaled(f, "feed")?;
                if s == 0 {
                    return Err(RecordError::FeedRoundsToZero {
                        feed: f,
                        unit: self.opts.feed_unit.name(),
                        decimals: self.decimals,
                    });
                }
                Some(s)
            }
        };
        match m.kind {
            MotionKind::Rapid => {
                self.tag_comment(m);
                self.block(Mode::Rapid, to, None, None, m.beam);
            }
            MotionKind::Line => {
                self.tag_comment(m);
                self.block(Mode::Line, to, None, feed, m.beam);
            }
            MotionKind::Arc(a) => self.write_arc(m, &a, to, feed)?,
        }
        Ok(())
    }

    pub(super) fn write_arc(
        &mut self,
        m: &Motion,
        a: &ArcData,
        to: [i64; 3],
        feed: Option<i64>,
    ) -> Result<(), RecordError> {
        let c = self.point(&a.center, "arc centre")?;
        let (ia, ib, inorm) = a.plane.axes();
        let start = self.pos;
        let (sa, sb) = (c[ia] - start[ia], c[ib] - start[ib]);
        let (ea, eb) = (c[ia] - to[ia], c[ib] - to[ib]);
        if sa == 0 && sb == 0 {
            return Err(RecordError::ZeroRadiusAtStart);
        }
        if ea == 0 && eb == 0 {
            return Err(RecordError::ZeroRadiusAtEnd);
        }
        let r0 = (sa as f64).hypot(sb as f64) / self.scale;
        let r1 = (ea as f64).hypot(eb as f64) / self.scale;
        if (r0 - r1).abs() > self.opts.arc_tolerance + 2.0 / self.scale {
            return Err(RecordError::EndOffCircle { r0, r1 });
        }
        let pmac = self.opts.dialect == Dialect::Pmac;
        if pmac && a.extra_turns > 0 && self.abc_next.is_some() && self.abc_next != self.abc {
            return Err(RecordError::TurnsWithRotary);
        }
        if pmac && a.extra_turns > MAX_PMAC_TURNS {
            return Err(RecordError::TooManyTurns(a.extra_turns));
        }
        let (wa, wb) = if self.opts.absolute_centers {
            (c[ia], c[ib])
        } else {
            (c[ia] - start[ia], c[ib] - start[ib])
        };
        let mut centre = [(ia, wa), (ib, wb)];
        centre.sort_by_key(|&(i, _)| i);
        let mode = if a.ccw { Mode::Ccw } else { Mode::Cw };
        self.tag_comment(m);
        if pmac && a.extra_turns > 0 {
            // Full circles first, each ending over the start point with its
            // share of the normal travel, then the remaining partial sweep.
            let f = |v: i64| v as f64;
            let cp = P2::new(f(c[ia]), f(c[ib]));
            let sp = P2::new(f(start[ia]), f(start[ib]));
            let ep = P2::new(f(to[ia]), f(to[ib]));
            // Scaled units: equal integers are the same printed point.
            let base = sweep_angle(&cp, &sp, &ep, a.ccw, 0, 0.5).abs();
            let n = a.extra_turns;
            let total = base + TAU * f64::from(n);
            let dn = f(to[inorm] - start[inorm]);
            let words = ArcWords {
                plane: a.plane,
                centre,
                turns: None,
            };
            for k in 1..=n {
                let mut t = start;
                t[inorm] = start[inorm] + (dn * TAU * f64::from(k) / total).round() as i64;
                self.block(mode, t, Some(words), feed, m.beam);
            }
            self.block(mode, to, Some(words), feed, m.beam);
        } else {
            let turns = if a.extra_turns > 0 && !pmac {
                Some(u64::from(a.extra_turns) + 1)
            } else {
                None
            };
            let words = ArcWords {
                plane: a.plane,
                centre,
                turns,
            };
            self.block(mode, to, Some(words), feed, m.beam);
        }
        Ok(())
    }

    /// One motion line (plus a PMAC plane line before it when the plane
    /// changes). Everything is validated by now; this only formats and
    /// updates the modal state.
    pub(super) fn block(&mut self, mode: Mode, to: [i64; 3], arc: Option<ArcWords>, feed: Option<i64>, beam: bool) {
        let d = self.opts.dialect;
        let plane_change = arc.map(|a| a.plane).filter(|p| self.plane != Some(*p));
        if let (Some(p), Dialect::Pmac) = (plane_change, d) {
            self.text_line(plane_word(d, p));
        }
        self.start_block();
        if let Some(p) = plane_change {
            if d == Dialect::Iso {
                self.push_word(plane_word(d, p));
            }
            self.plane = Some(p);
        }
        if self.beam != Some(beam) {
            self.beam_word(beam);
            self.beam = Some(beam);
        }
        if self.opts.repeat_motion || self.mode != Some(mode) {
            self.push_word(mode.word(d));
            self.mode = Some(mode);
        }
        let mut axes = [false; 3];
        for (i, w) in axes.iter_mut().enumerate() {
            *w = !self.positioned || to[i] != self.pos[i];
        }
        // Rotary words: all three the first time, then those that change.
        let mut rot = [false; 3];
        if let Some(n) = self.abc_next {
            for (i, w) in rot.iter_mut().enumerate() {
                *w = self.abc.is_none_or(|o| o[i] != n[i]);
            }
        }
        match &arc {
            Some(a) => {
                let (ia, ib, _) = a.plane.axes();
                if !axes[ia] && !axes[ib] {
                    axes[ia] = true;
                    axes[ib] = true;
                }
            }
            None => {
                if !axes.iter().any(|&w| w) && !rot.iter().any(|&w| w) {
                    axes[0] = true;
                }
            }
        }
        for i in 0..3 {
            if axes[i] {
                self.push_value(AXIS[i], to[i]);
            }
        }
        if let Some(n) = self.abc_next {
            for i in 0..3 {
                if rot[i] {
                    self.push_value(ROTARY[i], n[i]);
                }
            }
            self.abc = Some(n);
        }
        if let Some(a) = &arc {
            for (i, v) in a.centre {
                self.push_value(CENTRE[i], v);
            }
            if let Some(p) = a.turns {
                self.sep();
                self.buf.push('P');
                push_fixed(&mut self.buf, p as i64, 0, false);
            }
        }
        if let Some(f) = feed
            && self.feed != Some(f)
        {
            self.push_value("F", f);
            self.feed = Some(f);
        }
        self.blocks += 1;
        if d == Dialect::Pmac
            && let Some(var) = &self.opts.line_counter
            && !var.is_empty()
        {
            sep(&mut self.buf, self.line_start);
            self.buf.push_str(var);
            self.buf.push('=');
            push_fixed(&mut self.buf, self.blocks.min(i64::MAX as u64) as i64, 0, false);
        }
        self.end_line();
        self.pos = to;
        self.positioned = true;
    }

    pub(super) fn beam_word(&mut self, on: bool) {
        match self.opts.dialect {
            Dialect::Pmac => {
                self.sep();
                self.buf.push_str(&self.opts.shutter_var);
                let sync = match self.switch {
                    Some(sw) => sw == ShutterSwitch::Sync,
                    None => self.opts.shutter_sync,
                };
                self.buf.push_str(if sync { "==" } else { "=" });
                self.buf.push(if on { '1' } else { '0' });
            }
            Dialect::Iso => {
                let w = if on { &self.opts.beam_on } else { &self.opts.beam_off };
                if !w.is_empty() {
                    sep(&mut self.buf, self.line_start);
                    self.buf.push_str(w);
                }
            }
        }
    }

    pub(super) fn tag_comment(&mut self, m: &Motion) {
        if !self.opts.comments {
            return;
        }
        let tag = (m.chain, m.role);
        if self.tag == Some(tag) {
            return;
        }
        self.tag = Some(tag);
        self.comment_line(|b| {
            if let Some(c) = m.chain {
                b.push_str("chain ");
                push_fixed(b, c.min(i64::MAX as u64) as i64, 0, false);
            }
            if let Some(r) = m.role {
                if m.chain.is_some() {
                    b.push(' ');
                }
                b.push_str(r.name());
            }
            if m.chain.is_none() && m.role.is_none() {
                b.push_str("untagged");
            }
        });
    }

    pub(super) fn write_dwell(&mut self, seconds: f64) -> Result<(), RecordError> {
        if !non_negative(seconds) {
            return Err(RecordError::BadDwell(seconds));
        }
        match self.opts.dialect {
            Dialect::Iso => {
                let v = self.scaled(seconds, "dwell")?;
                self.start_block();
                self.push_value("G4 P", v);
            }
            Dialect::Pmac => {
                let v = self.scaled(seconds * 1000.0, "dwell")?;
                self.start_block();
                self.push_value("DWELL ", v);
            }
        }
        self.end_line();
        Ok(())
    }

    pub(super) fn write_spindle(&mut self, rpm: f64) -> Result<(), RecordError> {
        if !non_negative(rpm) {
            return Err(RecordError::BadSpindle(rpm));
        }
        let v = self.scaled(rpm, "spindle speed")?;
        match self.opts.dialect {
            Dialect::Iso => {
                self.start_block();
                self.push_value("S", v);
                self.end_line();
            }
            Dialect::Pmac => {
                let (dec, pt) = (self.decimals, self.opts.decimal_point);
                self.comment_line(|b| {
                    b.push_str("spindle S");
                    push_fixed(b, v, dec, pt);
                    b.push_str(" rpm (not commanded by the motion program)");
                });
            }
        }
        Ok(())
    }

    pub(super) fn write_accel(&mut self, ta: Option<f64>, ts: Option<f64>) -> Result<(), RecordError> {
        let mut vals: [Option<(&'static str, i64)>; 2] = [None, None];
        for (slot, (name, t)) in vals.iter_mut().zip([("TA", ta), ("TS", ts)]) {
            if let Some(t) = t {
                if !non_negative(t) {
                    return Err(RecordError::BadAccel { name, t });
                }
                *slot = Some((name, self.scaled(t, name)?));
            }
        }
        if vals.iter().all(Option::is_none) {
            return Ok(());
        }
        match self.opts.dialect {
            Dialect::Pmac => {
                self.start_block();
                for (name, v) in vals.into_iter().flatten() {
                    self.push_value(name, v);
                }
                self.end_line();
            }
            Dialect::Iso => {
                let (dec, pt) = (self.decimals, self.opts.decimal_point);
                self.comment_line(|b| {
                    let mut first = true;
                    for (name, v) in vals.into_iter().flatten() {
                        if !first {
                            b.push(' ');
                        }
                        first = false;
                        b.push_str(name);
                        b.push(' ');
                        push_fixed(b, v, dec, pt);
                        b.push_str(" ms");
                    }
                });
            }
        }
        Ok(())
    }

    pub(super) fn write_var(&mut self, name: &str, value: f64, sync: bool) -> Result<(), RecordError> {
        let v = self.scaled(value, "variable value")?;
        let plain = name.len() > 1
            && name.as_bytes()[0].is_ascii_alphabetic()
            && name.bytes().all(|c| c.is_ascii_alphanumeric() || c == b'_');
        let (dec, pt) = (self.decimals, self.opts.decimal_point);
        match self.opts.dialect {
            Dialect::Pmac => {
                if !plain {
                    return Err(RecordError::NotPmacVariable(name.to_string()));
                }
                let reserved = std::iter::once(self.opts.shutter_var.as_str())
                    .chain(self.opts.line_counter.as_deref())
                    .any(|r| r.eq_ignore_ascii_case(name));
                if reserved {
                    return Err(RecordError::DrivenVariable(name.to_string()));
                }
                // Turbo PMAC has synchronous assignment for M-variables only.
                if sync && !name.as_bytes()[0].eq_ignore_ascii_case(&b'M') {
                    return Err(RecordError::SyncNotM(name.to_string()));
                }
                self.start_block();
                self.buf.push_str(name);
                self.buf.push_str(if sync { "==" } else { "=" });
                self.push_num(v);
                self.end_line();
            }
            Dialect::Iso => {
                let param = name.strip_prefix('#').is_some_and(|rest| {
                    let b = rest.as_bytes();
                    (!b.is_empty() && b.iter().all(u8::is_ascii_digit))
                        || (b.len() > 2
                            && b[0] == b'<'
                            && b[b.len() - 1] == b'>'
                            && b[1..b.len() - 1]
                                .iter()
                                .all(|c| c.is_ascii_alphanumeric() || *c == b'_'))
                });
                if param {
                    self.start_block();
                    self.buf.push_str(name);
                    self.buf.push('=');
                    self.push_num(v);
                    self.end_line();
                } else if plain {
                    self.comment_line(|b| {
                        b.push_str(name);
                        b.push_str(if sync { "==" } else { "=" });
                        push_fixed(b, v, dec, pt);
                    });
                } else {
                    return Err(RecordError::NotVariable(name.to_string()));
                }
            }
        }
        Ok(())
    }
}
