//! What the contacts say about the part: gauge width (Bayesteh 2013,
//! section 4.4), circle diameter, centre and roundness, deviation from the
//! design, which parts of the design the probe could not reach, and the
//! uncertainty of each figure from the noise model.
//!
//! Contacts are probe centres. A surface lies `R_e` from them, so fitted
//! figures are compensated exactly: a plug's radius is the centres' radius
//! minus `R_e`, a bore's plus `R_e`; a width is the centre distance minus
//! `D_e`. Uncertainties propagate the per-contact standard deviation `u`
//! through each fit linearly. Fields hold standard uncertainties (k = 1);
//! the report adds the 99 % interval, [`K99`] times them.

use super::ProbeError;
use super::fit::{self, CircleFit, LineFit, ZoneFit};
use super::part::{Part, Prim};
use super::scan::Contact;
use crate::geometry::{P2, V2};

/// Coverage factor of the 99 % interval of a normal estimate.
pub const K99: f64 = 2.576;

/// A measured circle (plug or bore).
#[derive(Debug, Clone, PartialEq)]
pub struct CircleMeasure {
    /// True for a plug (material inside), false for a bore.
    pub plug: bool,
    /// Least-squares circle of the centres.
    pub lsq: CircleFit,
    /// Minimum-zone circles of the centres.
    pub zone: ZoneFit,
    /// Diameter of the surface by least squares (mm).
    pub diameter_lsq_mm: f64,
    /// Diameter of the surface from the mean of the minimum-zone radii (mm).
    pub diameter_mz_mm: f64,
    /// Standard uncertainty of the least-squares diameter (mm).
    pub u_diameter_mm: f64,
    /// Standard uncertainty of each centre coordinate (mm).
    pub u_center_mm: [f64; 2],
}

/// Measure a circle from scanned contacts; `u` is the per-contact standard
/// uncertainty (mm).
pub fn circle(contacts: &[Contact], re: f64, u: f64) -> Result<CircleMeasure, ProbeError> {
    let pts: Vec<P2> = contacts.iter().map(|c| c.center).collect();
    let lsq = fit::circle_lsq(&pts)?;
    let zone = fit::circle_min_zone(&pts)?;
    // Approaching towards the centre means the material is inside.
    let inward = contacts
        .iter()
        .filter(|c| c.dir.dot(&(lsq.center - c.center)) > 0.0)
        .count();
    let plug = 2 * inward >= contacts.len();
    let comp = if plug { -re } else { re };
    Ok(CircleMeasure {
        plug,
        diameter_lsq_mm: 2.0 * (lsq.radius + comp),
        diameter_mz_mm: (zone.r_in + zone.r_out) + 2.0 * comp,
        u_diameter_mm: 2.0 * u * lsq.cov_unit[(2, 2)].sqrt(),
        u_center_mm: [u * lsq.cov_unit[(0, 0)].sqrt(), u * lsq.cov_unit[(1, 1)].sqrt()],
        lsq,
        zone,
    })
}

/// A gauge width: a line fitted to one face and a point on the other.
#[derive(Debug, Clone, PartialEq)]
pub struct WidthMeasure {
    /// The fitted face (probe centres).
    pub face: LineFit,
    /// The contact on the opposite face.
    pub other: P2,
    /// The width (mm): centre distance minus D_e.
    pub width_mm: f64,
    /// Its standard uncertainty (mm).
    pub u_width_mm: f64,
}

/// Measure a width from the contacts on one face and one on the other.
pub fn width(face: &[Contact], other: &Contact, re: f64, u: f64) -> Result<WidthMeasure, ProbeError> {
    let pts: Vec<P2> = face.iter().map(|c| c.center).collect();
    let line = fit::line(&pts)?;
    let f = line.offset_sigma_factor(other.center);
    Ok(WidthMeasure {
        width_mm: line.offset(other.center).abs() - 2.0 * re,
        u_width_mm: u * (1.0 + f * f).sqrt(),
        face: line,
        other: other.center,
    })
}

/// One contact against the design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deviation {
    /// The surface point: the centre moved `R_e` towards the design.
    pub surface: P2,
    /// Signed deviation (mm): positive where the part stands proud of the
    /// design (the probe stopped early), negative where it is short.
    pub deviation_mm: f64,
    /// Standard uncertainty of the deviation (mm).
    pub u_mm: f64,
    /// The nearest design piece.
    pub prim: usize,
}

/// Deviation of every contact from the design contour.
pub fn deviations(design: &Part, contacts: &[Contact], re: f64, u: f64) -> Vec<Deviation> {
    contacts
        .iter()
        .map(|c| {
            let (d, prim) = design.distance(c.center);
            let foot = design.prims[prim].nearest(c.center);
            let inside = design.in_material(c.center);
            let signed = if inside { -d } else { d };
            let n = if d > 0.0 { (c.center - foot) / d } else { -c.dir };
            let n = if inside { -n } else { n };
            // Only the part of the touch error across the surface counts.
            let across = c.dir.dot(&n).abs();
            Deviation {
                surface: c.center - n * re,
                deviation_mm: signed - re,
                u_mm: u * across,
                prim,
            }
        })
        .collect()
}

