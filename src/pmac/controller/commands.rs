//! The emulator's command interpreter: on-line commands, lines stored into
//! an open buffer, and control characters, each answered with data lines
//! or an ERR number.

use super::{
    COUNTS_PER_MM, Emulator, Open, Pointer, Program, QueuedLine, Rotary, Run, Session, Source, VARS, err, fmt_value,
    parse_mdef, status_word,
};
use crate::pmac::protocol::line_words;
use std::collections::VecDeque;

/// A tiny cursor over an upper-cased command line.
struct Cur<'a> {
    b: &'a [u8],
    i: usize,
}

impl<'a> Cur<'a> {
    fn ws(&mut self) {
        while self.i < self.b.len() && self.b[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }
    fn done(&mut self) -> bool {
        self.ws();
        self.i >= self.b.len()
    }
    fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }
    /// Consume `word` if it comes next (spaces inside commands optional).
    fn kw(&mut self, word: &str) -> bool {
        let save = self.i;
        self.ws();
        for &c in word.as_bytes() {
            if c == b' ' {
                self.ws();
                continue;
            }
            if self.peek() != Some(c) {
                self.i = save;
                return false;
            }
            self.i += 1;
        }
        true
    }
    fn int(&mut self) -> Option<u32> {
        self.ws();
        let s = self.i;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.i += 1;
        }
        std::str::from_utf8(&self.b[s..self.i]).ok()?.parse().ok()
    }
    fn number(&mut self) -> Option<f64> {
        self.ws();
        if self.peek() == Some(b'$') {
            self.i += 1;
            let s = self.i;
            while self.peek().is_some_and(|c| c.is_ascii_hexdigit()) {
                self.i += 1;
            }
            return i64::from_str_radix(std::str::from_utf8(&self.b[s..self.i]).ok()?, 16)
                .ok()
                .map(|v| v as f64);
        }
        let s = self.i;
        if matches!(self.peek(), Some(b'-' | b'+')) {
            self.i += 1;
        }
        while self.peek().is_some_and(|c| c.is_ascii_digit() || c == b'.') {
            self.i += 1;
        }
        let v: f64 = std::str::from_utf8(&self.b[s..self.i]).ok()?.parse().ok()?;
        v.is_finite().then_some(v)
    }
}

/// Words that only make sense inside a program buffer.
const PROGRAM_WORDS: &[&str] = &[
    "LINEAR", "LIN", "RAPID", "RPD", "CIRCLE", "CIR", "DWELL", "DELAY", "ABS", "INC", "NORMAL", "TA", "TS", "TM", "F",
    "X", "Y", "Z",
];

impl Emulator {
    /// Store one program line into the open buffer.
    fn store(&mut self, open: Option<Open>, text: &str) -> Result<(), u16> {
        let words = line_words(text) as i64;
        self.lines_stored += 1;
        if self.cfg.err006_at_line == Some(self.lines_stored) {
            self.cfg.err006_at_line = None;
            return Err(err::NO_ROOM);
        }
        let now = self.now();
        match open {
            Some(Open::Prog(n)) => {
                if self.free_words() < words {
                    return Err(err::NO_ROOM);
                }
                let p = self.programs.entry(n).or_default();
                p.lines.push(text.to_string());
                p.words += words;
                Ok(())
            }
            Some(Open::Rot) => {
                let Some(r) = self.rotary.as_mut() else {
                    return Err(err::NEEDS_OPEN_BUFFER);
                };
                if r.used + words > r.capacity {
                    return Err(err::NO_ROOM);
                }
                r.used += words;
                r.lines.push_back(QueuedLine {
                    text: text.to_string(),
                    words,
                    arrival: now,
                });
                Ok(())
            }
            None => Err(err::NEEDS_OPEN_BUFFER),
        }
    }

