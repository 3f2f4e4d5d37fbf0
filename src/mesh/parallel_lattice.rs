//! Parallel rays from the points of a lattice (the verification rays of
//! Singh 2014: a step forward by a step over, cast along one direction):
//! each triangle is rasterised onto the lattice and tested against the
//! rays it may cover, keeping the nearest hit per ray in a depth buffer,
//! instead of looking up each ray's candidates in a cell.
//!
//! Exactness: every (triangle, ray) pair the rasteriser visits goes through
//! the same watertight test the BVH uses (`intersect` (src/mesh/triangle.rs), closed triangles),
//! with the ray's origin computed by [`Lattice::origin`], and the depth
//! buffer keeps the least `(t, triangle index)`: the answer the BVH's
//! `first_hit` gives, bit for bit, provided no pair that test would accept
//! is left out. The rasteriser's coverage is therefore padded beyond the
//! rounding of the test: each triangle's edges are moved outward by a
//! bound on the rounding of the test's edge functions (`pad` below, which
//! grows as an edge gets short against the longest one), and a triangle
//! too thin in projection for its edges to say where its inside is is
//! covered by its whole bounding box, padded by twice the BVH's own box
//! padding. A ray exactly through a shared edge or vertex is covered by
//! every triangle there, so the closed test keeps a closed mesh watertight.

use std::borrow::Cow;

use rayon::prelude::*;

use super::ParallelRays;
use crate::geometry::{P3, V3};
use crate::mesh::bvh::Hit;

/// Ray origins on a 2-D lattice: `base + eu * us[i] + ev * vs[j]`, for
/// every `i` and `j` (any `eu` and `ev` not both in the plane of the rays'
/// direction, any coordinate lists, in any order).
#[derive(Debug, Clone, Copy)]
pub struct Lattice<'a> {
    /// The origin of coordinates `(0, 0)`.
    pub base: P3,
    /// The first lattice axis.
    pub eu: V3,
    /// The second lattice axis.
    pub ev: V3,
    /// Coordinates along `eu` (the inner index of the results).
    pub us: &'a [f64],
    /// Coordinates along `ev` (the outer index).
    pub vs: &'a [f64],
}

impl Lattice<'_> {
    /// The origin of ray `(i, j)`: `base + eu * us[i] + ev * vs[j]`, in that
    /// order of operations (the same rays whichever query casts them).
    #[inline]
    pub fn origin(&self, i: usize, j: usize) -> P3 {
        self.base + self.eu * self.us[i] + self.ev * self.vs[j]
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.us.len() * self.vs.len()
    }

    /// True when there are no rays.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One axis of the lattice: its finite coordinates, ascending.
struct Axis<'a> {
    vals: Cow<'a, [f64]>,
    /// Where each sorted coordinate is in the caller's list (`None`: the
    /// caller's list was already sorted and finite).
    pos: Option<Vec<u32>>,
    lo: f64,
    /// Coordinates per unit, for a first guess of an index (exact for an
    /// evenly spaced axis, then corrected by a short walk).
    inv_step: f64,
}

