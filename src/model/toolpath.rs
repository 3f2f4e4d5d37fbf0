//! The toolpath model: an ordered list of records, each a move or a state
//! change, in absolute millimetre coordinates.
//!
//! Every G-code reader produces exactly this model and every G-code writer
//! serialises exactly this model, so toolpath -> G-code -> toolpath is
//! lossless within the output precision.

use crate::geometry::{Arc3, P3, Plane, Segment, V3};
use serde::{Deserialize, Serialize};

/// How far (mm) an arc's end may be off the circle through its start, on
/// top of [`ARC_END_REL_TOL`] of the radius, for an arc kept as a circle.
/// Programs printed with 4 decimals round by at most about 1.4e-4 mm, well
/// inside this. The readers of arcs (G-code of both dialects, toolpath JSON
/// Lines) also accept a larger miss within LinuxCNC's rule for I/J/K arcs
/// (about 0.002 inch), as the spiral a controller makes of it
/// ([`crate::gcode::arc_radii_accepted`]), so a program one tool accepts is
/// accepted by the next; a wrong centre (the usual writer bug) is far
/// outside, and the miss is named in the error.
pub const ARC_END_TOL_MM: f64 = 1e-3;
/// Relative part of the arc end tolerance, for large radii.
pub const ARC_END_REL_TOL: f64 = 1e-5;

/// The arc end tolerance (mm) for an arc of radius `r` mm.
pub fn arc_end_tolerance(r: f64) -> f64 {
    ARC_END_TOL_MM.max(ARC_END_REL_TOL * r.abs())
}

/// The largest coordinate magnitude (mm) a toolpath may carry: a kilometre
/// of travel. Beyond it no machine or output format means anything, and
/// lengths and times computed from such numbers overflow; readers refuse
/// it, naming the record.
pub const MAX_COORD_MM: f64 = 1e9;

/// Why a move is there. Previews colour by it, simulators report by it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Cutting along the drawing (beam on, tool in the material).
    Cut,
    /// Approach onto the contour before the cut.
    LeadIn,
    /// Departure from the contour after the cut.
    LeadOut,
    /// A corner loop that keeps the speed up through a sharp corner.
    Loop,
    /// Travel between cuts.
    Link,
    /// Feeding down into the material.
    Plunge,
    /// Leaving the material upwards.
    Retract,
}

impl Role {
    /// Every role, in the order reports list them.
    pub const ALL: [Role; 7] = [
        Role::Cut,
        Role::LeadIn,
        Role::LeadOut,
        Role::Loop,
        Role::Link,
        Role::Plunge,
        Role::Retract,
    ];

    /// The name used in the pipe formats ("cut", "lead_in", ...).
    pub fn name(self) -> &'static str {
        match self {
            Role::Cut => "cut",
            Role::LeadIn => "lead_in",
            Role::LeadOut => "lead_out",
            Role::Loop => "loop",
            Role::Link => "link",
            Role::Plunge => "plunge",
            Role::Retract => "retract",
        }
    }

    /// The role a pipe-format name stands for.
    pub fn from_name(s: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.name() == s)
    }
}

/// The unit of every `feed` in a toolpath, named in its header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum FeedUnit {
    /// Millimetres per second: PMAC programs (F per Isx90 = 1000 ms).
    #[default]
    MmPerS,
    /// Millimetres per minute: ISO/RS274 programs in G94 mode.
    MmPerMin,
}

impl FeedUnit {
    /// The name used in the toolpath header ("mm/s" or "mm/min").
    pub fn name(self) -> &'static str {
        match self {
            FeedUnit::MmPerS => "mm/s",
            FeedUnit::MmPerMin => "mm/min",
        }
    }

    /// The unit a header name stands for.
    pub fn from_name(s: &str) -> Option<FeedUnit> {
        match s {
            "mm/s" => Some(FeedUnit::MmPerS),
            "mm/min" => Some(FeedUnit::MmPerMin),
            _ => None,
        }
    }

    /// Factor that turns a feed in this unit into mm/s.
    pub fn to_mm_per_s(self) -> f64 {
        match self {
            FeedUnit::MmPerS => 1.0,
            FeedUnit::MmPerMin => 1.0 / 60.0,
        }
    }

    /// Convert `feed` given in `self` into `other`.
    pub fn convert(self, feed: f64, other: FeedUnit) -> f64 {
        if self == other {
            feed
        } else {
            feed * self.to_mm_per_s() / other.to_mm_per_s()
        }
    }
}

