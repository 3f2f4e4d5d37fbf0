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

use super::contour::{ContourJob, Warning};
use super::dubins::connect;
use super::offset::{continue_line, from_polyline, join_closed_ends, to_polyline};
use super::order;
use super::constant_velocity::{Note, Tagged, plan_tagged, ramps_record, to_records};
use super::setup::LaserSetup;
use crate::geometry::{P2, P3, Plane, V2};
use crate::model::chain::{Chain, Segment};
use crate::model::toolpath::{Record, Role};
use cavalier_contours::core::math::Vector2;
use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline, seg_closest_point};
use cavalier_contours::shape_algorithms::{Shape, ShapeOffsetOptions};
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
    #[error("{0} must be a positive finite number, got {1}")]
    NotPositive(&'static str, f64),
    #[error("--angle must be a finite number, got {0}")]
    BadAngle(f64),
    #[error("chain {0}: a coordinate is not a finite number")]
    NotFinite(u64),
    #[error("no closed chains to fill ({0} open chain(s) ignored): fill needs closed boundaries")]
    NoClosed(usize),
    #[error("the closed chains enclose no area to fill")]
    Empty,
    #[error(
        "the fill would make about {moves} moves in about {passes} passes (more than --max-moves {max}): \
         stepover {stepover} mm is too fine for these regions; raise the stepover or --max-moves"
    )]
    TooBig {
        passes: u64,
        moves: u64,
        max: u64,
        stepover: f64,
    },
}

/// One outer boundary with its holes at one Z.
#[derive(Debug, Clone)]
pub struct Region {
    /// Id of the outer chain (the moves carry it).
    pub chain: u64,
    pub z: f64,
    /// The outer (counter-clockwise) and its holes (clockwise).
    pub shape: Shape<f64>,
    /// Area of the region (outer minus holes, mm²).
    pub area: f64,
    pub holes: usize,
    pub vertices: usize,
    pub lo: P2,
    pub hi: P2,
}

/// Regions in cutting order, what the user should know, and the size
/// estimate the job was admitted with.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub regions: Vec<Region>,
    pub warnings: Vec<Warning>,
    pub estimate: Estimate,
}

/// A bound-of-work estimate made before any pass is computed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Estimate {
    pub passes: u64,
    pub moves: u64,
}

fn offset_options() -> ShapeOffsetOptions<f64> {
    // Micromachining sizes: positions equal within 1 nm, not 10 µm.
    ShapeOffsetOptions {
        pos_equal_eps: 1e-8,
        offset_dist_eps: 1e-7,
        slice_join_eps: 1e-7,
    }
}

fn finite_chain(c: &Chain) -> bool {
    c.segments.iter().all(Segment::is_finite)
}

/// Check the options, nest the chains into regions, order them and
/// estimate the work; refuse a job larger than `o.max_moves`.
pub fn prepare(chains: &[Chain], o: &FillOptions) -> Result<Prepared, FillError> {
    for (name, v) in [("--step-over", o.stepover), ("the beam radius", o.beam_radius)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(FillError::NotPositive(name, v));
        }
    }
    if !o.angle_deg.is_finite() {
        return Err(FillError::BadAngle(o.angle_deg));
    }
    if let Some(c) = chains.iter().find(|c| !finite_chain(c)) {
        return Err(FillError::NotFinite(c.id));
    }
    let mut warnings = Vec::new();
    let mut open = 0;
    // Levels by Z, in order of first appearance.
    let mut levels: Vec<(f64, Vec<&Chain>)> = Vec::new();
    for c in chains {
        let Some(first) = c.segments.first() else { continue };
        if !c.closed {
            open += 1;
            warnings.push(Warning {
                chain: c.id,
                message: "open chain ignored: fill needs closed boundaries".into(),
            });
            continue;
        }
        let z = first.start().z + 0.0;
        if c.segments.iter().any(|s| (s.start().z - z).abs() > 1e-9) {
            warnings.push(Warning {
                chain: c.id,
                message: format!("chain is not level; filled at the Z of its start, {z}"),
            });
        }
        match levels.iter_mut().find(|(lz, _)| lz.to_bits() == z.to_bits()) {
            Some((_, v)) => v.push(c),
            None => levels.push((z, vec![c])),
        }
    }
    if levels.is_empty() {
        return Err(FillError::NoClosed(open));
    }
    let mut regions = Vec::new();
    let mut here = P2::origin();
    for (z, level) in &levels {
        let mut rs = nest_level(level, *z, &mut warnings);
        if rs.is_empty() {
            continue;
        }
        let pts: Vec<P2> = rs.iter().map(|r| first_vertex(r).unwrap_or(r.lo)).collect();
        let seq = order::nearest_neighbour(&pts, here);
        if let Some(&l) = seq.last() {
            here = pts[l];
        }
        let mut slots: Vec<Option<Region>> = rs.drain(..).map(Some).collect();
        regions.extend(seq.into_iter().filter_map(|i| slots[i].take()));
    }
    if regions.is_empty() {
        return Err(FillError::Empty);
    }
    let estimate = estimate(&regions, o);
    if estimate.moves > o.max_moves {
        return Err(FillError::TooBig {
            passes: estimate.passes,
            moves: estimate.moves,
            max: o.max_moves,
            stepover: o.stepover,
        });
    }
    Ok(Prepared {
        regions,
        warnings,
        estimate,
    })
}

