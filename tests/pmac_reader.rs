//! The PMAC reader through the public API, on the sample programs under
//! `testdata/pmac/`, read from disk as the tools do (streaming, dialect
//! detected).

use microcam::gcode::{Dialect, GcodeError, ProgramReader, ReadOptions};
use microcam::model::toolpath::{MotionKind, Record};
use std::fs::File;
use std::io::BufReader;
use std::path::PathBuf;

fn sample(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("testdata/pmac")
        .join(name)
}

fn read_file(name: &str) -> (Dialect, Result<Vec<Record>, GcodeError>) {
    let file = File::open(sample(name)).expect("sample file");
    let reader = ProgramReader::new(BufReader::new(file), &ReadOptions::default()).expect("reader");
    let dialect = reader.dialect();
    (dialect, reader.collect())
}

#[test]
fn every_sample_is_detected_as_pmac() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("testdata/pmac");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "pmac") {
            let name = path.file_name().unwrap().to_str().unwrap().to_string();
            assert_eq!(read_file(&name).0, Dialect::Pmac, "{name}");
            n += 1;
        }
    }
    assert!(n >= 4);
}

#[test]
fn download_file_summary() {
    let (_, recs) = read_file("slot_and_hole.pmac");
    let recs = recs.unwrap();
    let moves: Vec<_> = recs.iter().filter_map(Record::motion).collect();
    assert_eq!(moves.len(), 7);
    let rapids = moves.iter().filter(|m| m.kind == MotionKind::Rapid).count();
    let arcs = moves.iter().filter(|m| matches!(m.kind, MotionKind::Arc(_))).count();
    assert_eq!((rapids, arcs), (2, 2));
    // Cutting moves: the slot's three segments and the hole.
    let lit: Vec<u64> = moves.iter().filter(|m| m.beam).filter_map(|m| m.block).collect();
    assert_eq!(lit, [11, 13, 15, 19]);
    let end = moves.last().unwrap().to;
    assert!((end.x - 1.0).abs() < 1e-12 && (end.y + 1.0).abs() < 1e-12 && end.z == 0.0);
}

#[test]
fn bare_program_reads_whole() {
    let (_, recs) = read_file("bare_shutter_contour.pmac");
    let recs = recs.unwrap();
    assert_eq!(recs.len(), 8);
    assert_eq!(recs.last().unwrap().block(), Some(16));
}

#[test]
fn arc_error_names_its_line() {
    let (_, recs) = read_file("arc_off_circle.pmac");
    let err = recs.unwrap_err();
    assert_eq!(err.line(), 3);
    assert!(
        err.to_string().starts_with("line 3: arc end is not on the circle"),
        "{err}"
    );
}
