//! Freeform pockets: a polygonal (or arc-bounded) pocket whose bottom is a
//! freeform surface, machined by navigating a grid (the Iowa State
//! grid-pocket thesis (1999)), or by contour-parallel offsets for
//! comparison.
//!
//! - [`surface`]: the bottom (Bezier patch, measured grid, flat).
//! - [`contact`]: where the cutter touches it; gouge-free moves.
//! - [`grid`]: the tool-centre region and its cells.
//! - [`navigate`]: the counter-clockwise priority navigation.
//! - [`passes`]: main, wall and zigzag passes at full depth.
//! - [`layers`]: rough and finish layers, links, records.
//! - [`motion`]: lines, arc + line, Bezier + line on the final layer.
//! - [`offset`]: the contour-parallel alternative.
//! - [`report`]: figures of a job.
//! - [`svg`]: a preview coloured by pass kind.

#![warn(missing_docs)]

pub mod contact;
pub mod grid;
pub mod layers;
pub mod motion;
pub mod navigate;
pub mod offset;
pub mod passes;
pub mod report;
pub mod surface;
pub mod svg;

use crate::cutter::Cutter;
use crate::geometry::P2;
use crate::machine::Machine;
use cavalier_contours::polyline::{PlineSource, Polyline};
use contact::Contact;
use grid::{Grid, Region};
use layers::{Feeds, LayerPlan, Program};
use motion::{FitOptions, MotionMode};
use navigate::Navigation;
use passes::{Pass, PassKind};
use report::Figures;
use surface::Surface;
use thiserror::Error;

/// Why a pocket cannot be made.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PocketError {
    /// A spec value out of range or an unreadable surface; the message
    /// says which and why.
    #[error("{0}")]
    Input(String),
    /// The grid pitch leaves material between cell centres.
    #[error(
        "grid pitch {pitch} mm is above D/sqrt(2) = {limit} mm: the cutter would not cover a whole cell from its centre and material would be left between grid centres (use --force to accept)"
    )]
    PitchTooLarge {
        /// The larger of the two pitches, mm.
        pitch: f64,
        /// D/√2 for the cutter, mm.
        limit: f64,
    },
    /// The boundary offset inward by the tool radius is empty; the
    /// cutter's diameter, mm.
    #[error("the cutter (diameter {0} mm) does not fit in the pocket: no tool-centre region")]
    NoRegion(f64),
    /// The cycle-time simulation refused the program (the machine's
    /// limits, a move it cannot time).
    #[error("{0}")]
    Time(String),
}

/// Which way the pocket is cleared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// Grid navigation (the thesis).
    Grid,
    /// Contour-parallel offsets.
    Offset,
}

/// How the layers are chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum Layers {
    /// This many layers of equal depth from the top to the deepest
    /// touching height; the last is the finish layer.
    Count(usize),
    /// Floors (mm) of the roughing layers; the finish layer follows.
    Floors(Vec<f64>),
}

/// Everything a pocket needs: the outline, the bottom, the cutter, the
/// grid and the cutting parameters (mm, mm/s).
#[derive(Debug, Clone)]
pub struct PocketSpec {
    /// Closed boundary (any orientation), lines and arcs.
    pub boundary: Polyline<f64>,
    /// The pocket's bottom.
    pub surface: Surface,
    /// The end mill: its radius offsets the boundary into the tool-centre
    /// region, its profile sets the touching heights.
    pub cutter: Cutter,
    /// Height of the stock's top, mm: [`Layers::Count`] divides the depth
    /// from here down to the deepest touching height, and the clearance
    /// height must be above it.
    pub top_z: f64,
    /// Grid pitch along X, mm; at most D/√2 (with the other pitch) unless
    /// `force`.
    pub dx: f64,
    /// Grid pitch along Y, mm.
    pub dy: f64,
    /// Lower-left corner of the grid (default: the boundary's).
    pub origin: Option<P2>,
    /// How the layers are chosen.
    pub layers: Layers,
    /// Feeds (mm/s) and the clearance height.
    pub feeds: Feeds,
    /// How the final layer's main path is written.
    pub motion: MotionMode,
    /// Tolerances of the final-layer fits.
    pub fit: FitOptions,
    /// Largest dip below the touching height a straight move or curve may
    /// make between checked points, mm.
    pub gouge_tol: f64,
    /// Grid navigation or contour-parallel offsets.
    pub strategy: Strategy,
    /// Offset strategy: distance between loops (mm).
    pub stepover: f64,
    /// Accept a pitch above D/√2.
    pub force: bool,
    /// The machine whose controller model times the program.
    pub machine: Machine,
}

/// A planned pocket.
#[derive(Debug, Clone)]
pub struct PocketJob {
    /// The toolpath, with the pass kind of each record.
    pub program: Program,
    /// The tool-centre region.
    pub region: Region,
    /// The grid cells in the region (computed for either strategy).
    pub grid: Grid,
    /// The grid navigation (empty for the offset strategy).
    pub nav: Navigation,
    /// Figures for the report.
    pub figures: Figures,
}

