//! `microcam.chains/1`: reader and writer.

use super::{FormatError, LineSource, check_schema, parse_json, point_from, push_point_2or3, push_str_lit};
use crate::geometry::P3;
use crate::model::chain::{Chain, ChainRef, ChainsHeader, Segment};
use serde::Deserialize;
use std::io::{BufRead, Write};

/// The schema name a chains stream's header carries.
pub const SCHEMA: &str = "microcam.chains/1";

/// How far a segment's start may be from the previous segment's end (mm).
/// Writers snap ends exactly, so this only absorbs printing round-off.
pub const JOIN_TOL: f64 = 1e-6;

#[derive(Deserialize)]
struct WireHeader {
    schema: Option<String>,
    units: Option<String>,
    source: Option<String>,
}

#[derive(Deserialize)]
struct WireSegment {
    #[serde(rename = "type")]
    kind: Option<String>,
    start: Option<Vec<f64>>,
    end: Option<Vec<f64>>,
    center: Option<Vec<f64>>,
    ccw: Option<bool>,
}

#[derive(Deserialize)]
struct WireChain {
    id: Option<u64>,
    layer: Option<String>,
    closed: Option<bool>,
    segments: Option<Vec<WireSegment>>,
    points: Option<Vec<Vec<f64>>>,
    repairs: Option<Vec<String>>,
    schema: Option<String>,
}

/// Streaming reader of chains, one chain per line.
pub struct ChainsReader<R> {
    lines: LineSource<R>,
    header: ChainsHeader,
}

impl<R: BufRead> ChainsReader<R> {
    /// Read and check the header (the schema, units "mm" if given); the
    /// chains are then read one per [`Iterator::next`].
    pub fn new(input: R) -> Result<Self, FormatError> {
        let mut lines = LineSource::new(input);
        let (text, line) = lines
            .next_line()?
            .ok_or_else(|| FormatError::invalid(1, format!("empty input: expected a '{SCHEMA}' header")))?;
        let h: WireHeader = parse_json(text, line)?;
        check_schema(h.schema.as_deref(), SCHEMA, line)?;
        if let Some(u) = h.units.as_deref()
            && u != "mm"
        {
            return Err(FormatError::invalid(
                line,
                format!("units '{u}' not supported (only \"mm\")"),
            ));
        }
        Ok(ChainsReader {
            lines,
            header: ChainsHeader { source: h.source },
        })
    }

    /// The stream's header.
    pub fn header(&self) -> &ChainsHeader {
        &self.header
    }

    fn next_chain(&mut self) -> Result<Option<Chain>, FormatError> {
        let Some((text, line)) = self.lines.next_line()? else {
            return Ok(None);
        };
        let w: WireChain = parse_json(text, line)?;
        decode_chain(w, line).map(Some)
    }
}

impl<R: BufRead> Iterator for ChainsReader<R> {
    type Item = Result<Chain, FormatError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_chain().transpose()
    }
}

