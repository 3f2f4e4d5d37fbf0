//! Golden-file tests of the binaries: each line of every
//! testdata/golden/*.tsv file (one file per tool) is `name<TAB>shell command`, run from the repository root with the built
//! binaries first on PATH. Its stdout (and, when the command fails or writes
//! to stderr, its stderr and exit status) must equal testdata/golden/<name>.out
//! byte for byte. `UPDATE_GOLDEN=1 cargo test --test golden` rewrites them.

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

#[test]
fn golden_outputs_match() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("testdata/golden");
    let mut tsvs: Vec<_> = std::fs::read_dir(&dir)
        .expect("testdata/golden")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "tsv"))
        .collect();
    tsvs.sort();
    let cases: String = tsvs.iter().map(|p| std::fs::read_to_string(p).expect("read .tsv")).collect();
    let update = std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v != "0");
    let path = format!("{}:{}", bin_dir().display(), std::env::var("PATH").unwrap_or_default());
    let mut failures = Vec::new();
    let mut count = 0;
    for line in cases.lines() {
        let line = line.trim_end();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (name, cmd) = line
            .split_once('\t')
            .unwrap_or_else(|| panic!("golden .tsv: no TAB in {line:?}"));
        count += 1;
        let out = Command::new("sh")
            .arg("-c")
            .arg(cmd)
            .current_dir(root)
            .env("PATH", &path)
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
    assert!(count > 0, "no golden cases");
    assert!(
        failures.is_empty(),
        "{} of {count} golden cases differ:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
