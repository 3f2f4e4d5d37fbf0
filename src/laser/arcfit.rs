//! Curves to tangent-continuous arcs: each span between two points becomes
//! a biarc (two arcs meeting tangentially, matching the tangent estimates at
//! both points) or a single arc leaving along the incoming tangent, so the
//! whole fit has continuous tangents — no corner loops, no speed changes —
//! and far fewer blocks than a polyline at the same tolerance. Sharp corners
//! in the input are kept as corners. docs/arcfit.md compares it with the
//! curvature matching of Bayesteh (2013) ([`super::arcfit_seed`]).

use crate::geometry::Segment;
use crate::geometry::arc::Arc3;
use crate::geometry::line::point_segment_distance;
use crate::geometry::{P2, P3, Plane, V2};
use std::f64::consts::TAU;

fn lift(p: &P2, z: f64) -> P3 {
    P3::new(p.x, p.y, z)
}

fn perp(v: &V2) -> V2 {
    V2::new(-v.y, v.x)
}

/// The arc (or line) leaving `p` along unit tangent `t` and ending at `q`.
pub(crate) fn arc_from_tangent(p: P2, t: V2, q: P2, z: f64) -> Segment {
    let d = q - p;
    let n = perp(&t);
    let dn = d.dot(&n);
    // Nearly straight: a line is exact within 1e-12 of a radius-1e9 arc.
    if dn.abs() <= 1e-12 * d.norm_squared().max(1e-300).sqrt() || d.norm_squared() / (2.0 * dn.abs()) > 1e9 {
        return Segment::line(lift(&p, z), lift(&q, z));
    }
    let rho = d.norm_squared() / (2.0 * dn);
    let c = p + n * rho;
    match Arc3::new(lift(&c, z), lift(&p, z), lift(&q, z), rho > 0.0, Plane::Xy, 0) {
        Some(a) => Segment::Arc(a),
        None => Segment::line(lift(&p, z), lift(&q, z)),
    }
}

/// Points from text: one `x y` (or `x,y`) per line, `#` starts a comment,
/// blank lines are skipped. An error names the 1-based line.
pub fn parse_points(text: &str) -> Result<Vec<P2>, (usize, &'static str)> {
    let mut pts = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or((i + 1, "expected numbers 'x y'"))?;
        // Beyond a kilometre nothing here is a drawing any stage can cut,
        // and squared distances would overflow into infinities.
        if v.iter().any(|x| x.abs() > 1e9) {
            return Err((i + 1, "coordinate beyond ±1e9 mm"));
        }
        if v.len() < 2 {
            return Err((i + 1, "expected 'x y'"));
        }
        pts.push(P2::new(v[0], v[1]));
    }
    Ok(pts)
}

/// Two arcs from `p0` (unit tangent `t0`) to `p1` (unit tangent `t1`),
/// tangent to each other at their joint (the equal-parameter biarc).
pub fn biarc(p0: P2, t0: V2, p1: P2, t1: V2, z: f64) -> Vec<Segment> {
    let v = p1 - p0;
    if v.norm() < 1e-12 {
        return Vec::new();
    }
    let t = t0 + t1;
    let denom = 2.0 * (1.0 - t0.dot(&t1));
    let vt = v.dot(&t);
    let d = if denom.abs() < 1e-12 {
        let vt1 = v.dot(&t1);
        if vt1.abs() < 1e-12 {
            // Tangents parallel and across the chord: no finite biarc.
            return vec![Segment::line(lift(&p0, z), lift(&p1, z))];
        }
        v.norm_squared() / (4.0 * vt1)
    } else {
        (-vt + (vt * vt + denom * v.norm_squared()).sqrt()) / denom
    };
    let j = P2::from((p0.coords + p1.coords + (t0 - t1) * d) * 0.5);
    let a = arc_from_tangent(p0, t0, j, z);
    // The joint's tangent is the first arc's end tangent.
    let tj = a.end_tangent().xy();
    let tj = if tj.norm() > 0.0 { tj.normalize() } else { v.normalize() };
    let b = arc_from_tangent(j, tj, p1, z);
    let mut out = Vec::with_capacity(2);
    for e in [a, b] {
        if e.length() > 1e-12 {
            out.push(e);
        }
    }
    out
}

/// Distance from `p` to a piece (XY).
pub fn dist_to_elem(p: &P2, e: &Segment) -> f64 {
    let q = P3::new(p.x, p.y, e.start().z);
    match e {
        Segment::Line(l) => l.distance(&q),
        Segment::Arc(a) => a.distance(&q).unwrap_or(f64::INFINITY),
    }
}

fn dist_to_polyline(p: &P2, pts: &[P2]) -> f64 {
    pts.windows(2)
        .map(|w| point_segment_distance(p, &w[0], &w[1]))
        .fold(f64::INFINITY, f64::min)
}

/// Unit tangent at `a` of the circle through `a`, `b`, `c`, pointing the
/// way `a` → `b` runs (the chord direction when the three are collinear).
fn circle_tangent(a: P2, b: P2, c: P2) -> V2 {
    let (ab, ac) = (b - a, c - a);
    let chord = ab.normalize();
    let cross = ab.perp(&ac);
    let (lab2, lac2) = (ab.norm_squared(), ac.norm_squared());
    // Collinear (or NaN): the chord.
    if cross.abs().partial_cmp(&(1e-12 * (lab2 * lac2).sqrt())) != Some(std::cmp::Ordering::Greater) {
        return chord;
    }
    // Centre relative to a; the tangent is the radius turned a quarter.
    let u = V2::new(ac.y * lab2 - ab.y * lac2, ab.x * lac2 - ac.x * lab2) / (2.0 * cross);
    let t = perp(&u);
    let t = if t.dot(&ab) < 0.0 { -t } else { t };
    if t.norm() > 0.0 { t.normalize() } else { chord }
}

