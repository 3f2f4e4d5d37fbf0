//! The Turbo PMAC Ethernet protocol: the 8-byte request header, the request
//! codes, the reply framing with I3=2 and I6=1, and WRITEBUFFER packing.
//!
//! Both the client and the emulator use these functions, so the two sides
//! cannot drift apart on a byte; every parser here takes untrusted bytes
//! and answers an error, never a panic.

use thiserror::Error;

/// The controller's TCP port for the Ethernet protocol.
pub const PMAC_PORT: u16 = 1025;
/// RequestType of a host-to-controller request carrying a payload.
pub const VR_DOWNLOAD: u8 = 0x40;
/// RequestType of a request that only asks for data.
pub const VR_UPLOAD: u8 = 0xC0;

// Request codes (the header's second byte), as the Turbo PMAC manual names
// them.
/// Send one command line; its reply is kept for GETLINE (the answer is a
/// single 0x40 byte).
pub const SENDLINE: u8 = 0xB0;
/// Fetch reply text kept from SENDLINE (a single 0 when there is none).
pub const GETLINE: u8 = 0xB1;
/// Drop every reply text not yet fetched.
pub const FLUSH: u8 = 0xB3;
/// Send one command line and get its reply text in the answer.
pub const GETRESPONSE: u8 = 0xBF;
/// Ask whether SENDLINE reply text waits (first byte 1) or not (0).
pub const READREADY: u8 = 0xC2;
/// Send a control character (header value) and get its reply text.
pub const CTRL_RESPONSE: u8 = 0xC4;
/// Fetch the next [`REPLY_CHUNK`] of a reply too long for one answer.
pub const GETBUFFER: u8 = 0xC5;
/// Send up to [`WRITEBUFFER_MAX`] bytes of NUL-terminated lines at once;
/// the answer is a 4-byte status ([`writebuffer_status`]).
pub const WRITEBUFFER: u8 = 0xC6;

/// Largest reply chunk; longer replies continue on GETBUFFER.
pub const REPLY_CHUNK: usize = 1400;
/// Largest WRITEBUFFER payload.
pub const WRITEBUFFER_MAX: usize = 1024;

/// Ends a complete data reply (I3=2).
pub const ACK: u8 = 0x06;
/// Starts an error reply, `BEL ERRnnn CR` (I6=1).
pub const BEL: u8 = 0x07;
/// Ends each line of reply text.
pub const CR: u8 = 0x0D;

/// The request header; 16-bit fields are big-endian on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// [`VR_DOWNLOAD`] (a payload follows) or [`VR_UPLOAD`].
    pub request_type: u8,
    /// The request code ([`GETRESPONSE`], [`WRITEBUFFER`], ...).
    pub request: u8,
    /// Request argument: the control character of [`CTRL_RESPONSE`], else 0.
    pub value: u16,
    /// Request argument, 0 in every request this crate makes.
    pub index: u16,
    /// Payload bytes following a download request, or the most reply bytes
    /// an upload request wants.
    pub length: u16,
}

impl Header {
    /// A header with `value` and `index` zero.
    pub fn new(request_type: u8, request: u8, length: u16) -> Self {
        Header {
            request_type,
            request,
            value: 0,
            index: 0,
            length,
        }
    }

    /// The 8 bytes on the wire.
    pub fn encode(&self) -> [u8; 8] {
        let v = self.value.to_be_bytes();
        let i = self.index.to_be_bytes();
        let l = self.length.to_be_bytes();
        [self.request_type, self.request, v[0], v[1], i[0], i[1], l[0], l[1]]
    }

    /// A header from its 8 wire bytes (any bytes make a header; the
    /// request code is checked by whoever serves it).
    pub fn decode(b: &[u8; 8]) -> Self {
        Header {
            request_type: b[0],
            request: b[1],
            value: u16::from_be_bytes([b[2], b[3]]),
            index: u16::from_be_bytes([b[4], b[5]]),
            length: u16::from_be_bytes([b[6], b[7]]),
        }
    }

    /// A download request carries `length` payload bytes after the header.
    pub fn has_payload(&self) -> bool {
        self.request_type == VR_DOWNLOAD
    }
}

/// Protocol-level faults (not controller ERR replies).
#[derive(Debug, Error, PartialEq, Eq)]
pub enum ProtocolError {
    /// A command of this many bytes exceeds the packet limit (the second
    /// number).
    #[error("command of {0} bytes is too long for one packet (limit {1})")]
    TooLong(usize, usize),
    /// A command holds a byte below 0x20 or DEL, which would end or garble
    /// it on the controller.
    #[error("command contains a control character or NUL")]
    BadChar,
    /// The controller's answer does not follow the framing; the text says
    /// what was wrong.
    #[error("malformed reply: {0}")]
    BadReply(String),
}

/// A GETRESPONSE request for one command line (no CR), in one buffer so
/// it goes out in one write.
pub fn getresponse(cmd: &str) -> Result<Vec<u8>, ProtocolError> {
    check_command(cmd, u16::MAX as usize)?;
    let mut v = Header::new(VR_DOWNLOAD, GETRESPONSE, cmd.len() as u16)
        .encode()
        .to_vec();
    v.extend_from_slice(cmd.as_bytes());
    Ok(v)
}

