//! Orientation by nesting depth: which closed chains lie inside which,
//! through a grid over their boxes and exact point-in-chain tests (arcs
//! included, no tessellation).

use super::{ChainReport, Chains, midpoint};
use crate::geometry::{EPS_LEN, P3, Plane, floor_i64};
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
/// axis extremes they pass) and its signed area, the arithmetic of
/// [`signed_area`] with each arc's sweep from one `atan2`.
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
        let Segment::Arc(a) = s else { continue };
        if a.plane != Plane::Xy || a.extra_turns != 0 {
            let Some(a) = s.to_arc_xy() else { continue };
            for (k, &(c, sn)) in quarter.iter().enumerate() {
                if a.contains_angle(k as f64 * std::f64::consts::FRAC_PI_2) {
                    let (x, y) = (a.center.x + a.radius * c, a.center.y + a.radius * sn);
                    lo = (lo.0.min(x), lo.1.min(y));
                    hi = (hi.0.max(x), hi.1.max(y));
                }
            }
            let (dx, dy) = (p.x - a.center.x, p.y - a.center.y);
            area += 0.5 * (dx * dx + dy * dy) * (a.sweep - a.sweep.sin());
            continue;
        }
        let turn = planar_turn(a);
        let r = turn.r2.sqrt();
        for (k, &(c, sn)) in quarter.iter().enumerate() {
            if turn.passes(k) {
                let (x, y) = (a.center.x + r * c, a.center.y + r * sn);
                lo = (lo.0.min(x), lo.1.min(y));
                hi = (hi.0.max(x), hi.1.max(y));
            }
        }
        area += 0.5 * turn.r2 * (turn.sweep - turn.sweep.sin());
    }
    (lo, hi, area)
}

/// An arc in the XY plane without extra turns, as the box and the area
/// need it: the squared radius, the signed sweep, and what the quarter
/// tests need, with no angle of either end.
struct PlanarTurn {
    /// The radius where counter-clockwise travel round the arc starts
    /// (the start of a counter-clockwise arc, the end of a clockwise one).
    from: (f64, f64),
    /// How far that travel turns, as a [`diamond`] pseudo-angle.
    reach: f64,
    full: bool,
    r2: f64,
    /// Signed, in `(0, 2 pi]` counter-clockwise, `[-2 pi, 0)` clockwise, as
    /// [`crate::geometry::arc::Arc3::sweep`] gives it.
    sweep: f64,
}

/// The sweep is the angle between the end radii, `atan2(u x v, u . v)`,
/// taken the arc's way round: one `atan2` where the start and end angles
/// took two, and no cancellation on short arcs (the difference of two
/// nearly equal angles). The full turn is `Arc3::sweep`'s rule.
fn planar_turn(a: &crate::geometry::arc::Arc3) -> PlanarTurn {
    use crate::geometry::P2;
    use std::f64::consts::TAU;
    let u = (a.start.x - a.center.x, a.start.y - a.center.y);
    let v = (a.end.x - a.center.x, a.end.y - a.center.y);
    let r2 = u.0 * u.0 + u.1 * u.1;
    let full = crate::geometry::planar::ends_close_full_turn(
        &P2::new(a.start.x, a.start.y),
        &P2::new(a.end.x, a.end.y),
        r2.sqrt(),
        EPS_LEN,
    );
    let phi = (u.0 * v.1 - u.1 * v.0).atan2(u.0 * v.0 + u.1 * v.1);
    let mut sweep = if a.ccw {
        if phi <= 0.0 { phi + TAU } else { phi }
    } else if phi >= 0.0 {
        phi - TAU
    } else {
        phi
    };
    // Opposite ends read as a zero angle by rounding are a whole turn too.
    let full = full || sweep.abs() >= TAU;
    if full {
        sweep = if a.ccw { TAU } else { -TAU };
    }
    // Travel counter-clockwise from `from` to `to`; `to` in `from`'s
    // frame is (from . to, from x to).
    let (from, to) = if a.ccw { (u, v) } else { (v, u) };
    let reach = diamond(from.0 * to.0 + from.1 * to.1, from.0 * to.1 - from.1 * to.0);
    PlanarTurn {
        from,
        reach,
        full,
        r2,
        sweep,
    }
}