/// Most layers of one job.
pub const MAX_LAYERS: usize = 1000;
/// Most grid cells of one job.
pub const MAX_CELLS: usize = 4_000_000;

/// The boundary's vertex box (arcs bulging out of it are covered by the
/// region computation, which uses the exact offset).
fn bbox(pl: &Polyline<f64>) -> (P2, P2) {
    let mut lo = P2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for v in pl.iter_vertexes() {
        lo = P2::new(lo.x.min(v.x), lo.y.min(v.y));
        hi = P2::new(hi.x.max(v.x), hi.y.max(v.y));
    }
    (lo, hi)
}

/// Check the spec's numbers.
fn validate(s: &PocketSpec) -> Result<(), PocketError> {
    let pos = |name: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(PocketError::Input(format!("{name} must be a positive number, got {v}")))
        }
    };
    pos("grid pitch X", s.dx)?;
    pos("grid pitch Y", s.dy)?;
    pos("roughing feed", s.feeds.rough)?;
    pos("finishing feed", s.feeds.finish)?;
    pos("plunge feed", s.feeds.plunge)?;
    pos("tolerance", s.fit.tol)?;
    pos("maximum radius", s.fit.max_radius)?;
    pos("gouge tolerance", s.gouge_tol)?;
    pos("stepover", s.stepover)?;
    if !(s.top_z.is_finite() && s.feeds.safe_z.is_finite() && s.feeds.safe_z > s.top_z) {
        return Err(PocketError::Input("the clearance height must be above the top".into()));
    }
    if s.boundary.vertex_count() < 2 || s.boundary.area().abs() <= 1e-12 {
        return Err(PocketError::Input("the boundary encloses no area".into()));
    }
    let limit = s.cutter.diameter() / 2f64.sqrt();
    let pitch = s.dx.max(s.dy);
    if pitch > limit * (1.0 + 1e-12) && !s.force {
        return Err(PocketError::PitchTooLarge { pitch, limit });
    }
    if let Layers::Floors(f) = &s.layers
        && (f.iter().any(|v| !v.is_finite()) || f.windows(2).any(|w| w[1] >= w[0]))
    {
        return Err(PocketError::Input("layer floors must be finite and descending".into()));
    }
    match &s.layers {
        Layers::Count(0) => return Err(PocketError::Input("at least one layer".into())),
        Layers::Count(n) if *n > MAX_LAYERS => {
            return Err(PocketError::Input(format!("{n} layers is more than {MAX_LAYERS}")));
        }
        Layers::Floors(f) if f.len() >= MAX_LAYERS => {
            return Err(PocketError::Input(format!(
                "{} layer floors is more than {MAX_LAYERS}",
                f.len()
            )));
        }
        _ => {}
    }
    // A job this large is a typo (a pitch in the wrong unit), not a part.
    let (lo, hi) = bbox(&s.boundary);
    let (w, h) = (hi.x - lo.x, hi.y - lo.y);
    if (w / s.dx + 2.0) * (h / s.dy + 2.0) > MAX_CELLS as f64 {
        return Err(PocketError::Input(format!(
            "a {w} x {h} mm pocket at pitch {} x {} mm has more than {MAX_CELLS} cells",
            s.dx, s.dy
        )));
    }
    if s.strategy == Strategy::Offset && w.max(h) / s.stepover > 20_000.0 {
        return Err(PocketError::Input(format!(
            "stepover {} mm gives too many loops",
            s.stepover
        )));
    }
    Ok(())
}

