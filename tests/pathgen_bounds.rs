//! pathgen's laser subcommands on hostile parameters (issue: bounded work):
//! what would make more moves than `--max-moves` is refused with exit 2
//! and the estimate, before anything is allocated; NaN, infinities,
//! negatives and zero counts are refused in every numeric flag where they
//! mean nothing. Also the laser flow's block margin with `--decimals 3` and
//! the warning for a drawing larger than the machine.

use std::time::{Duration, Instant};

const PATHGEN: &str = env!("CARGO_BIN_EXE_pathgen");
const GSIM: &str = env!("CARGO_BIN_EXE_gsim");

mod common;

use common::run;

const PLATE: &str = "testdata/chains/plate.chains";

/// Runs `pathgen args`, which must be refused quickly with exit 2, nothing
/// on stdout, and a message containing `want`.
fn refused(args: &[&str], want: &str) {
    let t = Instant::now();
    let o = run(PATHGEN, args, None);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?}: wrote output");
    assert!(err.contains(want), "{args:?}: {err}");
    assert!(
        t.elapsed() < Duration::from_secs(20),
        "{args:?}: took {:?}",
        t.elapsed()
    );
}

#[test]
fn impossible_sizes_are_refused_with_the_estimate() {
    let cases: &[&[&str]] = &[
        &["helix", "--radius", "1", "--pitch", "0.1", "--turns", "1000000000"],
        &["contour", "--levels", "1000000000", PLATE],
        &["contour", "--array", "100000,100000", PLATE],
        &["zigzag", "--length", "1", "--width", "1", "--step", "1e-9"],
        &[
            "cone",
            "--d1",
            "1",
            "--d2",
            "0.4",
            "--height",
            "0.3",
            "--levels",
            "1000000000",
        ],
        &["spiral", "--step", "1e-6", "--radius", "10"],
        &["spiral", "--kind", "square", "--step", "1e-9", "--size", "1"],
        &["cone", "--d1", "1", "--d2", "0.4", "--height", "0.3", "--step", "1e-9"],
    ];
    for args in cases {
        refused(args, "--max-moves");
        let err = String::from_utf8_lossy(&run(PATHGEN, args, None).stderr).into_owned();
        assert!(err.contains("makes about"), "{args:?}: no estimate in {err}");
    }
    // A count clap cannot read is bad usage too.
    refused(
        &["cone", "--d1", "1", "--d2", "0.4", "--height", "0.3", "--levels", "1e9"],
        "levels",
    );
}

#[test]
fn the_limit_is_where_the_estimate_says() {
    // A helix of n turns makes n arcs and four more moves.
    for n in [1u64, 7, 100, 2500] {
        let max = (n + 4).to_string();
        let turns = n.to_string();
        let base = [
            "helix",
            "--radius",
            "1",
            "--pitch",
            "-0.01",
            "--turns",
            &turns,
            "--max-moves",
        ];
        let ok = run(PATHGEN, &[&base[..], &[max.as_str()]].concat(), None);
        assert_eq!(
            ok.status.code(),
            Some(0),
            "{n}: {}",
            String::from_utf8_lossy(&ok.stderr)
        );
        let less = (n + 3).to_string();
        refused(&[&base[..], &[less.as_str()]].concat(), "--max-moves");
    }
    // A spiral whose tolerance asks for more pieces than allowed stops
    // making them at the limit (bounded work however small the tolerance).
    refused(
        &[
            "spiral",
            "--step",
            "0.01",
            "--radius",
            "2",
            "--arc-tol",
            "1e-6",
            "--max-moves",
            "3000",
        ],
        "--max-moves",
    );
    // Contours: chains x levels x copies.
    refused(
        &["contour", "--levels", "3", "--array", "2,2", "--max-moves", "10", PLATE],
        "--max-moves",
    );
    let o = run(PATHGEN, &["contour", "--levels", "3", "--array", "2,2", PLATE], None);
    assert_eq!(o.status.code(), Some(0));
}

