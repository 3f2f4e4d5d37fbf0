//! Block words of the ISO reader: a line normalised (comments and blanks
//! dropped, letters upper-cased), split into its G/M codes and letter
//! words, and checked as LinuxCNC checks them (one code per modal group,
//! no repeated word, no word the block cannot use).

use super::*;

/// Codes of one block, G and M codes kept as ten times their value
/// (G91.1 -> 911) so decimal codes compare exactly.
pub(super) struct Block {
    pub(super) g: [u16; 16],
    pub(super) ng: usize,
    pub(super) m: [u16; 8],
    pub(super) nm: usize,
    /// Value of each letter word A..Z (G, M, N, O not stored here).
    pub(super) w: [Option<f64>; 26],
    /// Polar coordinates: `@` radius and `^` angle (degrees).
    pub(super) polar: [Option<f64>; 2],
    /// Any G code other than G0-G3: most blocks of a large program have
    /// none, and then the modal settings need no looking at.
    pub(super) other_g: bool,
}

impl Block {
    pub(super) fn new() -> Self {
        Block {
            g: [0; 16],
            ng: 0,
            m: [0; 8],
            nm: 0,
            w: [None; 26],
            polar: [None; 2],
            other_g: false,
        }
    }

    pub(super) fn has_g(&self, code: u16) -> bool {
        self.g[..self.ng].contains(&code)
    }

    pub(super) fn has_m(&self, code: u16) -> bool {
        self.m[..self.nm].contains(&code)
    }

    pub(super) fn word(&self, letter: u8) -> Option<f64> {
        self.w[(letter - b'A') as usize]
    }
}

/// What each input byte becomes in a normalised line: 0 = dropped (blank),
/// 0xff = not allowed, `(` and `;` = comment starts, anything else = the
/// byte itself, upper-cased. A table keeps the per-byte work to one load.
pub(super) const NORMALISE: [u8; 256] = {
    let mut t = [0xffu8; 256];
    let mut c = 0x21;
    while c <= 0x7e {
        t[c] = if c >= b'a' as usize && c <= b'z' as usize {
            c as u8 - 32
        } else {
            c as u8
        };
        c += 1;
    }
    t[b' ' as usize] = 0;
    t[b'\t' as usize] = 0;
    t[b'\r' as usize] = 0;
    t
};

/// Modal group of a G code (times ten), or `None` when unknown.
pub(super) fn g_group(code: u16) -> Option<u8> {
    Some(match code {
        0
        | 10
        | 20
        | 30
        | 50..=52
        | 330
        | 331
        | 382..=385
        | 700
        | 710..=712
        | 720..=722
        | 730
        | 740
        | 760
        | 800..=890 => 1,
        // G5.3 is non-modal in LinuxCNC (group 0), G5.2 a motion.
        40 | 53 | 100 | 280 | 281 | 300 | 301 | 520 | 530 | 920..=923 => 0,
        170 | 171 | 180 | 181 | 190 | 191 => 2,
        900 | 910 => 3,
        901 | 911 => 4,
        930 | 940 | 950 => 5,
        200 | 210 => 6,
        400 | 410 | 411 | 420 | 421 => 7,
        430 | 431 | 432 | 490 => 8,
        980 | 990 => 10,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => 12,
        610 | 611 | 640 => 13,
        960 | 970 => 14,
        70 | 80 => 15,
        _ => return None,
    })
}

/// Modal group of an M code, or `None` when unknown.
pub(super) fn m_group(code: u16) -> Option<u8> {
    Some(match code {
        0 | 10 | 20 | 300 | 600 => 4,
        30 | 40 | 50 => 7,
        60 | 610 => 6,
        70 | 80 | 90 => 8,
        480 | 490 | 500 | 510 | 520 | 530 => 9,
        620..=680 | 700..=730 => 5,
        1000..=1990 => 10,
        _ => return None,
    })
}

pub(super) fn fmt_code(letter: char, code: u16) -> String {
    if code.is_multiple_of(10) {
        format!("{letter}{}", code / 10)
    } else {
        format!("{letter}{}.{}", code / 10, code % 10)
    }
}

