//! The gsim report as one JSON object (`microcam.gsim/1`): the figures the
//! simulation ([`super::report::Simulator`]) collected, written at the edge.

use super::beam::{BeamModel, ChainExposure, match_chains};
use super::picture::Overlay;
use super::report::{RemovalStats, TimeStats};
use super::stock::Stock;
use super::summary::PathSummary;
use super::time::Limit;
use crate::formats::{push_num, push_str_lit, push_uint};
use crate::machine::Machine;
use crate::model::chain::Chain;

/// The report's schema name.
pub const SCHEMA: &str = "microcam.gsim/1";

/// Everything gsim reports.
pub struct GsimReport {
    /// The machine profile simulated.
    pub machine: Machine,
    /// Counts, lengths and extents of the path.
    pub summary: PathSummary,
    /// Cycle time and what limited the feeds.
    pub time: TimeStats,
    /// The beam model with its cuts, settled.
    pub beam: BeamModel,
    /// With a drawing (`--chains`): the drawing chain index per cut and the
    /// exposure per drawing chain.
    pub drawing: Option<(Vec<Option<usize>>, Vec<ChainExposure>)>,
    /// With a stock (`--stock`): removal figures and the final stock.
    pub removal: Option<(RemovalStats, Stock)>,
    /// The path overlay for a picture, when asked for.
    pub picture: Option<Overlay>,
}

fn field(b: &mut String, k: &str, v: f64) {
    b.push_str(",\"");
    b.push_str(k);
    b.push_str("\":");
    push_num(b, v);
}

impl GsimReport {
    /// Compare the cuts with the drawing's chains (`tol` mm in XY).
    pub fn with_drawing(mut self, chains: &[Chain], tol: f64) -> GsimReport {
        self.drawing = Some(match_chains(&self.beam.cuts, chains, tol));
        self
    }

