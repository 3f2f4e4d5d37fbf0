//! A tool as convex pieces, and a move between two cutter locations as
//! the pieces swept along straight sub-moves.
//!
//! Flat end mill: one cylinder. Ball: a ball on a cylinder. Torus: an
//! inner cylinder, an outer cylinder above the corner, and the corner
//! (a tube around the axis) as a ring of balls; the ring lies inside the
//! tube and every point of the tube is within [`ring_error`] of it for `k`
//! balls, about `(R - r)·R·(π/k)²/(2r)` (stated as
//! [`MoveSweep::shape_error_mm`]).
//!
//! A move whose tool axis turns (5-axis) is split into `n` sub-moves with
//! the axis fixed at each sub-move's middle direction (spherical
//! interpolation of the two axes), turning the tool about a pivot half-way
//! up the flutes (h = L/2) whose path is followed by chords. A sub-move
//! turning by φ = θ/n then moves no tool point by more than
//! `φ/2·√(h² + R²) + h·φ²/4` (rotation about the pivot, plus the chord's
//! sagitta, counted twice); about half the error of pivoting at the tip
//! (`φ/2·√(L² + R²)`), so about half the sub-moves. `n` is chosen so that
//! is within the sweep tolerance left by the torus ring. Grown copies of
//! the whole move and of runs of sub-moves hold them, so a dexel a copy
//! misses (or whose material it does not touch) skips them all.

use super::sweep::Piece;
use crate::cutter::Cutter;
use crate::geometry::{P3, V3};

/// One cutter location: tool tip and unit tool axis (tip towards holder).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    /// The tool tip (the lowest point on the axis), mm.
    pub tip: P3,
    /// Unit tool axis, pointing from the tip towards the holder.
    pub axis: V3,
}

/// The cutting part of a tool: its shape and flute length (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolShape {
    /// The cutter's profile (flat, ball, torus).
    pub cutter: Cutter,
    /// Flute length, mm: the tool is cut off this far above the tip (the
    /// shank is not simulated).
    pub length: f64,
}

impl ToolShape {
    /// Distance from the tip to the farthest point of the tool.
    pub fn reach(&self) -> f64 {
        self.length.hypot(self.cutter.radius())
    }

    /// Number of balls in a torus corner ring for a shape error `tol`:
    /// the fewest whose [`ring_error`] is at most `tol`.
    fn ring_count(&self, tol: f64) -> usize {
        match self.cutter {
            Cutter::Torus { radius, corner } => {
                let rho = radius - corner;
                if rho <= 0.0 {
                    return 1;
                }
                // The along-the-ring bound alone: k ≥ πρ/tol.
                let linear = (std::f64::consts::PI * rho / tol).ceil();
                // The sagitta bound, solved for the half-angle δ = π/k:
                // 2ρ(ρ + r)(1 - cos δ) ≤ (r + tol)² - r².
                let room = (tol * (2.0 * corner + tol)) / (2.0 * rho * (rho + corner));
                let sag = if room >= 2.0 {
                    1.0
                } else {
                    (std::f64::consts::PI / (1.0 - room).acos()).ceil()
                };
                let mut k = linear.min(sag).clamp(8.0, 2880.0) as usize;
                // Rounding in the formulas: step until the bound holds.
                while k < 2880 && ring_error(rho, corner, k) > tol {
                    k += 1;
                }
                k
            }
            _ => 0,
        }
    }

    /// The convex pieces of the tool at `loc`, each moving by `d`.
    pub fn pieces(&self, loc: &Location, d: V3, ring: usize, out: &mut Vec<Piece>) {
        let (p, a, l) = (loc.tip, loc.axis, self.length);
        let cyl = |r: f64, s0: f64, s1: f64| Piece {
            c: p,
            a,
            r,
            cylinder: true,
            s0,
            s1,
            d,
        };
        match self.cutter {
            Cutter::Flat { radius } => out.push(cyl(radius, 0.0, l)),
            Cutter::Ball { radius } => {
                out.push(Piece {
                    c: p + a * radius,
                    a,
                    r: radius,
                    cylinder: false,
                    s0: -radius,
                    s1: (l - radius).min(radius),
                    d,
                });
                if l > radius {
                    out.push(cyl(radius, radius, l));
                }
            }
            Cutter::Torus { radius, corner } => {
                let rho = radius - corner;
                if rho > 0.0 {
                    out.push(cyl(rho, 0.0, l));
                }
                if l > corner {
                    out.push(cyl(radius, corner, l));
                }
                let (e1, e2) = perpendiculars(&a);
                let k = ring.max(1);
                for i in 0..k {
                    let phi = std::f64::consts::TAU * i as f64 / k as f64;
                    out.push(Piece {
                        c: p + a * corner + (e1 * phi.cos() + e2 * phi.sin()) * rho,
                        a,
                        r: corner,
                        cylinder: false,
                        s0: -corner,
                        s1: (l - corner).min(0.0),
                        d,
                    });
                }
            }
        }
    }
}