fn decode_chain(w: WireChain, line: u64) -> Result<Chain, FormatError> {
    if w.schema.is_some() {
        return Err(FormatError::invalid(
            line,
            "a second header in the middle of the stream",
        ));
    }
    let id = w.id.ok_or_else(|| FormatError::invalid(line, "chain needs 'id'"))?;
    let closed = w
        .closed
        .ok_or_else(|| FormatError::invalid(line, "chain needs 'closed'"))?;
    let wsegs = w
        .segments
        .ok_or_else(|| FormatError::invalid(line, "chain needs 'segments'"))?;
    let mut segments = Vec::with_capacity(wsegs.len());
    for (i, s) in wsegs.into_iter().enumerate() {
        let n = i + 1;
        let what = |f: &str| format!("segment {n} '{f}'");
        let kind = s
            .kind
            .ok_or_else(|| FormatError::invalid(line, format!("segment {n} needs 'type'")))?;
        let start = point_from(
            &s.start
                .ok_or_else(|| FormatError::invalid(line, format!("segment {n} needs 'start'")))?,
            line,
            &what("start"),
        )?;
        let end = point_from(
            &s.end
                .ok_or_else(|| FormatError::invalid(line, format!("segment {n} needs 'end'")))?,
            line,
            &what("end"),
        )?;
        let seg = match kind.as_str() {
            "line" => Segment::line(start, end),
            "arc" => {
                let center = point_from(
                    &s.center
                        .ok_or_else(|| FormatError::invalid(line, format!("arc segment {n} needs 'center'")))?,
                    line,
                    &what("center"),
                )?;
                let ccw = s
                    .ccw
                    .ok_or_else(|| FormatError::invalid(line, format!("arc segment {n} needs 'ccw'")))?;
                let r0 = (start - center).xy().norm();
                let r1 = (end - center).xy().norm();
                if r0 <= 0.0 || (r0 - r1).abs() > JOIN_TOL + 1e-9 * r0 {
                    return Err(FormatError::invalid(
                        line,
                        format!("arc segment {n}: radius at start {r0} differs from radius at end {r1}"),
                    ));
                }
                Segment::arc_xy(start, end, center, ccw)
            }
            other => {
                return Err(FormatError::invalid(
                    line,
                    format!("segment {n}: unknown type '{other}' (line or arc)"),
                ));
            }
        };
        if let Some(prev) = segments.last() {
            let prev: &Segment = prev;
            if (prev.end() - seg.start()).norm() > JOIN_TOL {
                return Err(FormatError::invalid(
                    line,
                    format!(
                        "segment {n} starts at {:?} but segment {} ended at {:?}",
                        seg.start().coords.as_slice(),
                        n - 1,
                        prev.end().coords.as_slice()
                    ),
                ));
            }
        }
        segments.push(seg);
    }
    if closed
        && let (Some(first), Some(last)) = (segments.first(), segments.last())
        && (first.start() - last.end()).norm() > JOIN_TOL
    {
        return Err(FormatError::invalid(
            line,
            "chain is marked closed but does not end where it starts",
        ));
    }
    let points = w
        .points
        .unwrap_or_default()
        .iter()
        .map(|p| point_from(p, line, "'points'"))
        .collect::<Result<Vec<P3>, _>>()?;
    Ok(Chain {
        id,
        layer: w.layer,
        closed,
        segments,
        points,
        repairs: w.repairs.unwrap_or_default(),
    })
}

/// Streaming writer of chains.
pub struct ChainsWriter<W: Write> {
    lines: super::LineWriter<W>,
}

impl<W: Write> ChainsWriter<W> {
    /// A writer into `out`; write the header first.
    pub fn new(out: W) -> Self {
        ChainsWriter {
            lines: super::LineWriter::new(out),
        }
    }

    /// Write the header line (schema, units, source).
    pub fn header(&mut self, h: &ChainsHeader) -> std::io::Result<()> {
        self.lines.header(SCHEMA, &[], h.source.as_deref())
    }

    /// Write one chain as one line.
    pub fn chain(&mut self, c: &Chain) -> std::io::Result<()> {
        self.lines.line(|b| format_chain(b, c))
    }

    /// Write chains formatted elsewhere by [`format_chain`], one line each
    /// with its newline (to format many on several threads).
    pub fn formatted(&mut self, lines: &str) -> std::io::Result<()> {
        self.lines.raw(lines)
    }

    /// Flush and give back the output.
    pub fn finish(self) -> std::io::Result<W> {
        self.lines.finish()
    }
}

/// A segment's start: a copy of the previous end's text `b[from..to]` when
/// it is the same point (equal points print the same text: `-0` and `0`
/// both print `0`), else formatted.
fn push_start(b: &mut String, p: &P3, prev: Option<(P3, usize, usize)>) {
    if let Some((q, from, to)) = prev
        && q == *p
        && to - from <= 128
    {
        let mut tmp = [0u8; 128];
        let n = to - from;
        tmp[..n].copy_from_slice(&b.as_bytes()[from..to]);
        if let Ok(t) = std::str::from_utf8(&tmp[..n]) {
            b.push_str(t);
            return;
        }
    }
    push_point_2or3(b, p);
}

/// Append one chain as a JSON object (no newline).
pub fn format_chain(b: &mut String, c: &Chain) {
    format_chain_ref(
        b,
        &ChainRef {
            id: c.id,
            layer: c.layer.as_deref(),
            closed: c.closed,
            segments: &c.segments,
            points: &c.points,
            repairs: &c.repairs,
        },
    );
}

