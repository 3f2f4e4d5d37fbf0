//! The ASCII tokenizer proper: a block of whole lines to an array of parsed
//! (group code, value) tags, with numbers parsed where they stand.
//!
//! [`tokenize`] is a pure function of the bytes, so the blocks of a file can
//! be tokenized on several threads and consumed in order by
//! [`super::reader::Reader`]. A block is cut at a line boundary, normally
//! just before a `0` line followed by an entity name ([`cut`]); the rare
//! block that ends after a group code whose value is in the next block
//! ([`End::Dangling`]) is tokenized again, joined to the next one, so the
//! result never depends on where the cuts fall.

use super::reader::{Kind, kind_of};

/// One tag of a block. `line` is the code's line, counted from 1 at the
/// block's first line.
#[derive(Debug, Clone, Copy)]
pub struct Tag {
    /// The group code (DXF codes fit in an `i16`; binary files store them so).
    pub code: i16,
    /// The string value was not UTF-8: its lossy decoding is
    /// `TokenBlock::lossy[val]`.
    pub lossy: bool,
    /// The group code's line, from 1 at the block's first line.
    pub line: u32,
    /// f64 bits (floats), i64 (integers) or `start | len << 32` (strings:
    /// the text, without its line end, in `TokenBlock::bytes`).
    pub val: u64,
}

/// How a block ended.
#[derive(Debug, Clone, PartialEq)]
pub enum End {
    /// After a complete tag (or empty).
    Clean,
    /// After a group code line whose value line is not in the block: the
    /// code's line and the byte offset where that line starts.
    Dangling {
        /// The group code's line, relative to the block.
        line: u32,
        /// The byte offset in the block where that line starts.
        off: usize,
        /// The group code.
        code: i32,
    },
    /// A blank line where a group code belongs, with only blank lines after
    /// it in this block: fine at the end of the file, an error before more
    /// tags.
    Blank {
        /// The blank line, relative to the block.
        line: u32,
    },
    /// A syntax error at this line (relative to the block).
    Error {
        /// The offending line, relative to the block.
        line: u32,
        /// What is wrong there.
        msg: String,
    },
}

/// A tokenized block of lines.
#[derive(Debug)]
pub struct TokenBlock {
    /// The block's bytes: whole lines, line ends included. String tags
    /// point into it.
    pub bytes: Vec<u8>,
    /// The tags in file order.
    pub tags: Vec<Tag>,
    /// Lossy decodings of the string values that were not UTF-8, indexed
    /// by [`Tag::val`] of a tag with [`Tag::lossy`] set.
    pub lossy: Vec<String>,
    /// Lines in the block.
    pub lines: u64,
    /// How the block ended: cleanly, inside a tag, or at an error.
    pub end: End,
    /// No line holds anything but white space.
    pub blank_only: bool,
}

impl TokenBlock {
    /// The text of string tag `t`.
    pub fn text(&self, t: &Tag) -> &str {
        if t.lossy {
            return self.lossy.get(t.val as usize).map_or("", |s| s.as_str());
        }
        let (a, n) = ((t.val & 0xffff_ffff) as usize, (t.val >> 32) as usize);
        // Checked to be UTF-8 by `tokenize`; checked again here because
        // nothing but that check ties the two together. Names, handles and
        // markers are short and ASCII: `is_ascii` is a few word compares
        // inline, where `from_utf8` was a call per tag (about 2 % of a
        // large import).
        match self.bytes.get(a..a + n) {
            // SAFETY: ASCII bytes are valid UTF-8 (checked in the guard).
            Some(b) if b.is_ascii() => unsafe { std::str::from_utf8_unchecked(b) },
            Some(b) => std::str::from_utf8(b).unwrap_or(""),
            None => "",
        }
    }
}

/// Exact powers of ten for the fast float path.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20,
    1e21, 1e22,
];

/// The end of the line starting at `pos` (the index of its `\n`, or the
/// length).
#[inline]
fn line_end(b: &[u8], pos: usize) -> usize {
    let mut i = pos;
    while i < b.len() && b[i] != b'\n' {
        i += 1;
    }
    i
}

