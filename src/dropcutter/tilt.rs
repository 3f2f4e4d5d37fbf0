//! The tilt search of the 5-axis gouge check: a location whose tool cuts
//! into the part tries other leads and tilts for the same contact before
//! it is lifted, and the turns it takes are eased in and out along its
//! pass so the rotary axes do not jump.
//!
//! Why the easing: each location is searched alone, so a location that
//! needs 15 degrees more tilt to clear a fillet sits between neighbours
//! that need none. Written as it is, the axis turns 15 degrees between two
//! CL points a few hundredths of a millimetre apart, which a trunnion can
//! only follow by stopping the feed (and which marks the surface). With a
//! ramp length `L`, every location within `L` of a turned one (measured
//! along the pass through the contact points) is offered that turn scaled
//! by `1 - d / L`, so the turn grows linearly into the stretch that needs
//! it and falls away after; the offer is taken only where it keeps the
//! tool clear of the part (checked like any other orientation), and
//! never where the location's own turn is larger.

use super::DropError;
use super::fiveaxis::{Contact, FiveAxis, Location};
use super::gouge::{GOUGE_TOL, GougeCheck, GougeReport, Placement, SettleReport, lifted, map_located};
use rayon::prelude::*;

/// How far the tilt search goes (all angles in radians, lengths in mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltSearch {
    /// The largest change of lead or tilt tried.
    pub max: f64,
    /// The step between the changes tried.
    pub step: f64,
    /// The distance along a pass over which a turn is eased in and out
    /// (0: no easing).
    pub ramp: f64,
    /// Where no turn of one angle clears the part, turn both by the same
    /// size (the four diagonals) before lifting the tool.
    pub both: bool,
}

/// What the tilt search did with the gouging locations
/// ([`GougeCheck::check_tilting`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TiltReport {
    /// Gouging locations given another orientation that clears the part.
    pub tilted: usize,
    /// Of those, the ones only a turn of both lead and tilt cleared
    /// ([`TiltSearch::both`]). (Easing may still offer a neighbour's turn
    /// of both, scaled, to a location one angle cleared.)
    pub both: usize,
    /// Gouging locations no orientation within reach cleared: lifted.
    pub lifted: usize,
    /// The largest change of lead or tilt taken (radians).
    pub largest_turn: f64,
    /// Locations that did not gouge, turned part way to ease the axis
    /// into and out of a turned stretch.
    pub eased: usize,
    /// The largest change of the turn (lead or tilt) between two
    /// consecutive locations of a pass (radians).
    pub largest_jump: f64,
}

/// One location's outcome: the turn taken (lead, tilt; radians) and how.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Outcome {
    /// The tool clears the part as asked.
    Clear,
    /// Turned to clear the part.
    Tilted(Location, [f64; 2]),
    /// No turn within reach clears it: lifted by this depth.
    Lifted(f64),
    /// Cleared as asked, turned part way anyway to ease the axis.
    Eased(Location, [f64; 2]),
}

impl Outcome {
    fn turn(&self) -> [f64; 2] {
        match *self {
            Outcome::Tilted(_, t) | Outcome::Eased(_, t) => t,
            Outcome::Clear | Outcome::Lifted(_) => [0.0; 2],
        }
    }
}

/// The larger of a turn's two angles, by size.
fn size(t: [f64; 2]) -> f64 {
    t[0].abs().max(t[1].abs())
}