/// Tangent estimates at each point: the direction of the circle through it
/// and its neighbours (exact for points on a circle). At the ends of an open
/// sequence, the tangent of the circle through the last three points (the
/// chord direction for two points); a closed sequence (last point = first)
/// wraps round instead.
pub fn tangents(pts: &[P2]) -> Vec<V2> {
    let n = pts.len();
    let closed = n >= 4 && (pts[n - 1] - pts[0]).norm() <= 1e-12;
    let bessel = |prev: P2, p: P2, next: P2| {
        let (a, b) = (p - prev, next - p);
        let (la, lb) = (a.norm(), b.norm());
        // Weighted so that the tangent of a circle through the three
        // points comes out exactly (Bessel's tangent).
        let t = a * (lb / la) + b * (la / lb);
        if t.norm() > 0.0 { t.normalize() } else { b.normalize() }
    };
    (0..n)
        .map(|i| {
            if n < 2 {
                return V2::x();
            }
            if n == 2 {
                return (pts[1] - pts[0]).normalize();
            }
            if closed && (i == 0 || i == n - 1) {
                return bessel(pts[n - 2], pts[0], pts[1]);
            }
            if i == 0 {
                return circle_tangent(pts[0], pts[1], pts[2]);
            }
            if i == n - 1 {
                return -circle_tangent(pts[n - 1], pts[n - 2], pts[n - 3]);
            }
            bessel(pts[i - 1], pts[i], pts[i + 1])
        })
        .collect()
}

/// Pieces (fit pieces or polyline segments) bucketed on a uniform grid, for
/// exact nearest-distance queries: rings of cells are searched outwards
/// until no unsearched cell can hold anything nearer (everything is
/// searched after 32 rings, for queries far from all).
///
/// [`Grid::new`] files a piece under every cell of its box; [`Grid::traced`]
/// only under the cells of points traced along it at most half a cell
/// apart, so a long diagonal segment or a wide arc (a noisy fit has many)
/// fills a line of cells instead of a square of them. The ring bound then
/// allows the half cell.
pub struct Grid {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<u32>>,
    /// Cells a piece may lie beyond the cells it is filed under.
    slack: f64,
    pieces: usize,
}