impl<'a> Axis<'a> {
    fn new(v: &'a [f64]) -> Axis<'a> {
        let sorted = v.iter().all(|x| x.is_finite()) && v.windows(2).all(|w| w[0] <= w[1]);
        let (vals, pos) = if sorted {
            (Cow::Borrowed(v), None)
        } else {
            let mut idx: Vec<u32> = (0..v.len() as u32).filter(|&i| v[i as usize].is_finite()).collect();
            idx.sort_by(|&a, &b| v[a as usize].total_cmp(&v[b as usize]).then(a.cmp(&b)));
            (Cow::Owned(idx.iter().map(|&i| v[i as usize]).collect()), Some(idx))
        };
        let n = vals.len();
        let (lo, span) = if n > 0 {
            (vals[0], vals[n - 1] - vals[0])
        } else {
            (0.0, 0.0)
        };
        let inv_step = if n > 1 && span > 0.0 {
            (n - 1) as f64 / span
        } else {
            0.0
        };
        Axis {
            vals,
            pos,
            lo,
            inv_step,
        }
    }

    /// The smallest index `k` with `vals[k] >= x`.
    #[inline]
    fn first_ge(&self, x: f64) -> usize {
        self.partition(x, |y| y < x)
    }

    /// The smallest index `k` with `vals[k] > x`.
    #[inline]
    fn first_gt(&self, x: f64) -> usize {
        self.partition(x, |y| y <= x)
    }

    /// The end of the prefix of `vals` that is `below`: guessed from an
    /// even spacing, corrected by a short walk, else a binary search.
    #[inline(always)]
    fn partition(&self, x: f64, below: impl Fn(f64) -> bool) -> usize {
        let v = &self.vals[..];
        let n = v.len();
        let g = (x - self.lo) * self.inv_step;
        // The cast saturates (below 0 and NaN to 0): no branch, and a u32's
        // saturation is cheaper than a usize's (an axis has fewer than
        // 2^32 coordinates).
        let mut k = (g as u32 as usize).min(n);
        for _ in 0..4 {
            if k > 0 && !below(v[k - 1]) {
                k -= 1;
            } else if k < n && below(v[k]) {
                k += 1;
            } else {
                return k;
            }
        }
        v.partition_point(|&y| below(y))
    }
}

/// One triangle ready to rasterise: the lattice `(u, v)` region that holds
/// every ray the test may accept, as half-planes (bounds on `u` along a
/// row, see `to_hp`).
struct Prep {
    hp: [[f64; 3]; 4],
    n_hp: u8,
    /// Sorted rows `j0..j1` the region may reach.
    j0: u32,
    j1: u32,
    /// Corners, each in the test's axis order (`kx`, `ky`, `kz`).
    p: [[f64; 3]; 3],
    id: u32,
    /// [`Hit::front`], the same for every ray.
    front: bool,
}

/// The lattice and the shear in the test's axis order.
struct Frame {
    /// `base + eu * us[i]` per component.
    col: [Vec<f64>; 3],
    ev: [f64; 3],
    s: [f64; 3],
}

/// Strips across the projection the triangles are grouped in (see
/// `row_order`).
const STRIPS: f64 = 64.0;

/// Rays per band of rows one task rasterises into (its depth buffer stays
/// in the core's cache).
const BAND_RAYS: usize = 32768;

impl ParallelRays {
    /// The triangles by strips along the projection's second axis, so
    /// that those of one band of lattice rows are read together, and
    /// nearest first within a strip.
    fn row_order(&self) -> &[(u32, [P3; 3])] {
        self.order.get_or_init(|| {
            let min = |t: &[P3; 3], d: &V3| t.iter().map(|p| p.coords.dot(d)).fold(f64::INFINITY, f64::min);
            let across: Vec<f64> = self.tris.iter().map(|t| min(t, &self.e2)).collect();
            let lo = across.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = across.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let inv = if hi > lo { STRIPS / (hi - lo) } else { 0.0 };
            // Strip across, then nearest first along the direction (the
            // front surface fills the depth buffer first and the faces
            // behind fail its test alike, a branch the core predicts).
            let mut k: Vec<(u32, f64, u32)> = across
                .iter()
                .zip(&self.tris)
                .enumerate()
                .map(|(i, (&a, t))| {
                    (
                        (((a - lo) * inv) as u32).min(STRIPS as u32),
                        min(t, &self.dir),
                        i as u32,
                    )
                })
                .collect();
            k.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(a.2.cmp(&b.2)));
            k.into_iter().map(|(_, _, i)| (i, self.tris[i as usize])).collect()
        })
    }

    /// The first hit of every ray of the lattice `l` along this index's
    /// direction, `t >= 0`, in the order `j * us.len() + i`: the same
    /// answers as [`ParallelRays::first_hit`] of each
    /// [`Lattice::origin`] (and so as the BVH's `first_hit`), bit for bit.
    /// Rasterises the triangles onto the lattice in parallel (rayon, by
    /// bands of rows). A lattice whose axes do not span a plane across the
    /// direction, or non-finite coordinates, go one ray at a time.
    pub fn first_hits_lattice(&self, l: &Lattice) -> Vec<Option<Hit>> {
        self.lattice(l)
    }

