//! Bytes to words: the line cursor, number scanning and the keyword table
//! of the Turbo PMAC reader.

/// What a multi-letter word means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kw {
    Linear,
    Rapid,
    Circle,
    Abs,
    Inc,
    Normal,
    Dwell,
    Delay,
    Ta,
    Ts,
    Tm,
    Frax,
    Open,
    Close,
    Clear,
    Delete,
    Define,
    Return,
    /// Program flow: needs a real interpreter with jumps.
    Flow,
    /// A PMAC command this reader does not model.
    Unsupported,
}

/// Program words with PMAC's short forms, grouped by first letter so a
/// lookup compares a handful of candidates, not the whole vocabulary.
fn keywords_for(first: u8) -> &'static [(&'static str, Kw)] {
    match first.to_ascii_uppercase() {
        b'A' => &[("ABS", Kw::Abs), ("ADDRESS", Kw::Unsupported), ("ADR", Kw::Unsupported)],
        b'B' => &[
            ("BLOCKSTART", Kw::Unsupported),
            ("BSTART", Kw::Unsupported),
            ("BLOCKSTOP", Kw::Unsupported),
            ("BSTOP", Kw::Unsupported),
        ],
        b'C' => &[
            ("CIRCLE", Kw::Circle),
            ("CIR", Kw::Circle),
            ("CLOSE", Kw::Close),
            ("CLEAR", Kw::Clear),
            ("CALL", Kw::Flow),
            ("CC", Kw::Unsupported),
            ("COMMAND", Kw::Unsupported),
            ("CMD", Kw::Unsupported),
        ],
        b'D' => &[
            ("DWELL", Kw::Dwell),
            ("DWE", Kw::Dwell),
            ("DELAY", Kw::Delay),
            ("DLY", Kw::Delay),
            ("DELETE", Kw::Delete),
            ("DEL", Kw::Delete),
            ("DEFINE", Kw::Define),
            ("DEF", Kw::Define),
            ("DISPLAY", Kw::Unsupported),
            ("DISP", Kw::Unsupported),
            ("DISABLE", Kw::Unsupported),
            ("DIS", Kw::Unsupported),
        ],
        b'E' => &[
            ("ELSE", Kw::Flow),
            ("ENDIF", Kw::Flow),
            ("ENDI", Kw::Flow),
            ("ENDWHILE", Kw::Flow),
            ("ENDW", Kw::Flow),
            ("ENABLE", Kw::Unsupported),
            ("ENA", Kw::Unsupported),
        ],
        b'F' => &[("FRAX", Kw::Frax)],
        b'G' => &[("GOTO", Kw::Flow), ("GOSUB", Kw::Flow)],
        b'H' => &[("HOME", Kw::Unsupported), ("HOMEZ", Kw::Unsupported)],
        b'I' => &[("INC", Kw::Inc), ("IF", Kw::Flow)],
        b'L' => &[("LINEAR", Kw::Linear), ("LIN", Kw::Linear), ("LOCK", Kw::Unsupported)],
        b'N' => &[("NORMAL", Kw::Normal), ("NRM", Kw::Normal)],
        b'O' => &[("OPEN", Kw::Open)],
        b'P' => &[
            ("PVT", Kw::Unsupported),
            ("PSET", Kw::Unsupported),
            ("PRELUDE", Kw::Unsupported),
            ("PAUSE", Kw::Unsupported),
        ],
        b'R' => &[
            ("RAPID", Kw::Rapid),
            ("RPD", Kw::Rapid),
            ("RETURN", Kw::Return),
            ("RET", Kw::Return),
            ("READ", Kw::Unsupported),
        ],
        b'S' => &[
            ("STOP", Kw::Flow),
            ("SPLINE", Kw::Unsupported),
            ("SEND", Kw::Unsupported),
        ],
        b'T' => &[
            ("TA", Kw::Ta),
            ("TS", Kw::Ts),
            ("TM", Kw::Tm),
            ("TSELECT", Kw::Unsupported),
            ("TSEL", Kw::Unsupported),
            ("TINIT", Kw::Unsupported),
        ],
        b'U' => &[("UNLOCK", Kw::Unsupported)],
        b'W' => &[("WHILE", Kw::Flow), ("WAIT", Kw::Flow)],
        _ => &[],
    }
}

