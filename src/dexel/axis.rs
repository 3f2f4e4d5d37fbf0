//! Swept pieces prepared for one family of axis-parallel rays.
//!
//! A dexel family's rays all run along one coordinate axis, so in the
//! problem [`Piece::interval`] solves (the extremes of `t` over the convex
//! set of `(t, u)` inside an ellipse and four half-planes) everything but
//! the ray's origin is the same for every ray of the family: the projected
//! ray direction and move, the half-planes' slopes, and the fixed vector of
//! each quadratic the candidates solve. [`AxisPiece`] computes those once
//! per piece and family, and looks at fewer candidates: the ellipse's own
//! extremes first, and only when an extreme lies outside some half-plane
//! the segments of those half-planes' edges inside the ellipse, clipped by
//! the others (in a convex problem whose unconstrained optimum breaks some
//! constraints, the optimum lies on one of those). The corners and edge
//! crossings it finds are the general routine's candidates, so the
//! intervals agree to rounding. A box around the swept piece across the
//! rays turns away rays that cannot meet it before anything is computed.

use super::sweep::{EPS, Piece};
use super::tool::{LineMaterial, MoveSweep};
use crate::geometry::{P3, V3};

/// One polygon edge (the line where a constraint is 0), followed across
/// the ellipse; fixed per piece and family.
#[derive(Debug, Clone, Copy)]
struct Edge {
    /// The constraint constrains nothing (all coefficients 0).
    skip: bool,
    /// `true`: `u = u0 + m·t` with `u0 = alpha·lead` (parameter `t`);
    /// `false`: `t = t0 + m·u` with `t0 = alpha·lead` (parameter `u`).
    along_t: bool,
    /// `-1/gamma` (along t) or `-1/beta` (along u).
    lead: f64,
    m: f64,
    /// The quadratic's fixed vector along the edge and its square.
    q: V3,
    qq: f64,
    inv_qq: f64,
    /// Each other constraint along the edge: `alpha_j + (beta_j or
    /// gamma_j)·x0 + slope_j·x >= 0`; `inv_slope_j` 0 where the edge is
    /// parallel to constraint j.
    slope: [f64; 4],
    inv_slope: [f64; 4],
}

/// A [`Piece`] prepared for rays along one coordinate axis.
#[derive(Debug, Clone, Copy)]
pub struct AxisPiece {
    piece: Piece,
    /// Box of the swept piece across the rays, grown past the tolerance
    /// of the routine's feasibility checks: `[p_lo, p_hi, q_lo, q_hi]`.
    across: [f64; 4],
    /// Projected ray direction and move.
    b: V3,
    c: V3,
    r2: f64,
    /// `1/cc` and `b·c / cc`, and the ellipse-extreme quadratic's fixed
    /// vector `b - c·k_b` with its square; `ellipse`: the ellipse has
    /// extremes in t (`cc` and that square above 1e-24).
    inv_cc: f64,
    k_b: f64,
    ell_q: V3,
    ell_qq: f64,
    inv_ell_qq: f64,
    ellipse: bool,
    /// The projected offset from the centre to the ray's origin
    /// (`a0 + op·ap + oq·aq`), its component along the axis
    /// (`s_0 + op·s_p + oq·s_q`) and its product with `c`.
    a0: V3,
    ap: V3,
    aq: V3,
    s_0: f64,
    s_p: f64,
    s_q: f64,
    ac0: f64,
    ac_p: f64,
    ac_q: f64,
    /// Constant coefficients of the four constraints.
    beta: [f64; 4],
    gamma: [f64; 4],
    edges: [Edge; 4],
    /// Bit k set: edge k is not skipped.
    live: u8,
}

/// Real roots of `|p + x·q|² = r2` with `q·q` (at least 1e-24) and its
/// reciprocal given.
#[inline]
fn roots_q(p: V3, q: &V3, qq: f64, inv_qq: f64, r2: f64) -> Option<(f64, f64)> {
    let pq = p.dot(q);
    let disc = pq * pq - qq * (p.dot(&p) - r2);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some(((-pq - s) * inv_qq, (-pq + s) * inv_qq))
}

