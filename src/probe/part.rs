//! Simulated parts: closed loops of exact lines and arcs in XY, and the
//! exact contact of a round probe tip with them.
//!
//! The probe centre may go wherever its distance to the part's boundary is
//! at least the tip radius `R_e`; it touches the part when it first reaches
//! the boundary of the boundary's Minkowski sum with a disc of radius `R_e`.
//! For a line that sum is a capsule (two offset lines and two end discs),
//! for an arc an annular sector closed by two end discs; a guarded move
//! stops at the first root along the move where it *enters* one of them.

use super::ProbeError;
use crate::geometry::P2;
use crate::geometry::segment::ArcXy;
use crate::model::chain::Chain;
use std::f64::consts::TAU;

/// One boundary piece of a part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prim {
    /// A straight piece from `a` to `b`.
    Line {
        /// Start.
        a: P2,
        /// End.
        b: P2,
    },
    /// A circular arc about `c` of radius `r`, starting at angle `a0`
    /// (radians) and sweeping `sweep` (positive counter-clockwise; +-2 pi is
    /// a full circle).
    Arc {
        /// Centre.
        c: P2,
        /// Radius.
        r: f64,
        /// Start angle, radians.
        a0: f64,
        /// Signed sweep, radians.
        sweep: f64,
    },
}

impl Prim {
    /// Where the piece starts.
    pub fn start(&self) -> P2 {
        match *self {
            Prim::Line { a, .. } => a,
            Prim::Arc { c, r, a0, .. } => c + r * v(a0),
        }
    }

    /// Where the piece ends.
    pub fn end(&self) -> P2 {
        match *self {
            Prim::Line { b, .. } => b,
            Prim::Arc { c, r, a0, sweep } => c + r * v(a0 + sweep),
        }
    }

    /// Length along the piece (mm).
    pub fn length(&self) -> f64 {
        match *self {
            Prim::Line { a, b } => (b - a).norm(),
            Prim::Arc { r, sweep, .. } => r * sweep.abs(),
        }
    }

    /// The point at arc length `s` from the start.
    pub fn at(&self, s: f64) -> P2 {
        match *self {
            Prim::Line { a, b } => {
                let l = (b - a).norm();
                if l == 0.0 { a } else { a + (b - a) * (s / l) }
            }
            Prim::Arc { c, r, a0, sweep } => c + r * v(a0 + sweep.signum() * s / r),
        }
    }

    /// The nearest point of the piece to `p`.
    pub fn nearest(&self, p: P2) -> P2 {
        match *self {
            Prim::Line { a, b } => {
                let d = b - a;
                let l2 = d.norm_squared();
                if l2 == 0.0 {
                    return a;
                }
                let t = ((p - a).dot(&d) / l2).clamp(0.0, 1.0);
                a + d * t
            }
            Prim::Arc { c, r, a0, sweep } => {
                let q = p - c;
                if q.norm() > 0.0 && in_sweep(q.y.atan2(q.x), a0, sweep) {
                    return c + q * (r / q.norm());
                }
                let (s, e) = (self.start(), self.end());
                if (p - s).norm() <= (p - e).norm() { s } else { e }
            }
        }
    }

    /// Distance from `p` to the piece.
    pub fn distance(&self, p: P2) -> f64 {
        (p - self.nearest(p)).norm()
    }

    /// The first parameter `t` in `[0, t_max]` where the centre `o + t d`
    /// (`d` a unit vector) of a tip of radius `re` enters this piece's
    /// Minkowski sum with the tip.
    fn first_entry(&self, o: P2, d: crate::geometry::V2, re: f64, t_max: f64) -> Option<f64> {
        let mut best: Option<f64> = None;
        let mut take = |t: f64| {
            if (-1e-12..=t_max + 1e-9).contains(&t) && best.is_none_or(|b| t < b) {
                best = Some(t.max(0.0));
            }
        };
        match *self {
            Prim::Line { a, b } => {
                let e = b - a;
                let l = e.norm();
                if l > 0.0 {
                    let u = e / l;
                    let nrm = crate::geometry::V2::new(-u.y, u.x);
                    for side in [1.0, -1.0] {
                        // Offset line: (x - a) . n = side * re, entered when
                        // moving against that side's outward normal.
                        let dn = d.dot(&nrm) * side;
                        if dn < 0.0 {
                            let t = (re - (o - a).dot(&nrm) * side) / dn;
                            let s = (o + d * t - a).dot(&u);
                            if (0.0..=l).contains(&s) {
                                take(t);
                            }
                        }
                    }
                }
                for q in [a, b] {
                    if let Some(t) = disc_entry(o, d, q, re) {
                        take(t);
                    }
                }
            }
            Prim::Arc { c, r, a0, sweep } => {
                // Outer circle, entered from outside at the smaller root.
                if let Some((t1, _)) = circle_roots(o, d, c, r + re) {
                    let q = o + d * t1 - c;
                    if in_sweep(q.y.atan2(q.x), a0, sweep) {
                        take(t1);
                    }
                }
                // Inner circle, entered from inside (moving outwards) at the
                // larger root.
                if r > re
                    && let Some((_, t2)) = circle_roots(o, d, c, r - re)
                {
                    let q = o + d * t2 - c;
                    if in_sweep(q.y.atan2(q.x), a0, sweep) {
                        take(t2);
                    }
                }
                if sweep.abs() < TAU {
                    for q in [self.start(), self.end()] {
                        if let Some(t) = disc_entry(o, d, q, re) {
                            take(t);
                        }
                    }
                }
            }
        }
        best
    }
}

