//! Group-code tokenizer for ASCII and binary DXF.
//!
//! A DXF file is a flat sequence of (group code, value) pairs; everything
//! above this layer is a state machine over them. The tokenizer streams from
//! a `BufRead` (one line or one binary tag at a time), so memory does not
//! grow with the file, and it parses every value eagerly by the type its
//! group code implies: a malformed number is reported at the exact line (or
//! byte offset, for binary files) where it sits, not later where it is used.

use super::tokens::{self, End, Tag, TokenBlock};
use std::collections::VecDeque;
use std::fmt;
use std::io::{BufRead, BufReader, Cursor, Read};
use thiserror::Error;

/// Where a tag sits in the input: ASCII files are addressed by line, binary
/// files by byte offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pos {
    /// A line of an ASCII file, counted from 1.
    Line(u64),
    /// A byte offset into a binary file, counted from 0.
    Byte(u64),
}

impl fmt::Display for Pos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Pos::Line(l) => write!(f, "line {l}"),
            Pos::Byte(b) => write!(f, "byte {b}"),
        }
    }
}

/// A DXF reading error, located.
#[derive(Debug, Error)]
pub enum DxfError {
    /// The file is not valid DXF (or holds what we refuse, such as a block
    /// bomb) at this position.
    #[error("{pos}: {msg}")]
    Syntax {
        /// Where the problem lies.
        pos: Pos,
        /// What it is, for the user.
        msg: String,
    },
    /// The input could not be read.
    #[error("read error: {0}")]
    Io(#[from] std::io::Error),
}

impl DxfError {
    /// A [`DxfError::Syntax`] at `pos`.
    pub fn at(pos: Pos, msg: impl Into<String>) -> Self {
        DxfError::Syntax { pos, msg: msg.into() }
    }
}

/// The value type a group code carries (DXF reference, "Group code value
/// types").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Text (also handles, and codes we do not know).
    Str,
    /// A double: coordinates, distances, angles, scales.
    Float,
    /// A 16-bit integer (flags, counts, colours).
    Int16,
    /// A 32-bit integer.
    Int32,
    /// A 64-bit integer.
    Int64,
    /// A boolean (one byte in binary files, 0 or 1 in ASCII).
    Bool,
    /// A binary chunk (hex text in ASCII files); its content is dropped.
    Binary,
}

/// The kinds of group codes 0 to 1071 (one load per tag instead of a
/// chain of range tests).
static KINDS: [Kind; 1072] = {
    let mut t = [Kind::Str; 1072];
    let mut c = 0;
    while c < 1072 {
        t[c] = kind_by_range(c as i32);
        c += 1;
    }
    t
};

/// The value type group code `code` carries; codes outside 0..=1071 read
/// as text.
#[inline]
pub fn kind_of(code: i32) -> Kind {
    match usize::try_from(code) {
        Ok(c) if c < KINDS.len() => KINDS[c],
        _ => Kind::Str,
    }
}

const fn kind_by_range(code: i32) -> Kind {
    match code {
        0..=9 => Kind::Str,
        10..=59 => Kind::Float,
        60..=79 => Kind::Int16,
        90..=99 => Kind::Int32,
        100..=109 => Kind::Str,
        110..=149 => Kind::Float,
        160..=169 => Kind::Int64,
        170..=179 => Kind::Int16,
        210..=239 => Kind::Float,
        270..=289 => Kind::Int16,
        290..=299 => Kind::Bool,
        300..=309 => Kind::Str,
        310..=319 => Kind::Binary,
        320..=369 => Kind::Str,
        370..=389 => Kind::Int16,
        390..=399 => Kind::Str,
        400..=409 => Kind::Int16,
        410..=419 => Kind::Str,
        420..=429 => Kind::Int32,
        430..=439 => Kind::Str,
        440..=459 => Kind::Int32,
        460..=469 => Kind::Float,
        470..=481 => Kind::Str,
        999 => Kind::Str,
        1000..=1003 => Kind::Str,
        1004 => Kind::Binary,
        1005..=1009 => Kind::Str,
        1010..=1059 => Kind::Float,
        1060..=1070 => Kind::Int16,
        1071 => Kind::Int32,
        // Unknown codes: keep the text; nothing downstream reads them.
        _ => Kind::Str,
    }
}

