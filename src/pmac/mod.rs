//! Talking to a Delta Tau Turbo PMAC, and an emulator of one.
//!
//! - [`protocol`]: the Ethernet request header, reply framing, WRITEBUFFER.
//! - [`client`]: a blocking TCP client with timeouts.
//! - [`controller`]: the emulated controller (buffers, memory, simulated
//!   execution, event log).
//! - [`server`]: the emulator's TCP server and fault injection.
//! - [`upload_plan`]: the program as pmac-send uploads it: lines, chunks cut
//!   where the beam is off, words of memory, the point a resume starts from.
//! - [`send`]: upload, run and watch, with safety stops and resume state.

#![warn(missing_docs)]

pub mod client;
pub mod controller;
pub mod protocol;
pub mod send;
pub mod server;
pub mod upload_plan;