/// The farthest a point of a torus corner (a tube of radius `r` about a
/// circle of radius `rho`) lies from the nearest of `k` balls of radius
/// `r` centred evenly on that circle, mm.
///
/// A tube point `q` is `a` out from the circle and `b` along the axis
/// (a² + b² ≤ r²) in the meridian of some circle point; the nearest ball
/// centre `c` is at most δ = π/k round the circle from it, so
/// |q − c|² = a² + b² + 2ρ(ρ + a)(1 − cos δ) ≤ r² + 2ρ(ρ + r)(1 − cos δ):
/// `q` is within √(r² + 2ρ(ρ + r)(1 − cos δ)) − r of that ball, about
/// ρ(ρ + r)δ²/(2r). The plainer bound, `q` within the arc ρδ of the
/// centre's ball, is kept where it is smaller (a thin corner). The
/// nearest point of the ball lies between `q` and `c`, so a ball clipped
/// at its equator (the lower half-tube's balls) gives the same bound.
///
/// Until the eighth session of 7 December 2026 only the arc bound was
/// used: a torus 1 mm across with a 0.25 mm corner took 126 balls at a
/// tolerance of 0.0125 mm, where 20 keep the same bound.
pub fn ring_error(rho: f64, r: f64, k: usize) -> f64 {
    let delta = std::f64::consts::PI / k.max(1) as f64;
    let one_minus_cos = 2.0 * (0.5 * delta).sin().powi(2);
    let sag = (r * r + 2.0 * rho * (rho + r) * one_minus_cos).sqrt() - r;
    sag.min(rho * delta)
}

/// Two unit vectors across `a` (and each other).
pub fn perpendiculars(a: &V3) -> (V3, V3) {
    let helper = if a.x.abs() < 0.9 { V3::x() } else { V3::y() };
    let e1 = a.cross(&helper).normalize();
    (e1, a.cross(&e1))
}

/// Spherical interpolation between unit vectors (`a0` when they are
/// opposite, which no tool path asks for).
fn slerp(a0: &V3, a1: &V3, u: f64) -> V3 {
    let c = a0.dot(a1).clamp(-1.0, 1.0);
    let th = c.acos();
    if th < 1e-9 {
        return *a0;
    }
    let s = th.sin();
    if s < 1e-9 {
        return *a0;
    }
    (a0 * ((1.0 - u) * th).sin() / s + a1 * (u * th).sin() / s).normalize()
}

/// Material along one line, as [`MoveSweep::remove_from`] sees it.
pub trait LineMaterial {
    /// Whether there is material strictly inside (t0, t1).
    fn has(&self, t0: f64, t1: f64) -> bool;
    /// Remove (t0, t1).
    fn remove(&mut self, t0: f64, t1: f64);
}

/// The volume one move sweeps, as pieces.
#[derive(Debug, Clone)]
pub struct MoveSweep {
    /// Grown pieces holding all of `fine` (`None`: `fine` is one sub-move
    /// and needs no culling copy).
    pub coarse: Option<Vec<Piece>>,
    /// Pieces of every sub-move.
    pub fine: Vec<Piece>,
    /// Sub-moves the move was split into.
    pub substeps: usize,
    /// Grown pieces of each run of `group` consecutive sub-moves (empty
    /// when there is one sub-move): a line whose material a group's copy
    /// does not touch skips that group's sub-moves.
    pub groups: Vec<Piece>,
    /// Sub-moves per group.
    pub group: usize,
    /// Low corner of a box around everything the move sweeps, mm.
    pub lo: [f64; 3],
    /// High corner of that box, mm.
    pub hi: [f64; 3],
    /// Largest distance from the true swept solid to the pieces', mm.
    pub shape_error_mm: f64,
}

impl MoveSweep {
    /// The sweep of `tool` from `from` to `to`, within `tol` mm; a torus
    /// corner ring takes at most half of `tol`.
    pub fn new(tool: &ToolShape, from: &Location, to: &Location, tol: f64) -> MoveSweep {
        MoveSweep::with_ring_tol(tool, from, to, tol, 0.5 * tol)
    }

