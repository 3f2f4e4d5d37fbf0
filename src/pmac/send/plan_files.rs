//! A dry run: the chunks a job would be sent in, as the files pmac-send
//! writes instead of sending them.

use super::{Mode, open_program};
use crate::pmac::upload_plan::{MARKER_WORDS, marker_lines};

/// The word budget of a dry run, where no controller reports its free
/// memory: `--buffer-words` less the marker in split mode, the chunk size
/// in rotary mode, none for one program. `None` inside `Err` names the
/// missing flag.
pub fn dry_run_budget(
    mode: Mode,
    buffer_words: Option<usize>,
    chunk_words: usize,
) -> Result<Option<usize>, &'static str> {
    match mode {
        Mode::Program => Ok(None),
        Mode::Split => buffer_words
            .map(|b| Some(b.saturating_sub(MARKER_WORDS)))
            .ok_or("--dry-run in split mode needs --buffer-words"),
        Mode::Rotary => Ok(Some(chunk_words)),
    }
}

/// One dry-run file: its name and text.
pub struct PlanFile {
    /// `chunk-NNN.pmac`, numbered from 1.
    pub name: String,
    /// The download as it would be sent (buffer chunks wrapped in
    /// `OPEN PROG` ... `CLOSE` with their completion marker).
    pub text: String,
}

/// A dry run: the chunks a job would be sent in, as download files, and the
/// `microcam.pmac-plan/1` description of them (`plan.json`).
pub fn dry_run(
    job: &crate::pmac::upload_plan::UploadPlan,
    mode: Mode,
    budget: Option<usize>,
    prog: u32,
    done_var: &str,
) -> Result<(Vec<PlanFile>, serde_json::Value), crate::pmac::upload_plan::PlanError> {
    let chunks = match (mode, budget) {
        (Mode::Rotary, Some(b)) => job.stream_chunks(b),
        _ => job.chunks(budget),
    }?;
    let mut files = Vec::with_capacity(chunks.len());
    let mut plan = Vec::with_capacity(chunks.len());
    for (i, c) in chunks.iter().enumerate() {
        let name = plan_file_name(i + 1);
        let mut text = String::new();
        let mut push = |l: &str| {
            text.push_str(l);
            text.push('\n');
        };
        if mode != Mode::Rotary {
            open_program(prog).iter().for_each(|l| push(l));
        }
        c.lines.iter().for_each(|l| push(l));
        if mode != Mode::Rotary {
            marker_lines(done_var, i + 1).iter().for_each(|l| push(l));
            push("CLOSE");
        }
        plan.push(serde_json::json!({
            "file": name, "lines": c.lines.len(), "words": c.words,
            "first_counter": c.first_counter, "last_counter": c.last_counter,
            "start": c.start, "end": c.end, "seconds": c.seconds,
        }));
        files.push(PlanFile { name, text });
    }
    let summary = serde_json::json!({
        "schema": "microcam.pmac-plan/1",
        "mode": mode.name(),
        "prog": prog,
        "budget_words": budget,
        "chunks": plan,
        "lines": chunks.iter().map(|c| c.lines.len()).sum::<usize>(),
        "estimated_seconds": chunks.iter().map(|c| c.seconds).sum::<f64>(),
    });
    Ok((files, summary))
}

/// The name of dry-run file `number` (1-based).
pub fn plan_file_name(number: usize) -> String {
    format!("chunk-{number:03}.pmac")
}

/// Whether a file named `name` is a chunk file that a plan of `chunks`
/// files did not write (left by an earlier, longer plan).
pub fn is_stale_plan_file(name: &str, chunks: usize) -> bool {
    name.strip_prefix("chunk-")
        .and_then(|r| r.strip_suffix(".pmac"))
        .and_then(|d| d.parse::<usize>().ok())
        .is_some_and(|k| k == 0 || k > chunks || name != plan_file_name(k))
}