impl GougeCheck<'_> {
    /// As [`GougeCheck::check`] with [`super::gouge::GougeRule::Lift`], but
    /// a gouging location first tries other orientations for the same
    /// contact: the lead or the tilt changed by `step`, then `2 step`, ...
    /// up to `max`, one angle at a time, both ways (tilt before lead at
    /// each size); of the turns that clear the part, from the smallest
    /// size that does to two steps more (`EXTRA_SIZES`), the pass takes for
    /// each location the one that keeps the turn steadiest along it
    /// (`choose_along`).
    /// (Both angles together at each size were tried: fewer locations are
    /// lifted, but neighbours then alternate between a turn of both and a
    /// slightly larger turn of one, and the axis swings 10-20 degrees
    /// between them; docs/dropcutter.md.) With [`TiltSearch::both`], a
    /// location that no turn of one angle clears tries both angles turned
    /// together (the four diagonals, size by size, the same way) before it
    /// is lifted: only there, so a stretch that one angle clears keeps its
    /// steady turn. When nothing clears, the location is lifted. Then the
    /// turns are eased in and out over `ramp` along each pass (the
    /// module's doc).
    /// `contacts` are the runs' contacts ([`FiveAxis::contacts`]), `fa` the
    /// orientation asked for. With [`Placement::SetDown`] (contacts with
    /// smoothed normals) every location, as asked or turned, is set down
    /// on the part ([`GougeCheck::settle_one`]) and counts as gouging when
    /// it had to rise beyond its own facet's plane; the third report says
    /// how the locations as asked were set down (empty with
    /// [`Placement::Tangent`]).
    pub fn check_tilting(
        &self,
        fa: &FiveAxis,
        contacts: &[Vec<Contact>],
        runs: &mut [Vec<Location>],
        search: &TiltSearch,
        placement: Placement,
    ) -> Result<(GougeReport, TiltReport, SettleReport), DropError> {
        let settle = placement == Placement::SetDown;
        let (r, rc) = FiveAxis::radii(self.drop_cutter())?;
        let length = fa.axis_length;
        let turned = |c: &Contact, t: [f64; 2]| {
            FiveAxis {
                lead: fa.lead + t[0],
                tilt: fa.tilt + t[1],
                axis_length: length,
            }
            .location(c.cc, c.normal, c.feed, r, rc)
        };
        // A location as placed for a contact (set down on the part with
        // `settle`), how deep in the part it is, and how far it would be
        // lifted to clear it.
        let place = |l: &Location, c: &Contact| -> (Location, f64, f64) {
            if settle {
                let s = self.settle_one(l, c, length);
                (s.location, s.depth, s.holder)
            } else {
                let d = self.clearance(l.cl, l.axis_point - l.cl, length);
                (*l, d, d)
            }
        };
        // A turned location, where it clears the part (as the tool
        // stands: a yes-or-no check, which stops at the first contact
        // deeper than the tolerance).
        let clear_turn = |c: &Contact, t: [f64; 2]| {
            if settle {
                let (l, d, _) = place(&turned(c, t), c);
                (d <= GOUGE_TOL).then_some(l)
            } else {
                let l = turned(c, t);
                self.clears(l.cl, l.axis_point - l.cl, length, GOUGE_TOL).then_some(l)
            }
        };
        // The locations as asked, placed, with their depths and lifts.
        let mut settling = SettleReport::default();
        let own_placed: Vec<Vec<(f64, f64)>> = if settle {
            let settled = self.settle_all(contacts, runs, length);
            runs.iter_mut()
                .zip(settled)
                .map(|(run, ss)| {
                    run.iter_mut()
                        .zip(ss)
                        .map(|(l, s)| {
                            settling.record(&s);
                            *l = s.location;
                            (s.depth, s.holder)
                        })
                        .collect()
                })
                .collect()
        } else {
            map_located(contacts, runs, |l, c| {
                let (_, d, lift) = place(l, c);
                (d, lift)
            })
        };
        let sizes = if search.step > 0.0 && search.max > 0.0 {
            ((search.max / search.step) + 1e-9).floor() as usize
        } else {
            0
        };
        // Locations only a turn of both angles cleared.
        let both_found = std::sync::atomic::AtomicUsize::new(0);
        let outcomes: Vec<Vec<(f64, Outcome)>> = own_placed
            .par_iter()
            .zip(contacts.par_iter())
            .map(|(placed, cs)| {
                // The turns that clear each gouging location, from the
                // smallest size that does to EXTRA_SIZES steps more; then
                // one of them for each, chosen along the pass.
                let found: Vec<(f64, Found)> = placed
                    .par_iter()
                    .zip(cs.par_iter())
                    .map(|(&(d, lift), c)| {
                        crate::progress::advance(1);
                        if d <= GOUGE_TOL {
                            return (d, Found::Clear);
                        }
                        let mut clear: Vec<(Location, [f64; 2])> = Vec::new();
                        // Turns of one angle; where none clears, of both.
                        let ways: &[TurnsOfSize] = if search.both {
                            &[single_turns, both_turns]
                        } else {
                            &[single_turns]
                        };
                        for turns in ways {
                            let mut last_size = sizes;
                            for k in 1..=sizes {
                                if k > last_size {
                                    break;
                                }
                                for t in turns(search.step * k as f64) {
                                    if let Some(l) = clear_turn(c, t) {
                                        if clear.is_empty() {
                                            last_size = sizes.min(k + EXTRA_SIZES);
                                        }
                                        clear.push((l, t));
                                    }
                                }
                            }
                            if !clear.is_empty() {
                                break;
                            }
                        }
                        if clear.first().is_some_and(|(_, t)| t[0] != 0.0 && t[1] != 0.0) {
                            both_found.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        }
                        if clear.is_empty() {
                            (d, Found::Lifted(lift))
                        } else {
                            (d, Found::Turns(clear))
                        }
                    })
                    .collect();
                ease(choose_along(found), cs, search.ramp, clear_turn)
            })
            .collect();
        let mut report = GougeReport::default();
        let mut tilt = TiltReport {
            both: both_found.into_inner(),
            ..Default::default()
        };
        for (run, outs) in runs.iter_mut().zip(outcomes) {
            let mut last: Option<[f64; 2]> = None;
            for (l, (d, out)) in run.iter_mut().zip(outs) {
                report.record(l, d);
                let t = out.turn();
                if let Some(p) = last {
                    tilt.largest_jump = tilt.largest_jump.max(size([t[0] - p[0], t[1] - p[1]]));
                }
                last = Some(t);
                match out {
                    Outcome::Clear => {}
                    Outcome::Tilted(to, t) => {
                        *l = to;
                        tilt.tilted += 1;
                        tilt.largest_turn = tilt.largest_turn.max(size(t));
                    }
                    Outcome::Eased(to, _) => {
                        *l = to;
                        tilt.eased += 1;
                    }
                    Outcome::Lifted(d) => {
                        *l = lifted(l, d);
                        tilt.lifted += 1;
                    }
                }
            }
        }
        Ok((report, tilt, settling))
    }
}