impl AxisPiece {
    /// `piece` prepared for rays along axis `dir` (0 = X, 1 = Y, 2 = Z).
    pub fn new(piece: &Piece, dir: usize) -> AxisPiece {
        let (p, q) = across(dir);
        let mut e = V3::zeros();
        e[dir] = 1.0;
        let b = piece.project(e);
        let c = piece.project(piece.d);
        let r2 = piece.r * piece.r;
        let se = piece.a.dot(&e);
        let sd = piece.a.dot(&piece.d);
        let cc = c.dot(&c);
        let (k_b, ell_q) = if cc > 1e-24 {
            let k_b = b.dot(&c) / cc;
            (k_b, b - c * k_b)
        } else {
            (0.0, V3::zeros())
        };
        // The constant parts of the four constraints (alphas vary).
        let lins = piece.constraints(0.0, se, sd);
        let beta = lins.map(|l| l.beta);
        let gamma = lins.map(|l| l.gamma);
        let edges: [Edge; 4] = std::array::from_fn(|k| {
            let l = lins[k];
            let along_t = l.gamma.abs() >= l.beta.abs();
            let (lead, m, q) = if along_t {
                let m = -l.beta / l.gamma;
                (-1.0 / l.gamma, m, b - c * m)
            } else {
                let m = -l.gamma / l.beta;
                (-1.0 / l.beta, m, b * m - c)
            };
            let mut slope = [0.0; 4];
            let mut inv_slope = [0.0; 4];
            for j in 0..4 {
                // Constraint j along the edge; parallel when its slope is
                // rounding of its parts (0 and 1, the two clipping planes,
                // are parallel exactly).
                let (x, y) = if along_t {
                    (beta[j], gamma[j] * m)
                } else {
                    (gamma[j], beta[j] * m)
                };
                slope[j] = x + y;
                if j != k && slope[j].abs() > 1e-12 * (x.abs() + y.abs()) {
                    inv_slope[j] = 1.0 / slope[j];
                }
            }
            Edge {
                skip: l.gamma == 0.0 && l.beta == 0.0,
                along_t,
                lead,
                m,
                q,
                qq: q.dot(&q),
                inv_qq: 1.0 / q.dot(&q),
                slope,
                inv_slope,
            }
        });
        let live = (0..4).filter(|&k| !edges[k].skip).fold(0u8, |acc, k| acc | 1 << k);
        let ell_qq = ell_q.dot(&ell_q);
        let (mut ep, mut eq) = (V3::zeros(), V3::zeros());
        ep[p] = 1.0;
        eq[q] = 1.0;
        let w0 = P3::origin() - piece.c;
        let (a0, ap, aq) = (piece.project(w0), piece.project(ep), piece.project(eq));
        // A point within sqrt(EPS·(1 + r²)) of the radius, or EPS of a
        // clipping plane, passes the routine's checks; grow well past.
        let margin = (EPS * (1.0 + r2)).sqrt() + 1e-6;
        let (lo, hi) = piece.bbox();
        AxisPiece {
            piece: *piece,
            across: [lo[p] - margin, hi[p] + margin, lo[q] - margin, hi[q] + margin],
            b,
            c,
            r2,
            inv_cc: if cc > 1e-24 { 1.0 / cc } else { 0.0 },
            k_b,
            ell_q,
            ell_qq,
            inv_ell_qq: 1.0 / ell_qq,
            ellipse: cc > 1e-24 && ell_qq >= 1e-24,
            a0,
            ap,
            aq,
            s_0: piece.a.dot(&w0),
            s_p: piece.a.dot(&ep),
            s_q: piece.a.dot(&eq),
            ac0: a0.dot(&c),
            ac_p: ap.dot(&c),
            ac_q: aq.dot(&c),
            beta,
            gamma,
            edges,
            live,
        }
    }

    /// Whether the ray through `(op, oq)` across the family may meet the
    /// swept piece (`false`: it certainly misses).
    #[inline]
    pub fn may_meet(&self, op: f64, oq: f64) -> bool {
        op >= self.across[0] && op <= self.across[1] && oq >= self.across[2] && oq <= self.across[3]
    }

