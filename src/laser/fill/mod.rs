//! `pathgen fill`: area fill of closed chains (Bayesteh (2013) §6.3.3.6:
//! a model sliced at Z levels, each planar section filled with passes of
//! the beam).
//!
//! Chains are grouped by their Z (one level per Z, in input order) and
//! nested within a level by containment: a chain inside an even number of
//! others is an outer boundary (made counter-clockwise), one inside an odd
//! number a hole (made clockwise) of the outer that directly contains it.
//! Each outer with its holes is one region, filled by
//!
//! - **offset** passes: the region's boundary offset inward (holes
//!   outward) by the beam radius, then by one stepover more each pass,
//!   until nothing is left (cavalier_contours' shape offset, exact for
//!   lines and arcs, islands and holes merging as they meet); or
//! - **hatch** lines at an angle, `stepover` apart, clipped to the region
//!   shrunk by the beam radius (so holes are excluded), run zigzag,
//!   optionally followed by that shrunk outline.
//!
//! So the beam centre stays at least one beam radius inside the region and
//! outside every hole. The passes of a region are joined by beam-off
//! links at V (Dubins paths of the stage's least radius, long enough for
//! the shutter) into one path, which the laser planner
//! ([`super::constant_velocity::plan_tagged`]) turns into moves like any other: lead-in
//! and lead-out, corner loops, shutter timing, PMAC pacing. Regions are cut
//! in nearest-neighbour order, level after level.
//!
//! Offset rings turn each reflex corner of the region with an arc of the
//! offset's radius about the corner; at the beam radius that arc asks far
//! more than the stage's acceleration at V. As in [`super::offset`], each
//! such join becomes a mitre (a real corner, looped with the beam off),
//! unless the mitre point would come closer to the region's boundary than
//! the offset itself; then the arc stays and the planner reports it.
//!
//! One idea per file: `regions.rs` (chains to nested, ordered regions, and
//! the work estimate), `rings.rs` (the contour-parallel offset passes),
//! `hatch.rs` (the hatch lines), `link.rs` (short stretches dropped, tiny
//! pieces merged, passes joined by beam-off links); this file holds the
//! options and plans the regions.

mod hatch;
mod link;
mod regions;
mod rings;
#[cfg(test)]
mod tests;

pub use regions::{estimate, prepare};

use super::constant_velocity::{Note, Tagged, plan_tagged, ramps_record, to_records};
use super::contour::{ContourJob, Warning};
use super::setup::LaserSetup;
use crate::geometry::P2;
use crate::model::chain::{Chain, Segment};
use crate::model::toolpath::Record;
use cavalier_contours::shape_algorithms::Shape;
use rayon::prelude::*;
use thiserror::Error;

/// One region planned: its records, its notes, whether it was cut, and
/// (stretches skipped, their length) for the tally.
type PlannedRegion = (Vec<Record>, Vec<Note>, bool, (usize, f64));

/// How a region is filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Pattern {
    /// Contour-parallel passes, inward from the boundary.
    Offset,
    /// Zigzag lines at an angle.
    Hatch,
}

/// What to fill with.
#[derive(Debug, Clone, PartialEq)]
pub struct FillOptions {
    /// Offset rings or hatch lines.
    pub pattern: Pattern,
    /// Beam radius (mm): the first pass runs this far inside the boundary.
    pub beam_radius: f64,
    /// Distance between passes (mm).
    pub stepover: f64,
    /// Hatch: direction of the lines (degrees from +X).
    pub angle_deg: f64,
    /// Hatch: cut the shrunk outline after the lines.
    pub outline: bool,
    /// Refuse jobs estimated to make more moves than this.
    pub max_moves: u64,
}

impl Default for FillOptions {
    fn default() -> Self {
        FillOptions {
            pattern: Pattern::Offset,
            beam_radius: 0.005,
            stepover: 0.005,
            angle_deg: 0.0,
            outline: false,
            max_moves: 5_000_000,
        }
    }
}