    /// The sweep of `tool` from `from` to `to`, within `tol` mm, its torus
    /// corner ring within `ring_tol` (at most `tol / 2`): a tight bound
    /// for the ring alone is cheap, its error falling with the square of
    /// the ball count, where a tight `tol` multiplies a turning axis's
    /// sub-moves.
    pub fn with_ring_tol(tool: &ToolShape, from: &Location, to: &Location, tol: f64, ring_tol: f64) -> MoveSweep {
        let theta = from.axis.dot(&to.axis).clamp(-1.0, 1.0).acos();
        let ring = tool.ring_count(ring_tol.min(0.5 * tol));
        let ring_err = if ring > 0 {
            let corner = tool.cutter.corner_radius();
            ring_error(tool.cutter.radius() - corner, corner, ring)
        } else {
            0.0
        };
        // The axis error gets what the ring leaves of `tol` (at least
        // half of it: the ring takes at most tol/2).
        let budget = (tol - ring_err).max(0.5 * tol);
        // Each span turns the tool about a pivot half-way up the flutes:
        // the pivot moves along the chord of its path, the axis is fixed
        // at the span's middle direction. No tool point is then farther
        // than `err(φ)` from where it should be, for a span turning by φ:
        // φ/2 times the pivot's reach (rotation) plus the pivot's chord
        // sagitta (≤ h·φ²/8, counted as h·φ²/4).
        let h = 0.5 * tool.length;
        let rp = h.hypot(tool.cutter.radius());
        let err = |phi: f64| 0.5 * phi * rp + 0.25 * h * phi * phi;
        let pivot = |u: f64| from.tip + (to.tip - from.tip) * u + slerp(&from.axis, &to.axis, u) * h;
        let span = |u0: f64, u1: f64, out: &mut Vec<Piece>| {
            let axis = if theta < 1e-12 {
                from.axis
            } else {
                slerp(&from.axis, &to.axis, 0.5 * (u0 + u1))
            };
            let (q0, q1) = if theta < 1e-12 {
                (from.tip + (to.tip - from.tip) * u0, from.tip + (to.tip - from.tip) * u1)
            } else {
                (pivot(u0) - axis * h, pivot(u1) - axis * h)
            };
            tool.pieces(&Location { tip: q0, axis }, q1 - q0, ring, out);
        };
        let mut n = if theta < 1e-12 {
            1
        } else {
            ((theta * rp / (2.0 * budget)).ceil() as usize).clamp(1, 100_000)
        };
        while n < 100_000 && theta >= 1e-12 && err(theta / n as f64) > budget {
            n += 1;
        }
        let mut fine = Vec::new();
        for k in 0..n {
            span(k as f64 / n as f64, (k + 1) as f64 / n as f64, &mut fine);
        }
        let axis_err = if n > 1 { err(theta / n as f64) } else { 0.0 };
        // Groups of about √n sub-moves: a line tests n/g groups and the
        // sub-moves of the few groups that reach its material. A group's
        // copy is grown by its own error plus a sub-move's, so it holds
        // every sub-move of the group.
        let group = if n > 1 { (n as f64).sqrt().ceil() as usize } else { n };
        let mut groups = Vec::new();
        if n > 1 {
            for k0 in (0..n).step_by(group) {
                let k1 = (k0 + group).min(n);
                let (u0, u1) = (k0 as f64 / n as f64, k1 as f64 / n as f64);
                let at = groups.len();
                span(u0, u1, &mut groups);
                let grow = err(theta * (u1 - u0)) + axis_err + 1e-9;
                for p in &mut groups[at..] {
                    *p = p.grown(grow);
                }
            }
        }
        let coarse = (n > 1).then(|| {
            let mut v = Vec::new();
            span(0.0, 1.0, &mut v);
            let grow = err(theta) + axis_err + 1e-9;
            v.iter().map(|p| p.grown(grow)).collect()
        });
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in coarse.as_deref().unwrap_or(&fine[..]) {
            let (l, h) = p.bbox();
            for k in 0..3 {
                lo[k] = lo[k].min(l[k]);
                hi[k] = hi[k].max(h[k]);
            }
        }
        MoveSweep {
            coarse,
            fine,
            substeps: n,
            groups,
            group,
            lo,
            hi,
            shape_error_mm: axis_err + ring_err,
        }
    }

