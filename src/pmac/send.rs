//! Upload, run and watch a job on a controller, chunk by chunk or through
//! a rotary buffer, stopping safely on any fault.
//!
//! Safety rule: whatever goes wrong (ERR reply, timeout, lost link, Ctrl-C,
//! a program that ends before its last line), the shutter is closed and the
//! coordinate system aborted on the existing link or a new one, and a
//! resume state is written naming the chunks confirmed complete. A chunk is
//! confirmed only by what the controller reports (the line counter read
//! back, and not running), never by what was sent.

use crate::geometry::P3;
use crate::pmac::client::{Client, ClientError, DownloadError};
use crate::pmac::controller::parse_status;
use crate::pmac::upload_plan::{Chunk, MARKER_WORDS, MoveGeom, Names, marker_lines};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use thiserror::Error;

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

/// The word budget of a dry run, where no controller reports its free
/// memory: `--buffer-words` less the marker in split mode, the chunk size
/// in rotary mode, none for one program. `None` inside `Err` names the
/// missing flag.
pub fn dry_run_budget(
    mode: Mode,
    buffer_words: Option<usize>,
    chunk_words: usize,
) -> Result<Option<usize>, &'static str> {
    match mode {
        Mode::Program => Ok(None),
        Mode::Split => buffer_words
            .map(|b| Some(b.saturating_sub(MARKER_WORDS)))
            .ok_or("--dry-run in split mode needs --buffer-words"),
        Mode::Rotary => Ok(Some(chunk_words)),
    }
}

/// One dry-run file: its name and text.
pub struct PlanFile {
    /// `chunk-NNN.pmac`, numbered from 1.
    pub name: String,
    /// The download as it would be sent (buffer chunks wrapped in
    /// `OPEN PROG` ... `CLOSE` with their completion marker).
    pub text: String,
}

/// A dry run: the chunks a job would be sent in, as download files, and the
/// `microcam.pmac-plan/1` description of them (`plan.json`).
pub fn dry_run(
    job: &crate::pmac::upload_plan::UploadPlan,
    mode: Mode,
    budget: Option<usize>,
    prog: u32,
    done_var: &str,
) -> Result<(Vec<PlanFile>, serde_json::Value), crate::pmac::upload_plan::PlanError> {
    let chunks = match (mode, budget) {
        (Mode::Rotary, Some(b)) => job.stream_chunks(b),
        _ => job.chunks(budget),
    }?;
    let mut files = Vec::with_capacity(chunks.len());
    let mut plan = Vec::with_capacity(chunks.len());
    for (i, c) in chunks.iter().enumerate() {
        let name = plan_file_name(i + 1);
        let mut text = String::new();
        let mut push = |l: &str| {
            text.push_str(l);
            text.push('\n');
        };
        if mode != Mode::Rotary {
            open_program(prog).iter().for_each(|l| push(l));
        }
        c.lines.iter().for_each(|l| push(l));
        if mode != Mode::Rotary {
            marker_lines(done_var, i + 1).iter().for_each(|l| push(l));
            push("CLOSE");
        }
        plan.push(serde_json::json!({
            "file": name, "lines": c.lines.len(), "words": c.words,
            "first_counter": c.first_counter, "last_counter": c.last_counter,
            "start": c.start, "end": c.end, "seconds": c.seconds,
        }));
        files.push(PlanFile { name, text });
    }
    let summary = serde_json::json!({
        "schema": "microcam.pmac-plan/1",
        "mode": mode.name(),
        "prog": prog,
        "budget_words": budget,
        "chunks": plan,
        "lines": chunks.iter().map(|c| c.lines.len()).sum::<usize>(),
        "estimated_seconds": chunks.iter().map(|c| c.seconds).sum::<f64>(),
    });
    Ok((files, summary))
}

/// The name of dry-run file `number` (1-based).
pub fn plan_file_name(number: usize) -> String {
    format!("chunk-{number:03}.pmac")
}