fn first_vertex(r: &Region) -> Option<P2> {
    r.shape.ccw_plines.first().and_then(|p| {
        (p.polyline.vertex_count() > 0).then(|| {
            let v = p.polyline.at(0);
            P2::new(v.x, v.y)
        })
    })
}

/// Regions of one level: containment by winding number about each
/// chain's first vertex (boxes first).
fn nest_level(level: &[&Chain], z: f64, warnings: &mut Vec<Warning>) -> Vec<Region> {
    struct Loop {
        id: u64,
        pl: Polyline<f64>,
        area: f64,
        lo: P2,
        hi: P2,
    }
    let mut loops: Vec<Loop> = Vec::new();
    for c in level {
        let pl = to_polyline(c);
        let area = if pl.vertex_count() >= 2 { pl.area() } else { 0.0 };
        let ext = pl.extents();
        match ext {
            Some(e) if area.abs() > 1e-12 => loops.push(Loop {
                id: c.id,
                pl,
                area,
                lo: P2::new(e.min_x, e.min_y),
                hi: P2::new(e.max_x, e.max_y),
            }),
            _ => warnings.push(Warning {
                chain: c.id,
                message: "closed chain encloses no area; ignored".into(),
            }),
        }
    }
    let n = loops.len();
    let containers: Vec<Vec<usize>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let v = loops[i].pl.at(0);
            let q = Vector2::new(v.x, v.y);
            (0..n)
                .filter(|&j| {
                    j != i
                        && loops[j].lo.x <= loops[i].lo.x
                        && loops[j].lo.y <= loops[i].lo.y
                        && loops[j].hi.x >= loops[i].hi.x
                        && loops[j].hi.y >= loops[i].hi.y
                        && loops[j].pl.winding_number(q) != 0
                })
                .collect()
        })
        .collect();
    let depth: Vec<usize> = containers.iter().map(Vec::len).collect();
    let mut out = Vec::new();
    for i in (0..n).filter(|&i| depth[i].is_multiple_of(2)) {
        let mut outer = loops[i].pl.clone();
        if loops[i].area < 0.0 {
            outer.invert_direction_mut();
        }
        let mut plines = vec![outer];
        let mut area = loops[i].area.abs();
        let mut vertices = loops[i].pl.vertex_count();
        for j in (0..n).filter(|&j| depth[j] == depth[i] + 1 && containers[j].contains(&i)) {
            let mut hole = loops[j].pl.clone();
            if loops[j].area > 0.0 {
                hole.invert_direction_mut();
            }
            area -= loops[j].area.abs();
            vertices += hole.vertex_count();
            plines.push(hole);
        }
        if area <= 1e-12 {
            warnings.push(Warning {
                chain: loops[i].id,
                message: "its holes leave no area to fill; skipped".into(),
            });
            continue;
        }
        let holes = plines.len() - 1;
        out.push(Region {
            chain: loops[i].id,
            z,
            shape: Shape::from_plines(plines),
            area,
            holes,
            vertices,
            lo: loops[i].lo,
            hi: loops[i].hi,
        });
    }
    out
}

/// Passes and moves the job will make, from the regions' sizes alone
/// (before any offset is computed): offset rings up to half the smaller
/// side of the box, hatch lines across it; about six moves per corner of a
/// ring (cut, loop, switch points) and twelve per hatch line.
pub fn estimate(regions: &[Region], o: &FillOptions) -> Estimate {
    let (mut passes, mut moves) = (0.0f64, 0.0f64);
    let (s, rb) = (o.stepover, o.beam_radius);
    let a = o.angle_deg.to_radians();
    for r in regions {
        let w = r.hi - r.lo;
        let loops = 1.0 + r.holes as f64;
        let verts = r.vertices as f64;
        match o.pattern {
            Pattern::Offset => {
                let rings = ((0.5 * w.x.min(w.y) - rb) / s).floor().max(0.0) + 1.0;
                passes += rings * loops;
                moves += rings * (6.0 * verts + 10.0 * loops);
            }
            Pattern::Hatch => {
                let across = (w.x * a.sin()).abs() + (w.y * a.cos()).abs();
                let lines = (across / s).floor() + 1.0;
                passes += lines * loops;
                moves += 12.0 * lines * loops;
                if o.outline {
                    passes += loops;
                    moves += 6.0 * verts + 10.0 * loops;
                }
            }
        }
    }
    let clamp = |x: f64| if x >= u64::MAX as f64 { u64::MAX } else { x as u64 };
    Estimate {
        passes: clamp(passes),
        moves: clamp(moves),
    }
}