#[test]
fn non_finite_negative_and_zero_parameters_are_refused() {
    // (subcommand and the arguments that make it valid, flag, values that
    // must be refused). Every numeric flag of the laser subcommands.
    let helix: &[&str] = &["helix", "--radius", "1", "--pitch", "0.01"];
    let spiral: &[&str] = &["spiral", "--radius", "0.5", "--step", "0.05"];
    let square: &[&str] = &["spiral", "--kind", "square", "--size", "0.5", "--step", "0.05"];
    let zigzag: &[&str] = &["zigzag", "--length", "1", "--width", "0.2", "--step", "0.05"];
    let cone: &[&str] = &[
        "cone", "--d1", "1", "--d2", "0.4", "--height", "0.3", "--levels", "2", "--step", "0.05",
    ];
    let contour: &[&str] = &["contour", PLATE];
    let nonfinite: &[&str] = &["nan", "NaN", "inf", "-inf"];
    let bad_positive: &[&str] = &["nan", "inf", "-inf", "-1", "0"];
    let bad_nonneg: &[&str] = &["nan", "inf", "-inf", "-1"];
    let machine_flags: &[(&str, &[&str])] = &[
        ("--feed", bad_positive),
        ("--ta-ms", bad_positive),
        ("--td-ms", bad_positive),
        ("--ts-ms", bad_nonneg),
        ("--accel-mm-s2", bad_positive),
        ("--open-delay", bad_nonneg),
        ("--open-transfer", bad_nonneg),
        ("--close-delay", bad_nonneg),
        ("--close-transfer", bad_nonneg),
        ("--min-exposure", bad_nonneg),
        ("--tangent-tol", bad_nonneg),
        ("--cut-ta-ms", bad_positive),
        // Ramps of a minute and more (the planner ran for minutes at 1e6).
        ("--cut-ta-ms", &["60001", "1e9"]),
        ("--ta-ms", &["1e9"]),
        ("--td-ms", &["1e9"]),
        ("--ts-ms", &["1e9"]),
    ];
    let mut cases: Vec<(&[&str], &str, &[&str])> = vec![
        (helix, "--radius", bad_positive),
        (helix, "--pitch", nonfinite),
        (helix, "--z", nonfinite),
        (helix, "--turns", &["0", "-1", "nan"]),
        (spiral, "--step", bad_positive),
        (spiral, "--radius", bad_positive),
        (spiral, "--inner", bad_nonneg),
        (spiral, "--arc-tol", bad_positive),
        // Below a nanometre (1e-12 made a cone of 2.4 million moves).
        (spiral, "--arc-tol", &["1e-7", "1e-12"]),
        (spiral, "--z", nonfinite),
        (square, "--size", bad_positive),
        (zigzag, "--length", bad_positive),
        (zigzag, "--width", bad_nonneg),
        (zigzag, "--step", bad_positive),
        (zigzag, "--corner-radius", bad_nonneg),
        (zigzag, "--origin", &["nan,0,0", "0,inf,0"]),
        (cone, "--d1", bad_positive),
        (cone, "--d2", bad_positive),
        (cone, "--height", bad_positive),
        (cone, "--levels", &["0", "-3"]),
        (cone, "--step", bad_positive),
        (cone, "--beam-diameter", bad_nonneg),
        (cone, "--arc-tol", bad_positive),
        (cone, "--arc-tol", &["1e-7", "1e-12"]),
        (cone, "--z", nonfinite),
        (cone, "--center", &["nan,0", "0,-inf"]),
        (contour, "--beam-diameter", bad_nonneg),
        (contour, "--offset", bad_nonneg),
        (contour, "--levels", &["0", "-1"]),
        (contour, "--level-step", nonfinite),
        (contour, "--array", &["0,0", "1,0", "0,1"]),
        (contour, "--pitch", &["nan,0", "0,inf"]),
        (contour, "--start-near", &["nan,0"]),
        (contour, "--cleanup-tol", bad_nonneg),
        (contour, "--max-moves", &["-1", "nan"]),
        (contour, "--decimals", &["10", "-1"]),
    ];
    for base in [helix, contour] {
        for &(flag, values) in machine_flags {
            cases.push((base, flag, values));
        }
    }
    let mut n = 0;
    for (base, flag, values) in cases {
        for v in values {
            let arg = format!("{flag}={v}");
            let args: Vec<&str> = base.iter().copied().chain([arg.as_str()]).collect();
            refused(&args, "");
            n += 1;
        }
    }
    assert!(n > 150, "{n} cases");
    // The valid bases themselves run.
    for base in [helix, spiral, square, zigzag, cone, contour] {
        let o = run(PATHGEN, base, None);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{base:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

/// A closed polygon of `n` vertices on a circle of radius `r`, as chains.
fn polygon_chains(n: usize, r: f64) -> String {
    let p = |k: usize| {
        let a = std::f64::consts::TAU * (k % n) as f64 / n as f64;
        (r * a.cos(), r * a.sin())
    };
    let segs: Vec<String> = (0..n)
        .map(|k| {
            let (a, b) = (p(k), p(k + 1));
            format!(
                "{{\"type\":\"line\",\"start\":[{:.12},{:.12}],\"end\":[{:.12},{:.12}]}}",
                a.0, a.1, b.0, b.1
            )
        })
        .collect();
    format!(
        "{{\"schema\":\"microcam.chains/1\",\"units\":\"mm\"}}\n{{\"id\":1,\"closed\":true,\"segments\":[{}]}}\n",
        segs.join(",")
    )
}

fn limited_blocks(program: &[u8]) -> (u64, u64) {
    let text = String::from_utf8_lossy(program).into_owned();
    let o = run(GSIM, &["--machine", "laser-stage", "-"], Some(&text));
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    (
        r["feed_blocks"].as_u64().unwrap(),
        r["limited_blocks"].as_u64().unwrap(),
    )
}

#[test]
fn short_pieces_are_cleaned_for_the_decimals_written() {
    // 2513 chords of 2.5 µm: longer than the least block with 4 decimals
    // (2.2 µm at 2 mm/s), shorter than with 3 (4 µm), where rounding the
    // ends to 1 µm leaves some blocks under 1 ms at V.
    let chains = polygon_chains(2513, 1.0);
    for decimals in ["4", "3"] {
        for side in ["on", "outside", "inside"] {
            // At 4 decimals the drawing's own pieces are long enough (an
            // outside offset still leaves nanometre mitre legs); at 3 every
            // side has pieces to clean.
            let cleaned = match (decimals, side) {
                ("3", _) => Some(true),
                (_, "on") => Some(false),
                _ => None,
            };
            let o = run(
                PATHGEN,
                &[
                    "contour",
                    "--side",
                    side,
                    "--offset",
                    "0.005",
                    "--gcode",
                    "pmac",
                    "--decimals",
                    decimals,
                    "-",
                ],
                Some(&chains),
            );
            let err = String::from_utf8_lossy(&o.stderr).into_owned();
            assert_eq!(o.status.code(), Some(0), "{err}");
            if let Some(c) = cleaned {
                assert_eq!(err.contains("cleanup:"), c, "{decimals} {side}: {err}");
            }
            assert!(!err.contains("stretches"), "{decimals} {side}: {err}");
            let (feed, limited) = limited_blocks(&o.stdout);
            assert!(feed > 0);
            assert_eq!(limited, 0, "{decimals} {side}: {limited} of {feed} blocks stretched");
            if err.contains("cleanup:") {
                // Reported deviation within the tolerance.
                let dev: f64 = err
                    .split("largest deviation ")
                    .nth(1)
                    .and_then(|t| t.split(' ').next())
                    .and_then(|t| t.parse().ok())
                    .unwrap();
                assert!(dev <= 0.001, "{err}");
            }
        }
    }
    // With the cleanup off the same drawing at 3 decimals is stretched
    // once written, and pathgen says what it could not remove.
    let o = run(
        PATHGEN,
        &[
            "contour",
            "--gcode",
            "pmac",
            "--decimals",
            "3",
            "--cleanup-tol",
            "0",
            "-",
        ],
        Some(&chains),
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(err.contains("2513 piece(s) shorter than the least block"), "{err}");
    assert!(limited_blocks(&o.stdout).1 > 10);
}

#[test]
fn a_drawing_larger_than_any_stage_is_warned_about() {
    let big = polygon_chains(6, 60_000.0);
    let o = run(PATHGEN, &["contour", "-"], Some(&big));
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.contains("120000.000 x 103923.048 mm"), "{err}");
    assert!(err.contains("--units") && err.contains("in mm"), "{err}");
    let small = polygon_chains(6, 6.0);
    let o = run(PATHGEN, &["contour", "-"], Some(&small));
    assert!(!String::from_utf8_lossy(&o.stderr).contains("--units"));
}
