//! LinuxCNC tool tables (`.tbl`), for cutter radius compensation (G41/G42
//! with D) and tool changes.
//!
//! One tool a line: words such as `T3 P3 Z12.5 D6.35 ;end mill 1/4`, where
//! T is the tool number, P its pocket, X..W its offsets, D its diameter, I
//! J Q the lathe front/back angles and orientation, and everything after
//! `;` a comment. Words may come in any order; blank lines and lines that
//! are only a comment are skipped. Lengths are in the table's units, which
//! the caller states (LinuxCNC uses the machine's units; we take the
//! program's millimetres unless told inches).

use std::collections::BTreeMap;
use std::fmt;

/// One tool of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolEntry {
    /// Tool number (T).
    pub number: u32,
    /// Pocket (P), if given.
    pub pocket: Option<u32>,
    /// Cutter diameter (D), mm.
    pub diameter_mm: f64,
    /// Length offset along Z, mm.
    pub z_mm: f64,
    /// The comment after `;`, trimmed.
    pub comment: String,
}

/// A tool table: tools by number.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ToolTable {
    tools: BTreeMap<u32, ToolEntry>,
}

/// A line of a tool table that cannot be read.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolTableError {
    /// 1-based line.
    pub line: usize,
    pub msg: String,
}

impl fmt::Display for ToolTableError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "tool table line {}: {}", self.line, self.msg)
    }
}

impl std::error::Error for ToolTableError {}

impl ToolTable {
    /// Parse a table; `inch` when its lengths are inches.
    pub fn parse(text: &str, inch: bool) -> Result<ToolTable, ToolTableError> {
        let scale = if inch { 25.4 } else { 1.0 };
        let mut tools = BTreeMap::new();
        for (k, raw) in text.lines().enumerate() {
            let line = k + 1;
            let err = |msg: String| ToolTableError { line, msg };
            let (words, comment) = match raw.find(';') {
                Some(i) => (&raw[..i], raw[i + 1..].trim()),
                None => (raw, ""),
            };
            if words.trim().is_empty() {
                continue;
            }
            let mut number = None;
            let mut entry = ToolEntry {
                number: 0,
                pocket: None,
                diameter_mm: 0.0,
                z_mm: 0.0,
                comment: comment.to_string(),
            };
            for w in words.split_whitespace() {
                let mut chars = w.chars();
                let letter = chars.next().unwrap_or(' ').to_ascii_uppercase();
                let value: f64 = chars
                    .as_str()
                    .parse()
                    .map_err(|_| err(format!("'{w}' is not a letter and a number")))?;
                if !value.is_finite() {
                    return Err(err(format!("'{w}' is not a finite number")));
                }
                let whole = |v: f64| -> Result<u32, ToolTableError> {
                    if v.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&v) {
                        Ok(v as u32)
                    } else {
                        Err(err(format!("'{w}' must be a whole number")))
                    }
                };
                match letter {
                    'T' => number = Some(whole(value)?),
                    'P' => entry.pocket = Some(whole(value)?),
                    'D' => {
                        if value < 0.0 {
                            return Err(err(format!("negative diameter '{w}'")));
                        }
                        entry.diameter_mm = value * scale;
                    }
                    'Z' => entry.z_mm = value * scale,
                    'X' | 'Y' | 'A' | 'B' | 'C' | 'U' | 'V' | 'W' | 'I' | 'J' | 'Q' => {}
                    _ => return Err(err(format!("unknown word '{w}'"))),
                }
            }
            let n = number.ok_or_else(|| err("a tool line needs a T word".into()))?;
            entry.number = n;
            if tools.insert(n, entry).is_some() {
                return Err(err(format!("tool T{n} is listed twice")));
            }
        }
        Ok(ToolTable { tools })
    }

    /// The tool with number `n`.
    pub fn get(&self, n: u32) -> Option<&ToolEntry> {
        self.tools.get(&n)
    }

    /// Number of tools.
    pub fn len(&self) -> usize {
        self.tools.len()
    }

    /// True when the table lists no tool.
    pub fn is_empty(&self) -> bool {
        self.tools.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linuxcnc_tables_read() {
        let t = ToolTable::parse(
            "T1 P1 D0.125 Z+0.511 ;1/8 end mill\n\n;only a comment\nT2 P2 Z0.1 D0.0625 X0 I0 J0 Q0 ;1/16 end mill\n",
            true,
        )
        .unwrap();
        assert_eq!(t.len(), 2);
        let t1 = t.get(1).unwrap();
        assert!((t1.diameter_mm - 3.175).abs() < 1e-12 && t1.comment == "1/8 end mill");
        assert!((t.get(2).unwrap().z_mm - 2.54).abs() < 1e-12);
        assert!(t.get(3).is_none());
    }

    #[test]
    fn bad_lines_are_named() {
        for (text, line, needle) in [
            ("T1 D3\nP2 D1\n", 2, "needs a T"),
            ("T1 D-3\n", 1, "negative"),
            ("T1 D3\nT1 D2\n", 2, "twice"),
            ("T1.5 D3\n", 1, "whole"),
            ("T1 Dx\n", 1, "not a letter"),
            ("T1 K3\n", 1, "unknown word"),
        ] {
            let e = ToolTable::parse(text, false).unwrap_err();
            assert_eq!(e.line, line, "{text:?}: {e}");
            assert!(e.msg.contains(needle), "{text:?}: {e}");
        }
    }
}