    /// The interval the whole move removes from the line `o + t·e` (the
    /// hull of the pieces' intervals; the pieces of one tool overlap, so
    /// for a convex tool that is exact per sub-move), judged with the
    /// culling copy when there is one.
    pub fn hull(&self, o: &P3, e: &V3) -> Option<(f64, f64)> {
        let pieces = self.coarse.as_deref().unwrap_or(&self.fine[..]);
        hull_of(pieces, o, e)
    }
}

impl MoveSweep {
    /// Remove the move from the line `o + t·e` (`o` on the line, `e` a
    /// unit direction): every sub-move's interval that can reach the
    /// material. Returns the sub-move (and group) interval tests made.
    ///
    /// With one sub-move that is its exact interval. With several, the
    /// whole move's grown copy is tested first, then each group's grown
    /// copy; only groups whose copy meets material test their sub-moves.
    /// The group with the lowest start and the one with the highest end
    /// go first, so the bulk is removed early and most other groups find
    /// no material left in reach. Every skipped sub-move's interval lies
    /// inside its group's, which held no material: the result is the same
    /// as removing every sub-move.
    pub fn remove_from<M: LineMaterial>(&self, o: &P3, e: &V3, m: &mut M, scratch: &mut Vec<(f64, f64, u32)>) -> u64 {
        remove_in_groups(
            self.coarse.as_deref(),
            &self.fine,
            &self.groups,
            self.substeps,
            self.group,
            |pcs: &[Piece]| hull_of(pcs, o, e),
            m,
            scratch,
        )
    }
}

/// [`MoveSweep::remove_from`] over any form of the pieces: `hull` gives
/// the interval a run of pieces removes from the line. Shared with the
/// pieces prepared for one ray family ([`super::axis::AxisMove`]), so both
/// make the same tests in the same order.
#[allow(clippy::too_many_arguments)]
pub(super) fn remove_in_groups<P, M: LineMaterial>(
    coarse: Option<&[P]>,
    fine: &[P],
    groups: &[P],
    substeps: usize,
    group: usize,
    hull: impl Fn(&[P]) -> Option<(f64, f64)>,
    m: &mut M,
    scratch: &mut Vec<(f64, f64, u32)>,
) -> u64 {
    let Some((t0, t1)) = hull(coarse.unwrap_or(fine)) else {
        return 0;
    };
    if !m.has(t0, t1) {
        return 0;
    }
    if coarse.is_none() {
        m.remove(t0, t1);
        return 0;
    }
    let per = fine.len() / substeps;
    let mut tests = 0u64;
    scratch.clear();
    for (g, pcs) in groups.chunks(per).enumerate() {
        tests += 1;
        if let Some((a, b)) = hull(pcs) {
            scratch.push((a, b, g as u32));
        }
    }
    // Lowest start first, then highest end, then the rest in order.
    let lo = (0..scratch.len()).min_by(|&i, &j| scratch[i].0.total_cmp(&scratch[j].0));
    let hi = (0..scratch.len()).max_by(|&i, &j| scratch[i].1.total_cmp(&scratch[j].1));
    let order = lo
        .into_iter()
        .chain(hi.filter(|&h| Some(h) != lo))
        .chain((0..scratch.len()).filter(|&k| Some(k) != lo && Some(k) != hi));
    for k in order {
        let (a, b, g) = scratch[k];
        if !m.has(a, b) {
            continue;
        }
        let k0 = g as usize * group;
        let k1 = (k0 + group).min(substeps);
        for sub in fine[k0 * per..k1 * per].chunks(per) {
            tests += 1;
            if let Some((a, b)) = hull(sub) {
                m.remove(a, b);
            }
        }
    }
    tests
}

