//! Hostile input to the G-code and toolpath readers (issue 18): numbers that
//! overflow or that no machine can mean, words that mean nothing on their
//! block, CR/LF/CRLF line ends, unbalanced PMAC buffers, and a step scale
//! that would never finish. Each is an error naming the line (exit 2,
//! nothing on stdout), never `null` in the output with exit 0.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn run(bin: &str, args: &[&str]) -> Output {
    Command::new(bin).args(args).output().unwrap()
}

fn gsim(args: &[&str]) -> Output {
    run(env!("CARGO_BIN_EXE_gsim"), args)
}

/// Exit 2, nothing on stdout, and stderr names `file:line` and `needle`.
fn refused(o: &Output, file: &Path, line: u64, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(o.stdout.is_empty(), "stdout: {}", String::from_utf8_lossy(&o.stdout));
    let at = format!("{}:{line}:", file.file_name().unwrap().to_string_lossy());
    assert!(
        err.contains(&at) && err.contains(needle),
        "want {at} ... {needle}; got {err}"
    );
}

#[test]
fn overflowing_and_absurd_numbers_are_errors_naming_the_line() {
    let d = tempfile::tempdir().unwrap();
    let digits = |n: usize| format!("1{}", "0".repeat(n));
    // Generated variations: magnitudes either side of the 1e9 mm limit and
    // past f64's range, as a literal, a parameter, an expression and an R.
    let cases: Vec<(String, u64, &str)> = vec![
        (
            format!("#1={}\n#2=[#1*#1]\nG1 X#2 F100\nM2\n", digits(300)),
            2,
            "not finite",
        ),
        (
            format!("G1 X1 F100\nG2 X2 R{}\nM2\n", digits(200)),
            2,
            "beyond what a machine can mean",
        ),
        (format!("G1 X{} F100\nM2\n", digits(400)), 1, "too large"),
        (
            "#1=[10**20]\nG1 X#1 F100\nM2\n".into(),
            2,
            "beyond what a machine can mean",
        ),
        ("G1 Y-1000000001 F100\nM2\n".into(), 1, "beyond what a machine can mean"),
        ("G1 X1 F100\nG1 Z[EXP[1000]]\nM2\n".into(), 2, "not finite"),
        ("G1 X1 F100\nG3 X1 Y0 I-1e5\nM2\n".into(), 2, "E word"),
    ];
    for (i, (text, line, needle)) in cases.iter().enumerate() {
        let f = write(d.path(), &format!("h{i}.ngc"), text.as_bytes());
        for args in [vec!["--moves", f.to_str().unwrap()], vec![f.to_str().unwrap()]] {
            refused(&gsim(&args), &f, *line, needle);
        }
    }
    // Within the limit is fine.
    let f = write(d.path(), "ok.ngc", b"G1 X1000000000 F100\nM2\n");
    assert!(gsim(&["--moves", f.to_str().unwrap()]).status.success());
    // --start with NaN is bad usage.
    let o = gsim(&["--start", "nan,0,0", f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stdout.is_empty());
}

#[test]
fn toolpath_records_beyond_the_machine_are_refused() {
    let d = tempfile::tempdir().unwrap();
    for (v, line) in [("1e308", 2), ("-1e308", 2), ("2e9", 2)] {
        let text = format!(
            "{{\"schema\":\"microcam.toolpath/1\",\"units\":\"mm\",\"feed_units\":\"mm/min\"}}\n\
             {{\"type\":\"line\",\"to\":[{v},0,0],\"feed\":100,\"beam\":false}}\n"
        );
        let f = write(d.path(), "t.jsonl", text.as_bytes());
        refused(
            &gsim(&[f.to_str().unwrap()]),
            &f,
            line,
            "beyond what a machine can mean",
        );
        refused(&gsim(&["--moves", f.to_str().unwrap()]), &f, line, "beyond");
    }
    // An arc centre far out as well.
    let text = "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"line\",\"to\":[1,0,0],\"feed\":1}\n\
                {\"type\":\"arc\",\"to\":[2,0,0],\"center\":[1.5,-1e300,0],\"ccw\":true,\"feed\":1}\n";
    let f = write(d.path(), "a.jsonl", text.as_bytes());
    let o = gsim(&[f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stdout.is_empty());
}

#[test]
fn pathgen_audit_refuses_a_pmac_circle_without_a_finite_centre() {
    let d = tempfile::tempdir().unwrap();
    for centre in ["I(0/0) J0", "I(SQRT(-1)) J0", "I0 J(1/0)", "R(0/0)"] {
        let text = format!("OPEN PROG 1 CLEAR\nABS\nLINEAR X1 F2\nCIRCLE1 X1 Y0 {centre}\nCLOSE\n");
        let f = write(d.path(), "n.pmc", text.as_bytes());
        let o = run(env!("CARGO_BIN_EXE_pathgen"), &["audit", f.to_str().unwrap()]);
        refused(&o, &f, 4, "not a finite number");
    }
}

#[test]
fn words_a_block_does_not_use_are_refused_as_rs274_refuses_them() {
    // Each message is rs274's (LinuxCNC 2.9) for the same line.
    let d = tempfile::tempdir().unwrap();
    let cases = [
        ("G1 X1 I5", "I word with no G2, G3"),
        ("G0 X1 K5", "K word with no G2, G3"),
        ("G1 X1 Q5", "Q word with no G5, G10"),
        ("R5", "R word with no g code that uses it"),
        ("P5", "P word with no G2 G3 G4"),
        ("L3", "L word with no G10"),
        ("D5", "D word with no G41"),
        ("H3", "H word with no G43"),
        ("G81 X1 Z-1 R1 P1", "P word with no"),
        ("G92 X0 R2", "R word with no"),
    ];
    for (i, (line, needle)) in cases.iter().enumerate() {
        let f = write(
            d.path(),
            &format!("w{i}.ngc"),
            format!("G21 G90 F100\nG1 X0\n{line}\nM2\n").as_bytes(),
        );
        refused(&gsim(&["--moves", f.to_str().unwrap()]), &f, 3, needle);
    }
    // And where they are used, they are accepted.
    for (i, line) in [
        "G4 P1",
        "G83 X1 Z-1 R1 Q0.5",
        "G82 X1 Z-1 R1 P1",
        "G2 X1 Y1 R1 P2",
        "G64 P0.01 Q0.01",
    ]
    .iter()
    .enumerate()
    {
        let f = write(
            d.path(),
            &format!("u{i}.ngc"),
            format!("G21 G90 F100\nG1 X0 Z2\n{line}\nM2\n").as_bytes(),
        );
        let o = gsim(&["--moves", f.to_str().unwrap()]);
        assert!(o.status.success(), "{line}: {}", String::from_utf8_lossy(&o.stderr));
    }
}

#[test]
fn cr_lf_and_crlf_line_ends_read_alike_in_every_reader() {
    let d = tempfile::tempdir().unwrap();
    let iso = "G21 G90\nG1 X1 F100\nG1 Y1\nG1 Z1\nM2\n";
    let pmac = "OPEN PROG 1 CLEAR\nABS\nLINEAR X1 F2\nX1 Y1\nCLOSE\n";
    let json = "{\"schema\":\"microcam.toolpath/1\"}\n{\"type\":\"line\",\"to\":[1,0,0],\"feed\":1}\n\
                {\"type\":\"line\",\"to\":[1,1,0],\"feed\":1}\n";
    for (name, text) in [("p.ngc", iso), ("p.pmc", pmac), ("p.jsonl", json)] {
        let lf = write(d.path(), name, text.as_bytes());
        let want = gsim(&["--moves", lf.to_str().unwrap()]);
        assert!(want.status.success());
        let mut n = 0;
        for ending in ["\r", "\r\n", "mixed"] {
            let t = if ending == "mixed" {
                // CR, LF and CRLF in turn.
                let mut s = String::new();
                for (k, l) in text.lines().enumerate() {
                    s.push_str(l);
                    s.push_str(["\r", "\n", "\r\n"][k % 3]);
                }
                s
            } else {
                text.replace('\n', ending)
            };
            let f = write(d.path(), name, t.as_bytes());
            let got = gsim(&["--moves", f.to_str().unwrap()]);
            assert!(
                got.status.success(),
                "{name} {ending:?}: {}",
                String::from_utf8_lossy(&got.stderr)
            );
            assert_eq!(got.stdout, want.stdout, "{name} with {ending:?} line ends");
            n += 1;
        }
        assert_eq!(n, 3);
    }
    // An error still names the right line in a CR-only file.
    let f = write(d.path(), "bad.ngc", b"G21\rG1 X1 F100\rG1 X1 I5\rM2\r");
    refused(&gsim(&["--moves", f.to_str().unwrap()]), &f, 3, "I word");
}

#[test]
fn pmac_close_without_open_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let cases: [(&str, u64); 2] = [
        ("LINEAR X1 F2\nCLOSE\n", 2),
        ("OPEN PROG 1 CLEAR\nLINEAR X1 F2\nCLOSE\nCLOSE\n", 4),
    ];
    for (text, line) in cases {
        let f = write(d.path(), "c.pmc", text.as_bytes());
        refused(&gsim(&["--moves", f.to_str().unwrap()]), &f, line, "CLOSE without OPEN");
    }
    // The download preamble (CLOSE before anything) stays accepted.
    let f = write(d.path(), "ok.pmc", b"CLOSE\nOPEN PROG 1 CLEAR\nLINEAR X1 F2\nCLOSE\n");
    assert!(gsim(&["--moves", f.to_str().unwrap()]).status.success());
}

#[test]
fn a_step_scale_that_would_never_finish_is_refused_with_the_estimate() {
    let d = tempfile::tempdir().unwrap();
    let f = write(
        d.path(),
        "s.ngc",
        b"G21 G90\nG0 X0 Y0 Z1\nM3 S10000\nG1 Z-0.1 F100\nG1 X10\nM2\n",
    );
    for scale in ["1e-12", "1e-300", "5e-6"] {
        let o = gsim(&[
            f.to_str().unwrap(),
            "--stock",
            "0,-2,-1,12,2,0",
            "--tool",
            "flat:1",
            "--flutes",
            "2",
            "--step-scale",
            scale,
        ]);
        refused(&o, &f, 4, "steps of");
    }
    let o = gsim(&[
        f.to_str().unwrap(),
        "--stock",
        "0,-2,-1,12,2,0",
        "--tool",
        "flat:1",
        "--flutes",
        "2",
        "--step-scale",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
