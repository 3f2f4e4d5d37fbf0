//! Rotating-wire probe scanning and measurement (Bayesteh 2013, ch. 4).
//!
//! A spinning bent wire sweeps a circle of effective diameter D_e; an
//! acoustic emission sensor hears it touch the part. The scan steps round a
//! contour in the XY plane from the last two contacts, and the contacts
//! give gauge widths, circle diameters, roundness and deviations from the
//! design.
//!
//! - [`tip`]: the probe, D_e = 2 L sin(beta), touch resolution.
//! - [`part`]: simulated parts (chains, circle, gauge block) and exact touches.
//! - [`noise`]: touch scatter, trigger delay, once-per-revolution touches.
//! - [`scan`]: the automated scan.
//! - [`fit`]: line, least-squares circle and minimum-zone circle.
//! - [`job`]: a whole job: scan a part, then measure.
//! - [`measure`]: widths, diameters, roundness, deviations, uncertainties.
//! - [`program`]: the probing program for a Turbo PMAC or an ISO control.
//! - [`svg`]: a picture of the scan against the design.
//! - [`report`]: the contact CSV and report JSON.
#![warn(missing_docs)]

pub mod fit;
pub mod job;
pub mod measure;
pub mod noise;
pub mod part;
pub mod program;
pub mod report;
pub mod scan;
pub mod svg;
pub mod tip;

/// What can go wrong planning or running a scan.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProbeError {
    /// A parameter out of range.
    #[error("{0}")]
    Param(String),
    /// The part cannot be built.
    #[error("{0}")]
    Part(String),
    /// The scan cannot start there.
    #[error("{0}")]
    Start(String),
    /// An approach found nothing.
    #[error("{0}")]
    NoSurface(String),
    /// Too few or degenerate points for a fit.
    #[error("{0}")]
    Fit(String),
}