/// Smallest interval holding every piece's interval on the line.
pub fn hull_of(pieces: &[Piece], o: &P3, e: &V3) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in pieces {
        if let Some((a, b)) = p.interval(o, e) {
            lo = lo.min(a);
            hi = hi.max(b);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point of the lower half-tube, on a fine grid of its meridian
    /// discs and round the circle, against the `k` balls themselves.
    #[test]
    fn ring_error_bounds_the_distance_from_every_tube_point() {
        for &(rho, r) in &[(0.25, 0.25), (1.5, 0.5), (0.1, 0.5), (2.0, 0.05), (0.5, 1e-4)] {
            for k in [8usize, 11, 14, 40, 126] {
                let bound = ring_error(rho, r, k);
                let centres: Vec<(f64, f64)> = (0..k)
                    .map(|i| {
                        let phi = std::f64::consts::TAU * i as f64 / k as f64;
                        (rho * phi.cos(), rho * phi.sin())
                    })
                    .collect();
                let mut worst = 0.0f64;
                for ia in 0..=20 {
                    for ib in 0..=10 {
                        let (a, b) = (r * (ia as f64 / 10.0 - 1.0), -r * ib as f64 / 10.0);
                        if a * a + b * b > r * r * (1.0 + 1e-12) {
                            continue;
                        }
                        for ip in 0..=64 {
                            // From one centre to the next, the middle included.
                            let phi = std::f64::consts::TAU / k as f64 * ip as f64 / 64.0;
                            let (x, y) = ((rho + a) * phi.cos(), (rho + a) * phi.sin());
                            let d = centres
                                .iter()
                                .map(|&(cx, cy)| ((x - cx).powi(2) + (y - cy).powi(2) + b * b).sqrt() - r)
                                .fold(f64::INFINITY, f64::min)
                                .max(0.0);
                            worst = worst.max(d);
                        }
                    }
                }
                assert!(worst <= bound + 1e-12, "rho {rho} r {r} k {k}: {worst} > {bound}");
                // Tight: the worst point (the outer rim, half-way between
                // two balls) is on the sampling grid.
                assert!(worst >= 0.9 * bound, "rho {rho} r {r} k {k}: {worst} << {bound}");
            }
        }
    }

    #[test]
    fn ring_count_is_the_fewest_balls_within_the_tolerance() {
        for &(radius, corner) in &[(0.5, 0.25), (2.0, 0.5), (3.0, 2.9), (1.0, 0.01)] {
            let tool = ToolShape {
                cutter: Cutter::Torus { radius, corner },
                length: 5.0,
            };
            let rho = radius - corner;
            for tol in [0.1, 0.0125, 0.005, 0.001] {
                let k = tool.ring_count(tol);
                assert!(ring_error(rho, corner, k) <= tol, "{radius} {corner} {tol}: {k}");
                assert!(
                    k == 8 || ring_error(rho, corner, k - 1) > tol,
                    "{radius} {corner} {tol}: {k}"
                );
                // Never more than the arc bound alone asked for.
                assert!(k <= ((std::f64::consts::PI * rho / tol).ceil() as usize).max(8));
            }
        }
        // The dome sample's torus at half the default tolerance of a
        // 0.025 mm spacing: 20 balls, where the arc bound took 126.
        let dome = ToolShape {
            cutter: Cutter::Torus {
                radius: 0.5,
                corner: 0.25,
            },
            length: 5.0,
        };
        assert_eq!(dome.ring_count(0.00625), 20);
    }

    #[test]
    fn flat_tool_vertical_ray_hits_bottom_and_top() {
        let tool = ToolShape {
            cutter: Cutter::Flat { radius: 3.0 },
            length: 10.0,
        };
        let a = Location {
            tip: P3::new(0.0, 0.0, -9.5),
            axis: V3::z(),
        };
        let b = Location {
            tip: P3::new(0.0, 5.0, -9.5),
            axis: V3::z(),
        };
        let s = MoveSweep::new(&tool, &a, &b, 0.005);
        assert_eq!(s.substeps, 1);
        let (t0, t1) = s.hull(&P3::new(2.9, 2.0, 0.0), &V3::z()).unwrap();
        assert!((t0 + 9.5).abs() < 1e-9 && (t1 - 0.5).abs() < 1e-9);
        assert!(s.hull(&P3::new(3.1, 2.0, 0.0), &V3::z()).is_none());
    }

    #[test]
    fn turning_axis_splits_and_culling_copy_holds_sub_moves() {
        let tool = ToolShape {
            cutter: Cutter::Torus {
                radius: 2.0,
                corner: 0.5,
            },
            length: 6.0,
        };
        let a = Location {
            tip: P3::new(0.0, 0.0, 0.0),
            axis: V3::z(),
        };
        let b = Location {
            tip: P3::new(1.0, 0.0, 0.0),
            axis: V3::new(0.3, 0.0, 1.0).normalize(),
        };
        let s = MoveSweep::new(&tool, &a, &b, 0.05);
        assert!(s.substeps > 10);
        assert!(s.shape_error_mm <= 0.05 + 1e-12);
        for i in 0..40 {
            let o = P3::new(-3.0 + 0.2 * i as f64, 0.37, 0.0);
            if let Some((f0, f1)) = hull_of(&s.fine, &o, &V3::z()) {
                let (c0, c1) = s.hull(&o, &V3::z()).unwrap();
                assert!(c0 <= f0 && c1 >= f1);
            }
        }
    }
}