/// The end of the line starting at `pos` (the index of its `\n`, or the
/// length) and the OR of its bytes before that, bit 7 set when any is not
/// ASCII. Eight bytes at a time: a word has a `\n` where, XORed with
/// `\n`s, it has a zero byte, and the lowest byte the zero-byte test
/// flags is the first zero (it can only flag a false one above a true
/// one).
#[inline]
fn line_end_ascii(b: &[u8], pos: usize) -> (usize, u8) {
    const ONES: u64 = 0x0101_0101_0101_0101;
    const HIGHS: u64 = 0x8080_8080_8080_8080;
    let mut e = pos;
    let mut acc = 0u64;
    while e + 8 <= b.len() {
        let w = u64::from_le_bytes(b[e..e + 8].try_into().unwrap_or([0; 8]));
        let x = w ^ (ONES * u64::from(b'\n'));
        let nl = x.wrapping_sub(ONES) & !x & HIGHS;
        if nl != 0 {
            let k = nl.trailing_zeros() as usize / 8;
            acc |= w & ((1u64 << (8 * k)) - 1);
            return (e + k, if acc & HIGHS != 0 { 0x80 } else { 0 });
        }
        acc |= w;
        e += 8;
    }
    let mut high = if acc & HIGHS != 0 { 0x80 } else { 0 };
    while e < b.len() && b[e] != b'\n' {
        high |= b[e];
        e += 1;
    }
    (e, high)
}

/// A line without its `\n` and trailing `\r`s (as `read_until` + pop did).
#[inline]
fn strip_eol(b: &[u8]) -> &[u8] {
    let mut n = b.len();
    while n > 0 && matches!(b[n - 1], b'\n' | b'\r') {
        n -= 1;
    }
    &b[..n]
}

/// Fast path for `[spaces][-]digits[spaces][\r]\n`: (value, index of the
/// next line). `None` sends the line to the general path.
#[inline]
fn fast_int(b: &[u8], mut i: usize) -> Option<(i64, usize)> {
    while i < b.len() && b[i] == b' ' {
        i += 1;
    }
    let neg = i < b.len() && b[i] == b'-';
    if neg {
        i += 1;
    }
    let d0 = i;
    let mut v: i64 = 0;
    while i < b.len() && b[i].is_ascii_digit() {
        // Wrapping: a run of more than 18 digits overflows here, and is
        // sent to the general path below whatever its value.
        v = v.wrapping_mul(10).wrapping_add((b[i] - b'0') as i64);
        i += 1;
    }
    if i == d0 || i - d0 > 18 {
        return None;
    }
    let i = eol(b, i)?;
    Some((if neg { -v } else { v }, i))
}

/// Fast path for the group code lines most writers emit: right-aligned in
/// three columns, `"  0\n"`, `" 10\n"`, `"330\n"` (AutoCAD's layout):
/// (code, index of the next line). Four bytes read at once and three digit
/// checks, where the general path walks the line byte by byte with a
/// bounds check on each. Anything else (CRLF, other widths, signs) goes
/// the general way.
#[inline]
fn code3(b: &[u8], pos: usize) -> Option<(i64, usize)> {
    let s: &[u8; 4] = b.get(pos..pos + 4)?.try_into().ok()?;
    if s[3] != b'\n' {
        return None;
    }
    let d = |c: u8| c.wrapping_sub(b'0');
    let (c0, c1, c2) = (s[0], s[1], d(s[2]));
    if c2 > 9 {
        return None;
    }
    let v = match (c0, c1) {
        (b' ', b' ') => c2 as i64,
        (b' ', _) if d(c1) <= 9 => (d(c1) * 10 + c2) as i64,
        _ if d(c0) <= 9 && d(c1) <= 9 => d(c0) as i64 * 100 + (d(c1) * 10 + c2) as i64,
        _ => return None,
    };
    Some((v, pos + 4))
}

/// Past trailing spaces and the line end: the next line's start.
#[inline]
fn eol(b: &[u8], mut i: usize) -> Option<usize> {
    while i < b.len() && b[i] == b' ' {
        i += 1;
    }
    if i < b.len() && b[i] == b'\r' {
        i += 1;
    }
    if i == b.len() {
        return Some(i);
    }
    (b[i] == b'\n').then_some(i + 1)
}

