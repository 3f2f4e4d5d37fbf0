//! Measuring a fit: the distance from points to the fitted pieces (a
//! grid over the pieces for large fits, probes prepared per piece, the
//! work counter the tests bound) and the deviation of a fit from its
//! points and from the curve between them.

use super::*;
use crate::geometry::arc::ArcFrame;
use crate::geometry::segment::length_fraction;

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
pub(super) enum Probe {
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
    pub(super) fn new(e: &Segment) -> Probe {
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

    pub(super) fn dist(&self, p: &P2) -> f64 {
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
pub(super) fn all_within(probes: &[Probe], pts: &[P2], limit: f64) -> bool {
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
    let samples = Samples::new(fit, samples_per_piece);
    let (n, sample) = (samples.n, |q: usize| samples.at(q));
    let queries = samples.count();
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

/// The points [`max_deviation`] samples a fit at: `n + 1` a piece, evenly
/// by length. Each arc's frame is made once, not once a sample
/// (`point_at_length` would redo the arc's length and angles, four
/// `atan2`, for each of its samples); the same points, bit for bit.
struct Samples<'a> {
    fit: &'a [Segment],
    n: usize,
    lens: Vec<f64>,
    frames: Vec<Option<ArcFrame>>,
}

impl<'a> Samples<'a> {
    fn new(fit: &'a [Segment], samples_per_piece: usize) -> Samples<'a> {
        Samples {
            fit,
            n: samples_per_piece.max(1),
            lens: fit.iter().map(Segment::length).collect(),
            frames: fit
                .iter()
                .map(|s| match s {
                    Segment::Arc(a) => Some(ArcFrame::new(a)),
                    Segment::Line(_) => None,
                })
                .collect(),
        }
    }

    fn count(&self) -> usize {
        Self::count_of(self.fit.len(), self.n)
    }

    /// How many samples `pieces` pieces at `samples_per_piece` give,
    /// without building the frames.
    fn count_of(pieces: usize, samples_per_piece: usize) -> usize {
        pieces * (samples_per_piece.max(1) + 1)
    }

    fn at(&self, q: usize) -> P2 {
        let (k, i) = (q / (self.n + 1), q % (self.n + 1));
        let t = length_fraction(self.lens[k] * i as f64 / self.n as f64, self.lens[k]);
        match &self.frames[k] {
            Some(f) => f.point_at(t).xy(),
            None => self.fit[k].point_at(t).xy(),
        }
    }
}

/// `max_deviation(fit, pts, samples_per_piece) <= limit`, the same verdict
/// on any input, sooner: a fit is accepted or refused thousands of times
/// while it grows, and only the verdict is wanted. On the small fits that
/// [`max_deviation`] measures by brute force, each sample stops at the
/// first chord within `limit` (tried from the chord the sample before it
/// found, which is where the next one usually lies), each point at the
/// first piece within it, and the answer is no at the first sample or
/// point beyond it. A distance is the same function of the same points
/// either way, so the verdict is too (a NaN distance counts as beyond, as
/// `max_deviation`'s folds leave it out).
pub fn deviation_within(fit: &[Segment], pts: &[P2], samples_per_piece: usize, limit: f64) -> bool {
    let queries = Samples::count_of(fit.len(), samples_per_piece);
    if pts.len() < 2 || queries * pts.len() > BRUTE {
        return max_deviation(fit, pts, samples_per_piece) <= limit;
    }
    let samples = Samples::new(fit, samples_per_piece);
    let chords = pts.len() - 1;
    let mut evals = 0u64;
    let mut hint = 0;
    let mut ok = true;
    for q in 0..queries {
        let p = samples.at(q);
        let near = (hint..chords).chain(0..hint).find(|&k| {
            evals += 1;
            point_segment_distance(&p, &pts[k], &pts[k + 1]) <= limit
        });
        match near {
            Some(k) => hint = k,
            None => {
                ok = false;
                break;
            }
        }
    }
    if ok {
        let probes: Vec<Probe> = fit.iter().map(Probe::new).collect();
        let mut hint = 0;
        ok = pts.iter().all(|p| {
            let near = (hint..probes.len()).chain(0..hint).find(|&k| {
                evals += 1;
                probes[k].dist(p) <= limit
            });
            near.inspect(|&k| hint = k).is_some()
        });
    }
    count_work(evals);
    ok
}
