//! Upload, run and watch a job on a controller, chunk by chunk or through
//! a rotary buffer, stopping safely on any fault.
//!
//! Safety rule: whatever goes wrong (ERR reply, timeout, lost link, Ctrl-C,
//! a program that ends before its last line), the shutter is closed and the
//! coordinate system aborted on the existing link or a new one, and a
//! resume state is written naming the chunks confirmed complete. A chunk is
//! confirmed only by what the controller reports (the line counter read
//! back, and not running), never by what was sent.

//!
//! Here: the modes, budgets, options, errors and what a session reports;
//! `sender.rs` runs a session, `state.rs` is the resume state and where a
//! stop left the stage, `plan_files.rs` the files of a dry run.

use crate::geometry::P3;
use crate::pmac::client::{ClientError, DownloadError};
use crate::pmac::upload_plan::{MARKER_WORDS, Names};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;
use thiserror::Error;

mod plan_files;
mod sender;
mod state;
#[cfg(test)]
mod tests;

pub use plan_files::{PlanFile, dry_run, dry_run_budget, is_stale_plan_file, plan_file_name};
pub use sender::Sender;
pub use state::{State, input_hash, locate};

/// How the job reaches the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Everything in one program buffer.
    Program,
    /// Chunks that fit the buffer, each run to completion before the next.
    Split,
    /// Streamed through a rotary buffer.
    Rotary,
}

impl Mode {
    /// The name `--mode` and the state file use.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Program => "program",
            Mode::Split => "split",
            Mode::Rotary => "rotary",
        }
    }
}

/// The share of a buffer a job may fill: split chunks take at most this
/// much of the free program memory `SIZE` reports, a rotary stream keeps
/// its buffer at most this full (room for the controller's own bookkeeping
/// and rounding in the word count).
pub const BUFFER_FILL: f64 = 0.9;

/// The commands that close any open buffer, empty the gather buffer and
/// open program buffer `prog` cleared, ready for lines (before a download
/// and before `SIZE` is read).
pub fn open_program(prog: u32) -> [String; 3] {
    [
        "CLOSE".into(),
        "DELETE GATHER".into(),
        format!("OPEN PROG {prog} CLEAR"),
    ]
}

/// The word budget of a split chunk: [`BUFFER_FILL`] of the `free` words
/// the controller reports, at most `limit` when given, less the completion
/// marker.
pub fn split_budget(free: i64, limit: Option<usize>) -> usize {
    let from_size = (free.max(0) as f64 * BUFFER_FILL) as usize;
    limit
        .map_or(from_size, |b| b.min(from_size))
        .saturating_sub(MARKER_WORDS)
}

/// What [`Sender`] needs besides the link and the chunks.
#[derive(Debug, Clone)]
pub struct SendOptions {
    /// How the job reaches the controller.
    pub mode: Mode,
    /// Program buffer number for program and split modes.
    pub prog: u32,
    /// Rotary buffer size, words (`DEFINE ROT`).
    pub rotary_words: usize,
    /// Fill the rotary buffer up to this fraction of its size
    /// ([`BUFFER_FILL`] unless a test wants otherwise).
    pub rotary_fill: f64,
    /// Time between status polls.
    pub poll: Duration,
    /// Give up when nothing changes on the controller for this long.
    pub stall: Duration,
    /// How long a safety stop keeps trying (reconnecting) before it gives
    /// up and says the shutter could not be confirmed closed.
    pub stop_deadline: Duration,
    /// Reply timeout during a safety stop (longer than the normal one).
    pub stop_timeout: Duration,
    /// The controller variables the job uses (shutter, counters, session).
    pub names: Names,
    /// Where the resume state goes.
    pub state_path: PathBuf,
    /// Program mode: store the program, do not run it (benchmarks,
    /// downloads checked by hand before running).
    pub upload_only: bool,
}