/// Why a fill cannot be planned.
#[derive(Debug, Error, PartialEq)]
pub enum FillError {
    /// The stepover or the beam radius (named) is zero, negative or not a
    /// number.
    #[error("{0} must be a positive finite number, got {1}")]
    NotPositive(&'static str, f64),
    /// The hatch angle is not a finite number.
    #[error("--angle must be a finite number, got {0}")]
    BadAngle(f64),
    /// This chain has a NaN or infinite coordinate.
    #[error("chain {0}: a coordinate is not a finite number")]
    NotFinite(u64),
    /// No closed chain at all; this many open ones were ignored.
    #[error("no closed chains to fill ({0} open chain(s) ignored): fill needs closed boundaries")]
    NoClosed(usize),
    /// The closed chains enclose no area (all degenerate, or holes as large
    /// as their outers).
    #[error("the closed chains enclose no area to fill")]
    Empty,
    /// Nothing left to fill, and this chain crosses itself at (x, y): its
    /// loops cancel (a bow tie encloses no net area).
    #[error(
        "nothing to fill: chain {chain} crosses itself at ({x:.6}, {y:.6}) and its loops cancel; \
         fill needs boundaries that do not cross themselves"
    )]
    Crosses {
        /// The chain's id.
        chain: u64,
        /// Where (mm).
        x: f64,
        /// Where (mm).
        y: f64,
    },
    /// The estimate is past [`FillOptions::max_moves`]: the stepover is
    /// too fine for the regions.
    #[error(
        "the fill would make about {moves} moves in about {passes} passes (more than --max-moves {max}): \
         stepover {stepover} mm is too fine for these regions; raise the stepover or --max-moves"
    )]
    TooBig {
        /// Estimated passes.
        passes: u64,
        /// Estimated moves.
        moves: u64,
        /// The limit.
        max: u64,
        /// The stepover asked for (mm).
        stepover: f64,
    },
}

/// One outer boundary with its holes at one Z.
#[derive(Debug, Clone)]
pub struct Region {
    /// Id of the outer chain (the moves carry it).
    pub chain: u64,
    /// The level's Z (mm): every pass of the region runs at it.
    pub z: f64,
    /// The outer (counter-clockwise) and its holes (clockwise).
    pub shape: Shape<f64>,
    /// Area of the region (outer minus holes, mm²).
    pub area: f64,
    /// How many holes it has.
    pub holes: usize,
    /// Vertices of the outer and the holes, for the work estimate.
    pub vertices: usize,
    /// Lower left corner of the outer's box (mm).
    pub lo: P2,
    /// Upper right corner of the outer's box (mm).
    pub hi: P2,
}

/// Regions in cutting order, what the user should know, and the size
/// estimate the job was admitted with.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The regions, level after level, nearest-neighbour within a level.
    pub regions: Vec<Region>,
    /// Chains ignored or changed, with why.
    pub warnings: Vec<Warning>,
    /// The work the job was admitted on.
    pub estimate: Estimate,
}

/// A bound-of-work estimate made before any pass is computed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Estimate {
    /// Passes (offset rings or hatch lines, outline rings).
    pub passes: u64,
    /// Toolpath moves, leads, loops and switch splits included.
    pub moves: u64,
}

/// How tight arcs of the passes are made followable.
struct Fix {
    /// The stage's least radius at V.
    rmin: f64,
    /// Largest distance of a chord from its arc.
    sag: f64,
}

/// The cut runs of one region (offset rings or hatch lines), unjoined, for
/// a stage whose least radius at V is `rmin`.
pub fn region_runs(r: &Region, o: &FillOptions, rmin: f64) -> Vec<Vec<Segment>> {
    let f = Fix {
        rmin,
        sag: 0.25 * o.stepover.min(o.beam_radius),
    };
    match o.pattern {
        Pattern::Offset => rings::offset_runs(r, o, &f),
        Pattern::Hatch => hatch::hatch_runs(r, o, &f),
    }
}

/// The paths of one region: its passes, less the stretches shorter than
/// the shutter's minimum exposure (counted in `dropped`: stretches, mm),
/// joined by beam-off links.
pub fn region_paths(r: &Region, m: &LaserSetup, o: &FillOptions, dropped: &mut (usize, f64)) -> Vec<Tagged> {
    link::join_runs(region_runs(r, o, m.min_radius()), m, dropped)
}

