//! Canned cycles G73, G74, G81-G87 and G89 of the ISO reader, expanded
//! into the rapid and feed moves LinuxCNC's interpreter makes of them.
//!
//! Every cycle works in the selected plane: it positions in the plane
//! (X/Y in G17, Z/X in G18, Y/Z in G19), then drills along the plane
//! normal (Z, Y or X) from the retract level R to the bottom given by that
//! axis' word. The rules follow LinuxCNC 2.9's `rs274` (checked move by
//! move with `scripts/rs274-diff`):
//!
//! - The first cycle block after another motion mode needs R and the
//!   bottom; later blocks of the same cycle reuse them (and P, Q).
//! - The level the tool came from (the "initial level") is remembered from
//!   the first cycle block until a non-cycle motion mode; G98 retracts to
//!   it (or to R when R is higher), G99 to R. Without either, `rs274`
//!   retracts to R, and so do we.
//! - If the tool starts below R, it first rises to R where it is.
//! - In G91, X and Y (in-plane words) are increments applied before every
//!   repeat, R is relative to the initial level and the bottom to R.
//! - L repeats the cycle (a whole number of at least 1).
//! - G73 and G83 peck by Q, backing off 0.254 mm (0.010 inch) before the
//!   next peck; G83 rises to R between pecks.
//!
//! G88 (a stop for a manual retract) is refused: the tool stays at the
//! bottom while the interpreter believes it retracted.

use super::{GcodeError, IsoInterpreter};
use crate::geometry::P3;
use crate::model::toolpath::{Motion, MotionKind, Record};
use std::collections::VecDeque;

/// How far G73/G83 back off above the last peck before feeding again, mm
/// (LinuxCNC's 0.010 inch, which it uses as 0.254 mm in metric programs).
const PECK_CLEARANCE_MM: f64 = 0.254;

/// What a cycle block remembers for the next block of the same cycle.
#[derive(Debug, Clone, Default)]
pub(super) struct CycleState {
    /// G98 (false) or G99 (true, also `rs274`'s starting state).
    pub r_plane_retract: bool,
    /// Initial level along the plane normal, machine frame mm, from the
    /// first block of a run of cycle blocks.
    pub initial_level: Option<f64>,
    /// R, bottom, P, Q, and G87's I, J, K as last given (program units).
    r: f64,
    bottom: f64,
    p: f64,
    q: f64,
    ijk: [f64; 3],
}

impl CycleState {
    pub(super) fn new() -> Self {
        CycleState {
            r_plane_retract: true,
            ..Default::default()
        }
    }
}

/// True for the G codes (times ten) that are canned cycles.
pub(super) fn is_cycle(code: u16) -> bool {
    matches!(code, 730 | 740 | 810..=890)
}

/// One move of a cycle: rapid or feed, to a point given by its
/// (first, second, normal) coordinates in the plane's axis order.
struct Emit<'a> {
    out: &'a mut VecDeque<Record>,
    axes: (usize, usize, usize),
    lineno: u64,
    feed: f64,
    tool: crate::model::toolpath::ToolState,
}