thread_local! {
    /// Distance evaluations made by the fit and its checks on this thread:
    /// the work counter the tests bound (no timing in unit tests).
    static WORK: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

fn count_work(n: u64) {
    WORK.with(|w| w.set(w.get().wrapping_add(n)));
}

/// Distance evaluations made on this thread so far (fit, point and polyline
/// checks, grid filing): differences of it measure a call's work.
pub fn work_done() -> u64 {
    WORK.with(|w| w.get())
}

impl Grid {
    /// The grid's frame and cell. The frame leaves out the outermost 1 %
    /// of the boxes on each side (a few far pieces, as a fit of noise has,
    /// would otherwise make every cell hold thousands); what lies outside
    /// is filed and searched clamped to the frame, which is exact because
    /// clamping to a box never lengthens a distance. The cell is the
    /// median piece's extent, coarsened so the grid has at most about four
    /// cells a piece (at most 2^20, and 2^16 a side).
    fn frame(boxes: &[(P2, P2)]) -> Grid {
        let q = |mut v: Vec<f64>, hi: bool| {
            v.sort_by(f64::total_cmp);
            let k = v.len() / 100;
            let x = if hi {
                v.len().checked_sub(k + 1).map(|i| v[i])
            } else {
                v.get(k).copied()
            };
            x.unwrap_or(0.0)
        };
        let fin = |v: &f64| v.is_finite();
        let lo = P2::new(
            q(boxes.iter().map(|b| b.0.x).filter(fin).collect(), false),
            q(boxes.iter().map(|b| b.0.y).filter(fin).collect(), false),
        );
        let hi = P2::new(
            q(boxes.iter().map(|b| b.1.x).filter(fin).collect(), true).max(lo.x),
            q(boxes.iter().map(|b| b.1.y).filter(fin).collect(), true).max(lo.y),
        );
        let (w, h) = (hi.x - lo.x, hi.y - lo.y);
        let mut ext: Vec<f64> = boxes.iter().map(|(a, b)| (b - a).amax()).filter(fin).collect();
        ext.sort_by(f64::total_cmp);
        let median = ext.get(ext.len() / 2).copied().unwrap_or(0.0);
        let cap = (4 * boxes.len()).clamp(4096, 1 << 20) as f64;
        let cell = median.max((w * h / cap).sqrt()).max(w.max(h) / 65536.0);
        let cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            w.max(h).max(1.0)
        };
        let nx = (w / cell).clamp(0.0, 65536.0) as usize + 1;
        let ny = (h / cell).clamp(0.0, 65536.0) as usize + 1;
        Grid {
            x0: lo.x,
            y0: lo.y,
            cell,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
            slack: 0.0,
            pieces: boxes.len(),
        }
    }

    /// Each piece filed under every cell its box touches.
    pub fn new(boxes: &[(P2, P2)]) -> Grid {
        let mut g = Grid::frame(boxes);
        for (k, (a, b)) in boxes.iter().enumerate() {
            let ((i0, j0), (i1, j1)) = (g.ij(a), g.ij(b));
            for j in j0..=j1 {
                for i in i0..=i1 {
                    g.cells[j * g.nx + i].push(k as u32);
                }
            }
        }
        g
    }

    /// Each piece filed under the cells of points along it:
    /// `trace(k, spacing)` gives points of piece `k` (ends included) at
    /// most `spacing` apart. A piece whose box covers few cells is filed
    /// by its box.
    pub fn traced(boxes: &[(P2, P2)], trace: impl Fn(usize, f64) -> Vec<P2>) -> Grid {
        let mut g = Grid::frame(boxes);
        g.slack = 0.5;
        for (k, (a, b)) in boxes.iter().enumerate() {
            let ((i0, j0), (i1, j1)) = (g.ij(a), g.ij(b));
            if (i1 - i0 + 1) * (j1 - j0 + 1) <= 9 {
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        g.cells[j * g.nx + i].push(k as u32);
                    }
                }
                continue;
            }
            let pts = trace(k, 0.5 * g.cell);
            count_work(pts.len() as u64);
            for p in pts {
                let (i, j) = g.ij(&p);
                let c = &mut g.cells[j * g.nx + i];
                if c.last() != Some(&(k as u32)) {
                    c.push(k as u32);
                }
            }
        }
        g
    }

    fn ij(&self, p: &P2) -> (usize, usize) {
        let f = |v: f64, n: usize| {
            if v.is_nan() {
                0
            } else {
                (v.max(0.0) as usize).min(n - 1)
            }
        };
        (
            f((p.x - self.x0) / self.cell, self.nx),
            f((p.y - self.y0) / self.cell, self.ny),
        )
    }

    /// Rings of cells round `p`, nearest first; `visit` gets each piece
    /// filed there and the ring's number, and stops the search by
    /// returning true. Returns whether it was stopped; false also when the
    /// 32 rings were not enough to settle (then the caller searches all).
    fn rings(&self, p: &P2, mut visit: impl FnMut(usize, i64) -> bool, settled: impl Fn(i64) -> bool) -> Option<bool> {
        let (ci, cj) = self.ij(p);
        let (ci, cj) = (ci as i64, cj as i64);
        for r in 0..=self.nx.max(self.ny).min(32) as i64 {
            for j in (cj - r).max(0)..=(cj + r).min(self.ny as i64 - 1) {
                for i in (ci - r).max(0)..=(ci + r).min(self.nx as i64 - 1) {
                    if (i - ci).abs() == r || (j - cj).abs() == r {
                        for &k in &self.cells[j as usize * self.nx + i as usize] {
                            if visit(k as usize, r) {
                                return Some(true);
                            }
                        }
                    }
                }
            }
            if settled(r) {
                return Some(false);
            }
        }
        None
    }

    /// Distance no unsearched piece can beat after ring `r`.
    fn bound(&self, r: i64) -> f64 {
        (r as f64 - self.slack) * self.cell
    }

    /// Smallest `dist(k)` over all pieces `k` (exact) and the piece.
    pub fn nearest_piece(&self, p: &P2, dist: impl Fn(usize) -> f64) -> (f64, Option<usize>) {
        let best = std::cell::Cell::new((f64::INFINITY, None));
        let done = self.rings(
            p,
            |k, _| {
                let d = dist(k);
                count_work(1);
                if d < best.get().0 {
                    best.set((d, Some(k)));
                }
                false
            },
            |r| best.get().0 <= self.bound(r),
        );
        let mut best = best.get();
        if done.is_none() {
            for k in 0..self.pieces {
                let d = dist(k);
                if d < best.0 {
                    best = (d, Some(k));
                }
            }
            count_work(self.pieces as u64);
        }
        best
    }

    /// Smallest `dist(k)` over all pieces `k` (exact).
    pub fn nearest(&self, p: &P2, dist: impl Fn(usize) -> f64) -> f64 {
        self.nearest_piece(p, dist).0
    }

    /// Some piece with `dist(k) <= limit`, if there is one (the first found).
    pub fn any_within(&self, p: &P2, limit: f64, dist: impl Fn(usize) -> f64) -> Option<usize> {
        let mut hit = None;
        let done = self.rings(
            p,
            |k, _| {
                count_work(1);
                let ok = dist(k) <= limit;
                if ok {
                    hit = Some(k);
                }
                ok
            },
            |r| self.bound(r) > limit,
        );
        if done.is_none() {
            for k in 0..self.pieces {
                count_work(1);
                if dist(k) <= limit {
                    return Some(k);
                }
            }
        }
        hit
    }

    /// The largest over `queries` of the distance to the nearest piece,
    /// with `dist(q, k)` the distance from query `q` to piece `k`.
    /// Queries are visited in a scrambled order (a fixed permutation, so
    /// the result is deterministic), and one only needs an exact nearest
    /// search when no piece lies within the largest distance so far: on
    /// its hint (the piece that settled a query of the same group, see
    /// `group`) or in the rings. In a scrambled order the largest so far
    /// rises only O(log n) times, so almost every query costs one
    /// distance. The result is exact.
    pub fn max_nearest(
        &self,
        queries: usize,
        point: impl Fn(usize) -> P2,
        group: impl Fn(usize) -> usize,
        groups: usize,
        dist: impl Fn(&P2, usize) -> f64,
    ) -> f64 {
        let mut hint = vec![usize::MAX; groups];
        let mut worst = 0.0f64;
        let step = scramble_step(queries);
        let mut q = 0usize;
        for _ in 0..queries {
            // q runs through all of 0..queries: the step is a unit mod queries.
            q = ((q as u128 + step as u128) % queries as u128) as usize;
            let (p, g) = (point(q), group(q));
            count_work(1);
            if hint[g] != usize::MAX && dist(&p, hint[g]) <= worst {
                continue;
            }
            if let Some(k) = self.any_within(&p, worst, |k| dist(&p, k)) {
                hint[g] = k;
                continue;
            }
            let (d, k) = self.nearest_piece(&p, |k| dist(&p, k));
            worst = worst.max(d);
            if let Some(k) = k {
                hint[g] = k;
            }
        }
        worst
    }
}

