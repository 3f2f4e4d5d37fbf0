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
    /// What is wrong with it.
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

/// A tool as a CAM post describes it in a header comment: number,
/// diameter and corner radius (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamTool {
    /// The T number the comment names.
    pub number: u32,
    /// Cutter diameter (`D=`), mm.
    pub diameter_mm: f64,
    /// Corner radius: 0 for a flat end mill, half the diameter for a ball.
    pub corner_mm: f64,
}

/// The tools a CAM post lists in comment lines of the program, as Fusion
/// 360 and its kin write them: `(T1 D=3 CR=0.5 - ZMIN=-5 - bullnose end
/// mill)`: a comment line starting with `T` and the tool number, with
/// `D=` the diameter and optionally `CR=` the corner radius (0 when
/// absent), in the program's units (`inch` for a G20 program). Lines that
/// do not have this shape are not tool descriptions and are passed over;
/// the first description of a number counts.
pub fn cam_tool_comments(text: &str, inch: bool) -> Vec<CamTool> {
    let scale = if inch { 25.4 } else { 1.0 };
    let mut out: Vec<CamTool> = Vec::new();
    for line in text.lines() {
        let t = line.trim();
        let Some(body) = t.strip_prefix('(').and_then(|b| b.strip_suffix(')')) else {
            continue;
        };
        let mut words = body.split_whitespace();
        let Some(n) = words
            .next()
            .and_then(|w| w.strip_prefix(['T', 't']))
            .and_then(|n| n.parse::<u32>().ok())
        else {
            continue;
        };
        let mut d = None;
        let mut cr = 0.0;
        for w in words {
            let num = |v: &str| v.parse::<f64>().ok().filter(|x| x.is_finite() && *x >= 0.0);
            if let Some(v) = w.strip_prefix("D=") {
                d = num(v);
            } else if let Some(v) = w.strip_prefix("CR=") {
                cr = num(v).unwrap_or(0.0);
            }
        }
        if let Some(d) = d.filter(|d| *d > 0.0)
            && !out.iter().any(|c| c.number == n)
        {
            out.push(CamTool {
                number: n,
                diameter_mm: d * scale,
                corner_mm: (cr * scale).min(d * scale / 2.0),
            });
        }
    }
    out
}

/// The cutter of each tool for material removal: the tool table's tools
/// with a diameter (flat end mills: a `.tbl` gives no corner radius), then
/// the program's CAM tool comments, which give the corner radius too and
/// win over the table for the same number.
pub fn tool_cutters(table: Option<&ToolTable>, cam: &[CamTool]) -> BTreeMap<u32, crate::cutter::Cutter> {
    let mut out = BTreeMap::new();
    if let Some(t) = table {
        for e in t.tools.values() {
            if let Some(c) = crate::cutter::Cutter::from_diameter_corner(e.diameter_mm, 0.0) {
                out.insert(e.number, c);
            }
        }
    }
    for t in cam {
        if let Some(c) = crate::cutter::Cutter::from_diameter_corner(t.diameter_mm, t.corner_mm) {
            out.insert(t.number, c);
        }
    }
    out
}

/// True when the first G20/G21 in ISO text (outside comments) is G20.
pub fn first_units_are_inch(text: &str) -> bool {
    for line in text.lines() {
        let code = line.split(['(', ';']).next().unwrap_or("").to_ascii_uppercase();
        let b = code.as_bytes();
        for (i, _) in code.match_indices('G') {
            let mut j = i + 1;
            while j < b.len() && b[j] == b' ' {
                j += 1;
            }
            let k = b[j..].iter().take_while(|c| c.is_ascii_digit()).count();
            match code[j..j + k].trim_start_matches('0') {
                "20" => return true,
                "21" => return false,
                _ => {}
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cam_header_comments_give_the_cutters() {
        let text = "%\n(T1  D=2.7 CR=0 - ZMIN=-13.3 - flat end mill)\n(  T2 D=3.175 CR=1.5875 - ball end mill )\n\
                    (T3 D=0.125 CR=0.02 - bull nose)\n(T4 no diameter)\n(T1 D=9 - again)\n(TOOL T5 D=1)\nG21\n";
        let t = cam_tool_comments(text, false);
        assert_eq!(t.len(), 3, "{t:?}");
        assert_eq!((t[0].number, t[0].diameter_mm, t[0].corner_mm), (1, 2.7, 0.0));
        assert_eq!((t[1].number, t[1].corner_mm), (2, 1.5875));
        let t = cam_tool_comments(text, true);
        assert!((t[2].diameter_mm - 3.175).abs() < 1e-12 && (t[2].corner_mm - 0.508).abs() < 1e-12);
        let table = ToolTable::parse("T1 D6\nT7 D0.5\nT8 D0\n", false).unwrap();
        let cutters = tool_cutters(Some(&table), &cam_tool_comments(text, false));
        use crate::cutter::Cutter;
        assert_eq!(
            cutters.get(&1),
            Some(&Cutter::Flat { radius: 1.35 }),
            "the comment wins"
        );
        assert_eq!(cutters.get(&2), Some(&Cutter::Ball { radius: 1.5875 }));
        assert_eq!(
            cutters.get(&3),
            Some(&Cutter::Torus {
                radius: 0.0625,
                corner: 0.02
            })
        );
        assert_eq!(cutters.get(&7), Some(&Cutter::Flat { radius: 0.25 }));
        assert_eq!(cutters.get(&8), None, "no diameter, no cutter");
        assert!(first_units_are_inch("(G21 in a comment)\nG90 G20\nG21\n"));
        assert!(!first_units_are_inch("G0 X1\nG21 G90\n"));
        assert!(!first_units_are_inch("G200\n"));
    }

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