    /// Only the `t` of [`ParallelRays::first_hits_lattice`]'s hits (the
    /// same bits), `f64::INFINITY` where a ray misses: a fifth of the
    /// memory per ray, for callers that want depths alone (the
    /// verification tool's design surface).
    pub fn first_depths_lattice(&self, l: &Lattice) -> Vec<f64> {
        self.lattice(l)
    }

    fn lattice<S: Slot>(&self, l: &Lattice) -> Vec<S> {
        let (nu, nv) = (l.us.len(), l.vs.len());
        let mut out = vec![S::EMPTY; nu * nv];
        let Some(sh) = self.shear else {
            return out;
        };
        if out.is_empty() || self.tris.is_empty() {
            return out;
        }
        let (kx, ky, kz, s) = (sh.kx, sh.ky, sh.kz, sh.s);
        // The test's projection: coordinates across the direction.
        let xp = |v: &V3| [v[kx] - s[0] * v[kz], v[ky] - s[1] * v[kz]];
        let (ju, jv) = (xp(&l.eu), xp(&l.ev));
        let det_j = ju[0] * jv[1] - jv[0] * ju[1];
        let finite = l
            .base
            .coords
            .iter()
            .chain(l.eu.iter())
            .chain(l.ev.iter())
            .all(|x| x.is_finite());
        let nj = ju[0].hypot(ju[1]) * jv[0].hypot(jv[1]);
        if !finite || !det_j.is_finite() || !nj.is_finite() || det_j.abs() <= 1e-9 * nj {
            out.par_iter_mut()
                .with_min_len(1024)
                .enumerate()
                .for_each(|(k, h)| *h = S::from_hit(self.first_hit(&l.origin(k % nu, k / nu))));
            return out;
        }
        let (au, av) = (Axis::new(l.us), Axis::new(l.vs));
        // From the projection to lattice coordinates.
        let m = [jv[1] / det_j, -jv[0] / det_j, -ju[1] / det_j, ju[0] / det_j];
        let xb = xp(&l.base.coords);
        let to_uv = |q: [f64; 2]| {
            let (dx, dy) = (q[0] - xb[0], q[1] - xb[1]);
            [m[0] * dx + m[1] * dy, m[2] * dx + m[3] * dy]
        };
        let mv = (m[2] * m[2] + m[3] * m[3]).sqrt();
        // The scale of every coordinate the test subtracts and multiplies.
        let amax = |v: &[f64]| v.iter().map(|x| x.abs()).fold(0.0f64, f64::max);
        let lat = l.base.coords.amax() + l.eu.amax() * amax(&au.vals) + l.ev.amax() * amax(&av.vals);
        let r = (self.scale + lat) * (1.0 + s[0].abs() + s[1].abs()) + f64::MIN_POSITIVE;
        let eps = f64::EPSILON;
        let base_pad = 1e-9 * r + 128.0 * eps * r;
        let box_pad = 2e-6 * r + base_pad;
        let axis_dir = s[0] == 0.0 && s[1] == 0.0;
        let dir = self.dir;
        let nus = au.vals.len();
        let nvs = av.vals.len();

        let prep = |&(id, ref t): &(u32, [P3; 3])| -> Option<Prep> {
            let q = t.map(|p| xp(&p.coords));
            if axis_dir && (q[0] == q[1] || q[1] == q[2] || q[2] == q[0]) {
                // Along an axis the test's projection is exact: two
                // corners on one ray make two edge functions exact
                // opposites and the third zero, so det is exactly 0.
                return None;
            }
            // Edge lengths in the 1-norm: at least the length, at most
            // sqrt 2 times it (no square roots; the bounds below allow it).
            let len = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]).abs() + (b[1] - a[1]).abs();
            let ls = [len(q[0], q[1]), len(q[1], q[2]), len(q[2], q[0])];
            let lmax = ls[0].max(ls[1]).max(ls[2]);
            let lmin = ls[0].min(ls[1]).min(ls[2]);
            let det2 = (q[1][0] - q[0][0]) * (q[2][1] - q[0][1]) - (q[1][1] - q[0][1]) * (q[2][0] - q[0][0]);
            let mut hp = [[0.0; 3]; 4];
            // `n · x' <= c` in lattice coordinates, `a_u u + a_v v <= c'`, as
            // a bound on u along a row: `u <= α + β v` (kind 1), `u >= α +
            // β v` (kind -1), or no bound but `α - β v >= 0` (kind 0).
            let to_hp = |n: [f64; 2], c: f64| {
                let (a_u, a_v) = (n[0] * ju[0] + n[1] * ju[1], n[0] * jv[0] + n[1] * jv[1]);
                let c = c - (n[0] * xb[0] + n[1] * xb[1]);
                if a_u == 0.0 {
                    [c, a_v, 0.0]
                } else {
                    let inv = 1.0 / a_u;
                    [c * inv, -a_v * inv, a_u.signum()]
                }
            };
            let good = det2.abs() >= 1e-6 * lmax * lmax && lmin > 0.0;
            let (n_hp, vlo, vhi) = if good {
                // The test's edge functions round by at most ~14 eps r
                // times the corners' distance from the ray (<= 2 lmax
                // here): a point that far outside an edge of length l is
                // inside by rounding at most.
                let pad = base_pad + 46.0 * eps * r * lmax / lmin;
                let sg = det2.signum();
                for k in 0..3 {
                    let (a, b) = (q[k], q[(k + 1) % 3]);
                    let n = [sg * (b[1] - a[1]), -sg * (b[0] - a[0])];
                    hp[k] = to_hp(n, n[0] * a[0] + n[1] * a[1] + pad * ls[k]);
                }
                // A sharp corner's padded apex moves out by pad / sin(angle / 2).
                let row_pad = pad * (1.0 + 2.0 * lmax * lmax / det2.abs()) * mv;
                let vs = q.map(|c| to_uv(c)[1]);
                (
                    3,
                    vs[0].min(vs[1]).min(vs[2]) - row_pad,
                    vs[0].max(vs[1]).max(vs[2]) + row_pad,
                )
            } else {
                // Too thin for its edges to bound it: its padded box.
                let lo = [
                    q[0][0].min(q[1][0]).min(q[2][0]) - box_pad,
                    q[0][1].min(q[1][1]).min(q[2][1]) - box_pad,
                ];
                let hi = [
                    q[0][0].max(q[1][0]).max(q[2][0]) + box_pad,
                    q[0][1].max(q[1][1]).max(q[2][1]) + box_pad,
                ];
                hp[0] = to_hp([1.0, 0.0], hi[0]);
                hp[1] = to_hp([-1.0, 0.0], -lo[0]);
                hp[2] = to_hp([0.0, 1.0], hi[1]);
                hp[3] = to_hp([0.0, -1.0], -lo[1]);
                let vs = [[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]].map(|c| to_uv(c)[1]);
                let e = base_pad * mv;
                (
                    4,
                    vs.iter().copied().fold(f64::INFINITY, f64::min) - e,
                    vs.iter().copied().fold(f64::NEG_INFINITY, f64::max) + e,
                )
            };
            let (j0, j1) = (av.first_ge(vlo), av.first_gt(vhi));
            if j0 >= j1 {
                return None;
            }
            let [a, b, c] = t;
            Some(Prep {
                hp,
                n_hp,
                j0: j0 as u32,
                j1: j1 as u32,
                p: t.map(|p| [p[kx], p[ky], p[kz]]),
                id,
                front: (b - a).cross(&(c - a)).dot(&dir) < 0.0,
            })
        };
        // Bands of rows; each triangle listed in every band it reaches, in
        // depth order.
        let threads = rayon::current_num_threads().max(1);
        let br = (BAND_RAYS / nus.max(1)).clamp(1, nvs.div_ceil(4 * threads).max(1));
        let nb = nvs.div_ceil(br);
        // Each triangle's bands beside it, so that the serial listing below
        // reads a few bytes a triangle, not the whole prepared triangle.
        let (preps, bands): (Vec<Option<Prep>>, Vec<(u32, u32)>) = self
            .row_order()
            .par_iter()
            .with_min_len(2048)
            .map(|t| {
                let p = prep(t);
                let b = p.as_ref().map_or((0, 0), |p| {
                    ((p.j0 as usize / br) as u32, ((p.j1 as usize - 1) / br + 1) as u32)
                });
                (p, b)
            })
            .unzip();
        let mut start = vec![0u32; nb + 1];
        for &(b0, b1) in &bands {
            for b in b0..b1 {
                start[b as usize + 1] += 1;
            }
        }
        for b in 0..nb {
            start[b + 1] += start[b];
        }
        let mut fill = start.clone();
        let mut refs = vec![0u32; start[nb] as usize];
        for (k, &(b0, b1)) in bands.iter().enumerate() {
            for b in b0 as usize..b1 as usize {
                refs[fill[b] as usize] = k as u32;
                fill[b] += 1;
            }
        }

        let identity = au.pos.is_none() && av.pos.is_none();
        let mut sorted_out = if identity {
            Vec::new()
        } else {
            vec![S::EMPTY; nus * nvs]
        };
        let res: &mut [S] = if identity { &mut out } else { &mut sorted_out };
        let (us, vs) = (&au.vals[..], &av.vals[..]);
        let perm = |v: &V3| [v[kx], v[ky], v[kz]];
        let (base, eu) = (perm(&l.base.coords), perm(&l.eu));
        // `base + eu * u` of every column, per component (the first two
        // operations of Lattice::origin).
        let col = |k: usize| us.iter().map(|&u| base[k] + eu[k] * u).collect::<Vec<f64>>();
        let lp = Frame {
            col: [col(0), col(1), col(2)],
            ev: perm(&l.ev),
            s,
        };
        res.par_chunks_mut(br * nus).enumerate().for_each(|(b, chunk)| {
            let jb0 = b * br;
            let jb1 = jb0 + chunk.len() / nus;
            // The depth buffer, unless the slots are depths themselves.
            let mut tb = if S::DEPTH_BUFFER {
                vec![f64::INFINITY; chunk.len()]
            } else {
                Vec::new()
            };
            for &pi in &refs[start[b] as usize..start[b + 1] as usize] {
                let Some(p) = &preps[pi as usize] else {
                    continue;
                };
                let (r0, r1) = ((p.j0 as usize).max(jb0), (p.j1 as usize).min(jb1));
                for (j, &v) in vs.iter().enumerate().take(r1).skip(r0) {
                    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
                    for h in &p.hp[..p.n_hp as usize] {
                        if h[2] > 0.0 {
                            hi = hi.min(h[0] + h[1] * v);
                        } else if h[2] < 0.0 {
                            lo = lo.max(h[0] + h[1] * v);
                        } else if h[0] - h[1] * v < 0.0 {
                            lo = f64::INFINITY;
                        }
                    }
                    // (min and max pass over a NaN bound: never NaN here.)
                    if lo > hi {
                        continue;
                    }
                    let (i0, i1) = (au.first_ge(lo), au.first_gt(hi));
                    if i0 >= i1 {
                        continue;
                    }
                    let row = (j - jb0) * nus;
                    let (a, b) = (row + i0, row + i1);
                    let tb = if S::DEPTH_BUFFER { &mut tb[a..b] } else { &mut [] };
                    S::row(p, &lp, v, i0..i1, tb, &mut chunk[a..b]);
                }
            }
        });

        if !identity {
            let (pu, pv) = (au.pos.as_deref(), av.pos.as_deref());
            let at = |p: Option<&[u32]>, k: usize| p.map_or(k, |p| p[k] as usize);
            for j in 0..nvs {
                let oj = at(pv, j);
                for i in 0..nus {
                    out[oj * nu + at(pu, i)] = sorted_out[j * nus + i];
                }
            }
            // Rays with a non-finite coordinate: one at a time.
            for j in 0..nv {
                for i in 0..nu {
                    if !(l.us[i].is_finite() && l.vs[j].is_finite()) {
                        out[j * nu + i] = S::from_hit(self.first_hit(&l.origin(i, j)));
                    }
                }
            }
        }
        out
    }
}

