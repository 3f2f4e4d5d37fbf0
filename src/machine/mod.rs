//! Machine profiles: what the controller, the stage, the shutter and the
//! spindle can do, read from a small JSON file (`microcam.machine/1`, see
//! testdata/machines/ and docs/machines.md) and adjusted by command-line
//! flags the same way in every tool (`--machine NAME|FILE`, then flags).
//!
//! A profile names its controller model, because the same program runs very
//! differently on a Turbo PMAC (fixed acceleration *time*, blended moves,
//! short moves stretched: [`pmac`]) than on a grbl/Klipper-style look-ahead
//! planner (fixed acceleration *rate*, junction speeds). A laser machine
//! has a `shutter` section, a mill a `spindle` section; the figures of the
//! cutter (diameter, flutes) come from the tool, not the machine.
//!
//! This module sits below the planners and the simulator: the laser
//! planner, pathgen, gsim, feedopt and pmac-send all read the same profile.
#![warn(missing_docs)]

pub mod pmac;

use serde::Deserialize;
use std::path::Path;
use thiserror::Error;

/// The `schema` a profile file names.
pub const SCHEMA: &str = "microcam.machine/1";

/// Profiles that ship with microcam, by name. The files are the single
/// source: tests and `--machine NAME` read the same text.
pub const BUILTIN: [(&str, &str); 3] = [
    ("laser-stage", include_str!("../../testdata/machines/laser-stage.json")),
    ("micro-mill", include_str!("../../testdata/machines/micro-mill.json")),
    ("lookahead", include_str!("../../testdata/machines/lookahead.json")),
];

/// Why a profile could not be loaded (each names the profile).
#[derive(Debug, Error)]
pub enum MachineError {
    /// The file could not be read.
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    /// The file is not a profile's JSON (unknown or missing fields too).
    #[error("{0}: {1}")]
    Json(String, serde_json::Error),
    /// A figure is out of range or the sections do not fit together.
    #[error("{0}: {1}")]
    Invalid(String, ProfileProblem),
}

/// What is wrong with a profile that parsed: the figure by its key in the
/// profile's JSON, and its value.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ProfileProblem {
    /// `schema` is not this version's.
    #[error("unknown schema '{0}' (expected '{SCHEMA}')")]
    UnknownSchema(String),
    /// A speed or acceleration that must be above zero.
    #[error("'{key}' must be a positive number, got {value}")]
    NotPositive {
        /// The figure's key (`rotary.` or `shutter.` in front for those sections).
        key: &'static str,
        /// Its value.
        value: f64,
    },
    /// A time, rate or deviation that must not be negative.
    #[error("'{key}' must be a number >= 0, got {value}")]
    Negative {
        /// The figure's key.
        key: &'static str,
        /// Its value.
        value: f64,
    },
    /// The spindle's speeds are not `0 < min <= max`.
    #[error("'spindle' speeds {min}..{max} rpm are not a positive range")]
    SpindleRange {
        /// `spindle.min_rpm`.
        min: f64,
        /// `spindle.max_rpm`.
        max: f64,
    },
    /// `lookahead_blocks` is 0.
    #[error("'lookahead_blocks' must be at least 1")]
    NoLookahead,
    /// An axis's limits are not `min <= max`.
    #[error("axis {axis} limits {lo}..{hi} are not a range")]
    LimitsNotRange {
        /// `X`, `Y` or `Z`.
        axis: char,
        /// The low limit, mm.
        lo: f64,
        /// The high limit, mm.
        hi: f64,
    },
    /// One of `limits_min_mm` and `limits_max_mm` without the other.
    #[error("'limits_min_mm' and 'limits_max_mm' go together")]
    LimitsUnpaired,
}

/// The controller's motion model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Controller {
    /// Turbo PMAC LINEAR/CIRCLE blending: each move lasts at least the
    /// acceleration time, velocity changes are ramps of that time centred
    /// on the move boundaries, RAPID moves start and end at rest.
    Pmac,
    /// grbl/Klipper family: constant acceleration, junction-deviation corner
    /// speeds, a bounded planner buffer, trapezoidal profiles.
    Lookahead,
}

impl Controller {
    /// The name profiles and flags use.
    pub fn name(self) -> &'static str {
        match self {
            Controller::Pmac => "pmac",
            Controller::Lookahead => "lookahead",
        }
    }
}

/// Shutter latencies, milliseconds (the laser stage's figures are those
/// Bayesteh (2013) measured: 3 ms delay and 9 ms transfer to open, 3 ms
/// delay and 14 ms transfer to close, 15 ms minimum exposure).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shutter {
    /// From the open command to the start of the opening transfer.
    pub open_delay_ms: f64,
    /// Opening transfer (blade travel).
    pub open_transfer_ms: f64,
    /// From the close command to the start of the closing transfer.
    pub close_delay_ms: f64,
    /// Closing transfer.
    pub close_transfer_ms: f64,
    /// Shortest command window that gives a reliable exposure.
    pub min_exposure_ms: f64,
}