const BINARY_SENTINEL: &[u8; 22] = b"AutoCAD Binary DXF\r\n\x1a\0";

enum Mode {
    Ascii,
    /// R12 binary files write group codes as one byte (255 escapes to a
    /// 16-bit code); later versions always use two bytes.
    Binary {
        wide_codes: bool,
    },
}

/// The tokenizer. After [`Reader::next_tag`] returns `Some(code)`, the value is
/// available through [`Reader::float`], [`Reader::int`] or [`Reader::text`]
/// according to the code's kind.
pub struct Reader {
    mode: Mode,
    /// ASCII: blocks tokenized ahead on the thread pool.
    ascii: Option<Ascii>,
    /// Binary: the byte stream.
    input: Box<dyn BufRead>,
    /// Binary: bytes consumed so far.
    count: u64,
    buf: Vec<u8>,
    /// The current tag's group code (what [`Reader::next_tag`] returned).
    pub code: i32,
    /// Where the current tag's group code sits, for error messages.
    pub pos: Pos,
    float: f64,
    int: i64,
    text: String,
    /// ASCII: the current tag (a string's text lives in its block).
    tag: Option<Tag>,
    peeked: bool,
}

/// Bytes per block handed to a tokenizing thread, and blocks in flight:
/// enough to keep both cores busy, little next to the geometry. Half a
/// megabyte rather than two (28 November 2026): a block and its tags then
/// stay in a core's cache between the tokenizer and the parser, the parser
/// starts after a quarter of the wait for the first block, and the mix
/// benchmark takes 6,000 fewer page faults; whole runs 0.94x on the mix
/// and dxf drawings (interleaved medians), 0.95x with three blocks ahead
/// instead of four.
const BLOCK: usize = 1 << 19;
const AHEAD: usize = 4;

/// A block being tokenized, or (the whole of a small input, the last
/// block) already done.
enum Pending {
    Ready(TokenBlock),
    /// On the rayon pool; the result (or the tokenizer's panic) comes back
    /// over the channel.
    Task(std::sync::mpsc::Receiver<std::thread::Result<TokenBlock>>),
    /// On a thread of its own, when the reader itself runs on the pool.
    Thread(std::thread::JoinHandle<TokenBlock>),
}

/// ASCII input: the file is read in blocks of whole lines, each tokenized
/// on the pool (or a thread of its own) while the caller consumes the
/// earlier ones in order.
struct Ascii {
    /// Bytes read but not yet in a block: `carry[..filled]` (see
    /// [`Ascii::read_block`]).
    carry: Vec<u8>,
    filled: usize,
    eof: bool,
    ahead: VecDeque<Pending>,
    cur: TokenBlock,
    /// Next tag of `cur`.
    idx: usize,
    /// Lines before `cur`'s first line.
    base: u64,
    /// Buffers of consumed blocks, to be filled again: the same few
    /// megabytes serve the whole file (allocating and freeing one block
    /// after another leaves the allocator holding far more).
    spare_bytes: Vec<Vec<u8>>,
    spare_tags: Vec<Vec<Tag>>,
}

impl Ascii {
    /// Read the next block's bytes from `input` (`None` at the end).
    ///
    /// `carry[..filled]` holds the bytes read and not yet in a block; the
    /// rest of `carry` is bytes already written once, which the next read
    /// overwrites. `read_to_end` zeroes the spare capacity it reads into on
    /// every call: 35 MB of `memset` on the reading thread for the mix
    /// benchmark's 35 MB. Reading into a buffer that is already
    /// initialised zeroes only what it grows by, and the buffers go round
    /// (a block's bytes come back as a spare), so after the first few
    /// blocks almost nothing.
    fn read_block(&mut self, input: &mut dyn BufRead) -> std::io::Result<Option<Vec<u8>>> {
        loop {
            if !self.eof && self.filled < BLOCK {
                if self.carry.len() < BLOCK {
                    self.carry.resize(BLOCK, 0);
                }
                while self.filled < BLOCK {
                    match input.read(&mut self.carry[self.filled..BLOCK]) {
                        Ok(0) => {
                            self.eof = true;
                            break;
                        }
                        Ok(n) => self.filled += n,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                        Err(e) => return Err(e),
                    }
                }
            }
            if self.filled == 0 {
                return Ok(None);
            }
            if self.eof {
                self.carry.truncate(self.filled);
                self.filled = 0;
                return Ok(Some(std::mem::take(&mut self.carry)));
            }
            match tokens::cut(&self.carry[..self.filled]) {
                Some(k) => {
                    let mut rest = self.spare_bytes.pop().unwrap_or_default();
                    let r = self.filled - k;
                    if rest.len() < r {
                        rest.resize(r, 0);
                    }
                    rest[..r].copy_from_slice(&self.carry[k..self.filled]);
                    self.carry.truncate(k);
                    self.filled = r;
                    return Ok(Some(std::mem::replace(&mut self.carry, rest)));
                }
                // One line longer than a block: read on.
                None => {
                    self.carry.truncate(self.filled);
                    let more = input.take(BLOCK as u64).read_to_end(&mut self.carry)?;
                    self.filled = self.carry.len();
                    if more == 0 {
                        self.eof = true;
                    }
                }
            }
        }
    }