/// The four turns of one size `a` tried together, (lead, tilt) each.
type TurnsOfSize = fn(f64) -> [[f64; 2]; 4];

/// The turns of one angle by `a` (lead, tilt): tilt before lead, + before
/// -.
fn single_turns(a: f64) -> [[f64; 2]; 4] {
    [[0.0, a], [0.0, -a], [a, 0.0], [-a, 0.0]]
}

/// The turns of both angles by `a`: the four diagonals, the axis some
/// 1.4 `a` off its asked orientation.
fn both_turns(a: f64) -> [[f64; 2]; 4] {
    [[a, a], [a, -a], [-a, a], [-a, -a]]
}

/// How many sizes past the smallest that clears a location are searched
/// for turns a pass may prefer: a neighbour's turn is often one step larger
/// the other way.
const EXTRA_SIZES: usize = 2;

/// What a larger turn costs in [`choose_along`], per radian of its size,
/// against a radian of change between neighbours: under one, so a pass
/// takes a turn a step larger where that spares it a change of way.
const SIZE_WEIGHT: f64 = 0.5;

/// What the search found for one location, before the pass chooses.
enum Found {
    /// The tool clears the part as asked.
    Clear,
    /// Every turn that clears the part, from the smallest size that does
    /// to [`EXTRA_SIZES`] more (by size, then tilt before lead, + before
    /// -), with the location it gives.
    Turns(Vec<(Location, [f64; 2])>),
    /// No turn within reach clears it: lifted by this depth.
    Lifted(f64),
}

/// One turn for each location of a pass, out of the turns that clear it,
/// so that the turn changes as little as it can along the pass and stays
/// small: the least sum, over the pass, of the changes between
/// consecutive locations (the larger of lead's and tilt's change, as
/// [`TiltReport::largest_jump`] counts them) plus [`SIZE_WEIGHT`] times
/// each turn's size, by dynamic programming over the few turns each
/// location offers; of equal sums, the turns earlier in the search's
/// order. Searched alone, each location took the first turn that cleared
/// it: where one side of a trough needs +15 degrees of lead and a location
/// in it clears with -10 as well as with +15, the pass went +15, -10, +15,
/// a 25-degree swing each way.
fn choose_along(found: Vec<(f64, Found)>) -> Vec<(f64, Outcome)> {
    // The turns a location may take, as (turn, index into its choices).
    let options = |f: &Found| -> Vec<[f64; 2]> {
        match f {
            Found::Turns(v) => v.iter().map(|&(_, t)| t).collect(),
            Found::Clear | Found::Lifted(_) => vec![[0.0; 2]],
        }
    };
    let change = |a: [f64; 2], b: [f64; 2]| size([a[0] - b[0], a[1] - b[1]]);
    // cost[i][k]: the least sum of changes up to location i taking its
    // option k; from[i][k] the option of location i - 1 it came from.
    let mut cost: Vec<Vec<f64>> = Vec::with_capacity(found.len());
    let mut from: Vec<Vec<usize>> = Vec::with_capacity(found.len());
    let mut prev: Vec<[f64; 2]> = Vec::new();
    for (i, (_, f)) in found.iter().enumerate() {
        let opts = options(f);
        let mut c = Vec::with_capacity(opts.len());
        let mut fr = Vec::with_capacity(opts.len());
        for &t in &opts {
            let (best, arg) = if i == 0 {
                (SIZE_WEIGHT * size(t), 0)
            } else {
                prev.iter()
                    .enumerate()
                    .map(|(j, &p)| (cost[i - 1][j] + change(p, t) + SIZE_WEIGHT * size(t), j))
                    .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
            };
            c.push(best);
            fr.push(arg);
        }
        cost.push(c);
        from.push(fr);
        prev = opts;
    }
    // Back from the cheapest end (the first of equal ones).
    let mut pick = vec![0usize; found.len()];
    if let Some(last) = cost.last() {
        let mut k = last
            .iter()
            .enumerate()
            .fold((f64::INFINITY, 0), |a, (j, &c)| if c < a.0 { (c, j) } else { a })
            .1;
        for i in (0..found.len()).rev() {
            pick[i] = k;
            k = from[i][k];
        }
    }
    found
        .into_iter()
        .zip(pick)
        .map(|((d, f), k)| {
            let o = match f {
                Found::Clear => Outcome::Clear,
                Found::Lifted(lift) => Outcome::Lifted(lift),
                Found::Turns(v) => {
                    let (l, t) = v[k];
                    Outcome::Tilted(l, t)
                }
            };
            (d, o)
        })
        .collect()
}