fn v(a: f64) -> crate::geometry::V2 {
    crate::geometry::V2::new(a.cos(), a.sin())
}

/// True when angle `a` lies on the arc starting at `a0` sweeping `sweep`.
pub fn in_sweep(a: f64, a0: f64, sweep: f64) -> bool {
    if sweep.abs() >= TAU {
        return true;
    }
    let tol = 1e-12;
    let arc = ArcXy {
        center: P2::origin(),
        radius: 0.0,
        start_angle: a0,
        sweep,
    };
    let d = arc.angle_offset(a);
    d <= sweep.abs() + tol || d >= TAU - tol
}

/// Both roots of |o + t d - c| = rho (d unit), smaller first.
fn circle_roots(o: P2, d: crate::geometry::V2, c: P2, rho: f64) -> Option<(f64, f64)> {
    let w = o - c;
    let b = w.dot(&d);
    let disc = b * b - (w.norm_squared() - rho * rho);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some((-b - s, -b + s))
}

/// Where a ray enters the disc of radius `rho` about `c`: the smaller root,
/// and only when the ray is moving towards the centre there.
fn disc_entry(o: P2, d: crate::geometry::V2, c: P2, rho: f64) -> Option<f64> {
    let (t1, _) = circle_roots(o, d, c, rho)?;
    let q = o + d * t1 - c;
    (q.dot(&d) <= 0.0).then_some(t1)
}

/// A part: closed loops of pieces; material lies inside an odd number of
/// loops (outer contours and their holes).
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Every piece, loop after loop.
    pub prims: Vec<Prim>,
    /// `loops[k]` is the range of `prims` that forms loop `k`.
    pub loops: Vec<std::ops::Range<usize>>,
}

/// Where and on what a guarded move touched.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touch {
    /// Distance travelled along the move (mm).
    pub t: f64,
    /// The piece touched (index into [`Part::prims`]).
    pub prim: usize,
}

impl Part {
    /// A part from closed chains (dxf2chains output). Open chains are refused:
    /// a probe cannot tell which side of them is material.
    pub fn from_chains(chains: &[Chain]) -> Result<Part, ProbeError> {
        let mut prims = Vec::new();
        let mut loops = Vec::new();
        for ch in chains {
            if !ch.closed {
                return Err(ProbeError::Part(format!(
                    "chain {} is open: only closed contours bound material",
                    ch.id
                )));
            }
            let first = prims.len();
            for s in &ch.segments {
                match s.to_arc_xy() {
                    None => {
                        let (a, b) = (s.start().xy(), s.end().xy());
                        if (b - a).norm() > 0.0 {
                            prims.push(Prim::Line { a, b });
                        }
                    }
                    Some(arc) => {
                        prims.push(Prim::Arc {
                            c: arc.center,
                            r: arc.radius,
                            a0: arc.start_angle,
                            sweep: arc.sweep,
                        });
                    }
                }
            }
            if prims.len() > first {
                loops.push(first..prims.len());
            }
        }
        if prims.is_empty() {
            return Err(ProbeError::Part("no closed contour in the input".into()));
        }
        Ok(Part { prims, loops })
    }

    /// A part bounded by one closed loop of pieces.
    pub fn single_loop(prims: Vec<Prim>) -> Part {
        let n = prims.len();
        Part {
            prims,
            loops: std::iter::once(0..n).collect(),
        }
    }

    /// A round plug of diameter `d` about `c` (a full circle, ccw).
    pub fn circle(c: P2, d: f64) -> Part {
        Part::single_loop(vec![Prim::Arc {
            c,
            r: d / 2.0,
            a0: 0.0,
            sweep: TAU,
        }])
    }

    /// A rectangle with corners `lo` and `hi`, counter-clockwise from `lo`:
    /// the section of a gauge block (width along X).
    pub fn rectangle(lo: P2, hi: P2) -> Part {
        let p = [lo, P2::new(hi.x, lo.y), hi, P2::new(lo.x, hi.y)];
        Part::single_loop(
            (0..4)
                .map(|i| Prim::Line {
                    a: p[i],
                    b: p[(i + 1) % 4],
                })
                .collect(),
        )
    }

