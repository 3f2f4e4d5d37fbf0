//! Hostile but well-formed drawings: extreme coordinates, curves that would
//! subdivide for ever, self-inserting blocks, deep nesting and insert bombs.
//! Each must end quickly with a located error or a bounded, warned result.

use super::{Import, ImportOptions, import};
use crate::dxf::reader::DxfError;
use std::io::Cursor;
use std::time::Instant;

fn run(text: &str, opts: &ImportOptions) -> Result<Import, DxfError> {
    import(Box::new(Cursor::new(text.as_bytes().to_vec())), opts)
}

fn entities(body: &str) -> String {
    format!("0\nSECTION\n2\nENTITIES\n{body}0\nENDSEC\n0\nEOF\n")
}

fn line(a: (f64, f64), b: (f64, f64)) -> String {
    format!(
        "0\nLINE\n8\n0\n10\n{:e}\n20\n{:e}\n11\n{:e}\n21\n{:e}\n",
        a.0, a.1, b.0, b.1
    )
}

fn triangle(far: f64) -> String {
    entities(&(line((0.0, 0.0), (far, 0.0)) + &line((far, 0.0), (0.0, 1.0)) + &line((0.0, 1.0), (0.0, 0.0))))
}

fn err(text: &str, opts: &ImportOptions) -> String {
    let t = Instant::now();
    let e = run(text, opts).expect_err("must be refused").to_string();
    assert!(t.elapsed().as_secs() < 10, "took {:?}", t.elapsed());
    e
}

#[test]
fn far_vertices_are_bad_input_at_their_line() {
    for far in [1e308, -1e308, 1e300, 1.0e10, -2e9, 1e9 * (1.0 + 1e-9)] {
        let e = err(&triangle(far), &ImportOptions::default());
        // The first LINE starts at line 5.
        assert!(e.starts_with("line 5:") && e.contains("beyond"), "{far}: {e}");
    }
    // At the limit itself: accepted.
    let imp = run(&triangle(1e9), &ImportOptions::default()).unwrap();
    assert_eq!(imp.sink.segments.len(), 3);
    // In y and z too, and on the second entity.
    let t = entities(&(line((0.0, 0.0), (1.0, 0.0)) + &line((1.0, 0.0), (1.0, -5e9))));
    let e = err(&t, &ImportOptions::default());
    assert!(e.starts_with("line 17:"), "{e}");
    let t = entities("0\nLINE\n10\n0\n20\n0\n30\n1e12\n11\n1\n21\n0\n31\n0\n");
    assert!(err(&t, &ImportOptions::default()).contains("beyond"));
}

#[test]
fn the_limit_is_after_units_and_user_transforms() {
    let t = triangle(1e8);
    assert!(run(&t, &ImportOptions::default()).is_ok());
    let inch = ImportOptions {
        units_mm: Some(25.4),
        ..Default::default()
    };
    assert!(err(&t, &inch).starts_with("line 5:"));
    let moved = ImportOptions {
        copies: vec![crate::dxf::ocs::Affine::translate(crate::geometry::V3::new(
            0.0, 2e9, 0.0,
        ))],
        ..Default::default()
    };
    assert!(err(&t, &moved).contains("beyond"));
    // A finite coordinate that overflows to infinity under the unit scale.
    let t = triangle(1e308);
    assert!(err(&t, &inch).contains("beyond"));
}

