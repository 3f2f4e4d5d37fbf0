//! On-line commands: the text of a download file outside its buffers,
//! which a controller executes as it arrives (`&1B1R`, `I5213,15,100=10`,
//! `M1->Y:$78800,0`, `#1->10000X`, `DELETE GATHER`, `UNDEFINE ALL`).
//!
//! None of them is refused. P, Q and M assignments (also over ranges) are
//! applied: the program's expressions read the values, and the shutter
//! variable sets the beam the program starts with. I-variables are stored
//! the same way (so `I130` in an expression reads them), with a note that
//! the controller setting itself is not modelled. Everything else is noted
//! and ignored, except the routine download and run sequence (`&1`,
//! `B1R`, `DELETE GATHER`, `DEFINE ROT n`), which is silent: motor
//! addressing, axis and M-variable
//! definitions, buffer management, queries, and text that is no command
//! (such as a name no `#define` gives). A move-mode word outside a buffer
//! (`LINEAR`, `RAPID`, `CIRCLE`) stays an error: it is program text that
//! the file leaves out of every program.

use super::expr::{VAR_MAX, Var, VarKind};
use super::lexer::{Cursor, is_ws};
use super::{GcodeError, PmacInterpreter};
use crate::model::toolpath::ShutterSwitch;

/// On-line words that manage buffers and set-up; their arguments run to the
/// next command.
const SETUP_WORDS: &[&str] = &[
    "DELETE", "DEL", "DEFINE", "DEF", "UNDEFINE", "UNDEF", "ENABLE", "ENA", "DISABLE", "DIS", "SAVE", "RESET", "CLEAR",
    "CLR", "LIST", "SIZE", "VERSION", "VER", "TYPE", "PASSWORD",
];

/// End of the command at `from`: the next blank, `;` or end of line.
fn command_end(cur: &Cursor, from: usize) -> usize {
    let mut j = from;
    while cur.b.get(j).is_some_and(|&c| !is_ws(c) && c != b';') {
        j += 1;
    }
    j
}

/// The first word of a line is one only an on-line command starts with
/// (besides `&`, `#`, `Mn->` and ranges, which the caller checks).
pub(super) fn is_setup_word(run: &[u8]) -> bool {
    run.eq_ignore_ascii_case(b"CLOSE") || SETUP_WORDS.iter().any(|w| run.eq_ignore_ascii_case(w.as_bytes()))
}