    /// The loop that piece `prim` belongs to.
    pub fn loop_of(&self, prim: usize) -> usize {
        self.loops.iter().position(|r| r.contains(&prim)).unwrap_or(0)
    }

    /// Distance from `p` to the nearest boundary, and that piece.
    pub fn distance(&self, p: P2) -> (f64, usize) {
        let mut best = (f64::INFINITY, 0);
        for (i, q) in self.prims.iter().enumerate() {
            let d = q.distance(p);
            if d < best.0 {
                best = (d, i);
            }
        }
        best
    }

    /// True when `p` lies in material (inside an odd number of loops), by
    /// counting crossings of the ray from `p` towards +X.
    pub fn in_material(&self, p: P2) -> bool {
        let mut n = 0usize;
        for q in &self.prims {
            match *q {
                Prim::Line { a, b } => {
                    if (a.y > p.y) != (b.y > p.y) {
                        let x = a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y);
                        if x > p.x {
                            n += 1;
                        }
                    }
                }
                Prim::Arc { c, r, a0, sweep } => {
                    let dy = p.y - c.y;
                    if dy.abs() >= r {
                        continue;
                    }
                    let dx = (r * r - dy * dy).sqrt();
                    for x in [c.x - dx, c.x + dx] {
                        let a = dy.atan2(x - c.x);
                        // Half-open at the ends, like the lines: an end on
                        // the ray counts for the piece that leaves upwards.
                        let (s, e) = (q.start(), q.end());
                        let at_end = |e: P2| (e.y - p.y).abs() < 1e-12 && (e.x - x).abs() < 1e-9;
                        if x > p.x && in_sweep(a, a0, sweep) && !(sweep.abs() < TAU && (at_end(s) || at_end(e))) {
                            n += 1;
                        }
                    }
                }
            }
        }
        n % 2 == 1
    }

    /// A guarded move of a tip of radius `re` from `o` along the unit
    /// vector `d` for at most `len`: where it first touches, if it does.
    pub fn guarded(&self, o: P2, d: crate::geometry::V2, re: f64, len: f64) -> Option<Touch> {
        let mut best: Option<Touch> = None;
        for (i, q) in self.prims.iter().enumerate() {
            if let Some(t) = q.first_entry(o, d, re, len)
                && best.is_none_or(|b| t < b.t)
            {
                best = Some(Touch { t, prim: i });
            }
        }
        best
    }

    /// The unit normal at the point of piece `prim` nearest to `p`,
    /// pointing from the boundary towards `p` (out of the material when
    /// `p` is a free probe centre).
    pub fn normal_towards(&self, prim: usize, p: P2) -> crate::geometry::V2 {
        let q = self.prims[prim].nearest(p);
        let w = p - q;
        if w.norm() > 0.0 {
            return w / w.norm();
        }
        crate::geometry::V2::new(1.0, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::V2;

    #[test]
    fn guarded_move_stops_a_radius_away_from_lines_and_arcs() {
        let sq = Part::rectangle(P2::new(0.0, 0.0), P2::new(10.0, 5.0));
        let t = sq.guarded(P2::new(-3.0, 2.0), V2::new(1.0, 0.0), 0.5, 10.0).unwrap();
        assert!((t.t - 2.5).abs() < 1e-12);
        // Grazing a corner: the end disc stops it.
        let t = sq.guarded(P2::new(-3.0, 5.3), V2::new(1.0, 0.0), 0.5, 10.0).unwrap();
        assert!((t.t - (3.0 - (0.25f64 - 0.09).sqrt())).abs() < 1e-12);
        // Moving away from a face it touches: no contact.
        assert!(sq.guarded(P2::new(-0.5, 2.0), V2::new(-1.0, 0.0), 0.5, 10.0).is_none());
        let c = Part::circle(P2::new(0.0, 0.0), 12.7);
        let t = c.guarded(P2::new(-10.0, 0.0), V2::new(1.0, 0.0), 0.05, 20.0).unwrap();
        assert!((t.t - (10.0 - 6.35 - 0.05)).abs() < 1e-12);
        // From inside a bore: the inner offset circle.
        let t = c.guarded(P2::new(0.0, 0.0), V2::new(0.0, 1.0), 0.05, 20.0).unwrap();
        assert!((t.t - 6.3).abs() < 1e-12);
        assert!(sq.in_material(P2::new(5.0, 2.5)) && !sq.in_material(P2::new(-1.0, 2.5)));
        assert!(c.in_material(P2::new(6.0, 0.0)) && !c.in_material(P2::new(6.4, 0.0)));
    }
}
