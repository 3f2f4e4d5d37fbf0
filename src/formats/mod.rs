//! Streaming readers and writers for the JSON Lines pipe formats
//! (`microcam.chains/1`, `microcam.toolpath/1`) and the plain-text CL
//! data. See docs/formats.md.
//!
//! Readers hold one line at a time, so memory stays flat however long the
//! input; they validate every record and name its line number on error.
//! Writers format numbers themselves (shortest round-trip form after
//! rounding to 1e-9 mm) so output is byte-identical for identical input.

#![warn(missing_docs)]

pub mod chains;
mod chains_whole;
pub mod cldata;
pub mod toolpath;

pub use chains_whole::read_chains;

use crate::geometry::P3;
use std::io::BufRead;
use thiserror::Error;

/// An error in a pipe-format stream. `line` is the 1-based line number of
/// the offending record (the header is line 1).
#[derive(Debug, Error)]
pub enum FormatError {
    /// The line is not a valid record of its format (unparsable, a field
    /// missing or out of range, a wrong schema).
    #[error("line {line}: {msg}")]
    Invalid {
        /// 1-based line number.
        line: u64,
        /// What is wrong, in words.
        msg: String,
    },
    /// Reading or writing failed at this line.
    #[error("line {line}: {source}")]
    Io {
        /// 1-based line number (the line being read or written).
        line: u64,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

impl FormatError {
    /// A [`FormatError::Invalid`] at `line`.
    pub fn invalid(line: u64, msg: impl Into<String>) -> Self {
        FormatError::Invalid { line, msg: msg.into() }
    }

    /// The line the error is about.
    pub fn line(&self) -> u64 {
        match self {
            FormatError::Invalid { line, .. } | FormatError::Io { line, .. } => *line,
        }
    }
}

/// Reads non-empty lines one at a time, counting line numbers.
pub(crate) struct LineSource<R> {
    input: R,
    buf: Vec<u8>,
    line: u64,
}

impl<R: BufRead> LineSource<R> {
    pub(crate) fn new(input: R) -> Self {
        LineSource {
            input,
            buf: Vec::new(),
            line: 0,
        }
    }

    /// The next non-blank line (trimmed), or `None` at end of input. Lines
    /// end at LF, CR or CRLF (`cli::read_line_any_ending`).
    pub(crate) fn next_line(&mut self) -> Result<Option<(&str, u64)>, FormatError> {
        loop {
            self.buf.clear();
            self.line += 1;
            let n = crate::cli::read_line_any_ending(&mut self.input, &mut self.buf).map_err(|e| FormatError::Io {
                line: self.line,
                source: e,
            })?;
            if n == 0 {
                return Ok(None);
            }
            if self.buf.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            let text = std::str::from_utf8(&self.buf).map_err(|e| FormatError::Io {
                line: self.line,
                source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
            })?;
            return Ok(Some((text.trim(), self.line)));
        }
    }
}

/// Writes one JSON Lines record at a time through a reused buffer, one
/// `write_all` per record: the plumbing both pipe-format writers share.
pub(crate) struct LineWriter<W: std::io::Write> {
    out: W,
    buf: String,
}

impl<W: std::io::Write> LineWriter<W> {
    pub(crate) fn new(out: W) -> Self {
        LineWriter {
            out,
            buf: String::with_capacity(256),
        }
    }

    /// Format one record with `f` and write it as a line.
    pub(crate) fn line(&mut self, f: impl FnOnce(&mut String)) -> std::io::Result<()> {
        self.buf.clear();
        f(&mut self.buf);
        self.buf.push('\n');
        self.out.write_all(self.buf.as_bytes())
    }

    /// The header record: schema, units, then `extra` fields, then source.
    pub(crate) fn header(&mut self, schema: &str, extra: &[(&str, &str)], source: Option<&str>) -> std::io::Result<()> {
        self.line(|b| {
            b.push_str("{\"schema\":\"");
            b.push_str(schema);
            b.push_str("\",\"units\":\"mm\"");
            for (k, v) in extra {
                b.push_str(",\"");
                b.push_str(k);
                b.push_str("\":");
                push_str_lit(b, v);
            }
            if let Some(s) = source {
                b.push_str(",\"source\":");
                push_str_lit(b, s);
            }
            b.push('}');
        })
    }

    /// Write records already formatted (whole lines, newlines included).
    pub(crate) fn raw(&mut self, text: &str) -> std::io::Result<()> {
        self.out.write_all(text.as_bytes())
    }

    pub(crate) fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Append a number in the pipe formats' canonical form: rounded to 1e-9,
/// shortest exact decimal digits, no trailing zeros, no `-0`.
///
/// Hand-written fixed-point formatting: the value is rounded to an integer
/// count of 1e-9 units and printed digit by digit, which is exact and about
/// three times faster than a general shortest-float formatter on the
/// millions of numbers a large toolpath carries.
pub fn push_num(out: &mut String, x: f64) {
    const SCALE: f64 = 1e9;
    // Beyond 4e6 mm, x * 1e9 passes 2^52 and the fixed form would print
    // digits the double does not have; such values print in shortest form.
    if !x.is_finite() {
        // JSON has no NaN or infinity. `null` makes every reader refuse the
        // record with a message naming it, so a bug that computed a NaN is
        // caught at the next tool instead of turning into a silent 0.
        out.push_str("null");
        return;
    }
    if x.abs() >= 4e6 {
        let mut b = ryu::Buffer::new();
        out.push_str(b.format_finite(x));
        return;
    }
    // Round half away from zero without a libm call (|y| < 2^52, so the
    // addition is exact enough and the cast truncates).
    let y = x * SCALE;
    let v = if y >= 0.0 { (y + 0.5) as i64 } else { (y - 0.5) as i64 };
    if v == 0 {
        out.push('0');
        return;
    }
    // Digits are written right to left into a stack buffer: 9 fraction
    // digits, then the integer part, then the sign.
    let mut buf = [b'0'; 32];
    let mut end = buf.len();
    let neg = v < 0;
    let v = v.unsigned_abs();
    let mut int = v / 1_000_000_000;
    let frac = (v % 1_000_000_000) as u32;
    if frac != 0 {
        let mut f = frac;
        let mut i = end;
        for _ in 0..4 {
            let d = (f % 100) as usize;
            f /= 100;
            i -= 2;
            buf[i..i + 2].copy_from_slice(&DIGIT_PAIRS[2 * d..2 * d + 2]);
        }
        i -= 1;
        buf[i] = b'0' + f as u8;
        while buf[end - 1] == b'0' {
            end -= 1;
        }
        buf[i - 1] = b'.';
    }
    let mut start = buf.len() - if frac != 0 { 10 } else { 0 };
    loop {
        if int >= 10 {
            let d = (int % 100) as usize;
            int /= 100;
            start -= 2;
            buf[start..start + 2].copy_from_slice(&DIGIT_PAIRS[2 * d..2 * d + 2]);
            if int == 0 && d < 10 {
                start += 1; // no leading zero
                break;
            }
            if int == 0 {
                break;
            }
        } else {
            start -= 1;
            buf[start] = b'0' + int as u8;
            break;
        }
    }
    if neg {
        start -= 1;
        buf[start] = b'-';
    }
    push_ascii(out, &buf[start..end]);
}

/// Append digits, '.' and '-' written by the formatters here. Checking
/// them as UTF-8 again cost about 3 % of a large `dxf2chains` run (a call
/// per number), and even an `is_ascii` check cost a tenth of
/// [`push_num`]'s time: its 8-byte loads of the bytes just written in 1-
/// and 2-byte stores cannot be forwarded from the store buffer and wait
/// for the stores to retire.
#[inline]
fn push_ascii(out: &mut String, digits: &[u8]) {
    debug_assert!(digits.is_ascii());
    // SAFETY: every caller writes its bytes from `DIGIT_PAIRS`, `b'0' + d`
    // with d < 10, `b'.'` and `b'-'`: ASCII, so valid UTF-8 (the debug
    // assertion above checks it in every test run).
    out.push_str(unsafe { std::str::from_utf8_unchecked(digits) });
}

/// Append an unsigned integer (ids, line numbers) without `core::fmt`.
pub fn push_uint(out: &mut String, mut v: u64) {
    let mut buf = [b'0'; 20];
    let mut i = buf.len();
    while v >= 100 {
        let d = (v % 100) as usize;
        v /= 100;
        i -= 2;
        buf[i..i + 2].copy_from_slice(&DIGIT_PAIRS[2 * d..2 * d + 2]);
    }
    if v >= 10 {
        i -= 2;
        buf[i..i + 2].copy_from_slice(&DIGIT_PAIRS[2 * v as usize..2 * v as usize + 2]);
    } else {
        i -= 1;
        buf[i] = b'0' + v as u8;
    }
    push_ascii(out, &buf[i..]);
}

const DIGIT_PAIRS: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Append `[x,y,z]`.
pub fn push_point3(out: &mut String, p: &P3) {
    out.push('[');
    push_num(out, p.x);
    out.push(',');
    push_num(out, p.y);
    out.push(',');
    push_num(out, p.z);
    out.push(']');
}

/// Append `[x,y]` when z is zero, else `[x,y,z]`.
pub fn push_point_2or3(out: &mut String, p: &P3) {
    if p.z == 0.0 {
        out.push('[');
        push_num(out, p.x);
        out.push(',');
        push_num(out, p.y);
        out.push(']');
    } else {
        push_point3(out, p);
    }
}

/// Append a JSON string literal.
pub fn push_str_lit(out: &mut String, s: &str) {
    // serde_json's escaping is the reference. It escapes only `"`, `\`
    // and control characters below 0x20: a string without any of them is
    // written as it is (layer names, on every chain), the rest by serde.
    if !s.bytes().any(|c| c < 0x20 || c == b'"' || c == b'\\') {
        out.push('"');
        out.push_str(s);
        out.push('"');
        return;
    }
    out.push_str(&serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into()));
}

/// Turn a `[x, y]` or `[x, y, z]` array into a point.
pub(crate) fn point_from(v: &[f64], line: u64, what: &str) -> Result<P3, FormatError> {
    let p = match v {
        [x, y] => P3::new(*x, *y, 0.0),
        [x, y, z] => P3::new(*x, *y, *z),
        _ => {
            return Err(FormatError::invalid(
                line,
                format!("{what} must be [x, y] or [x, y, z], got {} numbers", v.len()),
            ));
        }
    };
    if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
        return Err(FormatError::invalid(line, format!("{what} is not finite")));
    }
    Ok(p)
}

/// Parse a JSON line into `T`, naming the line on failure.
pub(crate) fn parse_json<'a, T: serde::Deserialize<'a>>(text: &'a str, line: u64) -> Result<T, FormatError> {
    serde_json::from_str(text).map_err(|e| FormatError::invalid(line, format!("bad JSON record: {e}")))
}

/// Read the header line and check its schema.
pub(crate) fn check_schema(schema: Option<&str>, want: &str, line: u64) -> Result<(), FormatError> {
    match schema {
        Some(s) if s == want => Ok(()),
        Some(s) => Err(FormatError::invalid(
            line,
            format!("unknown schema '{s}' (this tool reads '{want}')"),
        )),
        None => Err(FormatError::invalid(
            line,
            format!("the first record must be a header with \"schema\":\"{want}\""),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_canonical() {
        let mut s = String::new();
        for x in [
            0.0,
            -0.0,
            1.0,
            -2.5,
            0.1 + 0.2,
            1e-12,
            123456.000000000001,
            1e20,
            -0.000000001,
            0.0000000004,
            1.25e-7,
            -8999999999.5,
            10.0,
            -100.5,
            1234567.000001,
            0.05,
            99.99,
        ] {
            push_num(&mut s, x);
            s.push(' ');
        }
        assert_eq!(
            s,
            "0 0 1 -2.5 0.3 0 123456 1e20 -0.000000001 0 0.000000125 -8999999999.5 10 -100.5 1234567.000001 0.05 99.99 "
        );
    }

    #[test]
    fn integers_format_like_display() {
        for v in [0u64, 7, 10, 99, 100, 101, 12345, 1_000_000, u64::MAX] {
            let mut s = String::new();
            push_uint(&mut s, v);
            assert_eq!(s, v.to_string());
        }
    }

    #[test]
    fn fast_formatting_equals_a_plain_reference() {
        let reference = |x: f64| -> String {
            let y = x * 1e9;
            let v = if y >= 0.0 { (y + 0.5) as i64 } else { (y - 0.5) as i64 };
            if v == 0 {
                return "0".into();
            }
            let (sign, a) = (if v < 0 { "-" } else { "" }, v.unsigned_abs());
            let s = format!("{sign}{}.{:09}", a / 1_000_000_000, a % 1_000_000_000);
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let scale = 10f64.powi((state % 16) as i32 - 9);
            let x = ((state >> 12) as f64 / (1u64 << 52) as f64 - 0.5) * scale * 8.0;
            let mut s = String::new();
            push_num(&mut s, x);
            assert_eq!(s, reference(x), "{x:e}");
        }
    }

    #[test]
    fn string_literals_are_serde_json_s() {
        for t in [
            "",
            "CUT",
            "Layer 1",
            "a\"b",
            "back\\slash",
            "tab\there",
            "nl\n",
            "\u{1}\u{1f}",
            "\u{7f}",
            "Ü-Schicht",
            "\u{2028}",
            "名前",
        ] {
            let mut s = String::new();
            push_str_lit(&mut s, t);
            assert_eq!(s, serde_json::to_string(t).unwrap(), "{t:?}");
        }
    }

    #[test]
    fn numbers_read_back_within_half_a_nanometre() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..100_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let x = (state as f64 / u64::MAX as f64 - 0.5) * 10f64.powi((state % 14) as i32 - 4);
            let mut s = String::new();
            push_num(&mut s, x);
            let back: f64 = s.parse().unwrap();
            assert!(
                (back - x).abs() <= 0.5e-9 * (1.0 + 1e-6) + x.abs() * 1e-15,
                "{x} -> {s}"
            );
        }
    }
}
