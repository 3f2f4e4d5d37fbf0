//! The stderr summary of an import: what was read, skipped, fitted and
//! repaired. Deterministic text (sorted counts), one topic per line.

use super::chain::ChainReport;
use super::{Import, UnitSource};

fn counts<'a>(it: impl Iterator<Item = (&'a str, u64)>) -> String {
    it.map(|(k, v)| format!("{k} {v}")).collect::<Vec<_>>().join(", ")
}

fn num(x: f64) -> String {
    let s = format!("{x:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Lines for stderr, without the tool prefix.
/// `requested` are the `--layer` names: one that brought no geometry is
/// most often a typo, so it is named.
pub fn lines(imp: &Import, rep: &ChainReport, arc_tol: f64, point_chains: usize, requested: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let kind = if imp.binary { "binary" } else { "ASCII" };
    let ver = imp.version.as_deref().unwrap_or("no version");
    let units = match imp.unit_source {
        UnitSource::Header(c) => format!("$INSUNITS {c}: {} mm per unit", num(imp.unit_mm)),
        UnitSource::Option => format!("--units: {} mm per unit", num(imp.unit_mm)),
        UnitSource::Assumed => "no $INSUNITS: millimetres assumed".to_string(),
    };
    out.push(format!("{kind} DXF, {ver}, {units}"));
    if imp.unit_source == UnitSource::Assumed {
        out.push("warning: the file does not say its units; millimetres assumed (use --units to set them)".into());
    }
    let s = &imp.sink;
    if s.used.is_empty() {
        out.push("read no geometry".into());
    } else {
        out.push(format!("read {}", counts(s.used.iter())));
    }
    if !imp.skipped.is_empty() {
        out.push(format!(
            "skipped (not cuttable geometry) {}",
            counts(imp.skipped.iter().map(|(k, v)| (k.as_str(), *v)))
        ));
    }
    for l in requested {
        if !s.layers.contains(l) {
            out.push(format!("warning: --layer '{l}': no geometry on a layer of that name"));
        }
    }
    for (w, n) in &s.warnings {
        out.push(if *n > 1 {
            format!("warning: {w} ({n} times)")
        } else {
            format!("warning: {w}")
        });
    }
    if s.curves > 0 {
        out.push(format!(
            "{} splines/ellipses -> {} arcs and lines within {} mm; a polyline needs {}: {} blocks saved",
            s.curves,
            s.curve_pieces,
            num(arc_tol),
            s.curve_chords,
            s.curve_chords as i64 - s.curve_pieces as i64
        ));
    }
    out.push(format!(
        "{} chains: {} closed, {} open{}",
        rep.closed + rep.open,
        rep.closed,
        rep.open,
        if point_chains > 0 {
            format!(", {point_chains} with points only")
        } else {
            String::new()
        }
    ));
    let mut r = Vec::new();
    if rep.gaps_closed > 0 {
        r.push(format!(
            "{} gaps closed (largest {} mm)",
            rep.gaps_closed,
            num(rep.max_gap)
        ));
    }
    if rep.duplicates > 0 {
        r.push(format!("{} duplicates removed", rep.duplicates));
    }
    if rep.overlaps > 0 {
        r.push(format!("{} collinear overlaps merged", rep.overlaps));
    }
    if rep.zero_length > 0 {
        r.push(format!("{} zero-length pieces dropped", rep.zero_length));
    }
    if rep.non_finite > 0 {
        r.push(format!("{} pieces with non-finite coordinates dropped", rep.non_finite));
    }
    if !r.is_empty() {
        out.push(format!("repairs: {}", r.join(", ")));
    }
    if rep.reversed > 0 {
        out.push(format!(
            "{} closed chains reversed (outer contours counter-clockwise, holes clockwise)",
            rep.reversed
        ));
    }
    out
}