/// A stretch of the design the probe cannot reach (narrower than D_e, or
/// the inside of a sharp concave corner).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unreachable {
    /// First unreachable point along the contour.
    pub from: P2,
    /// Last unreachable point.
    pub to: P2,
    /// Length along the contour (mm).
    pub length_mm: f64,
}

/// Coverage of the design by a scan.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Coverage {
    /// Stretches the probe cannot reach, on the contours it touched.
    pub unreachable: Vec<Unreachable>,
    /// Skipped features: design pieces with no contact that a disc of
    /// diameter max(R_s, D_e), moving freely from where the scan went, can
    /// touch along more than 1.5 R_s. A feature larger than R_s is open at
    /// least R_s wide and long; contacts are R_s apart along straight
    /// faces, a little more round corners and concave arcs, hence the
    /// margin.
    pub missed: Vec<usize>,
    /// Contacts on each design piece.
    pub per_piece: Vec<usize>,
}

/// The side of a boundary point away from the material.
fn free_normal(design: &Part, q: P2, tangent: V2) -> V2 {
    let n = V2::new(-tangent.y, tangent.x);
    let eps = 1e-7 * (1.0 + q.coords.norm());
    if design.in_material(q + n * eps) { -n } else { n }
}

/// Which stretches of the touched contours a tip of radius `re` cannot
/// reach, and which pieces the contacts skipped.
pub fn coverage(design: &Part, contacts: &[Contact], re: f64, rs: f64) -> Coverage {
    let mut per_piece = vec![0usize; design.prims.len()];
    for c in contacts {
        per_piece[design.distance(c.center).1] += 1;
    }
    let mut loops: Vec<usize> = per_piece
        .iter()
        .enumerate()
        .filter(|&(_, &n)| n > 0)
        .map(|(i, _)| design.loop_of(i))
        .collect();
    loops.dedup();
    loops.sort_unstable();
    loops.dedup();
    // A quarter of the tip radius, but never more than a million samples:
    // the work stays bounded by the contour, whatever the tip.
    let contour_len: f64 = loops
        .iter()
        .flat_map(|&l| design.loops[l].clone())
        .map(|i| design.prims[i].length())
        .sum();
    let h = (re / 4.0).max(contour_len / 1e6);
    // The reach of a feature "larger than R_s".
    let rf = re.max(rs / 2.0);
    let mut cov = Coverage {
        per_piece,
        ..Default::default()
    };
    // Built only when a piece went untouched: the flood is the slow part.
    let grid = std::cell::OnceCell::new();
    for l in loops {
        // (point, reachable, length it stands for), in contour order.
        let mut samples: Vec<(P2, bool, f64)> = Vec::new();
        for i in design.loops[l].clone() {
            let prim = design.prims[i];
            let len = prim.length();
            let n = (len / h).ceil().max(1.0) as usize;
            let ds = len / n as f64;
            let mut feature_len = 0.0;
            let reach = |q: P2, n: V2, r: f64| design.distance(q + n * r).0 >= r * (1.0 - 1e-9);
            let open = |q: P2, n: V2| {
                reach(q, n, rf)
                    && grid
                        .get_or_init(|| FreeGrid::flood(design, contacts, rf))
                        .reached(q + n * rf)
            };
            for j in 0..n {
                let s = (j as f64 + 0.5) * ds;
                let q = prim.at(s);
                let nrm = free_normal(design, q, tangent(&prim, s));
                let ok = reach(q, nrm, re);
                if ok && cov.per_piece[i] == 0 && open(q, nrm) {
                    feature_len += ds;
                }
                samples.push((q, ok, ds));
            }
            if feature_len > 1.5 * rs && cov.per_piece[i] == 0 {
                cov.missed.push(i);
            }
        }
        // Runs of unreachable samples; a run may wrap round the start.
        let n = samples.len();
        let Some(first_ok) = samples.iter().position(|s| s.1) else {
            let len = samples.iter().map(|s| s.2).sum();
            cov.unreachable.push(Unreachable {
                from: samples[0].0,
                to: samples[n - 1].0,
                length_mm: len,
            });
            continue;
        };
        let mut k = 0;
        while k < n {
            let i = (first_ok + k) % n;
            if samples[i].1 {
                k += 1;
                continue;
            }
            let (from, mut to, mut len) = (samples[i].0, samples[i].0, 0.0);
            while k < n && !samples[(first_ok + k) % n].1 {
                let s = samples[(first_ok + k) % n];
                to = s.0;
                len += s.2;
                k += 1;
            }
            cov.unreachable.push(Unreachable {
                from,
                to,
                length_mm: len,
            });
        }
    }
    cov
}

/// Where a disc of radius `r` can go from the scanned contacts: a grid of
/// disc centres, free when the disc clears the part, flooded from the free
/// cells next to the contacts.
struct FreeGrid {
    lo: P2,
    g: f64,
    nx: usize,
    ny: usize,
    reached: Vec<bool>,
}