    /// Keep `AHEAD` blocks tokenizing.
    fn fill(&mut self, input: &mut dyn BufRead) -> std::io::Result<()> {
        while self.ahead.len() < AHEAD {
            let Some(bytes) = self.read_block(input)? else {
                break;
            };
            let tags = self.spare_tags.pop().unwrap_or_default();
            if self.eof && self.filled == 0 && self.ahead.is_empty() {
                // The last block and nothing else to wait for: no thread.
                self.ahead.push_back(Pending::Ready(tokens::tokenize_into(bytes, tags)));
            } else if rayon::current_thread_index().is_some() {
                // Read from inside the pool: waiting here for a task queued
                // behind this very thread could wait for ever.
                self.ahead.push_back(Pending::Thread(std::thread::spawn(move || {
                    tokens::tokenize_into(bytes, tags)
                })));
            } else {
                // On the pool, idle while a drawing is read: a thread of
                // its own per block cost a thread's start and stack, 68
                // times on the mix benchmark.
                let (tx, rx) = std::sync::mpsc::sync_channel(1);
                rayon::spawn(move || {
                    let block =
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| tokens::tokenize_into(bytes, tags)));
                    // The reader may have gone (an error ahead): nothing to do.
                    let _ = tx.send(block);
                });
                self.ahead.push_back(Pending::Task(rx));
            }
        }
        Ok(())
    }

    /// Make `next` the current block; the old one's buffers are kept for
    /// the blocks to come.
    fn advance(&mut self, next: TokenBlock) {
        let old = std::mem::replace(&mut self.cur, next);
        if self.spare_bytes.len() < 2 {
            self.spare_bytes.push(old.bytes);
        }
        if self.spare_tags.len() < 2 {
            self.spare_tags.push(old.tags);
        }
    }

    /// The next block in file order, or `None` at the end.
    fn next_block(&mut self, input: &mut dyn BufRead) -> std::io::Result<Option<TokenBlock>> {
        self.fill(input)?;
        match self.ahead.pop_front() {
            None => Ok(None),
            Some(p) => {
                let b = match p {
                    Pending::Ready(b) => b,
                    Pending::Task(rx) => rx
                        .recv()
                        .ok()
                        .and_then(Result::ok)
                        .ok_or_else(|| std::io::Error::other("a tokenizing task failed"))?,
                    Pending::Thread(h) => h
                        .join()
                        .map_err(|_| std::io::Error::other("a tokenizing thread failed"))?,
                };
                self.fill(input)?;
                Ok(Some(b))
            }
        }
    }
}

