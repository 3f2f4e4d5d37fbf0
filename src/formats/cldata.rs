//! CL data (cutter locations): the one reader (pathgen's output, stlverify's
//! input) and the writer.
//!
//! Plain text, one location per line, numbers separated by commas, tabs or
//! spaces. 3-axis rows are `x y z` (the tool tip on the axis); 5-axis rows
//! are `x y z x1 y1 z1`, the second point lying on the tool axis towards
//! the holder. These are the layouts of the 3- and 5-axis tool paths in
//! Singh 2014 (Annexures 1 and 2), whose tables also lead each row with a
//! serial number: a row of 4 or 7 numbers whose first is a whole number is
//! read as numbered and the number dropped. `#` starts a comment; header
//! lines (any line before the first location whose first word is not a
//! number: `S.No. X Y Z`) are skipped. Every row of a file has the same
//! layout. See docs/formats.md.

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
    /// The 1-based line each location was read from (same length as
    /// `points` when read; may be empty for data built in memory).
    pub lines: Vec<u64>,
}

impl ClData {
    /// Whether the rows carry a tool-axis point.
    pub fn is_five_axis(&self) -> bool {
        !self.axis.is_empty()
    }

    /// The line location `i` was read from (0 when not known).
    pub fn line_of(&self, i: usize) -> u64 {
        self.lines.get(i).copied().unwrap_or(0)
    }
}

/// Read CL data; errors name the line. Empty data (no rows) is not an
/// error here: a reader that needs locations says so.
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
        let mut first_is_word = false;
        let mut words = 0;
        for tok in text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
        {
            match tok.parse::<f64>() {
                Ok(v) => nums.push(v),
                Err(_) => {
                    first_is_word |= nums.is_empty() && words == 0;
                    words += 1;
                }
            }
        }
        if words > 0 {
            if first_is_word && data.points.is_empty() {
                continue; // a header line
            }
            return Err(FormatError::invalid(
                line,
                format!("expected numbers (x y z or x y z x1 y1 z1), got '{text}'"),
            ));
        }
        if let Some(v) = nums.iter().find(|v| !v.is_finite()) {
            return Err(FormatError::invalid(line, format!("'{v}' is not a finite number")));
        }
        // A leading serial number: a whole number before 3 or 6 values.
        let vals: &[f64] = match nums.len() {
            4 | 7 if nums[0].fract() == 0.0 => &nums[1..],
            3 | 6 => &nums[..],
            n => {
                return Err(FormatError::invalid(
                    line,
                    format!("{n} numbers; expected x y z or x y z x1 y1 z1"),
                ));
            }
        };
        match width {
            None => width = Some(vals.len()),
            Some(w) if w != vals.len() => {
                return Err(FormatError::invalid(
                    line,
                    format!("{} numbers, but the rows before have {w}", vals.len()),
                ));
            }
            Some(_) => {}
        }
        data.points.push(P3::new(vals[0], vals[1], vals[2]));
        if vals.len() == 6 {
            data.axis.push(P3::new(vals[3], vals[4], vals[5]));
        }
        data.lines.push(line);
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
    /// A writer to `out`.
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

    /// Flush and hand back the sink.
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
        assert_eq!(e.to_string(), "line 3: 2 numbers; expected x y z or x y z x1 y1 z1");
        let e = read_cldata("1 2 3\n1 2 3 4 5 6\n".as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), "line 2: 6 numbers, but the rows before have 3");
        let e = read_cldata("1 2 3\nx y z\n".as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("line 2: expected numbers"));
        assert!(read_cldata("1 2 nan\n".as_bytes()).is_err());
        assert_eq!(
            read_cldata("1 2 3\n1 2 3 4 5\n".as_bytes()).unwrap_err().to_string(),
            "line 2: 5 numbers; expected x y z or x y z x1 y1 z1"
        );
        assert!(read_cldata("1 2 3\n1.5 2 3 4\n".as_bytes()).is_err());
    }

    /// What either of the two former readers accepted, this one does: any
    /// whole leading number (not only the row's), the width counted
    /// without it, header lines with numbers after a leading word, no rows
    /// at all, and an axis point on the tip (the caller judges that).
    #[test]
    fn accepts_what_both_former_readers_accepted() {
        let d = read_cldata("5 1 2 3\n9 4 5 6\n7 8 9\n".as_bytes()).unwrap();
        assert_eq!(
            d.points,
            vec![P3::new(1.0, 2.0, 3.0), P3::new(4.0, 5.0, 6.0), P3::new(7.0, 8.0, 9.0)]
        );
        assert_eq!(d.lines, vec![1, 2, 3]);
        let d = read_cldata("Tool path 2 of 3\nS.No X Y Z\n\n1 0 0 0 # tip\n".as_bytes()).unwrap();
        assert_eq!(d.points, vec![P3::origin()]);
        assert_eq!(d.line_of(0), 4);
        assert_eq!(read_cldata("# none\n\n".as_bytes()).unwrap(), ClData::default());
        let d = read_cldata("1 2 3 1 2 3\n".as_bytes()).unwrap();
        assert_eq!(d.axis, vec![P3::new(1.0, 2.0, 3.0)]);
        // A header after the first row is an error.
        assert!(read_cldata("1 2 3\nX Y Z\n".as_bytes()).is_err());
    }
}
