//! Every DXF file of the shared corpus (real drawings from other programs,
//! read in place: see `microcam::corpus`) and every sample of our own
//! through the library: each either converts into chains that the chains
//! reader accepts back, byte-identically on a second run, or fails with a
//! located error. Files with a known feature are checked for it. Without
//! the corpus the corpus tests skip, saying so.

use microcam::dxf::{self, ImportOptions, UnitSource, chain};
use microcam::formats::chains::{ChainsReader, ChainsWriter};
use microcam::model::chain::{Chain, ChainsHeader, Segment};
use std::io::{BufReader, Cursor};
use std::path::{Path, PathBuf};

/// The corpus's dxf folder, or `None` after noting that `test` skipped.
fn corpus(test: &str) -> Option<PathBuf> {
    match microcam::corpus::dir() {
        Some(d) => Some(d.join("dxf")),
        None => {
            microcam::corpus::skip(test);
            None
        }
    }
}

fn corpus_dir() -> PathBuf {
    microcam::corpus::dir().expect("corpus present").join("dxf")
}

fn own(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(rel)
}

struct Run {
    imp: dxf::Import,
    chains: Vec<Chain>,
    report: chain::ChainReport,
    text: Vec<u8>,
}

fn convert(name: &str, opts: &ImportOptions) -> Result<Run, String> {
    convert_path(&corpus_dir().join(name), opts)
}

fn convert_path(path: &Path, opts: &ImportOptions) -> Result<Run, String> {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let f = std::fs::File::open(path).unwrap();
    let mut imp = dxf::import(Box::new(BufReader::new(f)), opts).map_err(|e| e.to_string())?;
    let segs = std::mem::take(&mut imp.sink.segments);
    let (chains, report) = chain::build(segs, &imp.sink.points, &imp.sink.layers, 0.001);
    let chains: Vec<Chain> = chains.iter().collect();
    let mut w = ChainsWriter::new(Vec::new());
    w.header(&ChainsHeader {
        source: Some(name.clone()),
    })
    .unwrap();
    for c in &chains {
        w.chain(c).unwrap();
    }
    let text = w.finish().unwrap();
    Ok(Run {
        imp,
        chains,
        report,
        text,
    })
}

