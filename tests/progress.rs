//! Progress display manners of the long-job tools: nothing on a stderr
//! that is not a terminal unless asked, and `--quiet`/`--progress` exclusive.

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
        &["pathgen", "slice"],
        &["pathgen", "dropcutter"],
        &["stlverify"],
    ] {
        let out = tool(args[0]).args(&args[1..]).arg("--help").output().unwrap();
        let help = String::from_utf8_lossy(&out.stdout);
        assert!(help.contains("-q, --quiet"), "{args:?} --help has no -q, --quiet");
    }
}
