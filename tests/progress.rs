//! Progress display manners of the long-job tools: nothing on a stderr
//! that is not a terminal unless asked, `--quiet`/`--progress` exclusive,
//! a bar on a terminal for work over a second and none with `--quiet`, and
//! the same output bytes whatever is shown.

use std::process::Command;

mod common;

fn tool(name: &str) -> Command {
    Command::new(common::bin(name))
}

#[test]
fn quiet_and_progress_together_are_bad_usage() {
    let out = tool("gsim").args(["--quiet", "--progress", "-"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--quiet"));
}

#[test]
fn a_pipeline_sees_a_clean_stderr() {
    // Not a terminal, no --progress: the removal run writes its report and
    // nothing at all on stderr.
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("slot.ngc");
    std::fs::write(&prog, "G21 G90 G17\nG0 X0 Y0 Z1\nG1 Z-0.2 F100\nG1 X5\nG1 Y2\nM2\n").unwrap();
    for quiet in [false, true] {
        let mut c = tool("gsim");
        c.args(["--stock", "-1,-1,-1,6,3,0", "--tool", "flat:1", "--cell-mm", "0.05"])
            .arg(&prog);
        if quiet {
            c.arg("--quiet");
        }
        let out = c.output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(
            out.stderr.is_empty(),
            "stderr: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(String::from_utf8_lossy(&out.stdout).contains("removed_volume_mm3"));
    }
}

#[test]
fn every_long_job_tool_has_quiet() {
    for args in [
        &["gsim"][..],
        &["plough2d"],
        &["stlverify"],
        &["feedopt"],
        &["dxf2chains"],
        &["pmac-send"],
        &["pathgen", "slice"],
        &["pathgen", "dropcutter"],
        &["pathgen", "contour"],
        &["pathgen", "fill"],
        &["pathgen", "pocket"],
        &["pathgen", "helix"],
        &["pathgen", "spiral"],
        &["pathgen", "zigzag"],
        &["pathgen", "cone"],
        &["pathgen", "emit"],
        &["pathgen", "audit"],
    ] {
        let out = tool(args[0]).args(&args[1..]).arg("--help").output().unwrap();
        let help = String::from_utf8_lossy(&out.stdout);
        assert!(help.contains("-q, --quiet"), "{args:?} --help has no -q, --quiet");
    }
}

#[test]
fn the_new_meters_leave_a_pipeline_clean_and_the_output_alone() {
    // Not a terminal: each run's stderr is exactly what it is with --quiet
    // (no progress text), and stdout is byte for byte the same.
    let dir = tempfile::tempdir().unwrap();
    let chains = dir.path().join("part.chains");
    let made = tool("dxf2chains")
        .args(["-q", "-o"])
        .arg(&chains)
        .arg("testdata/samples/part.dxf")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let chains = chains.to_str().unwrap().to_string();
    let runs: Vec<Vec<&str>> = vec![
        vec![
            "feedopt",
            "--tool",
            "flat:0.794",
            "--stock",
            "-2,-2,-1,2,2,0",
            "--cell-mm",
            "0.02",
            "testdata/feedopt/pocket.ngc",
        ],
        vec!["dxf2chains", "testdata/samples/part.dxf"],
        vec!["pathgen", "contour", "--side", "outside", &chains],
        vec!["pathgen", "fill", "--beam-diameter", "0.1", &chains],
        vec![
            "pathgen",
            "pocket",
            "--polygon",
            "0,0;4,0;4,3;0,3",
            "--tool",
            "ball:1",
            "--grid",
            "0.5,0.5",
            "--bezier-z",
            "-1,-0.9,-0.9,-1,-0.9,-0.7,-0.7,-0.9,-0.9,-0.7,-0.7,-0.9,-1,-0.9,-0.9,-1",
        ],
        vec!["pathgen", "zigzag", "--length", "2", "--width", "1", "--step", "0.01"],
        vec!["pathgen", "emit", "testdata/gcode/encoder-disc.ngc"],
    ];
    for args in runs {
        let go = |quiet: bool| {
            let mut c = tool(args[0]);
            c.args(&args[1..]).current_dir(env!("CARGO_MANIFEST_DIR"));
            if quiet {
                c.arg("--quiet");
            }
            c.output().unwrap()
        };
        let (plain, quiet) = (go(false), go(true));
        assert_eq!(
            plain.status.code(),
            Some(0),
            "{args:?}: {}",
            String::from_utf8_lossy(&plain.stderr)
        );
        assert!(!plain.stdout.is_empty(), "{args:?}: no output");
        assert!(plain.stdout == quiet.stdout, "{args:?}: --quiet changes the output");
        let err = String::from_utf8_lossy(&plain.stderr);
        // dxf2chains' --quiet also drops its summary; no other tool's
        // stderr changes, and no progress line appears in either.
        if args[0] != "dxf2chains" {
            assert_eq!(plain.stderr, quiet.stderr, "{args:?}");
        }
        for word in [
            "simulating",
            "planning",
            "touching",
            "records",
            "bytes read",
            "moves written",
        ] {
            assert!(!err.contains(word), "{args:?}: progress on a pipeline's stderr: {err}");
        }
    }
}

/// Run `command` with its stderr on a pseudo-terminal (util-linux
/// `script`), returning what the terminal showed; None where `script` is
/// missing.
fn on_a_terminal(command: &str) -> Option<String> {
    let out = Command::new("script")
        .args(["-qec", command, "/dev/null"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(std::process::Stdio::null())
        .output()
        .ok()?;
    assert!(
        out.status.success(),
        "{command}: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

#[test]
fn a_terminal_sees_a_bar_for_slow_work_and_none_with_quiet() {
    // Input that arrives after two seconds makes the work last past the
    // one-second delay on any machine; on a terminal the bar appears (and
    // is cleared), with --quiet nothing does, and the output is the same.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display();
    for (name, cmd, shown) in [
        ("dxf2chains", format!("dxf2chains -o {d}/OUT"), "dxf2chains: bytes read"),
        ("pathgen", format!("pathgen emit -o {d}/OUT"), "pathgen: emit: records"),
    ] {
        let input = if name == "dxf2chains" {
            "testdata/samples/part.dxf"
        } else {
            "testdata/gcode/encoder-disc.ngc"
        };
        let bin = common::bin(name);
        let slow = |quiet: &str, out: &str| {
            let full = cmd.replacen(name, bin.to_str().unwrap(), 1).replace("OUT", out);
            format!("(sleep 2; cat {input}) | {full} {quiet}")
        };
        let Some(seen) = on_a_terminal(&slow("", "a")) else {
            eprintln!("no `script` here: the terminal half of this test is skipped");
            return;
        };
        assert!(seen.contains(shown), "{name}: no bar on the terminal: {seen:?}");
        let quiet = on_a_terminal(&slow("--quiet", "b")).unwrap();
        assert!(!quiet.contains(shown), "{name}: a bar despite --quiet: {quiet:?}");
        let a = std::fs::read(dir.path().join("a")).unwrap();
        let b = std::fs::read(dir.path().join("b")).unwrap();
        assert!(!a.is_empty() && a == b, "{name}: the output depends on the display");
    }
}