/// Fast path for a plain decimal `[spaces][-]digits[.digits][spaces]`:
/// at most 19 significant digits, mantissa below 2^53 and at most 22
/// fraction digits, where one division of two exact doubles is the correctly
/// rounded value (Clinger's fast path), bit for bit what `str::parse` gives.
/// Anything else (exponents, long mantissas, `inf`) goes the general way.
#[inline]
fn fast_float(b: &[u8], mut i: usize) -> Option<(f64, usize)> {
    while i < b.len() && b[i] == b' ' {
        i += 1;
    }
    let neg = i < b.len() && b[i] == b'-';
    if neg {
        i += 1;
    }
    let mut m: u64 = 0;
    let mut digits = 0usize;
    while i < b.len() && b[i].is_ascii_digit() {
        m = m.wrapping_mul(10).wrapping_add((b[i] - b'0') as u64);
        digits += 1;
        i += 1;
    }
    let mut frac = 0usize;
    if i < b.len() && b[i] == b'.' {
        i += 1;
        while i < b.len() && b[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add((b[i] - b'0') as u64);
            frac += 1;
            i += 1;
        }
    }
    if digits + frac == 0 || digits + frac > 19 || frac > 22 || m > (1u64 << 53) {
        return None;
    }
    let i = eol(b, i)?;
    let v = m as f64 / POW10[frac];
    Some((if neg { -v } else { v }, i))
}

/// Tokenize a block of whole lines.
pub fn tokenize(bytes: Vec<u8>) -> TokenBlock {
    tokenize_into(bytes, Vec::new())
}

/// [`tokenize`] into `tags` (cleared first): the reader hands back the
/// arrays of blocks it is done with, so a file is read with the same few
/// buffers throughout.
pub fn tokenize_into(bytes: Vec<u8>, mut tags: Vec<Tag>) -> TokenBlock {
    let b = &bytes[..];
    tags.clear();
    tags.reserve(b.len() / 12);
    let mut lossy: Vec<String> = Vec::new();
    let mut pos = 0usize;
    let mut line: u32 = 0;
    let mut blank_only = true;
    let end = loop {
        if pos >= b.len() {
            break End::Clean;
        }
        // The group code line.
        line += 1;
        let code_line = line;
        let code_start = pos;
        let code = match code3(b, pos).or_else(|| fast_int(b, pos).filter(|&(c, _)| i32::try_from(c).is_ok())) {
            Some((c, next)) => {
                pos = next;
                c
            }
            None => {
                let e = line_end(b, pos);
                let text = strip_eol(&b[pos..e]).trim_ascii();
                if text.is_empty() {
                    // Only blank lines may follow, up to the end of the file.
                    let mut p = (e + 1).min(b.len());
                    let mut bad = false;
                    while p < b.len() {
                        let e2 = line_end(b, p);
                        if !b[p..e2].trim_ascii().is_empty() {
                            bad = true;
                            break;
                        }
                        p = e2 + 1;
                    }
                    if bad {
                        blank_only = false;
                        break End::Error {
                            line: code_line,
                            msg: "empty line where a group code belongs".into(),
                        };
                    }
                    break End::Blank { line: code_line };
                }
                blank_only = false;
                match std::str::from_utf8(text).ok().and_then(|s| s.parse::<i32>().ok()) {
                    Some(c) => {
                        pos = e + 1;
                        c as i64
                    }
                    None => {
                        break End::Error {
                            line: code_line,
                            msg: format!(
                                "expected a group code (an integer), found '{}'",
                                super::reader::shorten(&String::from_utf8_lossy(text))
                            ),
                        };
                    }
                }
            }
        };
        blank_only = false;
        if !(-5..=1071).contains(&code) {
            break End::Error {
                line: code_line,
                msg: format!("group code {code} is out of range"),
            };
        }
        let code = code as i32;
        if pos >= b.len() {
            break End::Dangling {
                line: code_line,
                off: code_start,
                code,
            };
        }
        // The value line.
        line += 1;
        let kind = kind_of(code);
        let val = match kind {
            Kind::Float => match fast_float(b, pos) {
                Some((v, next)) => {
                    pos = next;
                    v.to_bits()
                }
                None => {
                    let e = line_end(b, pos);
                    let t = strip_eol(&b[pos..e]).trim_ascii();
                    match super::reader::parse_float(t) {
                        Some(v) => {
                            pos = e + 1;
                            v.to_bits()
                        }
                        None => {
                            break End::Error {
                                line,
                                msg: super::reader::bad_number_msg(code, t),
                            };
                        }
                    }
                }
            },
            Kind::Int16 | Kind::Int32 | Kind::Int64 | Kind::Bool => match fast_int(b, pos) {
                Some((v, next)) => {
                    pos = next;
                    v as u64
                }
                None => {
                    let e = line_end(b, pos);
                    let t = strip_eol(&b[pos..e]).trim_ascii();
                    match super::reader::parse_int(t) {
                        Some(v) => {
                            pos = e + 1;
                            v as u64
                        }
                        None => {
                            break End::Error {
                                line,
                                msg: super::reader::bad_number_msg(code, t),
                            };
                        }
                    }
                }
            },
            Kind::Str | Kind::Binary => {
                // The line's end and whether it is ASCII in one pass (names,
                // handles and markers are short: a second pass to check
                // them cost as much as finding the end).
                let (e, high) = line_end_ascii(b, pos);
                let t = strip_eol(&b[pos..e]);
                let start = pos;
                pos = e + 1;
                if high < 0x80 || std::str::from_utf8(t).is_ok() {
                    (start as u64) | ((t.len() as u64) << 32)
                } else {
                    // Pre-2007 files are in a code page; names only matter
                    // for layers and blocks, so a lossy decode is enough.
                    lossy.push(String::from_utf8_lossy(t).into_owned());
                    tags.push(Tag {
                        code: code as i16,
                        lossy: true,
                        line: code_line,
                        val: (lossy.len() - 1) as u64,
                    });
                    continue;
                }
            }
        };
        tags.push(Tag {
            code: code as i16,
            lossy: false,
            line: code_line,
            val,
        });
    };
    // Lines: every `\n`, plus a last line without one. A clean end has
    // consumed every line, each ending at a `\n` or at the block's end, and
    // counted it.
    let lines = match &end {
        End::Clean => u64::from(line),
        End::Blank { .. } => {
            let nl = bytes.iter().filter(|&&c| c == b'\n').count() as u64;
            nl + u64::from(bytes.last().is_some_and(|&c| c != b'\n'))
        }
        _ => 0,
    };
    TokenBlock {
        bytes,
        tags,
        lossy,
        lines,
        end,
        blank_only,
    }
}