/// True when triangle `p` lies, for every ray of the row segment, wholly
/// behind the nearest hit found so far (`tb`), so the row functions would
/// keep none of its hits: the back faces of a closed part, which come
/// after the front ones in the depth order of `row_order`, cost a
/// subtraction and a product per ray instead of the whole test. A hit's
/// `t` is a convex combination of the corners' depths along the ray
/// (the barycentric weights are all of one sign); the bound is that
/// minimum, less a margin a million times the test's rounding, so a
/// skipped row is one whose every `t` the test would find above `best`.
#[inline]
fn row_hidden(p: &Prep, f: &Frame, v: f64, cols: std::ops::Range<usize>, tb: &[f64]) -> bool {
    let s2 = f.s[2];
    let z = [p.p[0][2], p.p[1][2], p.p[2][2]];
    let (zmin, zmax) = (z[0].min(z[1]).min(z[2]), z[0].max(z[1]).max(z[2]));
    // The depth t = (z - o_z) * s2 is least at the corner nearest along
    // the ray: the lowest z when s2 > 0, the highest when it is negative.
    let near = if s2 > 0.0 { zmin } else { zmax };
    let r2 = f.ev[2] * v;
    // The margin, 1e-9 of the largest |z - o_z| |s2|, is bounded by
    // 1e-9 (|near - o_z| + zmax - zmin) |s2| = 1e-9 |lb| + m0.
    let m0 = 1e-9 * (zmax - zmin) * s2.abs();
    f.col[2][cols].iter().zip(tb).all(|(&c2, &best)| {
        // The ray's origin z, as `row_test` computes it.
        let lb = (near - (c2 + r2)) * s2;
        lb - 1e-9 * lb.abs() - m0 > best
    })
}