impl IsoInterpreter {
    /// Run one canned-cycle block. `same` is true when the cycle in effect
    /// before this block was this one (then R, the bottom, P and Q may be
    /// left out).
    pub(super) fn canned_cycle(
        &mut self,
        b: &super::Block,
        code: u16,
        same: bool,
        lineno: u64,
        out: &mut VecDeque<Record>,
    ) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let name = super::fmt_code('G', code);
        if code == 880 {
            return Err(err(
                "G88 is not supported: it stops for a manual retract, and the tool's position after it is the operator's"
                    .into(),
            ));
        }
        if self.comp.side.is_some() {
            return Err(err(format!(
                "{name}: canned cycles cannot be used with cutter radius compensation on"
            )));
        }
        if self.feed_mode == super::FeedMode::InverseTime {
            return Err(err(format!(
                "{name}: canned cycles cannot be used in inverse time feed mode (G93)"
            )));
        }
        if self.feed_mm_per_min <= 0.0 {
            return Err(err(format!("{name} with no feed rate set (F is zero or missing)")));
        }
        let axes = self.plane.axes();
        let letters = [b'X', b'Y', b'Z'];
        let (la, lb, lc) = (letters[axes.0], letters[axes.1], letters[axes.2]);
        let u = self.unit();
        let off = self.offset();
        let r_word = match b.word(b'R') {
            Some(r) => r,
            None if same => self.cycle.r,
            None => {
                return Err(err(format!(
                    "{name} needs an R word (retract level) on its first block"
                )));
            }
        };
        let bottom_word = match b.word(lc) {
            Some(z) => z,
            None if same => self.cycle.bottom,
            None => {
                return Err(err(format!(
                    "{name} needs a {} word (bottom of the hole) on its first block in plane {}",
                    lc as char,
                    self.plane.name().to_uppercase()
                )));
            }
        };
        let repeats = match b.word(b'L') {
            None => 1,
            Some(l) if l.fract() == 0.0 && (1.0..=1e6).contains(&l) => l as u32,
            Some(l) => {
                return Err(err(format!(
                    "{name} L must be a whole number of repeats of at least 1, got {l}"
                )));
            }
        };
        let needs_p = matches!(code, 820 | 860 | 890);
        let p = match b.word(b'P') {
            Some(p) => p,
            None if needs_p && !same => return Err(err(format!("{name} needs a P word (dwell seconds)"))),
            None => self.cycle.p,
        };
        if p < 0.0 {
            return Err(err(format!("negative dwell time P{p}")));
        }
        let q = match b.word(b'Q') {
            Some(q) => q,
            None if matches!(code, 730 | 830) && !same => {
                return Err(err(format!("{name} needs a Q word (peck depth)")));
            }
            None => self.cycle.q,
        };
        let mut ijk = self.cycle.ijk;
        if code == 870 {
            for (k, l) in [b'I', b'J', b'K'].into_iter().enumerate() {
                match b.word(l) {
                    Some(v) => ijk[k] = v,
                    None if !same => return Err(err(format!("G87 needs an {} word", l as char))),
                    None => {}
                }
            }
        }
        if matches!(code, 860 | 870) && !self.beam {
            return Err(err(format!("{name} needs the spindle turning (M3 or M4)")));
        }
        let current = self.pos;
        let old_level = *self.cycle.initial_level.get_or_insert(current[axes.2]);
        let (mut aa, mut bb, inc, r, bottom);
        if self.incremental {
            inc = [b.word(la).unwrap_or(0.0) * u, b.word(lb).unwrap_or(0.0) * u];
            aa = current[axes.0];
            bb = current[axes.1];
            r = r_word * u + old_level;
            bottom = r + bottom_word * u;
        } else {
            inc = [0.0, 0.0];
            aa = b.word(la).map_or(current[axes.0], |v| v * u + off[axes.0]);
            bb = b.word(lb).map_or(current[axes.1], |v| v * u + off[axes.1]);
            if b.polar.iter().any(Option::is_some) {
                (aa, bb) = self.polar_xy(b, current, false, lineno)?;
            }
            r = r_word * u + off[axes.2];
            bottom = bottom_word * u + off[axes.2];
        }
        if r < bottom {
            return Err(err(format!(
                "{name}: the retract level R is below the bottom of the hole ({} word)",
                lc as char
            )));
        }
        let q_mm = q * u;
        if matches!(code, 730 | 830) && q_mm <= 0.0 {
            return Err(err(format!("{name} needs a positive Q (peck depth), got Q{q}")));
        }
        let feed = self.feed_mm_per_min(lineno)?;
        let mut e = Emit {
            out,
            axes,
            lineno,
            feed,
            tool: self.tool_state(),
        };
        let mut pos = current;
        let mut level = old_level;
        if level < r {
            // Below R: rise to R where the tool is.
            pos[axes.2] = r;
            e.go(&mut pos, None, None, r, true, self.beam);
            level = r;
        }
        let clear = if self.cycle.r_plane_retract { r } else { level };
        let beam = self.beam;
        let polar_steps = self.incremental && b.polar.iter().any(Option::is_some);
        if polar_steps && (b.word(la).is_some() || b.word(lb).is_some() || self.plane != crate::geometry::Plane::Xy) {
            return Err(err(format!(
                "{name}: polar coordinates (@ ^) replace X and Y, in the XY plane only"
            )));
        }
        for _ in 0..repeats {
            if polar_steps {
                // Each repeat turns by ^ and moves out by @ about the origin.
                let mut p = pos;
                (p[axes.0], p[axes.1]) = (aa, bb);
                (aa, bb) = self.polar_xy(b, p, true, lineno)?;
            }
            aa += inc[0];
            bb += inc[1];
            // Still below R (a lower R before): cross at the clearance
            // level, as rs274 does.
            let now = if pos[axes.2] < r { clear } else { pos[axes.2] };
            e.go(&mut pos, Some(aa), Some(bb), now, true, beam);
            if now != r {
                e.go(&mut pos, None, None, r, true, beam);
            }
            match code {
                810 | 820 | 860 => {
                    e.go(&mut pos, None, None, bottom, false, beam);
                    if code != 810 {
                        e.dwell(p);
                    }
                    // G86 stops the spindle for the way out.
                    e.go(&mut pos, None, None, clear, true, beam && code != 860);
                }
                730 | 830 => {
                    let mut depth = r - q_mm;
                    while depth > bottom {
                        e.go(&mut pos, None, None, depth, false, beam);
                        if code == 830 {
                            e.go(&mut pos, None, None, r, true, beam);
                        }
                        e.go(&mut pos, None, None, depth + PECK_CLEARANCE_MM, true, beam);
                        depth -= q_mm;
                    }
                    e.go(&mut pos, None, None, bottom, false, beam);
                    e.go(&mut pos, None, None, clear, true, beam);
                }
                740 | 840 | 890 => {
                    e.go(&mut pos, None, None, bottom, false, beam);
                    e.dwell(p);
                    e.go(&mut pos, None, None, clear, false, beam);
                }
                850 => {
                    e.go(&mut pos, None, None, bottom, false, beam);
                    e.go(&mut pos, None, None, r, false, beam);
                    e.go(&mut pos, None, None, clear, true, beam);
                }
                870 => {
                    // Back boring: in through the hole with the spindle
                    // stopped and offset by I/J, feed up to K and back.
                    let (i, j) = (ijk[0] * u, ijk[1] * u);
                    let k = if self.incremental {
                        bottom + ijk[2] * u
                    } else {
                        ijk[2] * u + off[axes.2]
                    };
                    e.go(&mut pos, Some(aa + i), Some(bb + j), r, true, false);
                    e.go(&mut pos, None, None, bottom, true, false);
                    e.go(&mut pos, Some(aa), Some(bb), bottom, true, false);
                    e.go(&mut pos, None, None, k, false, beam);
                    e.go(&mut pos, None, None, bottom, false, beam);
                    e.go(&mut pos, Some(aa + i), Some(bb + j), bottom, true, false);
                    e.go(&mut pos, None, None, clear, true, false);
                    e.go(&mut pos, Some(aa), Some(bb), clear, true, false);
                }
                _ => return Err(err(format!("{name} is not supported"))),
            }
        }
        self.pos = pos;
        self.comp.exit = false;
        self.cycle.r = r_word;
        self.cycle.bottom = bottom_word;
        self.cycle.p = p;
        self.cycle.q = q;
        self.cycle.ijk = ijk;
        Ok(())
    }
}