impl IsoInterpreter {
    /// Fill `self.norm` with the line minus comments and blanks, upper-cased.
    pub(super) fn normalise(&mut self, bytes: &[u8], lineno: u64) -> Result<(), GcodeError> {
        self.norm.clear();
        let mut i = 0;
        while i < bytes.len() {
            let c = bytes[i];
            i += 1;
            match NORMALISE[c as usize] {
                0 => {}
                b'(' => match bytes[i..].iter().position(|&c| c == b')') {
                    Some(k) => i += k + 1,
                    None => return Err(GcodeError::at(lineno, "comment '(' is not closed on this line")),
                },
                b';' => break,
                0xff => {
                    return Err(GcodeError::at(
                        lineno,
                        format!("character 0x{c:02x} is not allowed in G-code outside comments"),
                    ));
                }
                out => self.norm.push(out),
            }
        }
        Ok(())
    }

    /// Parse the normalised line into `b` (a fresh [`Block::new`]). The
    /// block is filled in place rather than returned: it is over 500 bytes,
    /// and returning it cost a copy per line.
    pub(super) fn parse_block(&mut self, b: &mut Block, lineno: u64) -> Result<(), GcodeError> {
        self.assigns.clear();
        let norm = std::mem::take(&mut self.norm);
        let res = self.parse_words(&norm, b, lineno);
        self.norm = norm;
        res
    }

    pub(super) fn parse_words(&mut self, s: &[u8], b: &mut Block, lineno: u64) -> Result<(), GcodeError> {
        let err = |msg: String| GcodeError::at(lineno, msg);
        let mut c = Cursor::new(s);
        if c.peek() == Some(b'/') {
            // Block delete switch is off (LinuxCNC's default): run the line.
            c.pos += 1;
        }
        if c.peek() == Some(b'N') {
            c.pos += 1;
            c.number().map_err(|e| err(format!("line number N: {e}")))?;
        }
        let mut groups_g = [false; 16];
        let mut groups_m = [false; 11];
        let mut g80 = false;
        while let Some(ch) = c.peek() {
            if ch == b'#' {
                let r = c.param_ref(&self.params).map_err(|e| err(e.to_string()))?;
                if c.peek() != Some(b'=') {
                    return Err(err(
                        "a parameter outside an expression must be assigned: '#n=value'".into()
                    ));
                }
                c.pos += 1;
                let v = c.real_value(&self.params).map_err(|e| err(e.to_string()))?;
                self.assigns.push((r, v));
                continue;
            }
            if ch == b'@' || ch == b'^' {
                c.pos += 1;
                let v = c
                    .real_value(&self.params)
                    .map_err(|e| err(format!("{} word: {e}", ch as char)))?;
                let slot = &mut b.polar[usize::from(ch == b'^')];
                if slot.is_some() {
                    return Err(err(format!("{} word repeated on one line", ch as char)));
                }
                *slot = Some(v);
                continue;
            }
            if !ch.is_ascii_uppercase() {
                return Err(err(format!(
                    "expected a word letter, found '{}'",
                    String::from_utf8_lossy(&s[c.pos..(c.pos + 8).min(s.len())])
                )));
            }
            c.pos += 1;
            let v = c
                .real_value(&self.params)
                .map_err(|e| err(format!("{} word: {e}", ch as char)))?;
            match ch {
                b'G' | b'M' => {
                    let t = (v * 10.0).round();
                    if (v * 10.0 - t).abs() > 1e-6 || !(0.0..=65535.0).contains(&t) {
                        return Err(err(format!("{}{v} is not a valid code", ch as char)));
                    }
                    let code = t as u16;
                    if ch == b'G' && code == 800 {
                        // LinuxCNC lets G80 share a line with another motion
                        // code (CAM preambles write `G0 G80`): the other wins.
                        g80 = true;
                        b.other_g = true;
                    } else if ch == b'G' {
                        let g = g_group(code).ok_or_else(|| err(format!("unknown G code {}", fmt_code('G', code))))?;
                        // Non-modal group 0 codes may share a line with each
                        // other only when they are different (G4 with G92...).
                        if g != 0 && groups_g[g as usize] {
                            return Err(err(format!("two G codes from modal group {g} on one line")));
                        }
                        groups_g[g as usize] = true;
                        if b.ng == b.g.len() {
                            return Err(err("too many G codes on one line".into()));
                        }
                        b.g[b.ng] = code;
                        b.ng += 1;
                        b.other_g |= !matches!(code, 0 | 10 | 20 | 30);
                    } else {
                        let g = m_group(code).ok_or_else(|| err(format!("unknown M code {}", fmt_code('M', code))))?;
                        if g != 10 && groups_m[g as usize] {
                            return Err(err(format!("two M codes from modal group {g} on one line")));
                        }
                        groups_m[g.min(10) as usize] = true;
                        if b.nm == b.m.len() {
                            return Err(err("too many M codes on one line".into()));
                        }
                        b.m[b.nm] = code;
                        b.nm += 1;
                    }
                }
                b'N' => return Err(err("N word must be at the start of the line".into())),
                b'O' => return Err(err("an O word must start the line".into())),
                _ => {
                    let slot = &mut b.w[(ch - b'A') as usize];
                    if slot.is_some() {
                        return Err(err(format!("{} word repeated on one line", ch as char)));
                    }
                    *slot = Some(v);
                }
            }
        }
        if g80 && !groups_g[1] {
            if b.ng == b.g.len() {
                return Err(err("too many G codes on one line".into()));
            }
            b.g[b.ng] = 800;
            b.ng += 1;
        }
        Ok(())
    }