/// The outcome of the ray-triangle test for one ray of a row.
struct RowTest {
    outside: bool,
    det: f64,
    t: f64,
    ev: f64,
    ew: f64,
}

/// `intersect` (src/mesh/triangle.rs)'s arithmetic, operation for
/// operation (so the same bits), without its branches, for the ray from
/// `base + eu * u + ev * v` given as its column's `(o0, o1, o2)` and the
/// row's `r = ev * v`.
#[inline(always)]
fn row_test(p: &Prep, s: [f64; 3], r: [f64; 3], o0: f64, o1: f64, o2: f64) -> RowTest {
    let [a, b, c] = &p.p;
    // `base + eu * u + ev * v`, per component, as Lattice::origin.
    let o = [o0 + r[0], o1 + r[1], o2 + r[2]];
    let ta = [a[0] - o[0], a[1] - o[1], a[2] - o[2]];
    let tb = [b[0] - o[0], b[1] - o[1], b[2] - o[2]];
    let tc = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
    let (ax, ay) = (ta[0] - s[0] * ta[2], ta[1] - s[1] * ta[2]);
    let (bx, by) = (tb[0] - s[0] * tb[2], tb[1] - s[1] * tb[2]);
    let (cx, cy) = (tc[0] - s[0] * tc[2], tc[1] - s[1] * tc[2]);
    let eu = cx * by - cy * bx;
    let ev = ax * cy - ay * cx;
    let ew = bx * ay - by * ax;
    let outside = (eu < 0.0 || ev < 0.0 || ew < 0.0) & (eu > 0.0 || ev > 0.0 || ew > 0.0);
    let det = eu + ev + ew;
    let t = (eu * ta[2] + ev * tb[2] + ew * tc[2]) * s[2] / det;
    RowTest {
        outside,
        det,
        t,
        ev,
        ew,
    }
}

