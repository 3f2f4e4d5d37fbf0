//! The Turbo PMAC's acceleration-time rule, in one place: the laser
//! planner, `pathgen audit` and gsim's time model all ask this module, so
//! they cannot disagree about whether a block is stretched.
//!
//! A Turbo PMAC runs every LINEAR/CIRCLE block for at least its
//! acceleration time, and blends consecutive blocks over that time. The
//! acceleration time is TA (Isx87, or the program's `TA`), which the
//! controller keeps in whole milliseconds (at least 1), lengthened to 2·TS
//! when the S-curve time TS (Isx88, or `TS`) needs it (Delta Tau, Turbo
//! PMAC User Manual, "Acceleration and S-curve time"). A block shorter in
//! time than this is stretched to it, so its feed falls in proportion to its
//! length: the behaviour Bayesteh (2013) measured on a micro mill, where
//! blocks under about 0.4 mm never reached 3 mm/s.

/// The TA a Turbo PMAC actually uses for a requested `ta_ms`: whole
/// milliseconds, at least 1.
///
/// ```
/// use microcam::machine::pmac::effective_ta_ms;
/// assert_eq!(effective_ta_ms(6.4), 6.0);
/// assert_eq!(effective_ta_ms(0.2), 1.0);
/// ```
pub fn effective_ta_ms(ta_ms: f64) -> f64 {
    ta_ms.round().max(1.0)
}

/// The acceleration time in seconds for TA and TS in ms: the effective TA,
/// or 2·TS when that is longer.
///
/// ```
/// use microcam::machine::pmac::accel_time_s;
/// assert_eq!(accel_time_s(100.0, 20.0), 0.1);
/// assert_eq!(accel_time_s(10.0, 50.0), 0.1); // the factory defaults
/// ```
pub fn accel_time_s(ta_ms: f64, ts_ms: f64) -> f64 {
    effective_ta_ms(ta_ms).max(2.0 * ts_ms) / 1000.0
}

/// Whether a block `len_mm` long at `feed_mm_s` lasts less than the
/// acceleration time, so that the controller stretches it.
///
/// ```
/// use microcam::machine::pmac::stretches;
/// assert!(stretches(0.1, 3.0, 133.0, 0.0)); // 33 ms < 133 ms
/// assert!(!stretches(0.4, 3.0, 133.0, 0.0));
/// ```
pub fn stretches(len_mm: f64, feed_mm_s: f64, ta_ms: f64, ts_ms: f64) -> bool {
    len_mm / feed_mm_s < accel_time_s(ta_ms, ts_ms) * (1.0 - 1e-9) - 1e-12
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_and_s_curve() {
        assert_eq!(accel_time_s(133.0, 0.0), 0.133);
        assert_eq!(accel_time_s(6.5, 0.0), 0.007);
        assert_eq!(accel_time_s(0.0, 0.0), 0.001);
        assert_eq!(accel_time_s(1.0, 30.0), 0.06);
        // A block exactly one TA long is not stretched.
        assert!(!stretches(0.2, 2.0, 100.0, 0.0));
        assert!(stretches(0.199, 2.0, 100.0, 0.0));
    }
}
