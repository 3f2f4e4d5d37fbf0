//! Upload, run and watch a job on a controller, chunk by chunk or through
//! a rotary buffer, stopping safely on any fault.
//!
//! Safety rule: whatever goes wrong (ERR reply, timeout, lost link, Ctrl-C,
//! a program that ends before its last line), the shutter is closed and the
//! coordinate system aborted on the existing link or a new one, and a
//! resume state is written naming the chunks confirmed complete. A chunk is
//! confirmed only by what the controller reports (the line counter read
//! back, and not running), never by what was sent.

use crate::pmac::client::{Client, ClientError, DownloadError};
use crate::pmac::controller::parse_status;
use crate::pmac::plan::{Chunk, Names, marker_lines};
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
    pub fn name(self) -> &'static str {
        match self {
            Mode::Program => "program",
            Mode::Split => "split",
            Mode::Rotary => "rotary",
        }
    }
}

#[derive(Debug, Clone)]
pub struct SendOptions {
    pub mode: Mode,
    /// Program buffer number for program and split modes.
    pub prog: u32,
    /// Rotary buffer size, words (`DEFINE ROT`).
    pub rotary_words: usize,
    /// Fill the rotary buffer up to this fraction of its size.
    pub rotary_fill: f64,
    /// Time between status polls.
    pub poll: Duration,
    /// Give up when nothing changes on the controller for this long.
    pub stall: Duration,
    /// Blocks the controller may calculate ahead of motion: a rotary chunk
    /// counts as done only when the counter is this far past its end.
    pub lookahead: u64,
    pub names: Names,
    /// Where the resume state goes.
    pub state_path: PathBuf,
    /// Program mode: store the program, do not run it (benchmarks,
    /// downloads checked by hand before running).
    pub upload_only: bool,
}

/// The resume state, written after every confirmed chunk and on a stop.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct State {
    pub version: u32,
    /// FNV-1a of the input text: resume refuses another program.
    pub input_hash: String,
    pub mode: Mode,
    /// Word budget the chunks were cut with (so resume cuts the same).
    pub budget: Option<usize>,
    pub chunks: usize,
    /// Chunks confirmed complete, in order: resume starts at this index.
    pub chunks_done: usize,
    pub last_counter: u64,
    /// Why the last session stopped (absent when it finished).
    pub stopped: Option<String>,
}