/// A step coprime with `n` near n/φ, so that `q += step (mod n)` visits
/// every index once in a well spread order.
fn scramble_step(n: usize) -> usize {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 { a } else { gcd(b, a % b) }
    }
    if n <= 2 {
        return 1;
    }
    let mut s = ((n as f64) * 0.618_033_988_749_895) as usize;
    s = s.clamp(1, n - 1);
    while gcd(s, n) != 1 {
        s += 1;
    }
    s
}

/// A piece's XY bounding box, for [`Grid`].
pub fn elem_box(e: &Segment) -> (P2, P2) {
    let b = match e {
        Segment::Line(l) => l.bbox(),
        Segment::Arc(a) => a.bbox(),
    };
    (b.min.xy(), b.max.xy())
}

/// Below this many distance evaluations the plain double loop is faster
/// than building a grid.
const BRUTE: usize = 1 << 14;

/// A piece prepared for many distance queries: a planar arc's inside test
/// by cross products instead of angles (the fit asks millions).
enum Probe {
    Line {
        a: P2,
        b: P2,
    },
    Arc {
        c: P2,
        s: P2,
        e: P2,
        u: V2,
        w: V2,
        r0: f64,
        r1: f64,
        sgn: f64,
        big: bool,
        full: bool,
        sweep: f64,
    },
    Exact(Segment),
}

impl Probe {
    fn new(e: &Segment) -> Probe {
        match e {
            Segment::Line(l) => Probe::Line {
                a: l.start.xy(),
                b: l.end.xy(),
            },
            Segment::Arc(x) if x.plane == Plane::Xy && x.rise() == 0.0 && x.extra_turns == 0 => {
                let (c, s, e) = (x.center.xy(), x.start.xy(), x.end.xy());
                let sweep = x.sweep();
                Probe::Arc {
                    c,
                    s,
                    e,
                    u: s - c,
                    w: e - c,
                    r0: x.radius(),
                    r1: x.end_radius(),
                    sgn: if x.ccw { 1.0 } else { -1.0 },
                    big: sweep.abs() > std::f64::consts::PI,
                    full: sweep.abs() >= TAU,
                    sweep: sweep.abs(),
                }
            }
            other => Probe::Exact(*other),
        }
    }

    fn dist(&self, p: &P2) -> f64 {
        match self {
            Probe::Line { a, b } => point_segment_distance(p, a, b),
            Probe::Arc {
                c,
                s,
                e,
                u,
                w,
                r0,
                r1,
                sgn,
                big,
                full,
                sweep,
            } => {
                let v = p - c;
                let (cu, cw) = (sgn * u.perp(&v), sgn * v.perp(w));
                let inside = *full
                    || if *big {
                        cu >= 0.0 || cw >= 0.0
                    } else {
                        cu >= 0.0 && cw >= 0.0
                    };
                if inside {
                    let r = if (r1 - r0).abs() <= 1e-12 * r0 {
                        *r0
                    } else {
                        // Radius blended over the sweep, as Arc3 does.
                        let mut f = (sgn * u.perp(&v)).atan2(u.dot(&v));
                        if f < 0.0 {
                            f += TAU;
                        }
                        r0 + (r1 - r0) * (f / sweep).min(1.0)
                    };
                    (v.norm() - r).abs()
                } else {
                    (p - s).norm().min((p - e).norm())
                }
            }
            Probe::Exact(e) => dist_to_elem(p, e),
        }
    }
}

/// Whether every point is within `limit` of the pieces (stops at the first
/// that is not).
fn all_within(probes: &[Probe], pts: &[P2], limit: f64) -> bool {
    count_work((probes.len() * pts.len()) as u64);
    pts.iter().all(|p| probes.iter().any(|q| q.dist(p) <= limit))
}

/// Points along a piece, ends included, at most `spacing` apart (for
/// [`Grid::traced`]).
pub fn trace_elem(e: &Segment, spacing: f64) -> Vec<P2> {
    let len = e.length();
    let n = (len / spacing).ceil().clamp(1.0, f64::from(1u32 << 20)) as usize;
    (0..=n)
        .map(|k| e.point_at_length(len * k as f64 / n as f64).xy())
        .collect()
}

fn trace_segment(a: P2, b: P2, spacing: f64) -> Vec<P2> {
    let n = ((b - a).norm() / spacing).ceil().clamp(1.0, f64::from(1u32 << 20)) as usize;
    (0..=n).map(|k| a + (b - a) * (k as f64 / n as f64)).collect()
}

/// Largest distance from the points to the fit (points are the truth; the
/// curve between them is unknown).
pub fn point_deviation(fit: &[Segment], pts: &[P2]) -> f64 {
    let probes: Vec<Probe> = fit.iter().map(Probe::new).collect();
    let brute = |p: &P2| probes.iter().map(|q| q.dist(p)).fold(f64::INFINITY, f64::min);
    if fit.len() <= 16 || fit.len() * pts.len() <= BRUTE {
        count_work((fit.len() * pts.len()) as u64);
        return pts.iter().map(brute).fold(0.0, f64::max);
    }
    let g = Grid::traced(&fit.iter().map(elem_box).collect::<Vec<_>>(), |k, sp| {
        trace_elem(&fit[k], sp)
    });
    // Neighbouring points share a hint: they lie by the same pieces.
    g.max_nearest(
        pts.len(),
        |q| pts[q],
        |q| q / 8,
        pts.len() / 8 + 1,
        |p, k| probes[k].dist(p),
    )
}