/// The longest keyword that starts the letter run `w`, so that `LINEARX1`
/// reads as `LINEAR X1` and `DELAY` is not `DEL` + `AY`.
pub(super) fn match_keyword(w: &[u8]) -> Option<(&'static str, Kw)> {
    let mut best: Option<(&'static str, Kw)> = None;
    for &(name, kw) in keywords_for(*w.first()?) {
        let n = name.as_bytes();
        if w.get(..n.len()).is_some_and(|p| p.eq_ignore_ascii_case(n)) && best.is_none_or(|(b, _)| b.len() < n.len()) {
            best = Some((name, kw));
        }
    }
    best
}

pub(super) fn is_ws(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

/// A position in one line of text.
pub(super) struct Cursor<'a> {
    pub(super) text: &'a str,
    pub(super) b: &'a [u8],
    pub(super) i: usize,
}

impl<'a> Cursor<'a> {
    pub(super) fn new(text: &'a str) -> Self {
        Cursor {
            text,
            b: text.as_bytes(),
            i: 0,
        }
    }

    #[inline]
    pub(super) fn peek(&self) -> Option<u8> {
        self.b.get(self.i).copied()
    }

    #[inline]
    pub(super) fn peek_at(&self, k: usize) -> Option<u8> {
        self.b.get(self.i + k).copied()
    }

    #[inline]
    pub(super) fn skip_ws(&mut self) {
        while self.peek().is_some_and(is_ws) {
            self.i += 1;
        }
    }

    #[inline]
    pub(super) fn eat(&mut self, c: u8) -> bool {
        if self.peek() == Some(c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    /// End of the run of ASCII letters starting at `from`.
    pub(super) fn letters_end(&self, from: usize) -> usize {
        let mut j = from;
        while self.b.get(j).is_some_and(u8::is_ascii_alphabetic) {
            j += 1;
        }
        j
    }

    /// Unsigned integer (digits only); `None` when there is no digit. Values
    /// saturate, so a long digit string cannot overflow.
    pub(super) fn uint(&mut self) -> Option<u64> {
        let start = self.i;
        let mut n: u64 = 0;
        while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
            n = n.saturating_mul(10).saturating_add(u64::from(c - b'0'));
            self.i += 1;
        }
        (self.i > start).then_some(n)
    }

    /// Unsigned decimal constant (`12`, `1.5`, `.5`, `5.`); `None` when no
    /// digit. PMAC has no exponent notation, so none is read.
    pub(super) fn number(&mut self) -> Option<f64> {
        let start = self.i;
        let mut mant: u64 = 0;
        let mut digits = 0u32;
        let mut frac = 0u32;
        while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
            mant = mant.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
            digits += 1;
            self.i += 1;
        }
        if self.peek() == Some(b'.') {
            self.i += 1;
            while let Some(c) = self.peek().filter(u8::is_ascii_digit) {
                mant = mant.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
                digits += 1;
                frac += 1;
                self.i += 1;
            }
        }
        if digits == 0 {
            self.i = start;
            return None;
        }
        // Exact and correctly rounded: both operands are exact doubles.
        const POW10: [f64; 16] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
        ];
        if digits <= 15
            && let Some(p) = POW10.get(frac as usize)
        {
            return Some(mant as f64 / p);
        }
        // Long constants: let the standard library round them.
        self.text.get(start..self.i).and_then(|s| s.parse::<f64>().ok())
    }

    /// `$` hexadecimal integer constant, after the `$`.
    pub(super) fn hex(&mut self) -> Option<f64> {
        let start = self.i;
        let mut n: u64 = 0;
        while let Some(d) = self.peek().and_then(|c| (c as char).to_digit(16)) {
            if self.i - start >= 16 {
                return None;
            }
            n = (n << 4) | u64::from(d);
            self.i += 1;
        }
        (self.i > start).then_some(n as f64)
    }

    /// A short excerpt at `at` for error messages.
    pub(super) fn snippet(&self, at: usize) -> String {
        let rest = self.text.get(at..).unwrap_or("");
        rest.chars()
            .take_while(|c| !c.is_whitespace() && *c != ';')
            .take(16)
            .collect()
    }
}

/// The first letter run at or after `from` that begins with one of `words`
/// (upper case), outside `;` comments and `"` strings: its start and which
/// word it is.
pub(super) fn find_word(b: &[u8], from: usize, words: &[&str]) -> Option<(usize, usize)> {
    let mut i = from;
    let mut quoted = false;
    while let Some(&c) = b.get(i) {
        if quoted {
            quoted = c != b'"';
            i += 1;
            continue;
        }
        match c {
            b';' => return None,
            b'"' => {
                quoted = true;
                i += 1;
            }
            c if c.is_ascii_alphabetic() => {
                let start = i;
                while b.get(i).is_some_and(u8::is_ascii_alphabetic) {
                    i += 1;
                }
                let run = b.get(start..i).unwrap_or(&[]);
                if let Some(k) = words
                    .iter()
                    .position(|w| run.get(..w.len()).is_some_and(|p| p.eq_ignore_ascii_case(w.as_bytes())))
                {
                    return Some((start, k));
                }
            }
            _ => i += 1,
        }
    }
    None
}

/// The name of a one-letter word, for messages.
pub(super) fn letter_name(letter: u8) -> &'static str {
    const NAMES: [&str; 26] = [
        "A", "B", "C", "D", "E", "F", "G", "H", "I", "J", "K", "L", "M", "N", "O", "P", "Q", "R", "S", "T", "U", "V",
        "W", "X", "Y", "Z",
    ];
    NAMES
        .get(usize::from(letter.to_ascii_uppercase().wrapping_sub(b'A')))
        .copied()
        .unwrap_or("?")
}