/// The header record of a toolpath stream.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Header {
    /// The unit of every feed in the stream.
    pub feed_unit: FeedUnit,
    /// Where the toolpath came from (a file name), if known.
    pub source: Option<String>,
}

/// Arc data of an arc move: the centre, the sense, the plane and whole
/// extra turns. The centre lies in the plane of the arc's start point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcData {
    /// The arc centre (absolute), at the start's normal coordinate.
    pub center: P3,
    /// Counter-clockwise about the plane normal (see [`Plane`]).
    pub ccw: bool,
    /// The plane the arc turns in (G17/G18/G19).
    pub plane: Plane,
    /// Whole turns added to the sweep (RS274 `P2` = 1 extra turn).
    pub extra_turns: u32,
}

impl ArcData {
    /// The arc this data describes when travelled from `from` to `to`
    /// ([`Arc3::new`]: `None` for a zero radius or a non-finite number).
    pub fn arc(&self, from: P3, to: P3) -> Option<Arc3> {
        Arc3::new(self.center, from, to, self.ccw, self.plane, self.extra_turns)
    }
}

/// How the command that switched the shutter before a move was written on
/// a Turbo PMAC: synchronous (`M33==1`, takes effect when that move's
/// motion starts) or immediate (`M33=1`, takes effect when look-ahead
/// calculates the line, ahead of the motion). Simulators time the shutter
/// by it; writers reproduce it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ShutterSwitch {
    /// `M33==1`: switches when the move's motion starts.
    Sync,
    /// `M33=1`: switches when look-ahead calculates the line.
    Immediate,
}

impl ShutterSwitch {
    /// The name used in the pipe formats ("sync" or "immediate").
    pub fn name(self) -> &'static str {
        match self {
            ShutterSwitch::Sync => "sync",
            ShutterSwitch::Immediate => "immediate",
        }
    }

    /// The switch a pipe-format name stands for.
    pub fn from_name(s: &str) -> Option<ShutterSwitch> {
        match s {
            "sync" => Some(ShutterSwitch::Sync),
            "immediate" => Some(ShutterSwitch::Immediate),
            _ => None,
        }
    }
}

/// What kind of motion a [`Motion`] is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionKind {
    /// Positioning at the machine's rapid speed (G0, RAPID).
    Rapid,
    /// Straight feed move (G1, LINEAR).
    Line,
    /// Circular or helical feed move (G2/G3, CIRCLE1/CIRCLE2).
    Arc(ArcData),
}

impl MotionKind {
    /// The feed motion that travels `seg`: a line, or an arc with its data.
    pub fn of_segment(seg: &Segment) -> MotionKind {
        match seg {
            Segment::Line(_) => MotionKind::Line,
            Segment::Arc(a) => MotionKind::Arc(ArcData {
                center: a.center,
                ccw: a.ccw,
                plane: a.plane,
                extra_turns: a.extra_turns,
            }),
        }
    }
}

/// One motion to an absolute end point.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    /// Rapid, line or arc (with its data).
    pub kind: MotionKind,
    /// The absolute end point (mm).
    pub to: P3,
    /// Commanded feed in the header's unit; `None` for rapids.
    pub feed: Option<f64>,
    /// Commanded beam / shutter / cutting state during the move.
    pub beam: bool,
    /// When `beam` differs from the previous move's: how that switch was
    /// commanded, if the source says (PMAC `==` or `=`); `None` otherwise.
    pub beam_switch: Option<ShutterSwitch>,
    /// Why the move is there, when generated.
    pub role: Option<Role>,
    /// Source chain id, when generated from chains.
    pub chain: Option<u64>,
    /// Source line number (1-based) when read from G-code.
    pub block: Option<u64>,
    /// What milling adds: rotary axes, tool number, tool axis.
    pub tool: ToolState,
}

