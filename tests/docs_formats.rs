//! docs/formats.md must not drift from the code: every ```jsonl block in it
//! is read by our readers and written back byte for byte, and every
//! ```jsonl-invalid block fails with exactly the message in the ```text
//! block that follows it.

use microcam::formats::chains::{self, ChainsReader, ChainsWriter};
use microcam::formats::toolpath::{self, ToolpathReader, ToolpathWriter};

const DOC: &str = include_str!("../docs/formats.md");

/// (info string, body) of every fenced block, in order.
fn blocks() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut cur: Option<(String, String)> = None;
    for line in DOC.lines() {
        match (&mut cur, line.strip_prefix("```")) {
            (None, Some(info)) => cur = Some((info.trim().to_string(), String::new())),
            (Some(_), Some("")) => out.push(cur.take().unwrap()),
            (Some((_, body)), _) => {
                body.push_str(line);
                body.push('\n');
            }
            (None, None) => {}
        }
    }
    assert!(cur.is_none(), "unclosed code block in docs/formats.md");
    out
}

/// Read `text` with the reader its header names and write it back.
fn round_trip(text: &str) -> Result<String, String> {
    if text.contains(chains::SCHEMA) {
        let r = ChainsReader::new(text.as_bytes()).map_err(|e| e.to_string())?;
        let mut w = ChainsWriter::new(Vec::new());
        w.header(r.header()).unwrap();
        for c in r {
            w.chain(&c.map_err(|e| e.to_string())?).unwrap();
        }
        Ok(String::from_utf8(w.finish().unwrap()).unwrap())
    } else {
        let r = ToolpathReader::new(text.as_bytes()).map_err(|e| e.to_string())?;
        let mut w = ToolpathWriter::new(Vec::new());
        w.header(r.header()).unwrap();
        for rec in r {
            w.record(&rec.map_err(|e| e.to_string())?).unwrap();
        }
        Ok(String::from_utf8(w.finish().unwrap()).unwrap())
    }
}

#[test]
fn valid_examples_round_trip_byte_for_byte() {
    let mut n = 0;
    for (info, body) in blocks() {
        if info == "jsonl" {
            n += 1;
            assert_eq!(round_trip(&body).as_deref(), Ok(body.as_str()), "example:\n{body}");
        }
    }
    assert!(n >= 4, "only {n} jsonl examples found");
}

#[test]
fn invalid_examples_fail_with_the_documented_message() {
    let bs = blocks();
    let mut n = 0;
    for (i, (info, body)) in bs.iter().enumerate() {
        if info == "jsonl-invalid" {
            n += 1;
            let (next_info, want) = bs
                .get(i + 1)
                .expect("an invalid example needs a ```text block after it");
            assert_eq!(next_info, "text", "after invalid example:\n{body}");
            let got = round_trip(body).expect_err(body);
            assert_eq!(got, want.trim_end(), "example:\n{body}");
        }
    }
    assert!(n >= 2, "only {n} invalid examples found");
}

#[test]
fn error_table_messages_are_real() {
    // The stream-level messages quoted in the tables.
    let cases = [
        ("", "line 1: empty input: expected a 'microcam.toolpath/1' header"),
        ("{\"type\":\"line\"}\n", "the first record must be a header"),
        (
            "{\"schema\":\"microcam.toolpath/2\"}\n",
            "unknown schema 'microcam.toolpath/2'",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\",\"units\":\"in\"}\n",
            "units 'in' not supported (only \"mm\")",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\"}\n{\"schema\":\"microcam.toolpath/1\"}\n",
            "line 2: a second header in the middle of the stream",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\",\"feed_units\":\"in/min\"}\n",
            "line 1: feed_units 'in/min' not supported (\"mm/s\" or \"mm/min\")",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"rapid\",\"type\":\"line\",\"to\":[0,0]}\n",
            "line 2: bad JSON record: duplicate field `type`",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"rapid\",\"to\":[1e999,0]}\n",
            "line 2: bad JSON record: number out of range",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"line\",\"to\":[1,0],\"feed\":null}\n",
            "line 2: 'line' record needs 'feed'",
        ),
        (
            "{\"schema\":\"microcam.toolpath/1\"}\n\u{0}\u{ff}\n",
            "invalid utf-8 sequence",
        ),
    ];
    for (text, want) in cases {
        let got = if text.contains('\u{ff}') {
            // Not valid UTF-8 once the escape is turned into a raw byte.
            let mut bytes = text.as_bytes().to_vec();
            let at = bytes.windows(2).position(|w| w == "\u{ff}".as_bytes()).unwrap();
            bytes.splice(at..at + 2, [0xff]);
            let r = ToolpathReader::new(bytes.as_slice()).unwrap();
            r.collect::<Result<Vec<_>, _>>().unwrap_err().to_string()
        } else {
            round_trip(text).unwrap_err()
        };
        assert!(got.contains(want), "{text:?}: got {got:?}, want {want:?}");
    }
    assert_eq!(toolpath::SCHEMA, "microcam.toolpath/1");
}

