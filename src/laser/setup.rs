//! The stage, shutter and feed every laser strategy is planned against: a
//! [`LaserSetup`], made from a machine profile ([`crate::machine::Machine`])
//! and pathgen's flags.
//!
//! Its `Default` is the laser stage of Bayesteh (2013): a Geo Brick LV with
//! the shutter on `M33`, 3 ms delay + 9 ms transfer to open, 3 ms delay +
//! 14 ms transfer to close (a 29 ms window), 15 ms minimum exposure, and
//! 100 ms ramps (the `laser-stage` profile's Isx87/Isx88 rule).

use crate::machine::Controller;
use thiserror::Error;

/// Decimals PMAC text is written with unless told otherwise (0.1 µm).
pub const DEFAULT_DECIMALS: u8 = 4;

/// Why a set of machine parameters cannot be planned with.
#[derive(Debug, Error, PartialEq)]
pub enum SetupError {
    /// This parameter (named) must be above zero: the feed, TA, TD, the
    /// cut TA.
    #[error("{0} must be a positive finite number, got {1}")]
    NotPositive(&'static str, f64),
    /// This parameter (named) may be zero but not negative: TS, the
    /// shutter's delays and transfers, the minimum exposure, the tangency
    /// tolerance.
    #[error("{0} must be a finite number >= 0, got {1}")]
    Negative(&'static str, f64),
    /// A ramp time (TA, TD, the cut TA, TS) beyond [`MAX_RAMP_MS`].
    #[error("{0} of {1} ms is beyond {max} ms: no stage ramps its moves for that long", max = MAX_RAMP_MS)]
    TooLong(&'static str, f64),
}

/// Longest ramp time (TA, TD, TS, the cut TA) a setup may ask, ms. Real
/// ramps last milliseconds to a second; a minute is already absurd, and far
/// beyond it the planner's block merging (blocks at V last at least the
/// cut TA) ran for minutes on a drawing of a few thousand moves.
pub const MAX_RAMP_MS: f64 = 60_000.0;

/// Stage and shutter parameters. Times in ms (as PMAC TA/TS are given),
/// lengths in mm, speeds in mm/s.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserSetup {
    /// Constant feed V while the beam is on (mm/s).
    pub feed: f64,
    /// Acceleration time TA (ms): 0 -> V takes this long.
    pub ta_ms: f64,
    /// Deceleration time TD (ms).
    pub td_ms: f64,
    /// S-curve time TS (ms). PMAC stretches the ramp to 2·TS when TA < 2·TS.
    pub ts_ms: f64,
    /// Shutter: delay after the command before it starts to open (ms).
    pub open_delay_ms: f64,
    /// Shutter: transfer time from starting to open to fully open (ms).
    pub open_transfer_ms: f64,
    /// Shutter: delay after the command before it starts to close (ms).
    pub close_delay_ms: f64,
    /// Shutter: transfer time from starting to close to fully closed (ms).
    pub close_transfer_ms: f64,
    /// Shortest exposure the shutter makes reliably (ms); shorter cuts are reported.
    pub min_exposure_ms: f64,
    /// Two segments meeting at less than this angle (degrees) are tangent:
    /// no corner loop.
    pub tangent_tol_deg: f64,
    /// The controller the program is planned for: it decides where a
    /// shutter command takes effect and how short a block may be.
    pub controller: Controller,
    /// PMAC: the acceleration time (ms) written for the moves at V between
    /// a path's ramps. Those moves are tangent and at one speed, so the
    /// blend changes nothing but the curvature, and a short TA keeps every
    /// block at V (a Turbo PMAC stretches a block shorter than its TA to
    /// TA) and puts an `M33==` switch within V·TA/2 of its block boundary.
    pub cut_ta_ms: f64,
    /// Decimal places the program's positions are written with: a block
    /// may come out up to two units of the last place shorter than
    /// planned, so every length that must last a given time keeps
    /// [`block_margin`](Self::block_margin) in hand.
    pub decimals: u8,
}

impl Default for LaserSetup {
    fn default() -> Self {
        LaserSetup {
            feed: 2.0,
            ta_ms: 100.0,
            td_ms: 100.0,
            ts_ms: 0.0,
            open_delay_ms: 3.0,
            open_transfer_ms: 9.0,
            close_delay_ms: 3.0,
            close_transfer_ms: 14.0,
            min_exposure_ms: 15.0,
            tangent_tol_deg: 0.5,
            controller: Controller::Pmac,
            // 2 × the close delay: the close command then acts V·TA/2 =
            // V·close delay before the cut end, i.e. on the boundary at
            // the cut end itself, with no extra block.
            cut_ta_ms: 6.0,
            decimals: DEFAULT_DECIMALS,
        }
    }
}

impl LaserSetup {
    /// Check every figure; planning with NaN or zero feed would loop or divide by zero.
    pub fn validate(&self) -> Result<(), SetupError> {
        for (name, v) in [
            ("feed", self.feed),
            ("TA", self.ta_ms),
            ("TD", self.td_ms),
            ("cut TA", self.cut_ta_ms),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(SetupError::NotPositive(name, v));
            }
        }
        for (name, v) in [
            ("TS", self.ts_ms),
            ("shutter open delay", self.open_delay_ms),
            ("shutter open transfer", self.open_transfer_ms),
            ("shutter close delay", self.close_delay_ms),
            ("shutter close transfer", self.close_transfer_ms),
            ("minimum exposure", self.min_exposure_ms),
            ("tangency tolerance", self.tangent_tol_deg),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SetupError::Negative(name, v));
            }
        }
        for (name, v) in [
            ("TA", self.ta_ms),
            ("TD", self.td_ms),
            ("cut TA", self.cut_ta_ms),
            ("TS", self.ts_ms),
        ] {
            if v > MAX_RAMP_MS {
                return Err(SetupError::TooLong(name, v));
            }
        }
        Ok(())
    }

    /// Set TA = TD from an acceleration (mm/s²): the time to reach V at it.
    /// For a Turbo PMAC, which keeps TA in whole milliseconds, rounded up
    /// so the stage never accelerates harder than `a`.
    pub fn with_accel(mut self, a: f64) -> Self {
        let t = 1000.0 * self.feed / a;
        self.ta_ms = match self.controller {
            Controller::Pmac => (t - 1e-9).ceil().max(1.0),
            Controller::Lookahead => t,
        };
        self.td_ms = self.ta_ms;
        self
    }

    /// Effective ramp time (s) for `t_ms`: on a Turbo PMAC the controller's
    /// own rule ([`crate::machine::pmac::accel_time_s`]: whole ms, 2·TS
    /// when longer); on a look-ahead planner `t_ms` or 2·TS.
    fn ramp_s(&self, t_ms: f64) -> f64 {
        match self.controller {
            Controller::Pmac => crate::machine::pmac::accel_time_s(t_ms, self.ts_ms),
            Controller::Lookahead => t_ms.max(2.0 * self.ts_ms) / 1000.0,
        }
    }

    /// The stage's acceleration limit (mm/s²): V over the slower ramp. With
    /// an S-curve the peak is higher than this mean; we plan with the mean
    /// because that is what TA/TD promise the user.
    pub fn accel(&self) -> f64 {
        self.feed / self.ramp_s(self.ta_ms).max(self.ramp_s(self.td_ms))
    }

    /// Smallest radius a move at V may have: R = V²/a.
    pub fn min_radius(&self) -> f64 {
        self.feed * self.feed / self.accel()
    }

    /// The TA written into programs: a Turbo PMAC has one TA for speeding
    /// up and slowing down, so the slower of TA and TD is used for both.
    pub fn program_ta_ms(&self) -> f64 {
        let t = self.ta_ms.max(self.td_ms);
        match self.controller {
            // What the controller will run (whole ms), so the program says it.
            Controller::Pmac => crate::machine::pmac::effective_ta_ms(t),
            Controller::Lookahead => t,
        }
    }

    /// Distance to reach V from rest (trapezoid: ½·V·TA, with the program's TA).
    pub fn accel_distance(&self) -> f64 {
        0.5 * self.feed * self.ramp_s(self.program_ta_ms())
    }

    /// Distance to stop from V (½·V·TD, with the program's TA).
    pub fn decel_distance(&self) -> f64 {
        0.5 * self.feed * self.ramp_s(self.program_ta_ms())
    }

    /// Distance travelled at V between the open command and fully open.
    pub fn open_lead(&self) -> f64 {
        self.feed * (self.open_delay_ms + self.open_transfer_ms) / 1000.0
    }

    /// Distance travelled at V between the close command and the shutter
    /// starting to close.
    pub fn close_lead(&self) -> f64 {
        self.feed * self.close_delay_ms / 1000.0
    }

    /// Distance travelled at V while the shutter closes.
    pub fn close_travel(&self) -> f64 {
        self.feed * self.close_transfer_ms / 1000.0
    }

    /// Shortest beam-off stretch (mm at V) that lets the shutter close and
    /// reopen: the 29 ms window of Fig. 6-40.
    pub fn shutter_window(&self) -> f64 {
        self.feed * (self.open_delay_ms + self.open_transfer_ms + self.close_delay_ms + self.close_transfer_ms) / 1000.0
    }

    /// Time (s) of the program's start and stop ramps: max(TA, TD) or 2·TS.
    pub fn ramp_time_s(&self) -> f64 {
        self.ramp_s(self.program_ta_ms())
    }

    /// PMAC: the integer TA (ms) of the moves at V. A Turbo PMAC rounds TA
    /// to whole milliseconds and needs at least TA1.
    pub fn cut_ta(&self) -> u32 {
        self.cut_ta_ms.floor().clamp(1.0, 1e6) as u32
    }

    /// Shortest block pathgen makes on purpose (mm): one millisecond at V,
    /// the least TA a Turbo PMAC accepts, so no such block is stretched
    /// (plus [`block_margin`](Self::block_margin) for the written decimals).
    pub fn min_block(&self) -> f64 {
        self.feed / 1000.0 + self.block_margin()
    }

    /// The farthest (mm) a shutter command may act off its point where
    /// the pieces around it are too short for a block boundary there
    /// ([`Note::SwitchOff`](super::constant_velocity::Note::SwitchOff)):
    /// V·1 ms on a Turbo PMAC; on a look-ahead control the least block
    /// (V·1 ms and the writer's rounding margin), which no split may leave.
    pub fn switch_off_bound(&self) -> f64 {
        match self.controller {
            Controller::Pmac => self.feed / 1000.0,
            Controller::Lookahead => self.min_block(),
        }
    }

    /// What every beam-off connection (corner loop, turnaround) must be:
    /// long enough for the shutter window, no piece shorter than
    /// [`min_block`](Self::min_block), its last piece at least
    /// [`switch_tail`](Self::switch_tail).
    pub fn connection_shape(&self) -> crate::laser::dubins::ConnectionLimits {
        crate::laser::dubins::ConnectionLimits {
            min_len: self.shutter_window(),
            min_piece: self.min_block(),
            tail: self.switch_tail(),
        }
    }

    /// Least length of the last piece of every beam-off connection before a
    /// cut (a turn or a straight).
    /// PMAC: the open command must act `open_lead` before the cut, on a
    /// block boundary b = command + V·t/2, with blocks of at least t ms on
    /// both sides; a last piece of open lead + V·TA/2 holds that boundary for
    /// t = the cut TA (when the open lead leaves room for it: t ≤ 2/3 of
    /// the open lead's time). A look-ahead controller switches at any
    /// boundary: none needed.
    pub fn switch_tail(&self) -> f64 {
        match self.controller {
            Controller::Pmac => {
                self.open_lead() + 0.5 * self.feed * self.cut_ta() as f64 / 1000.0 + 2.0 * self.block_margin()
            }
            Controller::Lookahead => 0.0,
        }
    }

    /// Lead-in length: reach V, then travel at V while the shutter opens.
    /// A PMAC block lasts at least its TA, so the block that starts from
    /// rest is V·TA long (the ramp covers its first half); the shutter
    /// command then follows it.
    pub fn lead_in(&self) -> f64 {
        match self.controller {
            Controller::Pmac => self.ramp_block() + self.open_lead(),
            Controller::Lookahead => self.accel_distance() + self.open_lead(),
        }
    }

    /// Lead-out length: stay at V while the shutter closes, then stop.
    /// PMAC: a block at V of (cut TA + TA)/2, so that the blend into the
    /// stopping block (which takes that block's TA) fits in it, then the
    /// stopping block of V·TA.
    pub fn lead_out(&self) -> f64 {
        match self.controller {
            Controller::Pmac => self.lead_out_cruise() + self.ramp_block(),
            Controller::Lookahead => self.close_lead().max(0.0) + self.close_travel() + self.decel_distance(),
        }
    }

    /// PMAC: length of a block that starts from or ends at rest: it must
    /// last its TA, with [`block_margin`](Self::block_margin) in hand.
    pub fn ramp_block(&self) -> f64 {
        self.feed * self.ramp_time_s() + self.block_margin()
    }

    /// PMAC: the part of the lead-out at V before the stopping block.
    pub fn lead_out_cruise(&self) -> f64 {
        let at_v = 0.5 * self.feed * (self.cut_ta() as f64 / 1000.0 + self.ramp_time_s()) + self.block_margin();
        // Never shorter than the shutter needs to close at V.
        at_v.max(self.close_lead().max(0.0) + self.close_travel())
    }

    /// Shortest cut the shutter exposes reliably (mm).
    pub fn min_cut(&self) -> f64 {
        self.feed * self.min_exposure_ms / 1000.0
    }

    /// One unit of the last decimal place written (mm).
    pub fn write_quantum(&self) -> f64 {
        10f64.powi(-i32::from(self.decimals.min(9)))
    }

    /// Length (mm) kept in hand on a block that must last a given time:
    /// rounding both ends to the written decimals shortens a block by less
    /// than two units of the last place.
    pub fn block_margin(&self) -> f64 {
        2.0 * self.write_quantum()
    }

    /// Cosine of the tangency tolerance.
    pub fn tangent_cos(&self) -> f64 {
        self.tangent_tol_deg.to_radians().cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_follow_the_shutter_of_bayesteh_2013() {
        let m = LaserSetup::default();
        m.validate().unwrap();
        // 29 ms window at 2 mm/s.
        assert!((m.shutter_window() - 0.058).abs() < 1e-12);
        // a = 2 / 0.1 = 20 mm/s², R = 4 / 20 = 0.2 mm.
        assert!((m.accel() - 20.0).abs() < 1e-12);
        assert!((m.min_radius() - 0.2).abs() < 1e-12);
        // PMAC: a V·TA block from rest, then the shutter's 12 ms at V.
        assert!((m.lead_in() - (0.2002 + 0.024)).abs() < 1e-12);
        // At V for (6 + 100)/2 ms, then the V·TA stopping block.
        assert!((m.lead_out() - (0.1062 + 0.2002)).abs() < 1e-12);
        let l = LaserSetup {
            controller: Controller::Lookahead,
            ..LaserSetup::default()
        };
        assert!((l.lead_in() - (0.1 + 0.024)).abs() < 1e-12);
        assert!((l.lead_out() - (0.006 + 0.028 + 0.1)).abs() < 1e-12);
    }

    #[test]
    fn the_block_margin_follows_the_written_decimals() {
        let m = LaserSetup::default();
        assert!((m.block_margin() - 2e-4).abs() < 1e-15);
        assert!((m.min_block() - 0.0022).abs() < 1e-12);
        let m3 = LaserSetup {
            decimals: 3,
            ..LaserSetup::default()
        };
        assert!((m3.block_margin() - 2e-3).abs() < 1e-15);
        assert!((m3.min_block() - 0.004).abs() < 1e-12);
        assert!((m3.ramp_block() - (0.2 + 2e-3)).abs() < 1e-12);
    }

    #[test]
    fn s_curve_stretches_the_ramp_and_accel_sets_ta() {
        let m = LaserSetup {
            ts_ms: 80.0,
            ..LaserSetup::default()
        };
        assert!((m.accel_distance() - 0.5 * 2.0 * 0.16).abs() < 1e-12);
        let m = LaserSetup::default().with_accel(100.0);
        assert!((m.ta_ms - 20.0).abs() < 1e-12);
        assert!((m.min_radius() - 0.04).abs() < 1e-12);
        assert!(
            LaserSetup {
                feed: f64::NAN,
                ..LaserSetup::default()
            }
            .validate()
            .is_err()
        );
    }
}