/// The milling side of a move: where the rotary axes end, which tool is
/// in the spindle and which way it points. Every field is optional, so
/// toolpaths without them (laser jobs, old files) mean what they meant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ToolState {
    /// Rotary axes A, B, C at the end of the move, degrees, absolute
    /// (machine frame). `None`: the program commands no rotary axis, they
    /// stay where they are. A reader that has seen a rotary axis word sets
    /// all three on every later move.
    pub abc: Option<[f64; 3]>,
    /// The tool in the spindle (T number after M6), when known.
    pub number: Option<u32>,
    /// The tool axis as a unit vector from the tip towards the holder
    /// (5-axis); `None` means +Z. No kinematics are applied here: a
    /// 5-axis generator states it, G-code readers do not derive it.
    pub axis: Option<V3>,
}

impl ToolState {
    /// True when no field is set (a 3-axis move with no tool named).
    pub fn is_empty(&self) -> bool {
        self.abc.is_none() && self.number.is_none() && self.axis.is_none()
    }
}

impl Motion {
    /// A bare move: beam off, and no shutter switch, role, chain, source
    /// line or tool state.
    pub fn bare(kind: MotionKind, to: P3, feed: Option<f64>) -> Motion {
        Motion {
            kind,
            to,
            feed,
            beam: false,
            beam_switch: None,
            role: None,
            chain: None,
            block: None,
            tool: ToolState::default(),
        }
    }

    /// A motion read from G-code line `block`: no role or chain, which only
    /// generated toolpaths carry.
    pub fn from_block(kind: MotionKind, to: P3, feed: Option<f64>, beam: bool, block: u64) -> Motion {
        Motion {
            beam,
            block: Some(block),
            ..Motion::bare(kind, to, feed)
        }
    }
}

impl Motion {
    /// The arc this move travels when it starts at `from`; `None` for a
    /// rapid, a line, or an arc with a zero radius or a non-finite number.
    pub fn arc(&self, from: P3) -> Option<Arc3> {
        match &self.kind {
            MotionKind::Arc(a) => a.arc(from, self.to),
            _ => None,
        }
    }

    /// The exact path of this move when it starts at `from`: its arc, or the
    /// straight line to `to` for rapids, lines and degenerate arcs (zero
    /// radius: readers refuse them, so only the chord is left to travel).
    pub fn segment(&self, from: P3) -> Segment {
        match self.arc(from) {
            Some(a) => Segment::Arc(a),
            None => Segment::line(from, self.to),
        }
    }
}

/// One toolpath record after the header.
#[derive(Debug, Clone, PartialEq)]
pub enum Record {
    /// A move.
    Move(Motion),
    /// Wait in place (G4, DWELL). Stops PMAC look-ahead.
    Dwell {
        /// How long (s).
        seconds: f64,
        /// Source line number, if read from G-code.
        block: Option<u64>,
    },
    /// Spindle speed change (S word), revolutions per minute.
    Spindle {
        /// The new speed (rev/min).
        rpm: f64,
        /// Source line number, if read from G-code.
        block: Option<u64>,
    },
    /// Acceleration and S-curve times (PMAC TA, TS), milliseconds.
    Accel {
        /// Acceleration time TA (ms), when set.
        ta_ms: Option<f64>,
        /// S-curve time TS (ms), when set.
        ts_ms: Option<f64>,
        /// Source line number, if read from G-code.
        block: Option<u64>,
    },
    /// A controller variable assignment that is not the shutter or the line
    /// counter (those are modelled by `beam` and by block order).
    /// `sync` is PMAC's `==`: executed with the next move, not ahead of it.
    Var {
        /// The variable's name as written (e.g. `P100`).
        name: String,
        /// The value assigned.
        value: f64,
        /// Written with `==` (executed with the next move).
        sync: bool,
        /// Source line number, if read from G-code.
        block: Option<u64>,
    },
}

/// A number of a record that no tool may compute with or print (see
/// [`Record::check_numbers`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BadNumber {
    /// NaN or infinite.
    #[error("{what} is not a finite number ({value})")]
    NotFinite {
        /// Which number ("feed", "end point", a variable's name...).
        what: String,
        /// The value.
        value: f64,
    },
    /// A coordinate beyond [`MAX_COORD_MM`].
    #[error("{what} {axis} = {value:e} mm is beyond what a machine can mean (|value| <= {MAX_COORD_MM:e} mm)")]
    Coordinate {
        /// Which point ("end point", "arc centre").
        what: &'static str,
        /// "X", "Y" or "Z".
        axis: &'static str,
        /// The value, mm.
        value: f64,
    },
    /// A rotary axis position beyond [`MAX_COORD_MM`] degrees.
    #[error("rotary axis {axis} = {value:e} degrees is beyond what a machine can mean")]
    Rotary {
        /// "A", "B" or "C".
        axis: &'static str,
        /// The value, degrees.
        value: f64,
    },
}