/// Largest deviation between a fit and a polyline: the fit sampled densely
/// (`samples_per_piece` + 1 points a piece) against the polyline, and the
/// polyline's vertices against the fit. Exact for those samples; the work
/// is about one distance per sample on any input (see [`Grid::max_nearest`]).
pub fn max_deviation(fit: &[Segment], pts: &[P2], samples_per_piece: usize) -> f64 {
    let n = samples_per_piece.max(1);
    let lens: Vec<f64> = fit.iter().map(Segment::length).collect();
    let sample = |q: usize| {
        let (k, i) = (q / (n + 1), q % (n + 1));
        fit[k].point_at_length(lens[k] * i as f64 / n as f64).xy()
    };
    let queries = fit.len() * (n + 1);
    let mut worst: f64 = 0.0;
    if queries * pts.len() <= BRUTE || pts.len() < 2 {
        count_work((queries * pts.len()) as u64);
        for q in 0..queries {
            worst = worst.max(dist_to_polyline(&sample(q), pts));
        }
    } else {
        let seg_box = |w: &[P2]| {
            (
                P2::new(w[0].x.min(w[1].x), w[0].y.min(w[1].y)),
                P2::new(w[0].x.max(w[1].x), w[0].y.max(w[1].y)),
            )
        };
        let g = Grid::traced(&pts.windows(2).map(seg_box).collect::<Vec<_>>(), |k, sp| {
            trace_segment(pts[k], pts[k + 1], sp)
        });
        worst = g.max_nearest(
            queries,
            sample,
            |q| q / (n + 1),
            fit.len(),
            |p, k| point_segment_distance(p, &pts[k], &pts[k + 1]),
        );
    }
    worst.max(point_deviation(fit, pts))
}

/// Consecutive pieces on one circle (centres and radii within `eps`, same
/// sense, less than a turn together) or one line become one piece: a biarc
/// between two points of a circle with the circle's tangents is two arcs of
/// that circle.
fn merge_pieces(pieces: Vec<Segment>, eps: f64) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::with_capacity(pieces.len());
    for e in pieces {
        let merged = match (out.last(), &e) {
            (Some(Segment::Arc(a)), Segment::Arc(b))
                if a.ccw == b.ccw
                    && a.plane == b.plane
                    && a.rise() == 0.0
                    && b.rise() == 0.0
                    && a.extra_turns == 0
                    && b.extra_turns == 0
                    && (a.center - b.center).norm() + (a.radius() - b.radius()).abs() <= eps =>
            {
                let sweep = a.sweep().abs() + b.sweep().abs();
                Arc3::new(a.center, a.start, b.end, a.ccw, a.plane, 0)
                    .filter(|m| sweep < TAU - 1e-6 && (m.sweep().abs() - sweep).abs() <= 1e-9)
                    .map(Segment::Arc)
            }
            (Some(Segment::Line(a)), Segment::Line(b)) => {
                let (d, j) = (b.end - a.start, a.end - a.start);
                let off = d.cross(&j).norm() / d.norm().max(1e-300);
                (off <= eps && d.dot(&j) > 0.0 && (b.end - a.end).dot(&j) > 0.0).then(|| Segment::line(a.start, b.end))
            }
            _ => None,
        };
        match merged {
            Some(m) => *out.last_mut().expect("merged with the last piece") = m,
            None => out.push(e),
        }
    }
    out
}

/// Indices of the points where the sequence turns a corner: the chords
/// either side turn by more than 20° and by more than four times the turn
/// at either neighbouring point (a coarse polygon of a smooth curve turns
/// evenly and has none).
fn corners(pts: &[P2]) -> Vec<usize> {
    let n = pts.len();
    if n < 3 {
        return Vec::new();
    }
    let turn = |k: usize| {
        if k == 0 || k + 1 >= n {
            return 0.0;
        }
        let (a, b) = (pts[k] - pts[k - 1], pts[k + 1] - pts[k]);
        a.perp(&b).atan2(a.dot(&b)).abs()
    };
    (1..n - 1)
        .filter(|&k| {
            let t = turn(k);
            t > 20f64.to_radians() && t > 4.0 * turn(k - 1).max(turn(k + 1))
        })
        .collect()
}

/// Caps on a single arc's end-tangent error, in units of tol / span chord
/// (0: biarcs only). Each is tried and the fit with fewest blocks is kept.
const SINGLE_ARC_CAPS: [f64; 4] = [0.0, 4.0, 8.0, 16.0];