impl PmacInterpreter {
    /// Execute the on-line commands from the cursor to the end of the line,
    /// or up to an `OPEN`, which opens its buffer and returns (the caller
    /// reads the rest of the line in the new state).
    pub(super) fn online(&mut self, cur: &mut Cursor, lineno: u64) -> Result<(), GcodeError> {
        loop {
            cur.skip_ws();
            let Some(c) = cur.peek() else {
                return Ok(());
            };
            if c == b';' {
                cur.i = cur.b.len();
                return Ok(());
            }
            let start = cur.i;
            match c {
                b'&' => {
                    cur.i += 1;
                    cur.skip_ws();
                    match cur.uint() {
                        // Part of the routine run sequence (`&1B1R`): silent.
                        Some(_) => {}
                        None => {
                            let end = command_end(cur, start);
                            self.note(
                                lineno,
                                format!("'{}': no coordinate system number; ignored", slice(cur, start, end)),
                            );
                            cur.i = end;
                        }
                    }
                }
                b'#' => {
                    let end = command_end(cur, start);
                    let text = slice(cur, start, end);
                    cur.i = end;
                    let what = if text.contains("->") {
                        "motor axis definition; noted only (the program is read in axis units)"
                    } else {
                        "motor command; ignored"
                    };
                    self.note(lineno, format!("{text}: {what}"));
                }
                c if c.is_ascii_alphabetic() => {
                    let end = cur.letters_end(start);
                    let run = cur.b.get(start..end).unwrap_or(&[]);
                    let next = cur.b.get(end).copied();
                    let is_var = run.len() == 1 && next.is_some_and(|n| n.is_ascii_digit() || n == b'(');
                    if let (true, Some(kind)) = (is_var, VarKind::from_letter(c)) {
                        cur.i = end;
                        if !self.online_var(kind, start, cur, lineno)? {
                            return Ok(());
                        }
                        continue;
                    }
                    let is = |w: &str| run.eq_ignore_ascii_case(w.as_bytes());
                    if is("OPEN") {
                        cur.i = end;
                        return self.open(cur, lineno);
                    }
                    if is("CLOSE") {
                        cur.i = end;
                        self.close(lineno)?;
                        continue;
                    }
                    let starts = |w: &str| run.get(..w.len()).is_some_and(|p| p.eq_ignore_ascii_case(w.as_bytes()));
                    if ["LINEAR", "RAPID", "CIRCLE"].into_iter().any(starts)
                        || ["LIN", "RPD", "CIR"].into_iter().any(is)
                    {
                        return Err(GcodeError::at(
                            lineno,
                            format!(
                                "'{}' after CLOSE and before the next OPEN: motion outside a program buffer \
                                 is not part of the program",
                                cur.snippet(start)
                            ),
                        ));
                    }
                    if SETUP_WORDS.iter().any(|w| is(w)) {
                        // The word, its object (GATHER, PLC, ALL, ROT ...)
                        // and any numbers after it.
                        cur.i = end;
                        cur.skip_ws();
                        cur.i = cur.letters_end(cur.i);
                        while cur
                            .peek()
                            .is_some_and(|c| is_ws(c) || c.is_ascii_digit() || c == b',' || c == b'.')
                        {
                            cur.i += 1;
                        }
                        let text = slice(cur, start, cur.i).trim_end().to_string();
                        if !is_routine_download(&text) {
                            self.note(
                                lineno,
                                format!("{text}: on-line buffer or set-up command; nothing to simulate"),
                            );
                        }
                        continue;
                    }
                    if run.len() == 1 {
                        // B1R, R, A, J/, H ...: controller commands.
                        let end = command_end(cur, start);
                        let text = slice(cur, start, end).to_string();
                        cur.i = end;
                        // B1R, R, A, Q: the routine run sequence, silent.
                        if !text.bytes().all(|c| c.is_ascii_digit() || b"BRAQSHbraqsh".contains(&c)) {
                            self.note(
                                lineno,
                                format!("{text}: on-line command; ignored (not part of a program)"),
                            );
                        }
                        continue;
                    }
                    self.note_rest(cur, start, lineno);
                    return Ok(());
                }
                _ => {
                    self.note_rest(cur, start, lineno);
                    return Ok(());
                }
            }
        }
    }

    /// The rest of the line is no command this reader knows: a note, and
    /// the line is done.
    fn note_rest(&mut self, cur: &mut Cursor, start: usize, lineno: u64) {
        let text = cur.text.get(start..).unwrap_or("");
        let text = text.split(';').next().unwrap_or("").trim_end().to_string();
        cur.i = cur.b.len();
        let hint = if text.contains("$(") {
            " ($(NAME) is a template macro left unexpanded: expand the template (EPICS msi) first)"
        } else if text
            .as_bytes()
            .first()
            .is_some_and(|c| c.is_ascii_alphabetic() || *c == b'_')
        {
            " (a name no #define gives? its header file is not #included)"
        } else {
            ""
        };
        self.note(
            lineno,
            format!("'{text}': not an on-line command this reader knows{hint}; ignored"),
        );
    }