    /// Execute one command line as the controller would from any port and
    /// answer its data lines, or the ERR number of the first failing
    /// command (commands before it have taken effect, as on a controller).
    pub fn command_line(&mut self, sess: &mut Session, line: &str) -> Result<Vec<String>, u16> {
        self.advance();
        if sess.epoch != self.epoch {
            sess.epoch = self.epoch;
            sess.open = None;
            sess.cs = 1;
        }
        if !line.is_ascii() {
            return Err(err::ILLEGAL_CHAR);
        }
        let up = line.to_ascii_uppercase();
        // Strip a comment; the controller never stores it.
        let up = up.split(';').next().unwrap_or("").trim().to_string();
        if sess.open.is_some() {
            return self.buffered_line(sess, &up);
        }
        let mut out = Vec::new();
        let mut c = Cur { b: up.as_bytes(), i: 0 };
        while !c.done() {
            self.online_command(sess, &mut c, &mut out)?;
        }
        Ok(out)
    }

    /// A line while a buffer is open: a few on-line commands act at once,
    /// the rest is stored.
    fn buffered_line(&mut self, sess: &mut Session, up: &str) -> Result<Vec<String>, u16> {
        let compact: String = up.chars().filter(|c| !c.is_whitespace()).collect();
        if compact.is_empty() {
            return Ok(vec![]);
        }
        // On-line commands act at once even with a buffer open; the rest
        // of the line follows them on-line too (`PR &1?? P400`).
        const ONLINE: &[&str] = &[
            "SIZE", "VER", "CID", "PR", "??", "$$$", "&", "OPEN", "CLOSE", "MFLUSH", "#",
        ];
        let b = compact.as_bytes();
        let var_query =
            b.len() > 1 && matches!(b[0], b'P' | b'M' | b'I' | b'Q') && b[1..].iter().all(u8::is_ascii_digit);
        let online =
            ONLINE.iter().any(|w| compact.starts_with(w)) || ["A", "Q", "R"].contains(&compact.as_str()) || var_query;
        if online {
            let mut out = Vec::new();
            let mut c = Cur { b: up.as_bytes(), i: 0 };
            while !c.done() {
                self.online_command(sess, &mut c, &mut out)?;
            }
            return Ok(out);
        }
        // `... CLOSE` at the end of a program line: store, then close.
        if let Some(body) = compact.strip_suffix("CLOSE")
            && !body.is_empty()
        {
            let body = up.trim_end().strip_suffix("CLOSE").unwrap_or(up).trim_end();
            self.store(sess.open, body)?;
            sess.open = None;
            return Ok(vec![]);
        }
        if compact == "CLEAR" {
            match sess.open {
                Some(Open::Prog(n)) => {
                    self.programs.insert(n, Program::default());
                }
                Some(Open::Rot) => {
                    if let Some(r) = self.rotary.as_mut() {
                        r.lines.clear();
                        r.used = 0;
                    }
                }
                None => {}
            }
            return Ok(vec![]);
        }
        self.store(sess.open, up)?;
        Ok(vec![])
    }

