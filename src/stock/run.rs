//! Running a whole toolpath through the stock: chip volume per step and
//! per block, and rapids that hit material (collisions).

use super::cutter::Cutter;
use super::heightfield::{HeightField, StockError};
use super::path::cut_motion;
use crate::geometry::P3;
use crate::model::toolpath::{MotionKind, Record};

/// Chip volumes of one motion block.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockChips {
    /// Source line, when the toolpath came from G-code.
    pub block: Option<u64>,
    /// Index of the motion in the toolpath (0-based).
    pub motion: u64,
    pub rapid: bool,
    pub steps: u64,
    pub removed_mm3: f64,
    pub max_step_mm3: f64,
}

impl BlockChips {
    pub fn mean_step_mm3(&self) -> f64 {
        if self.steps == 0 {
            0.0
        } else {
            self.removed_mm3 / self.steps as f64
        }
    }
}

/// Totals of a run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StockTotals {
    pub removed_mm3: f64,
    pub steps: u64,
    pub max_step_mm3: f64,
    /// Material removed by rapid moves: each one is a collision.
    pub rapid_removed_mm3: f64,
    /// Source lines (or motion indices when there are none) of the rapids
    /// that removed material, the first 100.
    pub collisions: Vec<u64>,
    pub collision_count: u64,
}

/// A stock being cut by a toolpath, one record at a time.
pub struct StockRun {
    pub stock: HeightField,
    tool: Cutter,
    step_mm: f64,
    pos: P3,
    motions: u64,
    pub totals: StockTotals,
}

impl StockRun {
    /// `step_mm`: chip step length (feed per tooth x scale factor).
    pub fn new(stock: HeightField, tool: Cutter, step_mm: f64, start: P3) -> StockRun {
        StockRun {
            stock,
            tool,
            step_mm,
            pos: start,
            motions: 0,
            totals: StockTotals::default(),
        }
    }

    /// Cut one record; `on_step(block, step_end, removed_mm3)` sees every
    /// step. Returns the block's chips for a motion, `None` otherwise.
    pub fn add(
        &mut self,
        r: &Record,
        mut on_step: impl FnMut(&BlockChips, P3, f64),
    ) -> Result<Option<BlockChips>, StockError> {
        let Record::Move(m) = r else { return Ok(None) };
        let mut chips = BlockChips {
            block: m.block,
            motion: self.motions,
            rapid: matches!(m.kind, MotionKind::Rapid),
            steps: 0,
            removed_mm3: 0.0,
            max_step_mm3: 0.0,
        };
        let mut steps = Vec::new();
        cut_motion(&mut self.stock, &self.tool, self.pos, m, self.step_mm, |p, v| {
            steps.push((p, v))
        })?;
        for (p, v) in steps {
            chips.steps += 1;
            chips.removed_mm3 += v;
            chips.max_step_mm3 = chips.max_step_mm3.max(v);
            on_step(&chips, p, v);
        }
        let t = &mut self.totals;
        t.removed_mm3 += chips.removed_mm3;
        t.steps += chips.steps;
        t.max_step_mm3 = t.max_step_mm3.max(chips.max_step_mm3);
        if chips.rapid && chips.removed_mm3 > 0.0 {
            t.rapid_removed_mm3 += chips.removed_mm3;
            t.collision_count += 1;
            if t.collisions.len() < 100 {
                t.collisions.push(m.block.unwrap_or(self.motions));
            }
        }
        self.pos = m.to;
        self.motions += 1;
        Ok(Some(chips))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::{ReadOptions, read_str};

    #[test]
    fn a_program_cuts_reports_chips_per_block_and_finds_a_rapid_collision() {
        let (_, recs) = read_str(
            "G21 G90\nG0 X2 Y5 Z1\nG1 Z-0.2 F60\nG1 X8\nG0 X9 Z-0.1\nG0 Z5\n",
            &ReadOptions::default(),
        )
        .unwrap();
        let stock = HeightField::new(P3::new(0.0, 0.0, -2.0), P3::new(10.0, 10.0, 0.0), 0.02).unwrap();
        let mut run = StockRun::new(stock, Cutter::flat(0.5).unwrap(), 0.05, P3::new(0.0, 0.0, 5.0));
        let before = run.stock.volume();
        let mut blocks = Vec::new();
        for r in &recs {
            if let Some(b) = run.add(r, |_, _, _| {}).unwrap() {
                blocks.push(b);
            }
        }
        assert!((before - run.stock.volume() - run.totals.removed_mm3).abs() < 1e-6);
        // The slot along X: 6 mm x 1 mm x 0.2 mm plus the plunge's disc.
        let slot = blocks.iter().find(|b| b.block == Some(4)).unwrap();
        assert!((slot.removed_mm3 - 6.0 * 1.0 * 0.2).abs() < 0.03 * 1.2, "{slot:?}");
        assert_eq!(slot.steps, 120);
        assert!(slot.mean_step_mm3() > 0.0 && slot.max_step_mm3 >= slot.mean_step_mm3());
        // The rapid on line 5 goes back down into material: a collision.
        assert_eq!(run.totals.collisions, vec![5]);
        assert_eq!(run.totals.collision_count, 1);
    }
}