/// Why a session stopped.
#[derive(Debug, Error)]
pub enum SendError {
    /// The link or the controller's reply (ERR, timeout, lost connection).
    #[error("{0}")]
    Client(#[from] ClientError),
    /// A download failed part way (names the line).
    #[error("{0}")]
    Download(#[from] DownloadError),
    /// Ctrl-C or SIGTERM.
    #[error("interrupted")]
    Interrupted,
    /// Nothing changed on the controller for this long (at this counter).
    #[error("no progress on the controller for {0:?} (line counter {1})")]
    Stalled(Duration, u64),
    /// The program stopped before its last line.
    #[error("program ended at line counter {got}, expected {want} (controller reset or program error)")]
    Incomplete {
        /// The counter the controller reported.
        got: u64,
        /// The counter of the chunk's last move.
        want: u64,
    },
    /// The job or a chunk does not fit the controller's memory.
    #[error("the job needs {need} words, the controller has {free} free: use --mode split or rotary")]
    TooBig {
        /// Words needed.
        need: usize,
        /// Words free (or allowed).
        free: i64,
    },
    /// A reply that cannot be trusted (not a number, impossible counter).
    #[error("bad reply '{0}'")]
    BadReply(String),
    /// The state file could not be read or written.
    #[error("resume state {0}")]
    State(String),
}

impl SendError {
    /// The link failed (not the controller): the stop needs a new one.
    pub fn is_link(&self) -> bool {
        match self {
            SendError::Client(e) => e.is_link(),
            SendError::Download(d) => d.error.is_link(),
            _ => false,
        }
    }
}

/// What a session did, printed as JSON at the end.
#[derive(Debug, Clone, Serialize, Default)]
pub struct SendSummary {
    /// [`Mode::name`].
    pub mode: String,
    /// Chunks the job was cut into (from the resume point).
    pub chunks: usize,
    /// Chunks run to completion.
    pub chunks_run: usize,
    /// Moves in the job.
    pub moves: u64,
    /// First move this session ran (above 1 after --resume).
    pub first_move: u64,
    /// Program lines downloaded.
    pub lines_sent: u64,
    /// Requests sent to the controller.
    pub requests: u64,
    /// The last line counter the controller confirmed.
    pub final_counter: u64,
    /// A beam-off rapid to the resume point was added.
    pub repositioned: bool,
    /// Time spent downloading, s.
    pub upload_seconds: f64,
    /// Wall time of the session, s.
    pub seconds: f64,
    /// The chunks' estimated run time, s.
    pub estimated_run_seconds: f64,
}

impl SendSummary {
    /// The summary of a session that had nothing to run: every move of the
    /// state had executed.
    pub fn finished(state: &State) -> SendSummary {
        SendSummary {
            mode: state.mode.name().into(),
            moves: state.moves,
            first_move: state.next_move,
            final_counter: state.moves,
            ..Default::default()
        }
    }

    /// The JSON line pmac-send prints: the summary's fields and `ok`.
    pub fn to_json(&self, ok: bool) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or_default();
        v["ok"] = serde_json::json!(ok);
        v
    }
}

/// Why the safety stop after a failure could not be confirmed: the
/// operator must look at the machine before anything else runs.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SafeStopError {
    /// The controller did not report the program stopped and the shutter
    /// closed before the stop deadline (`last`: its last answer, or why
    /// it could not be asked).
    #[error("could not confirm the shutter closed within {deadline:?}: {last}")]
    Unconfirmed {
        /// How long the stop was tried.
        deadline: Duration,
        /// The last reply or failure seen.
        last: String,
    },
    /// The stop was confirmed but where the job stopped could not be saved.
    #[error("shutter closed, but {0}")]
    StateNotSaved(String),
    /// Saving the state after the stop failed (the stop itself reported
    /// no error).
    #[error("{0}")]
    StateSave(String),
}

/// Why a saved state may not resume this job.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ResumeRefused {
    /// The program given is not the one the state was written for.
    #[error("{state} belongs to another program (input changed): refusing to resume")]
    OtherProgram {
        /// The state file.
        state: String,
    },
    /// The state was written by a session in another upload mode.
    #[error("{state} was written in {mode} mode")]
    OtherMode {
        /// The state file.
        state: String,
        /// The mode it was written in.
        mode: &'static str,
    },
}

/// A failed session: the error, what the safety stop did, and the state.
#[derive(Debug)]
pub struct Failure {
    /// What stopped the session.
    pub error: SendError,
    /// Whether the safety stop confirmed the shutter closed and the
    /// program aborted (the error says why not).
    pub safe_stop: Result<(), SafeStopError>,
    /// The state as saved after the stop.
    pub state: State,
    /// What the session did before it stopped.
    pub summary: SendSummary,
}

impl Failure {
    /// The JSON line pmac-send prints: the summary, `ok: false`, the
    /// first move not run and the error.
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = self.summary.to_json(false);
        v["next_move"] = serde_json::json!(self.state.next_move);
        v["error"] = serde_json::json!(self.error.to_string());
        v
    }
}

/// The controller's word after a safety stop: counter, session number,
/// position (mm).
#[derive(Debug, Clone, Copy)]
pub struct Reading {
    /// The line counter (x.5: a beam-off reposition before move x + 1).
    pub counter: f64,
    /// The session variable.
    pub session: f64,
    /// The motor positions, mm.
    pub pos: P3,
}

/// Tolerance for placing the stage on a move, mm.
pub const POSITION_TOL_MM: f64 = 0.002;
