//! `microcam.toolpath/1`: reader and writer.

use super::{
    FormatError, LineSource, check_schema, parse_json, point_from, push_num, push_point3, push_str_lit, push_uint,
};
use crate::geometry::V3;
use crate::geometry::{P3, Plane};
use crate::model::toolpath::{ArcData, FeedUnit, Header, Motion, MotionKind, Record, Role, ShutterSwitch, ToolState};
use serde::Deserialize;
use std::io::{BufRead, Write};

/// The schema name a toolpath stream's header carries.
pub const SCHEMA: &str = "microcam.toolpath/1";

#[derive(Deserialize)]
struct WireHeader<'a> {
    #[serde(borrow)]
    schema: Option<std::borrow::Cow<'a, str>>,
    units: Option<String>,
    feed_units: Option<String>,
    source: Option<String>,
}

#[derive(Deserialize)]
struct WireRecord {
    #[serde(rename = "type")]
    kind: Option<String>,
    to: Option<Vec<f64>>,
    center: Option<Vec<f64>>,
    ccw: Option<bool>,
    plane: Option<String>,
    turns: Option<u32>,
    feed: Option<f64>,
    beam: Option<bool>,
    beam_switch: Option<String>,
    role: Option<String>,
    chain: Option<u64>,
    block: Option<u64>,
    seconds: Option<f64>,
    rpm: Option<f64>,
    ta_ms: Option<f64>,
    ts_ms: Option<f64>,
    name: Option<String>,
    value: Option<f64>,
    sync: Option<bool>,
    schema: Option<String>,
    abc: Option<Vec<f64>>,
    tool: Option<u32>,
    tool_axis: Option<Vec<f64>>,
}

/// Streaming reader: `ToolpathReader::new(input)?` reads and checks the
/// header, then iterates the records.
pub struct ToolpathReader<R> {
    lines: LineSource<R>,
    header: Header,
    /// Where the previous move ended, to check arcs.
    pos: Option<P3>,
}

impl<R: BufRead> ToolpathReader<R> {
    /// Read and check the header: the schema, units "mm" if given, and
    /// `feed_units` ("mm/s", the default, or "mm/min").
    pub fn new(input: R) -> Result<Self, FormatError> {
        let mut lines = LineSource::new(input);
        let (text, line) = lines
            .next_line()?
            .ok_or_else(|| FormatError::invalid(1, format!("empty input: expected a '{SCHEMA}' header")))?;
        let h: WireHeader = parse_json(text, line)?;
        let source = h.source.clone();
        check_schema(h.schema.as_deref(), SCHEMA, line)?;
        if let Some(u) = h.units.as_deref()
            && u != "mm"
        {
            return Err(FormatError::invalid(
                line,
                format!("units '{u}' not supported (only \"mm\")"),
            ));
        }
        let feed_unit = match h.feed_units.as_deref() {
            None => FeedUnit::MmPerS,
            Some(s) => FeedUnit::from_name(s).ok_or_else(|| {
                FormatError::invalid(line, format!("feed_units '{s}' not supported (\"mm/s\" or \"mm/min\")"))
            })?,
        };
        Ok(ToolpathReader {
            lines,
            header: Header { feed_unit, source },
            pos: None,
        })
    }

    /// The stream's header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Read everything into memory (for tools that need the whole path).
    pub fn read_all(self) -> Result<(Header, Vec<Record>), FormatError> {
        let header = self.header.clone();
        let records = self.collect::<Result<Vec<_>, _>>()?;
        Ok((header, records))
    }

    fn next_record(&mut self) -> Result<Option<Record>, FormatError> {
        let Some((text, line)) = self.lines.next_line()? else {
            return Ok(None);
        };
        let w: WireRecord = parse_json(text, line)?;
        let rec = decode(w, line, self.pos)?;
        rec.check_numbers()
            .map_err(|m| FormatError::invalid(line, m.to_string()))?;
        if let Record::Move(m) = &rec {
            self.pos = Some(m.to);
        }
        Ok(Some(rec))
    }
}

impl<R: BufRead> Iterator for ToolpathReader<R> {
    type Item = Result<Record, FormatError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_record().transpose()
    }
}