    fn online_command(&mut self, sess: &mut Session, c: &mut Cur, out: &mut Vec<String>) -> Result<(), u16> {
        let running = self.run.is_some();
        if c.kw("OPEN PROG") {
            let n = c.int().ok_or(err::DATA)?;
            let clear = c.kw("CLEAR");
            if sess.open.is_some() {
                return Err(err::IN_USE);
            }
            if let Some(Run {
                source: Source::Prog { n: rn, .. },
                ..
            }) = &self.run
                && *rn == n
            {
                return Err(err::RUNNING);
            }
            if running {
                return Err(err::RUNNING);
            }
            sess.open = Some(Open::Prog(n));
            // Any OPEN PROG invalidates the coordinate system's pointer.
            self.pointer = None;
            let p = self.programs.entry(n).or_default();
            if clear {
                *p = Program::default();
            }
            return Ok(());
        }
        if c.kw("OPEN ROT") {
            if sess.open.is_some() {
                return Err(err::IN_USE);
            }
            if self.rotary.is_none() {
                return Err(err::DATA);
            }
            sess.open = Some(Open::Rot);
            return Ok(());
        }
        if c.kw("OPEN") {
            return Err(err::DATA);
        }
        if c.kw("CLOSE") {
            sess.open = None;
            return Ok(());
        }
        if c.kw("CLEAR") {
            return Err(err::NEEDS_OPEN_BUFFER);
        }
        if c.kw("DELETE GATHER") || c.kw("DEL GAT") {
            self.gather = 0;
            return Ok(());
        }
        if c.kw("DELETE ROT") || c.kw("DEL ROT") {
            if matches!(self.run.as_ref().map(|r| &r.source), Some(Source::Rot)) {
                return Err(err::RUNNING);
            }
            if sess.open == Some(Open::Rot) {
                return Err(err::IN_USE);
            }
            self.rotary = None;
            if self.pointer == Some(Pointer::Rot) {
                self.pointer = None;
            }
            return Ok(());
        }
        if c.kw("DEFINE ROT") || c.kw("DEF ROT") {
            let n = i64::from(c.int().ok_or(err::DATA)?);
            if running {
                return Err(err::RUNNING);
            }
            if self.rotary.is_some() {
                return Err(err::IN_USE);
            }
            if self.free_words() < n {
                return Err(err::NO_ROOM);
            }
            self.rotary = Some(Rotary {
                capacity: n,
                used: 0,
                lines: VecDeque::new(),
            });
            return Ok(());
        }
        if c.kw("DEFINE GATHER") || c.kw("DEF GAT") {
            let free = self.free_words();
            let n = c.int().map_or(free, i64::from);
            if n > free {
                return Err(err::NO_ROOM);
            }
            self.gather = n;
            return Ok(());
        }
        if c.kw("MFLUSH") {
            self.sync_left.clear();
            if let Some(r) = self.run.as_mut() {
                r.sync_pending.clear();
            }
            return Ok(());
        }
        if c.kw("SIZE") {
            let free = self.free_words();
            out.push(format!("{}", if sess.open.is_some() { -free } else { free }));
            return Ok(());
        }
        if c.kw("VER") {
            out.push("1.945  ".into());
            return Ok(());
        }
        if c.kw("CID") {
            out.push("603382".into());
            return Ok(());
        }
        if c.kw("TYPE") {
            out.push("TURBO2, X4".into());
            return Ok(());
        }
        if c.kw("SAVE") {
            return Ok(());
        }
        if c.kw("$$$") {
            self.reset();
            return Ok(());
        }
        if c.kw("???") {
            out.push(format!("{:06X}{:06X}", 0, 0));
            return Ok(());
        }
        if c.kw("??") {
            out.push(self.status(sess.cs));
            return Ok(());
        }
        if c.kw("PR") {
            let n = if sess.cs == 1 {
                self.rotary.as_ref().map_or(0, |r| r.lines.len())
            } else {
                0
            };
            out.push(n.to_string());
            return Ok(());
        }
        c.ws();
        match c.peek() {
            Some(b'&') => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)?;
                if !(1..=16).contains(&n) {
                    return Err(err::DATA);
                }
                sess.cs = n;
                Ok(())
            }
            Some(b'#') => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)?;
                if !(1..=8).contains(&n) {
                    return Err(err::DATA);
                }
                sess.motor = n;
                if c.kw("->") {
                    // Query only: X, Y, Z on motors 1-3.
                    out.push(match n {
                        1..=3 => format!("{}{}", fmt_value(COUNTS_PER_MM), ["X", "Y", "Z"][n as usize - 1]),
                        _ => "0".into(),
                    });
                }
                Ok(())
            }
            Some(b'P') if !c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                // Position of the addressed motor, counts.
                c.i += 1;
                let p = self.position();
                let v = match sess.motor {
                    1 => p.x,
                    2 => p.y,
                    3 => p.z,
                    _ => 0.0,
                };
                out.push(fmt_value((v * COUNTS_PER_MM * 10.0).round() / 10.0));
                Ok(())
            }
            Some(b'B') if c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit() || *d == b' ') => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)?;
                if running {
                    return Err(err::RUNNING);
                }
                self.cs1(sess)?;
                self.pointer = Some(if n == 0 { Pointer::Rot } else { Pointer::Prog(n) });
                Ok(())
            }
            Some(b'R') => {
                c.i += 1;
                self.cs1(sess)?;
                if running {
                    return Err(err::RUNNING);
                }
                if sess.open.is_some() && self.pointer != Some(Pointer::Rot) {
                    return Err(err::IN_USE);
                }
                let p = self.pointer.ok_or(err::BAD_POINTER)?;
                self.start_run(p)?;
                self.advance();
                Ok(())
            }
            Some(b'A') => {
                c.i += 1;
                self.abort();
                Ok(())
            }
            Some(b'Q') if !c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                c.i += 1;
                if let Some(r) = self.run.as_mut() {
                    r.quit = true;
                }
                self.advance();
                Ok(())
            }
            Some(l @ (b'I' | b'P' | b'Q' | b'M')) if c.b.get(c.i + 1).is_some_and(|d| d.is_ascii_digit()) => {
                c.i += 1;
                let n = c.int().ok_or(err::DATA)? as usize;
                if n >= VARS {
                    return Err(err::DATA);
                }
                if l == b'M' && c.kw("->") {
                    c.ws();
                    let s = c.i;
                    while c.peek().is_some_and(|d| !d.is_ascii_whitespace()) {
                        c.i += 1;
                    }
                    let def = std::str::from_utf8(&c.b[s..c.i]).unwrap_or("").to_string();
                    if def.is_empty() {
                        out.push(self.mdefs.get(&n).map_or("*".into(), |d| d.text.clone()));
                    } else if def == "*" {
                        self.mdefs.remove(&n);
                    } else {
                        self.mdefs.insert(n, parse_mdef(&def).ok_or(err::DATA)?);
                    }
                } else if c.kw("=") {
                    let v = c.number().ok_or(err::DATA)?;
                    let t = self.now();
                    self.set_var(l, n, v, t);
                } else {
                    out.push(fmt_value(self.var(l, n)));
                }
                Ok(())
            }
            _ => {
                if PROGRAM_WORDS.iter().any(|w| c.kw(w)) {
                    return Err(err::NEEDS_OPEN_BUFFER);
                }
                Err(err::DATA)
            }
        }
    }

    fn cs1(&self, sess: &Session) -> Result<(), u16> {
        if sess.cs == 1 { Ok(()) } else { Err(err::NO_MOTORS) }
    }

    fn status(&self, cs: u32) -> String {
        if cs != 1 {
            return status_word(false, true);
        }
        status_word(self.running(), self.in_position())
    }

    /// Answer a control character (VR_CTRL_RESPONSE / on-line ^G etc.).
    pub fn control(&mut self, ch: u8) -> Result<Vec<String>, u16> {
        self.advance();
        match ch {
            // ^B / ^C: coordinate system and motor status words.
            0x02 | 0x03 => Ok(vec![self.status(1)]),
            // ^G: global status.
            0x07 => Ok(vec![format!("{:06X}{:06X}", 0, 0)]),
            // ^P positions, ^F following errors, ^V velocities (motors 1-3).
            0x10 => {
                let p = self.position();
                Ok(vec![format!(
                    "{} {} {}",
                    fmt_value(p.x),
                    fmt_value(p.y),
                    fmt_value(p.z)
                )])
            }
            0x06 | 0x16 => Ok(vec!["0 0 0".into()]),
            _ => Err(err::DATA),
        }
    }
}