/// Where to cut `buf` (which does not end the file) into a block and the
/// rest: before a line `0` followed by a line starting with a letter (an
/// entity or section name, so the cut is at a tag boundary in any valid
/// file), searched backwards from the end; failing that, after the last
/// line end. `None` when `buf` holds no line end at all.
pub fn cut(buf: &[u8]) -> Option<usize> {
    let last_nl = buf.iter().rposition(|&c| c == b'\n')?;
    let start_of = |end: usize| buf[..end].iter().rposition(|&c| c == b'\n').map_or(0, |p| p + 1);
    // Candidate pairs of complete lines, walking backwards: `first` ends
    // at the `\n` just before `second` starts.
    let mut second = (start_of(last_nl), last_nl);
    let limit = buf.len().saturating_sub(1 << 20);
    while second.0 > limit.max(1) {
        let first = (start_of(second.0 - 1), second.0 - 1);
        let a = strip_eol(&buf[first.0..first.1]).trim_ascii();
        let b = buf[second.0..second.1].trim_ascii_start();
        if first.0 > 0 && a == b"0" && b.first().is_some_and(|c| c.is_ascii_alphabetic()) {
            return Some(first.0);
        }
        second = first;
    }
    Some(last_nl + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_float_matches_std() {
        for s in [
            "0",
            "-0.0",
            "1.5",
            "123.456789",
            "-6.000001",
            "0.1",
            "3.141592653589793",
            "1234567890123456789",
            "12345678901234567.89",
            ".5",
            "1.",
            "  42.25  ",
            "9007199254740993",
            "0.000000000000000000001",
        ] {
            let want: f64 = s.trim().parse().unwrap();
            let line = format!("{s}\n");
            match fast_float(line.as_bytes(), 0) {
                Some((v, next)) => {
                    assert_eq!(v.to_bits(), want.to_bits(), "{s}");
                    assert_eq!(next, line.len());
                }
                None => {
                    let t = line.trim().as_bytes();
                    assert_eq!(super::super::reader::parse_float(t).unwrap().to_bits(), want.to_bits());
                }
            }
        }
        for s in ["", ".", "-", "1e5", "1,5", "inf", "+1"] {
            assert!(fast_float(format!("{s}\n").as_bytes(), 0).is_none(), "{s}");
        }
    }

    /// The word-at-a-time line end against the byte loop, on lines of
    /// digits, names, CRs and bytes above 0x7f of every length from 0 to
    /// 40, so the line ends at each place in a word and in the tail.
    #[test]
    fn line_end_ascii_is_the_byte_loop() {
        let mut rnd = crate::geometry::test_rng::unit_rng(0x5eed_0001);
        let alphabet = b"0123456789.- \r\nxAe\x80\xc3\xa9/:\t";
        for _ in 0..20_000 {
            let n = (rnd() * 40.0) as usize;
            let line: Vec<u8> = (0..n)
                .map(|_| alphabet[(rnd() * alphabet.len() as f64) as usize])
                .collect();
            let want_end = line.iter().position(|&c| c == b'\n').unwrap_or(line.len());
            let want_high = line[..want_end].iter().fold(0u8, |h, &c| h | c) & 0x80;
            let (e, high) = line_end_ascii(&line, 0);
            assert_eq!(
                (e, high & 0x80),
                (want_end, want_high),
                "{:?}",
                String::from_utf8_lossy(&line)
            );
        }
    }

    #[test]
    fn fast_float_random_values_match_std() {
        // A fixed sequence of values printed the ways writers print them.
        let mut rnd = crate::geometry::test_rng::unit_rng(0x9e37_79b9_7f4a_7c15);
        for _ in 0..20_000 {
            let v = rnd() * 2e6 - 1e6;
            for s in [
                format!("{v:.6}"),
                format!("{v:.12}"),
                format!("{v}"),
                format!("{:.3}", v / 1e3),
            ] {
                let want: f64 = s.parse().unwrap();
                if let Some((got, _)) = fast_float(format!("{s}\r\n").as_bytes(), 0) {
                    assert_eq!(got.to_bits(), want.to_bits(), "{s}");
                }
            }
        }
    }

    #[test]
    fn three_column_codes_match_the_general_path() {
        // Every code line code3 takes is read as the general path reads
        // it; whatever it refuses goes to the general path unchanged.
        for line in [
            "  0\n", " 10\n", "330\n", "100\n", "999\n", " 07\n", "007\n", "  9\n", " -1\n", "0\n", "1071\n", "  a\n",
            " 1 \n", "1 0\n", "  0\r\n", "  0", " +1\n", "\n\n\n\n",
        ] {
            let b = line.as_bytes();
            if let Some((v, next)) = code3(b, 0) {
                assert_eq!(next, 4, "{line:?}");
                let (w, next2) = fast_int(b, 0).unwrap_or_else(|| panic!("{line:?}"));
                assert_eq!((v, next), (w, next2), "{line:?}");
            } else {
                assert!(
                    !["  0\n", " 10\n", "330\n", "100\n", "999\n", " 07\n", "007\n", "  9\n"].contains(&line),
                    "{line:?} refused"
                );
            }
        }
    }

    #[test]
    fn tokenize_reports_lines_and_dangling_codes() {
        let b = tokenize(b"  0\r\nLINE\r\n 10\r\n1.5\r\n 70\r\n     3\r\n 10\r\n".to_vec());
        assert_eq!(b.tags.len(), 3);
        assert_eq!(b.text(&b.tags[0]), "LINE");
        assert_eq!(f64::from_bits(b.tags[1].val), 1.5);
        assert_eq!(b.tags[2].val as i64, 3);
        assert_eq!(b.tags[2].line, 5);
        assert_eq!(
            b.end,
            End::Dangling {
                line: 7,
                off: 34,
                code: 10
            }
        );
    }

    #[test]
    fn cut_lands_before_an_entity() {
        let t = b"  0\nLINE\n  8\n0\n 10\n1.0\n  0\nARC\n 10\n2\n";
        let k = cut(t).unwrap();
        assert_eq!(&t[k..k + 8], b"  0\nARC\n");
        // No entity start: after the last line end.
        assert_eq!(cut(b" 10\n1.0\n 20\n2."), Some(12));
        assert_eq!(cut(b"no newline"), None);
    }
}
