//! Orientation by nesting depth: which closed chains lie inside which,
//! through a grid over their boxes and exact point-in-chain tests (arcs
//! included, no tessellation).

use super::{ChainReport, Chains, midpoint};
use crate::geometry::{P3, floor_i64};
use crate::model::chain::Segment;
use rayon::prelude::*;

/// Point in a closed chain: the parity of crossings of the ray from `p`
/// towards +X, with lines and arcs exactly (no tessellation, so memory
/// does not grow with arc counts).
fn inside(segs: &[Segment], p: &P3) -> bool {
    let mut c = false;
    for s in segs {
        match s.to_arc_xy() {
            None => {
                let (a, b) = (s.start(), s.end());
                if (a.y > p.y) != (b.y > p.y) {
                    let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
                    if x > p.x {
                        c = !c;
                    }
                }
            }
            Some(arc) => {
                let (center, r, end) = (arc.center, arc.radius, s.end());
                let dy = p.y - center.y;
                if dy.abs() >= r {
                    continue;
                }
                let dx = (r * r - dy * dy).sqrt();
                for x in [center.x - dx, center.x + dx] {
                    if x > p.x && arc.contains_angle(dy.atan2(x - center.x)) {
                        // Half-open at the arc's end, so a crossing exactly
                        // at a shared vertex counts once.
                        let at_end = (P3::new(x, p.y, end.z) - end).xy().norm() <= 1e-12 * r.max(1.0);
                        if !at_end {
                            c = !c;
                        }
                    }
                }
            }
        }
    }
    c
}

pub use crate::geometry::segment::signed_area;

/// The XY box of a closed chain (arcs included exactly: their ends and the
/// axis extremes they pass) and its signed area, the same arithmetic as
/// [`signed_area`], with each arc's angles computed once for both.
/// `quarter` holds (cos, sin) of 0, pi/2, pi and 3 pi/2.
fn box_and_area(segs: &[Segment], quarter: &[(f64, f64); 4]) -> ((f64, f64), (f64, f64), f64) {
    let mut lo = (f64::INFINITY, f64::INFINITY);
    let mut hi = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut area = 0.0;
    for s in segs {
        let (p, q) = (s.start(), s.end());
        lo = (lo.0.min(p.x), lo.1.min(p.y));
        hi = (hi.0.max(p.x), hi.1.max(p.y));
        lo = (lo.0.min(q.x), lo.1.min(q.y));
        hi = (hi.0.max(q.x), hi.1.max(q.y));
        area += 0.5 * (p.x * q.y - q.x * p.y);
        if let Some(a) = s.to_arc_xy() {
            for (k, &(c, sn)) in quarter.iter().enumerate() {
                let t = k as f64 * std::f64::consts::FRAC_PI_2;
                if a.contains_angle(t) {
                    let (x, y) = (a.center.x + a.radius * c, a.center.y + a.radius * sn);
                    lo = (lo.0.min(x), lo.1.min(y));
                    hi = (hi.0.max(x), hi.1.max(y));
                }
            }
            let (dx, dy) = (p.x - a.center.x, p.y - a.center.y);
            let r2 = dx * dx + dy * dy;
            area += 0.5 * r2 * (a.sweep - a.sweep.sin());
        }
    }
    (lo, hi, area)
}