    /// LinuxCNC's check of words that mean nothing on their block
    /// (`G1 X1 I5`, a lone `R5`): each is an error with rs274's message,
    /// never silently ignored. The motion the block will make is its own
    /// group-1 code, or the modal one when it has axis words that no
    /// G10/G28/G30/G52/G92 takes.
    pub(super) fn check_words(&self, b: &Block) -> Result<(), &'static str> {
        let has = |l: u8| b.word(l).is_some();
        if !(has(b'D')
            || has(b'H')
            || has(b'I')
            || has(b'J')
            || has(b'K')
            || has(b'L')
            || has(b'P')
            || has(b'Q')
            || has(b'R'))
        {
            return Ok(());
        }
        let has_axes = has(b'X') || has(b'Y') || has(b'Z') || b.polar.iter().any(Option::is_some);
        let covets = [100u16, 280, 300, 520, 920].iter().any(|&c| b.has_g(c));
        let motion = b.g[..b.ng]
            .iter()
            .copied()
            .find(|&c| g_group(c) == Some(1))
            .or(match self.motion {
                Some(m) if has_axes && !covets => Some(match m {
                    MotionMode::Rapid => 0,
                    MotionMode::Feed => 10,
                    MotionMode::Cw => 20,
                    MotionMode::Ccw => 30,
                    MotionMode::Cycle(c) | MotionMode::Spline(c) => c,
                    MotionMode::Nurbs => 52,
                }),
                _ => None,
            });
        let motion_in = |codes: &[u16]| motion.is_some_and(|m| codes.contains(&m));
        let cycle = motion.is_some_and(|m| (810..=890).contains(&m) || m == 730);
        let g10 = b.has_g(100);
        let comp = [410u16, 411, 420, 421].iter().any(|&c| b.has_g(c));
        let user_m = b.m[..b.nm].iter().any(|m| (1000..=1990).contains(m));
        let m_in = |codes: &[u16]| codes.iter().any(|&c| b.has_m(c));
        if has(b'D') && !comp && !b.has_g(960) {
            return Err("D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it");
        }
        if has(b'H') && !b.has_g(430) && !b.has_g(432) && !motion_in(&[760]) {
            return Err("H word with no G43 or G76 to use it");
        }
        if has(b'I') && !g10 && !motion_in(&[20, 30, 50, 51, 331, 760, 870]) {
            return Err("I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it");
        }
        if has(b'J') && !g10 && !motion_in(&[20, 30, 50, 51, 760, 870]) {
            return Err("J word with no G2, G3, G5, G5.1, G10, G76 or G87 to use it");
        }
        if has(b'K') && !motion_in(&[20, 30, 330, 331, 760, 870]) {
            return Err("K word with no G2, G3, G33, G33.1, G76, or G87 to use it");
        }
        if has(b'L') && !(cycle || g10 || comp || motion_in(&[760, 52]) || m_in(&[660, 980])) {
            return Err(
                "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code",
            );
        }
        if has(b'P')
            && !(g10
                || b.has_g(40)
                || b.has_g(640)
                || motion_in(&[760, 820, 860, 880, 890, 50, 52, 20, 30])
                || m_in(&[500, 510, 520, 530, 620, 630, 640, 650, 660, 190, 980])
                || user_m)
        {
            return Err(
                "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it",
            );
        }
        if has(b'Q')
            && !(g10 || b.has_g(640) || motion_in(&[830, 730, 50, 760]) || m_in(&[660, 670, 680, 610, 190]) || user_m)
        {
            return Err("Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it");
        }
        if has(b'R') && !(g10 || cycle || b.has_g(411) || b.has_g(421) || motion_in(&[20, 30, 760]) || m_in(&[190])) {
            return Err("R word with no g code that uses it");
        }
        Ok(())
    }
}
