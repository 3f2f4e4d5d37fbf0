//! The pocket report (`microcam.pocket-report/1`): path length, predicted
//! cycle time under gsim's controller model, the scallop and surface error
//! estimates of the Iowa State grid-pocket thesis (1999) (Fig. 35: CL/CC
//! surface error R(1 - cos θ) and scallop height between neighbouring
//! grid points; Fig. 20: surface-point error of a Bezier through grid
//! points), cells, layers and block counts of each final-layer motion.

use super::layers::Program;
use crate::formats::push_num;
use crate::geometry::P3;
use crate::machine::Machine;
use crate::model::toolpath::{FeedUnit, Header, MotionKind, Record};
use crate::sim::beam::CommandTiming;
use crate::sim::report::{SimError, Simulator};

/// Thesis Fig. 35 between two neighbours `g` apart whose heights differ
/// by `dz`, for a cutter of radius `r`: (surface error, scallop height).
pub fn fig35(r: f64, g: f64, dz: f64) -> (f64, f64) {
    let dz = dz.abs();
    let theta = (dz / g).atan();
    let surface = r * (1.0 - theta.cos());
    let h = g.hypot(r - dz);
    (surface, r * theta.cos() * (h - r) / h)
}

/// Thesis Fig. 20: surface-point error of a unit Bezier step of length
/// `unit` rising `dz`.
pub fn fig20(unit: f64, dz: f64) -> f64 {
    let h = unit.hypot(dz);
    if h == 0.0 { 0.0 } else { dz.abs() * (h - unit) / h }
}

/// Cycle time (s) of the records under `machine`'s controller model,
/// starting where the first move goes.
pub fn cycle_time_s(records: &[Record], machine: &Machine) -> Result<f64, SimError> {
    let start = records
        .iter()
        .find_map(|r| r.motion().map(|m| m.to))
        .unwrap_or(P3::origin());
    let header = Header {
        feed_unit: FeedUnit::MmPerS,
        source: None,
    };
    let mut sim: Simulator<std::io::Sink> = Simulator::new(&header, machine.clone(), CommandTiming::Sync, start, None);
    for r in records {
        sim.add(r)?;
    }
    let (rep, _) = sim.finish()?;
    Ok(rep.time.cycle_time_s)
}

/// Feed and rapid path lengths (mm).
pub fn lengths(records: &[Record]) -> (f64, f64) {
    let (mut feed, mut rapid) = (0.0, 0.0);
    let mut pos: Option<P3> = None;
    for r in records {
        let Some(m) = r.motion() else { continue };
        if let Some(p) = pos {
            let l = m.segment(p).length();
            if m.kind == MotionKind::Rapid {
                rapid += l;
            } else {
                feed += l;
            }
        }
        pos = Some(m.to);
    }
    (feed, rapid)
}

/// Figures of one job, for the JSON report.
#[derive(Debug, Clone, Default)]
pub struct Figures {
    /// "grid" or "offset".
    pub strategy: String,
    /// The cutter as `shape:diameter` (e.g. `ball:1`, `torus:2:0.5`).
    pub cutter: String,
    /// Grid cells whose centres lie in the tool-centre region.
    pub cells: usize,
    /// Layers, the final (finishing) one included.
    pub layers: usize,
    /// Floors of the roughing layers, highest first, mm.
    pub floors_mm: Vec<f64>,
    /// (pass kind name, passes of that kind), in [`PassKind`] order.
    ///
    /// [`PassKind`]: super::passes::PassKind
    pub passes: Vec<(String, usize)>,
    /// Length of the feed moves, mm (3-D).
    pub feed_length_mm: f64,
    /// Length of the rapid moves, mm (3-D).
    pub rapid_length_mm: f64,
    /// Predicted cycle time under the machine's controller model, s.
    pub cycle_time_s: f64,
    /// The machine profile's name.
    pub machine: String,
    /// Records (moves) in the program.
    pub blocks: usize,
    /// Moves of the final layer's main path in the chosen motion.
    pub final_main_blocks: usize,
    /// (mode, blocks, largest cell-point deviation mm) per final-layer motion.
    pub motion_blocks: Vec<(String, usize, f64)>,
    /// The chosen final-layer motion ([`MotionMode::name`]).
    ///
    /// [`MotionMode::name`]: super::motion::MotionMode::name
    pub motion: String,
    /// The fitting tolerance, mm.
    pub tolerance_mm: f64,
    /// Largest scallop height between neighbouring grid points (thesis
    /// Fig. 35), mm; for the offset strategy, between flat loops a
    /// stepover apart.
    pub scallop_fig35_mm: f64,
    /// Largest CL/CC surface error R(1 − cos θ) between neighbouring grid
    /// points (thesis Fig. 35), mm; 0 for the offset strategy.
    pub surface_error_fig35_mm: f64,
    /// Largest surface-point error of a Bezier step through grid points
    /// (thesis Fig. 20), mm.
    pub surface_point_error_fig20_mm: f64,
}

