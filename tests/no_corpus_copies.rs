//! Files written by other programs stay in the shared corpus, under their
//! owners' licences: no file in this repository may have the same content
//! as a corpus file. Checked by content (length, then bytes), so a renamed
//! copy is caught too.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

fn walk(dir: &Path, skip: &[&str], out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if skip.contains(&name.as_str()) {
            continue;
        }
        match e.file_type() {
            Ok(t) if t.is_dir() => walk(&p, skip, out),
            Ok(t) if t.is_file() => out.push(p),
            _ => {}
        }
    }
}

#[test]
fn no_file_of_the_repository_is_a_corpus_file() {
    let Some(corpus) = microcam::corpus::dir() else {
        microcam::corpus::skip("no_corpus_copies");
        return;
    };
    let mut corpus_files = Vec::new();
    walk(&corpus, &[], &mut corpus_files);
    // Corpus READMEs describe the corpus; they are not test data.
    corpus_files.retain(|p| p.file_name().is_none_or(|n| n != "README.md"));
    let mut by_len: HashMap<u64, Vec<PathBuf>> = HashMap::new();
    for p in &corpus_files {
        let len = std::fs::metadata(p).unwrap().len();
        by_len.entry(len).or_default().push(p.clone());
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut ours = Vec::new();
    walk(root, &["target", ".git", ".venv", "out", "fuzz"], &mut ours);
    walk(&root.join("fuzz"), &["target", "corpus", "artifacts"], &mut ours);
    let mut copies = Vec::new();
    for p in &ours {
        let len = std::fs::metadata(p).unwrap().len();
        let Some(same_len) = by_len.get(&len) else { continue };
        let bytes = std::fs::read(p).unwrap();
        for c in same_len {
            if std::fs::read(c).unwrap() == bytes {
                copies.push(format!("{} = {}", p.display(), c.display()));
            }
        }
    }
    assert!(corpus_files.len() > 50, "corpus looks empty: {}", corpus.display());
    assert!(
        copies.is_empty(),
        "corpus files copied into the repository:\n{}",
        copies.join("\n")
    );
    microcam::corpus::record("no_corpus_copies", corpus_files.len());
}