fn run(name: &str) -> Run {
    convert(name, &ImportOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn radius(s: &Segment) -> Option<f64> {
    s.radius()
}

/// One file through the library: converts cleanly (chains read back,
/// identical on a second run, snapped) or fails at a located line or byte.
fn check_file(path: &Path, expect_error: bool) {
    let name = path.display();
    match convert_path(path, &ImportOptions::default()) {
        Err(e) => {
            assert!(expect_error, "{name}: {e}");
            assert!(
                e.starts_with("line ") || e.starts_with("byte "),
                "{name}: error not located: {e}"
            );
        }
        Ok(r) => {
            assert!(!expect_error, "{name} should fail");
            // The pipe format's own reader accepts every chain back.
            let back: Vec<Chain> = ChainsReader::new(Cursor::new(&r.text))
                .unwrap()
                .collect::<Result<_, _>>()
                .unwrap_or_else(|e| panic!("{name}: chains reader rejects our output: {e}"));
            assert_eq!(back.len(), r.chains.len());
            // Identical input, identical output.
            let again = convert_path(path, &ImportOptions::default()).unwrap();
            assert_eq!(again.text, r.text, "{name}: output differs between runs");
            for c in &r.chains {
                for w in c.segments.windows(2) {
                    assert_eq!(w[0].end(), w[1].start(), "{name}: chain {} not snapped", c.id);
                }
                if c.closed {
                    assert_eq!(c.segments.last().unwrap().end(), c.segments[0].start());
                }
            }
        }
    }
}

#[test]
fn every_corpus_file_converts_or_fails_cleanly() {
    let Some(dir) = corpus("dxf_every_corpus_file") else {
        return;
    };
    let files = microcam::corpus::files("dxf", &[".dxf"]);
    assert!(files.len() >= 30, "{}: expected the DXF corpus", dir.display());
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy();
        check_file(path, name.starts_with("nothing-decimal-comma"));
    }
    microcam::corpus::record("dxf_every_corpus_file", files.len());
}

#[test]
fn every_own_sample_and_broken_file_converts_or_fails_cleanly() {
    let mut n = 0;
    for sub in ["samples", "dxf"] {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(own(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("dxf")))
            .collect();
        paths.sort();
        for path in paths {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            check_file(&path, name.starts_with("bad-") || name.starts_with("decimal-comma"));
            n += 1;
        }
    }
    assert!(n >= 13, "{n} files");
}

#[test]
fn stir_mirrored_arcs_land_where_autocad_draws_them() {
    if corpus("stir_mirrored_arcs_land_where_autocad_draws_them").is_none() {
        return;
    }
    microcam::corpus::record("stir_mirrored_arcs_land_where_autocad_draws_them", 1);
    let r = run("Stir_1.dxf");
    assert_eq!(r.report.closed, 14);
    assert_eq!(r.report.open, 0);
    // The central hole: a circle with extrusion (0,0,-1) at OCS x = -3.489655
    // lies at world x = +3.489655.
    let hole = r
        .chains
        .iter()
        .find(|c| c.segments.len() == 1 && radius(&c.segments[0]).is_some_and(|x| (x - 26.8).abs() < 1e-6))
        .expect("the central circle");
    let Some(center) = hole.segments[0].arc().map(|a| a.center) else {
        unreachable!()
    };
    assert!(
        (center.x - 3.489655).abs() < 1e-9 && (center.y + 0.846101).abs() < 1e-9,
        "{center:?}"
    );
    // Every arc of the outline ends on its neighbours: no chain is open,
    // which would not be so if the mirrored arcs were placed unmirrored.
}

#[test]
fn duplicate_lines_halve() {
    if corpus("duplicate_lines_halve").is_none() {
        return;
    }
    microcam::corpus::record("duplicate_lines_halve", 1);
    let r = run("1997_simplified_doppelte_linien.dxf");
    assert_eq!(r.imp.sink.used.get("LINE"), Some(&908));
    assert_eq!(r.report.duplicates, 454);
    let segs: usize = r.chains.iter().map(|c| c.segments.len()).sum();
    assert_eq!(segs, 454);
    assert!(r.chains.iter().all(|c| c.closed));
}

#[test]
fn inch_file_scales_by_25_4() {
    if corpus("inch_file_scales_by_25_4").is_none() {
        return;
    }
    microcam::corpus::record("inch_file_scales_by_25_4", 1);
    let inch = run("fc_mounting.dxf");
    let plain = run("fc_mounting_R12.dxf");
    assert_eq!(inch.imp.unit_source, UnitSource::Header(1));
    assert_eq!(plain.imp.unit_source, UnitSource::Assumed);
    let ri: Vec<f64> = inch.chains.iter().filter_map(|c| radius(&c.segments[0])).collect();
    let rp: Vec<f64> = plain.chains.iter().filter_map(|c| radius(&c.segments[0])).collect();
    assert_eq!(ri.len(), 8);
    for (a, b) in ri.iter().zip(&rp) {
        assert!((a / b - 25.4).abs() < 1e-9, "{a} {b}");
    }
    // --units overrides the header.
    let o = ImportOptions {
        units_mm: Some(1.0),
        ..Default::default()
    };
    let mm = convert("fc_mounting.dxf", &o).unwrap();
    assert!((radius(&mm.chains[0].segments[0]).unwrap() - 1.3).abs() < 1e-9);
}

#[test]
fn splines_and_ellipses_come_out_as_arcs() {
    if corpus("splines_and_ellipses_come_out_as_arcs").is_none() {
        return;
    }
    microcam::corpus::record("splines_and_ellipses_come_out_as_arcs", 1);
    for name in [
        "Inkspace_dxf_export_kreis_splines.dxf",
        "ellipse-reverse.dxf",
        "camotics.dxf",
        "Wiele.DXF",
    ] {
        let r = run(name);
        assert!(r.imp.sink.curves > 0, "{name}");
        assert!(
            r.imp.sink.curve_pieces < r.imp.sink.curve_chords,
            "{name}: no blocks saved"
        );
        let arcs = r
            .chains
            .iter()
            .flat_map(|c| &c.segments)
            .filter(|s| matches!(s, Segment::Arc { .. }))
            .count();
        assert!(arcs as u64 >= r.imp.sink.curve_pieces / 2, "{name}: mostly lines");
    }
    // Inkscape's circle of seven splines is one closed chain.
    let r = run("Inkspace_dxf_export_kreis_splines.dxf");
    assert_eq!((r.report.closed, r.report.open), (1, 0));
}

#[test]
fn inserts_nested_and_mirrored() {
    if corpus("inserts_nested_and_mirrored").is_none() {
        return;
    }
    microcam::corpus::record("inserts_nested_and_mirrored", 1);
    let r = run("transform-insert.dxf");
    assert_eq!(r.imp.sink.used.get("INSERT"), Some(&6));
    assert_eq!((r.report.closed, r.report.open), (3, 0));
    let r = run("insert_bricscad_level_1.dxf");
    assert_eq!(r.imp.unit_source, UnitSource::Header(6));
    assert_eq!(r.chains.len(), 330);
    let r = run("Bogen_Ellipsen_Polylinien_Block.dxf");
    assert_eq!(r.imp.unit_source, UnitSource::Header(1));
    assert!(r.imp.sink.curves >= 15);
}

#[test]
fn binary_files_read() {
    if corpus("binary_files_read").is_none() {
        return;
    }
    microcam::corpus::record("binary_files_read", 1);
    let r = run("bin_dxf_r12.dxf");
    assert!(r.imp.binary);
    assert_eq!(r.imp.sink.used.get("LINE"), Some(&3));
    let r = run("diamond-bin.dxf");
    assert!(r.imp.binary);
    assert_eq!(r.imp.sink.used.get("LINE"), Some(&12));
}

#[test]
fn skipped_types_are_counted() {
    if corpus("skipped_types_are_counted").is_none() {
        return;
    }
    microcam::corpus::record("skipped_types_are_counted", 1);
    let r = run("FLH-001.dxf");
    assert_eq!(r.imp.skipped.get("SOLID"), Some(&22));
    assert_eq!(r.imp.skipped.get("TEXT"), Some(&12));
}

#[test]
fn decimal_commas_fail_at_their_line() {
    if corpus("decimal_commas_fail_at_their_line").is_none() {
        return;
    }
    microcam::corpus::record("decimal_commas_fail_at_their_line", 1);
    let e = convert("nothing-decimal-comma-separated.dxf", &ImportOptions::default())
        .err()
        .unwrap();
    assert!(e.starts_with("line 10:") && e.contains("decimal comma"), "{e}");
}

#[test]
fn every_prefix_of_a_file_fails_cleanly_or_converts() {
    // Truncation anywhere: never a panic, never accepted.
    for name in ["samples/part.dxf", "samples/part-bin.dxf", "samples/blocks.dxf"] {
        let bytes = std::fs::read(own(name)).unwrap();
        for cut in (0..bytes.len()).step_by(7) {
            let r = dxf::import(Box::new(Cursor::new(bytes[..cut].to_vec())), &ImportOptions::default());
            assert!(r.is_err(), "{name} cut at {cut} accepted");
        }
    }
}

#[test]
fn own_samples_have_their_features() {
    let run_own = |rel: &str| convert_path(&own(rel), &ImportOptions::default()).unwrap();
    // The part: outline, 4 holes, slot, ellipse, spline pocket (closed),
    // the engraving (open) and a pierce point.
    let r = run_own("samples/part.dxf");
    assert_eq!((r.report.closed, r.report.open), (8, 1));
    assert_eq!(r.imp.sink.curves, 2, "spline and ellipse");
    assert!(r.imp.sink.curve_pieces < r.imp.sink.curve_chords);
    assert_eq!(r.imp.sink.points.len(), 1);
    // Inches: 25.4 mm per unit from the header; --units overrides it.
    let r = run_own("samples/part-inch.dxf");
    assert_eq!(r.imp.unit_source, UnitSource::Header(1));
    let hole = r
        .chains
        .iter()
        .find_map(|c| (c.segments.len() == 1).then(|| radius(&c.segments[0])).flatten())
        .unwrap();
    assert!((hole - 0.0625 * 25.4).abs() < 1e-9, "{hole}");
    // Blocks: nested, mirrored in X and in Y, rotated, scaled.
    let r = run_own("samples/blocks.dxf");
    assert_eq!(r.imp.sink.used.get("INSERT"), Some(&5));
    assert_eq!((r.report.closed, r.report.open), (9, 0));
    // Duplicates: 4 removed (drawn reversed), a zero-length piece, a gap.
    let r = run_own("samples/duplicates.dxf");
    assert_eq!(r.report.duplicates, 4);
    assert_eq!((r.report.closed, r.report.open), (2, 0));
    // OCS (0,0,-1): the circle drawn at OCS x = -5 lies at world x = +5.
    let r = run_own("samples/ocs-mirror.dxf");
    let c = r
        .chains
        .iter()
        .find_map(|c| match c.segments.as_slice() {
            [Segment::Arc(a)] => Some(a.center),
            _ => None,
        })
        .unwrap();
    assert!((c.x - 5.0).abs() < 1e-9 && (c.y - 2.0).abs() < 1e-9, "{c:?}");
    // TEXT and SOLID are counted as skipped.
    let r = run_own("samples/text-skipped.dxf");
    assert_eq!(r.imp.skipped.get("TEXT"), Some(&1));
    assert_eq!(r.imp.skipped.get("SOLID"), Some(&1));
    // Binary.
    let r = run_own("samples/part-bin.dxf");
    assert!(r.imp.binary);
    assert_eq!(r.imp.sink.used.get("LINE"), Some(&3));
    // Decimal commas fail at their line.
    let e = convert_path(&own("samples/decimal-comma.dxf"), &ImportOptions::default())
        .err()
        .unwrap();
    assert!(e.starts_with("line ") && e.contains("decimal comma"), "{e}");
}