fn need<T>(v: Option<T>, line: u64, kind: &str, field: &str) -> Result<T, FormatError> {
    v.ok_or_else(|| FormatError::invalid(line, format!("'{kind}' record needs '{field}'")))
}

fn finite(x: f64, line: u64, field: &str) -> Result<f64, FormatError> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(FormatError::invalid(line, format!("'{field}' is not finite")))
    }
}

fn decode(w: WireRecord, line: u64, pos: Option<P3>) -> Result<Record, FormatError> {
    if w.schema.is_some() {
        return Err(FormatError::invalid(
            line,
            "a second header in the middle of the stream",
        ));
    }
    let kind = need(w.kind.clone(), line, "toolpath", "type")?;
    let role = match w.role.as_deref() {
        None => None,
        Some(r) => Some(Role::from_name(r).ok_or_else(|| FormatError::invalid(line, format!("unknown role '{r}'")))?),
    };
    let block = w.block;
    let beam_switch = match w.beam_switch.as_deref() {
        None => None,
        Some(b) => Some(
            ShutterSwitch::from_name(b)
                .ok_or_else(|| FormatError::invalid(line, format!("unknown beam_switch '{b}' (sync or immediate)")))?,
        ),
    };
    let feed_of = |w: &WireRecord| -> Result<f64, FormatError> {
        let f = finite(need(w.feed, line, &kind, "feed")?, line, "feed")?;
        if f <= 0.0 {
            return Err(FormatError::invalid(line, format!("feed must be positive, got {f}")));
        }
        Ok(f)
    };
    let tool = tool_state(&w, line)?;
    let motion = |mk: MotionKind, to: P3, feed: Option<f64>| Motion {
        kind: mk,
        to,
        feed,
        beam: w.beam.unwrap_or(false),
        beam_switch,
        role,
        chain: w.chain,
        block,
        tool,
    };
    Ok(match kind.as_str() {
        "rapid" => {
            let to = point_from(&need(w.to.clone(), line, &kind, "to")?, line, "'to'")?;
            Record::Move(motion(MotionKind::Rapid, to, None))
        }
        "line" => {
            let to = point_from(&need(w.to.clone(), line, &kind, "to")?, line, "'to'")?;
            Record::Move(motion(MotionKind::Line, to, Some(feed_of(&w)?)))
        }
        "arc" => {
            let to = point_from(&need(w.to.clone(), line, &kind, "to")?, line, "'to'")?;
            let center = point_from(&need(w.center.clone(), line, &kind, "center")?, line, "'center'")?;
            let ccw = need(w.ccw, line, &kind, "ccw")?;
            let plane = match w.plane.as_deref() {
                None | Some("xy") => Plane::Xy,
                Some("xz") => Plane::Xz,
                Some("yz") => Plane::Yz,
                Some(p) => return Err(FormatError::invalid(line, format!("unknown plane '{p}'"))),
            };
            let extra_turns = match w.turns {
                None => 0,
                Some(0) => return Err(FormatError::invalid(line, "'turns' must be at least 1")),
                Some(t) => t - 1,
            };
            if let Some(start) = pos {
                check_arc(&start, &to, &center, plane, line)?;
            }
            let arc = ArcData {
                center,
                ccw,
                plane,
                extra_turns,
            };
            Record::Move(motion(MotionKind::Arc(arc), to, Some(feed_of(&w)?)))
        }
        "dwell" => {
            let s = finite(need(w.seconds, line, &kind, "seconds")?, line, "seconds")?;
            if s < 0.0 {
                return Err(FormatError::invalid(line, "dwell 'seconds' is negative"));
            }
            Record::Dwell { seconds: s, block }
        }
        "spindle" => Record::Spindle {
            rpm: finite(need(w.rpm, line, &kind, "rpm")?, line, "rpm")?,
            block,
        },
        "accel" => {
            let ta_ms = w.ta_ms.map(|v| finite(v, line, "ta_ms")).transpose()?;
            let ts_ms = w.ts_ms.map(|v| finite(v, line, "ts_ms")).transpose()?;
            if ta_ms.is_none() && ts_ms.is_none() {
                return Err(FormatError::invalid(line, "'accel' record needs 'ta_ms' or 'ts_ms'"));
            }
            Record::Accel { ta_ms, ts_ms, block }
        }
        "var" => Record::Var {
            name: need(w.name, line, &kind, "name")?,
            value: finite(need(w.value, line, &kind, "value")?, line, "value")?,
            sync: w.sync.unwrap_or(false),
            block,
        },
        other => {
            return Err(FormatError::invalid(
                line,
                format!("unknown record type '{other}' (rapid, line, arc, dwell, spindle, accel, var)"),
            ));
        }
    })
}