    /// The report as one JSON object (`microcam.gsim/1`).
    pub fn to_json(&self, source: Option<&str>) -> String {
        let mut b = format!("{{\"schema\":\"{SCHEMA}\"");
        if let Some(s) = source {
            b.push_str(",\"source\":");
            push_str_lit(&mut b, s);
        }
        b.push_str(",\"machine\":");
        push_str_lit(&mut b, &self.machine.name);
        b.push_str(",\"controller\":\"");
        b.push_str(self.machine.controller.name());
        b.push('"');
        self.summary.push_fields(&mut b);
        let t = &self.time;
        field(&mut b, "cycle_time_s", t.cycle_time_s);
        field(&mut b, "cutting_time_s", t.cutting_time_s);
        field(&mut b, "rapid_time_s", t.rapid_time_s);
        field(&mut b, "dwell_time_s", t.dwell_time_s);
        field(&mut b, "ideal_cutting_time_s", t.ideal_cutting_time_s);
        if let Some(f) = t.min_achieved_feed_mm_s {
            field(&mut b, "min_achieved_feed_mm_s", f);
        }
        field(&mut b, "feed_blocks", t.feed_blocks as f64);
        field(&mut b, "limited_blocks", t.limited_blocks as f64);
        b.push_str(",\"limited_by\":{");
        let mut first = true;
        for (i, l) in Limit::ALL.iter().enumerate() {
            if t.limited_by[i] > 0 {
                if !first {
                    b.push(',');
                }
                first = false;
                b.push('"');
                b.push_str(l.name());
                b.push_str("\":");
                push_uint(&mut b, t.limited_by[i]);
            }
        }
        b.push_str("},\"limited_examples\":[");
        for (i, e) in t.examples.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            b.push('{');
            if let Some(l) = e.line {
                b.push_str("\"line\":");
                push_uint(&mut b, l);
                b.push(',');
            }
            b.push_str("\"length_mm\":");
            push_num(&mut b, e.length_mm);
            field(&mut b, "commanded_feed_mm_s", e.commanded_feed_mm_s);
            field(&mut b, "achieved_feed_mm_s", e.achieved_feed_mm_s);
            b.push_str(",\"limited_by\":\"");
            b.push_str(e.limited_by.name());
            b.push_str("\"}");
        }
        b.push(']');
        self.push_beam(&mut b);
        if let Some((r, stock)) = &self.removal {
            b.push_str(",\"removal\":{\"cells\":[");
            push_uint(&mut b, stock.nx as u64);
            b.push(',');
            push_uint(&mut b, stock.ny as u64);
            b.push(']');
            field(&mut b, "cell_mm", stock.cell);
            b.push_str(",\"cells_visited\":");
            push_uint(&mut b, stock.cells_visited);
            field(&mut b, "initial_volume_mm3", r.initial_volume_mm3);
            field(&mut b, "removed_volume_mm3", r.removed_volume_mm3);
            field(&mut b, "final_volume_mm3", stock.volume());
            field(&mut b, "max_block_volume_mm3", r.max_block_volume_mm3);
            if let Some(l) = r.max_block_line {
                b.push_str(",\"max_block_line\":");
                push_uint(&mut b, l);
            }
            field(&mut b, "rapids_in_material", r.rapids_in_material as f64);
            b.push_str(",\"rapid_in_material_lines\":[");
            for (i, l) in r.rapid_lines.iter().enumerate() {
                if i > 0 {
                    b.push(',');
                }
                push_uint(&mut b, *l);
            }
            b.push_str("]}");
        }
        b.push('}');
        b
    }

    fn push_beam(&self, b: &mut String) {
        let m = &self.beam;
        b.push_str(",\"beam\":{\"command_timing\":\"");
        b.push_str(m.timing.name());
        b.push('"');
        field(
            b,
            "open_latency_ms",
            self.machine.shutter_or_instant().open_latency_s() * 1e3,
        );
        field(
            b,
            "close_latency_ms",
            self.machine.shutter_or_instant().close_latency_s() * 1e3,
        );
        field(b, "shutter_opens", m.opens as f64);
        field(b, "shutter_open_time_s", m.light_time_s);
        field(b, "intended_length_mm", m.intended_mm());
        field(b, "exposed_length_mm", m.exposed_mm());
        field(b, "unexposed_length_mm", m.unexposed_mm());
        field(b, "overexposed_length_mm", m.overexposed_mm());
        field(b, "stationary_exposure_s", m.stationary_exposure_s());
        field(b, "short_exposures", m.short_exposures as f64);
        field(b, "missed_exposures", m.missed_exposures as f64);
        b.push_str(",\"short_exposure_lines\":[");
        for (i, l) in m.short_exposure_lines.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            push_uint(b, *l);
        }
        b.push_str("],\"cuts\":[");
        for (i, c) in m.cuts.iter().enumerate() {
            if i > 0 {
                b.push(',');
            }
            b.push_str("{\"cut\":");
            push_uint(b, i as u64 + 1);
            if let Some(ch) = c.chain {
                b.push_str(",\"chain\":");
                push_uint(b, ch);
            }
            if let Some(l) = c.first_line {
                b.push_str(",\"first_line\":");
                push_uint(b, l);
            }
            if let Some(l) = c.last_line {
                b.push_str(",\"last_line\":");
                push_uint(b, l);
            }
            if let Some((which, per)) = &self.drawing
                && let Some(Some(k)) = which.get(i)
            {
                b.push_str(",\"drawing_chain\":");
                push_uint(b, per[*k].id);
            }
            field(b, "length_mm", c.length_mm);
            field(b, "exposed_mm", c.exposed_mm);
            field(b, "unexposed_mm", c.unexposed_mm());
            field(b, "overexposed_mm", c.overexposed_mm);
            field(b, "stationary_exposure_s", c.stationary_exposure_s);
            b.push('}');
        }
        b.push(']');
        if let Some((_, per)) = &self.drawing {
            field(b, "drawing_length_mm", per.iter().map(|c| c.drawing_length_mm).sum());
            field(
                b,
                "drawing_unexposed_length_mm",
                per.iter().map(|c| c.unexposed_mm()).sum(),
            );
            b.push_str(",\"chains\":[");
            for (i, c) in per.iter().enumerate() {
                if i > 0 {
                    b.push(',');
                }
                b.push_str("{\"chain\":");
                push_uint(b, c.id);
                field(b, "drawing_length_mm", c.drawing_length_mm);
                field(b, "cuts", c.cuts as f64);
                field(b, "cut_length_mm", c.cut_length_mm);
                field(b, "exposed_mm", c.exposed_mm);
                field(b, "unexposed_mm", c.unexposed_mm());
                field(b, "overexposed_mm", c.overexposed_mm);
                b.push('}');
            }
            b.push(']');
        }
        b.push('}');
    }
}