/// One row of candidate rays (coordinates `us` along the row, `v` across)
/// against one triangle: [`row_test`] per ray, then the depth buffer `tb`
/// and the hits `out` kept where the hit is nearer, or as near and of a
/// lower triangle index.
#[inline]
fn lattice_row(p: &Prep, f: &Frame, v: f64, cols: std::ops::Range<usize>, tb: &mut [f64], out: &mut [Option<Hit>]) {
    let r = [f.ev[0] * v, f.ev[1] * v, f.ev[2] * v];
    let (c0, c1, c2) = (&f.col[0][cols.clone()], &f.col[1][cols.clone()], &f.col[2][cols]);
    for ((((&o0, &o1), &o2), best), slot) in c0.iter().zip(c1).zip(c2).zip(tb.iter_mut()).zip(out.iter_mut()) {
        let h = row_test(p, f.s, r, o0, o1, o2);
        if !h.outside & (h.det != 0.0) & (h.t >= 0.0) & (h.t <= *best)
            && (h.t < *best || slot.is_none_or(|s| p.id < s.triangle))
        {
            *best = h.t;
            *slot = Some(Hit {
                t: h.t,
                triangle: p.id,
                u: h.ev / h.det,
                v: h.ew / h.det,
                front: p.front,
            });
        }
    }
}