#[test]
fn far_curves_are_refused_before_fitting() {
    let spline = |c: f64| {
        let mut s = String::from("0\nSPLINE\n8\n0\n70\n8\n71\n3\n72\n8\n73\n4\n");
        for k in [0, 0, 0, 0, 1, 1, 1, 1] {
            s += &format!("40\n{k}\n");
        }
        for (x, y) in [(0.0, 0.0), (c, 1.0), (-c, 3.0), (5.0, c)] {
            s += &format!("10\n{x:e}\n20\n{y:e}\n30\n0\n");
        }
        entities(&s)
    };
    for c in [1e20, 1e300, -3e9] {
        assert!(err(&spline(c), &ImportOptions::default()).starts_with("line 5:"));
    }
    let ellipse = |major: f64, ratio: f64| {
        entities(&format!(
            "0\nELLIPSE\n8\n0\n10\n0\n20\n0\n30\n0\n11\n{major:e}\n21\n0\n31\n0\n40\n{ratio:e}\n41\n0\n42\n6.283185307179586\n"
        ))
    };
    for (m, r) in [(1e20, 1e-12), (1e20, 1.0), (1.0, 1e20), (2e9, 0.5)] {
        assert!(
            err(&ellipse(m, r), &ImportOptions::default()).starts_with("line 5:"),
            "{m} {r}"
        );
    }
    let circle = entities("0\nCIRCLE\n8\n0\n10\n0\n20\n0\n40\n1e20\n");
    assert!(err(&circle, &ImportOptions::default()).starts_with("line 5:"));
    // A nearly straight bulge: a radius of 2.5e9, its centre far out but
    // the arc within 1e-10 of its chord: it becomes the chord.
    let bulge = |b: f64, x: f64| {
        entities(&format!(
            "0\nLWPOLYLINE\n8\n0\n90\n2\n70\n0\n10\n0\n20\n0\n42\n{b:e}\n10\n{x:e}\n20\n0\n"
        ))
    };
    let imp = run(&bulge(1e-10, 1.0), &ImportOptions::default()).unwrap();
    assert!(matches!(
        imp.sink.segments[..],
        [(crate::model::chain::Segment::Line(_), _)]
    ));
    // A long flat arc whose centre is far out and which bows far from its
    // chord: refused (its centre would be written out).
    let e = err(&bulge(0.01, 9e8), &ImportOptions::default());
    assert!(e.starts_with("line 5:") && e.contains("beyond"), "{e}");
    // Near its limits, but in range: an arc.
    let imp = run(&bulge(0.5, 1e8), &ImportOptions::default()).unwrap();
    assert!(matches!(
        imp.sink.segments[..],
        [(crate::model::chain::Segment::Arc(_), _)]
    ));
    let point = entities("0\nPOINT\n8\n0\n10\n0\n20\n1e10\n");
    assert!(err(&point, &ImportOptions::default()).starts_with("line 5:"));
}

#[test]
fn curve_fitting_is_bounded_at_any_tolerance() {
    // In range, but at a tolerance no fit can meet: bounded work, a warning.
    let mut s = String::from("0\nSPLINE\n8\n0\n70\n8\n71\n3\n");
    for (x, y) in [(0.0, 0.0), (9e5, 1.0), (-9e5, 3e5), (5.0, 9e5), (1.0, -9e5), (7e5, 7e5)] {
        s += &format!("10\n{x:e}\n20\n{y:e}\n30\n0\n");
    }
    let opts = ImportOptions {
        arc_tol: 0.0,
        ..Default::default()
    };
    let t = Instant::now();
    let imp = run(&entities(&s), &opts).unwrap();
    assert!(t.elapsed().as_secs() < 30, "took {:?}", t.elapsed());
    let n = imp.sink.segments.len() as u64;
    assert!(n > 0 && n <= 4 * crate::dxf::curves::MAX_STEPS, "{n}");
    assert!(
        imp.sink.warnings.keys().any(|w| w.contains("fitting steps")),
        "{:?}",
        imp.sink.warnings
    );
}

fn blocks(defs: &[(&str, &str)]) -> String {
    let mut b = String::from("0\nSECTION\n2\nBLOCKS\n");
    for (name, body) in defs {
        b += &format!("0\nBLOCK\n2\n{name}\n10\n0\n20\n0\n{body}0\nENDBLK\n");
    }
    b + "0\nENDSEC\n"
}

fn insert(name: &str, x: f64) -> String {
    format!("0\nINSERT\n2\n{name}\n10\n{x}\n20\n0\n")
}

