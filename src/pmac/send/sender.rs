//! One session on one controller: download, run, watch the counters, and
//! stop safely on any fault.

use super::{
    Failure, Mode, POSITION_TOL_MM, Reading, SafeStopError, SendError, SendOptions, SendSummary, State, locate,
    open_program,
};
use crate::geometry::P3;
use crate::pmac::client::{Client, ClientError};
use crate::pmac::controller::parse_status;
use crate::pmac::upload_plan::{Chunk, MoveGeom, marker_lines};
use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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
            // Progress (the tool's bar): moves confirmed executed.
            crate::progress::set(c as u64);
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
                    failure.safe_stop = failure.safe_stop.and(Err(SafeStopError::StateSave(e.to_string())));
                }
                failure.state = state.clone();
                Err(Box::new(failure))
            }
        }
    }

    /// Stop safely, then take from the controller where the job stopped
    /// (when its counters are this job's) and save it in the state.
    pub fn recover(&mut self, state: &mut State, link_failed: bool) -> Result<(), SafeStopError> {
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
            .map_err(|e| SafeStopError::StateNotSaved(e.to_string()))
    }

    /// Close the shutter, abort, flush queued synchronous assignments, and
    /// keep at it, reconnecting, until the controller confirms the program
    /// is not running and the shutter is closed, or the stop deadline
    /// passes. Each reply may take [`SendOptions::stop_timeout`].
    fn secure(&mut self, link_failed: bool) -> Result<Reading, SafeStopError> {
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
                return Err(SafeStopError::Unconfirmed {
                    deadline: self.opts.stop_deadline,
                    last,
                });
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
        let mut watch = StallWatch::new(self.opts.stall);
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
            watch.see((running, inpos, counter, done), counter)?;
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
        let mut watch = StallWatch::new(self.opts.stall);
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
            watch.see((running, inpos, counter, queued as u64), counter)?;
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

/// What a polling loop last saw of the controller (running, in position,
/// line counter, and the loop's own progress figure) and since when: the
/// same state for longer than the stall time is a stall.
struct StallWatch {
    stall: Duration,
    last: Option<(bool, bool, f64, u64)>,
    changed: Instant,
}

impl StallWatch {
    fn new(stall: Duration) -> StallWatch {
        StallWatch {
            stall,
            last: None,
            changed: Instant::now(),
        }
    }

    /// Record one poll's state; an error once it has not changed for
    /// longer than the stall time (`counter` is reported with it).
    fn see(&mut self, state: (bool, bool, f64, u64), counter: f64) -> Result<(), SendError> {
        if Some(state) != self.last {
            self.last = Some(state);
            self.changed = Instant::now();
            Ok(())
        } else if self.changed.elapsed() > self.stall {
            Err(SendError::Stalled(self.stall, counter as u64))
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_unchanged_past_the_stall_time_is_a_stall_and_any_change_resets_it() {
        let mut w = StallWatch::new(Duration::from_millis(30));
        let s = (true, false, 3.0, 7);
        w.see(s, 3.0).unwrap();
        std::thread::sleep(Duration::from_millis(40));
        // Moving on (the counter advanced) is never a stall.
        w.see((true, false, 4.0, 7), 4.0).unwrap();
        w.see((true, false, 4.0, 7), 4.0).unwrap();
        std::thread::sleep(Duration::from_millis(40));
        match w.see((true, false, 4.0, 7), 4.0) {
            Err(SendError::Stalled(d, 4)) => assert_eq!(d, Duration::from_millis(30)),
            other => panic!("{other:?}"),
        }
    }
}