impl FreeGrid {
    fn flood(design: &Part, contacts: &[Contact], r: f64) -> FreeGrid {
        let (mut lo, mut hi) = (
            P2::new(f64::INFINITY, f64::INFINITY),
            P2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for p in &design.prims {
            for k in 0..=16 {
                let q = p.at(p.length() * k as f64 / 16.0);
                lo = P2::new(lo.x.min(q.x), lo.y.min(q.y));
                hi = P2::new(hi.x.max(q.x), hi.y.max(q.y));
            }
        }
        let pad = 3.0 * r;
        lo -= V2::new(pad, pad);
        hi += V2::new(pad, pad);
        // A quarter of the radius, coarser if the grid would pass 250,000 cells.
        let area = (hi.x - lo.x) * (hi.y - lo.y);
        let g = (r / 4.0).max((area / 2.5e5).sqrt());
        let nx = ((hi.x - lo.x) / g).ceil() as usize + 1;
        let ny = ((hi.y - lo.y) / g).ceil() as usize + 1;
        let at = |i: usize, j: usize| P2::new(lo.x + i as f64 * g, lo.y + j as f64 * g);
        let free: Vec<bool> = (0..nx * ny)
            .map(|k| {
                let c = at(k % nx, k / nx);
                !design.in_material(c) && design.distance(c).0 >= r
            })
            .collect();
        let mut reached = vec![false; nx * ny];
        let mut stack = Vec::new();
        for c in contacts {
            let (ci, cj) = (((c.center.x - lo.x) / g).round(), ((c.center.y - lo.y) / g).round());
            let span = (r / g).ceil() as i64 + 2;
            for dj in -span..=span {
                for di in -span..=span {
                    let (i, j) = (ci as i64 + di, cj as i64 + dj);
                    if i < 0 || j < 0 || i >= nx as i64 || j >= ny as i64 {
                        continue;
                    }
                    let k = j as usize * nx + i as usize;
                    if free[k] && !reached[k] && (at(i as usize, j as usize) - c.center).norm() <= r + 2.0 * g {
                        reached[k] = true;
                        stack.push(k);
                    }
                }
            }
        }
        while let Some(k) = stack.pop() {
            let (i, j) = (k % nx, k / nx);
            let mut push = |i: usize, j: usize| {
                let k = j * nx + i;
                if free[k] && !reached[k] {
                    reached[k] = true;
                    stack.push(k);
                }
            };
            if i > 0 {
                push(i - 1, j);
            }
            if i + 1 < nx {
                push(i + 1, j);
            }
            if j > 0 {
                push(i, j - 1);
            }
            if j + 1 < ny {
                push(i, j + 1);
            }
        }
        FreeGrid { lo, g, nx, ny, reached }
    }

    /// True when a reached grid centre lies within one cell of `c`.
    fn reached(&self, c: P2) -> bool {
        let (fi, fj) = ((c.x - self.lo.x) / self.g, (c.y - self.lo.y) / self.g);
        for j in [fj.floor(), fj.ceil()] {
            for i in [fi.floor(), fi.ceil()] {
                if i >= 0.0
                    && j >= 0.0
                    && (i as usize) < self.nx
                    && (j as usize) < self.ny
                    && self.reached[j as usize * self.nx + i as usize]
                {
                    return true;
                }
            }
        }
        false
    }
}

fn tangent(p: &Prim, s: f64) -> V2 {
    match *p {
        Prim::Line { a, b } => (b - a) / (b - a).norm(),
        Prim::Arc { r, a0, sweep, .. } => {
            let a = a0 + sweep.signum() * s / r;
            V2::new(-a.sin(), a.cos()) * sweep.signum()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_has_one_unreachable_corner_stretch_per_concave_corner_only() {
        // An L-shaped pocket wall seen from outside has one concave corner.
        let pts = [
            P2::new(0.0, 0.0),
            P2::new(4.0, 0.0),
            P2::new(4.0, 2.0),
            P2::new(2.0, 2.0),
            P2::new(2.0, 4.0),
            P2::new(0.0, 4.0),
        ];
        let part = Part::single_loop(
            (0..6)
                .map(|i| Prim::Line {
                    a: pts[i],
                    b: pts[(i + 1) % 6],
                })
                .collect(),
        );
        let c = Contact {
            center: P2::new(-0.1, 1.0),
            exact: P2::new(-0.1, 1.0),
            dir: V2::new(1.0, 0.0),
            kind: super::super::scan::MoveKind::Approach,
            prim: 5,
            run_mm: 1.0,
        };
        let cov = coverage(&part, &[c], 0.1, 0.3);
        assert_eq!(cov.unreachable.len(), 1);
        let u = cov.unreachable[0];
        assert!((u.length_mm - 0.2).abs() < 0.03, "{u:?}");
        assert!((u.from - P2::new(2.0, 2.0)).norm() < 0.11);
        assert_eq!(cov.missed, vec![0, 1, 2, 3, 4]);
    }
}
