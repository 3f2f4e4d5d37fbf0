//! Hatch passes: parallel lines at an angle, a stepover apart, clipped to
//! the region shrunk by the beam radius and run zigzag, optionally followed
//! by the shrunk outline.

use super::rings::{offset_options, rings_at, start_near};
use super::{FillOptions, Fix, Region};
use crate::geometry::{P2, P3, V2};
use crate::laser::offset::from_polyline;
use crate::model::chain::Segment;

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
pub(super) fn hatch_runs(r: &Region, o: &FillOptions, f: &Fix) -> Vec<Vec<Segment>> {
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