/// The optional milling fields of a move: `abc` (three numbers, degrees),
/// `tool` (a tool number) and `tool_axis` (a direction, normalised here).
fn tool_state(w: &WireRecord, line: u64) -> Result<ToolState, FormatError> {
    let abc = match w.abc.as_deref() {
        None => None,
        Some([a, b, c]) => Some([
            finite(*a, line, "abc")?,
            finite(*b, line, "abc")?,
            finite(*c, line, "abc")?,
        ]),
        Some(v) => {
            return Err(FormatError::invalid(
                line,
                format!("'abc' must be [a, b, c] (degrees), got {} numbers", v.len()),
            ));
        }
    };
    let axis = match w.tool_axis.as_deref() {
        None => None,
        Some([i, j, k]) => {
            let v = V3::new(
                finite(*i, line, "tool_axis")?,
                finite(*j, line, "tool_axis")?,
                finite(*k, line, "tool_axis")?,
            );
            let n = v.norm();
            if !n.is_finite() || n <= 1e-9 {
                return Err(FormatError::invalid(line, "'tool_axis' must be a non-zero direction"));
            }
            Some(v / n)
        }
        Some(v) => {
            return Err(FormatError::invalid(
                line,
                format!("'tool_axis' must be [i, j, k], got {} numbers", v.len()),
            ));
        }
    };
    Ok(ToolState {
        abc,
        number: w.tool,
        axis,
    })
}

/// An arc's start and end must be the same distance from its centre (within
/// what the G-code readers accept: LinuxCNC's spirals), and
/// the centre must lie in the start point's plane.
fn check_arc(start: &P3, to: &P3, center: &P3, plane: Plane, line: u64) -> Result<(), FormatError> {
    let c = plane.project(center);
    let r0 = (plane.project(start) - c).norm();
    let r1 = (plane.project(to) - c).norm();
    if !crate::gcode::arc_radii_accepted(r0, r1) {
        return Err(FormatError::invalid(
            line,
            format!("arc radius at start {r0} differs from radius at end {r1}"),
        ));
    }
    if r0 <= 0.0 {
        return Err(FormatError::invalid(line, "arc of zero radius"));
    }
    Ok(())
}

/// Streaming writer. Call [`ToolpathWriter::header`] once, then
/// [`ToolpathWriter::record`] for each record; [`ToolpathWriter::finish`]
/// flushes.
pub struct ToolpathWriter<W: Write> {
    lines: super::LineWriter<W>,
}

impl<W: Write> ToolpathWriter<W> {
    /// A writer into `out`.
    pub fn new(out: W) -> Self {
        ToolpathWriter {
            lines: super::LineWriter::new(out),
        }
    }

    /// Write the header line (schema, units, feed units, source).
    pub fn header(&mut self, h: &Header) -> std::io::Result<()> {
        self.lines
            .header(SCHEMA, &[("feed_units", h.feed_unit.name())], h.source.as_deref())
    }

    /// Write one record as one line.
    pub fn record(&mut self, r: &Record) -> std::io::Result<()> {
        self.lines.line(|b| format_record(b, r))
    }

    /// Flush and give back the output.
    pub fn finish(self) -> std::io::Result<W> {
        self.lines.finish()
    }
}