impl Emit<'_> {
    /// Move to (`a`, `b`, `n`) in plane order (`None` keeps that in-plane
    /// coordinate), rapid or at the feed.
    fn go(&mut self, pos: &mut P3, a: Option<f64>, b: Option<f64>, n: f64, rapid: bool, beam: bool) {
        let mut to = *pos;
        if let Some(a) = a {
            to[self.axes.0] = a;
        }
        if let Some(b) = b {
            to[self.axes.1] = b;
        }
        to[self.axes.2] = n;
        let (kind, feed) = if rapid {
            (MotionKind::Rapid, None)
        } else {
            (MotionKind::Line, Some(self.feed))
        };
        let mut m = Motion::from_block(kind, to, feed, beam, self.lineno);
        m.tool = self.tool;
        self.out.push_back(Record::Move(m));
        *pos = to;
    }

    fn dwell(&mut self, seconds: f64) {
        self.out.push_back(Record::Dwell {
            seconds,
            block: Some(self.lineno),
        });
    }
}

#[cfg(test)]
mod tests {
    use crate::gcode::{Dialect, ReadOptions, read_str};
    use crate::model::toolpath::{MotionKind, Record};
    use proptest::prelude::*;

    /// (rapid, x, y, z) of every move, and dwell seconds as (false, -1, s, 0).
    fn trace(text: &str) -> Vec<(bool, f64, f64, f64)> {
        let opts = ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        };
        let (_, recs) = read_str(text, &opts).unwrap_or_else(|e| panic!("{e}\n{text}"));
        recs.iter()
            .filter_map(|r| match r {
                Record::Move(m) => Some((m.kind == MotionKind::Rapid, m.to.x, m.to.y, m.to.z)),
                Record::Dwell { seconds, .. } => Some((false, -1.0, *seconds, 0.0)),
                _ => None,
            })
            .collect()
    }

    fn same(a: &[(bool, f64, f64, f64)], b: &[(bool, f64, f64, f64)]) -> bool {
        a.len() == b.len()
            && a.iter().zip(b).all(|(p, q)| {
                p.0 == q.0 && (p.1 - q.1).abs() < 1e-9 && (p.2 - q.2).abs() < 1e-9 && (p.3 - q.3).abs() < 1e-9
            })
    }

    #[test]
    fn drilling_matches_rs274_move_for_move() {
        // Expected moves printed by LinuxCNC 2.9's rs274 for these programs.
        let got = trace("G0 Z5\nG81 X1 Y1 Z-1 R2 F10\nX2\nG91 X1 L3\n");
        let want = [
            (true, 0.0, 0.0, 5.0),
            (true, 1.0, 1.0, 5.0),
            (true, 1.0, 1.0, 2.0),
            (false, 1.0, 1.0, -1.0),
            (true, 1.0, 1.0, 2.0),
            (true, 2.0, 1.0, 2.0),
            (false, 2.0, 1.0, -1.0),
            (true, 2.0, 1.0, 2.0),
            (true, 2.0, 1.0, 7.0),
            (true, 3.0, 1.0, 7.0),
            (false, 3.0, 1.0, 6.0),
            (true, 3.0, 1.0, 7.0),
            (true, 4.0, 1.0, 7.0),
            (false, 4.0, 1.0, 6.0),
            (true, 4.0, 1.0, 7.0),
            (true, 5.0, 1.0, 7.0),
            (false, 5.0, 1.0, 6.0),
            (true, 5.0, 1.0, 7.0),
        ];
        assert!(same(&got, &want), "{got:?}");
        let got = trace("G0 Z5\nG98 G83 X1 Y1 Z-2 R2 Q1.5 F10\n");
        let want = [
            (true, 0.0, 0.0, 5.0),
            (true, 1.0, 1.0, 5.0),
            (true, 1.0, 1.0, 2.0),
            (false, 1.0, 1.0, 0.5),
            (true, 1.0, 1.0, 2.0),
            (true, 1.0, 1.0, 0.754),
            (false, 1.0, 1.0, -1.0),
            (true, 1.0, 1.0, 2.0),
            (true, 1.0, 1.0, -0.746),
            (false, 1.0, 1.0, -2.0),
            (true, 1.0, 1.0, 5.0),
        ];
        assert!(same(&got, &want), "{got:?}");
        // A tool below the new R (a lower R before) crosses at the
        // clearance level (G98: the initial level) rather than rising first.
        let got = trace("G0 X0 Y0 Z5\nG81 X5 Y5 Z-2 R1 F300\nG98 X15 Y5 Z-2 R2\n");
        let want = [
            (true, 0.0, 0.0, 5.0),
            (true, 5.0, 5.0, 5.0),
            (true, 5.0, 5.0, 1.0),
            (false, 5.0, 5.0, -2.0),
            (true, 5.0, 5.0, 1.0),
            (true, 15.0, 5.0, 5.0),
            (true, 15.0, 5.0, 2.0),
            (false, 15.0, 5.0, -2.0),
            (true, 15.0, 5.0, 5.0),
        ];
        assert!(same(&got, &want), "{got:?}");
        // G18: positions in Z/X, drills along Y.
        let got = trace("G0 Z5\nG18 G81 X1 Y1 Z-1 R2 F10\n");
        let want = [
            (true, 0.0, 0.0, 5.0),
            (true, 0.0, 2.0, 5.0),
            (true, 1.0, 2.0, -1.0),
            (false, 1.0, 1.0, -1.0),
            (true, 1.0, 2.0, -1.0),
        ];
        assert!(same(&got, &want), "{got:?}");
    }

    #[test]
    fn cycle_errors_name_the_line() {
        let cases = [
            ("G0 Z5\nG81 X1 Z-1 F10\n", 2, "needs an R word"),
            ("G0 Z5\nG81 X1 R1 F10\n", 2, "needs a Z word"),
            ("G0 Z5\nG81 X1 Z3 R2 F10\n", 2, "below the bottom"),
            ("G0 Z5\nG81 X1 Z-1 R2 L0 F10\n", 2, "L must be"),
            ("G0 Z5\nG83 X1 Z-1 R2 F10\n", 2, "needs a Q"),
            ("G0 Z5\nG82 X1 Z-1 R2 F10\n", 2, "needs a P"),
            ("G0 Z5\nG86 X1 Z-1 R2 P1 F10\n", 2, "spindle turning"),
            ("G0 Z5\nG88 X1 Z-1 R2 P1 F10\n", 2, "G88 is not supported"),
            ("G0 Z5\nG81 X1 Z-1 R2 F10\nG80\nX2\n", 4, "no motion mode"),
        ];
        let opts = ReadOptions {
            dialect: Some(Dialect::Iso),
            ..Default::default()
        };
        for (text, line, needle) in cases {
            let e = read_str(text, &opts).unwrap_err();
            assert_eq!(e.line(), line, "{text:?}: {e}");
            assert!(e.to_string().contains(needle), "{text:?}: {e}");
        }
    }

    /// The cycle block written out by hand as G0/G1/G4 lines, following
    /// the cycle's definition (not the reader's code).
    #[allow(clippy::too_many_arguments)]
    fn hand_expanded(
        code: u32,
        incremental: bool,
        r_plane: bool,
        z0: f64,
        xy: (f64, f64),
        r: f64,
        z: f64,
        q: f64,
        l: u32,
    ) -> String {
        let mut s = format!("G90 G0 X0 Y0 Z{z0}\nF100\n");
        let r_abs = if incremental { z0 + r } else { r };
        let bottom = if incremental { r_abs + z } else { z };
        let mut level = z0;
        let mut zc = z0;
        if z0 < r_abs {
            s += &format!("G0 Z{r_abs}\n");
            level = r_abs;
            zc = r_abs;
        }
        let clear = if r_plane { r_abs } else { level };
        let (mut x, mut y) = (0.0, 0.0);
        for _ in 0..l {
            if incremental {
                x += xy.0;
                y += xy.1;
            } else {
                (x, y) = xy;
            }
            s += &format!("G0 X{x} Y{y}\n");
            if zc != r_abs {
                s += &format!("G0 Z{r_abs}\n");
            }
            match code {
                81 => s += &format!("G1 Z{bottom}\nG0 Z{clear}\n"),
                82 => s += &format!("G1 Z{bottom}\nG4 P0.5\nG0 Z{clear}\n"),
                85 => s += &format!("G1 Z{bottom}\nG1 Z{r_abs}\nG0 Z{clear}\n"),
                89 => s += &format!("G1 Z{bottom}\nG4 P0.5\nG1 Z{clear}\n"),
                73 | 83 => {
                    let mut d = r_abs - q;
                    while d > bottom {
                        s += &format!("G1 Z{d}\n");
                        if code == 83 {
                            s += &format!("G0 Z{r_abs}\n");
                        }
                        s += &format!("G0 Z{}\n", d + 0.254);
                        d -= q;
                    }
                    s += &format!("G1 Z{bottom}\nG0 Z{clear}\n");
                }
                _ => unreachable!(),
            }
            zc = clear;
        }
        s
    }

    proptest! {
        #[test]
        fn cycles_with_repeats_match_a_hand_expanded_program(
            code in prop_oneof![Just(81u32), Just(82), Just(73), Just(83), Just(85), Just(89)],
            incremental: bool,
            r_plane: bool,
            z0 in -5i32..10,
            xy in (-20i32..20, -20i32..20),
            r in 0i32..8,
            depth in 1i32..12,
            q in 1i32..5,
            l in 1u32..4,
        ) {
            // Whole tenths keep the printed programs exact.
            let z0 = z0 as f64 / 2.0;
            let xy = (xy.0 as f64 / 4.0, xy.1 as f64 / 4.0);
            let (r, z) = if incremental {
                (r as f64 / 2.0 - 2.0, -(depth as f64) / 2.0)
            } else {
                (r as f64 / 2.0, r as f64 / 2.0 - depth as f64 / 2.0)
            };
            let q = q as f64 / 2.0;
            let mode = if incremental { "G91" } else { "G90" };
            let retract = if r_plane { "G99" } else { "G98" };
            // Only the words the cycle uses: rs274 refuses a Q or P that
            // means nothing to it.
            let q_word = if matches!(code, 73 | 83) { format!(" Q{q}") } else { String::new() };
            let p_word = if matches!(code, 82 | 89) { " P0.5" } else { "" };
            let program = format!(
                "G90 G0 X0 Y0 Z{z0}\nF100\n{mode} {retract} G{code} X{} Y{} R{r} Z{z}{q_word}{p_word} L{l}\n",
                xy.0, xy.1
            );
            let want = trace(&hand_expanded(code, incremental, r_plane, z0, xy, r, z, q, l));
            let got = trace(&program);
            prop_assert!(same(&got, &want), "{program}\n got {got:?}\nwant {want:?}");
        }
    }
}
