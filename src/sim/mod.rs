//! Simulation of a toolpath: what the machine will do with a program.
//!
//! - [`summary`]: path lengths, counts and extents, one pass, constant memory.
//! - [`time`]: motion time per block under the PMAC or look-ahead model.
//! - [`beam`]: where the shutter really passes the beam, per cut.
//! - [`stock`]: material removal on a height-field stock.
//! - [`stl`]: the simulated stock as a watertight STL.
//! - [`picture`]: a PNG of the stock with the path drawn over it.
//! - [`removal`]: the removal engine (chip volume per block and step), no I/O.
//! - [`report`]: all of it in one streaming pass.
//! - [`gsim_json`]: the gsim report as JSON.

#![warn(missing_docs)]

pub mod beam;
pub mod gsim_json;
pub mod picture;
pub mod removal;
pub mod report;
pub mod stl;
pub mod stock;
pub mod summary;
pub mod time;
