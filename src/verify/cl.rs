//! Cutter locations in: CL data text (3- or 5-axis) or a G-code program.
//!
//! CL data (docs/formats.md): one location per line, numbers separated by
//! commas, tabs or spaces; `x y z` (tool tip, axis along +Z) or
//! `x y z x1 y1 z1` (tip and a second point on the tool axis towards the
//! holder), the layouts of Singh 2014's Annexures 1 and 2. Header lines
//! (any line before the first location whose first word is not a number),
//! blank lines and `#` comments are skipped. The annexures number their
//! rows, so a leading record number is dropped when a line has 4 or 7
//! numbers and the first is a whole number.

use crate::dexel::tool::Location;
use crate::gcode::ReadOptions;
use crate::geometry::{P3, V3};
use crate::model::toolpath::{MotionKind, Record};
use crate::source::ToolpathSource;
use std::io::BufRead;
use thiserror::Error;

/// Why CL data could not be read.
#[derive(Debug, Error)]
pub enum ClError {
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("line {line}: {message}")]
    Line { line: usize, message: String },
    #[error("no cutter locations")]
    Empty,
    #[error("{0}")]
    Program(String),
}

fn bad(line: usize, message: impl Into<String>) -> ClError {
    ClError::Line {
        line,
        message: message.into(),
    }
}

/// Read CL data; `true` in the result when it was 5-axis.
pub fn read_cl<R: BufRead>(r: R) -> Result<(Vec<Location>, bool), ClError> {
    let mut out = Vec::new();
    let mut width: Option<usize> = None;
    for (n, line) in r.lines().enumerate() {
        let line = line?;
        let ln = n + 1;
        let text = line.split('#').next().unwrap_or("").trim();
        if text.is_empty() {
            continue;
        }
        let words: Vec<&str> = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|w| !w.is_empty())
            .collect();
        let nums: Result<Vec<f64>, _> = words.iter().map(|w| w.parse::<f64>()).collect();
        let Ok(mut nums) = nums else {
            if out.is_empty() && words[0].parse::<f64>().is_err() {
                continue; // a header line
            }
            return Err(bad(ln, format!("'{text}': expected numbers")));
        };
        if (nums.len() == 4 || nums.len() == 7) && nums[0].fract() == 0.0 {
            nums.remove(0);
        }
        if nums.len() != 3 && nums.len() != 6 {
            return Err(bad(
                ln,
                format!("{} numbers; expected x y z or x y z x1 y1 z1", nums.len()),
            ));
        }
        if nums.iter().any(|v| !v.is_finite()) {
            return Err(bad(ln, "a number is not finite"));
        }
        match width {
            None => width = Some(nums.len()),
            Some(w) if w != nums.len() => {
                return Err(bad(ln, format!("{} numbers after lines of {w}", nums.len())));
            }
            _ => {}
        }
        let tip = P3::new(nums[0], nums[1], nums[2]);
        let axis = if nums.len() == 6 {
            let v = P3::new(nums[3], nums[4], nums[5]) - tip;
            let l = v.norm();
            if l.is_nan() || l <= 1e-9 {
                return Err(bad(ln, "the second axis point is on the tool tip"));
            }
            v / l
        } else {
            V3::z()
        };
        out.push(Location { tip, axis });
    }
    if out.is_empty() {
        return Err(ClError::Empty);
    }
    Ok((out, width == Some(6)))
}

/// The locations a program visits (3-axis, tool along +Z): every move's
/// end point, arcs as chords within `sag` mm. The move from the start
/// position to the first end point is not cut.
pub fn program_locations(src: ToolpathSource, sag: f64) -> Result<Vec<Location>, ClError> {
    let mut out: Vec<Location> = Vec::new();
    let loc = |tip: P3| Location { tip, axis: V3::z() };
    for rec in src {
        let rec = rec.map_err(|e| ClError::Program(e.message))?;
        let Record::Move(m) = rec else { continue };
        let from = out.last().map(|l| l.tip);
        match (m.kind, from) {
            (MotionKind::Arc(a), Some(from)) => {
                let arc = a
                    .arc(from, m.to)
                    .ok_or_else(|| ClError::Program(format!("line {}: degenerate arc", m.block.unwrap_or(0))))?;
                let r = arc.radius().max(1e-12);
                let dphi = if sag >= r {
                    std::f64::consts::FRAC_PI_2
                } else {
                    2.0 * (1.0 - sag / r).acos()
                };
                let n = ((arc.sweep().abs() / dphi).ceil() as usize).clamp(1, 1 << 20);
                for k in 1..=n {
                    out.push(loc(arc.point_at(k as f64 / n as f64)));
                }
            }
            _ => out.push(loc(m.to)),
        }
    }
    if out.is_empty() {
        return Err(ClError::Empty);
    }
    Ok(out)
}

/// Default reading options for programs (start at the origin).
pub fn program_options() -> ReadOptions {
    ReadOptions::default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_and_five_axis_with_headers_and_row_numbers() {
        let text = "S.No. X Y Z\n1\t10\t0.5\t-9.5\n\n2 10, 1, -9.5 # c\n";
        let (v, five) = read_cl(text.as_bytes()).unwrap();
        assert!(!five);
        assert_eq!(v.len(), 2);
        assert_eq!(v[1].tip, P3::new(10.0, 1.0, -9.5));
        let text = "x y z x1 y1 z1\n0 0 0 0 3 4\n";
        let (v, five) = read_cl(text.as_bytes()).unwrap();
        assert!(five);
        assert!((v[0].axis - V3::new(0.0, 0.6, 0.8)).norm() < 1e-12);
    }

    #[test]
    fn errors_name_the_line() {
        for (t, want) in [
            ("1 2 3\n1 2\n", "line 2"),
            ("1 2 3\nfoo\n", "line 2"),
            ("1 2 3\n1 2 3 4 5 6\n", "line 2"),
            ("1 2 3 1 2 3\n", "line 1"),
            ("1 nan 3\n", "line 1"),
        ] {
            let e = read_cl(t.as_bytes()).unwrap_err().to_string();
            assert!(e.contains(want), "{t:?}: {e}");
        }
        assert!(matches!(read_cl("# nothing\n".as_bytes()), Err(ClError::Empty)));
    }
}