/// Append one record as a JSON object (no newline).
pub fn format_record(b: &mut String, r: &Record) {
    match r {
        Record::Move(m) => {
            let t = match m.kind {
                MotionKind::Rapid => "rapid",
                MotionKind::Line => "line",
                MotionKind::Arc(_) => "arc",
            };
            b.push_str("{\"type\":\"");
            b.push_str(t);
            b.push_str("\",\"to\":");
            push_point3(b, &m.to);
            if let MotionKind::Arc(a) = &m.kind {
                b.push_str(",\"center\":");
                push_point3(b, &a.center);
                b.push_str(if a.ccw { ",\"ccw\":true" } else { ",\"ccw\":false" });
                b.push_str(",\"plane\":\"");
                b.push_str(a.plane.name());
                b.push('"');
                if a.extra_turns > 0 {
                    b.push_str(",\"turns\":");
                    push_num(b, (a.extra_turns + 1) as f64);
                }
            }
            if let Some(f) = m.feed {
                b.push_str(",\"feed\":");
                push_num(b, f);
            }
            if m.feed.is_some() || m.beam {
                b.push_str(if m.beam { ",\"beam\":true" } else { ",\"beam\":false" });
            }
            if let Some(sw) = m.beam_switch {
                b.push_str(",\"beam_switch\":\"");
                b.push_str(sw.name());
                b.push('"');
            }
            if let Some(role) = m.role {
                b.push_str(",\"role\":\"");
                b.push_str(role.name());
                b.push('"');
            }
            if let Some(c) = m.chain {
                b.push_str(",\"chain\":");
                push_uint(b, c);
            }
            if let Some(abc) = &m.tool.abc {
                b.push_str(",\"abc\":");
                push_point3(b, &P3::new(abc[0], abc[1], abc[2]));
            }
            if let Some(t) = m.tool.number {
                b.push_str(",\"tool\":");
                push_uint(b, u64::from(t));
            }
            if let Some(a) = &m.tool.axis {
                b.push_str(",\"tool_axis\":");
                push_point3(b, &P3::from(*a));
            }
            push_block(b, m.block);
        }
        Record::Dwell { seconds, block } => {
            b.push_str("{\"type\":\"dwell\",\"seconds\":");
            push_num(b, *seconds);
            push_block(b, *block);
        }
        Record::Spindle { rpm, block } => {
            b.push_str("{\"type\":\"spindle\",\"rpm\":");
            push_num(b, *rpm);
            push_block(b, *block);
        }
        Record::Accel { ta_ms, ts_ms, block } => {
            b.push_str("{\"type\":\"accel\"");
            if let Some(v) = ta_ms {
                b.push_str(",\"ta_ms\":");
                push_num(b, *v);
            }
            if let Some(v) = ts_ms {
                b.push_str(",\"ts_ms\":");
                push_num(b, *v);
            }
            push_block(b, *block);
        }
        Record::Var {
            name,
            value,
            sync,
            block,
        } => {
            b.push_str("{\"type\":\"var\",\"name\":");
            push_str_lit(b, name);
            b.push_str(",\"value\":");
            push_num(b, *value);
            if *sync {
                b.push_str(",\"sync\":true");
            }
            push_block(b, *block);
        }
    }
    b.push('}');
}

