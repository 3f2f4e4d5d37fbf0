//! A whole 5-axis job, from XY passes to the locations written, in the
//! one order that keeps each step's promise:
//! 1. contacts along the passes (facet normals, or smoothed ones);
//! 2. one location per contact: the axis along the normal with lead and
//!    tilt ([`FiveAxis::location`]);
//! 3. the check of the whole tool (and holder) against the part that the
//!    job asks for: none, a report, lifts, or the tilt search; with
//!    smoothed normals every location is first set down on the mesh;
//! 4. the limit on the axis change between neighbours
//!    ([`AxisLimit`]): last, so that it keeps every location the check
//!    left, in order, and its steps are set down and checked on their own.
//!
//! The CLI (`pathgen dropcutter --five-axis`) parses and checks the
//! options, builds a [`FiveAxisJob`], and writes what
//! [`FiveAxisJob::check`] returns.

use super::fiveaxis::{Contact, FiveAxis, Location};
use super::gouge::{GougeCheck, GougeReport, GougeRule, Holder, Placement, SettleReport};
use super::swing::{AxisLimit, AxisReport};
use super::tilt::{TiltReport, TiltSearch};
use super::{DropCutter, DropError};
use crate::geometry::P2;

/// What the job does with a location whose tool cuts into the part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GougeMode {
    /// No check (with smoothed normals the locations are still set down).
    Off,
    /// Keep every location as computed; count the gouges.
    Report,
    /// Lift a gouging location along its axis until the tool only touches.
    Lift,
    /// Turn lead or tilt first ([`TiltSearch`]); lift where no turn clears.
    Tilt(TiltSearch),
}

/// A 5-axis job's rules.
#[derive(Debug, Clone, PartialEq)]
pub struct FiveAxisJob {
    /// Lead, tilt and the length of tool checked.
    pub five: FiveAxis,
    /// Axes from smoothed normals with this crease angle (radians); `None`
    /// for the facets' own normals.
    pub smooth_crease: Option<f64>,
    /// The gouge check.
    pub gouge: GougeMode,
    /// The holder's cylinders (none: the cutter alone is checked).
    pub holders: Vec<Holder>,
    /// Changes of the tool axis between neighbours over this (radians)
    /// are turned in checked steps, or the tool lifted (`None`: kept as
    /// computed).
    pub max_axis_change: Option<f64>,
    /// Over the limit: steps where they can be made (else a lift), or
    /// always a lift.
    pub axis_steps: bool,
}

/// The locations of a job before the check: one run per stretch of a pass
/// over the part, each location beside the contact it was made from.
#[derive(Debug, Clone)]
pub struct Located {
    contacts: Vec<Vec<Contact>>,
    runs: Vec<Vec<Location>>,
}

impl Located {
    /// How many locations there are.
    pub fn count(&self) -> usize {
        self.runs.iter().map(Vec::len).sum()
    }
}

/// What a job made and what each step did.
#[derive(Debug, Clone)]
pub struct FiveAxisOutcome {
    /// The locations, run by run (the tool goes to the safe Z between).
    pub runs: Vec<Vec<Location>>,
    /// With smoothed normals: how the locations were set down.
    pub settled: Option<SettleReport>,
    /// What the gouge check found (`None` with [`GougeMode::Off`]).
    pub gouge: Option<GougeReport>,
    /// What the tilt search did (with [`GougeMode::Tilt`]).
    pub tilt: Option<TiltReport>,
    /// How far the axis turns between neighbours, and what the limit did.
    pub axes: AxisReport,
}

impl FiveAxisJob {
    /// Steps 1 and 2: the contacts along `passes` and a location for each.
    /// Fails for a ball cutter (its contact does not depend on its axis).
    pub fn locate(&self, dc: &DropCutter, passes: &[Vec<P2>]) -> Result<Located, DropError> {
        let (r, rc) = FiveAxis::radii(dc)?;
        let smooth = self.smooth_crease.map(|c| dc.smooth_normals(c));
        let contacts: Vec<Vec<Contact>> = passes
            .iter()
            .flat_map(|p| FiveAxis::contacts_with(dc, p, smooth.as_ref()))
            .collect();
        let runs = contacts
            .iter()
            .map(|run| {
                run.iter()
                    .map(|c| self.five.location(c.cc, c.normal, c.feed, r, rc))
                    .collect()
            })
            .collect();
        Ok(Located { contacts, runs })
    }

    /// How many units of work [`FiveAxisJob::check`] reports through
    /// [`crate::progress::advance`] for `located` (for a meter's total).
    pub fn check_units(&self, located: &Located) -> u64 {
        let per = match (self.gouge, self.smooth_crease.is_some()) {
            (GougeMode::Off, false) => 0,
            // Setting down and checking count a location each; the tilt
            // search with smoothed normals does both.
            (GougeMode::Tilt(_), true) => 2,
            _ => 1,
        };
        located.count() as u64 * per
    }