/// A request with no payload (GETBUFFER, READREADY, FLUSH ...).
pub fn upload_request(request: u8, want: u16) -> [u8; 8] {
    Header::new(VR_UPLOAD, request, want).encode()
}

/// A VR_CTRL_RESPONSE request for control character `ch` (e.g. 0x07 ^G).
pub fn ctrl_response(ch: u8) -> [u8; 8] {
    let mut h = Header::new(VR_UPLOAD, CTRL_RESPONSE, REPLY_CHUNK as u16);
    h.value = u16::from(ch);
    h.encode()
}

/// The control character of a VR_CTRL_RESPONSE: clients disagree on the
/// byte order of wValue, so take whichever byte is set.
pub fn ctrl_char(value: u16) -> u8 {
    let [hi, lo] = value.to_be_bytes();
    if lo != 0 { lo } else { hi }
}

fn check_command(cmd: &str, limit: usize) -> Result<(), ProtocolError> {
    if cmd.len() > limit {
        return Err(ProtocolError::TooLong(cmd.len(), limit));
    }
    if cmd.bytes().any(|c| c < 0x20 || c == 0x7F) {
        return Err(ProtocolError::BadChar);
    }
    Ok(())
}

/// One WRITEBUFFER packet: the request bytes and how many lines it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Header and payload, ready to write.
    pub bytes: Vec<u8>,
    /// Program lines in the payload.
    pub lines: usize,
}

/// Pack lines into WRITEBUFFER packets, each line NUL-terminated, at most
/// [`WRITEBUFFER_MAX`] payload bytes per packet. A line that cannot fit
/// one packet on its own is an error (the controller would truncate it).
pub fn pack_lines<S: AsRef<str>>(lines: &[S]) -> Result<Vec<Packet>, ProtocolError> {
    let mut out = Vec::new();
    let mut payload: Vec<u8> = Vec::with_capacity(WRITEBUFFER_MAX);
    let mut n = 0usize;
    for l in lines {
        let l = l.as_ref();
        check_command(l, WRITEBUFFER_MAX - 1)?;
        if payload.len() + l.len() + 1 > WRITEBUFFER_MAX {
            out.push(finish_packet(&payload, n));
            payload.clear();
            n = 0;
        }
        payload.extend_from_slice(l.as_bytes());
        payload.push(0);
        n += 1;
    }
    if n > 0 {
        out.push(finish_packet(&payload, n));
    }
    Ok(out)
}

fn finish_packet(payload: &[u8], lines: usize) -> Packet {
    let mut bytes = Header::new(VR_DOWNLOAD, WRITEBUFFER, payload.len() as u16)
        .encode()
        .to_vec();
    bytes.extend_from_slice(payload);
    Packet { bytes, lines }
}

/// The 4-byte WRITEBUFFER status: `None` when all lines were taken, else
/// the failing line (0-based within the packet) and its ERR number.
pub fn writebuffer_status(ok: Option<(u16, u16)>) -> [u8; 4] {
    match ok {
        None => [0, 0, 0, 0],
        Some((line, err)) => {
            let l = line.to_le_bytes();
            [l[0], l[1], err.min(255) as u8, 0x80]
        }
    }
}

/// Decode a WRITEBUFFER status reply (see [`writebuffer_status`]).
pub fn parse_writebuffer_status(b: &[u8]) -> Result<Option<(u16, u16)>, ProtocolError> {
    match b {
        [_, _, _, 0] => Ok(None),
        [l0, l1, e, 0x80 | 0xFF] => Ok(Some((u16::from_le_bytes([*l0, *l1]), u16::from(*e)))),
        _ => Err(ProtocolError::BadReply(format!("WRITEBUFFER status {b:02X?}"))),
    }
}

/// Frame a controller answer as I3=2, I6=1 reply text: data lines each
/// ended by CR then ACK, or BEL ERRnnn CR.
pub fn frame_reply(result: &Result<Vec<String>, u16>) -> Vec<u8> {
    match result {
        Ok(lines) => {
            let mut v = Vec::with_capacity(lines.iter().map(|l| l.len() + 1).sum::<usize>() + 1);
            for l in lines {
                v.extend_from_slice(l.as_bytes());
                v.push(CR);
            }
            v.push(ACK);
            v
        }
        Err(code) => format!("\x07ERR{code:03}\r").into_bytes(),
    }
}

/// What a complete reply says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// The lines of reply text (without CR; none for a command that
    /// answers nothing).
    Data(Vec<String>),
    /// The controller refused the command: `ERRnnn`'s number.
    Error(u16),
}