impl Record {
    /// The motion, if this record is a move.
    pub fn motion(&self) -> Option<&Motion> {
        match self {
            Record::Move(m) => Some(m),
            _ => None,
        }
    }

    /// Check that every number of the record is finite and that its
    /// coordinates (end point, arc centre) lie within [`MAX_COORD_MM`];
    /// the error says which number. Readers call this on every record, so
    /// no tool computes with, or prints, an overflowed value.
    pub fn check_numbers(&self) -> Result<(), BadNumber> {
        fn num(v: f64, what: &str) -> Result<(), BadNumber> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(BadNumber::NotFinite {
                    what: what.to_string(),
                    value: v,
                })
            }
        }
        fn point(p: &P3, what: &'static str) -> Result<(), BadNumber> {
            for (v, axis) in [(p.x, "X"), (p.y, "Y"), (p.z, "Z")] {
                num(v, what)?;
                if v.abs() > MAX_COORD_MM {
                    return Err(BadNumber::Coordinate { what, axis, value: v });
                }
            }
            Ok(())
        }
        match self {
            Record::Move(m) => {
                point(&m.to, "end point")?;
                if let MotionKind::Arc(a) = &m.kind {
                    point(&a.center, "arc centre")?;
                }
                if let Some(f) = m.feed {
                    num(f, "feed")?;
                }
                if let Some(abc) = &m.tool.abc {
                    for (v, axis) in abc.iter().zip(["A", "B", "C"]) {
                        num(*v, "rotary axis")?;
                        if v.abs() > MAX_COORD_MM {
                            return Err(BadNumber::Rotary { axis, value: *v });
                        }
                    }
                }
                if let Some(a) = &m.tool.axis {
                    for v in a.iter() {
                        num(*v, "tool axis")?;
                    }
                }
                Ok(())
            }
            Record::Dwell { seconds, .. } => num(*seconds, "dwell time"),
            Record::Spindle { rpm, .. } => num(*rpm, "spindle speed"),
            Record::Accel { ta_ms, ts_ms, .. } => {
                ta_ms.map_or(Ok(()), |v| num(v, "TA"))?;
                ts_ms.map_or(Ok(()), |v| num(v, "TS"))
            }
            Record::Var { value, name, .. } => num(*value, name),
        }
    }

    /// Source line number, if any.
    pub fn block(&self) -> Option<u64> {
        match self {
            Record::Move(m) => m.block,
            Record::Dwell { block, .. }
            | Record::Spindle { block, .. }
            | Record::Accel { block, .. }
            | Record::Var { block, .. } => *block,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_move_is_its_segment() {
        let from = P3::new(1.0, 0.0, 0.0);
        let arc = ArcData {
            center: P3::origin(),
            ccw: true,
            plane: Plane::Xy,
            extra_turns: 0,
        };
        let m = Motion::from_block(MotionKind::Arc(arc), P3::new(0.0, 1.0, 0.0), Some(1.0), true, 3);
        let s = m.segment(from);
        assert!((s.length() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(MotionKind::of_segment(&s), m.kind);
        assert_eq!(m.arc(from).map(Segment::Arc), Some(s));
        // A zero-radius arc travels its chord; a line is a line.
        let degenerate = Motion {
            to: P3::new(2.0, 0.0, 0.0),
            ..m.clone()
        };
        assert_eq!(
            degenerate.segment(P3::origin()),
            Segment::line(P3::origin(), degenerate.to)
        );
        let line = Motion {
            kind: MotionKind::Line,
            ..m
        };
        assert_eq!(line.segment(from), Segment::line(from, line.to));
        assert_eq!(MotionKind::of_segment(&line.segment(from)), MotionKind::Line);
        assert!(line.arc(from).is_none());
    }
}
