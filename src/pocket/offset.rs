//! Contour-parallel pocketing of the same boundary, for comparison with
//! the grid: inward offsets of the boundary at the tool radius, then every
//! stepover further in (exact lines and arcs through cavalier_contours,
//! written as polygons inside the exact loops, see
//! [`super::grid::polygonize`]), cut from the innermost loop outward so the
//! last loop finishes the wall. Heights follow the surface the same way as
//! the grid's passes; consecutive loops are joined by a feed move when
//! the straight link stays in the tool-centre region ("linked inside the
//! pocket"), by a retract otherwise.

use super::contact::Contact;
use super::grid::{Region, ccw, polygonize};
use super::passes::{Pass, PassKind, closed_loop_from_nearest, lift};
use crate::geometry::P2;
use cavalier_contours::polyline::{PlineSource, Polyline};

/// The loops, innermost first, each starting at the vertex nearest the
/// previous loop's start; `pitch` densifies them so heights follow the
/// surface.
pub fn offset_passes(c: &Contact, boundary: &Polyline<f64>, stepover: f64, pitch: f64) -> Vec<Pass> {
    let b = ccw(boundary.clone());
    let r = c.cutter.radius();
    let mut rings: Vec<Vec<P2>> = Vec::new();
    for k in 0..100_000usize {
        let d = r + stepover * k as f64;
        let loops: Vec<Vec<P2>> = b
            .parallel_offset(d)
            .into_iter()
            .filter(|p| p.is_closed() && p.area().abs() > 1e-12)
            .map(|p| polygonize(&ccw(p)))
            .filter(|l| l.len() >= 3)
            .collect();
        if loops.is_empty() {
            break;
        }
        rings.extend(loops);
    }
    rings.reverse();
    let mut out = Vec::new();
    let mut near: Option<P2> = None;
    for l in rings {
        let (xy, start) = closed_loop_from_nearest(&l, near, pitch);
        near = Some(start);
        out.push(Pass {
            kind: PassKind::Offset,
            pts: lift(c, &xy),
            runs: Vec::new(),
        });
    }
    out
}

/// True when the straight XY link from `a` to `b` stays in `region`.
pub fn link_inside(region: &Region, a: P2, b: P2) -> bool {
    region.segment_inside(a, b)
}