    /// Steps 3 and 4: the gouge check, then the axis-change limit.
    pub fn check(&self, dc: &DropCutter, located: Located) -> Result<FiveAxisOutcome, DropError> {
        let Located { contacts, mut runs } = located;
        // Built only when a check, a setting down or the axis steps run,
        // and once for all of them: its 3-D tree takes a quarter of a
        // second on a million triangles.
        let built = std::cell::OnceCell::new();
        let checker = || -> Result<&GougeCheck, DropError> {
            if let Some(c) = built.get() {
                return Ok(c);
            }
            let c = self
                .holders
                .iter()
                .try_fold(GougeCheck::new(dc), |c, &h| c.with_holder(h))?;
            Ok(built.get_or_init(|| c))
        };
        let length = self.five.axis_length;
        let settling = self.smooth_crease.is_some();
        let (mut settled, mut gouge, mut tilt) = (None, None, None);
        match self.gouge {
            GougeMode::Off if settling => {
                let (_, s) = checker()?.check_settling(&contacts, &mut runs, length, GougeRule::Report);
                settled = Some(s);
            }
            GougeMode::Off => {}
            GougeMode::Report | GougeMode::Lift => {
                let rule = if self.gouge == GougeMode::Lift {
                    GougeRule::Lift
                } else {
                    GougeRule::Report
                };
                if settling {
                    let (report, s) = checker()?.check_settling(&contacts, &mut runs, length, rule);
                    (gouge, settled) = (Some(report), Some(s));
                } else {
                    gouge = Some(checker()?.check(&mut runs, length, rule));
                }
            }
            GougeMode::Tilt(search) => {
                let placement = if settling {
                    Placement::SetDown
                } else {
                    Placement::Tangent
                };
                let (report, t, s) = checker()?.check_tilting(&self.five, &contacts, &mut runs, &search, placement)?;
                (gouge, tilt) = (Some(report), Some(t));
                settled = settling.then_some(s);
            }
        }
        let limit = AxisLimit {
            max: self.max_axis_change.unwrap_or(std::f64::consts::PI),
            length,
            steps: self.axis_steps,
        };
        // The checker is built for the steps only when a change is over
        // the limit: with `--gouge off` on a part whose axis never turns
        // that far, nothing else needs it.
        let axes = match self.max_axis_change {
            Some(_) if limit.steps && limit.exceeded(&runs) => limit.apply(Some(checker()?), &mut runs),
            _ => limit.apply(None, &mut runs),
        };
        Ok(FiveAxisOutcome {
            runs,
            settled,
            gouge,
            tilt,
            axes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;
    use crate::dropcutter::fiveaxis::axis_change;
    use crate::dropcutter::tests::sphere;

    fn job(gouge: GougeMode, max_axis_change: Option<f64>) -> FiveAxisJob {
        FiveAxisJob {
            five: FiveAxis {
                lead: 10f64.to_radians(),
                tilt: 0.0,
                axis_length: 20.0,
            },
            smooth_crease: None,
            gouge,
            holders: Vec::new(),
            max_axis_change,
            axis_steps: true,
        }
    }

    /// The steps in their order: the check sees the computed locations
    /// and the limit sees what the check left; a ball cutter is refused.
    #[test]
    fn the_job_checks_then_limits_the_axis_changes() {
        let mesh = sphere(5.0, 32, 16);
        let dc = DropCutter::new(&mesh, Cutter::parse("flat:2").unwrap()).unwrap();
        let passes: Vec<Vec<P2>> = (-4..=4)
            .map(|k| (-40..=40).map(|i| P2::new(f64::from(i) * 0.1, f64::from(k))).collect())
            .collect();
        let plain = job(GougeMode::Off, None);
        let located = plain.locate(&dc, &passes).unwrap();
        let n = located.count();
        assert!(n > 300, "{n}");
        assert_eq!(plain.check_units(&located), 0);
        let off = plain.check(&dc, located).unwrap();
        assert!(off.gouge.is_none() && off.tilt.is_none() && off.settled.is_none());
        assert_eq!(off.runs.iter().map(Vec::len).sum::<usize>(), n);

        let lifted = job(GougeMode::Lift, None);
        let located = lifted.locate(&dc, &passes).unwrap();
        assert_eq!(lifted.check_units(&located), n as u64);
        let lift = lifted.check(&dc, located).unwrap();
        let report = lift.gouge.unwrap();
        assert_eq!(report.checked, n);
        // Lifted along their own axes: the same axes, tips no lower.
        for (a, b) in off.runs.iter().flatten().zip(lift.runs.iter().flatten()) {
            assert!(axis_change(a, b) < 1e-9);
            assert!(b.cl.z >= a.cl.z - 1e-12);
        }

        // A limit below the facets' own steps: every change over it is
        // stepped or split, the computed locations all kept in order.
        let limit = 2f64.to_radians();
        let limited = job(GougeMode::Lift, Some(limit));
        let out = limited.check(&dc, limited.locate(&dc, &passes).unwrap()).unwrap();
        assert!(out.axes.stepped + out.axes.split > 0, "{:?}", out.axes);
        let kept: Vec<&Location> = out.runs.iter().flatten().collect();
        let mut j = 0;
        for a in lift.runs.iter().flatten() {
            while j < kept.len() && kept[j] != a {
                j += 1;
            }
            assert!(j < kept.len(), "{a:?} lost");
        }
        for run in &out.runs {
            for w in run.windows(2) {
                assert!(axis_change(&w[0], &w[1]) <= limit + 1e-9);
            }
        }

        let ball = DropCutter::new(&mesh, Cutter::parse("ball:2").unwrap()).unwrap();
        assert!(plain.locate(&ball, &passes).is_err());
    }
}