impl Shutter {
    /// A shutter that acts the instant it is commanded: what a profile
    /// without a `shutter` section (a mill) is simulated with, so the
    /// cutting state follows the program exactly.
    pub fn instant() -> Shutter {
        Shutter {
            open_delay_ms: 0.0,
            open_transfer_ms: 0.0,
            close_delay_ms: 0.0,
            close_transfer_ms: 0.0,
            min_exposure_ms: 0.0,
        }
    }

    /// The beam is taken to pass from halfway through the opening transfer
    /// to halfway through the closing transfer: a half-open aperture passes
    /// about half the beam, so this threshold neither favours under- nor
    /// over-exposure.
    pub fn open_latency_s(&self) -> f64 {
        (self.open_delay_ms + 0.5 * self.open_transfer_ms) * 1e-3
    }

    /// Seconds from the close command to the beam half blocked: the
    /// close delay and half the transfer time.
    pub fn close_latency_s(&self) -> f64 {
        (self.close_delay_ms + 0.5 * self.close_transfer_ms) * 1e-3
    }
}

/// A machine profile. Every figure carries its unit in its name.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    /// [`SCHEMA`].
    pub schema: String,
    /// The profile's name (messages, reports).
    pub name: String,
    /// Where the figures come from (free text, for people).
    #[serde(default)]
    pub note: Option<String>,
    /// The motion model programs are timed with.
    pub controller: Controller,
    /// Axis travel, mm; absent = unchecked.
    #[serde(default)]
    pub limits_min_mm: Option<[f64; 3]>,
    #[serde(default)]
    /// Upper axis travel, mm (with `limits_min_mm`).
    pub limits_max_mm: Option<[f64; 3]>,
    /// Highest path feed the controller will run; faster F is clamped.
    pub max_feed_mm_s: f64,
    /// Rapid (RAPID / G0) speed: per axis on a PMAC, along the path on a
    /// look-ahead planner.
    pub rapid_mm_s: f64,
    /// Acceleration of rapid moves (PMAC jog acceleration, per axis).
    pub rapid_accel_mm_s2: f64,
    /// Path acceleration of the look-ahead planner.
    pub accel_mm_s2: f64,
    /// Junction deviation (grbl `$11`), mm.
    pub junction_deviation_mm: f64,
    /// Blocks the look-ahead planner sees ahead (grbl: 16).
    pub lookahead_blocks: usize,
    /// PMAC acceleration time Isx87 / TA until the program sets TA, ms.
    pub ta_ms: f64,
    /// PMAC S-curve time Isx88 / TS until the program sets TS, ms.
    pub ts_ms: f64,
    /// Blocks per second the controller can compute; 0 = no limit. A block
    /// shorter in time than 1/rate starves the planner, so it lasts 1/rate.
    pub block_rate_hz: f64,
    /// The laser's shutter; absent on a machine without one.
    #[serde(default)]
    pub shutter: Option<Shutter>,
    /// The milling spindle; absent on a machine without one.
    #[serde(default)]
    pub spindle: Option<Spindle>,
    /// The rotary axes (A, B, C); absent: their moves are timed with the
    /// linear figures read as degrees ([`Machine::rotary_or_linear`]).
    #[serde(default)]
    pub rotary: Option<Rotary>,
}

/// Speed limits of the rotary axes A, B, C, each on its own.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rotary {
    /// Highest feed speed of a rotary axis, degrees/s.
    pub max_deg_s: f64,
    /// Rapid speed of a rotary axis, degrees/s.
    pub rapid_deg_s: f64,
    /// Acceleration of a rotary axis, degrees/s².
    pub accel_deg_s2: f64,
}

/// A milling spindle's speed range (rev/min).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spindle {
    /// Slowest speed the spindle runs at.
    pub min_rpm: f64,
    /// Fastest speed.
    pub max_rpm: f64,
}

/// Command-line adjustments of a profile: each `Some` replaces the
/// profile's figure of the same name ([`Machine::apply`]).
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// `--controller`.
    pub controller: Option<Controller>,
    /// `--ta-ms`.
    pub ta_ms: Option<f64>,
    /// `--ts-ms`.
    pub ts_ms: Option<f64>,
    /// `--accel-mm-s2`.
    pub accel_mm_s2: Option<f64>,
    /// `--junction-deviation-mm`.
    pub junction_deviation_mm: Option<f64>,
    /// `--max-feed-mm-s`.
    pub max_feed_mm_s: Option<f64>,
    /// `--rapid-mm-s`.
    pub rapid_mm_s: Option<f64>,
    /// `--block-rate-hz`.
    pub block_rate_hz: Option<f64>,
    /// `--lookahead-blocks`.
    pub lookahead_blocks: Option<usize>,
    /// xmin,xmax,ymin,ymax,zmin,zmax.
    pub limits_mm: Option<[f64; 6]>,
}