/// Distance from `p` to the region's boundary, looking only within `reach`
/// (infinite when nothing is that close).
fn boundary_distance(r: &Region, p: P2, reach: f64) -> f64 {
    let q = Vector2::new(p.x, p.y);
    let mut best = f64::INFINITY;
    for ip in r.shape.ccw_plines.iter().chain(&r.shape.cw_plines) {
        let pl = &ip.polyline;
        let n = pl.vertex_count();
        for i in ip
            .spatial_index
            .query(p.x - reach, p.y - reach, p.x + reach, p.y + reach)
        {
            let c = seg_closest_point(pl.at(i), pl.at((i + 1) % n), q, 1e-12);
            best = best.min((c - q).length());
        }
    }
    best
}

/// Make every arc of a pass that is tighter than the stage's least radius
/// at V (`rmin`) followable: a join arc (radius `d` about a point of the
/// boundary) becomes a mitre, or a bevel past 150°, when its corner points
/// stay at least `d` from the boundary; any other tight arc becomes chords
/// within `sag` of it (on its concave side). The corners so made are looped
/// with the beam off by the planner.
fn fix_tight_arcs(path: Vec<Segment>, r: &Region, d: f64, rmin: f64, sag: f64) -> Vec<Segment> {
    const MAX_MITER_SWEEP: f64 = 150.0 * std::f64::consts::PI / 180.0;
    let tol = 1e-9 * (1.0 + d);
    let mut out: Vec<Segment> = Vec::with_capacity(path.len() + 4);
    let push = |out: &mut Vec<Segment>, e: Segment| match out.last().and_then(|prev| continue_line(prev, &e)) {
        Some(joined) => *out.last_mut().expect("checked above") = joined,
        None => out.push(e),
    };
    let polyline = |out: &mut Vec<Segment>, pts: Vec<P3>| {
        for w in pts.windows(2) {
            push(out, Segment::line(w[0], w[1]));
        }
    };
    for e in path {
        let Segment::Arc(arc) = e else {
            push(&mut out, e);
            continue;
        };
        let rad = arc.radius();
        if rad >= rmin * (1.0 - 1e-9) {
            push(&mut out, e);
            continue;
        }
        let (a, b) = (arc.start, arc.end);
        let sweep = arc.sweep().abs();
        let join = (rad - d).abs() <= tol && boundary_distance(r, arc.center.xy(), 1e-6 + tol) <= tol;
        if join {
            let (ta, tb) = (e.start_tangent(), e.end_tangent());
            let pts: Vec<P3> = if sweep <= MAX_MITER_SWEEP {
                vec![a + ta * (d * (0.5 * sweep).tan())]
            } else {
                vec![a + ta * d, b - tb * d]
            };
            if pts.iter().all(|p| boundary_distance(r, p.xy(), d) >= d - tol) {
                let mut all = vec![a];
                all.extend(pts);
                all.push(b);
                polyline(&mut out, all);
                continue;
            }
        }
        // Chords: each spans at most 2·acos(1 - sag/r) of the arc.
        let span = 2.0 * (1.0 - (sag / rad).min(1.0)).acos();
        let k = if span > 0.0 {
            (sweep / span).ceil().clamp(1.0, 4096.0) as usize
        } else {
            1
        };
        let pts: Vec<P3> = (0..=k).map(|i| arc.point_at(i as f64 / k as f64)).collect();
        polyline(&mut out, pts);
    }
    join_closed_ends(&mut out);
    out
}

/// The closed rings of the region's offset at `d` (outer rings first),
/// as path pieces at the region's Z, tight arcs made followable.
fn rings_at(r: &Region, d: f64, f: &Fix) -> Vec<Vec<Segment>> {
    let sh = r.shape.parallel_offset(d, &offset_options());
    if sh.ccw_plines.is_empty() {
        return Vec::new();
    }
    sh.ccw_plines
        .iter()
        .chain(&sh.cw_plines)
        .map(|ip| {
            let mut p = fix_tight_arcs(from_polyline(&ip.polyline, r.z), r, d, f.rmin, f.sag);
            if let (Some(s), Some(last)) = (p.first().map(Segment::start), p.last_mut()) {
                last.set_end(s);
            }
            p
        })
        .filter(|p| !p.is_empty())
        .collect()
}

/// Rotate a closed ring to start at its vertex nearest `q`.
fn start_near(path: &mut [Segment], q: P2) {
    let best = (0..path.len()).min_by(|&a, &b| {
        let da = (path[a].start().xy() - q).norm();
        let db = (path[b].start().xy() - q).norm();
        da.total_cmp(&db).then(a.cmp(&b))
    });
    if let Some(k) = best {
        path.rotate_left(k);
    }
}