/// Whether a file named `name` is a chunk file that a plan of `chunks`
/// files did not write (left by an earlier, longer plan).
pub fn is_stale_plan_file(name: &str, chunks: usize) -> bool {
    name.strip_prefix("chunk-")
        .and_then(|r| r.strip_suffix(".pmac"))
        .and_then(|d| d.parse::<usize>().ok())
        .is_some_and(|k| k == 0 || k > chunks || name != plan_file_name(k))
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

/// The resume state: written before the controller is touched, whenever
/// the controller confirms progress, and after a stop.
///
/// Progress is counted in moves (the counter numbers them): every move
/// before `next_move` has executed; of `next_move` only the part before
/// `resume_at` (when set) has.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct State {
    /// Layout version of the state file (2).
    pub version: u32,
    /// FNV-1a of the input text: resume refuses another program.
    pub input_hash: String,
    /// The mode the job was started in (resume keeps it).
    pub mode: Mode,
    /// Word budget the chunks were cut with (so resume cuts the same).
    pub budget: Option<usize>,
    /// Moves in the job.
    pub moves: u64,
    /// The first move not wholly executed (moves + 1 when finished).
    pub next_move: u64,
    /// Where along `next_move` the stage stopped (mm), if it had started it.
    pub resume_at: Option<[f64; 3]>,
    /// This job's number, also written to the session variable on the
    /// controller: counters read back count only when it matches.
    pub session: u64,
    /// Why the last session stopped (absent when it finished).
    pub stopped: Option<String>,
}

impl State {
    /// The state of a new job of `moves` moves read from text hashing to
    /// `input_hash`, with a fresh session number (the clock and the process
    /// id, so two sessions on one controller do not share one).
    pub fn new(input_hash: String, mode: Mode, moves: u64) -> State {
        let session = (std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64)
            ^ u64::from(std::process::id()))
            % 1_000_000_000
            + 1;
        State {
            version: 2,
            input_hash,
            mode,
            budget: None,
            moves,
            next_move: 1,
            resume_at: None,
            session,
            stopped: None,
        }
    }

    /// Whether this saved state may resume the job whose text hashes to
    /// `input_hash` in `mode`; the error says why not (`path` names the
    /// state file).
    pub fn check_resume(&self, input_hash: &str, mode: Mode, path: &Path) -> Result<(), String> {
        if self.input_hash != input_hash {
            return Err(format!(
                "{} belongs to another program (input changed): refusing to resume",
                path.display()
            ));
        }
        if self.mode != mode {
            return Err(format!("{} was written in {} mode", path.display(), self.mode.name()));
        }
        Ok(())
    }

    /// Read a state file.
    pub fn load(path: &Path) -> Result<State, SendError> {
        let text = std::fs::read_to_string(path).map_err(|e| SendError::State(format!("{}: {e}", path.display())))?;
        serde_json::from_str(&text).map_err(|e| SendError::State(format!("{}: {e}", path.display())))
    }

    /// Write the state file whole (a temporary file renamed over it), so a
    /// kill mid-write leaves the previous state.
    pub fn save(&self, path: &Path) -> Result<(), SendError> {
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let err = |e: &dyn std::fmt::Display| SendError::State(format!("{}: {e}", path.display()));
        let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(|e| err(&e))?;
        let text = serde_json::to_string_pretty(self).map_err(|e| err(&e))?;
        writeln!(tmp, "{text}").map_err(|e| err(&e))?;
        tmp.persist(path).map_err(|e| err(&e))?;
        Ok(())
    }

    /// Where along `next_move` to resume (`resume_at` as a point).
    pub fn resume_point(&self) -> Option<P3> {
        self.resume_at.map(|a| P3::new(a[0], a[1], a[2]))
    }

    /// Take a resume point if it is further along than the saved one
    /// (progress never goes back).
    pub fn advance_to(&mut self, moves: &[MoveGeom], next: u64, at: Option<P3>) -> bool {
        let key = |n: u64, a: Option<P3>| -> (u64, f64) {
            let s = match (a, moves.get((n as usize).wrapping_sub(1))) {
                (Some(p), Some(m)) => m.project(p).1,
                _ => 0.0,
            };
            (n, s)
        };
        let (new, old) = (key(next, at), key(self.next_move, self.resume_point()));
        if new.0 > old.0 || (new.0 == old.0 && new.1 > old.1 + 1e-6) {
            self.next_move = next;
            self.resume_at = at.map(|p| [p.x, p.y, p.z]);
            true
        } else {
            false
        }
    }
}