    /// A P/Q/M/I word on-line, the cursor after its letter: an assignment
    /// (`P10=5`, `I5213,15,100=10`, `P1..8=0`), an M-variable definition
    /// (`M1->Y:$78800,0`) or a query (`I130`). Returns false when the rest
    /// of the line was consumed.
    fn online_var(&mut self, kind: VarKind, start: usize, cur: &mut Cursor, lineno: u64) -> Result<bool, GcodeError> {
        let letter = kind.letter();
        // The first variable: a number or an (expression).
        let first = if cur.eat(b'(') {
            match self.vars.expr(cur, 1, lineno) {
                Ok(v) if cur.eat(b')') && v >= 0.0 && v <= f64::from(VAR_MAX) => v as u32,
                Ok(_) | Err(_) => {
                    self.note_unapplied(cur, start, lineno, "its variable number is not one");
                    return Ok(false);
                }
            }
        } else {
            match cur.uint() {
                Some(n) if n <= u64::from(VAR_MAX) => n as u32,
                _ => {
                    self.note_unapplied(cur, start, lineno, &format!("{letter} numbers go to {VAR_MAX}"));
                    return Ok(false);
                }
            }
        };
        // Range: `,count[,step]` or `..last`.
        let (mut count, mut step) = (1u64, 1u64);
        if cur.eat(b',') {
            count = cur.uint().unwrap_or(0);
            if cur.eat(b',') {
                step = cur.uint().unwrap_or(0);
            }
        } else if cur.peek() == Some(b'.') && cur.peek_at(1) == Some(b'.') {
            cur.i += 2;
            let last = cur.uint().unwrap_or(0);
            count = last.saturating_add(1).saturating_sub(u64::from(first));
        }
        cur.skip_ws();
        if cur.peek() == Some(b'-') && cur.peek_at(1) == Some(b'>') {
            let end = command_end(cur, start);
            let text = slice(cur, start, end).to_string();
            cur.i = end;
            self.note(
                lineno,
                format!("{text}: {letter}-variable definition; noted only (its value, if assigned, is kept)"),
            );
            return Ok(true);
        }
        if !(cur.peek() == Some(b'=') && cur.peek_at(1) != Some(b'=')) {
            let text = slice(cur, start, cur.i).trim_end().to_string();
            self.note(lineno, format!("{text}: query; no effect"));
            return Ok(true);
        }
        cur.i += 1;
        let value = match self.vars.expr(cur, 0, lineno) {
            Ok(v) if v.is_finite() => v,
            Ok(_) => {
                self.note_unapplied(cur, start, lineno, "the value is not a finite number");
                return Ok(false);
            }
            Err(e) => {
                let msg = match &e {
                    GcodeError::Invalid { msg, .. } => msg.clone(),
                    other => other.to_string(),
                };
                self.note_unapplied(cur, start, lineno, &msg);
                return Ok(false);
            }
        };
        // Saturating: a count or step of 20 digits must land past VAR_MAX
        // (and be refused), not wrap round to a small last variable.
        let last = u64::from(first).saturating_add(count.saturating_sub(1).saturating_mul(step));
        if count == 0 || step == 0 || last > u64::from(VAR_MAX) {
            self.note_unapplied(
                cur,
                start,
                lineno,
                &format!("the range is empty or runs past {letter}{VAR_MAX}"),
            );
            return Ok(false);
        }
        for k in 0..count {
            let var = Var {
                kind,
                index: (u64::from(first) + k * step) as u32,
            };
            self.vars.set(var, value);
            if Some(var) == self.shutter {
                // The shutter as the program will find it.
                self.beam = value != 0.0;
                self.moved_beam = self.beam;
                self.last_switch = ShutterSwitch::Immediate;
            }
        }
        if kind == VarKind::I {
            let text = slice(cur, start, cur.i).trim_end().to_string();
            let which = if count == 1 {
                format!("{letter}{first}")
            } else {
                format!("{letter}{first}..{letter}{last} ({count} variables, step {step})")
            };
            self.note(
                lineno,
                format!(
                    "{text}: {which} = {value} stored; the controller setting is not modelled (no effect on the toolpath)"
                ),
            );
        }
        Ok(true)
    }

    /// An assignment that cannot be applied: a note with the reason, and
    /// the rest of the line skipped.
    fn note_unapplied(&mut self, cur: &mut Cursor, start: usize, lineno: u64, why: &str) {
        let text = cur.text.get(start..).unwrap_or("");
        let text = text.split(';').next().unwrap_or("").trim_end().to_string();
        cur.i = cur.b.len();
        let hint = if text.contains("$(") {
            "; $(NAME) is a template macro left unexpanded: expand the template (EPICS msi) first"
        } else {
            ""
        };
        self.note(lineno, format!("'{text}': not applied ({why}){hint}; ignored"));
    }
}

/// The safe download sequence (`DELETE GATHER`, `DEFINE ROT n`,
/// `DELETE ROT`), sent before every program: silent, not noted.
fn is_routine_download(text: &str) -> bool {
    let mut w = text.split_whitespace().map(str::to_ascii_uppercase);
    let (Some(verb), Some(object)) = (w.next(), w.next()) else {
        return false;
    };
    matches!(verb.as_str(), "DELETE" | "DEL" | "DEFINE" | "DEF")
        && matches!(object.as_str(), "GATHER" | "GAT" | "ROT" | "ROTARY")
}

fn slice<'a>(cur: &Cursor<'a>, from: usize, to: usize) -> &'a str {
    cur.text.get(from..to).unwrap_or("")
}