impl Machine {
    /// Parse and check a profile; `name` is used in messages.
    pub fn from_json(text: &str, name: &str) -> Result<Machine, MachineError> {
        let m: Machine = serde_json::from_str(text).map_err(|e| MachineError::Json(name.into(), e))?;
        m.check().map_err(|p| MachineError::Invalid(name.into(), p))?;
        Ok(m)
    }

    /// A built-in profile by name, or a profile file.
    pub fn load(spec: &str) -> Result<Machine, MachineError> {
        if let Some((name, text)) = BUILTIN.iter().find(|(n, _)| *n == spec) {
            return Machine::from_json(text, name);
        }
        let p = Path::new(spec);
        let text = std::fs::read_to_string(p).map_err(|e| MachineError::Io(spec.into(), e))?;
        Machine::from_json(&text, spec)
    }

    /// The rotary limits, or, for a profile without a `rotary` section,
    /// the linear ones read as degrees (1 degree counts as 1 mm: the
    /// maximum feed, the rapid speed and the rapid acceleration).
    pub fn rotary_or_linear(&self) -> Rotary {
        self.rotary.unwrap_or(Rotary {
            max_deg_s: self.max_feed_mm_s,
            rapid_deg_s: self.rapid_mm_s,
            accel_deg_s2: self.rapid_accel_mm_s2,
        })
    }

    /// A built-in profile; panics only if a shipped file is broken, which
    /// the tests catch.
    pub fn builtin(name: &str) -> Machine {
        match Machine::load(name) {
            Ok(m) => m,
            Err(e) => panic!("built-in machine profile: {e}"),
        }
    }

    /// The shutter, or [`Shutter::instant`] when the profile has none.
    pub fn shutter_or_instant(&self) -> Shutter {
        self.shutter.clone().unwrap_or_else(Shutter::instant)
    }

    /// Shortest time a block can take (s): the controller's block
    /// processing rate; 0 when the rate is unlimited (0 Hz in the profile).
    pub fn block_time_s(&self) -> f64 {
        if self.block_rate_hz > 0.0 {
            1.0 / self.block_rate_hz
        } else {
            0.0
        }
    }

