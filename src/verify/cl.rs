//! Cutter locations in: CL data text (3- or 5-axis, read by
//! [`crate::formats::cldata::read_cldata`], the one CL reader) or a G-code
//! program.

use crate::dexel::tool::Location;
use crate::formats::FormatError;
use crate::formats::cldata::{ClData, read_cldata};
use crate::gcode::ReadOptions;
use crate::geometry::{P3, V3};
use crate::model::toolpath::{MotionKind, Record};
use crate::source::ToolpathSource;
use std::io::BufRead;
use thiserror::Error;

/// Why cutter locations could not be read.
#[derive(Debug, Error)]
pub enum ClError {
    /// The CL text is not CL data (names the line).
    #[error("{0}")]
    Format(#[from] FormatError),
    /// A location the verifier cannot use (names the line).
    #[error("line {line}: {message}")]
    Line {
        /// 1-based line of the location.
        line: u64,
        /// What is wrong with it.
        message: String,
    },
    /// Neither rows nor moves.
    #[error("no cutter locations")]
    Empty,
    /// The program could not be read or interpreted.
    #[error("{0}")]
    Program(String),
}

/// The tool locations of CL data: tip and unit axis (+Z for 3-axis rows).
/// An axis point on the tip, or no rows, is an error.
pub fn locations(data: &ClData) -> Result<Vec<Location>, ClError> {
    if data.points.is_empty() {
        return Err(ClError::Empty);
    }
    let mut out = Vec::with_capacity(data.points.len());
    for (i, &tip) in data.points.iter().enumerate() {
        let axis = match data.axis.get(i) {
            Some(&q) => {
                let v = q - tip;
                let l = v.norm();
                if l.is_nan() || l <= 1e-9 {
                    return Err(ClError::Line {
                        line: data.line_of(i),
                        message: "the second axis point is on the tool tip".into(),
                    });
                }
                v / l
            }
            None => V3::z(),
        };
        out.push(Location { tip, axis });
    }
    Ok(out)
}

/// Read CL data as tool locations; `true` in the result when it was 5-axis.
pub fn read_cl<R: BufRead>(r: R) -> Result<(Vec<Location>, bool), ClError> {
    let data = read_cldata(r)?;
    Ok((locations(&data)?, data.is_five_axis()))
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