/// One tangent-continuous chain through `pts` (no corners inside).
fn fit_chain(pts: &[P2], tol: f64, z: f64, polyline: bool, cap: f64, eps: f64) -> Vec<Segment> {
    let tan = tangents(pts);
    // Quarter points of each interval on the cubic Hermite curve through
    // the points with their tangent estimates: where the smooth curve the
    // points sample most likely runs between them.
    let mids: Vec<P2> = pts
        .windows(2)
        .zip(tan.windows(2))
        .flat_map(|(p, t)| {
            let (m0, m1) = (t[0] * (p[1] - p[0]).norm(), t[1] * (p[1] - p[0]).norm());
            [0.25, 0.5, 0.75].map(|u: f64| {
                let (u2, u3) = (u * u, u * u * u);
                let (h00, h10, h01, h11) = (
                    2.0 * u3 - 3.0 * u2 + 1.0,
                    u3 - 2.0 * u2 + u,
                    3.0 * u2 - 2.0 * u3,
                    u3 - u2,
                );
                P2::from(p[0].coords * h00 + m0 * h10 + p[1].coords * h01 + m1 * h11)
            })
        })
        .collect();
    // 32 samples per arc, with 5 % margin, keeps the dense check (which
    // samples far finer) within tol.
    let limit = 0.95 * tol;
    // Polyline length up to each point.
    let cum: Vec<f64> = std::iter::once(0.0)
        .chain(pts.windows(2).scan(0.0, |acc, w| {
            *acc += (w[1] - w[0]).norm();
            Some(*acc)
        }))
        .collect();
    let within = |f: &[Segment], i: usize, j: usize| {
        if polyline {
            return max_deviation(f, &pts[i..=j], 32) <= limit;
        }
        // The point checks are one-sided: a loop out and back through the
        // points passes them. A fit of a curve the points sample is no
        // longer than their polyline, bar the sagitta terms: refuse one
        // that is longer by a tenth.
        if f.iter().map(Segment::length).sum::<f64>() > 1.1 * (cum[j] - cum[i]) + 2.0 * tol {
            return false;
        }
        let probes: Vec<Probe> = f.iter().map(Probe::new).collect();
        all_within(&probes, &pts[i..=j], limit) && all_within(&probes, &mids[3 * i..3 * j], limit)
    };
    // The longest span from i that `try_fit` accepts (i + 1 is always
    // taken, with `fallback` when nothing fits).
    let longest = |i: usize, try_fit: &dyn Fn(usize) -> Option<Vec<Segment>>, fallback: Vec<Segment>| {
        let mut good = i + 1;
        let mut best = try_fit(good).unwrap_or(fallback);
        let mut step = 1;
        let mut bad = None;
        while good < pts.len() - 1 {
            // Gallop, the last try clipped to the last point.
            let next = (good + step).min(pts.len() - 1);
            match try_fit(next) {
                Some(f) => {
                    good = next;
                    best = f;
                    step *= 2;
                }
                None => {
                    bad = Some(next);
                    break;
                }
            }
        }
        if let Some(mut hi) = bad {
            while hi - good > 1 {
                let mid = (good + hi) / 2;
                match try_fit(mid) {
                    Some(f) => {
                        good = mid;
                        best = f;
                    }
                    None => hi = mid,
                }
            }
        }
        (good, best)
    };
    let mut out = Vec::new();
    let mut i = 0;
    let mut t_in = tan[0];
    while i < pts.len() - 1 {
        let two = |j: usize| {
            let f = merge_pieces(biarc(pts[i], t_in, pts[j], tan[j], z), eps);
            within(&f, i, j).then_some(f)
        };
        // A single arc leaving along t_in, while its end tangent stays
        // within cap·tol/chord of the estimate there (so the error it hands
        // on stays bounded).
        let one = |j: usize| {
            let e = arc_from_tangent(pts[i], t_in, pts[j], z);
            let te = e.end_tangent().xy();
            let err = te.perp(&tan[j]).atan2(te.dot(&tan[j])).abs();
            let f = vec![e];
            (err <= cap * tol / (pts[j] - pts[i]).norm() && within(&f, i, j)).then_some(f)
        };
        // Nothing fits even the next point: the biarc to it anyway (it
        // passes through both points; only the midpoint estimate is missed)
        // or, against a polyline, the polyline's own piece.
        // On noise the tangent estimates point anywhere, and a biarc whose
        // two tangents both point back along the chord swings out by
        // metres; then the biarc that arrives along the chord (it turns
        // once, within about the chord) is taken when it is shorter.
        let next = if polyline {
            vec![Segment::line(lift(&pts[i], z), lift(&pts[i + 1], z))]
        } else {
            let b = merge_pieces(biarc(pts[i], t_in, pts[i + 1], tan[i + 1], z), eps);
            let chord = (pts[i + 1] - pts[i]).norm();
            let len = |f: &[Segment]| f.iter().map(Segment::length).sum::<f64>();
            if len(&b) > 1.1 * chord + 2.0 * tol {
                let c = merge_pieces(biarc(pts[i], t_in, pts[i + 1], (pts[i + 1] - pts[i]) / chord, z), eps);
                if len(&c) < len(&b) { c } else { b }
            } else {
                b
            }
        };
        let (jb, fb) = longest(i, &two, next);
        let (ja, fa) = if cap > 0.0 && one(i + 1).is_some() {
            longest(i, &one, Vec::new())
        } else {
            (i, Vec::new())
        };
        // More points per block wins; a tie keeps the biarc, which meets
        // the tangent estimate at its end.
        let (j, f) = if !fa.is_empty() && (ja - i) * fb.len() > (jb - i) * fa.len() {
            (ja, fa)
        } else {
            (jb, fb)
        };
        if let Some(e) = f.last() {
            let d = e.end_tangent().xy();
            t_in = if d.norm() > 0.0 { d.normalize() } else { tan[j] };
        }
        out.extend(f);
        i = j;
    }
    merge_pieces(out, eps)
}