#[test]
fn record_table_messages_are_real() {
    let tp = "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"rapid\",\"to\":[0,0,0]}\n";
    let toolpath_cases = [
        ("{\"to\":[1,0]}", "'toolpath' record needs 'type'"),
        (
            "{\"type\":\"line\",\"to\":[1,0],\"feed\":1,\"role\":\"cutting\"}",
            "unknown role 'cutting'",
        ),
        (
            "{\"type\":\"arc\",\"to\":[1,0],\"ccw\":true,\"feed\":1}",
            "'arc' record needs 'center'",
        ),
        (
            "{\"type\":\"rapid\",\"to\":[1]}",
            "'to' must be [x, y] or [x, y, z], got 1 numbers",
        ),
        (
            "{\"type\":\"arc\",\"to\":[1,0],\"center\":[0.5,0],\"ccw\":true,\"plane\":\"zx\",\"feed\":1}",
            "unknown plane 'zx'",
        ),
        (
            "{\"type\":\"arc\",\"to\":[1,0],\"center\":[0.5,0],\"ccw\":true,\"turns\":0,\"feed\":1}",
            "'turns' must be at least 1",
        ),
        (
            "{\"type\":\"arc\",\"to\":[0,0],\"center\":[0,0],\"ccw\":true,\"feed\":1}",
            "arc of zero radius",
        ),
        (
            "{\"type\":\"line\",\"to\":[1,0],\"feed\":0}",
            "feed must be positive, got 0",
        ),
        (
            "{\"type\":\"rapid\",\"to\":[0,0],\"abc\":[1,2]}",
            "'abc' must be [a, b, c] (degrees), got 2 numbers",
        ),
        (
            "{\"type\":\"rapid\",\"to\":[0,0],\"tool_axis\":[0,0,0]}",
            "'tool_axis' must be a non-zero direction",
        ),
        ("{\"type\":\"dwell\",\"seconds\":-1}", "dwell 'seconds' is negative"),
        ("{\"type\":\"accel\"}", "'accel' record needs 'ta_ms' or 'ts_ms'"),
        (
            "{\"type\":\"jump\"}",
            "unknown record type 'jump' (rapid, line, arc, dwell, spindle, accel, var)",
        ),
    ];
    for (rec, want) in toolpath_cases {
        let got = round_trip(&format!("{tp}{rec}\n")).unwrap_err();
        assert_eq!(got, format!("line 3: {want}"), "{rec}");
    }

    let ch = "{\"schema\":\"microcam.chains/1\"}\n";
    let line = |a: &str, b: &str| format!("{{\"type\":\"line\",\"start\":{a},\"end\":{b}}}");
    let chain_cases = [
        ("{\"closed\":true,\"segments\":[]}".to_string(), "chain needs 'id'"),
        (
            format!("{{\"id\":1,\"closed\":false,\"segments\":[{},{{\"type\":\"line\",\"end\":[2,0]}}]}}", line("[0,0]", "[1,0]")),
            "segment 2 needs 'start'",
        ),
        (
            "{\"id\":1,\"closed\":false,\"segments\":[{\"type\":\"arc\",\"start\":[0,0],\"end\":[3,0],\"ccw\":true}]}".into(),
            "arc segment 1 needs 'center'",
        ),
        (
            format!("{{\"id\":1,\"closed\":false,\"segments\":[{},{{\"type\":\"spline\",\"start\":[1,0],\"end\":[2,0]}}]}}", line("[0,0]", "[1,0]")),
            "segment 2: unknown type 'spline' (line or arc)",
        ),
        (
            format!("{{\"id\":1,\"closed\":false,\"segments\":[{}]}}", line("[0,0]", "[1]")),
            "segment 1 'end' must be [x, y] or [x, y, z], got 1 numbers",
        ),
        (
            "{\"id\":1,\"closed\":false,\"segments\":[{\"type\":\"arc\",\"start\":[0,0],\"end\":[3,0],\"center\":[1,0],\"ccw\":true}]}".into(),
            "arc segment 1: radius at start 1 differs from radius at end 2",
        ),
        (
            format!("{{\"id\":1,\"closed\":false,\"segments\":[{},{}]}}", line("[0,0]", "[1,0]"), line("[2,0]", "[3,0]")),
            "segment 2 starts at [2.0, 0.0, 0.0] but segment 1 ended at [1.0, 0.0, 0.0]",
        ),
        (
            format!("{{\"id\":1,\"closed\":true,\"segments\":[{}]}}", line("[0,0]", "[1,0]")),
            "chain is marked closed but does not end where it starts",
        ),
    ];
    for (rec, want) in chain_cases {
        let got = round_trip(&format!("{ch}{rec}\n")).unwrap_err();
        assert_eq!(got, format!("line 2: {want}"), "{rec}");
    }
}