/// Decode reply text if it is complete; `Ok(None)` means more bytes are
/// needed. Text after an error is ignored.
pub fn parse_reply(b: &[u8]) -> Result<Option<Reply>, ProtocolError> {
    if let Some(p) = b.iter().position(|&c| c == BEL) {
        let rest = &b[p + 1..];
        let Some(end) = rest.iter().position(|&c| c == CR) else {
            return Ok(None);
        };
        let text = std::str::from_utf8(&rest[..end]).map_err(|_| ProtocolError::BadReply("non-ASCII error".into()))?;
        let code = text
            .strip_prefix("ERR")
            .and_then(|d| d.trim().parse::<u16>().ok())
            .ok_or_else(|| ProtocolError::BadReply(format!("error text '{}'", text.escape_debug())))?;
        return Ok(Some(Reply::Error(code)));
    }
    match b.last() {
        Some(&ACK) => {
            let body = &b[..b.len() - 1];
            let text = String::from_utf8_lossy(body);
            let lines = text
                .split('\r')
                .filter(|l| !l.is_empty())
                .map(|l| l.trim_matches(['\n', '\0']).to_string())
                .collect();
            Ok(Some(Reply::Data(lines)))
        }
        Some(0) if b.len() == 1 => Err(ProtocolError::BadReply("controller busy or command lost (NUL)".into())),
        _ => Ok(None),
    }
}

/// Words of controller memory a program line takes: about one per value
/// plus the command word (the Ethernet protocol's request size).
pub fn line_words(line: &str) -> usize {
    let b = line.as_bytes();
    let mut n = 1;
    let mut i = 0;
    while i < b.len() {
        if b[i] == b';' {
            break;
        }
        if b[i].is_ascii_digit() || (b[i] == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit)) {
            n += 1;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
        } else {
            i += 1;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_round_trip_big_endian() {
        let mut h = Header::new(VR_DOWNLOAD, GETRESPONSE, 0x0102);
        h.value = 0x0304;
        let b = h.encode();
        assert_eq!(b, [0x40, 0xBF, 3, 4, 0, 0, 1, 2]);
        assert_eq!(Header::decode(&b), h);
    }

    #[test]
    fn ctrl_char_either_order() {
        assert_eq!(ctrl_char(0x0007), 7);
        assert_eq!(ctrl_char(0x0700), 7);
    }

    #[test]
    fn packing_respects_limit_and_nul() {
        let lines: Vec<String> = (0..500).map(|i| format!("LINEAR X{i} Y{i} P400={i}")).collect();
        let packets = pack_lines(&lines).unwrap();
        assert!(packets.len() > 1);
        assert_eq!(packets.iter().map(|p| p.lines).sum::<usize>(), 500);
        let mut back = Vec::new();
        for p in &packets {
            assert!(p.bytes.len() - 8 <= WRITEBUFFER_MAX);
            let h = Header::decode(p.bytes[..8].try_into().unwrap());
            assert_eq!(h.request, WRITEBUFFER);
            assert_eq!(h.length as usize, p.bytes.len() - 8);
            assert_eq!(*p.bytes.last().unwrap(), 0);
            for l in p.bytes[8..p.bytes.len() - 1].split(|&c| c == 0) {
                back.push(String::from_utf8(l.to_vec()).unwrap());
            }
        }
        assert_eq!(back, lines);
        assert!(pack_lines(&["X".repeat(1024)]).is_err());
        assert!(pack_lines(&["X".repeat(1023)]).is_ok());
    }

    #[test]
    fn replies_parse() {
        let ok = frame_reply(&Ok(vec!["1.945  ".into()]));
        assert_eq!(ok, b"1.945  \r\x06");
        assert_eq!(parse_reply(&ok).unwrap(), Some(Reply::Data(vec!["1.945  ".into()])));
        assert_eq!(parse_reply(b"\x06").unwrap(), Some(Reply::Data(vec![])));
        assert_eq!(parse_reply(b"\x07ERR006\r").unwrap(), Some(Reply::Error(6)));
        assert_eq!(parse_reply(b"\x07ERR00").unwrap(), None);
        assert_eq!(parse_reply(b"12\r").unwrap(), None);
        assert!(parse_reply(b"\x07XYZ\r").is_err());
        assert!(parse_reply(b"\0").is_err());
    }

    #[test]
    fn writebuffer_status_round_trip() {
        assert_eq!(parse_writebuffer_status(&writebuffer_status(None)).unwrap(), None);
        let s = writebuffer_status(Some((300, 6)));
        assert_eq!(parse_writebuffer_status(&s).unwrap(), Some((300, 6)));
        assert!(parse_writebuffer_status(&[1, 2]).is_err());
    }

    #[test]
    fn words_per_line() {
        assert_eq!(line_words("X1000 Y1200 Z1400"), 4);
        assert_eq!(line_words("LINEAR X1.5 Y-.25 F2 P400=3 ; c 9"), 6);
        assert_eq!(line_words(""), 1);
    }

    #[test]
    fn parsers_never_panic_on_bytes() {
        for n in 0..2000u32 {
            let b: Vec<u8> = (0..(n % 17))
                .map(|k| (n.wrapping_mul(2654435761).wrapping_add(k * 97) >> 3) as u8)
                .collect();
            let _ = parse_reply(&b);
            let _ = parse_writebuffer_status(&b);
            let _ = line_words(&String::from_utf8_lossy(&b));
        }
    }
}