/// Where the stage is in the job, from the counter `c` (moves wholly
/// executed: move n sets it to n where the next move starts) and the
/// position `p`: the move to continue and the point on it. A position on
/// neither move `c + 1` nor move `c` (the blend) gives move `c + 1` from its
/// start: re-cutting a little is safe, skipping is not.
pub fn locate(moves: &[MoveGeom], c: u64, p: P3, tol: f64) -> (u64, Option<P3>) {
    let place = |n: u64| -> Option<(u64, Option<P3>)> {
        let m = moves.get((n as usize).checked_sub(1)?)?;
        let (d, s) = m.project(p);
        if d > tol {
            return None;
        }
        let len = m.length();
        Some(if len - s <= tol {
            (n + 1, None)
        } else if s <= tol {
            (n, None)
        } else {
            (n, Some(m.point_at(s)))
        })
    };
    place(c + 1)
        .or_else(|| if c >= 1 { place(c) } else { None })
        .unwrap_or((c + 1, None))
}

/// FNV-1a 64 of the input, as hex.
pub fn input_hash(text: &str) -> String {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x100000001b3);
    }
    format!("{h:016x}")
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

/// A counter read back: a multiple of 0.5 between 0 and the job's moves
/// (x.5 marks a beam-off reposition before move x + 1), or the reply is
/// bad and must not be trusted.
fn counter_value(s: &str, moves: u64) -> Result<f64, SendError> {
    let v = s
        .trim()
        .parse::<f64>()
        .map_err(|_| SendError::BadReply(format!("counter '{}' is not a number", s.trim())))?;
    if !v.is_finite() || v < 0.0 || v > moves as f64 || (v * 2.0).fract() != 0.0 {
        return Err(SendError::BadReply(format!(
            "counter '{}' is impossible (the job has {moves} moves)",
            s.trim()
        )));
    }
    Ok(v)
}

