//! CL data (cutter locations): reader and writer.
//!
//! Plain text, one location per line, numbers separated by commas, tabs or
//! spaces. 3-axis rows are `x y z` (the tool tip on the axis); 5-axis rows
//! are `x y z x1 y1 z1`, the second point lying on the tool axis towards
//! the holder. These are the layouts of the 3- and 5-axis tool paths in
//! Singh 2014 (Annexures 1 and 2), whose tables also lead each row with a
//! serial number: a row of 4 or 7 numbers whose first is its 1-based row
//! number is read that way. `#` starts a comment; one header line of words
//! (`X Y Z`) before the first row is skipped. Every row of a file has the
//! same layout. See docs/formats.md.

use super::{FormatError, LineSource, push_num};
use crate::geometry::P3;
use std::io::{BufRead, Write};

/// CL data in memory.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ClData {
    /// Tool-tip locations.
    pub points: Vec<P3>,
    /// 5-axis: a point on the tool axis per location (same length as
    /// `points`); empty for 3-axis data.
    pub axis: Vec<P3>,
}

impl ClData {
    /// Whether the rows carry a tool-axis point.
    pub fn is_five_axis(&self) -> bool {
        !self.axis.is_empty()
    }
}

/// Read CL data; errors name the line.
pub fn read_cldata(input: impl BufRead) -> Result<ClData, FormatError> {
    let mut lines = LineSource::new(input);
    let mut data = ClData::default();
    let mut width: Option<usize> = None;
    let mut nums: Vec<f64> = Vec::with_capacity(8);
    while let Some((text, line)) = lines.next_line()? {
        let text = text.split('#').next().unwrap_or("").trim();
        if text.is_empty() {
            continue;
        }
        nums.clear();
        let mut words = 0;
        for tok in text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
        {
            match tok.parse::<f64>() {
                Ok(v) if v.is_finite() => nums.push(v),
                Ok(_) => return Err(FormatError::invalid(line, format!("'{tok}' is not a finite number"))),
                Err(_) => words += 1,
            }
        }
        if words > 0 {
            if width.is_none() && nums.is_empty() && data.points.is_empty() {
                continue; // the header line
            }
            return Err(FormatError::invalid(
                line,
                format!("expected numbers (x y z or x y z x1 y1 z1), got '{text}'"),
            ));
        }
        let row = data.points.len() as f64 + 1.0;
        // A leading serial number is recognised by its value on every row.
        let vals: &[f64] = match nums.len() {
            4 | 7 if nums[0] == row && width.is_none_or(|w| w == nums.len()) => &nums[1..],
            3 | 6 => &nums[..],
            n => {
                return Err(FormatError::invalid(
                    line,
                    format!("a row has 3 numbers (x y z) or 6 (x y z x1 y1 z1), got {n}"),
                ));
            }
        };
        match width {
            None => width = Some(nums.len()),
            Some(w) if w != nums.len() => {
                return Err(FormatError::invalid(
                    line,
                    format!("{} numbers, but the rows before have {w}", nums.len()),
                ));
            }
            Some(_) => {}
        }
        data.points.push(P3::new(vals[0], vals[1], vals[2]));
        if vals.len() == 6 {
            data.axis.push(P3::new(vals[3], vals[4], vals[5]));
        }
    }
    Ok(data)
}

/// Streaming writer: space-separated numbers in the pipe formats'
/// canonical form (rounded to 1e-9, no exponent), `#` comment lines.
pub struct ClWriter<W: Write> {
    out: W,
    buf: String,
}

impl<W: Write> ClWriter<W> {
    pub fn new(out: W) -> Self {
        ClWriter {
            out,
            buf: String::with_capacity(128),
        }
    }

    /// A `# ...` line (one per line of `text`).
    pub fn comment(&mut self, text: &str) -> std::io::Result<()> {
        for l in text.lines() {
            writeln!(self.out, "# {l}")?;
        }
        Ok(())
    }

    /// A 3-axis row.
    pub fn point(&mut self, p: &P3) -> std::io::Result<()> {
        self.row(&[p.x, p.y, p.z])
    }

    /// A 5-axis row: tip and a point on the tool axis.
    pub fn point5(&mut self, p: &P3, q: &P3) -> std::io::Result<()> {
        self.row(&[p.x, p.y, p.z, q.x, q.y, q.z])
    }

    fn row(&mut self, v: &[f64]) -> std::io::Result<()> {
        self.buf.clear();
        for (i, x) in v.iter().enumerate() {
            if i > 0 {
                self.buf.push(' ');
            }
            push_num(&mut self.buf, *x);
        }
        self.buf.push('\n');
        self.out.write_all(self.buf.as_bytes())
    }

    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_the_thesis_layouts() {
        let mut w = ClWriter::new(Vec::new());
        w.comment("microcam CL data").unwrap();
        w.point(&P3::new(0.5, -1.25, 3.0)).unwrap();
        w.point(&P3::new(0.1 + 0.2, 0.0, -0.0)).unwrap();
        let text = String::from_utf8(w.finish().unwrap()).unwrap();
        assert_eq!(text, "# microcam CL data\n0.5 -1.25 3\n0.3 0 0\n");
        let d = read_cldata(text.as_bytes()).unwrap();
        assert_eq!(d.points, vec![P3::new(0.5, -1.25, 3.0), P3::new(0.3, 0.0, 0.0)]);
        assert!(!d.is_five_axis());
        // Serial-numbered, tab-separated rows under a header of words.
        let t = "S.No\tX\tY\tZ\tX1\tY1\tZ1\n1\t0.5\t0.5\t-5\t0.5\t1.5\t60\n2\t0.5\t1\t-5.1\t0.6\t3\t59\n";
        let d = read_cldata(t.as_bytes()).unwrap();
        assert!(d.is_five_axis());
        assert_eq!(d.points[1], P3::new(0.5, 1.0, -5.1));
        assert_eq!(d.axis[0], P3::new(0.5, 1.5, 60.0));
        let d = read_cldata("1,2,3\n4,5,6\n".as_bytes()).unwrap();
        assert_eq!(d.points.len(), 2);
    }

    #[test]
    fn errors_name_the_line() {
        let e = read_cldata("1 2 3\n\n1 2\n".as_bytes()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 3: a row has 3 numbers (x y z) or 6 (x y z x1 y1 z1), got 2"
        );
        let e = read_cldata("1 2 3\n1 2 3 4 5 6\n".as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "line 2: 6 numbers, but the rows before have 3");
        let e = read_cldata("1 2 3\nx y z\n".as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("line 2: expected numbers"));
        assert!(read_cldata("1 2 nan\n".as_bytes()).is_err());
    }
}