/// Plan the pocket: check the spec, make the tool-centre region, the grid
/// and the passes of the strategy, the layers' program, and the report's
/// figures (the cycle time under the spec's machine).
pub fn plan(s: &PocketSpec) -> Result<PocketJob, PocketError> {
    validate(s)?;
    let contact = Contact::new(&s.surface, s.cutter, s.gouge_tol);
    let region = Region::new(&s.boundary, s.cutter.radius());
    if region.is_empty() {
        return Err(PocketError::NoRegion(s.cutter.diameter()));
    }
    let origin = s.origin.unwrap_or_else(|| bbox(&s.boundary).0);
    let grid = Grid::new(&region, origin, s.dx, s.dy);
    let pitch = s.dx.min(s.dy);
    let (nav, every, final_only) = match s.strategy {
        Strategy::Grid => {
            let nav = navigate::navigate(&grid, &region);
            // Progress (a tool's spinner): each stage counts the touching
            // heights it computes (see Contact::tip_z).
            crate::progress::stage("main passes: touching heights", 0);
            let main = passes::main_passes(&contact, &grid, &nav);
            let end = main
                .last()
                .and_then(|p| p.pts.last())
                .map(|p| P2::new(p.x, p.y))
                .unwrap_or(origin);
            let mut every = main;
            crate::progress::stage("wall passes: touching heights", 0);
            every.extend(passes::wall_passes(&contact, &region, end, pitch));
            crate::progress::stage("zigzag passes: touching heights", 0);
            let mut fin = passes::zigzag_passes(&contact, &grid, &region, &nav, true);
            fin.extend(passes::zigzag_passes(&contact, &grid, &region, &nav, false));
            (nav, every, fin)
        }
        Strategy::Offset => {
            crate::progress::stage("offset passes: touching heights", 0);
            (
                Navigation::default(),
                offset::offset_passes(&contact, &s.boundary, s.stepover, pitch),
                Vec::new(),
            )
        }
    };
    let deepest = every
        .iter()
        .chain(&final_only)
        .flat_map(|p| p.pts.iter().map(|q| q.z))
        .fold(f64::INFINITY, f64::min);
    let floors = match &s.layers {
        Layers::Floors(f) => f.clone(),
        Layers::Count(n) => {
            let depth = (s.top_z - deepest).max(0.0);
            (1..*n).map(|k| s.top_z - depth * k as f64 / *n as f64).collect()
        }
    };
    let lp = LayerPlan {
        contact: &contact,
        region: &region,
        floors: floors.clone(),
        feeds: s.feeds,
        every_layer: every.clone(),
        final_only: final_only.clone(),
        motion: s.motion,
        fit: s.fit,
        step: 0.125 * pitch,
        feed_links: s.strategy == Strategy::Offset,
    };
    crate::progress::stage("layers: touching heights", 0);
    let program = layers::build(&lp);
    let mut fig = Figures {
        strategy: match s.strategy {
            Strategy::Grid => "grid",
            Strategy::Offset => "offset",
        }
        .into(),
        cutter: s.cutter.to_string(),
        cells: grid.cells.len(),
        layers: floors.len() + 1,
        floors_mm: floors,
        motion: s.motion.name().into(),
        tolerance_mm: s.fit.tol,
        ..Default::default()
    };
    let mut counts: std::collections::BTreeMap<PassKind, usize> = Default::default();
    for p in every.iter().chain(&final_only) {
        *counts.entry(p.kind).or_default() += 1;
    }
    fig.passes = counts.into_iter().map(|(k, n)| (k.name().to_string(), n)).collect();
    crate::progress::stage("estimates: touching heights", 0);
    estimates(&mut fig, &contact, &grid, &every, s);
    fig.measure(&program, &s.machine)
        .map_err(|e| PocketError::Time(e.to_string()))?;
    Ok(PocketJob {
        program,
        region,
        grid,
        nav,
        figures: fig,
    })
}

/// Thesis estimates and the block counts of each final-layer motion.
fn estimates(fig: &mut Figures, c: &Contact, grid: &Grid, every: &[Pass], s: &PocketSpec) {
    let r = s.cutter.radius();
    let (mut scallop, mut surf, mut pt_err) = (0.0f64, 0.0f64, 0.0f64);
    if s.strategy == Strategy::Grid {
        for &(i, j) in &grid.cells {
            let z0 = c.tip_z_at(grid.centre((i, j)));
            for (d, g) in [((1, 0), s.dx), ((0, 1), s.dy)] {
                let n = (i + d.0, j + d.1);
                if grid.id(n).is_some() {
                    let (e, h) = report::fig35(r, g, c.tip_z_at(grid.centre(n)) - z0);
                    surf = surf.max(e);
                    scallop = scallop.max(h);
                }
            }
        }
    } else {
        // Neighbouring loops a stepover apart: the flat-bottom case.
        scallop = report::fig35(r, s.stepover, 0.0).1;
    }
    let mut modes = Vec::new();
    for mode in [MotionMode::Lines, MotionMode::ArcLine, MotionMode::BezierLine] {
        let (mut blocks, mut dev) = (0usize, 0.0f64);
        for p in every.iter().filter(|p| p.kind == PassKind::Main) {
            for run in &p.runs {
                let e = motion::fit_run(c, run, mode, &s.fit, 0.125 * s.dx.min(s.dy));
                dev = dev.max(motion::point_deviation(&e, run));
                blocks += e.len();
                if mode == MotionMode::BezierLine {
                    for w in run.windows(2) {
                        let unit = (w[1].xy() - w[0].xy()).norm();
                        pt_err = pt_err.max(report::fig20(unit, w[1].z - w[0].z));
                    }
                }
            }
        }
        if s.strategy == Strategy::Grid {
            modes.push((mode.name().to_string(), blocks, dev));
        }
    }
    fig.motion_blocks = modes;
    fig.scallop_fig35_mm = scallop;
    fig.surface_error_fig35_mm = surf;
    fig.surface_point_error_fig20_mm = pt_err;
}