/// [`format_chain`] of borrowed parts.
pub fn format_chain_ref(b: &mut String, c: &ChainRef) {
    b.push_str("{\"id\":");
    super::push_uint(b, c.id);
    if let Some(l) = c.layer {
        b.push_str(",\"layer\":");
        push_str_lit(b, l);
    }
    b.push_str(if c.closed {
        ",\"closed\":true"
    } else {
        ",\"closed\":false"
    });
    b.push_str(",\"segments\":[");
    // The previous segment's end and where its text is in `b`: the next
    // segment starts there (chains share their ends exactly), so that text
    // is copied instead of formatted again.
    let mut prev: Option<(P3, usize, usize)> = None;
    for (i, s) in c.segments.iter().enumerate() {
        if i > 0 {
            b.push(',');
        }
        match s {
            Segment::Line(l) => {
                b.push_str("{\"type\":\"line\",\"start\":");
                push_start(b, &l.start, prev);
                b.push_str(",\"end\":");
                let at = b.len();
                push_point_2or3(b, &l.end);
                prev = Some((l.end, at, b.len()));
            }
            Segment::Arc(a) => {
                b.push_str("{\"type\":\"arc\",\"start\":");
                push_start(b, &a.start, prev);
                b.push_str(",\"end\":");
                let at = b.len();
                push_point_2or3(b, &a.end);
                prev = Some((a.end, at, b.len()));
                b.push_str(",\"center\":");
                push_point_2or3(b, &a.center);
                b.push_str(if a.ccw { ",\"ccw\":true" } else { ",\"ccw\":false" });
            }
        }
        b.push('}');
    }
    b.push(']');
    if !c.points.is_empty() {
        b.push_str(",\"points\":[");
        for (i, p) in c.points.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            push_point_2or3(b, p);
        }
        b.push(']');
    }
    if !c.repairs.is_empty() {
        b.push_str(",\"repairs\":[");
        for (i, r) in c.repairs.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            push_str_lit(b, r);
        }
        b.push(']');
    }
    b.push('}');
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = r#"{"schema":"microcam.chains/1","units":"mm","source":"part.dxf"}
{"id":1,"layer":"CUT","closed":true,"segments":[{"type":"line","start":[0,0],"end":[10,0]},{"type":"arc","start":[10,0],"end":[10,10],"center":[10,5],"ccw":true},{"type":"line","start":[10,10],"end":[0,0]}]}
{"id":2,"layer":"MARK","closed":false,"segments":[{"type":"line","start":[0,0,1],"end":[5,0,1]}],"points":[[1,1]],"repairs":["gap of 0.0004 mm closed"]}
"#;

    #[test]
    fn round_trips_byte_for_byte() {
        let r = ChainsReader::new(EXAMPLE.as_bytes()).unwrap();
        let h = r.header().clone();
        let chains: Vec<Chain> = r.collect::<Result<_, _>>().unwrap();
        assert_eq!(chains.len(), 2);
        let mut w = ChainsWriter::new(Vec::new());
        w.header(&h).unwrap();
        for c in &chains {
            w.chain(c).unwrap();
        }
        assert_eq!(String::from_utf8(w.finish().unwrap()).unwrap(), EXAMPLE);
    }

    #[test]
    fn rejects_broken_chains_with_line_numbers() {
        let head = "{\"schema\":\"microcam.chains/1\"}\n";
        let cases = [
            (
                "{\"id\":1,\"closed\":false,\"segments\":[{\"type\":\"line\",\"start\":[0,0],\"end\":[1,0]},{\"type\":\"line\",\"start\":[2,0],\"end\":[3,0]}]}",
                "segment 2 starts",
            ),
            (
                "{\"id\":1,\"closed\":true,\"segments\":[{\"type\":\"line\",\"start\":[0,0],\"end\":[1,0]}]}",
                "closed",
            ),
            ("{\"closed\":true,\"segments\":[]}", "'id'"),
            (
                "{\"id\":1,\"closed\":false,\"segments\":[{\"type\":\"arc\",\"start\":[0,0],\"end\":[3,0],\"center\":[1,0],\"ccw\":true}]}",
                "radius",
            ),
        ];
        for (rec, needle) in cases {
            let text = format!("{head}{rec}\n");
            let e = ChainsReader::new(text.as_bytes()).unwrap().next().unwrap().unwrap_err();
            assert_eq!(e.line(), 2);
            assert!(e.to_string().contains(needle), "{e}");
        }
    }
}
