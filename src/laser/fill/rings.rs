//! Contour-parallel passes: the region offset inward by the beam radius,
//! then one stepover further each pass, with the arcs too tight for the
//! stage at V made into mitres or chords.

use super::regions::first_vertex;
use super::{FillOptions, Fix, Region};
use crate::geometry::arc::chord_angle;
use crate::geometry::{P2, P3};
use crate::laser::offset::{continue_line, from_polyline, join_closed_ends};
use crate::model::chain::Segment;
use cavalier_contours::core::math::Vector2;
use cavalier_contours::polyline::{PlineSource, seg_closest_point};
use cavalier_contours::shape_algorithms::ShapeOffsetOptions;

/// cavalier_contours' offset tolerances, for the sizes of micromachining.
pub(super) fn offset_options() -> ShapeOffsetOptions<f64> {
    // Micromachining sizes: positions equal within 1 nm, not 10 µm.
    ShapeOffsetOptions {
        pos_equal_eps: 1e-8,
        offset_dist_eps: 1e-7,
        slice_join_eps: 1e-7,
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
        // Chords: each spans at most 2·acos(1 - sag/r) of the arc, and at
        // most half a turn.
        let span = chord_angle(rad, sag).min(std::f64::consts::PI);
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
pub(super) fn rings_at(r: &Region, d: f64, f: &Fix) -> Vec<Vec<Segment>> {
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

/// Rotate a closed ring to start at its vertex nearest `q` (the contour
/// planner's rule, so filled rings and contours start alike).
pub(super) fn start_near(path: &mut [Segment], q: P2) {
    crate::laser::contour::start_near(path, &q);
}

/// Offset passes: rings at the beam radius, then one stepover further in
/// each pass until the region is used up; within a pass the ring nearest
/// to where the last one ended comes next.
pub(super) fn offset_runs(r: &Region, o: &FillOptions, f: &Fix) -> Vec<Vec<Segment>> {
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