    /// Apply flags, then re-check.
    pub fn apply(&mut self, o: &Overrides) -> Result<(), MachineError> {
        if let Some(c) = o.controller {
            self.controller = c;
        }
        let set = |dst: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *dst = v;
            }
        };
        set(&mut self.ta_ms, o.ta_ms);
        set(&mut self.ts_ms, o.ts_ms);
        set(&mut self.accel_mm_s2, o.accel_mm_s2);
        set(&mut self.junction_deviation_mm, o.junction_deviation_mm);
        set(&mut self.max_feed_mm_s, o.max_feed_mm_s);
        set(&mut self.rapid_mm_s, o.rapid_mm_s);
        set(&mut self.block_rate_hz, o.block_rate_hz);
        if let Some(n) = o.lookahead_blocks {
            self.lookahead_blocks = n;
        }
        if let Some(l) = o.limits_mm {
            self.limits_min_mm = Some([l[0], l[2], l[4]]);
            self.limits_max_mm = Some([l[1], l[3], l[5]]);
        }
        self.check()
            .map_err(|p| MachineError::Invalid(format!("machine '{}'", self.name), p))
    }

    fn check(&self) -> Result<(), ProfileProblem> {
        if self.schema != SCHEMA {
            return Err(ProfileProblem::UnknownSchema(self.schema.clone()));
        }
        let positive = [
            ("max_feed_mm_s", self.max_feed_mm_s),
            ("rapid_mm_s", self.rapid_mm_s),
            ("rapid_accel_mm_s2", self.rapid_accel_mm_s2),
            ("accel_mm_s2", self.accel_mm_s2),
        ];
        for (k, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(ProfileProblem::NotPositive { key: k, value: v });
            }
        }
        let mut non_negative = vec![
            ("junction_deviation_mm", self.junction_deviation_mm),
            ("ta_ms", self.ta_ms),
            ("ts_ms", self.ts_ms),
            ("block_rate_hz", self.block_rate_hz),
        ];
        if let Some(r) = &self.rotary {
            for (k, v) in [
                ("rotary.max_deg_s", r.max_deg_s),
                ("rotary.rapid_deg_s", r.rapid_deg_s),
                ("rotary.accel_deg_s2", r.accel_deg_s2),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(ProfileProblem::NotPositive { key: k, value: v });
                }
            }
        }
        if let Some(sh) = &self.shutter {
            non_negative.extend([
                ("shutter.open_delay_ms", sh.open_delay_ms),
                ("shutter.open_transfer_ms", sh.open_transfer_ms),
                ("shutter.close_delay_ms", sh.close_delay_ms),
                ("shutter.close_transfer_ms", sh.close_transfer_ms),
                ("shutter.min_exposure_ms", sh.min_exposure_ms),
            ]);
        }
        if let Some(sp) = &self.spindle
            && !(sp.min_rpm.is_finite() && sp.max_rpm.is_finite() && 0.0 < sp.min_rpm && sp.min_rpm <= sp.max_rpm)
        {
            return Err(ProfileProblem::SpindleRange {
                min: sp.min_rpm,
                max: sp.max_rpm,
            });
        }
        for (k, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ProfileProblem::Negative { key: k, value: v });
            }
        }
        if self.lookahead_blocks == 0 {
            return Err(ProfileProblem::NoLookahead);
        }
        match (self.limits_min_mm, self.limits_max_mm) {
            (None, None) => {}
            (Some(lo), Some(hi)) => {
                for i in 0..3 {
                    if !(lo[i].is_finite() && hi[i].is_finite() && lo[i] <= hi[i]) {
                        return Err(ProfileProblem::LimitsNotRange {
                            axis: "XYZ".as_bytes()[i] as char,
                            lo: lo[i],
                            hi: hi[i],
                        });
                    }
                }
            }
            _ => return Err(ProfileProblem::LimitsUnpaired),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_profiles_parse_and_carry_the_seed_facts() {
        for (name, _) in BUILTIN {
            let m = Machine::builtin(name);
            assert_eq!(m.name, name);
        }
        let laser = Machine::builtin("laser-stage");
        assert_eq!(laser.controller, Controller::Pmac);
        // Bayesteh (2013): 3 ms delay + 9 ms transfer to open, 14 ms to close.
        let sh = laser.shutter.as_ref().unwrap();
        assert_eq!(sh.open_delay_ms + sh.open_transfer_ms, 12.0);
        assert_eq!(sh.close_transfer_ms, 14.0);
        assert_eq!(sh.min_exposure_ms, 15.0);
        let mill = Machine::builtin("micro-mill");
        assert!(mill.shutter.is_none());
        let sp = mill.spindle.as_ref().unwrap();
        assert_eq!((sp.min_rpm, sp.max_rpm), (10_000.0, 80_000.0));
        // 0.4 mm at 3 mm/s: about 133 ms.
        let t = pmac::accel_time_s(mill.ta_ms, mill.ts_ms);
        assert!((t * 3.0 - 0.4).abs() < 0.005, "{t}");
        assert_eq!(Machine::builtin("lookahead").controller, Controller::Lookahead);
    }

    #[test]
    fn bad_profiles_are_named() {
        let mut text = BUILTIN[0].1.replace("\"max_feed_mm_s\": 50", "\"max_feed_mm_s\": -1");
        assert!(text != BUILTIN[0].1, "fixture drift");
        let e = Machine::from_json(&text, "x.json").unwrap_err().to_string();
        assert!(e.contains("x.json") && e.contains("max_feed_mm_s"), "{e}");
        text = BUILTIN[0].1.replace("\"controller\"", "\"bogus\": 1, \"controller\"");
        assert!(Machine::from_json(&text, "y.json").is_err());
        let mut m = Machine::builtin("lookahead");
        let o = Overrides {
            limits_mm: Some([0.0, 1.0, 0.0, -1.0, 0.0, 1.0]),
            ..Default::default()
        };
        assert!(m.apply(&o).unwrap_err().to_string().contains("axis Y"));
        // The problem is a value a caller can match, not only a message.
        let text = BUILTIN[0].1.replace("\"max_feed_mm_s\": 50", "\"max_feed_mm_s\": -1");
        match Machine::from_json(&text, "x.json") {
            Err(MachineError::Invalid(name, ProfileProblem::NotPositive { key, value })) => {
                assert_eq!((name.as_str(), key, value), ("x.json", "max_feed_mm_s", -1.0));
            }
            other => panic!("{other:?}"),
        }
        let o = Overrides {
            lookahead_blocks: Some(0),
            ..Default::default()
        };
        assert!(matches!(
            Machine::builtin("lookahead").apply(&o),
            Err(MachineError::Invalid(_, ProfileProblem::NoLookahead))
        ));
    }
}
