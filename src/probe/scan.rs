//! The automated XY scan of Bayesteh 2013 (ch. 4, sections 4.2-4.3) in
//! vector form, run against a simulated part.
//!
//! Two contacts are taken along the user's direction `d` (the second from a
//! start moved `R_s` to the left of `d`). From then on, with `P0`, `P1` the
//! last two contacts, `u = (P1 - P0) / |P1 - P0|` and `n` the normal of `u`
//! on the material's side (the side is fixed by the first two contacts):
//!
//! - back off by `R_o` against the move that touched (less if that move was
//!   shorter: retracing it is then sure to be free);
//! - move to `S = P1 + R_s u - R_o n` (the thesis' circle-line intersections,
//!   eqs. 4.2-4.7, are exactly these two points);
//! - approach along `n` for at most `R_o + R_s`.
//!
//! Every move is guarded, as it is on the machine (the acoustic emission
//! sensor fires on any touch): a touch while backing off or repositioning
//! (a concave corner, a bump) is a contact like any other. When the approach
//! finds nothing the surface has turned away (a convex corner): the probe
//! searches back along `-u` from where the approach ended, then straight
//! back towards `P1`. The scan stops when it is back within `R_s` of the
//! first contact on the same side, or at a limit, each with its reason.

use super::ProbeError;
use super::noise::{NoiseModel, Rng};
use super::part::Part;
use super::tip::Probe;
use crate::geometry::{P2, V2};

/// What the user sets for a scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanParams {
    /// Step along the surface R_s (mm).
    pub step_mm: f64,
    /// Back-off from the surface R_o (mm).
    pub offset_mm: f64,
    /// Where the probe centre starts (free space).
    pub start: P2,
    /// The initial approach direction (any length).
    pub dir: V2,
    /// Stop after this many contacts.
    pub max_points: usize,
    /// The longest initial approach (mm).
    pub max_approach_mm: f64,
}

/// Why a move was made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveKind {
    /// A guarded approach towards the surface.
    Approach,
    /// Backing off from a contact.
    Retract,
    /// Moving to the next approach start.
    Reposition,
    /// Looking for a surface that turned away (convex corner).
    Search,
    /// Unguarded travel lifted clear of the part in Z (to the opposite face
    /// of a gauge block).
    Travel,
}

impl MoveKind {
    /// The name used in the CSV and report.
    pub fn name(self) -> &'static str {
        match self {
            MoveKind::Approach => "approach",
            MoveKind::Retract => "retract",
            MoveKind::Reposition => "reposition",
            MoveKind::Search => "search",
            MoveKind::Travel => "travel",
        }
    }
}

/// One straight move of the probe centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathMove {
    /// Where it started.
    pub from: P2,
    /// Where it stopped (at the touch, if it touched).
    pub to: P2,
    /// Why.
    pub kind: MoveKind,
    /// True when it stopped on a touch.
    pub touched: bool,
}

/// One recorded contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// The probe centre as the controller reports it (noise included, mean
    /// over-travel removed).
    pub center: P2,
    /// The exact centre at first touch (simulation only).
    pub exact: P2,
    /// Unit direction of the move that touched.
    pub dir: V2,
    /// The move that touched.
    pub kind: MoveKind,
    /// The part piece touched (simulation only).
    pub prim: usize,
    /// How far the touching move ran before it touched (mm): backing off
    /// along it that far or less retraces free space.
    pub run_mm: f64,
}

/// Why a scan ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// Back at the first contact: the contour is closed.
    Closed,
    /// The contact limit was reached.
    MaxPoints(usize),
    /// Neither the approach nor the searches found the surface.
    LostSurface(P2),
    /// The last contacts did not move forward.
    Stuck(P2),
}

impl Stop {
    /// A sentence for the user.
    pub fn message(&self) -> String {
        match self {
            Stop::Closed => "contour closed".into(),
            Stop::MaxPoints(n) => format!("stopped at the limit of {n} contacts before the contour closed"),
            Stop::LostSurface(p) => format!(
                "lost the surface after the contact at ({:.6}, {:.6}): no touch within R_o + R_s of the step, nor on the searches back",
                p.x, p.y
            ),
            Stop::Stuck(p) => format!("no progress: the last contacts stay near ({:.6}, {:.6})", p.x, p.y),
        }
    }

    /// A short code for the report.
    pub fn code(&self) -> &'static str {
        match self {
            Stop::Closed => "closed",
            Stop::MaxPoints(_) => "max_points",
            Stop::LostSurface(_) => "lost_surface",
            Stop::Stuck(_) => "stuck",
        }
    }
}