    /// [`Piece::interval`] of the ray through `(op, oq)` across the
    /// family (coordinate 0 along it), to rounding.
    pub fn interval(&self, op: f64, oq: f64) -> Option<(f64, f64)> {
        if !self.may_meet(op, oq) {
            return None;
        }
        let pc = &self.piece;
        // Everything below is affine in the origin across the rays.
        let a = self.a0 + self.ap * op + self.aq * oq;
        let (b, c, r2) = (self.b, self.c, self.r2);
        let s = self.s_0 + self.s_p * op + self.s_q * oq;
        let alpha = [s - pc.s0, pc.s1 - s, 0.0, 1.0];
        let (beta, gamma) = (&self.beta, &self.gamma);
        // Constraints broken at (t, u), as bits.
        let broken = |t: f64, u: f64| {
            (0..4).fold(0u8, |acc, k| {
                acc | (((alpha[k] + beta[k] * t + gamma[k] * u) < -EPS) as u8) << k
            })
        };
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut take = |t: f64| {
            lo = lo.min(t);
            hi = hi.max(t);
        };
        let todo = if self.ellipse {
            // The ellipse's extremes in t; none: the ellipse is empty.
            let k_a = (self.ac0 + self.ac_p * op + self.ac_q * oq) * self.inv_cc;
            let (t0, t1) = roots_q(a - c * k_a, &self.ell_q, self.ell_qq, self.inv_ell_qq, r2)?;
            let mut todo = 0;
            for t in [t0, t1] {
                let br = broken(t, k_a + self.k_b * t);
                if br == 0 {
                    take(t);
                }
                todo |= br;
            }
            todo
        } else {
            self.live
        };
        for (k, e) in self.edges.iter().enumerate() {
            if todo & (1 << k) == 0 || e.skip {
                continue;
            }
            // The edge inside the ellipse, as a range of its parameter x.
            let x_at = alpha[k] * e.lead;
            let p = if e.along_t { a - c * x_at } else { a + b * x_at };
            let (mut x0, mut x1) = if e.qq < 1e-24 {
                // The quadratic does not change along the edge.
                if p.dot(&p) > r2 + EPS * (1.0 + r2) {
                    continue;
                }
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                match roots_q(p, &e.q, e.qq, e.inv_qq, r2) {
                    Some(r) => r,
                    None => continue,
                }
            };
            // Clipped by the other constraints.
            for j in 0..4 {
                if j == k {
                    continue;
                }
                let cj = alpha[j] + if e.along_t { gamma[j] } else { beta[j] } * x_at;
                let inv = e.inv_slope[j];
                if inv == 0.0 {
                    if cj < -EPS {
                        x1 = f64::NEG_INFINITY;
                    }
                } else if e.slope[j] > 0.0 {
                    x0 = x0.max(-cj * inv);
                } else {
                    x1 = x1.min(-cj * inv);
                }
            }
            if !(x0 <= x1 && x0.is_finite() && x1.is_finite()) {
                continue;
            }
            if e.along_t {
                take(x0);
                take(x1);
            } else {
                take(x_at + e.m * x0);
                take(x_at + e.m * x1);
            }
        }
        (lo <= hi).then_some((lo, hi))
    }
}

