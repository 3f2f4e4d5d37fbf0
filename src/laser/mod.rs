//! Laser toolpath strategies (Bayesteh (2013) §6.1.3): constant-velocity,
//! shutter-exact paths from chains and from parametric patterns.
//!
//! - [`setup`]: the stage, shutter and feed a laser job is planned with, taken from a machine profile.
//! - [`constant_velocity`]: one cut path to moves at constant V: leads,
//!   corner loops, shutter timing, Turbo PMAC pacing. Every strategy below
//!   ends here.
//! - [`contour`]: chains offset, cleaned, nested and ordered into a job.
//! - [`fill`]: closed regions filled with offset rings or hatch lines.
//! - [`patterns`]: helix, spirals, zigzag and cones.
//! - [`offset`]: exact offsets of chains (cavalier_contours).
//! - [`cleanup`]: pieces too short for a controller block removed.
//! - [`order`]: the cut order (nearest neighbour, 2-opt, Or-opt).
//! - [`dubins`]: minimum-radius corner loops and beam-off links.
//! - [`elem`]: what planning adds to exact path pieces.
//! - [`arcfit`], [`arcfit_seed`]: points to tangent-continuous arcs, and
//!   the curvature-matching method of Bayesteh (2013) it is compared with.
//! - [`audit`]: what the stage and shutter will do with a toolpath, checked
//!   against the machine.
//! - [`svg`]: a preview of a planned job.
#![warn(missing_docs)]

pub mod arcfit;
pub mod arcfit_seed;
pub mod audit;
pub mod cleanup;
pub mod constant_velocity;
pub mod contour;
pub mod dubins;
pub mod elem;
pub mod fill;
pub mod offset;
pub mod order;
pub mod patterns;
pub mod setup;
pub mod svg;

#[cfg(test)]
mod physics_tests;