/// Offset passes: rings at the beam radius, then one stepover further in
/// each pass until the region is used up; within a pass the ring nearest
/// to where the last one ended comes next.
fn offset_runs(r: &Region, o: &FillOptions, f: &Fix) -> Vec<Vec<Segment>> {
    let mut runs = Vec::new();
    let mut here = first_vertex(r).unwrap_or(r.lo);
    for k in 0u64.. {
        let d = o.beam_radius + k as f64 * o.stepover;
        let mut rings = rings_at(r, d, f);
        if rings.is_empty() {
            break;
        }
        while !rings.is_empty() {
            let dist = |p: &Vec<Segment>| {
                p.iter()
                    .map(|e| (e.start().xy() - here).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            let i = (0..rings.len())
                .min_by(|&a, &b| dist(&rings[a]).total_cmp(&dist(&rings[b])).then(a.cmp(&b)))
                .expect("non-empty");
            let mut ring = rings.swap_remove(i);
            start_near(&mut ring, here);
            here = ring[0].start().xy();
            runs.push(ring);
        }
    }
    runs
}

/// A piece of the shrunk boundary that is monotone across the hatch lines:
/// its value of n·p at both ends and how to find a crossing inside.
struct Mono {
    elem: Segment,
    t0: f64,
    t1: f64,
    v0: f64,
    v1: f64,
}

fn point_at(e: &Segment, t: f64) -> P2 {
    match e {
        Segment::Line(l) => (l.start + (l.end - l.start) * t).xy(),
        Segment::Arc(a) => a.point_at(t).xy(),
    }
}

/// Split the boundary pieces where n·p turns (arcs at their extreme
/// points across the lines).
fn monotone_pieces(elems: &[Segment], n: V2) -> Vec<Mono> {
    let val = |p: P2| n.x * p.x + n.y * p.y;
    let mut out = Vec::new();
    for e in elems {
        let mut ts = vec![0.0, 1.0];
        if let Some(arc) = e.to_arc_xy() {
            let phi = n.y.atan2(n.x);
            for th in [phi, phi + std::f64::consts::PI] {
                let t = arc.angle_offset(th) / arc.sweep.abs();
                if t > 1e-12 && t < 1.0 - 1e-12 {
                    ts.push(t);
                }
            }
            ts.sort_by(f64::total_cmp);
        }
        let pts: Vec<f64> = ts.iter().map(|&t| val(point_at(e, t))).collect();
        for k in 0..ts.len() - 1 {
            out.push(Mono {
                elem: *e,
                t0: ts[k],
                t1: ts[k + 1],
                v0: pts[k],
                v1: pts[k + 1],
            });
        }
    }
    out
}

/// Hatch lines clipped to the region shrunk by the beam radius, zigzag,
/// then (with `outline`) the shrunk boundary itself.
fn hatch_runs(r: &Region, o: &FillOptions, f: &Fix) -> Vec<Vec<Segment>> {
    let sh = r.shape.parallel_offset(o.beam_radius, &offset_options());
    if sh.ccw_plines.is_empty() {
        return Vec::new();
    }
    let boundary: Vec<Segment> = sh
        .ccw_plines
        .iter()
        .chain(&sh.cw_plines)
        .flat_map(|ip| from_polyline(&ip.polyline, r.z))
        .collect();
    let a = o.angle_deg.to_radians();
    let (u, n) = (V2::new(a.cos(), a.sin()), V2::new(-a.sin(), a.cos()));
    let pieces = monotone_pieces(&boundary, n);
    let (lo, hi) = pieces.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), m| {
        (lo.min(m.v0).min(m.v1), hi.max(m.v0).max(m.v1))
    });
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return Vec::new();
    }
    let s = o.stepover;
    let count = ((hi - lo) / s).floor() as usize + 1;
    let c0 = lo + 0.5 * ((hi - lo) - (count - 1) as f64 * s);
    let c = |j: usize| c0 + j as f64 * s;
    let mut cross: Vec<Vec<f64>> = vec![Vec::new(); count];
    for m in &pieces {
        let (a, b) = (m.v0.min(m.v1), m.v0.max(m.v1));
        // Half-open: a piece crosses line c when a < c <= b, so a vertex on
        // a line counts once.
        let j0 = (((a - c0) / s).floor().max(0.0) as usize).min(count);
        let j1 = (((b - c0) / s).floor().max(-1.0) + 1.0).max(0.0) as usize;
        #[allow(clippy::needless_range_loop)] // j is the line's index and its position
        for j in j0..j1.min(count) {
            let cj = c(j);
            if !(a < cj && cj <= b) {
                continue;
            }
            let p = match m.elem {
                Segment::Line(_) => {
                    let t = m.t0 + (m.t1 - m.t0) * (cj - m.v0) / (m.v1 - m.v0);
                    point_at(&m.elem, t)
                }
                Segment::Arc(_) => {
                    // n·p is monotone on [t0, t1]: bisect.
                    let (mut x, mut y) = (m.t0, m.t1);
                    let up = m.v1 > m.v0;
                    for _ in 0..64 {
                        let mid = 0.5 * (x + y);
                        let v = n.dot(&point_at(&m.elem, mid).coords);
                        if (v < cj) == up { x = mid } else { y = mid }
                    }
                    point_at(&m.elem, 0.5 * (x + y))
                }
            };
            cross[j].push(u.dot(&p.coords));
        }
    }
    let at = |t: f64, cj: f64| {
        let p = u * t + n * cj;
        P3::new(p.x, p.y, r.z)
    };
    let mut runs = Vec::new();
    let mut forward = true;
    for (j, xs) in cross.iter_mut().enumerate() {
        xs.sort_by(f64::total_cmp);
        if xs.len() % 2 == 1 {
            // A line grazing a vertex numerically: no reliable inside.
            continue;
        }
        let mut lines: Vec<Segment> = xs
            .chunks(2)
            .filter(|w| w[1] - w[0] > 1e-9)
            .map(|w| Segment::line(at(w[0], c(j)), at(w[1], c(j))))
            .collect();
        if lines.is_empty() {
            continue;
        }
        if !forward {
            lines.reverse();
            for l in &mut lines {
                *l = l.reversed();
            }
        }
        forward = !forward;
        runs.extend(lines.into_iter().map(|l| vec![l]));
    }
    if o.outline {
        let mut here = runs
            .last()
            .and_then(|r: &Vec<Segment>| r.last())
            .map_or(r.lo, |e| e.end().xy());
        for mut ring in rings_at(r, o.beam_radius, f) {
            start_near(&mut ring, here);
            here = ring[0].start().xy();
            runs.push(ring);
        }
    }
    runs
}