/// A finished scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Contacts in order.
    pub contacts: Vec<Contact>,
    /// Every move, in order.
    pub path: Vec<PathMove>,
    /// Why it ended.
    pub stop: Stop,
    /// +1 when the material lies to the left of the travel, -1 to the right.
    pub side: f64,
}

fn perp(u: V2) -> V2 {
    V2::new(-u.y, u.x)
}

struct Runner<'a> {
    part: &'a Part,
    probe: &'a Probe,
    noise: &'a NoiseModel,
    rng: Rng,
    re: f64,
    pos: P2,
    scan: Scan,
}

impl Runner<'_> {
    /// Back off from contact `c` against its touching move by `R_o`, or by
    /// as far as that move ran if less: the way it came is free, so this
    /// move needs no guard (on the machine the wire may still be rubbing
    /// the surface as it leaves, and a guard would fire at once).
    fn back_off(&mut self, c: &Contact, ro: f64) {
        let to = c.exact - c.dir * ro.min(c.run_mm);
        self.scan.path.push(PathMove {
            from: c.exact,
            to,
            kind: MoveKind::Retract,
            touched: false,
        });
        self.pos = to;
    }

    /// A guarded move from the current position to `to`; records the touch.
    fn go(&mut self, to: P2, kind: MoveKind) -> bool {
        let from = self.pos;
        let w = to - from;
        let len = w.norm();
        if len == 0.0 {
            return false;
        }
        let d = w / len;
        match self.part.guarded(from, d, self.re, len) {
            Some(t) => {
                let exact = from + d * t.t;
                let center = exact + d * self.noise.draw(self.probe, &mut self.rng);
                self.scan.path.push(PathMove {
                    from,
                    to: exact,
                    kind,
                    touched: true,
                });
                self.scan.contacts.push(Contact {
                    center,
                    exact,
                    dir: d,
                    kind,
                    prim: t.prim,
                    run_mm: t.t,
                });
                self.pos = exact;
                true
            }
            None => {
                self.scan.path.push(PathMove {
                    from,
                    to,
                    kind,
                    touched: false,
                });
                self.pos = to;
                false
            }
        }
    }
}

/// Run the scan of `params` with `probe` against `part`; `seed` drives the
/// noise.
pub fn run(part: &Part, probe: &Probe, noise: &NoiseModel, params: &ScanParams, seed: u64) -> Result<Scan, ProbeError> {
    let re = probe.radius();
    check(params)?;
    let d = params.dir / params.dir.norm();
    let (dist, _) = part.distance(params.start);
    if part.in_material(params.start) || dist <= re {
        return Err(ProbeError::Start(format!(
            "the start ({}, {}) is in the part or within R_e = {} mm of it",
            params.start.x, params.start.y, re
        )));
    }
    let mut r = Runner {
        part,
        probe,
        noise,
        rng: Rng::new(seed),
        re,
        pos: params.start,
        scan: Scan {
            contacts: Vec::new(),
            path: Vec::new(),
            stop: Stop::Closed,
            side: 1.0,
        },
    };
    let (rs, ro) = (params.step_mm, params.offset_mm);
    // The two initial contacts along the user's direction.
    let starts = [params.start, params.start + perp(d) * rs];
    for (i, s) in starts.into_iter().enumerate() {
        if i == 1 {
            let c = r.scan.contacts[0];
            r.back_off(&c, ro);
            if r.go(s, MoveKind::Reposition) {
                return Err(ProbeError::Start(format!(
                    "the second start ({}, {}), R_s to the left of the first, cannot be reached without touching",
                    s.x, s.y
                )));
            }
        }
        if !r.go(s + d * params.max_approach_mm, MoveKind::Approach) {
            return Err(ProbeError::NoSurface(format!(
                "initial approach {} from ({}, {}) along ({}, {}) found no surface within the maximum approach of {} mm",
                i + 1,
                s.x,
                s.y,
                d.x,
                d.y,
                params.max_approach_mm
            )));
        }
    }
    let c = &r.scan.contacts;
    let u0 = c[1].center - c[0].center;
    let side = perp(u0).dot(&d);
    if u0.norm() < 1e-3 * rs || side.abs() < 1e-3 * u0.norm() {
        return Err(ProbeError::Start(
            "the two initial contacts do not define a direction along the surface (the surface is parallel to the approach there)".into(),
        ));
    }
    let side = side.signum();
    r.scan.side = side;
    let mut travelled = u0.norm();
    let first = r.scan.contacts[0];
    let mut repeats = 0;
    loop {
        let k = r.scan.contacts.len();
        if k >= params.max_points {
            r.scan.stop = Stop::MaxPoints(params.max_points);
            break;
        }
        let (p0, p1) = (r.scan.contacts[k - 2], r.scan.contacts[k - 1]);
        let w = p1.center - p0.center;
        // Two contacts too close for a direction: the tangent across the
        // last approach, on the scan's side.
        let u = if w.norm() > 0.1 * rs {
            w / w.norm()
        } else {
            let n = p1.dir;
            V2::new(n.y, -n.x) * side
        };
        let n = perp(u) * side;
        if k >= 4 && travelled > 2.5 * rs && (p1.center - first.center).norm() < rs && n.dot(&first.dir) > 0.0 {
            r.scan.stop = Stop::Closed;
            break;
        }
        // A contact back where one of the last few was means the scan is
        // going round in a small cycle; a few in a row and it is stuck.
        let recent = &r.scan.contacts[k.saturating_sub(9)..k - 1];
        if recent.iter().any(|c| (c.center - p1.center).norm() < 0.02 * rs) {
            repeats += 1;
            if repeats >= 4 {
                r.scan.stop = Stop::Stuck(p1.center);
                break;
            }
        } else {
            repeats = 0;
        }
        r.back_off(&p1, ro);
        let touched = r.go(p1.center + u * rs - n * ro, MoveKind::Reposition)
            || {
                let s = r.pos;
                r.go(s + n * (ro + rs), MoveKind::Approach)
            }
            || {
                let e = r.pos;
                r.go(e - u * (rs + ro), MoveKind::Search)
            }
            || r.go(p1.exact, MoveKind::Search);
        if !touched {
            r.scan.stop = Stop::LostSurface(p1.center);
            break;
        }
        let last = r.scan.contacts[r.scan.contacts.len() - 1];
        travelled += (last.center - p1.center).norm();
    }
    // Leave the surface.
    if let Some(c) = r.scan.contacts.last().copied() {
        r.back_off(&c, ro);
    }
    Ok(r.scan)
}