/// A ```ngc (ISO) or ```pmac program in the document is followed by the
/// toolpath our G-code reader makes of it.
#[test]
fn gcode_examples_read_as_documented() {
    use microcam::gcode::{ReadOptions, read_str};
    use microcam::model::toolpath::Header;
    let bs = blocks();
    let mut n = 0;
    for (i, (info, program)) in bs.iter().enumerate() {
        let want_dialect = match info.as_str() {
            "ngc" => microcam::gcode::Dialect::Iso,
            "pmac" => microcam::gcode::Dialect::Pmac,
            _ => continue,
        };
        n += 1;
        let (next_info, want) = bs.get(i + 1).expect("a G-code example needs a ```jsonl block after it");
        assert_eq!(next_info, "jsonl", "after G-code example:\n{program}");
        let (dialect, records) =
            read_str(program, &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}\n{program}"));
        assert_eq!(dialect, want_dialect, "detected dialect of:\n{program}");
        let source = ToolpathReader::new(want.as_bytes()).unwrap().header().source.clone();
        let mut w = ToolpathWriter::new(Vec::new());
        w.header(&Header {
            feed_unit: dialect.feed_unit(),
            source,
        })
        .unwrap();
        for r in &records {
            w.record(r).unwrap();
        }
        assert_eq!(
            String::from_utf8(w.finish().unwrap()).unwrap(),
            *want,
            "program:\n{program}"
        );
    }
    assert!(n >= 2, "only {n} G-code examples found");
}

/// A ```ngc-invalid program fails with the message in the ```text block after it.
#[test]
fn invalid_gcode_examples_fail_with_the_documented_message() {
    use microcam::gcode::{ReadOptions, read_str};
    let bs = blocks();
    let mut n = 0;
    for (i, (info, program)) in bs.iter().enumerate() {
        if info == "ngc-invalid" || info == "pmac-invalid" {
            n += 1;
            let (next_info, want) = bs
                .get(i + 1)
                .expect("an invalid example needs a ```text block after it");
            assert_eq!(next_info, "text");
            let err = read_str(program, &ReadOptions::default()).expect_err(program);
            assert_eq!(err.to_string(), want.trim_end(), "program:\n{program}");
        }
    }
    assert!(n >= 1, "no invalid G-code example found");
}

/// "Chain ids are written as exact integers, whatever their size."
#[test]
fn large_ids_round_trip() {
    let text = "{\"schema\":\"microcam.chains/1\",\"units\":\"mm\"}\n{\"id\":18446744073709551615,\"closed\":false,\"segments\":[]}\n";
    assert_eq!(round_trip(text).as_deref(), Ok(text));
    let text = "{\"schema\":\"microcam.toolpath/1\",\"units\":\"mm\",\"feed_units\":\"mm/s\"}\n{\"type\":\"rapid\",\"to\":[0,0,0],\"chain\":4000000,\"block\":9007199254740993}\n";
    assert_eq!(round_trip(text).as_deref(), Ok(text));
}