fn push_f(b: &mut String, k: &str, v: f64) {
    b.push_str(",\"");
    b.push_str(k);
    b.push_str("\":");
    push_num(b, (v * 1e9).round() / 1e9);
}

impl Figures {
    /// Fill lengths, block count and cycle time from the program.
    pub fn measure(&mut self, prog: &Program, machine: &Machine) -> Result<(), SimError> {
        (self.feed_length_mm, self.rapid_length_mm) = lengths(&prog.records);
        self.blocks = prog.records.len();
        self.final_main_blocks = prog.final_main_blocks;
        self.cycle_time_s = cycle_time_s(&prog.records, machine)?;
        self.machine = machine.name.clone();
        Ok(())
    }

    /// One JSON object on one line.
    pub fn to_json(&self) -> String {
        let mut b = String::from("{\"schema\":\"microcam.pocket-report/1\",\"strategy\":\"");
        b.push_str(&self.strategy);
        b.push_str("\",\"cutter\":\"");
        b.push_str(&self.cutter);
        b.push_str("\",\"machine\":\"");
        b.push_str(&self.machine);
        b.push_str(&format!(
            "\",\"cells\":{},\"layers\":{},\"floors_mm\":[",
            self.cells, self.layers
        ));
        for (k, f) in self.floors_mm.iter().enumerate() {
            if k > 0 {
                b.push(',');
            }
            push_num(&mut b, (f * 1e9).round() / 1e9);
        }
        b.push_str("],\"passes\":{");
        for (k, (n, c)) in self.passes.iter().enumerate() {
            if k > 0 {
                b.push(',');
            }
            b.push_str(&format!("\"{n}\":{c}"));
        }
        b.push('}');
        push_f(&mut b, "feed_length_mm", self.feed_length_mm);
        push_f(&mut b, "rapid_length_mm", self.rapid_length_mm);
        push_f(&mut b, "cycle_time_s", self.cycle_time_s);
        b.push_str(&format!(
            ",\"blocks\":{},\"motion\":\"{}\",\"final_main_blocks\":{}",
            self.blocks, self.motion, self.final_main_blocks
        ));
        push_f(&mut b, "tolerance_mm", self.tolerance_mm);
        b.push_str(",\"final_main_motion\":{");
        for (k, (n, c, d)) in self.motion_blocks.iter().enumerate() {
            if k > 0 {
                b.push(',');
            }
            b.push_str(&format!("\"{n}\":{{\"blocks\":{c}"));
            push_f(&mut b, "max_point_deviation_mm", *d);
            b.push('}');
        }
        b.push('}');
        push_f(&mut b, "scallop_fig35_mm", self.scallop_fig35_mm);
        push_f(&mut b, "surface_error_fig35_mm", self.surface_error_fig35_mm);
        push_f(
            &mut b,
            "surface_point_error_fig20_mm",
            self.surface_point_error_fig20_mm,
        );
        b.push('}');
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_formulas_vanish_where_they_should() {
        let (s, h) = fig35(1.0, 0.5, 0.0);
        assert_eq!(s, 0.0);
        // Flat neighbours: R·(√(g²+R²) - R)/√(g²+R²).
        let w = (0.5f64.hypot(1.0) - 1.0) / 0.5f64.hypot(1.0);
        assert!((h - w).abs() < 1e-12);
        assert_eq!(fig20(1.0, 0.0), 0.0);
        assert!(fig20(1.0, 0.5) > 0.0);
    }
}
