//! The resume state, and where in the job a stopped stage is.

use super::{Mode, ResumeRefused, SendError};
use crate::geometry::P3;
use crate::pmac::upload_plan::MoveGeom;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

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
    pub fn check_resume(&self, input_hash: &str, mode: Mode, path: &Path) -> Result<(), ResumeRefused> {
        if self.input_hash != input_hash {
            return Err(ResumeRefused::OtherProgram {
                state: path.display().to_string(),
            });
        }
        if self.mode != mode {
            return Err(ResumeRefused::OtherMode {
                state: path.display().to_string(),
                mode: self.mode.name(),
            });
        }
        Ok(())
    }

    /// Read a state file.
    pub fn load(path: &Path) -> Result<State, SendError> {
        let text = std::fs::read_to_string(path).map_err(|e| SendError::State(format!("{}: {e}", path.display())))?;
        State::from_json(&text, &path.display().to_string())
    }

    /// Parse a state file's text (`name` for messages) and check that it
    /// describes a place in a job: layout version 2, `1 <= next_move <=
    /// moves + 1`, a finite `resume_at` only on a move of the job, a
    /// session number. The file is ours, but it may have been cut short,
    /// edited or swapped; resuming from a state that says less than it
    /// seems would skip or repeat cuts, so it is refused with the reason.
    pub fn from_json(text: &str, name: &str) -> Result<State, SendError> {
        let s: State = serde_json::from_str(text).map_err(|e| SendError::State(format!("{name}: {e}")))?;
        let bad = |why: String| Err(SendError::State(format!("{name}: {why}; not resuming from it")));
        if s.version != 2 {
            return bad(format!("layout version {} (this pmac-send writes 2)", s.version));
        }
        if s.next_move == 0 || s.next_move > s.moves.saturating_add(1) {
            return bad(format!(
                "next move {} is outside the job's {} moves",
                s.next_move, s.moves
            ));
        }
        if let Some(a) = s.resume_at {
            if !a.iter().all(|v| v.is_finite()) {
                return bad("resume point is not finite".into());
            }
            if s.next_move > s.moves {
                return bad("a resume point on a finished job".into());
            }
        }
        if s.session == 0 {
            return bad("session number 0 (sessions count from 1)".into());
        }
        if s.budget == Some(0) {
            return bad("word budget 0".into());
        }
        Ok(s)
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