fn push_block(b: &mut String, block: Option<u64>) {
    if let Some(n) = block {
        b.push_str(",\"block\":");
        push_uint(b, n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Vec<Record>, FormatError> {
        ToolpathReader::new(text.as_bytes())?.collect()
    }

    const EXAMPLE: &str = r#"{"schema":"microcam.toolpath/1","units":"mm","feed_units":"mm/s"}
{"type":"rapid","to":[0,-0.3,0]}
{"type":"line","to":[0,0,0],"feed":2,"beam":false,"role":"lead_in","chain":1}
{"type":"line","to":[10,0,0],"feed":2,"beam":true,"role":"cut","chain":1}
{"type":"arc","to":[10,10,0],"center":[10,5,0],"ccw":true,"plane":"xy","feed":2,"beam":true,"role":"cut","chain":1}
{"type":"dwell","seconds":0.05}
"#;

    #[test]
    fn milling_fields_are_optional_and_round_trip() {
        let text = r#"{"schema":"microcam.toolpath/1","units":"mm","feed_units":"mm/min"}
{"type":"rapid","to":[0,0,5],"abc":[0,90,-45.5],"tool":3}
{"type":"line","to":[1,0,5],"feed":100,"beam":true,"abc":[0,91,-45.5],"tool":3,"tool_axis":[0,0.6,0.8],"block":7}
{"type":"line","to":[2,0,5],"feed":100,"beam":true}
"#;
        let recs = read(text).unwrap();
        let m: Vec<&Motion> = recs.iter().filter_map(Record::motion).collect();
        assert_eq!(m[0].tool.abc, Some([0.0, 90.0, -45.5]));
        assert_eq!(m[1].tool.number, Some(3));
        assert_eq!(m[1].tool.axis, Some(V3::new(0.0, 0.6, 0.8)));
        assert!(m[2].tool.is_empty(), "an old-style move has none of them");
        let mut w = ToolpathWriter::new(Vec::new());
        w.header(&Header {
            feed_unit: FeedUnit::MmPerMin,
            source: None,
        })
        .unwrap();
        for r in &recs {
            w.record(r).unwrap();
        }
        assert_eq!(String::from_utf8(w.finish().unwrap()).unwrap(), text);
        // A tool axis is normalised; bad ones are named.
        let head = "{\"schema\":\"microcam.toolpath/1\"}\n";
        let recs = read(&format!(
            "{head}{{\"type\":\"rapid\",\"to\":[0,0,0],\"tool_axis\":[0,0,2]}}\n"
        ))
        .unwrap();
        assert_eq!(recs[0].motion().unwrap().tool.axis, Some(V3::new(0.0, 0.0, 1.0)));
        for (rec, needle) in [
            (
                r#"{"type":"rapid","to":[0,0,0],"tool_axis":[0,0,0]}"#,
                "non-zero direction",
            ),
            (
                r#"{"type":"rapid","to":[0,0,0],"abc":[1,2]}"#,
                "'abc' must be [a, b, c]",
            ),
            (r#"{"type":"rapid","to":[0,0,0],"tool":-1}"#, "line 2"),
        ] {
            let e = read(&format!("{head}{rec}\n")).unwrap_err().to_string();
            assert!(e.contains(needle), "{rec}: {e}");
        }
    }

    #[test]
    fn the_documented_example_round_trips_byte_for_byte() {
        let recs = read(EXAMPLE).unwrap();
        assert_eq!(recs.len(), 5);
        let mut w = ToolpathWriter::new(Vec::new());
        w.header(&Header::default()).unwrap();
        for r in &recs {
            w.record(r).unwrap();
        }
        let text = String::from_utf8(w.finish().unwrap()).unwrap();
        assert_eq!(text, EXAMPLE);
    }

    #[test]
    fn errors_name_the_line_and_the_problem() {
        let cases = [
            ("{\"schema\":\"microcam.toolpath/2\"}\n", 1, "unknown schema"),
            ("{\"type\":\"line\"}\n", 1, "header"),
            (
                "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"line\",\"to\":[1,2]}\n",
                2,
                "needs 'feed'",
            ),
            (
                "{\"schema\":\"microcam.toolpath/1\"}\n\n{\"type\":\"line\",\"to\":[1,2],\"feed\":NaN}\n",
                3,
                "bad JSON",
            ),
            (
                "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"jump\",\"to\":[1,2]}\n",
                2,
                "unknown record type",
            ),
            (
                "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"rapid\",\"to\":[1]}\n",
                2,
                "[x, y]",
            ),
            (
                "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"rapid\",\"to\":[0,0]}\n{\"type\":\"arc\",\"to\":[2,0],\"center\":[0.7,0],\"ccw\":true,\"feed\":1}\n",
                3,
                "radius",
            ),
            ("", 1, "empty input"),
        ];
        for (text, line, needle) in cases {
            let e = read(text).unwrap_err();
            assert_eq!(e.line(), line, "{text}: {e}");
            assert!(e.to_string().contains(needle), "{text}: {e}");
        }
    }
}

/// Why [`write_stream`] stopped: the source failed (nothing should be
/// committed) or writing failed.
#[derive(Debug)]
pub enum StreamError<E> {
    /// The record source's own error, as it gave it.
    Source(E),
    /// Writing the output failed.
    Io(std::io::Error),
}

/// Records per batch handed from the reading thread to the writing thread:
/// large enough that the hand-over costs nothing, small enough that memory
/// stays flat.
const BATCH: usize = 4096;

/// Write a header and every record of `records` to `out`, formatting on a
/// second thread while the caller's thread produces records (interpreting
/// G-code, say), so the two stages overlap on two cores. The channel holds
/// at most a few batches, so memory stays flat. Output is byte-identical to
/// writing with [`ToolpathWriter`] in one thread.
pub fn write_stream<W, E, I>(header: &Header, records: I, out: W) -> Result<W, StreamError<E>>
where
    W: Write + Send,
    I: Iterator<Item = Result<Record, E>>,
{
    let mut records = records;
    write_stream_batches(
        header,
        |batch: &mut Vec<Record>, max: usize| {
            while batch.len() < max {
                match records.next() {
                    Some(r) => batch.push(r?),
                    None => break,
                }
            }
            Ok(())
        },
        out,
    )
}

/// [`write_stream`] for a producer that fills whole batches: `fill(batch,
/// max)` appends up to `max` records to `batch` (fewer only at the end) or
/// fails. A producer that can move its records straight into the batch
/// (the G-code reader: [`crate::gcode::ProgramReader::next_batch`]) saves
/// the copies an iterator makes of each record on the way.
pub fn write_stream_batches<W, E, F>(header: &Header, mut fill: F, out: W) -> Result<W, StreamError<E>>
where
    W: Write + Send,
    F: FnMut(&mut Vec<Record>, usize) -> Result<(), E>,
{
    let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Record>>(4);
    let (back_tx, back_rx) = std::sync::mpsc::channel::<Vec<Record>>();
    std::thread::scope(|s| {
        let writer = s.spawn(move || -> std::io::Result<W> {
            let mut w = ToolpathWriter::new(out);
            w.header(header)?;
            for mut batch in rx {
                for r in &batch {
                    w.record(r)?;
                }
                batch.clear();
                // Hand the allocation back; if the producer is gone, drop it.
                let _ = back_tx.send(batch);
            }
            w.finish()
        });
        let mut failed = None;
        loop {
            let mut batch = back_rx.try_recv().unwrap_or_else(|_| Vec::with_capacity(BATCH));
            if let Err(e) = fill(&mut batch, BATCH) {
                // Nothing of a failed source is committed: its last batch
                // is dropped and the caller reports the error.
                failed = Some(e);
                break;
            }
            let last = batch.len() < BATCH;
            if !batch.is_empty() && tx.send(batch).is_err() {
                break; // the writer failed; its error is reported below
            }
            if last {
                break;
            }
        }
        drop(tx);
        let written = writer
            .join()
            .unwrap_or_else(|_| Err(std::io::Error::other("toolpath writer thread panicked")));
        match (failed, written) {
            (Some(e), _) => Err(StreamError::Source(e)),
            (None, Err(e)) => Err(StreamError::Io(e)),
            (None, Ok(w)) => Ok(w),
        }
    })
}

#[cfg(test)]
mod stream_tests {
    use super::*;

    fn sample(n: usize) -> Vec<Record> {
        (0..n)
            .map(|i| {
                Record::Move(Motion {
                    kind: MotionKind::Line,
                    to: P3::new(i as f64 * 0.1, (i % 7) as f64, 0.0),
                    feed: Some(2.0),
                    beam: i % 3 == 0,
                    beam_switch: None,
                    role: None,
                    chain: None,
                    block: Some(i as u64 + 1),
                    tool: Default::default(),
                })
            })
            .collect()
    }

    #[test]
    fn threaded_output_equals_single_threaded_output() {
        let recs = sample(3 * BATCH + 17);
        let h = Header::default();
        let mut w = ToolpathWriter::new(Vec::new());
        w.header(&h).unwrap();
        recs.iter().for_each(|r| w.record(r).unwrap());
        let want = w.finish().unwrap();
        let got = write_stream::<_, (), _>(&h, recs.into_iter().map(Ok), Vec::new()).unwrap();
        assert_eq!(got, want);
    }

    #[test]
    fn a_source_error_is_returned_not_swallowed() {
        let recs = sample(2 * BATCH);
        let it = recs
            .into_iter()
            .enumerate()
            .map(|(i, r)| if i == BATCH + 5 { Err("bad line") } else { Ok(r) });
        match write_stream(&Header::default(), it, Vec::new()) {
            Err(StreamError::Source(e)) => assert_eq!(e, "bad line"),
            other => panic!("expected the source error, got {:?}", other.map(|v| v.len())),
        }
    }
}