impl PlanarTurn {
    /// Does the arc pass the direction `k` quarter turns from +X (ends
    /// included)? The direction's turn from `from`, counter-clockwise, is
    /// compared with the arc's own, both as [`diamond`] pseudo-angles
    /// (monotonic in the angle, no trigonometry).
    fn passes(&self, k: usize) -> bool {
        if self.full {
            return true;
        }
        // The direction in `from`'s frame: (from . d, from x d).
        let f = self.from;
        let d = [(f.0, -f.1), (f.1, f.0), (-f.0, f.1), (-f.1, -f.0)][k];
        diamond(d.0, d.1) <= self.reach
    }
}

/// The counter-clockwise angle of `(x, y)` from +X as a number in
/// `[0, 4)`: 1 a quarter turn, 2 a half; monotonic in the angle, so it
/// orders directions as the angle does, from one division.
fn diamond(x: f64, y: f64) -> f64 {
    if y >= 0.0 {
        if x > 0.0 { y / (x + y) } else { 1.0 - x / (y - x) }
    } else if x < 0.0 {
        2.0 - y / (-x - y)
    } else {
        3.0 + x / (x - y)
    }
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
    // The closed chains are listed first, so the pool writes the infos
    // straight into one array of the exact size: filtered on the pool,
    // they were gathered in a vector per task and copied into the result,
    // 1,400 page faults of fresh memory on the mix benchmark.
    let closed: Vec<usize> = (0..chains.items.len())
        .filter(|&k| chains.items[k].closed && chains.items[k].len > 0)
        .collect();
    let infos: Vec<Info> = closed
        .par_iter()
        .map_init(Vec::new, |buf: &mut Vec<Segment>, &idx| {
            chains.segments_into(&chains.items[idx], buf);
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
    // The row starts are the fill cursor (as in `repair::adjacency`): each
    // ends at the next row's start, and one move back restores them.
    for (k, c) in cells.iter().enumerate() {
        if let Some((x0, x1, y0, y1)) = *c {
            for x in x0..=x1 {
                for y in y0..=y1 {
                    let key = ckey(x, y);
                    let r = row_of(key);
                    grid[start[r] as usize] = (key, k as u32);
                    start[r] += 1;
                }
            }
        }
    }
    start.copy_within(0..rows, 1);
    start[0] = 0;
    drop(cells);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::test_rng::unit_rng;
    use std::f64::consts::{FRAC_PI_2, TAU};

    /// The box and area of one arc the general way: both end angles by
    /// `atan2`, the quarter directions by `contains_angle`.
    fn general(s: &Segment) -> ((f64, f64), (f64, f64), f64) {
        let a = s.to_arc_xy().unwrap();
        let (p, q) = (s.start(), s.end());
        let mut lo = (p.x.min(q.x), p.y.min(q.y));
        let mut hi = (p.x.max(q.x), p.y.max(q.y));
        for k in 0..4 {
            let t = k as f64 * FRAC_PI_2;
            if a.contains_angle(t) {
                let (x, y) = (a.center.x + a.radius * t.cos(), a.center.y + a.radius * t.sin());
                lo = (lo.0.min(x), lo.1.min(y));
                hi = (hi.0.max(x), hi.1.max(y));
            }
        }
        (lo, hi, signed_area(std::slice::from_ref(s)))
    }

    fn quarter() -> [(f64, f64); 4] {
        std::array::from_fn(|k| {
            let t = k as f64 * FRAC_PI_2;
            (t.cos(), t.sin())
        })
    }

    #[test]
    fn one_atan2_box_and_area_agree_with_the_end_angles() {
        let mut rnd = unit_rng(0x0_71e47);
        let q = quarter();
        for case in 0..20_000 {
            let c = P3::new(2e3 * rnd() - 1e3, 2e3 * rnd() - 1e3, 0.0);
            let r = 10f64.powf(6.0 * rnd() - 3.0);
            // Ends at random angles, a tenth of them on an axis direction
            // (the box's boundary cases), some a hair apart (short arcs).
            let pick = |rnd: &mut dyn FnMut() -> f64| {
                if rnd() < 0.1 {
                    (rnd() * 4.0).floor() * FRAC_PI_2
                } else {
                    TAU * rnd()
                }
            };
            let a0 = pick(&mut rnd);
            let a1 = if case % 5 == 0 {
                a0 + 1e-7 * (rnd() - 0.5)
            } else {
                pick(&mut rnd)
            };
            let s = P3::new(c.x + r * a0.cos(), c.y + r * a0.sin(), 0.0);
            let e = P3::new(c.x + r * a1.cos(), c.y + r * a1.sin(), 0.0);
            let seg = Segment::arc_xy(s, e, c, rnd() < 0.5);
            let (lo, hi, area) = box_and_area(std::slice::from_ref(&seg), &q);
            let (glo, ghi, garea) = general(&seg);
            let shoelace = 0.5 * (s.x * e.y - e.x * s.y);
            // An axis direction at an end is that end up to rounding: the
            // boxes may differ by the rounding of the radius, no more.
            let slack = 1e-12 * (r + c.x.abs() + c.y.abs());
            for (x, y) in [(lo.0, glo.0), (lo.1, glo.1), (hi.0, ghi.0), (hi.1, ghi.1)] {
                assert!(
                    (x - y).abs() <= slack,
                    "case {case}: box {lo:?} {hi:?} against {glo:?} {ghi:?}"
                );
            }
            // The arcs' own area terms, without the shared shoelace term.
            let (mine, theirs) = (area - shoelace, garea - shoelace);
            assert!(
                (mine - theirs).abs() <= 1e-9 * r * r + 1e-12 * theirs.abs(),
                "case {case}: area {mine} against {theirs} (r {r})"
            );
        }
    }

    #[test]
    fn full_circles_and_half_turns_keep_their_whole_box_and_area() {
        let q = quarter();
        let c = P3::new(3.0, -2.0, 0.0);
        let s = P3::new(5.0, -2.0, 0.0);
        for ccw in [true, false] {
            let (lo, hi, area) = box_and_area(&[Segment::arc_xy(s, s, c, ccw)], &q);
            assert_eq!((lo, hi), ((1.0, -4.0), (5.0, 0.0)));
            let want = if ccw {
                4.0 * std::f64::consts::PI
            } else {
                -4.0 * std::f64::consts::PI
            };
            assert!((area - want).abs() < 1e-12, "{area}");
        }
        // Half a turn from +x to -x: counter-clockwise over the top.
        let e = P3::new(1.0, -2.0, 0.0);
        // (The end at -x passes that axis direction too: its point, from
        // the rounded sine of pi, is the end within 1e-15.)
        let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
        let (lo, hi, _) = box_and_area(&[Segment::arc_xy(s, e, c, true)], &q);
        assert!(near(lo.1, -2.0) && near(hi.1, 0.0), "{lo:?} {hi:?}");
        let (lo, hi, _) = box_and_area(&[Segment::arc_xy(s, e, c, false)], &q);
        assert!(near(lo.1, -4.0) && near(hi.1, -2.0), "{lo:?} {hi:?}");
    }

    #[test]
    fn diamond_orders_directions_as_the_angle_does() {
        let mut rnd = unit_rng(0xd1a);
        let mut v: Vec<(f64, f64)> = (0..2000)
            .map(|_| {
                let t = TAU * rnd();
                let m = 10f64.powf(4.0 * rnd() - 2.0);
                (t, diamond(m * t.cos(), m * t.sin()))
            })
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(v.windows(2).all(|w| w[0].1 <= w[1].1));
        assert!(v.iter().all(|x| (0.0..4.0).contains(&x.1)));
        assert_eq!(
            [
                diamond(1.0, 0.0),
                diamond(0.0, 1.0),
                diamond(-1.0, 0.0),
                diamond(0.0, -1.0)
            ],
            [0.0, 1.0, 2.0, 3.0]
        );
    }
}