/// A small whole number (the chunk marker).
fn count(s: &str) -> Result<u64, SendError> {
    let v = s
        .trim()
        .parse::<f64>()
        .map_err(|_| SendError::BadReply(s.to_string()))?;
    if !v.is_finite() || v < 0.0 || v.fract() != 0.0 || v > 1e9 {
        return Err(SendError::BadReply(s.to_string()));
    }
    Ok(v as u64)
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

/// A failed session: the error, what the safety stop did, and the state.
#[derive(Debug)]
pub struct Failure {
    /// What stopped the session.
    pub error: SendError,
    /// Whether the safety stop confirmed the shutter closed and the
    /// program aborted (the error says why not).
    pub safe_stop: Result<(), String>,
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

/// One session on one controller: runs chunks, watches progress, stops
/// safely.
pub struct Sender<'a> {
    client: Option<Client>,
    host: String,
    transport: crate::pmac::client::Transport,
    opts: SendOptions,
    stop: Arc<AtomicBool>,
    progress: &'a mut dyn Write,
    summary: SendSummary,
    last_note: Instant,
    moves: Vec<MoveGeom>,
}

impl<'a> Sender<'a> {
    /// A session on `client` (connected to `host`); progress lines go to
    /// `progress`, `stop` is set by the signal handler, `moves` are the
    /// job's moves (to locate a stop).
    pub fn new(
        client: Client,
        host: &str,
        opts: SendOptions,
        stop: Arc<AtomicBool>,
        progress: &'a mut dyn Write,
        moves: Vec<MoveGeom>,
    ) -> Self {
        Sender {
            transport: client.transport(),
            client: Some(client),
            host: host.to_string(),
            opts,
            stop,
            progress,
            summary: SendSummary::default(),
            last_note: Instant::now() - Duration::from_secs(10),
            moves,
        }
    }

    fn c(&mut self) -> Result<&mut Client, SendError> {
        self.client
            .as_mut()
            .ok_or_else(|| SendError::Client(ClientError::Io(std::io::Error::other("no connection"))))
    }

    fn cmd(&mut self, s: &str) -> Result<Vec<String>, SendError> {
        Ok(self.c()?.command(s)?)
    }

    fn check_stop(&self) -> Result<(), SendError> {
        if self.stop.load(Ordering::SeqCst) {
            Err(SendError::Interrupted)
        } else {
            Ok(())
        }
    }

    fn note(&mut self, force: bool, msg: impl FnOnce() -> String) {
        if force || self.last_note.elapsed() >= Duration::from_millis(500) {
            self.last_note = Instant::now();
            let _ = writeln!(self.progress, "pmac-send: {}", msg());
        }
    }

    fn n_moves(&self) -> u64 {
        self.moves.len() as u64
    }

    /// Free words after clearing program `prog` and the gather buffer.
    pub fn free_words(&mut self) -> Result<i64, SendError> {
        for c in open_program(self.opts.prog) {
            self.cmd(&c)?;
        }
        self.cmd("CLOSE")?;
        let r = self.cmd("SIZE")?;
        let s = r.first().cloned().unwrap_or_default();
        s.trim().parse::<i64>().map_err(|_| SendError::BadReply(s))
    }

    /// Record the progress a validated counter confirms: moves up to `c`
    /// have executed.
    fn progress_to(&mut self, state: &mut State, c: f64) -> Result<(), SendError> {
        if c.fract() == 0.0 && state.advance_to(&self.moves, c as u64 + 1, None) {
            self.summary.final_counter = c as u64;
            self.save(state)?;
        }
        Ok(())
    }

    /// Run the chunks (cut from the state's resume point).
    pub fn run(mut self, chunks: &[Chunk], state: &mut State) -> Result<SendSummary, Box<Failure>> {
        let t0 = Instant::now();
        self.summary.mode = self.opts.mode.name().into();
        self.summary.chunks = chunks.len();
        self.summary.moves = self.n_moves();
        self.summary.first_move = state.next_move;
        self.summary.estimated_run_seconds = chunks.iter().map(|c| c.seconds).sum();
        let r = match self.opts.mode {
            Mode::Program | Mode::Split => self.run_buffers(chunks, state),
            Mode::Rotary => self.run_rotary(chunks, state),
        };
        self.summary.seconds = t0.elapsed().as_secs_f64();
        if let Some(c) = &self.client {
            self.summary.requests += c.requests;
        }
        match r {
            Ok(()) => {
                state.stopped = None;
                if let Err(e) = state.save(&self.opts.state_path) {
                    let _ = writeln!(self.progress, "pmac-send: warning: {e}");
                }
                Ok(self.summary)
            }
            Err(error) => {
                let link = error.is_link() || matches!(error, SendError::BadReply(_));
                let safe_stop = self.recover(state, link);
                state.stopped = Some(error.to_string());
                let mut failure = Failure {
                    error,
                    safe_stop,
                    state: state.clone(),
                    summary: self.summary.clone(),
                };
                if let Err(e) = state.save(&self.opts.state_path) {
                    failure.safe_stop = failure.safe_stop.and(Err(e.to_string()));
                }
                failure.state = state.clone();
                Err(Box::new(failure))
            }
        }
    }

    /// Stop safely, then take from the controller where the job stopped
    /// (when its counters are this job's) and save it in the state.
    pub fn recover(&mut self, state: &mut State, link_failed: bool) -> Result<(), String> {
        let reading = self.secure(link_failed)?;
        if reading.session == state.session as f64
            && let Ok(c) = counter_value(&fmt_reading(reading.counter), self.n_moves())
        {
            let (next, at) = if c.fract() != 0.0 {
                // Still repositioning before move c + 0.5: nothing new ran.
                (state.next_move, state.resume_point())
            } else {
                locate(&self.moves, c as u64, reading.pos, POSITION_TOL_MM)
            };
            state.advance_to(&self.moves, next, at);
        }
        state
            .save(&self.opts.state_path)
            .map_err(|e| format!("shutter closed, but {e}"))
    }

    /// Close the shutter, abort, flush queued synchronous assignments, and
    /// keep at it, reconnecting, until the controller confirms the program
    /// is not running and the shutter is closed, or the stop deadline
    /// passes. Each reply may take [`SendOptions::stop_timeout`].
    fn secure(&mut self, link_failed: bool) -> Result<Reading, String> {
        let deadline = Instant::now() + self.opts.stop_deadline;
        let sh = self.opts.names.shutter.clone();
        let stop_line = format!("CLOSE {sh}=0 &1A &1 MFLUSH {sh}=0");
        let n = &self.opts.names;
        let check = format!("&1?? {sh} {} {} #1P #2P #3P #1-> #2-> #3->", n.counter, n.session);
        if link_failed {
            self.client = None;
        }
        let mut last = String::new();
        loop {
            if self.client.is_none() {
                match Client::connect(&self.host, self.transport, self.opts.stop_timeout) {
                    Ok(c) => self.client = Some(c),
                    Err(e) => last = format!("could not reach the controller: {e}"),
                }
            }
            if self.client.is_some() {
                let r = self.cmd(&stop_line).and_then(|_| self.cmd(&check));
                match r {
                    Ok(v) => match parse_check(&v) {
                        Some((running, shut, reading)) => {
                            if !running && shut == 0.0 {
                                return Ok(reading);
                            }
                            last = format!("controller still reports running={running}, {sh}={shut}")
                        }
                        None => last = format!("bad reply to '{check}': {v:?}"),
                    },
                    Err(e) => {
                        last = e.to_string();
                        if !matches!(&e, SendError::Client(ClientError::Pmac { .. })) {
                            self.client = None;
                        }
                    }
                }
            }
            if Instant::now() >= deadline {
                return Err(format!(
                    "could not confirm the shutter closed within {:?}: {last}",
                    self.opts.stop_deadline
                ));
            }
            let _ = writeln!(
                self.progress,
                "pmac-send: safety stop not confirmed yet ({last}); retrying"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    fn save(&mut self, state: &State) -> Result<(), SendError> {
        state.save(&self.opts.state_path)
    }

    /// The lines of chunk `c`; with `reposition`, a beam-off RAPID to its
    /// start first, which sets the counter to the move before it.
    fn chunk_lines(&mut self, c: &Chunk, reposition: bool, number: usize) -> Vec<String> {
        let mut lines = c.lines.clone();
        if self.opts.mode != Mode::Rotary {
            lines.extend(marker_lines(&self.opts.names.done, number));
        }
        if reposition {
            let at = lines
                .iter()
                .position(|l| l.starts_with(&format!("{}=", self.opts.names.shutter)))
                .map_or(0, |p| p + 1);
            lines.insert(
                at,
                format!(
                    "RAPID X{:.4} Y{:.4} Z{:.4} {}=={}",
                    c.start[0],
                    c.start[1],
                    c.start[2],
                    self.opts.names.counter_m,
                    c.first_counter - 1
                ),
            );
            self.summary.repositioned = true;
        }
        lines
    }

    /// Before `R`: the counter M-variable pointed at its register, the
    /// counter and session set, leftover synchronous assignments flushed.
    fn prepare(&mut self, state: &State, counter: f64, first: bool) -> Result<(), SendError> {
        let n = self.opts.names.clone();
        let def = n.counter_definition().unwrap_or_default();
        let mut line = format!(
            "{def} {}={} {}={}",
            n.counter,
            fmt_reading(counter),
            n.session,
            state.session
        );
        if first {
            line += &format!(" {}=0", n.done);
        }
        self.cmd(&format!("{line} {}=0 &1 MFLUSH", n.shutter))?;
        Ok(())
    }

    fn run_buffers(&mut self, chunks: &[Chunk], state: &mut State) -> Result<(), SendError> {
        let prog = self.opts.prog;
        let n = chunks.len();
        let resumed = state.next_move > 1 || state.resume_at.is_some();
        for (i, chunk) in chunks.iter().enumerate() {
            self.check_stop()?;
            let reposition = i == 0 && resumed;
            let lines = self.chunk_lines(chunk, reposition, i + 1);
            let t = Instant::now();
            for c in open_program(prog) {
                self.cmd(&c)?;
            }
            // Send in slices so Ctrl-C is seen during long uploads.
            for part in lines.chunks(256) {
                self.check_stop()?;
                self.c()?.write_lines(part)?;
                self.summary.lines_sent += part.len() as u64;
            }
            self.cmd("CLOSE")?;
            self.summary.upload_seconds += t.elapsed().as_secs_f64();
            if self.opts.upload_only {
                self.note(true, || {
                    format!("chunk {}/{n}: {} lines uploaded, not run", i + 1, lines.len())
                });
                continue;
            }
            self.note(true, || {
                format!("chunk {}/{n}: {} lines uploaded, running", i + 1, lines.len())
            });
            let c0 = (chunk.first_counter - 1) as f64 + if reposition { 0.5 } else { 0.0 };
            self.prepare(state, c0, i == 0)?;
            self.cmd(&format!("&1B{prog}R"))?;
            let remaining: f64 = chunks[i + 1..].iter().map(|c| c.seconds).sum();
            let (got, done) = self.wait_done(i, n, chunk, remaining, state)?;
            if got < chunk.last_counter as f64 || done < (i + 1) as u64 {
                return Err(SendError::Incomplete {
                    got: got.max(0.0) as u64,
                    want: chunk.last_counter,
                });
            }
            self.progress_to(state, got)?;
            self.summary.chunks_run += 1;
        }
        Ok(())
    }

    /// Poll until the program is not running and in position, saving the
    /// progress the counter confirms.
    fn wait_done(
        &mut self,
        i: usize,
        n: usize,
        chunk: &Chunk,
        remaining: f64,
        state: &mut State,
    ) -> Result<(f64, u64), SendError> {
        let mut last: Option<(bool, bool, f64, u64)> = None;
        let mut changed = Instant::now();
        let q = format!("&1?? {} {}", self.opts.names.counter, self.opts.names.done);
        loop {
            self.check_stop()?;
            let r = self.cmd(&q)?;
            let (Some(st), Some(cnt), Some(done)) = (r.first(), r.get(1), r.get(2)) else {
                return Err(SendError::BadReply(r.join(" ")));
            };
            let (running, inpos) = parse_status(st).ok_or_else(|| SendError::BadReply(st.clone()))?;
            let counter = counter_value(cnt, self.n_moves())?;
            let done = count(done)?;
            let s = (running, inpos, counter, done);
            if Some(s) != last {
                last = Some(s);
                changed = Instant::now();
            } else if changed.elapsed() > self.opts.stall {
                return Err(SendError::Stalled(self.opts.stall, counter as u64));
            }
            self.progress_to(state, counter)?;
            let span = (chunk.last_counter + 1).saturating_sub(chunk.first_counter).max(1) as f64;
            let frac = ((counter - (chunk.first_counter - 1) as f64) / span).clamp(0.0, 1.0);
            let left = remaining + chunk.seconds * (1.0 - frac);
            let var = self.opts.names.counter.clone();
            self.note(false, || {
                format!(
                    "chunk {}/{n}: {var} = {counter} of {}; about {left:.1} s left",
                    i + 1,
                    chunk.last_counter
                )
            });
            if !running && inpos {
                return Ok((counter, done));
            }
            std::thread::sleep(self.opts.poll);
        }
    }

    /// Stream the chunks through the rotary buffer, whole chunks at a time:
    /// every chunk ends with the beam off, so whatever the controller holds
    /// ends with the shutter closed and a stream the host stops feeding
    /// runs dry with the beam off.
    fn run_rotary(&mut self, chunks: &[Chunk], state: &mut State) -> Result<(), SendError> {
        let resumed = state.next_move > 1 || state.resume_at.is_some();
        let mut units: Vec<(Vec<String>, usize)> = Vec::new();
        for (i, c) in chunks.iter().enumerate() {
            let mut ls = self.chunk_lines(c, i == 0 && resumed, i + 1);
            if i + 1 == chunks.len() {
                // A dwell lets the last synchronous assignments (the last
                // counter) act; the stream then waits, suspended.
                ls.push("DWELL0".into());
            }
            let w = ls.iter().map(|l| crate::pmac::protocol::line_words(l)).sum();
            units.push((ls, w));
        }
        let total_lines: usize = units.iter().map(|u| u.0.len()).sum();
        let final_counter = chunks.last().map_or(0, |c| c.last_counter);
        let cap = self.opts.rotary_words;
        let limit = ((cap as f64) * self.opts.rotary_fill.clamp(0.1, 1.0)) as usize;
        if let Some((_, w)) = units.iter().find(|u| u.1 > limit) {
            return Err(SendError::TooBig {
                need: *w,
                free: limit as i64,
            });
        }
        self.cmd("CLOSE")?;
        self.cmd("DELETE GATHER")?;
        self.cmd("&1 A")?;
        self.cmd("&1 DELETE ROT")?;
        self.cmd(&format!("&1 DEFINE ROT {cap}"))?;
        self.cmd("&1 B0")?;
        let first = chunks.first().map_or(0, |c| c.first_counter - 1) as f64 + if resumed { 0.5 } else { 0.0 };
        self.prepare(state, first, true)?;
        self.cmd("OPEN ROT")?;
        // Lines of each unit, to know how many words still wait (PR).
        let mut sent_units = 0usize;
        let mut sent_lines = 0usize;
        let mut queued = 0usize;
        let line_words: Vec<usize> = units
            .iter()
            .flat_map(|u| u.0.iter().map(|l| crate::pmac::protocol::line_words(l)))
            .collect();
        let mut started = false;
        let mut last: Option<(bool, bool, f64, usize)> = None;
        let mut changed = Instant::now();
        let n = chunks.len();
        loop {
            self.check_stop()?;
            let waiting: usize = line_words[sent_lines.saturating_sub(queued)..sent_lines].iter().sum();
            let mut room = limit.saturating_sub(waiting);
            let mut batch: Vec<String> = Vec::new();
            while sent_units < units.len() && units[sent_units].1 <= room && batch.len() < 200 {
                room -= units[sent_units].1;
                batch.extend(units[sent_units].0.iter().cloned());
                sent_units += 1;
            }
            if !batch.is_empty() {
                let t = Instant::now();
                self.c()?.write_lines(&batch)?;
                self.summary.upload_seconds += t.elapsed().as_secs_f64();
                self.summary.lines_sent += batch.len() as u64;
                sent_lines += batch.len();
            }
            if !started {
                self.cmd("&1R")?;
                started = true;
                self.note(true, || {
                    format!("rotary: running, {sent_lines} of {total_lines} lines queued")
                });
            }
            let q = format!("PR &1?? {}", self.opts.names.counter);
            let r = self.cmd(&q)?;
            let (Some(pr), Some(st), Some(cnt)) = (r.first(), r.get(1), r.get(2)) else {
                return Err(SendError::BadReply(r.join(" ")));
            };
            queued = pr.trim().parse().map_err(|_| SendError::BadReply(pr.clone()))?;
            if queued > sent_lines {
                return Err(SendError::BadReply(format!("PR {queued} with {sent_lines} lines sent")));
            }
            let (running, inpos) = parse_status(st).ok_or_else(|| SendError::BadReply(st.clone()))?;
            let counter = counter_value(cnt, self.n_moves())?;
            self.progress_to(state, counter)?;
            let var = self.opts.names.counter.clone();
            self.note(false, || {
                format!(
                    "rotary: {sent_units}/{n} chunks sent, {queued} lines queued, {var} = {counter} of {final_counter}"
                )
            });
            let s = (running, inpos, counter, queued);
            if Some(s) != last {
                last = Some(s);
                changed = Instant::now();
            } else if changed.elapsed() > self.opts.stall {
                return Err(SendError::Stalled(self.opts.stall, counter as u64));
            }
            if !running {
                // A rotary program runs (suspended when dry) until Q or A:
                // not running means it was stopped.
                return Err(SendError::Incomplete {
                    got: counter as u64,
                    want: final_counter,
                });
            }
            // Done: everything sent and calculated, motion ended, and the
            // last counter set (by the final DWELL0).
            if sent_units == units.len() && queued == 0 && inpos && counter >= final_counter as f64 {
                break;
            }
            if batch.is_empty() {
                std::thread::sleep(self.opts.poll);
            }
        }
        self.cmd("CLOSE")?;
        self.cmd("&1Q")?;
        self.cmd("&1 DELETE ROT")?;
        self.summary.chunks_run = chunks.len();
        Ok(())
    }
}

/// Tolerance for placing the stage on a move, mm.
pub const POSITION_TOL_MM: f64 = 0.002;

fn fmt_reading(v: f64) -> String {
    crate::pmac::controller::fmt_value(v)
}

/// Parse the answer to `&1?? M33 P400 P402 #1P #2P #3P #1-> #2-> #3->`: (running,
/// shutter, reading). `None` if any part is malformed.
fn parse_check(v: &[String]) -> Option<(bool, f64, Reading)> {
    if v.len() != 10 {
        return None;
    }
    let (running, _) = parse_status(&v[0])?;
    let num = |s: &String| s.trim().parse::<f64>().ok().filter(|x| x.is_finite());
    let shutter = num(&v[1])?;
    let counter = num(&v[2])?;
    let session = num(&v[3])?;
    // `#n->` answers the axis definition, e.g. `10000X`: counts per mm.
    let scale = |s: &String| -> Option<f64> {
        let t = s.trim();
        let end = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
        t[..end].parse::<f64>().ok().filter(|x| x.is_finite() && *x != 0.0)
    };
    let pos = P3::new(
        num(&v[4])? / scale(&v[7])?,
        num(&v[5])? / scale(&v[8])?,
        num(&v[6])? / scale(&v[9])?,
    );
    Some((running, shutter, Reading { counter, session, pos }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pmac::upload_plan::UploadPlan;

    #[test]
    fn split_budget_fills_ninety_percent_at_most_the_limit_less_the_marker() {
        assert_eq!(split_budget(10_000, None), 9_000 - MARKER_WORDS);
        assert_eq!(split_budget(10_000, Some(5_000)), 5_000 - MARKER_WORDS);
        assert_eq!(split_budget(10_000, Some(50_000)), 9_000 - MARKER_WORDS);
        assert_eq!(split_budget(-5, None), 0);
        assert_eq!(split_budget(4, Some(4)), 0);
    }

    #[test]
    fn dry_run_files_are_wrapped_buffers_or_bare_rotary_chunks() {
        let mut text = String::from("G21 G90\n");
        for i in 1..=40 {
            text.push_str(&format!("G1 X{i} F10\n"));
        }
        let job = UploadPlan::read(&text, &Names::default()).unwrap();
        let budget = dry_run_budget(Mode::Split, Some(60), 16).unwrap();
        assert_eq!(budget, Some(60 - MARKER_WORDS));
        let (files, plan) = dry_run(&job, Mode::Split, budget, 3, "P401").unwrap();
        assert!(files.len() > 1, "{}", files.len());
        assert_eq!(plan["chunks"].as_array().unwrap().len(), files.len());
        for (i, f) in files.iter().enumerate() {
            assert_eq!(f.name, plan_file_name(i + 1));
            assert!(
                f.text.starts_with("CLOSE\nDELETE GATHER\nOPEN PROG 3 CLEAR\n"),
                "{}",
                f.text
            );
            assert!(
                f.text.ends_with(&format!("DWELL0\nP401={}\nCLOSE\n", i + 1)),
                "{}",
                f.text
            );
        }
        let (rot, _) = dry_run(&job, Mode::Rotary, Some(16), 3, "P401").unwrap();
        assert!(
            rot.iter()
                .all(|f| !f.text.contains("OPEN PROG") && !f.text.contains("P401="))
        );
        assert!(dry_run_budget(Mode::Split, None, 16).is_err());
        assert_eq!(dry_run_budget(Mode::Program, None, 16), Ok(None));
        assert!(is_stale_plan_file("chunk-005.pmac", 4));
        assert!(!is_stale_plan_file("chunk-004.pmac", 4));
        assert!(is_stale_plan_file("chunk-000.pmac", 4));
        assert!(is_stale_plan_file("chunk-5.pmac", 4));
        assert!(is_stale_plan_file("chunk-3.pmac", 4));
        assert!(!is_stale_plan_file("plan.json", 4));
    }

    #[test]
    fn resume_is_refused_for_another_input_or_mode() {
        let s = State::new("abc".into(), Mode::Split, 5);
        assert!(s.session >= 1 && s.session <= 1_000_000_000);
        let p = Path::new("st.json");
        assert!(s.check_resume("abc", Mode::Split, p).is_ok());
        assert!(
            s.check_resume("abd", Mode::Split, p)
                .unwrap_err()
                .contains("another program")
        );
        assert!(
            s.check_resume("abc", Mode::Rotary, p)
                .unwrap_err()
                .contains("split mode")
        );
        let mut done = s.clone();
        done.next_move = 6;
        let v = SendSummary::finished(&done).to_json(true);
        assert_eq!(v["ok"], true);
        assert_eq!(v["final_counter"], 5);
        assert_eq!(v["mode"], "split");
    }
}