impl State {
    pub fn load(path: &Path) -> Result<State, SendError> {
        let text = std::fs::read_to_string(path).map_err(|e| SendError::State(format!("{}: {e}", path.display())))?;
        serde_json::from_str(&text).map_err(|e| SendError::State(format!("{}: {e}", path.display())))
    }

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

#[derive(Debug, Error)]
pub enum SendError {
    #[error("{0}")]
    Client(#[from] ClientError),
    #[error("{0}")]
    Download(#[from] DownloadError),
    #[error("interrupted")]
    Interrupted,
    #[error("no progress on the controller for {0:?} (line counter {1})")]
    Stalled(Duration, u64),
    #[error("program ended at line counter {got}, expected {want} (controller reset or program error)")]
    Incomplete { got: u64, want: u64 },
    #[error("the job needs {need} words, the controller has {free} free: use --mode split or rotary")]
    TooBig { need: usize, free: i64 },
    #[error("bad reply '{0}'")]
    BadReply(String),
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

/// `&1??`, the line counter and the done marker: (running, in position,
/// counter, chunks done).
type Polled = (bool, bool, u64, u64);

/// A counter variable's value as a count (negative or junk: 0).
fn count(s: &str) -> Result<u64, SendError> {
    let v = s
        .trim()
        .parse::<f64>()
        .map_err(|_| SendError::BadReply(s.to_string()))?;
    Ok(if v.is_finite() && v > 0.0 { v as u64 } else { 0 })
}

/// What a session did, printed as JSON at the end.
#[derive(Debug, Clone, Serialize, Default)]
pub struct Summary {
    pub mode: String,
    pub chunks: usize,
    /// First chunk this session ran (non-zero after --resume).
    pub first_chunk: usize,
    pub chunks_run: usize,
    pub lines_sent: u64,
    pub requests: u64,
    pub final_counter: u64,
    /// A beam-off rapid to the resumed chunk's start was added.
    pub repositioned: bool,
    pub upload_seconds: f64,
    pub seconds: f64,
    pub estimated_run_seconds: f64,
}

/// A failed session: the error, what the safety stop did, and the state.
#[derive(Debug)]
pub struct Failure {
    pub error: SendError,
    pub safe_stop: Result<(), String>,
    pub state: State,
    pub summary: Summary,
}

pub struct Sender<'a> {
    client: Option<Client>,
    host: String,
    transport: crate::pmac::client::Transport,
    timeout: Duration,
    opts: SendOptions,
    stop: Arc<AtomicBool>,
    progress: &'a mut dyn Write,
    summary: Summary,
    last_note: Instant,
}

impl<'a> Sender<'a> {
    pub fn new(
        client: Client,
        host: &str,
        timeout: Duration,
        opts: SendOptions,
        stop: Arc<AtomicBool>,
        progress: &'a mut dyn Write,
    ) -> Self {
        Sender {
            transport: client.transport(),
            client: Some(client),
            host: host.to_string(),
            timeout,
            opts,
            stop,
            progress,
            summary: Summary::default(),
            last_note: Instant::now() - Duration::from_secs(10),
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

    /// Free words after clearing program `prog` and the gather buffer.
    pub fn free_words(&mut self) -> Result<i64, SendError> {
        let prog = self.opts.prog;
        self.cmd("CLOSE")?;
        self.cmd("DELETE GATHER")?;
        self.cmd(&format!("OPEN PROG {prog} CLEAR"))?;
        self.cmd("CLOSE")?;
        let r = self.cmd("SIZE")?;
        let s = r.first().cloned().unwrap_or_default();
        s.trim().parse::<i64>().map_err(|_| SendError::BadReply(s))
    }

    /// `&1?? P400 P401` in one request: (running, in position, counter,
    /// chunks marked done).
    fn poll(&mut self) -> Result<Polled, SendError> {
        let q = format!("&1?? {} {}", self.opts.names.counter, self.opts.names.done);
        let r = self.cmd(&q)?;
        let (Some(st), Some(cnt), Some(done)) = (r.first(), r.get(1), r.get(2)) else {
            return Err(SendError::BadReply(r.join(" ")));
        };
        let (run, inpos) = parse_status(st).ok_or_else(|| SendError::BadReply(st.clone()))?;
        Ok((run, inpos, count(cnt)?, count(done)?))
    }

    /// Run the chunks from `state.chunks_done` on; `state` is updated and
    /// saved after each confirmed chunk.
    pub fn run(mut self, chunks: &[Chunk], state: &mut State) -> Result<Summary, Box<Failure>> {
        let t0 = Instant::now();
        self.summary.mode = self.opts.mode.name().into();
        self.summary.chunks = chunks.len();
        self.summary.first_chunk = state.chunks_done;
        self.summary.estimated_run_seconds = chunks.iter().skip(state.chunks_done).map(|c| c.seconds).sum();
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
                let link = error.is_link();
                let (safe_stop, status) = self.safe_stop(link);
                // What the controller says decides what is complete.
                if let Some((_, _, counter, done)) = status {
                    confirm(chunks, state, counter, done, self.opts.mode, self.opts.lookahead);
                }
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

    /// Close the shutter and abort (for a failure outside [`Sender::run`]).
    pub fn stop_safely(&mut self, link_failed: bool) -> Result<(), String> {
        self.safe_stop(link_failed).0
    }

    /// Close the shutter and abort, on the current link or a new one.
    /// Returns the status read first (before the abort) when it could.
    fn safe_stop(&mut self, link_failed: bool) -> (Result<(), String>, Option<Polled>) {
        if link_failed || self.client.is_none() {
            self.client = None;
            // Bounded: a few tries, each with the client timeout.
            let mut last = String::new();
            for _ in 0..3 {
                match Client::connect(&self.host, self.transport, self.timeout) {
                    Ok(c) => {
                        self.client = Some(c);
                        break;
                    }
                    Err(e) => {
                        last = e.to_string();
                        std::thread::sleep(Duration::from_millis(200));
                    }
                }
            }
            if self.client.is_none() {
                return (
                    Err(format!("could not reach the controller to close the shutter: {last}")),
                    None,
                );
            }
        }
        let status = self.poll().ok();
        let shutter = format!("{}=0", self.opts.names.shutter);
        // CLOSE first so the shutter command is not stored in an open
        // buffer; the shutter again after the abort, in case the program
        // opened it in its last calculated line.
        let mut res = Ok(());
        for cmd in ["CLOSE", &shutter, "&1A", &shutter] {
            if let Err(e) = self.cmd(cmd) {
                res = Err(format!("'{cmd}' failed: {e}"));
            }
        }
        // A chunk that ended between the first poll and the abort set its
        // done marker; read it again so it is not run twice.
        let status = self.poll().ok().or(status);
        (res, status)
    }

    fn save(&mut self, state: &State) -> Result<(), SendError> {
        state.save(&self.opts.state_path)
    }

    fn chunk_lines(&mut self, c: &Chunk, reposition: bool, number: usize) -> Vec<String> {
        let mut lines = c.lines.clone();
        if self.opts.mode != Mode::Rotary {
            lines.extend(marker_lines(&self.opts.names.done, number));
        }
        if reposition {
            // After an interrupted chunk the stage is not where this chunk
            // starts: go there with the beam off (the header closed it).
            let at = lines
                .iter()
                .position(|l| l.starts_with(&format!("{}=", self.opts.names.shutter)))
                .map_or(0, |p| p + 1);
            lines.insert(
                at,
                format!("RAPID X{:.4} Y{:.4} Z{:.4}", c.start[0], c.start[1], c.start[2]),
            );
            self.summary.repositioned = true;
        }
        lines
    }

    fn run_buffers(&mut self, chunks: &[Chunk], state: &mut State) -> Result<(), SendError> {
        let prog = self.opts.prog;
        let n = chunks.len();
        let start = state.chunks_done;
        if start == 0 {
            let (c, d) = (self.opts.names.counter.clone(), self.opts.names.done.clone());
            self.cmd(&format!("{c}=0 {d}=0"))?;
        }
        for (i, chunk) in chunks.iter().enumerate().skip(start) {
            self.check_stop()?;
            let reposition = i == start && i > 0;
            let lines = self.chunk_lines(chunk, reposition, i + 1);
            let t = Instant::now();
            self.cmd("CLOSE")?;
            self.cmd("DELETE GATHER")?;
            self.cmd(&format!("OPEN PROG {prog} CLEAR"))?;
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
            self.cmd(&format!("&1B{prog}R"))?;
            let (last, remaining): (u64, f64) = (chunk.last_counter, chunks[i + 1..].iter().map(|c| c.seconds).sum());
            let (got, done) = self.wait_done(i, n, chunk, remaining)?;
            if got < last || done < (i + 1) as u64 {
                return Err(SendError::Incomplete { got, want: last });
            }
            state.chunks_done = i + 1;
            state.last_counter = got;
            self.summary.chunks_run += 1;
            self.summary.final_counter = got;
            self.save(state)?;
        }
        Ok(())
    }

    /// Poll until the program is not running and in position.
    fn wait_done(&mut self, i: usize, n: usize, chunk: &Chunk, remaining: f64) -> Result<(u64, u64), SendError> {
        let mut last = (true, false, u64::MAX, u64::MAX);
        let mut changed = Instant::now();
        loop {
            self.check_stop()?;
            let s = self.poll()?;
            if s != last {
                last = s;
                changed = Instant::now();
            } else if changed.elapsed() > self.opts.stall {
                return Err(SendError::Stalled(self.opts.stall, s.2));
            }
            let (running, inpos, counter, done) = s;
            let span = (chunk.last_counter + 1).saturating_sub(chunk.first_counter).max(1) as f64;
            let done_frac = (counter.saturating_sub(chunk.first_counter - 1) as f64 / span).clamp(0.0, 1.0);
            let left = remaining + chunk.seconds * (1.0 - done_frac);
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

    fn run_rotary(&mut self, chunks: &[Chunk], state: &mut State) -> Result<(), SendError> {
        let start = state.chunks_done;
        // Every line with the chunk it belongs to.
        let mut lines: Vec<(usize, String)> = Vec::new();
        for (i, c) in chunks.iter().enumerate().skip(start) {
            let ls = self.chunk_lines(c, i == start && i > 0, i + 1);
            lines.extend(ls.into_iter().map(|l| (i, l)));
        }
        let words: Vec<usize> = lines
            .iter()
            .map(|(_, l)| crate::pmac::protocol::line_words(l))
            .collect();
        let final_counter = chunks.last().map_or(0, |c| c.last_counter);
        let cap = self.opts.rotary_words;
        let limit = ((cap as f64) * self.opts.rotary_fill.clamp(0.1, 1.0)) as usize;
        if let Some(w) = words.iter().find(|&&w| w > limit) {
            return Err(SendError::TooBig {
                need: *w,
                free: limit as i64,
            });
        }
        if start == 0 {
            let c = self.opts.names.counter.clone();
            self.cmd(&format!("{c}=0"))?;
        }
        self.cmd("CLOSE")?;
        self.cmd("DELETE GATHER")?;
        self.cmd("&1 DELETE ROT")?;
        self.cmd(&format!("&1 DEFINE ROT {cap}"))?;
        self.cmd("&1 B0")?;
        self.cmd("OPEN ROT")?;
        let mut sent = 0usize;
        let mut queued = 0usize; // lines the controller reports waiting (PR)
        let mut started = false;
        let mut last = (false, false, u64::MAX, usize::MAX);
        let mut changed = Instant::now();
        let n = chunks.len();
        loop {
            self.check_stop()?;
            // Words still waiting: the last `queued` lines sent.
            let waiting: usize = words[sent.saturating_sub(queued)..sent].iter().sum();
            let mut end = sent;
            let mut room = limit.saturating_sub(waiting);
            while end < lines.len() && words[end] <= room && end - sent < 200 {
                room -= words[end];
                end += 1;
            }
            if end > sent {
                let batch: Vec<&str> = lines[sent..end].iter().map(|(_, l)| l.as_str()).collect();
                let t = Instant::now();
                self.c()?.write_lines(&batch)?;
                self.summary.upload_seconds += t.elapsed().as_secs_f64();
                self.summary.lines_sent += batch.len() as u64;
                sent = end;
            }
            if !started {
                self.cmd("&1R")?;
                started = true;
                self.note(true, || {
                    format!("rotary: running, {sent} of {} lines queued", lines.len())
                });
            }
            let q = format!("PR &1?? {}", self.opts.names.counter);
            let r = self.cmd(&q)?;
            let (Some(pr), Some(st), Some(cnt)) = (r.first(), r.get(1), r.get(2)) else {
                return Err(SendError::BadReply(r.join(" ")));
            };
            queued = pr.trim().parse().map_err(|_| SendError::BadReply(pr.clone()))?;
            let (running, inpos) = parse_status(st).ok_or_else(|| SendError::BadReply(st.clone()))?;
            let counter = count(cnt)?;
            let cur_chunk = lines.get(sent.saturating_sub(queued + 1)).map_or(n, |(i, _)| *i + 1);
            self.summary.final_counter = counter;
            let (var, total) = (self.opts.names.counter.clone(), lines.len());
            self.note(false, || {
                format!(
                    "rotary: chunk {cur_chunk}/{n}, {sent}/{total} lines sent, {queued} queued, \
                     {var} = {counter} of {final_counter}"
                )
            });
            let s = (running, inpos, counter, queued);
            if s != last {
                last = s;
                changed = Instant::now();
            } else if changed.elapsed() > self.opts.stall {
                return Err(SendError::Stalled(self.opts.stall, counter));
            }
            confirm(chunks, state, counter, 0, Mode::Rotary, self.opts.lookahead);
            if sent == lines.len() && queued == 0 && inpos {
                if counter < final_counter {
                    if !running {
                        return Err(SendError::Incomplete {
                            got: counter,
                            want: final_counter,
                        });
                    }
                } else {
                    break;
                }
            } else if !running {
                return Err(SendError::Incomplete {
                    got: counter,
                    want: final_counter,
                });
            }
            if end == sent && sent < lines.len() || sent == lines.len() {
                std::thread::sleep(self.opts.poll);
            }
        }
        self.cmd("CLOSE")?;
        self.cmd("&1Q")?;
        self.cmd("&1 DELETE ROT")?;
        state.chunks_done = chunks.len();
        state.last_counter = final_counter;
        self.summary.chunks_run = chunks.len() - start;
        self.save(state)?;
        Ok(())
    }
}

/// Mark chunks complete from what the controller reports.
fn confirm(chunks: &[Chunk], state: &mut State, counter: u64, done: u64, mode: Mode, lookahead: u64) {
    let mut k = state.chunks_done;
    while let Some(c) = chunks.get(k) {
        let ok = match mode {
            // The done marker runs after DWELL0: all motion has ended.
            Mode::Program | Mode::Split => done > k as u64,
            // In a stream, later lines may be calculated ahead of motion.
            Mode::Rotary => counter >= c.last_counter + lookahead,
        };
        if !ok {
            break;
        }
        k += 1;
        state.last_counter = c.last_counter;
    }
    state.chunks_done = k;
}
