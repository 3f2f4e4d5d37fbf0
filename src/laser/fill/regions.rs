//! From chains to regions: levels by Z, nesting by containment (outer
//! boundaries counter-clockwise, their holes clockwise), nearest-neighbour
//! order, and the work estimate a job is admitted on.

use super::{Estimate, FillError, FillOptions, Pattern, Prepared, Region};
use crate::geometry::P2;
use crate::laser::contour::Warning;
use crate::laser::offset::to_polyline;
use crate::laser::order;
use crate::model::chain::{Chain, Segment};
use cavalier_contours::core::Control;
use cavalier_contours::core::math::Vector2;
use cavalier_contours::polyline::{
    PlineIntersect, PlineSelfIntersectOptions, PlineSource, PlineSourceMut, Polyline, SelfIntersectsInclude,
};
use cavalier_contours::shape_algorithms::Shape;
use rayon::prelude::*;

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
    // The first chain that crosses itself, to name when nothing is left.
    let mut crossing = None;
    for (z, level) in &levels {
        let mut rs = nest_level(level, *z, &mut warnings, &mut crossing);
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
        return Err(match crossing {
            Some((chain, p)) => FillError::Crosses { chain, x: p.x, y: p.y },
            None => FillError::Empty,
        });
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

/// The first vertex of the region's outer boundary: where the region
/// stands in the cut order, and near where its first ring starts.
pub(super) fn first_vertex(r: &Region) -> Option<P2> {
    r.shape.ccw_plines.first().and_then(|p| {
        (p.polyline.vertex_count() > 0).then(|| {
            let v = p.polyline.at(0);
            P2::new(v.x, v.y)
        })
    })
}

/// Where a closed polyline crosses or touches itself (the first such
/// point found), if it does: between pieces that do not share a joint, so
/// a chain folded back on itself along a line is not a crossing (it
/// encloses no area, and is said so).
fn self_crossing(pl: &Polyline<f64>) -> Option<P2> {
    let mut at = None;
    let mut opts = PlineSelfIntersectOptions::new();
    opts.include = SelfIntersectsInclude::Global;
    let _: Control<()> = pl.visit_self_intersects_opt(
        &mut |i: PlineIntersect<f64>| {
            let p = match i {
                PlineIntersect::Basic(b) => b.point,
                PlineIntersect::Overlapping(o) => o.point1,
            };
            at = Some(P2::new(p.x, p.y));
            Control::Break(())
        },
        &opts,
    );
    at
}

/// Regions of one level: containment by winding number about each
/// chain's first vertex (boxes first).
fn nest_level(level: &[&Chain], z: f64, warnings: &mut Vec<Warning>, crossing: &mut Option<(u64, P2)>) -> Vec<Region> {
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
        if let Some(p) = self_crossing(&pl) {
            // Sections of real meshes and drawings touch themselves at a
            // point often enough, and fill well; but where a boundary
            // crosses itself, cavalier_contours' offsets fill only the
            // loops turning with the chain's net direction (none when they
            // cancel, as in a bow tie). Said, not refused.
            warnings.push(Warning {
                chain: c.id,
                message: format!(
                    "closed chain crosses or touches itself at ({:.6}, {:.6}): a loop of it turning against \
                     the rest is left uncut",
                    p.x, p.y
                ),
            });
            crossing.get_or_insert((c.id, p));
        }
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
