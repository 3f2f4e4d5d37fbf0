//! Laser toolpath strategies (Bayesteh (2013) §6.1.3): constant-velocity,
//! shutter-exact paths from chains and from parametric patterns.
//!
//! - [`setup`]: the stage, shutter and feed a laser job is planned with, taken from a machine profile.
//! - [`elem`]: exact path pieces that can be split and joined.
//! - [`dubins`]: minimum-radius corner loops.

pub mod arcfit;
pub mod arcfit_seed;
pub mod audit;
pub mod cleanup;
pub mod contour;
pub mod dubins;
pub mod elem;
pub mod fill;
pub mod offset;
pub mod order;
pub mod patterns;
pub mod constant_velocity;
pub mod setup;
pub mod svg;

#[cfg(test)]
mod physics_tests;