/// Orient closed chains by nesting depth: even depth (outer contours)
/// counter-clockwise, odd depth (holes) clockwise.
pub(super) fn orient(chains: &mut Chains, tol: f64, report: &mut ChainReport) {
    struct Info {
        idx: usize,
        lo: (f64, f64),
        hi: (f64, f64),
        area: f64,
        probe: P3,
    }
    let quarter: [(f64, f64); 4] = std::array::from_fn(|k| {
        let t = k as f64 * std::f64::consts::FRAC_PI_2;
        (t.cos(), t.sin())
    });
    // Each chain's box, area and probe on its own: in parallel, in order.
    let infos: Vec<Info> = chains
        .items
        .par_iter()
        .enumerate()
        .filter(|(_, it)| it.closed && it.len > 0)
        .map_init(Vec::new, |buf: &mut Vec<Segment>, (idx, it)| {
            chains.segments_into(it, buf);
            let (lo, hi, area) = box_and_area(buf, &quarter);
            Info {
                idx,
                lo,
                hi,
                area,
                probe: midpoint(&buf[0]),
            }
        })
        .collect();
    crate::progress::lap("orient: infos");
    if infos.is_empty() {
        return;
    }
    // A grid over the boxes: each chain is listed in the cells its box
    // covers (or in `big` when that would be too many cells).
    let total: f64 = infos
        .iter()
        .map(|i| (i.hi.0 - i.lo.0).max(tol) * (i.hi.1 - i.lo.1).max(tol))
        .sum();
    let size = (total / infos.len() as f64).sqrt().max(1e-9);
    // Each chain is listed under the cells its box covers (or in `big`
    // when that would be too many cells), in compressed rows by a hash of
    // the cell: two passes over the boxes, where sorting the (cell, chain)
    // pairs was a fifth of the orientation's time on the mix benchmark,
    // and each probe goes straight to its row. A row holds the pairs of
    // every cell that hashes to it, in chain order; a probe takes those of
    // its own cell.
    let ckey = |x: i64, y: i64| ((x as u32 as u64) << 32) | (y as u32 as u64);
    let cells: Vec<Option<(i64, i64, i64, i64)>> = infos
        .par_iter()
        .map(|i| {
            let (x0, y0) = (floor_i64(i.lo.0 / size), floor_i64(i.lo.1 / size));
            let (x1, y1) = (floor_i64(i.hi.0 / size), floor_i64(i.hi.1 / size));
            // In i128: far-out boxes (the casts saturate) must not wrap
            // into a small, or a huge, cell range.
            let n = (x1 as i128 - x0 as i128 + 1) * (y1 as i128 - y0 as i128 + 1);
            (1..=256).contains(&n).then_some((x0, x1, y0, y1))
        })
        .collect();
    let pairs: usize = cells
        .iter()
        .flatten()
        .map(|&(x0, x1, y0, y1)| ((x1 - x0 + 1) * (y1 - y0 + 1)) as usize)
        .sum();
    let rows = pairs.max(2).next_power_of_two();
    let shift = 64 - rows.trailing_zeros();
    let row_of = |key: u64| (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> shift) as usize;
    let mut start = vec![0u32; rows + 1];
    let mut big: Vec<u32> = Vec::new();
    for (k, c) in cells.iter().enumerate() {
        match *c {
            None => big.push(k as u32),
            Some((x0, x1, y0, y1)) => {
                for x in x0..=x1 {
                    for y in y0..=y1 {
                        start[row_of(ckey(x, y)) + 1] += 1;
                    }
                }
            }
        }
    }
    for r in 0..rows {
        start[r + 1] += start[r];
    }
    let mut grid: Vec<(u64, u32)> = vec![(0, 0); pairs];
    let mut fill = start.clone();
    for (k, c) in cells.iter().enumerate() {
        if let Some((x0, x1, y0, y1)) = *c {
            for x in x0..=x1 {
                for y in y0..=y1 {
                    let key = ckey(x, y);
                    let r = row_of(key);
                    grid[fill[r] as usize] = (key, k as u32);
                    fill[r] += 1;
                }
            }
        }
    }
    drop((cells, fill));
    crate::progress::lap("orient: grid");
    // Each probe's depth is a read-only question: answered on the pool.
    let flip: Vec<usize> = infos
        .par_iter()
        .enumerate()
        .with_min_len(1 << 8)
        .map_init(Vec::new, |buf: &mut Vec<Segment>, (k, me)| {
            let p = me.probe;
            let cell = ckey(floor_i64(p.x / size), floor_i64(p.y / size));
            let r = row_of(cell);
            let row = &grid[start[r] as usize..start[r + 1] as usize];
            let mut depth = 0;
            for j in row
                .iter()
                .filter(|e| e.0 == cell)
                .map(|e| e.1)
                .chain(big.iter().copied())
            {
                let o = &infos[j as usize];
                if j as usize == k
                    || o.area.abs() <= me.area.abs()
                    || o.lo.0 > me.lo.0 + tol
                    || o.lo.1 > me.lo.1 + tol
                    || o.hi.0 < me.hi.0 - tol
                    || o.hi.1 < me.hi.1 - tol
                {
                    continue;
                }
                chains.segments_into(&chains.items[o.idx], buf);
                if inside(buf, &p) {
                    depth += 1;
                }
            }
            let want_ccw = depth % 2 == 0;
            (me.area != 0.0 && (me.area > 0.0) != want_ccw).then_some(me.idx)
        })
        .flatten()
        .collect();
    for idx in flip {
        chains.items[idx].reversed = true;
        report.reversed += 1;
    }
}