/// Split a run at its corners (joints the planner loops) and drop the
/// stretches shorter than the shutter's minimum exposure: it cannot expose
/// them reliably. Counts what was dropped in `dropped` (stretches, mm).
fn drop_short(run: Vec<Segment>, m: &LaserSetup, dropped: &mut (usize, f64)) -> Vec<Vec<Segment>> {
    let n = run.len();
    if n == 0 {
        return Vec::new();
    }
    let min = m.min_cut();
    let cos = m.tangent_cos();
    let corner = |a: &Segment, b: &Segment| a.end_tangent().dot(&b.start_tangent()) < cos;
    let mut starts = vec![0];
    starts.extend((1..n).filter(|&i| corner(&run[i - 1], &run[i])));
    let mut stretches: Vec<Vec<(usize, usize)>> = starts
        .iter()
        .enumerate()
        .map(|(k, &a)| vec![(a, starts.get(k + 1).copied().unwrap_or(n))])
        .collect();
    let closed = (run[0].start() - run[n - 1].end()).norm() < 1e-9;
    if closed && stretches.len() > 1 && !corner(&run[n - 1], &run[0]) {
        // The seam is smooth: the last stretch runs on into the first.
        let first = stretches.remove(0);
        stretches.last_mut().expect("more than one").extend(first);
    }
    let lens: Vec<f64> = stretches
        .iter()
        .map(|v| v.iter().flat_map(|&(a, b)| &run[a..b]).map(Segment::length).sum())
        .collect();
    let Some(j) = lens.iter().position(|&l| l < min) else {
        return vec![run];
    };
    let k = stretches.len();
    // A closed run restarts after a dropped stretch, so what is kept stays
    // in one piece where it can.
    let order: Vec<usize> = if closed {
        (1..=k).map(|i| (j + i) % k).collect()
    } else {
        (0..k).collect()
    };
    let mut out = Vec::new();
    let mut cur: Vec<Segment> = Vec::new();
    for i in order {
        if lens[i] < min {
            dropped.0 += 1;
            dropped.1 += lens[i];
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
        } else {
            for &(a, b) in &stretches[i] {
                cur.extend_from_slice(&run[a..b]);
            }
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Fold pieces shorter than the controller's least block (1 ms at V) into
/// a neighbouring line: a Turbo PMAC would stretch such a block and slow
/// down there. Pieces inside a stretch meet tangentially (within the
/// tangency tolerance), so the line barely turns.
fn merge_tiny(run: Vec<Segment>, min_block: f64, rmin: f64) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::with_capacity(run.len());
    let mut pending: Option<Segment> = None;
    for e in run {
        let e = match pending.take() {
            // A tiny piece before this line: the line starts earlier.
            Some(t) => match e {
                Segment::Line(_) => Segment::line(t.start(), e.end()),
                _ => match extend_arc(&e.reversed(), t.start(), rmin) {
                    Some(a) => a.reversed(),
                    None => {
                        out.push(t);
                        e
                    }
                },
            },
            None => e,
        };
        if e.length() >= min_block {
            out.push(e);
            continue;
        }
        match out.last_mut() {
            Some(prev @ Segment::Line(_)) => *prev = Segment::line(prev.start(), e.end()),
            Some(prev) => match extend_arc(prev, e.end(), rmin) {
                Some(a) => *prev = a,
                None => out.push(e),
            },
            None => pending = Some(e),
        }
    }
    if let Some(t) = pending {
        out.push(t);
    }
    out
}

/// The arc leaving where `e` (an arc) starts, along its start direction,
/// and ending at `to`: `e` extended over a tiny piece that follows it.
/// None when that arc would be tighter than `rmin` or is degenerate.
fn extend_arc(e: &Segment, to: P3, rmin: f64) -> Option<Segment> {
    let Segment::Arc(_) = e else { return None };
    let a = e.start();
    let t = e.start_tangent();
    let n = crate::geometry::V3::new(-t.y, t.x, 0.0);
    let d = to - a;
    let den = 2.0 * n.dot(&d);
    if den.abs() < 1e-15 {
        return None;
    }
    let rho = d.norm_squared() / den;
    let arc = crate::geometry::arc::Arc3::new(a + n * rho, a, to, rho > 0.0, Plane::Xy, 0)?;
    (arc.radius() >= rmin * (1.0 - 1e-9)).then_some(Segment::Arc(arc))
}

/// Join runs of cut pieces into beam-off-linked paths: a Dubins link at
/// V from the end of one run to the start of the next, in the stage's
/// least radius and long enough for the shutter. Where no link exists the
/// path ends and the next starts (a rapid between).
fn join_runs(runs: Vec<Vec<Segment>>, m: &LaserSetup, dropped: &mut (usize, f64)) -> Vec<Tagged> {
    let r = m.min_radius();
    let shape = m.connection_shape();
    let xy = |v: crate::geometry::V3| V2::new(v.x, v.y);
    let mut paths = Vec::new();
    let mut cur: Tagged = Vec::new();
    let runs: Vec<Vec<Segment>> = runs
        .into_iter()
        .flat_map(|r| drop_short(r, m, dropped))
        .map(|r| merge_tiny(r, m.min_block(), m.min_radius()))
        .collect();
    for run in runs {
        let Some(first) = run.first() else { continue };
        if let Some((last, _)) = cur.last() {
            let (din, dout) = (xy(last.end_tangent()), xy(first.start_tangent()));
            let link = (din.norm() > 1e-12 && dout.norm() > 1e-12)
                .then(|| {
                    connect(
                        last.end(),
                        din.normalize(),
                        first.start(),
                        dout.normalize(),
                        r,
                        shape,
                        Plane::Xy,
                    )
                })
                .flatten();
            match link {
                Some(link) => {
                    // A turn whose ends (almost) coincide is either a sliver
                    // or a whole loop, and a toolpath reader cannot tell
                    // which: drop a sliver, write a loop as two halves.
                    let mut at = last.end();
                    for e in link {
                        let pieces = match e {
                            Segment::Arc(_) if (e.end() - e.start()).norm() < 1e-6 => {
                                match e.split_at_length(0.5 * e.length(), super::elem::MIN_PIECE) {
                                    Some((a, b)) if e.length() > 1e-6 => vec![a, b],
                                    _ => Vec::new(),
                                }
                            }
                            _ => vec![e],
                        };
                        for mut p in pieces {
                            p.set_start(at);
                            at = p.end();
                            cur.push((p, Role::Link));
                        }
                    }
                }
                None => paths.push(std::mem::take(&mut cur)),
            }
        }
        cur.extend(run.into_iter().map(|e| (e, Role::Cut)));
    }
    if !cur.is_empty() {
        paths.push(cur);
    }
    paths
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
        Pattern::Offset => offset_runs(r, o, &f),
        Pattern::Hatch => hatch_runs(r, o, &f),
    }
}

/// The paths of one region: its passes, less the stretches shorter than
/// the shutter's minimum exposure (counted in `dropped`: stretches, mm),
/// joined by beam-off links.
pub fn region_paths(r: &Region, m: &LaserSetup, o: &FillOptions, dropped: &mut (usize, f64)) -> Vec<Tagged> {
    join_runs(region_runs(r, o, m.min_radius()), m, dropped)
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

/// Plan a whole fill job.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::laser::audit::{audit, feed_elem};
    use crate::model::toolpath::MotionKind;

    fn poly(id: u64, pts: &[(f64, f64)], z: f64) -> Chain {
        let p: Vec<P3> = pts.iter().map(|&(x, y)| P3::new(x, y, z)).collect();
        Chain {
            id,
            closed: true,
            segments: (0..p.len())
                .map(|i| Segment::line(p[i], p[(i + 1) % p.len()]))
                .collect(),
            ..Default::default()
        }
    }

    fn circle(id: u64, c: (f64, f64), r: f64, z: f64, ccw: bool) -> Chain {
        let s = P3::new(c.0 + r, c.1, z);
        Chain {
            id,
            closed: true,
            segments: vec![Segment::arc_xy(s, s, P3::new(c.0, c.1, z), ccw)],
            ..Default::default()
        }
    }

    /// An L-shaped plate (a reflex corner) with a round hole, a triangular
    /// hole, and a rounded convex corner; drawn clockwise to check that
    /// orientation does not matter.
    fn plate(z: f64) -> Vec<Chain> {
        let mut outer = poly(
            1,
            &[(0.0, 0.0), (0.0, 1.2), (0.6, 1.2), (0.6, 0.6), (1.4, 0.6), (1.4, 0.0)],
            z,
        );
        outer.segments.reverse();
        for s in &mut outer.segments {
            *s = s.reversed();
        }
        vec![
            outer,
            circle(2, (0.3, 0.3), 0.12, z, true),
            poly(3, &[(0.9, 0.15), (1.2, 0.15), (1.05, 0.45)], z),
        ]
    }

    fn setup(min_exposure_ms: f64) -> LaserSetup {
        LaserSetup {
            min_exposure_ms,
            ..LaserSetup::default().with_accel(200.0)
        }
    }

    /// Cut moves as exact pieces.
    fn cuts(recs: &[Record]) -> Vec<Segment> {
        let mut pos = P3::origin();
        let mut out = Vec::new();
        for mv in recs.iter().filter_map(Record::motion) {
            if mv.role == Some(Role::Cut)
                && let Some(e) = feed_elem(pos, mv)
            {
                out.push(e);
            }
            pos = mv.to;
        }
        out
    }

    fn dist(e: &Segment, p: &P3) -> f64 {
        match e {
            Segment::Line(l) => l.distance(p),
            Segment::Arc(a) => a.distance(p).unwrap_or(f64::INFINITY),
        }
    }

    /// Signed distance to the region of `chains` (positive inside the outer
    /// and outside the holes), exact on lines and arcs.
    fn inside_distance(chains: &[Chain], p: &P3) -> f64 {
        let d = chains
            .iter()
            .flat_map(super::super::offset::chain_elems)
            .map(|e| dist(&e, p))
            .fold(f64::INFINITY, f64::min);
        let q = Vector2::new(p.x, p.y);
        let inside_outer = to_polyline(&chains[0]).winding_number(q) != 0;
        let in_hole = chains[1..].iter().any(|c| to_polyline(c).winding_number(q) != 0);
        if inside_outer && !in_hole { d } else { -d }
    }

    /// Largest distance from a grid point of the region to the nearest cut
    /// (cuts bucketed on a grid of `cell`).
    fn coverage(chains: &[Chain], cut: &[Segment], step: f64) -> f64 {
        let cell = 0.05;
        let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
        let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
        for (i, e) in cut.iter().enumerate() {
            let (a, b) = (e.start(), e.end());
            let r = if let Segment::Arc(x) = e { x.radius() } else { 0.0 };
            let (lo, hi) = (
                key(a.x.min(b.x) - r, a.y.min(b.y) - r),
                key(a.x.max(b.x) + r, a.y.max(b.y) + r),
            );
            for gx in lo.0..=hi.0 {
                for gy in lo.1..=hi.1 {
                    grid.entry((gx, gy)).or_default().push(i);
                }
            }
        }
        let mut worst: f64 = 0.0;
        let n = (1.5 / step) as i64;
        for i in 0..=n {
            for j in 0..=n {
                let p = P3::new(i as f64 * step, j as f64 * step, chains[0].segments[0].start().z);
                if inside_distance(chains, &p) < 0.0 {
                    continue;
                }
                let k = key(p.x, p.y);
                let mut best = f64::INFINITY;
                for gx in k.0 - 1..=k.0 + 1 {
                    for gy in k.1 - 1..=k.1 + 1 {
                        for &e in grid.get(&(gx, gy)).into_iter().flatten() {
                            best = best.min(dist(&cut[e], &p));
                        }
                    }
                }
                worst = worst.max(best);
            }
        }
        worst
    }

    fn options(pattern: Pattern, outline: bool) -> FillOptions {
        FillOptions {
            pattern,
            beam_radius: 0.005,
            stepover: 0.01,
            angle_deg: 30.0,
            outline,
            ..Default::default()
        }
    }

    #[test]
    fn every_point_of_the_region_is_within_a_stepover_of_a_cut() {
        let chains = plate(0.0);
        let m = setup(0.0);
        for (pattern, outline) in [(Pattern::Offset, false), (Pattern::Hatch, true)] {
            let o = options(pattern, outline);
            let job = fill(&chains, &m, &o).unwrap();
            let cut = cuts(&job.records);
            assert!(!cut.is_empty());
            let worst = coverage(&chains, &cut, 0.004);
            // The stepover, plus a quarter of it where a tight arc became
            // chords.
            assert!(worst <= 1.25 * o.stepover + 1e-9, "{pattern:?}: {worst}");
            // Every cut stays a beam radius inside (less the chords' sag):
            // the beam never leaves the region nor enters a hole.
            let mut least = f64::INFINITY;
            for e in &cut {
                for k in 0..=8 {
                    let p = e.point_at_length(e.length() * k as f64 / 8.0);
                    least = least.min(inside_distance(&chains, &p));
                }
            }
            assert!(least >= 0.75 * o.beam_radius - 1e-9, "{pattern:?}: {least}");
        }
    }

    #[test]
    fn hatch_without_outline_covers_the_inside() {
        let chains = plate(0.0);
        let o = options(Pattern::Hatch, false);
        let job = fill(&chains, &setup(0.0), &o).unwrap();
        let cut = cuts(&job.records);
        // Lines only: parallel, stepover apart, each in one piece.
        for e in &cut {
            let d = e.start_tangent();
            assert!((d.y.atan2(d.x).to_degrees().rem_euclid(180.0) - 30.0).abs() < 1e-6);
        }
        assert!(coverage(&chains, &cut, 0.01) < 0.1);
    }

    #[test]
    fn fill_output_obeys_the_machine() {
        let chains = plate(-0.02);
        for m in [
            setup(15.0),
            LaserSetup::default(),
            LaserSetup {
                controller: crate::machine::Controller::Lookahead,
                ..setup(15.0)
            },
        ] {
            for (pattern, outline) in [
                (Pattern::Offset, false),
                (Pattern::Hatch, false),
                (Pattern::Hatch, true),
            ] {
                let o = options(pattern, outline);
                let job = fill(&chains, &m, &o).unwrap();
                let a = audit(&job.records, &m, P3::origin());
                let what = format!("{pattern:?} outline {outline} {:?}", m.controller);
                assert_eq!(a.off_feed_moves, 0, "{what}");
                assert_eq!(a.corners_at_speed, 0, "{what}");
                assert_eq!(a.beam_on_rapids, 0, "{what}");
                assert!(
                    a.max_accel_off_cut <= m.accel() * (1.0 + 1e-9),
                    "{what}: {}",
                    a.max_accel_off_cut
                );
                // The passes themselves, too: no arc tighter than V²/a.
                assert!(
                    a.max_accel_cut <= m.accel() * (1.0 + 1e-9),
                    "{what}: {}",
                    a.max_accel_cut
                );
                let off = job.warnings.iter().any(|w| w.message.contains("shutter switch"));
                let tol = if off { m.feed / 1000.0 + 1e-6 } else { 1e-6 };
                assert!(a.exposure_error < tol, "{what}: {}", a.exposure_error);
                assert!(a.min_run_before_open >= m.accel_distance() - 1e-9, "{what}");
                assert!(a.min_run_after_close >= -1e-9, "{what}");
                assert_eq!(a.stretched_moves, 0, "{what}");
                // Every move at the chains' Z, beam-on moves only on cuts'
                // paths (no rapid carries the beam).
                for mv in job.records.iter().filter_map(Record::motion) {
                    assert!((mv.to.z + 0.02).abs() < 1e-12, "{what}: {mv:?}");
                    if mv.kind == MotionKind::Rapid {
                        assert!(!mv.beam);
                    }
                }
            }
        }
    }

    #[test]
    fn levels_are_kept_apart_and_in_input_order() {
        let mut chains = plate(0.0);
        let mut lower = plate(-0.5);
        for (i, c) in lower.iter_mut().enumerate() {
            c.id = 10 + i as u64;
        }
        chains.extend(lower);
        let o = options(Pattern::Offset, false);
        let p = prepare(&chains, &o).unwrap();
        assert_eq!(p.regions.len(), 2);
        assert_eq!((p.regions[0].z, p.regions[1].z), (0.0, -0.5));
        assert_eq!((p.regions[0].holes, p.regions[1].holes), (2, 2));
        let job = fill(&chains, &setup(15.0), &o).unwrap();
        let zs: Vec<f64> = job.records.iter().filter_map(Record::motion).map(|m| m.to.z).collect();
        let first_low = zs.iter().position(|&z| z == -0.5).unwrap();
        assert!(zs[..first_low].iter().all(|&z| z == 0.0));
        assert!(zs[first_low..].iter().all(|&z| z == -0.5));
        assert_eq!(fill(&chains, &setup(15.0), &o).unwrap().records, job.records);
    }

    #[test]
    fn bad_inputs_are_refused() {
        let o = FillOptions::default();
        let mut open = poly(1, &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 0.0);
        open.closed = false;
        assert_eq!(prepare(&[open], &o).unwrap_err(), FillError::NoClosed(1));
        assert_eq!(prepare(&[], &o).unwrap_err(), FillError::NoClosed(0));
        let flat = poly(2, &[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)], 0.0);
        assert_eq!(prepare(&[flat], &o).unwrap_err(), FillError::Empty);
        let mut nan = poly(3, &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], 0.0);
        nan.segments[1] = Segment::line(P3::new(1.0, 0.0, 0.0), P3::new(f64::NAN, 1.0, 0.0));
        assert_eq!(prepare(&[nan], &o).unwrap_err(), FillError::NotFinite(3));
        let sq = poly(4, &[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)], 0.0);
        let tiny = FillOptions {
            stepover: 1e-9,
            ..FillOptions::default()
        };
        match prepare(std::slice::from_ref(&sq), &tiny).unwrap_err() {
            FillError::TooBig { passes, moves, .. } => assert!(passes > 1_000_000_000 && moves > passes),
            e => panic!("{e}"),
        }
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let o = FillOptions {
                stepover: bad,
                ..FillOptions::default()
            };
            assert!(matches!(
                prepare(std::slice::from_ref(&sq), &o),
                Err(FillError::NotPositive(..))
            ));
        }
    }

    #[test]
    fn a_region_narrower_than_the_beam_makes_nothing_and_says_so() {
        let thin = poly(5, &[(0.0, 0.0), (1.0, 0.0), (1.0, 0.004), (0.0, 0.004)], 0.0);
        let job = fill(&[thin], &setup(15.0), &FillOptions::default()).unwrap();
        assert!(cuts(&job.records).is_empty());
        assert!(
            job.warnings
                .iter()
                .any(|w| w.message.contains("narrower than the beam"))
        );
    }
}