/// Fit tangent-continuous arcs to a point sequence within `tol`.
///
/// Spans grow greedily (galloping, then bisection) while the pieces over
/// them stay within `tol` of every point in between and of the midpoints of
/// the cubic Hermite curve through the points with their tangent estimates
/// (the points are samples of an unknown smooth curve) or, when `polyline`
/// is set, of every polyline piece both ways (the polyline is the shape).
/// Each span is a biarc (meeting the next point's tangent estimate) or a
/// single arc (its end-tangent error capped), whichever covers more points
/// per block; every piece leaves in the direction the previous one arrived.
/// Several caps are tried (0: biarcs only) and the fit with the fewest
/// blocks kept. Pieces on one circle are merged. Sharp corners in the points
/// (where the chords turn by more than 20° and by more than four times the
/// turn at either neighbouring point) are kept: the fit is
/// tangent-continuous between them.
pub fn fit_points(pts: &[P2], tol: f64, z: f64, polyline: bool) -> Vec<Segment> {
    let mut clean: Vec<P2> = Vec::with_capacity(pts.len());
    for p in pts {
        if clean.last().is_none_or(|q: &P2| (p - q).norm() > 1e-12) {
            clean.push(*p);
        }
    }
    let pts = clean;
    if pts.len() < 2 {
        return Vec::new();
    }
    // Pieces on one circle within this are merged (the merge moves the path
    // by at most this much).
    let eps = 1e-2 * tol.abs().min(1.0);
    let mut cuts = vec![0];
    cuts.extend(corners(&pts));
    cuts.push(pts.len() - 1);
    let mut out = Vec::new();
    for w in cuts.windows(2) {
        let part = &pts[w[0]..=w[1]];
        let best = SINGLE_ARC_CAPS
            .iter()
            .map(|&cap| fit_chain(part, tol, z, polyline, cap, eps))
            .min_by_key(Vec::len)
            .unwrap_or_default();
        out.extend(best);
    }
    merge_pieces(out, eps)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle_pts(r: f64, n: usize, turns: f64) -> Vec<P2> {
        (0..=n)
            .map(|i| {
                let a = TAU * turns * i as f64 / n as f64;
                P2::new(r * a.cos(), r * a.sin())
            })
            .collect()
    }

    #[test]
    fn end_tangents_are_exact_on_a_circle() {
        let pts = circle_pts(3.0, 40, 0.3);
        let t = tangents(&pts);
        for (p, u) in [(pts[0], t[0]), (pts[40], t[40])] {
            let exact = V2::new(-p.y, p.x) / 3.0;
            assert!((u - exact).norm() < 1e-12, "{u:?} vs {exact:?}");
        }
    }

    #[test]
    fn a_closed_circle_is_two_arcs_and_an_open_arc_one() {
        for tol in [1e-3, 1e-6] {
            let closed = circle_pts(5.0, 720, 1.0);
            let f = fit_points(&closed, tol, 0.0, false);
            assert!(f.len() <= 2, "{} pieces", f.len());
            assert!(point_deviation(&f, &closed) <= tol);
            let open = circle_pts(5.0, 300, 0.6);
            let f = fit_points(&open, tol, 0.0, false);
            assert_eq!(f.len(), 1);
            assert!(point_deviation(&f, &open) <= tol);
            assert!((f[0].end().xy() - open[300]).norm() < 1e-12);
        }
    }

    #[test]
    fn a_sharp_corner_is_kept() {
        // A line into a half circle, turning 90° at the origin.
        let mut pts: Vec<P2> = (0..=30).map(|i| P2::new(-3.0 + 0.1 * i as f64, 0.0)).collect();
        pts.extend((1..=47).map(|i| {
            let a = std::f64::consts::PI * (1.0 - i as f64 / 47.0);
            P2::new(1.5 + 1.5 * a.cos(), 1.5 * a.sin())
        }));
        let f = fit_points(&pts, 1e-4, 0.0, false);
        assert_eq!(f.len(), 2, "{f:?}");
        assert!(matches!(f[0], Segment::Line(_)) && matches!(f[1], Segment::Arc(_)));
        assert!((f[0].end().xy() - P2::origin()).norm() < 1e-12);
        // A coarse polygon of a circle turns evenly: no corners.
        assert!(corners(&circle_pts(1.0, 12, 1.0)).is_empty());
    }

    #[test]
    fn probes_and_the_grid_measure_exactly() {
        // Arcs of every size and sense, lines; points all round.
        let mut fit = Vec::new();
        for k in 0..40 {
            let a0 = k as f64 * 0.7;
            let sweep = 0.1 + (k as f64 * 0.37) % 6.0;
            let c = P3::new((k % 7) as f64, (k % 5) as f64, 0.0);
            let r = 0.2 + (k % 3) as f64;
            let at = |a: f64| P3::new(c.x + r * a.cos(), c.y + r * a.sin(), 0.0);
            let ccw = k % 2 == 0;
            let end = if ccw { a0 + sweep } else { a0 - sweep };
            fit.push(Segment::Arc(Arc3::new(c, at(a0), at(end), ccw, Plane::Xy, 0).unwrap()));
            fit.push(Segment::line(at(end), P3::new(c.x - 1.0, c.y + 0.5, 0.0)));
        }
        let pts: Vec<P2> = (0..500)
            .map(|i| {
                P2::new(
                    (i as f64 * 0.618).fract() * 9.0 - 1.0,
                    (i as f64 * 0.414).fract() * 7.0 - 1.0,
                )
            })
            .collect();
        for p in &pts {
            for e in &fit {
                let (a, b) = (Probe::new(e).dist(p), dist_to_elem(p, e));
                assert!((a - b).abs() <= 1e-12 * (1.0 + b), "{a} vs {b} for {e:?}");
            }
        }
        let brute = pts
            .iter()
            .map(|p| fit.iter().map(|e| dist_to_elem(p, e)).fold(f64::INFINITY, f64::min))
            .fold(0.0, f64::max);
        assert!((point_deviation(&fit, &pts) - brute).abs() < 1e-12);
        let poly_brute = fit
            .iter()
            .flat_map(|e| (0..=8).map(move |k| e.point_at_length(e.length() * k as f64 / 8.0).xy()))
            .map(|q| dist_to_polyline(&q, &pts))
            .fold(brute, f64::max);
        assert!((max_deviation(&fit, &pts, 8) - poly_brute).abs() < 1e-12);
    }

    #[test]
    fn degenerate_input_does_not_panic() {
        let p = |x: f64, y: f64| P2::new(x, y);
        assert!(fit_points(&[], 1e-3, 0.0, false).is_empty());
        assert!(fit_points(&[p(1.0, 1.0)], 1e-3, 0.0, true).is_empty());
        assert!(fit_points(&[p(1.0, 1.0), p(1.0, 1.0)], 1e-3, 0.0, false).is_empty());
        let col = [p(0.0, 0.0), p(1.0, 1.0), p(1.0, 1.0), p(2.0, 2.0), p(3.0, 3.0)];
        let f = fit_points(&col, 1e-4, 0.0, false);
        assert_eq!(f.len(), 1, "{f:?}");
        let back = [p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1e-9), p(1.0, 0.0)];
        for polyline in [false, true] {
            let f = fit_points(&back, 1e-4, 0.0, polyline);
            assert!(point_deviation(&f, &back) <= 1e-4);
        }
    }

    #[test]
    fn biarcs_join_tangentially_and_hit_both_ends() {
        for (t0, t1) in [(0.3f64, -1.2f64), (0.0, 0.0), (1.0, 2.5), (-0.7, 0.9)] {
            let (p0, p1) = (P2::new(0.0, 0.0), P2::new(2.0, 0.5));
            let (u0, u1) = (V2::new(t0.cos(), t0.sin()), V2::new(t1.cos(), t1.sin()));
            let f = biarc(p0, u0, p1, u1, 0.0);
            assert!((f[0].start().xy() - p0).norm() < 1e-12);
            assert!((f.last().unwrap().end().xy() - p1).norm() < 1e-9);
            assert!((f[0].start_tangent().xy() - u0).norm() < 1e-9);
            assert!((f.last().unwrap().end_tangent().xy() - u1).norm() < 1e-6, "{t0} {t1}");
            for w in f.windows(2) {
                assert!(w[0].end_tangent().dot(&w[1].start_tangent()) > 1.0 - 1e-9);
            }
        }
    }

    #[test]
    fn sampled_points_fit_far_fewer_blocks() {
        // Coarse samples of a sine: as points (not a polyline) they fit in
        // a handful of biarcs, every point within tol.
        let pts: Vec<P2> = (0..=126)
            .map(|i| P2::new(i as f64 * 0.05, (i as f64 * 0.05).sin()))
            .collect();
        let f = fit_points(&pts, 1e-4, 0.0, false);
        assert!(point_deviation(&f, &pts) <= 1e-4);
        assert!(f.len() * 2 < pts.len(), "{} pieces", f.len());
    }

    #[test]
    fn a_sine_fits_within_tolerance_in_fewer_blocks() {
        let pts: Vec<P2> = (0..=400)
            .map(|i| {
                let x = i as f64 * 0.025;
                P2::new(x, x.sin())
            })
            .collect();
        for tol in [1e-3, 1e-4] {
            let f = fit_points(&pts, tol, 0.0, true);
            let dev = max_deviation(&f, &pts, 64);
            assert!(dev <= tol * 1.0001, "deviation {dev} > {tol}");
            assert!(f.len() * 4 < pts.len(), "{} pieces for {} points", f.len(), pts.len());
            for w in f.windows(2) {
                assert!((w[0].end() - w[1].start()).norm() < 1e-9);
                assert!(w[0].end_tangent().dot(&w[1].start_tangent()) > (0.5f64).to_radians().cos());
            }
        }
    }

    /// Noisy samples, deterministic: a circle with radial noise far above
    /// the tolerance (a measured part) and a random walk across a line.
    fn noisy(n: usize, walk: bool) -> Vec<P2> {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..n)
            .map(|i| {
                if walk {
                    P2::new(i as f64 * 0.01, 0.1 * rnd())
                } else {
                    let a = TAU * i as f64 / n as f64;
                    let r = 6.35 + 4e-3 * rnd();
                    P2::new(r * a.cos(), r * a.sin())
                }
            })
            .collect()
    }

    #[test]
    fn noisy_points_cost_near_linear_work() {
        // The fit and both checks, as `pathgen arcfit --report` runs them:
        // distance evaluations per point stay bounded (about log n) from
        // 10k to 40k points, where the old checks grew with n.
        for walk in [false, true] {
            let mut per_point = Vec::new();
            for n in [10_000, 40_000] {
                let pts = noisy(n, walk);
                let w0 = work_done();
                let f = fit_points(&pts, 1e-3, 0.0, false);
                let dev_pts = point_deviation(&f, &pts);
                let dev_poly = max_deviation(&f, &pts, 256);
                let w = (work_done() - w0) as f64 / n as f64;
                assert!(dev_pts <= 1e-3, "{dev_pts}");
                // No excursion far from the points (noise of 0.1 mm at most).
                assert!(dev_poly < 1.0, "the fit swings {dev_poly} mm off the points");
                eprintln!(
                    "walk {walk} n {n}: {w:.0} distance evaluations per point, {} pieces",
                    f.len()
                );
                per_point.push(w);
            }
            assert!(per_point[1] < 1.5 * per_point[0], "work per point grew {per_point:?}");
        }
    }
}
