//! End-to-end tests of plough2d: the thesis-like pocket at Bayesteh 2013's
//! five feeds, both dialects, the outputs, and bad input.

use std::path::Path;
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_plough2d"))
}

fn pocket(dir: &Path, feed: f64, dialect: &str) -> std::path::PathBuf {
    let out = bin()
        .args(["--write-pocket", &feed.to_string(), "--pocket-dialect", dialect])
        .output()
        .unwrap();
    assert!(out.status.success());
    let p = dir.join(format!("pocket-{feed}.{dialect}"));
    std::fs::write(&p, &out.stdout).unwrap();
    p
}

fn summary(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

const STOCK: &str = "0,0,4,3";

#[test]
fn ploughing_fraction_falls_as_the_feed_rises() {
    let dir = tempfile::tempdir().unwrap();
    let mut last = (f64::INFINITY, f64::INFINITY);
    for feed in [0.5, 0.75, 1.0, 1.25, 2.0] {
        let p = pocket(dir.path(), feed, "pmac");
        let s = summary(
            &bin()
                .args(["--stock", STOCK, "--rpm", "60000"])
                .arg(&p)
                .output()
                .unwrap(),
        );
        let mean = s["mean_plough_fraction"].as_f64().unwrap();
        let total = s["plough_fraction_of_total"].as_f64().unwrap();
        assert!(
            mean < last.0 && total < last.1,
            "{feed} mm/s: {mean} {total} after {last:?}"
        );
        // The same pocket is cut whatever the feed.
        let chip = s["chip_area_um2"].as_f64().unwrap();
        assert!((chip - 5.865e6).abs() < 0.01e6, "{chip}");
        last = (mean, total);
    }
}

#[test]
fn iso_and_pmac_programs_agree() {
    // ISO gives F in mm/min and S in the program; PMAC mm/s and --rpm.
    let dir = tempfile::tempdir().unwrap();
    let iso = pocket(dir.path(), 2.0, "iso");
    let pmac = pocket(dir.path(), 2.0, "pmac");
    let a = summary(&bin().args(["--stock", STOCK]).arg(&iso).output().unwrap());
    let b = summary(
        &bin()
            .args(["--stock", STOCK, "--rpm", "60000"])
            .arg(&pmac)
            .output()
            .unwrap(),
    );
    assert_eq!(a["steps"], b["steps"]);
    let (x, y) = (
        a["plough_area_um2"].as_f64().unwrap(),
        b["plough_area_um2"].as_f64().unwrap(),
    );
    assert!((x - y).abs() < 1e-3 * y, "{x} vs {y}");
}

#[test]
fn outputs_are_written_whole_and_identical_run_to_run() {
    let dir = tempfile::tempdir().unwrap();
    let p = pocket(dir.path(), 2.0, "pmac");
    let run = |tag: &str| {
        let f = |n: &str| dir.path().join(format!("{tag}-{n}"));
        let out = bin()
            .args(["--stock", STOCK, "--rpm", "60000", "--csv"])
            .arg(f("s.csv"))
            .arg("--plot")
            .arg(f("plot.svg"))
            .arg("--svg")
            .arg(f("stock.svg"))
            .arg("--png")
            .arg(f("stock.png"))
            .arg(&p)
            .output()
            .unwrap();
        let s = summary(&out);
        let files: Vec<Vec<u8>> = ["s.csv", "plot.svg", "stock.svg", "stock.png"]
            .iter()
            .map(|n| std::fs::read(f(n)).unwrap())
            .collect();
        (out.stdout, s, files)
    };
    let (a, s, fa) = run("a");
    let (b, _, fb) = run("b");
    assert_eq!(a, b);
    assert_eq!(fa, fb);
    let csv = String::from_utf8(fa[0].clone()).unwrap();
    assert!(csv.starts_with("step,line,path_mm,x_mm,y_mm,chip_area_um2,plough_area_um2,plough_fraction\n"));
    assert_eq!(csv.lines().count() as u64, s["steps"].as_u64().unwrap() + 1);
    assert!(fa[1].starts_with(b"<svg") && fa[2].starts_with(b"<svg"));
    assert!(fa[3].starts_with(b"\x89PNG"));
}

#[test]
fn bad_input_is_exit_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = pocket(dir.path(), 1.0, "pmac");
    let csv = dir.path().join("never.csv");
    for (extra, needle) in [
        (vec![], "no spindle speed"),
        (vec!["--rpm", "60000", "--diameter-mm", "3.5"], "does not fit"),
        (vec!["--rpm", "60000", "--resolution-um", "0.00001"], "MiB"),
    ] {
        let out = bin()
            .args(["--stock", STOCK, "--csv"])
            .arg(&csv)
            .args(&extra)
            .arg(&p)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        assert!(out.stdout.is_empty());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!csv.exists());
    }
}