/// Plan the prepared regions chunk by chunk (each chunk on every core),
/// handing each chunk's moves to `sink` in cutting order, after the
/// program's ramps record. `sink` returns false to stop. Returns the
/// warnings (preparation's, then one per region and kind).
pub fn plan_prepared(
    p: &Prepared,
    m: &LaserSetup,
    o: &FillOptions,
    mut sink: impl FnMut(Vec<Record>) -> bool,
) -> Vec<Warning> {
    let mut warnings = p.warnings.clone();
    let mut t = Tally::default();
    if !sink(vec![ramps_record(m)]) {
        return warnings;
    }
    for chunk in p.regions.chunks(16) {
        let planned: Vec<PlannedRegion> = chunk
            .par_iter()
            .map(|r| {
                let mut dropped = (0, 0.0);
                let paths = region_paths(r, m, o, &mut dropped);
                let mut notes = Vec::new();
                let mut recs = Vec::new();
                for path in &paths {
                    let pieces = plan_tagged(path, m, &mut notes);
                    to_records(&pieces, m, Some(r.chain), &mut recs);
                }
                (recs, notes, paths.is_empty(), dropped)
            })
            .collect();
        // Progress (a tool's bar): each region's share of the job's
        // estimate, so the units add up to `p.estimate.moves`.
        crate::progress::advance(regions::estimate(chunk, o).moves);
        let mut recs = Vec::with_capacity(planned.iter().map(|p| p.0.len()).sum());
        for ((rs, notes, empty, dropped), r) in planned.into_iter().zip(chunk) {
            recs.extend(rs);
            if dropped.0 > 0 {
                t.dropped.0 += dropped.0;
                t.dropped.1 += dropped.1;
                t.dropped_in.get_or_insert(r.chain);
            }
            if empty && dropped.0 == 0 {
                t.narrow += 1;
                t.narrow_in.get_or_insert(r.chain);
            }
            let mut seen = std::collections::BTreeSet::new();
            for n in notes {
                let kind = match n {
                    Note::SwitchOff { count, worst } => {
                        t.switch.0 += count;
                        t.switch.1 = t.switch.1.max(worst);
                        t.switch_in.get_or_insert(r.chain);
                        continue;
                    }
                    Note::TightArc { .. } => "tight".to_string(),
                    _ => n.to_string(),
                };
                if seen.insert(kind) {
                    warnings.push(Warning {
                        chain: r.chain,
                        message: n.to_string(),
                    });
                }
            }
        }
        if !sink(recs) {
            break;
        }
    }
    // One line per kind for the whole job, however many regions.
    if let Some(chain) = t.dropped_in {
        warnings.push(Warning {
            chain,
            message: format!(
                "{} pass stretch(es) between corners, {:.6} mm in all, are shorter than the shutter's minimum \
                 exposure ({:.6} mm at this feed); not cut",
                t.dropped.0,
                t.dropped.1,
                m.min_cut()
            ),
        });
    }
    if let Some(chain) = t.narrow_in {
        warnings.push(Warning {
            chain,
            message: format!(
                "{} region(s) narrower than the beam ({} mm radius): nothing to cut there",
                t.narrow, o.beam_radius
            ),
        });
    }
    if let Some(chain) = t.switch_in {
        warnings.push(Warning {
            chain,
            message: Note::SwitchOff {
                count: t.switch.0,
                worst: t.switch.1,
            }
            .to_string(),
        });
    }
    warnings
}

/// Job-wide tallies of what the user is told once.
#[derive(Default)]
struct Tally {
    dropped: (usize, f64),
    dropped_in: Option<u64>,
    narrow: usize,
    narrow_in: Option<u64>,
    switch: (usize, f64),
    switch_in: Option<u64>,
}

/// Plan a whole fill job: [`prepare`], then [`plan_prepared`] into one
/// record list.
pub fn fill(chains: &[Chain], m: &LaserSetup, o: &FillOptions) -> Result<ContourJob, FillError> {
    let p = prepare(chains, o)?;
    let mut records = Vec::new();
    let warnings = plan_prepared(&p, m, o, |r| {
        records.extend(r);
        true
    });
    Ok(ContourJob {
        records,
        warnings,
        cleanup: Default::default(),
    })
}
