//! Golden-file tests of the binaries: each line of every
//! testdata/golden/*.tsv file (one file per tool) is `name<TAB>shell command`, run from the repository root with the built
//! binaries first on PATH. Its stdout (and, when the command fails or writes
//! to stderr, its stderr and exit status) must equal testdata/golden/<name>.out
//! byte for byte. `UPDATE_GOLDEN=1 cargo test --test golden` rewrites them.
//!
//! Cases in `*.corpus.tsv` files run on real files written by other
//! programs, read in place from the shared corpus (see `microcam::corpus`):
//! they run with the corpus folder as the working directory (so commands
//! name `dxf/Stir_1.dxf`, and messages quote that short name) and `$ROOT`
//! set to the repository root. Without the corpus they are skipped, and
//! the count says so.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin_dir() -> PathBuf {
    // Every binary of the package is built for integration tests; gsim's
    // directory holds them all.
    Path::new(env!("CARGO_BIN_EXE_gsim")).parent().unwrap().to_path_buf()
}

fn render(out: &std::process::Output) -> String {
    let mut s = String::from_utf8_lossy(&out.stdout).into_owned();
    let code = out.status.code().unwrap_or(-1);
    if code != 0 || !out.stderr.is_empty() {
        s.push_str("--- stderr ---\n");
        s.push_str(&String::from_utf8_lossy(&out.stderr));
        s.push_str(&format!("--- exit {code} ---\n"));
    }
    s
}

struct Case {
    name: String,
    cmd: String,
    corpus: bool,
}

fn cases(dir: &Path) -> Vec<Case> {
    let mut tsvs: Vec<_> = std::fs::read_dir(dir)
        .expect("testdata/golden")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "tsv"))
        .collect();
    tsvs.sort();
    let mut out = Vec::new();
    for p in tsvs {
        let corpus = p.to_string_lossy().ends_with(".corpus.tsv");
        let text = std::fs::read_to_string(&p).expect("read .tsv");
        for line in text.lines() {
            let line = line.trim_end();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (name, cmd) = line
                .split_once('\t')
                .unwrap_or_else(|| panic!("{}: no TAB in {line:?}", p.display()));
            out.push(Case {
                name: name.to_string(),
                cmd: cmd.to_string(),
                corpus,
            });
        }
    }
    out
}

#[test]
fn golden_outputs_match() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("testdata/golden");
    let update = std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v != "0");
    let path = format!("{}:{}", bin_dir().display(), std::env::var("PATH").unwrap_or_default());
    let corpus = microcam::corpus::dir();
    let mut failures = Vec::new();
    let (mut count, mut corpus_ran, mut corpus_skipped) = (0, 0, 0);
    let mut names = std::collections::HashSet::new();
    for case in cases(&dir) {
        assert!(
            names.insert(case.name.clone()),
            "golden case {} listed twice",
            case.name
        );
        let cwd = if case.corpus {
            match &corpus {
                Some(c) => {
                    corpus_ran += 1;
                    c.clone()
                }
                None => {
                    corpus_skipped += 1;
                    continue;
                }
            }
        } else {
            root.to_path_buf()
        };
        count += 1;
        let (name, cmd) = (&case.name, &case.cmd);
        let out = Command::new("sh")
            .arg("-c")
            .arg(cmd)
            .current_dir(&cwd)
            .env("PATH", &path)
            .env("ROOT", root)
            .output()
            .expect("run sh");
        let got = render(&out);
        let file = dir.join(format!("{name}.out"));
        if update {
            std::fs::write(&file, &got).unwrap();
            continue;
        }
        match std::fs::read_to_string(&file) {
            Ok(want) if want == got => {}
            Ok(want) => {
                let first = want
                    .lines()
                    .zip(got.lines())
                    .position(|(a, b)| a != b)
                    .unwrap_or(want.lines().count().min(got.lines().count()));
                failures.push(format!(
                    "{name}: output differs from {} at line {}\n  want: {:?}\n  got:  {:?}",
                    file.display(),
                    first + 1,
                    want.lines().nth(first).unwrap_or("<end>"),
                    got.lines().nth(first).unwrap_or("<end>")
                ));
            }
            Err(_) => failures.push(format!("{name}: missing {} (run with UPDATE_GOLDEN=1)", file.display())),
        }
    }
    if corpus_skipped > 0 {
        microcam::corpus::skip("golden");
    } else {
        microcam::corpus::record("golden", corpus_ran);
    }
    assert!(count > 0, "no golden cases");
    assert!(
        failures.is_empty(),
        "{} of {count} golden cases differ:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Every `.out` file belongs to a listed case: a renamed or removed case
/// must not leave its old output behind.
#[test]
fn no_orphan_golden_outputs() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata/golden");
    let names: std::collections::HashSet<String> = cases(&dir).into_iter().map(|c| c.name).collect();
    let mut orphans: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "out"))
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .filter(|n| !names.contains(n))
        .collect();
    orphans.sort();
    assert!(orphans.is_empty(), "golden outputs with no case: {orphans:?}");
}