/// [`lattice_row`] for depths alone: the answer is its own depth buffer
/// (of equal depths the triangle does not matter), one array less to
/// fill, read and write per ray.
#[inline]
fn lattice_row_depths(p: &Prep, f: &Frame, v: f64, cols: std::ops::Range<usize>, out: &mut [f64]) {
    let r = [f.ev[0] * v, f.ev[1] * v, f.ev[2] * v];
    let (c0, c1, c2) = (&f.col[0][cols.clone()], &f.col[1][cols.clone()], &f.col[2][cols]);
    for (((&o0, &o1), &o2), best) in c0.iter().zip(c1).zip(c2).zip(out.iter_mut()) {
        let h = row_test(p, f.s, r, o0, o1, o2);
        if !h.outside & (h.det != 0.0) & (h.t >= 0.0) & (h.t <= *best) {
            *best = h.t;
        }
    }
}

/// What the lattice query keeps per ray.
trait Slot: Copy + Send + Sync {
    /// A ray with no hit yet.
    const EMPTY: Self;
    /// The query keeps a depth buffer beside its slots (hits do; depths
    /// are their own).
    const DEPTH_BUFFER: bool;
    /// The answer of a one-ray query.
    fn from_hit(h: Option<Hit>) -> Self;
    /// One row of candidate rays against triangle `p`, unless the triangle
    /// is hidden there ([`row_hidden`]); `tb` is the depth buffer when
    /// [`Slot::DEPTH_BUFFER`], else empty.
    fn row(p: &Prep, f: &Frame, v: f64, cols: std::ops::Range<usize>, tb: &mut [f64], out: &mut [Self]);
}

impl Slot for Option<Hit> {
    const EMPTY: Self = None;
    const DEPTH_BUFFER: bool = true;

    fn from_hit(h: Option<Hit>) -> Self {
        h
    }

    #[inline(always)]
    fn row(p: &Prep, f: &Frame, v: f64, cols: std::ops::Range<usize>, tb: &mut [f64], out: &mut [Self]) {
        if !row_hidden(p, f, v, cols.clone(), tb) {
            lattice_row(p, f, v, cols, tb, out);
        }
    }
}

impl Slot for f64 {
    const EMPTY: Self = f64::INFINITY;
    const DEPTH_BUFFER: bool = false;

    fn from_hit(h: Option<Hit>) -> Self {
        h.map_or(f64::INFINITY, |h| h.t)
    }

    #[inline(always)]
    fn row(p: &Prep, f: &Frame, v: f64, cols: std::ops::Range<usize>, _: &mut [f64], out: &mut [Self]) {
        if !row_hidden(p, f, v, cols.clone(), out) {
            lattice_row_depths(p, f, v, cols, out);
        }
    }
}

#[cfg(test)]
#[path = "parallel_lattice_tests.rs"]
mod tests;
