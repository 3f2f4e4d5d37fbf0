//! PMAC download files as Delta Tau's downloader takes them, end to end:
//! `gsim --moves` on the real project files of the corpus (read in place)
//! and on small files of our own with `#include`, on-line commands and
//! several programs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn gsim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gsim"))
        .args(args)
        .output()
        .expect("gsim runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The corpus's PMAC file `name`, or `None` (with the skip recorded).
fn corpus_file(name: &str) -> Option<PathBuf> {
    let f = microcam::corpus::file(&format!("pmac/{name}"));
    if f.is_none() {
        microcam::corpus::skip("pmac_download");
    }
    f
}

/// The JSON lines after the header, as text.
fn records(o: &Output) -> Vec<String> {
    text(&o.stdout).lines().skip(1).map(str::to_string).collect()
}

/// The notes gsim printed: (line, text).
fn notes(o: &Output, f: &Path) -> Vec<(u64, String)> {
    let prefix = format!("gsim: {}:", f.display());
    text(&o.stderr)
        .lines()
        .filter_map(|l| {
            let rest = l.strip_prefix(&prefix)?;
            let (line, note) = rest.split_once(": note: ")?;
            Some((line.parse().ok()?, note.to_string()))
        })
        .collect()
}

#[test]
fn every_corpus_project_file_reads_or_is_refused_on_a_named_line() {
    let cases: [(&str, Option<u64>); 5] = [
        ("DiamondLightSource_pmacUtil__PROG11_Move_to_Reference.pmc", None),
        ("DiamondLightSource_pmac__CS_3jack.pmc", None),
        ("DiamondLightSource_pmac__LabPLCs.plc", None),
        ("DiamondLightSource_pmac__PROG10_CS_motion.pmc", None),
        // Its program number and variables are names from a header file
        // it does not #include, and its body is WHILE/IF/GOSUB flow with
        // PVT moves from memory filled at run time: out of scope.
        ("DiamondLightSource_pmac__trajectory_scan_code.pmc", Some(22)),
    ];
    let mut ran = 0;
    for (name, refused_at) in cases {
        let Some(f) = corpus_file(name) else { return };
        let o = gsim(&["--moves", f.to_str().unwrap()]);
        let err = text(&o.stderr);
        match refused_at {
            None => assert!(o.status.success(), "{name}: {err}"),
            Some(line) => {
                assert_eq!(o.status.code(), Some(2), "{name}: {err}");
                assert!(err.contains(&format!("{}:{line}: ", f.display())), "{name}: {err}");
            }
        }
        ran += 1;
    }
    microcam::corpus::record("pmac_download", ran);
}

#[test]
fn corpus_prog11_runs_its_define_and_dwell() {
    let Some(f) = corpus_file("DiamondLightSource_pmacUtil__PROG11_Move_to_Reference.pmc") else {
        return;
    };
    let o = gsim(&["--moves", f.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    // RECOVERYSTA is #defined as Q69.
    assert_eq!(
        records(&o),
        [
            r#"{"type":"var","name":"Q69","value":1,"block":16}"#,
            r#"{"type":"dwell","seconds":10,"block":17}"#,
            r#"{"type":"var","name":"Q69","value":0,"block":18}"#,
        ]
    );
    assert!(notes(&o, &f).is_empty(), "{}", text(&o.stderr));
}

#[test]
fn corpus_prog10_notes_its_i_variable_ranges_and_reads_its_timed_move() {
    let Some(f) = corpus_file("DiamondLightSource_pmac__PROG10_CS_motion.pmc") else {
        return;
    };
    let o = gsim(&["--moves", f.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    // TM(Q70) with Q70..Q79 unset (0): a move to where it is, in no time,
    // then DWELL0.
    assert_eq!(
        records(&o),
        [
            r#"{"type":"dwell","seconds":0,"block":52}"#,
            r#"{"type":"dwell","seconds":0,"block":53}"#,
        ]
    );
    let n = notes(&o, &f);
    assert_eq!(n.iter().map(|n| n.0).collect::<Vec<_>>(), [39, 40, 41], "{n:?}");
    assert!(
        n[0].1.contains("I5213..I6613 (15 variables, step 100) = 10 stored"),
        "{n:?}"
    );
    // From elsewhere, the move is a real one at the speed TM gives.
    let o = gsim(&["--moves", "--start", "3,4,0", f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains(":52: TM0: a 5.000000 mm move in no time"),
        "{}",
        text(&o.stderr)
    );
}

#[test]
fn corpus_plc_and_kinematics_files_are_skipped_with_notes() {
    for (name, skipped, last) in [
        ("DiamondLightSource_pmac__LabPLCs.plc", vec![7, 14, 29], 36),
        ("DiamondLightSource_pmac__CS_3jack.pmc", vec![104, 150, 194], 237),
    ] {
        let Some(f) = corpus_file(name) else { return };
        let o = gsim(&["--moves", f.to_str().unwrap()]);
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        assert!(records(&o).is_empty(), "{name}");
        let n = notes(&o, &f);
        let buffers: Vec<u64> = n
            .iter()
            .filter(|n| n.1.contains("skipped to its CLOSE"))
            .map(|n| n.0)
            .collect();
        assert_eq!(buffers, skipped, "{name}: {n:?}");
        let end = n.last().unwrap();
        assert_eq!(end.0, last, "{name}");
        assert!(end.1.starts_with("no motion program"), "{name}: {n:?}");
    }
    // The 3-jack file's template macros ($(COORD), $(J1X)) are named.
    let Some(f) = corpus_file("DiamondLightSource_pmac__CS_3jack.pmc") else {
        return;
    };
    let o = gsim(&["--moves", f.to_str().unwrap()]);
    let n = notes(&o, &f);
    let q20 = n.iter().find(|n| n.0 == 63).expect("a note on line 63");
    assert!(
        q20.1.contains("'Q20 = $(Q20)': not applied") && q20.1.contains("template macro"),
        "{q20:?}"
    );
}

#[test]
fn the_report_simulates_a_download_file_too() {
    let Some(f) = corpus_file("DiamondLightSource_pmacUtil__PROG11_Move_to_Reference.pmc") else {
        return;
    };
    let o = gsim(&[f.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["dwell_time_s"].as_f64(), Some(10.0), "{report}");
}

#[test]
fn includes_online_commands_and_program_choice_end_to_end() {
    let d = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(d.path().join("inc")).unwrap();
    std::fs::write(
        d.path().join("inc/axes.pmc"),
        "; motor set-up\n#1->1000X\n#define SPEED 2\n#define P_END P20\n",
    )
    .unwrap();
    let f = d.path().join("job.pmc");
    std::fs::write(
        &f,
        "CLOSE\nDELETE GATHER\n#include \"inc/axes.pmc\"\nP_END = 3\nI5113,2,100=10\n\
         OPEN PROG 1 CLEAR\nLINEAR X1 F(SPEED)\nCLOSE\n\
         OPEN PROG 2 CLEAR\nLINEAR X(P_END) F(SPEED)\nCLOSE\n&1B1R\n",
    )
    .unwrap();
    let path = f.to_str().unwrap();
    let o = gsim(&["--moves", path]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = records(&o);
    assert_eq!(r.len(), 1, "{r:?}");
    assert!(r[0].contains(r#""to":[1,0,0],"feed":2"#), "{r:?}");
    let n = notes(&o, &f);
    let lines: Vec<u64> = n.iter().map(|n| n.0).collect();
    // DELETE GATHER and &1B1R are the routine sequence: no notes.
    assert_eq!(lines, [3, 5, 9], "{n:?}");
    assert!(n[0].1.starts_with("in "), "{n:?}");
    assert!(n[0].1.contains("axes.pmc:2: #1->1000X: motor axis definition"), "{n:?}");
    assert!(
        n[2].1.contains("PROG 2 skipped") && n[2].1.contains("--program N"),
        "{n:?}"
    );
    let o = gsim(&["--moves", "--program", "2", path]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(records(&o)[0].contains(r#""to":[3,0,0],"feed":2"#));
    let o = gsim(&["--moves", "--program", "7", path]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains(&format!("{path}:12: --program 7: the file has no OPEN PROG 7")),
        "{}",
        text(&o.stderr)
    );
    // A missing include names the file and line.
    std::fs::write(&f, "CLOSE\n\n#include \"gone.pmc\"\n").unwrap();
    let o = gsim(&["--moves", path]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains(&format!("{path}:3: #include \"gone.pmc\": cannot read")),
        "{}",
        text(&o.stderr)
    );
}
