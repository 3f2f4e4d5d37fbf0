//! Talking to a Delta Tau Turbo PMAC, and an emulator of one.
//!
//! - [`protocol`]: the Ethernet request header, reply framing, WRITEBUFFER.
//! - [`client`]: a blocking TCP client with timeouts.
//! - [`controller`]: the emulated controller (buffers, memory, simulated
//!   execution, event log).
//! - [`server`]: the emulator's TCP server and fault injection.
//! - [`plan`]: the program as pmac-send uploads it: lines, chunks cut where
//!   the beam is off, words of memory.
//! - [`send`]: upload, run and watch, with safety stops and resume state.

pub mod client;
pub mod controller;
pub mod plan;
pub mod protocol;
pub mod send;
pub mod server;