/// Ease one pass's turns in and out over `ramp` (mm along the contacts):
/// each location within `ramp` of a turned one is offered that turn times
/// `1 - d / ramp`, the largest offer of all its turned neighbours, where
/// that is larger than its own turn (whichever way it leans: the stretch
/// around a large turn takes that turn's way, and the change of way moves
/// out to where the offers are as small as the turns they replace);
/// `place` gives the location at an
/// offered turn when it clears the part (the offer is dropped otherwise).
/// A gouging location that takes an offer is tilted (it needed a turn); a
/// clear one is eased.
fn ease(
    own: Vec<(f64, Outcome)>,
    contacts: &[Contact],
    ramp: f64,
    place: impl Fn(&Contact, [f64; 2]) -> Option<Location> + Sync,
) -> Vec<(f64, Outcome)> {
    if ramp.is_nan() || ramp <= 0.0 || !own.iter().any(|(_, o)| matches!(o, Outcome::Tilted(..))) {
        return own;
    }
    // Distance along the pass at each contact.
    let mut s = Vec::with_capacity(contacts.len());
    let mut acc = 0.0;
    for (i, c) in contacts.iter().enumerate() {
        if i > 0 {
            acc += (c.cc - contacts[i - 1].cc).norm();
        }
        s.push(acc);
    }
    // The offers at each location are the upper envelope of one tent per
    // turned location. Tents of one turn fall at one slope, so along the
    // pass the nearest one of a turn behind a location is the best of that
    // turn: one pass each way per turn present (a handful: the search's
    // turns are whole steps), not a walk over every pair within the ramp,
    // which a long ramp on a long pass made quadratic.
    // Classes: one per turn (size and way) present.
    let mut classes: Vec<[f64; 2]> = own
        .iter()
        .filter(|(_, o)| matches!(o, Outcome::Tilted(..)))
        .map(|(_, o)| o.turn())
        .collect();
    classes.sort_by(|a, b| {
        size(*a)
            .total_cmp(&size(*b))
            .then(a[0].total_cmp(&b[0]))
            .then(a[1].total_cmp(&b[1]))
    });
    classes.dedup();
    let n = own.len();
    let mut offer: Vec<Option<[f64; 2]>> = vec![None; n];
    let mut best: Vec<f64> = own.iter().map(|(_, o)| size(o.turn())).collect();
    for &class in &classes {
        for forward in [true, false] {
            let mut seed: Option<(f64, [f64; 2])> = None;
            for k in 0..n {
                let j = if forward { k } else { n - 1 - k };
                if let Outcome::Tilted(_, t) = own[j].1
                    && t == class
                {
                    seed = Some((s[j], t));
                }
                let Some((si, t)) = seed else { continue };
                let d = (s[j] - si).abs();
                if d >= ramp {
                    seed = None;
                    continue;
                }
                let w = 1.0 - d / ramp;
                let cand = [t[0] * w, t[1] * w];
                if size(cand) > best[j] {
                    best[j] = size(cand);
                    offer[j] = Some(cand);
                }
            }
        }
    }
    own.into_par_iter()
        .zip(offer.into_par_iter())
        .zip(contacts.par_iter())
        .map(|(((d, o), off), c)| {
            let Some(t) = off else { return (d, o) };
            match (place(c, t), o) {
                (None, _) => (d, o),
                (Some(l), Outcome::Clear) => (d, Outcome::Eased(l, t)),
                (Some(l), _) => (d, Outcome::Tilted(l, t)),
            }
        })
        .collect()
}

#[cfg(test)]
#[path = "tilt_tests.rs"]
mod tests;