/// The two coordinates across rays along axis `dir` (as the families
/// lay them out).
fn across(dir: usize) -> (usize, usize) {
    match dir {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// A [`MoveSweep`] prepared for one family of axis-parallel rays.
#[derive(Debug, Clone)]
pub struct AxisMove {
    coarse: Option<Vec<AxisPiece>>,
    fine: Vec<AxisPiece>,
    groups: Vec<AxisPiece>,
    substeps: usize,
    group: usize,
}

impl AxisMove {
    /// `sweep` prepared for rays along axis `dir`.
    pub fn new(sweep: &MoveSweep, dir: usize) -> AxisMove {
        let prep = |v: &[Piece]| v.iter().map(|p| AxisPiece::new(p, dir)).collect::<Vec<_>>();
        AxisMove {
            coarse: sweep.coarse.as_deref().map(prep),
            fine: prep(&sweep.fine),
            groups: prep(&sweep.groups),
            substeps: sweep.substeps,
            group: sweep.group,
        }
    }

    /// [`MoveSweep::remove_from`] for the ray through `(op, oq)` across
    /// the family: the same tests in the same order, so the same result.
    pub fn remove_from<M: LineMaterial>(&self, op: f64, oq: f64, m: &mut M, scratch: &mut Vec<(f64, f64, u32)>) -> u64 {
        let hull = |pcs: &[AxisPiece]| {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for p in pcs {
                if let Some((a, b)) = p.interval(op, oq) {
                    lo = lo.min(a);
                    hi = hi.max(b);
                }
            }
            (lo <= hi).then_some((lo, hi))
        };
        super::tool::remove_in_groups(
            self.coarse.as_deref(),
            &self.fine,
            &self.groups,
            self.substeps,
            self.group,
            hull,
            m,
            scratch,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), uniform in [lo, hi).
    struct Rng(u64);
    impl Rng {
        fn f(&mut self, lo: f64, hi: f64) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            lo + (hi - lo) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn v(&mut self, s: f64) -> V3 {
            V3::new(self.f(-s, s), self.f(-s, s), self.f(-s, s))
        }
    }

    fn random_piece(g: &mut Rng) -> Piece {
        let mut a = g.v(1.0);
        // Some pieces along an axis or in a coordinate plane, where
        // projected vectors vanish and candidates degenerate.
        match (g.f(0.0, 4.0)) as u32 {
            0 => a = V3::z(),
            1 => a.z = 0.0,
            _ => {}
        }
        if a.norm() < 1e-3 {
            a = V3::z();
        }
        let cylinder = g.f(0.0, 1.0) < 0.6;
        let r = g.f(0.2, 2.0);
        let s0 = if cylinder { g.f(-1.0, 1.0) } else { g.f(-r, 0.0) };
        let mut d = g.v(3.0);
        match (g.f(0.0, 5.0)) as u32 {
            0 => d = V3::zeros(),
            1 => d = a * g.f(-2.0, 2.0),
            2 => d.z = 0.0,
            _ => {}
        }
        Piece {
            c: P3::from(g.v(1.0)),
            a: a.normalize(),
            r,
            cylinder,
            s0,
            s1: s0 + g.f(0.0, 3.0),
            d,
        }
    }

    /// Whether two intervals agree to rounding: both `None`, or both
    /// present with ends within 1e-12 (relative above 1 mm); a ray that
    /// only grazes the piece (an interval under 1e-6 long, or a touch the
    /// general routine's feasibility tolerance admits) may be present in
    /// one and absent in the other.
    fn agree(got: Option<(f64, f64)>, want: Option<(f64, f64)>) -> bool {
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * (1.0 + x.abs().max(y.abs()));
        match (got, want) {
            (Some(g), Some(w)) => close(g.0, w.0) && close(g.1, w.1),
            (None, None) => true,
            (Some(i), None) | (None, Some(i)) => i.1 - i.0 < 1e-6,
        }
    }

    #[test]
    fn axis_interval_equals_the_general_routine() {
        let mut g = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut met, mut grazed) = (0, 0);
        for _ in 0..2000 {
            let pc = random_piece(&mut g);
            for dir in 0..3 {
                let ap = AxisPiece::new(&pc, dir);
                let mut e = V3::zeros();
                e[dir] = 1.0;
                for _ in 0..50 {
                    let (op, oq) = (g.f(-5.0, 5.0), g.f(-5.0, 5.0));
                    let mut o = P3::origin();
                    o[across(dir).0] = op;
                    o[across(dir).1] = oq;
                    let want = pc.interval(&o, &e);
                    let got = ap.interval(op, oq);
                    assert!(agree(got, want), "{pc:?} dir {dir} at {op}, {oq}: {got:?} vs {want:?}");
                    met += want.is_some() as usize;
                    grazed += (got.is_some() != want.is_some()) as usize;
                }
            }
        }
        // The rays are not all misses (the comparison would be vacuous),
        // and grazing rays are rare.
        assert!(met > 20_000 && grazed < 10, "{met} {grazed}");
    }

    /// Brute force: the piece stamped at 301 points of the move, each
    /// stamp's interval on the line sampled every 0.004 mm.
    fn sampled(p: &Piece, o: &P3, e: &V3) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..=300 {
            let c = p.c + p.d * (k as f64 / 300.0);
            for i in 0..=4000 {
                let t = -8.0 + 16.0 * i as f64 / 4000.0;
                let w = o + e * t - c;
                let s = p.a.dot(&w);
                let dist = if p.cylinder { (w - p.a * s).norm() } else { w.norm() };
                if dist <= p.r && s >= p.s0 && s <= p.s1 {
                    lo = lo.min(t);
                    hi = hi.max(t);
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    #[test]
    fn axis_interval_matches_sampling_on_random_pieces() {
        let mut g = Rng(0x2545_f491_4f6c_dd1d);
        let mut met = 0;
        for _ in 0..40 {
            let pc = random_piece(&mut g);
            let dir = (g.f(0.0, 3.0) as usize).min(2);
            let ap = AxisPiece::new(&pc, dir);
            let mut e = V3::zeros();
            e[dir] = 1.0;
            for _ in 0..3 {
                let (op, oq) = (g.f(-3.0, 3.0), g.f(-3.0, 3.0));
                let mut o = P3::origin();
                o[across(dir).0] = op;
                o[across(dir).1] = oq;
                let got = ap.interval(op, oq);
                let want = sampled(&pc, &o, &e);
                // The sampler's steps (a move of up to ~5 mm in 300
                // stamps, t every 0.004 mm) bound its error.
                match (got, want) {
                    (Some(g), Some(w)) => {
                        met += 1;
                        assert!(
                            (g.0 - w.0).abs() < 0.03 && (g.1 - w.1).abs() < 0.03,
                            "{pc:?} {o:?}: {g:?} {w:?}"
                        )
                    }
                    (None, None) => {}
                    (Some(g), None) => assert!(g.1 - g.0 < 0.03, "{pc:?} {o:?}: {g:?}"),
                    (None, Some(w)) => panic!("{pc:?} {o:?}: missed {w:?}"),
                }
            }
        }
        assert!(met > 20, "{met}");
    }
}
