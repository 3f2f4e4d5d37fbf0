//! The buffer structure of a download file: `OPEN PROG n` / `OPEN ROT` /
//! `OPEN PLC n` ... `CLOSE`, and which motion program is the one read.
//!
//! A file may hold several programs; a controller runs one at a time
//! (`&1B10R`), so one is read: `PROG n` when [`ReadOptions::pmac_program`]
//! (gsim's `--program n`) names it, otherwise the first motion buffer in
//! the file (`OPEN PROG` or `OPEN ROT`). The others, and every PLC and
//! kinematic buffer (`OPEN PLC`, `OPEN FORWARD`, `OPEN INVERSE`, ...), are
//! skipped to their `CLOSE` with a note.
//!
//! [`ReadOptions::pmac_program`]: crate::gcode::ReadOptions::pmac_program

use super::lexer::Cursor;
use super::{Buffer, GcodeError, PmacInterpreter};

impl PmacInterpreter {
    /// `OPEN` with the cursor after the word.
    pub(super) fn open(&mut self, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        if matches!(self.buffer, Buffer::Open | Buffer::Skip) {
            return Err(GcodeError::at(
                lineno,
                format!(
                    "OPEN while the buffer opened at line {} is still open (CLOSE missing)",
                    self.opened_at
                ),
            ));
        }
        cur.skip_ws();
        let start = cur.i;
        let end = cur.letters_end(start);
        let w = cur.b.get(start..end).unwrap_or(&[]);
        let word = cur.text.get(start..end).unwrap_or("").to_ascii_uppercase();
        cur.i = end;
        let is = |s: &str| w.eq_ignore_ascii_case(s.as_bytes());
        self.buffer = if is("PROG") || is("PROGRAM") {
            cur.skip_ws();
            let at = cur.i;
            let Some(n) = cur.uint() else {
                return Err(GcodeError::at(
                    lineno,
                    if cur.peek().is_some_and(|c| c.is_ascii_alphabetic() || c == b'_') {
                        format!(
                            "OPEN {word} {}: the program number is a name no #define gives \
                             (defined in a header file this one does not #include?)",
                            cur.snippet(at)
                        )
                    } else {
                        "OPEN PROG needs a program number".to_string()
                    },
                ));
            };
            self.choose(format!("PROG {n}"), Some(n), lineno)
        } else if is("ROT") || is("ROTARY") {
            self.choose("the rotary buffer (OPEN ROT)".into(), None, lineno)
        } else if ["PLC", "PLCC", "FORWARD", "FWD", "INVERSE", "INV", "BIN", "BINARY"]
            .iter()
            .any(|s| is(s))
        {
            let what = match word.as_str() {
                "PLC" | "PLCC" => "PLC program",
                "BIN" | "BINARY" => "binary buffer",
                _ => "kinematic subroutine",
            };
            let rest = cur.text.get(cur.i..).unwrap_or("");
            let rest = rest.split(';').next().unwrap_or("").trim();
            let label = if rest.is_empty() {
                word.clone()
            } else {
                format!("{word} {}", rest.split_whitespace().next().unwrap_or(""))
            };
            self.note(
                lineno,
                format!("OPEN {label}: {what} skipped to its CLOSE (not a motion program)"),
            );
            Buffer::Skip
        } else {
            return Err(GcodeError::at(
                lineno,
                format!("OPEN {}: expected OPEN PROG n or OPEN ROT", cur.snippet(start)),
            ));
        };
        self.opened_at = lineno;
        self.buffer_has_records = false;
        Ok(())
    }

    /// Whether the motion buffer `name` (`PROG n` when `number`) is the one
    /// read; the others are skipped with a note.
    fn choose(&mut self, name: String, number: Option<u64>, lineno: u64) -> Buffer {
        self.buffers_seen.push(name.clone());
        let wanted = match self.program_choice {
            Some(c) => number == Some(u64::from(c)),
            None => true,
        };
        match &self.program_read {
            None if wanted => {
                self.program_read = Some(name);
                Buffer::Open
            }
            read => {
                let why = match (self.program_choice, read) {
                    (Some(c), _) if !wanted => format!("--program {c} chooses PROG {c}"),
                    (_, Some(r)) => format!(
                        "only one program of a file is read, here {r}{}",
                        if self.program_choice.is_none() {
                            " (the first); choose another with --program N"
                        } else {
                            ""
                        }
                    ),
                    _ => String::new(),
                };
                self.note(lineno, format!("{name} skipped: {why}"));
                Buffer::Skip
            }
        }
    }

    /// `CLOSE` in any state.
    pub(super) fn close(&mut self, lineno: u64) -> Result<(), GcodeError> {
        match self.buffer {
            // CLOSE before any program text is the safe download preamble:
            // the file may still be a bare program, so stay in it.
            Buffer::Undecided => Ok(()),
            Buffer::Bare if self.buffer_has_records => Err(GcodeError::at(
                lineno,
                "CLOSE without OPEN: the program text above it is in no buffer (OPEN PROG n first)",
            )),
            Buffer::Bare => Ok(()),
            // Before the first OPEN a CLOSE is the preamble; a second CLOSE
            // after a buffer's is unbalanced.
            Buffer::Outside if self.opened_at == 0 => Ok(()),
            Buffer::Outside => Err(GcodeError::at(
                lineno,
                format!(
                    "CLOSE without OPEN: the buffer opened at line {} is closed already",
                    self.opened_at
                ),
            )),
            Buffer::Open | Buffer::Skip => {
                self.buffer = Buffer::Outside;
                Ok(())
            }
        }
    }

    /// End of the file in a download file: the program chosen must exist.
    pub(super) fn check_program_found(&mut self, lineno: u64) -> Result<(), GcodeError> {
        if self.buffer != Buffer::Outside || self.program_read.is_some() {
            return Ok(());
        }
        let seen = if self.buffers_seen.is_empty() {
            "none".to_string()
        } else {
            self.buffers_seen.join(", ")
        };
        match self.program_choice {
            Some(c) => Err(GcodeError::at(
                lineno,
                format!("--program {c}: the file has no OPEN PROG {c} (motion programs in it: {seen})"),
            )),
            None => {
                self.note(
                    lineno,
                    "no motion program (OPEN PROG or OPEN ROT) in the file: nothing to simulate",
                );
                Ok(())
            }
        }
    }
}