impl Reader {
    /// Sniff binary vs ASCII from the first bytes, then stream.
    pub fn new(mut input: Box<dyn BufRead>) -> Result<Reader, DxfError> {
        let mut head = Vec::with_capacity(24);
        (&mut input).take(24).read_to_end(&mut head)?;
        let (mode, rest): (Mode, Vec<u8>) = if head.len() >= 22 && &head[..22] == BINARY_SENTINEL {
            // The first tag is (0, "SECTION"): in the one-byte form the byte
            // after the code 0 is 'S', in the two-byte form it is 0.
            let wide = head.get(23) == Some(&0);
            (Mode::Binary { wide_codes: wide }, head[22..].to_vec())
        } else {
            (Mode::Ascii, head)
        };
        let count = match mode {
            Mode::Ascii => 0,
            Mode::Binary { .. } => 22,
        };
        let (input, ascii): (Box<dyn BufRead>, Option<Ascii>) = match mode {
            Mode::Ascii => {
                let mut a = Ascii {
                    filled: rest.len(),
                    carry: rest,
                    eof: false,
                    ahead: VecDeque::new(),
                    cur: tokens::tokenize(Vec::new()),
                    idx: 0,
                    base: 0,
                    spare_bytes: Vec::new(),
                    spare_tags: Vec::new(),
                };
                a.fill(&mut input)?;
                (input, Some(a))
            }
            Mode::Binary { .. } => (
                Box::new(BufReader::with_capacity(1 << 16, Cursor::new(rest).chain(input))),
                None,
            ),
        };
        Ok(Reader {
            mode,
            ascii,
            input,
            count,
            buf: Vec::with_capacity(256),
            code: 0,
            pos: Pos::Line(0),
            float: 0.0,
            int: 0,
            text: String::new(),
            tag: None,
            peeked: false,
        })
    }

    /// True for a binary DXF (sniffed from its sentinel), false for ASCII.
    pub fn is_binary(&self) -> bool {
        matches!(self.mode, Mode::Binary { .. })
    }

    /// Push the current tag back so the next [`Reader::next_tag`] returns it again.
    pub fn unread(&mut self) {
        self.peeked = true;
    }

    /// The next tag's group code, or `None` at the end of the input.
    ///
    /// Inline for the common case, the next tag of the current ASCII block
    /// (a few million calls on a large drawing: the call itself had cost
    /// more than the work); the rest goes through `next_tag_slow`.
    #[inline]
    pub fn next_tag(&mut self) -> Result<Option<i32>, DxfError> {
        if !self.peeked
            && let Some(a) = self.ascii.as_mut()
            && let Some(&t) = a.cur.tags.get(a.idx)
        {
            a.idx += 1;
            let base = a.base;
            return Ok(Some(self.accept(t, base)));
        }
        self.next_tag_slow()
    }

    /// Make `t` (of the block whose first line follows line `base`) the
    /// current tag and return its code.
    #[inline]
    fn accept(&mut self, t: Tag, base: u64) -> i32 {
        let code = t.code as i32;
        self.code = code;
        self.pos = Pos::Line(base + t.line as u64);
        match kind_of(code) {
            Kind::Float => self.float = f64::from_bits(t.val),
            Kind::Int16 | Kind::Int32 | Kind::Int64 | Kind::Bool => self.int = t.val as i64,
            Kind::Str | Kind::Binary => {}
        }
        self.tag = Some(t);
        code
    }

    /// [`Reader::next_tag`] past the current block, after an unread, or
    /// in a binary file.
    #[inline(never)]
    fn next_tag_slow(&mut self) -> Result<Option<i32>, DxfError> {
        if self.peeked {
            self.peeked = false;
            return Ok(Some(self.code));
        }
        match self.mode {
            Mode::Ascii => self.next_ascii(),
            Mode::Binary { wide_codes } => self.next_binary(wide_codes),
        }
    }

    /// The current tag's value, when its code is of [`Kind::Float`]
    /// (otherwise the last float read).
    pub fn float(&self) -> f64 {
        self.float
    }

    /// The current tag's value, when its code is an integer or boolean kind
    /// (otherwise the last integer read).
    pub fn int(&self) -> i64 {
        self.int
    }

    /// The current tag's text, when its code is of [`Kind::Str`] (lossily
    /// decoded when not UTF-8). A [`Kind::Binary`] chunk reads as its hex
    /// text in an ASCII file and as empty in a binary one.
    pub fn text(&self) -> &str {
        match (&self.ascii, &self.tag) {
            (Some(a), Some(t)) => a.cur.text(t),
            _ => &self.text,
        }
    }

    /// The value as a number whatever its declared kind (some writers put
    /// integers where floats belong and the reverse).
    pub fn number(&self) -> f64 {
        match kind_of(self.code) {
            Kind::Float => self.float,
            Kind::Int16 | Kind::Int32 | Kind::Int64 | Kind::Bool => self.int as f64,
            _ => self.text().trim().parse().unwrap_or(f64::NAN),
        }
    }

