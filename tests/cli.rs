//! End-to-end checks of the manners every binary shares: help with
//! examples, exit codes, errors that name the file and line, nothing on
//! stdout (or in an -o file) when a run fails, identical output for
//! identical input.

use std::path::Path;
use std::process::{Command, Output, Stdio};

fn run(bin: &str, args: &[&str], stdin: Option<&str>) -> Output {
    use std::io::Write;
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    if let Some(text) = stdin {
        child.stdin.take().unwrap().write_all(text.as_bytes()).unwrap();
    }
    drop(child.stdin.take());
    child.wait_with_output().expect("wait")
}

const GSIM: &str = env!("CARGO_BIN_EXE_gsim");
const PATHGEN: &str = env!("CARGO_BIN_EXE_pathgen");

#[test]
fn help_teaches_with_examples() {
    for (bin, args) in [(GSIM, vec!["-h"]), (PATHGEN, vec!["-h"]), (PATHGEN, vec!["emit", "-h"])] {
        let o = run(bin, &args, None);
        assert_eq!(o.status.code(), Some(0));
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("Examples:"), "{bin} {args:?}: {text}");
    }
}

#[test]
fn bad_usage_and_bad_input_exit_2_and_name_the_problem() {
    let o = run(GSIM, &["--dialect", "fanuc", "x.ngc"], None);
    assert_eq!(o.status.code(), Some(2));
    let o = run(GSIM, &["no/such/file.ngc"], None);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no/such/file.ngc"));
    assert!(o.stdout.is_empty());
    let o = run(GSIM, &["--moves", "-"], Some("G0 X1\nG0 X2\nG2 X3 F1\n"));
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.starts_with("gsim: <stdin>:3: "), "{err}");
    assert!(
        o.stdout.is_empty(),
        "half-written output: {}",
        String::from_utf8_lossy(&o.stdout)
    );
}

#[test]
fn a_failed_run_leaves_no_output_file_and_keeps_an_old_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("moves.jsonl");
    let out_s = out.to_str().unwrap();
    // Long enough that the bad line comes after plenty of output.
    let mut prog: String = (0..20_000).map(|i| format!("G0 X{i}\n")).collect();
    prog.push_str("G1 X0\n");
    let o = run(GSIM, &["--moves", "-o", out_s, "-"], Some(&prog));
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.exists(), "a failed run must not leave a file");
    std::fs::write(&out, "old\n").unwrap();
    let o = run(GSIM, &["--moves", "-o", out_s, "-"], Some(&prog));
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old\n");
    let o = run(GSIM, &["--moves", "-o", out_s, "-"], Some("G0 X1\n"));
    assert_eq!(o.status.code(), Some(0));
    assert!(std::fs::read_to_string(&out).unwrap().contains("\"to\":[1,0,0]"));
    // Large outputs to stdout spill to disk and still arrive whole.
    let big: String = (0..300_000).map(|i| format!("G0 X{i}\n")).collect();
    let o = run(GSIM, &["--moves", "-"], Some(&big));
    assert_eq!(o.status.code(), Some(0));
    assert_eq!(o.stdout.iter().filter(|&&b| b == b'\n').count(), 300_001);
}

#[test]
fn devices_and_symlinks_are_written_in_place() {
    let dir = tempfile::tempdir().unwrap();
    // -o /dev/stdout with stdout redirected to a regular file: the system's
    // /dev/stdout link must survive and the data reach the file.
    let target = dir.path().join("out.jsonl");
    let f = std::fs::File::create(&target).unwrap();
    let status = Command::new(GSIM)
        .args(["--moves", "-o", "/dev/stdout", "testdata/gcode/badge.ngc"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(f)
        .status()
        .unwrap();
    assert!(status.success());
    assert!(
        std::fs::symlink_metadata("/dev/stdout")
            .unwrap()
            .file_type()
            .is_symlink()
            || !Path::new("/dev/stdout").is_file()
    );
    assert!(
        std::fs::read_to_string(&target)
            .unwrap()
            .contains("microcam.toolpath/1")
    );
    // A symlink to a file: the file is replaced, the link kept.
    #[cfg(unix)]
    {
        let real = dir.path().join("real.jsonl");
        let link = dir.path().join("link.jsonl");
        std::fs::write(&real, "old\n").unwrap();
        std::os::unix::fs::symlink(&real, &link).unwrap();
        let o = run(
            GSIM,
            &["--moves", "-o", link.to_str().unwrap(), "testdata/gcode/badge.ngc"],
            None,
        );
        assert_eq!(o.status.code(), Some(0));
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert!(std::fs::read_to_string(&real).unwrap().contains("microcam.toolpath/1"));
    }
}

#[test]
fn identical_input_gives_identical_output() {
    let prog = Path::new("testdata/gcode/encoder-disc.ngc").to_str().unwrap();
    let a = run(GSIM, &["--moves", prog], None);
    let b = run(GSIM, &["--moves", prog], None);
    assert_eq!(a.status.code(), Some(0));
    assert_eq!(a.stdout, b.stdout);
    let pa = run(PATHGEN, &["emit", "--dialect", "pmac", prog], None);
    let pb = run(PATHGEN, &["emit", "--dialect", "pmac", prog], None);
    assert_eq!(pa.status.code(), Some(0));
    assert_eq!(pa.stdout, pb.stdout);
}

#[test]
fn iso_to_pmac_and_back_keeps_the_path() {
    let prog = "testdata/gcode/badge.ngc";
    let direct = run(GSIM, &[prog], None);
    let pmac = run(PATHGEN, &["emit", "--dialect", "pmac", "--decimals", "6", prog], None);
    assert_eq!(pmac.status.code(), Some(0), "{}", String::from_utf8_lossy(&pmac.stderr));
    let text = String::from_utf8(pmac.stdout).unwrap();
    let back = run(GSIM, &["-"], Some(&text));
    assert_eq!(back.status.code(), Some(0), "{}", String::from_utf8_lossy(&back.stderr));
    let field = |o: &[u8], k: &str| -> f64 {
        let v: serde_json::Value = serde_json::from_slice(o).unwrap();
        v[k].as_f64().unwrap()
    };
    for k in ["feed_length_mm", "rapid_length_mm", "arcs", "lines"] {
        let (a, b) = (field(&direct.stdout, k), field(&back.stdout, k));
        assert!((a - b).abs() <= 1e-4 * a.abs().max(1.0), "{k}: {a} vs {b}");
    }
}
