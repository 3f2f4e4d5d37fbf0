//! Where the shared test corpus lies: real files written by other programs
//! (DXF, G-code, PMAC, STL, OBJ), kept outside this repository under their
//! owners' licences.
//!
//! Tests and benchmarks read corpus files in place. The folder is
//! `$MICROCAM_CORPUS` when set, else `shared/corpus` beside the checkout
//! (where CI puts it). In a clone without it, corpus tests skip with one
//! line saying why and everything else still runs.
//!
//! Each corpus test tallies its cases with [`record`] (or [`skip`]), and
//! `make test` prints the sum (`scripts/corpus-tally`).

use std::path::PathBuf;

/// The corpus folder, if present.
pub fn dir() -> Option<PathBuf> {
    let d = match std::env::var_os("MICROCAM_CORPUS") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus"),
    };
    d.is_dir().then_some(d)
}

/// A file in the corpus (`rel` like `"stl/Cube_ascii.stl"`), if present.
pub fn file(rel: &str) -> Option<PathBuf> {
    let p = dir()?.join(rel);
    p.is_file().then_some(p)
}

/// Every corpus mesh: the STL files, then the OBJ files, each sorted.
pub fn meshes() -> Vec<PathBuf> {
    let mut v = files("stl", &[".stl"]);
    v.extend(files("obj", &[".obj"]));
    v
}

/// Every file under `sub` (e.g. `"dxf"`) whose name ends with one of
/// `exts` (case-insensitive), sorted; empty when the corpus is absent.
pub fn files(sub: &str, exts: &[&str]) -> Vec<PathBuf> {
    let Some(d) = dir() else { return Vec::new() };
    let Ok(rd) = std::fs::read_dir(d.join(sub)) else {
        return Vec::new();
    };
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let n = p
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or("")
                .to_ascii_lowercase();
            p.is_file() && exts.iter().any(|e| n.ends_with(&e.to_ascii_lowercase()))
        })
        .collect();
    v.sort();
    v
}

fn tally_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/corpus-tally")
}

/// Record that test `name` ran `cases` corpus cases.
pub fn record(name: &str, cases: usize) {
    let d = tally_dir();
    let _ = std::fs::create_dir_all(&d);
    let _ = std::fs::write(d.join(format!("{name}.ran")), format!("{cases}\n"));
}

/// Record that test `name` skipped its corpus cases, and say why on stderr.
pub fn skip(name: &str) {
    crate::diag!("{name}: skipped, no corpus (set MICROCAM_CORPUS or put shared/corpus beside the checkout)");
    let d = tally_dir();
    let _ = std::fs::create_dir_all(&d);
    let _ = std::fs::write(d.join(format!("{name}.skipped")), "0\n");
}