    fn next_ascii(&mut self) -> Result<Option<i32>, DxfError> {
        let Some(a) = self.ascii.as_mut() else {
            return Ok(None);
        };
        loop {
            if let Some(&t) = a.cur.tags.get(a.idx) {
                a.idx += 1;
                let base = a.base;
                return Ok(Some(self.accept(t, base)));
            }
            let input = &mut *self.input;
            match std::mem::replace(&mut a.cur.end, End::Clean) {
                End::Clean => {
                    let Some(next) = a.next_block(input)? else {
                        return Ok(None);
                    };
                    a.base += a.cur.lines;
                    a.advance(next);
                    a.idx = 0;
                    self.tag = None;
                }
                End::Error { line, msg } => return Err(DxfError::at(Pos::Line(a.base + line as u64), msg)),
                End::Blank { line } => {
                    // Only more blank lines may follow, to the end.
                    while let Some(next) = a.next_block(input)? {
                        if !next.blank_only {
                            return Err(DxfError::at(
                                Pos::Line(a.base + line as u64),
                                "empty line where a group code belongs",
                            ));
                        }
                    }
                    return Ok(None);
                }
                End::Dangling { line, off, code } => {
                    let Some(next) = a.next_block(input)? else {
                        return Err(DxfError::at(
                            Pos::Line(a.base + line as u64),
                            format!("file ends after group code {code}: truncated file?"),
                        ));
                    };
                    // The block was cut inside a tag: tokenize again from
                    // the code line on, joined to the next block.
                    let mut bytes = a.cur.bytes.split_off(off);
                    bytes.extend_from_slice(&next.bytes);
                    drop(next);
                    a.base += line as u64 - 1;
                    a.cur = tokens::tokenize(bytes);
                    a.idx = 0;
                    self.tag = None;
                }
            }
        }
    }

    fn byte(&mut self, what: &str) -> Result<u8, DxfError> {
        let mut b = [0u8; 1];
        self.exact(&mut b, what)?;
        Ok(b[0])
    }

    fn exact(&mut self, out: &mut [u8], what: &str) -> Result<(), DxfError> {
        match self.input.read_exact(out) {
            Ok(()) => {
                self.count += out.len() as u64;
                Ok(())
            }
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Err(DxfError::at(
                Pos::Byte(self.count),
                format!("file ends inside {what}: truncated file?"),
            )),
            Err(e) => Err(e.into()),
        }
    }

    fn next_binary(&mut self, wide: bool) -> Result<Option<i32>, DxfError> {
        let start = self.count;
        self.pos = Pos::Byte(start);
        // End of input exactly at a tag boundary is a normal end.
        if self.input.fill_buf()?.is_empty() {
            return Ok(None);
        }
        let code = if wide {
            let mut b = [0u8; 2];
            self.exact(&mut b, "a group code")?;
            i16::from_le_bytes(b) as i32
        } else {
            let b = self.byte("a group code")?;
            if b == 255 {
                let mut w = [0u8; 2];
                self.exact(&mut w, "a group code")?;
                i16::from_le_bytes(w) as i32
            } else {
                b as i32
            }
        };
        if !(-5..=1071).contains(&code) {
            return Err(DxfError::at(
                Pos::Byte(start),
                format!("group code {code} is out of range: not a DXF file, or a corrupt one"),
            ));
        }
        self.code = code;
        match kind_of(code) {
            Kind::Float => {
                let mut b = [0u8; 8];
                self.exact(&mut b, "a floating-point value")?;
                self.float = f64::from_le_bytes(b);
            }
            Kind::Int16 => {
                let mut b = [0u8; 2];
                self.exact(&mut b, "an integer value")?;
                self.int = i16::from_le_bytes(b) as i64;
            }
            Kind::Int32 => {
                let mut b = [0u8; 4];
                self.exact(&mut b, "an integer value")?;
                self.int = i32::from_le_bytes(b) as i64;
            }
            Kind::Int64 => {
                let mut b = [0u8; 8];
                self.exact(&mut b, "an integer value")?;
                self.int = i64::from_le_bytes(b);
            }
            Kind::Bool => {
                self.int = self.byte("a boolean value")? as i64;
            }
            Kind::Binary => {
                let n = self.byte("a binary chunk length")? as usize;
                let mut b = vec![0u8; n];
                self.exact(&mut b, "a binary chunk")?;
                self.text.clear();
            }
            Kind::Str => {
                self.buf.clear();
                let n = self.input.read_until(0, &mut self.buf)?;
                self.count += n as u64;
                if self.buf.last() != Some(&0) {
                    return Err(DxfError::at(
                        Pos::Byte(self.count),
                        "file ends inside a string: truncated file?",
                    ));
                }
                self.buf.pop();
                if self.buf.len() > 65_536 {
                    return Err(DxfError::at(
                        Pos::Byte(start),
                        "string value longer than 64 KiB: corrupt file?",
                    ));
                }
                self.text.clear();
                self.text.push_str(&String::from_utf8_lossy(&self.buf));
            }
        }
        Ok(Some(code))
    }
}