#[test]
fn a_block_that_inserts_itself_is_drawn_once_with_a_warning() {
    let l = line((0.0, 0.0), (1.0, 0.0));
    // Directly, through two and three blocks, and from an array insert.
    let cases = [
        blocks(&[("A", &(l.clone() + &insert("A", 1.0)))]) + &entities(&insert("A", 0.0)),
        blocks(&[("A", &(l.clone() + &insert("B", 1.0))), ("B", &insert("A", 1.0))]) + &entities(&insert("A", 0.0)),
        blocks(&[
            ("A", &(l.clone() + &insert("B", 1.0))),
            ("B", &insert("C", 1.0)),
            ("C", &(l.clone() + &insert("a", 1.0))),
        ]) + &entities(&insert("A", 0.0)),
    ];
    for (k, t) in cases.iter().enumerate() {
        let imp = run(t, &ImportOptions::default()).unwrap();
        let w: Vec<&String> = imp.sink.warnings.keys().collect();
        assert!(w.len() == 1 && w[0].contains("inserts itself"), "case {k}: {w:?}");
        let expect = if k == 2 { 2 } else { 1 };
        assert_eq!(imp.sink.segments.len(), expect, "case {k}");
    }
    // The same block twice side by side is not recursion.
    let t = blocks(&[("A", &l), ("B", &(insert("A", 0.0) + &insert("A", 5.0)))]) + &entities(&insert("B", 0.0));
    let imp = run(&t, &ImportOptions::default()).unwrap();
    assert!(imp.sink.warnings.is_empty(), "{:?}", imp.sink.warnings);
    assert_eq!(imp.sink.segments.len(), 2);
}

/// Block B0 holds a line; B(i) inserts B(i-1) one unit to the right.
fn chain_of_blocks(n: usize) -> String {
    let mut defs: Vec<(String, String)> = vec![("B0".into(), line((0.0, 0.0), (1.0, 0.0)))];
    for i in 1..n {
        defs.push((format!("B{i}"), insert(&format!("B{}", i - 1), 1.0)));
    }
    let refs: Vec<(&str, &str)> = defs.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
    blocks(&refs) + &entities(&insert(&format!("B{}", n - 1), 0.0))
}

#[test]
fn deep_legitimate_nesting_is_kept() {
    for n in [2, 65, 500, crate::dxf::expand::MAX_NESTING] {
        let imp = run(&chain_of_blocks(n), &ImportOptions::default()).unwrap();
        assert!(imp.sink.warnings.is_empty(), "{n}: {:?}", imp.sink.warnings);
        assert_eq!(imp.sink.segments.len(), 1, "{n}");
        let (s, _) = imp.sink.segments[0];
        assert_eq!(s.start().x, (n - 1) as f64, "{n}");
    }
}

#[test]
fn nesting_past_the_limit_is_refused_with_its_line() {
    let n = crate::dxf::expand::MAX_NESTING + 1;
    let e = err(&chain_of_blocks(n), &ImportOptions::default());
    assert!(
        e.contains("nested more than") && e.contains("as placed by the INSERT at line"),
        "{e}"
    );
}

#[test]
fn insert_bombs_of_empty_or_filtered_blocks_are_bounded() {
    let opts = ImportOptions {
        max_segments: 100_000,
        ..Default::default()
    };
    // Empty block in arrays of arrays: no segment ever, yet a billion copies.
    let empty = blocks(&[("E", ""), ("F", "0\nINSERT\n2\nE\n70\n30000\n71\n30000\n")])
        + &entities("0\nINSERT\n2\nF\n70\n30000\n71\n30000\n");
    let e = err(&empty, &opts);
    assert!(e.contains("expands the drawing past 100000"), "{e}");
    // Geometry on a layer that is filtered out.
    let filtered = blocks(&[
        ("E", &line((0.0, 0.0), (1.0, 0.0))),
        ("F", "0\nINSERT\n2\nE\n70\n30000\n71\n30000\n"),
    ]) + &entities("0\nINSERT\n2\nF\n70\n30000\n71\n30000\n");
    let o = ImportOptions {
        layers: vec!["NONE".into()],
        ..opts.clone()
    };
    assert!(err(&filtered, &o).contains("expands the drawing"));
}
