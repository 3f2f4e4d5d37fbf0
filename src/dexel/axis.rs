//! Swept pieces prepared for one family of axis-parallel rays.
//!
//! A dexel family's rays all run along one coordinate axis, so in
//! [`Piece::interval`] everything but the ray's origin is the same for
//! every ray of the family: the projected ray direction and move, the
//! polygon's edge directions and corners' determinants, and the fixed
//! vector of each quadratic the candidates solve. [`AxisPiece`] computes
//! those once per piece and family and evaluates the rest with the same
//! expressions in the same order, so its intervals equal the general
//! routine's bit for bit; a box around the swept piece across the rays
//! (grown past the routine's tolerances) turns away rays that cannot meet
//! it before any candidate is computed.

use super::sweep::{EPS, Lin, Piece};
use super::tool::{LineMaterial, MoveSweep};
use crate::geometry::{P3, V3};

/// How one polygon edge is followed across the ellipse (fixed per piece
/// and family: it depends only on the edge's slope).
#[derive(Debug, Clone, Copy)]
enum Edge {
    /// The edge has no direction (a constraint on nothing): skipped.
    Skip,
    /// `u = -alpha/gamma + m·t`; roots of `|a - c·u0 + t·q|² = r²`.
    AlongT { m: f64, q: V3, qq: f64 },
    /// `t = -alpha/beta + m·u`; roots of `|a + b·t0 + u·q|² = r²`.
    AlongU { m: f64, q: V3, qq: f64 },
}

/// A [`Piece`] prepared for rays along one coordinate axis.
#[derive(Debug, Clone, Copy)]
pub struct AxisPiece {
    piece: Piece,
    /// The two coordinates across the rays.
    p: usize,
    q: usize,
    /// Box of the swept piece across the rays, grown past the tolerance
    /// of the routine's feasibility checks: `[p_lo, p_hi, q_lo, q_hi]`.
    across: [f64; 4],
    /// Projected ray direction and move.
    b: V3,
    c: V3,
    r2: f64,
    se: f64,
    sd: f64,
    cc: f64,
    /// `b·c / cc`, and the ellipse-extreme quadratic's fixed vector
    /// `b - c·k_b` with its square (`qq < 1e-24`: no roots).
    k_b: f64,
    ell_q: V3,
    ell_qq: f64,
    /// Determinants of the corner pairs (0 when the pair is skipped).
    det: [[f64; 4]; 4],
    edges: [Edge; 4],
}

/// `roots(p, q, r2)` of the sweep module with `q·q` given.
#[inline]
fn roots_q(p: V3, q: &V3, qq: f64, r2: f64) -> Option<(f64, f64)> {
    if qq < 1e-24 {
        return None;
    }
    let pq = p.dot(q);
    let disc = pq * pq - qq * (p.dot(&p) - r2);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    Some(((-pq - s) / qq, (-pq + s) / qq))
}