pub(super) fn shorten(s: &str) -> String {
    // Binary garbage must not reach the terminal as is.
    let mut t: String = s
        .chars()
        .take(40)
        .map(|c| if c.is_ascii_graphic() || c == ' ' { c } else { '?' })
        .collect();
    if s.chars().count() > 40 {
        t.push_str("...");
    }
    t
}

pub(super) fn bad_number_msg(code: i32, t: &[u8]) -> String {
    let s = String::from_utf8_lossy(t);
    let hint = if s.contains(',') && s.replace(',', ".").parse::<f64>().is_ok() {
        " (a decimal comma? DXF numbers use a decimal point)"
    } else {
        ""
    };
    format!("group code {code} needs a number, found '{}'{hint}", shorten(&s))
}

pub(super) fn parse_float(t: &[u8]) -> Option<f64> {
    let s = std::str::from_utf8(t).ok()?;
    let v: f64 = s.parse().ok()?;
    v.is_finite().then_some(v)
}

pub(super) fn parse_int(t: &[u8]) -> Option<i64> {
    let s = std::str::from_utf8(t).ok()?;
    if let Ok(v) = s.parse::<i64>() {
        return Some(v);
    }
    // Some writers print integers as "1.0"; accept only whole values.
    let f: f64 = s.parse().ok()?;
    (f.is_finite() && f.fract() == 0.0 && f.abs() < 9e15).then_some(f as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reader(bytes: &[u8]) -> Reader {
        Reader::new(Box::new(Cursor::new(bytes.to_vec()))).unwrap()
    }

    #[test]
    fn ascii_tags_and_numbers() {
        let mut r = reader(b"  0\r\nSECTION\r\n 10\r\n1.5\r\n 70\r\n     3\r\n");
        assert_eq!(r.next_tag().unwrap(), Some(0));
        assert_eq!(r.text(), "SECTION");
        assert_eq!(r.next_tag().unwrap(), Some(10));
        assert_eq!(r.float(), 1.5);
        assert_eq!(r.next_tag().unwrap(), Some(70));
        assert_eq!(r.int(), 3);
        assert_eq!(r.next_tag().unwrap(), None);
    }

    /// A reader that hands out at most a few bytes per call, as a pipe
    /// may.
    struct Trickle {
        data: Vec<u8>,
        at: usize,
        step: usize,
    }

    impl std::io::Read for Trickle {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.step = self.step % 7 + 1;
            let n = buf.len().min(self.step * 997).min(self.data.len() - self.at);
            buf[..n].copy_from_slice(&self.data[self.at..self.at + n]);
            self.at += n;
            Ok(n)
        }
    }

    /// Every tag as (code, line, value text or number), to the end.
    fn all_tags(mut r: Reader) -> Vec<(i32, String, String)> {
        let mut out = Vec::new();
        while let Some(c) = r.next_tag().unwrap() {
            let v = match kind_of(c) {
                Kind::Float => r.float().to_string(),
                Kind::Int16 | Kind::Int32 | Kind::Int64 | Kind::Bool => r.int().to_string(),
                _ => r.text().to_string(),
            };
            out.push((c, format!("{:?}", r.pos), v));
        }
        out
    }

    #[test]
    fn blocks_over_short_reads_and_a_long_line_give_every_tag_once() {
        // Three blocks and more of entities, a comment line longer than a
        // block in the middle, read whole and through short reads: the
        // buffers go round (each block's bytes come back as a spare and
        // are read into again), and nothing of one block may show in the
        // next.
        let mut t = String::from("  0\nSECTION\n  2\nENTITIES\n");
        for k in 0..40_000 {
            t += &format!("  0\nLINE\n  8\nL{}\n 10\n{}.25\n 20\n-{}.5\n", k % 7, k, k * 3);
            if k == 17_000 {
                t += &format!("999\n{}\n", "x".repeat(BLOCK + 12_345));
            }
        }
        t += "  0\nENDSEC\n  0\nEOF\n";
        assert!(t.len() > 3 * BLOCK);
        let whole = all_tags(reader(t.as_bytes()));
        let trickled = all_tags(
            Reader::new(Box::new(std::io::BufReader::with_capacity(
                64,
                Trickle {
                    data: t.clone().into_bytes(),
                    at: 0,
                    step: 0,
                },
            )))
            .unwrap(),
        );
        assert_eq!(whole.len(), 2 + 40_000 * 4 + 1 + 2);
        assert_eq!(trickled, whole);
        let long = whole.iter().find(|x| x.0 == 999).unwrap();
        assert_eq!(long.2.len(), BLOCK + 12_345);
        let last_line = whole.iter().rev().find(|x| x.0 == 20).unwrap();
        assert_eq!(last_line.2, format!("{}", -(39_999.0 * 3.0 + 0.5)));
    }

    #[test]
    fn reading_from_inside_a_one_thread_pool_finishes() {
        // The pool's only thread reads: tokenizing tasks queued on that
        // pool would never run while it waits for them.
        let mut t = String::from("  0\nSECTION\n  2\nENTITIES\n");
        for k in 0..60_000 {
            t += &format!("  0\nPOINT\n 10\n{k}.5\n 20\n1.25\n");
        }
        t += "  0\nENDSEC\n  0\nEOF\n";
        assert!(t.len() > 3 * BLOCK);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let n = pool.install(|| all_tags(reader(t.as_bytes())).len());
        assert_eq!(n, 2 + 60_000 * 3 + 2);
    }

    #[test]
    fn decimal_comma_is_located() {
        let mut r = reader(b"0\nSECTION\n10\n-6,5\n");
        r.next_tag().unwrap();
        let e = r.next_tag().unwrap_err().to_string();
        assert!(e.starts_with("line 4:"), "{e}");
        assert!(e.contains("decimal comma"), "{e}");
    }

    #[test]
    fn truncated_after_code() {
        let mut r = reader(b"0\nSECTION\n10\n");
        r.next_tag().unwrap();
        let e = r.next_tag().unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("truncated"), "{e}");
    }

    #[test]
    fn garbage_code() {
        let mut r = reader(b"0\nSECTION\nhello\nx\n");
        r.next_tag().unwrap();
        let e = r.next_tag().unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("group code"), "{e}");
    }

    #[test]
    fn binary_one_byte_codes() {
        let mut b = BINARY_SENTINEL.to_vec();
        b.extend_from_slice(b"\0SECTION\0");
        b.push(10);
        b.extend_from_slice(&2.5f64.to_le_bytes());
        b.push(70);
        b.extend_from_slice(&7i16.to_le_bytes());
        let mut r = reader(&b);
        assert!(r.is_binary());
        assert_eq!(r.next_tag().unwrap(), Some(0));
        assert_eq!(r.text(), "SECTION");
        assert_eq!(r.next_tag().unwrap(), Some(10));
        assert_eq!(r.float(), 2.5);
        assert_eq!(r.next_tag().unwrap(), Some(70));
        assert_eq!(r.int(), 7);
        assert_eq!(r.next_tag().unwrap(), None);
    }

    #[test]
    fn binary_two_byte_codes_and_truncation() {
        let mut b = BINARY_SENTINEL.to_vec();
        b.extend_from_slice(&0i16.to_le_bytes());
        b.extend_from_slice(b"SECTION\0");
        b.extend_from_slice(&10i16.to_le_bytes());
        b.extend_from_slice(&[1, 2, 3]);
        let mut r = reader(&b);
        assert_eq!(r.next_tag().unwrap(), Some(0));
        let e = r.next_tag().unwrap_err().to_string();
        assert!(e.contains("byte") && e.contains("truncated"), "{e}");
    }
}