fn check(p: &ScanParams) -> Result<(), ProbeError> {
    for (name, v) in [
        ("step R_s", p.step_mm),
        ("offset R_o", p.offset_mm),
        ("maximum approach", p.max_approach_mm),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(ProbeError::Param(format!("{name} must be a positive number, got {v}")));
        }
    }
    if !(p.dir.norm() > 0.0 && p.dir.norm().is_finite()) {
        return Err(ProbeError::Param(
            "the initial direction must be a non-zero vector".into(),
        ));
    }
    if !(p.start.x.is_finite() && p.start.y.is_finite()) {
        return Err(ProbeError::Param("the start must be finite".into()));
    }
    if p.max_points < 3 {
        return Err(ProbeError::Param(format!(
            "the contact limit must be at least 3, got {}",
            p.max_points
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(start: P2, dir: V2, rs: f64) -> ScanParams {
        ScanParams {
            step_mm: rs,
            offset_mm: 0.1,
            start,
            dir,
            max_points: 2000,
            max_approach_mm: 5.0,
        }
    }

    #[test]
    fn circle_scan_closes_with_every_contact_on_the_offset_circle() {
        let part = Part::circle(P2::new(1.0, 2.0), 12.7);
        let probe = Probe::new(0.1, 30_000.0, 0.05).unwrap();
        let p = params(P2::new(-7.0, 2.0), V2::new(1.0, 0.0), 0.4);
        let s = run(&part, &probe, &NoiseModel::default(), &p, 1).unwrap();
        assert_eq!(s.stop, Stop::Closed);
        assert!(s.contacts.len() > 90 && s.contacts.len() < 110, "{}", s.contacts.len());
        for c in &s.contacts {
            assert!(((c.center - P2::new(1.0, 2.0)).norm() - 6.4).abs() < 1e-12);
        }
    }

    #[test]
    fn square_corners_are_followed_both_ways() {
        let part = Part::rectangle(P2::new(0.0, 0.0), P2::new(4.0, 3.0));
        let probe = Probe::new(0.2, 30_000.0, 0.05).unwrap();
        // Outside (convex corners), going either way round.
        for dir in [V2::new(1.0, 0.0), V2::new(1.0, 0.3)] {
            let s = run(
                &part,
                &probe,
                &NoiseModel::default(),
                &params(P2::new(-1.0, 1.0), dir, 0.3),
                1,
            )
            .unwrap();
            assert_eq!(s.stop, Stop::Closed);
            let mut seen = [0; 4];
            for c in &s.contacts {
                seen[c.prim] += 1;
            }
            assert!(seen.iter().all(|&n| n >= 8), "{seen:?}");
        }
    }
}