impl AxisPiece {
    /// `piece` prepared for rays along axis `dir` (0 = X, 1 = Y, 2 = Z).
    pub fn new(piece: &Piece, dir: usize) -> AxisPiece {
        let (p, q) = match dir {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
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
        let lins = lins(piece, 0.0, se, sd);
        let mut det = [[0.0; 4]; 4];
        for i in 0..4 {
            for j in i + 1..4 {
                let (li, lj) = (lins[i], lins[j]);
                let d = li.beta * lj.gamma - lj.beta * li.gamma;
                det[i][j] = if d.abs() < 1e-15 { 0.0 } else { d };
            }
        }
        let edges = lins.map(|l| {
            if l.gamma.abs() >= l.beta.abs() {
                if l.gamma == 0.0 {
                    return Edge::Skip;
                }
                let m = -l.beta / l.gamma;
                let q = b - c * m;
                Edge::AlongT { m, q, qq: q.dot(&q) }
            } else {
                let m = -l.gamma / l.beta;
                let q = b * m - c;
                Edge::AlongU { m, q, qq: q.dot(&q) }
            }
        });
        // A point within sqrt(EPS·(1 + r²)) of the radius, or EPS of a
        // clipping plane, passes the routine's checks; grow well past.
        let margin = (EPS * (1.0 + r2)).sqrt() + 1e-6;
        let (lo, hi) = piece.bbox();
        AxisPiece {
            piece: *piece,
            p,
            q,
            across: [lo[p] - margin, hi[p] + margin, lo[q] - margin, hi[q] + margin],
            b,
            c,
            r2,
            se,
            sd,
            cc,
            k_b,
            ell_q,
            ell_qq: ell_q.dot(&ell_q),
            det,
            edges,
        }
    }

    /// Whether the ray through `(op, oq)` across the family may meet the
    /// swept piece (`false`: it certainly misses).
    #[inline]
    pub fn may_meet(&self, op: f64, oq: f64) -> bool {
        op >= self.across[0] && op <= self.across[1] && oq >= self.across[2] && oq <= self.across[3]
    }

    /// [`Piece::interval`] of the ray through `(op, oq)` across the
    /// family (coordinate 0 along it), bit for bit.
    pub fn interval(&self, op: f64, oq: f64) -> Option<(f64, f64)> {
        if !self.may_meet(op, oq) {
            return None;
        }
        let pc = &self.piece;
        let mut o = P3::origin();
        o[self.p] = op;
        o[self.q] = oq;
        let w = o - pc.c;
        let a = pc.project(w);
        let (b, c, r2) = (self.b, self.c, self.r2);
        let s = pc.a.dot(&w);
        let lins = lins(pc, s, self.se, self.sd);
        let q_ok = |t: f64, u: f64| {
            let v = a + b * t - c * u;
            v.dot(&v) <= r2 + EPS * (1.0 + r2)
        };
        let lin_ok =
            |t: f64, u: f64, skip: usize| lins.iter().enumerate().all(|(k, l)| k == skip || l.at(t, u) >= -EPS);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut take = |t: f64| {
            lo = lo.min(t);
            hi = hi.max(t);
        };
        // The ellipse's extremes in t.
        if self.cc > 1e-24 {
            let k_a = a.dot(&c) / self.cc;
            if let Some((t0, t1)) = roots_q(a - c * k_a, &self.ell_q, self.ell_qq, r2) {
                for t in [t0, t1] {
                    let u = k_a + self.k_b * t;
                    if lin_ok(t, u, usize::MAX) {
                        take(t);
                    }
                }
            }
        }
        // Corners of the polygon.
        for i in 0..4 {
            for j in i + 1..4 {
                let det = self.det[i][j];
                if det == 0.0 {
                    continue;
                }
                let (li, lj) = (lins[i], lins[j]);
                let t = (-li.alpha * lj.gamma + lj.alpha * li.gamma) / det;
                let u = (-li.beta * lj.alpha + lj.beta * li.alpha) / det;
                if q_ok(t, u) && lin_ok(t, u, usize::MAX) {
                    take(t);
                }
            }
        }
        // Edges across the ellipse.
        for (k, (l, edge)) in lins.iter().zip(&self.edges).enumerate() {
            match *edge {
                Edge::Skip => {}
                Edge::AlongT { m, q, qq } => {
                    let u0 = -l.alpha / l.gamma;
                    if let Some((t0, t1)) = roots_q(a - c * u0, &q, qq, r2) {
                        for t in [t0, t1] {
                            if lin_ok(t, u0 + m * t, k) {
                                take(t);
                            }
                        }
                    }
                }
                Edge::AlongU { m, q, qq } => {
                    let t0 = -l.alpha / l.beta;
                    if let Some((u0, u1)) = roots_q(a + b * t0, &q, qq, r2) {
                        for u in [u0, u1] {
                            let t = t0 + m * u;
                            if lin_ok(t, u, k) {
                                take(t);
                            }
                        }
                    }
                }
            }
        }
        (lo <= hi).then_some((lo, hi))
    }
}

/// The four linear constraints of [`Piece::interval`] for a ray whose
/// origin is `s` along the axis from the piece's centre.
#[inline]
fn lins(p: &Piece, s: f64, se: f64, sd: f64) -> [Lin; 4] {
    [
        Lin {
            alpha: s - p.s0,
            beta: se,
            gamma: -sd,
        },
        Lin {
            alpha: p.s1 - s,
            beta: -se,
            gamma: sd,
        },
        Lin {
            alpha: 0.0,
            beta: 0.0,
            gamma: 1.0,
        },
        Lin {
            alpha: 1.0,
            beta: 0.0,
            gamma: -1.0,
        },
    ]
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

    #[test]
    fn axis_interval_equals_the_general_routine_bit_for_bit() {
        let mut g = Rng(0x9e37_79b9_7f4a_7c15);
        let mut met = 0;
        for _ in 0..400 {
            let pc = random_piece(&mut g);
            for dir in 0..3 {
                let ap = AxisPiece::new(&pc, dir);
                let mut e = V3::zeros();
                e[dir] = 1.0;
                for _ in 0..50 {
                    let (op, oq) = (g.f(-5.0, 5.0), g.f(-5.0, 5.0));
                    let mut o = P3::origin();
                    o[ap.p] = op;
                    o[ap.q] = oq;
                    let want = pc.interval(&o, &e);
                    let got = ap.interval(op, oq);
                    assert_eq!(
                        got.map(|(a, b)| (a.to_bits(), b.to_bits())),
                        want.map(|(a, b)| (a.to_bits(), b.to_bits())),
                        "{pc:?} dir {dir} at {op}, {oq}"
                    );
                    met += want.is_some() as usize;
                }
            }
        }
        // The rays are not all misses (the comparison would be vacuous).
        assert!(met > 2_000, "{met}");
    }
}
