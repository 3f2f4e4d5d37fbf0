//! Golden files: toolpath JSON Lines in testdata/writer/ streamed through
//! the G-code writer must give the stored programs byte for byte, so any
//! change to the output format shows up as a diff in review (and the reader
//! engineers get real writer output to test against).
//!
//! After an intended format change, regenerate with
//! `UPDATE_GOLDEN=1 cargo test --test gcode_writer_golden` and review the diff.

use microcam::formats::toolpath::ToolpathReader;
use microcam::gcode::Dialect;
use microcam::gcode::writer::{GcodeWriter, WriteOptions};
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("testdata/writer")
}

/// Stream `input` through the writer one record at a time, as a CLI would.
fn render(input: &str, opts: WriteOptions) -> String {
    let text = std::fs::read_to_string(dir().join(input)).expect("read input");
    let reader = ToolpathReader::new(text.as_bytes()).expect("toolpath header");
    let unit = reader.header().feed_unit;
    let mut w = GcodeWriter::new(Vec::new(), opts, unit);
    w.begin().expect("header");
    for r in reader {
        w.record(&r.expect("toolpath record")).expect("write record");
    }
    String::from_utf8(w.finish().expect("trailer")).expect("utf-8")
}

fn check(input: &str, opts: WriteOptions, golden: &str) {
    let got = render(input, opts);
    let path = dir().join(golden);
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, &got).expect("write golden");
        return;
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(got, want, "{} differs from {}", input, path.display());
}

#[test]
fn laser_pmac() {
    check("laser.jsonl", WriteOptions::for_dialect(Dialect::Pmac), "laser.pmac");
}

#[test]
fn laser_iso_numbered_with_comments() {
    let mut o = WriteOptions::for_dialect(Dialect::Iso);
    o.line_numbers = Some(10);
    o.comments = true;
    check("laser.jsonl", o, "laser.ngc");
}

#[test]
fn mixed_pmac() {
    check("mixed.jsonl", WriteOptions::for_dialect(Dialect::Pmac), "mixed.pmac");
}

#[test]
fn mixed_iso() {
    check("mixed.jsonl", WriteOptions::for_dialect(Dialect::Iso), "mixed.ngc");
}
