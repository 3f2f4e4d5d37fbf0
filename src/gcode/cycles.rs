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
            None => return Err(err(format!("{name} needs an R word (retract level) on its first block"))),
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
            Some(l) => return Err(err(format!("{name} L must be a whole number of repeats of at least 1, got {l}"))),
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
            None if matches!(code, 730 | 830) && !same => return Err(err(format!("{name} needs a Q word (peck depth)"))),
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
        let feed = self.feed_mm_per_min;
        let mut e = Emit {
            out,
            axes,
            lineno,
            feed,
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
        for _ in 0..repeats {
            aa += inc[0];
            bb += inc[1];
            let now = pos[axes.2];
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
        self.out
            .push_back(Record::Move(Motion::from_block(kind, to, feed, beam, self.lineno)));
        *pos = to;
    }

    fn dwell(&mut self, seconds: f64) {
        self.out.push_back(Record::Dwell {
            seconds,
            block: Some(self.lineno),
        });
    }
}
