//! Large changes of the tool axis between neighbouring 5-axis locations,
//! turned in checked steps or, where a step cannot be made, replaced by a
//! lift.
//!
//! Between two neighbouring locations a 5-axis machine moves its linear
//! axes and swings its rotary ones at once. Where the tool axis turns by
//! tens of degrees between two points a step apart (facet normals across a
//! ridge, the tilt search's opposite turns side by side), that swing stops
//! the feed and sweeps the tool through whatever lies beside the two
//! locations, which neither location's gouge check saw. With a limit,
//! each such change is cut into steps of at most the limit: the axis
//! turned evenly (spherical interpolation), the tip moved evenly between
//! the two, and each step's tool set down on the part along its axis
//! ([`GougeCheck::rest_height`]: touching, nowhere in it) and checked with
//! the holder. So the tool rolls over a ridge on its edge instead of
//! swinging through the air or the part. Where a step finds no part under
//! it within reach, or its holder would hit, the run ends there instead;
//! the writer ([`super::output::write_cldata5`]) then draws the tool back
//! along its axis to the safe Z, turns it there and puts it down along the
//! new axis.

use super::fiveaxis::{Location, axis_change};
use super::gouge::{GOUGE_TOL, GougeCheck};
use crate::geometry::{P3, V3};
use rayon::prelude::*;

/// What [`AxisLimit::apply`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AxisReport {
    /// Places where the axis turned by more than the limit and was
    /// turned in steps instead.
    pub stepped: usize,
    /// Locations added by those steps.
    pub inserted: usize,
    /// Places where a step could not be made: the run ends there (a lift).
    pub split: usize,
    /// The largest change over the limit met (radians; 0 if none).
    pub largest_over: f64,
    /// The largest change left between neighbours of a run (radians): at
    /// most the limit once applied.
    pub largest_kept: f64,
}

/// The largest change of the tool axis allowed between two neighbouring
/// locations of a run, and how much of the tool a step is checked with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimit {
    /// Radians, above 0.
    pub max: f64,
    /// The length of tool set down and checked (mm; `--axis-length`).
    pub length: f64,
    /// Turn in steps where the steps can be set down (else every change
    /// over the limit ends the run).
    pub steps: bool,
}

/// The steps between two neighbours `a` and `b` whose axes are
/// `angle` apart, each set down on the part, or `None` when one of them
/// cannot be: nothing under it within reach, the holder in the part, axes
/// too near opposite to interpolate, or more than a thousand steps.
fn steps_between(check: &GougeCheck, a: &Location, b: &Location, angle: f64, lim: &AxisLimit) -> Option<Vec<Location>> {
    // Half a turn has no one interpolating plane.
    if angle > std::f64::consts::PI - 1e-6 {
        return None;
    }
    // More steps than this (a limit far finer than any rotary axis
    // needs) are not made: the change ends the run instead.
    const MAX_STEPS: f64 = 1000.0;
    let steps = (angle / lim.max).ceil();
    if steps.is_nan() || steps > MAX_STEPS {
        return None;
    }
    let n = steps as usize;
    let (u, v) = (a.axis(), b.axis());
    let sin = angle.sin();
    let gap = (b.cl - a.cl).norm();
    // Far enough down to find the part under a step whose straight-line
    // tip lies above it: the cutter's radius and the tips' distance.
    let below = check.drop_cutter().shape.r + gap + GOUGE_TOL;
    let mut out = Vec::with_capacity(n.saturating_sub(1));
    for k in 1..n {
        let t = k as f64 / n as f64;
        let axis: V3 = if sin < 1e-12 {
            u
        } else {
            (u * ((1.0 - t) * angle).sin() + v * (t * angle).sin()) / sin
        };
        let tip = P3::from(a.cl.coords * (1.0 - t) + b.cl.coords * t);
        let rise = check.rest_height(tip, axis, lim.length, below)?;
        let cl = tip + axis * rise;
        // The cutter rests on the part; the holder must clear it too.
        if check.clearance(cl, axis, lim.length) > GOUGE_TOL {
            return None;
        }
        out.push(Location {
            cl,
            axis_point: cl + axis * lim.length,
        });
    }
    Some(out)
}

impl AxisLimit {
    /// Whether any change between neighbours in `runs` is over the limit
    /// (the steps need a gouge checker only then).
    pub fn exceeded(&self, runs: &[Vec<Location>]) -> bool {
        runs.par_iter()
            .any(|run| run.windows(2).any(|w| axis_change(&w[0], &w[1]) > self.max))
    }

    /// Apply the limit to every run: each change over it turned in steps
    /// (when `steps` and `check` is given and the steps can be set down)
    /// or split into two runs. Every location is kept, in order.
    pub fn apply(&self, check: Option<&GougeCheck>, runs: &mut Vec<Vec<Location>>) -> AxisReport {
        let mut report = AxisReport::default();
        // Each run's largest change within the limit, and the steps of its
        // changes over it (index of the second location, angle, steps or
        // None), worked out on the pool, each change measured once.
        type Over = Vec<(usize, f64, Option<Vec<Location>>)>;
        let overs: Vec<(f64, Over)> = runs
            .par_iter()
            .map(|run| {
                let mut kept = 0.0f64;
                let mut over = Over::new();
                for i in 1..run.len() {
                    let angle = axis_change(&run[i - 1], &run[i]);
                    if angle <= self.max {
                        kept = kept.max(angle);
                        continue;
                    }
                    let steps = match check {
                        Some(c) if self.steps => steps_between(c, &run[i - 1], &run[i], angle, self),
                        _ => None,
                    };
                    over.push((i, angle, steps));
                }
                (kept, over)
            })
            .collect();
        let mut out: Vec<Vec<Location>> = Vec::with_capacity(runs.len());
        for (run, (kept, over)) in runs.drain(..).zip(overs) {
            report.largest_kept = report.largest_kept.max(kept);
            if over.is_empty() {
                out.push(run);
                continue;
            }
            let mut cur: Vec<Location> = Vec::with_capacity(run.len());
            let mut next_over = over.into_iter().peekable();
            for (i, l) in run.into_iter().enumerate() {
                if let Some((_, angle, steps)) = next_over.next_if(|o| o.0 == i) {
                    report.largest_over = report.largest_over.max(angle);
                    match steps {
                        Some(steps) => {
                            report.stepped += 1;
                            report.inserted += steps.len();
                            let mut prev = *cur.last().unwrap_or(&l);
                            for s in &steps {
                                report.largest_kept = report.largest_kept.max(axis_change(&prev, s));
                                prev = *s;
                            }
                            report.largest_kept = report.largest_kept.max(axis_change(&prev, &l));
                            cur.extend(steps);
                        }
                        None => {
                            report.split += 1;
                            out.push(std::mem::take(&mut cur));
                        }
                    }
                }
                cur.push(l);
            }
            out.push(cur);
        }
        *runs = out;
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cutter::Cutter;
    use crate::dropcutter::DropCutter;
    use crate::dropcutter::fiveaxis::FiveAxis;
    use crate::dropcutter::fiveaxis::tests::leaning;
    use crate::dropcutter::gouge::tests::{inside_tool, on_corpus_passes, samples};
    use crate::geometry::P2;
    use crate::mesh::Mesh;
    use crate::mesh::Triangle;

    /// Two slopes along x meeting at y = 0 at `deg` degrees from level
    /// each: a ridge (`up`) or a groove.
    fn roof(deg: f64, up: bool) -> Mesh {
        let h = 3.0 * deg.to_radians().tan() * if up { 1.0 } else { -1.0 };
        let p = |x: f64, y: f64, z: f64| P3::new(x, y, z);
        Mesh::from_triangles(&[
            Triangle::new(p(-3.0, -3.0, 0.0), p(3.0, -3.0, 0.0), p(3.0, 0.0, h)),
            Triangle::new(p(-3.0, -3.0, 0.0), p(3.0, 0.0, h), p(-3.0, 0.0, h)),
            Triangle::new(p(-3.0, 0.0, h), p(3.0, 0.0, h), p(3.0, 3.0, 0.0)),
            Triangle::new(p(-3.0, 0.0, h), p(3.0, 3.0, 0.0), p(-3.0, 3.0, 0.0)),
        ])
    }

    #[test]
    fn over_a_ridge_or_a_groove_the_tool_turns_in_steps_that_touch_the_part_and_stay_out_of_it() {
        let cutters = [
            Cutter::Flat { radius: 0.5 },
            Cutter::Torus {
                radius: 0.5,
                corner: 0.2,
            },
        ];
        for (cutter, up) in cutters.into_iter().flat_map(|c| [(c, true), (c, false)]) {
            let mesh = roof(40.0, up);
            let dc = DropCutter::new(&mesh, cutter).unwrap();
            let check = GougeCheck::new(&dc);
            let fa = FiveAxis {
                lead: 0.0,
                tilt: 0.0,
                axis_length: 10.0,
            };
            let xy: Vec<P2> = (0..=16).map(|i| P2::new(0.5, -2.0 + 0.25 * i as f64)).collect();
            let mut runs = fa.pass(&dc, &xy).unwrap();
            let before: Vec<Location> = runs.iter().flatten().copied().collect();
            let lim = AxisLimit {
                max: 20f64.to_radians(),
                length: 10.0,
                steps: true,
            };
            let r = lim.apply(Some(&check), &mut runs);
            // One crossing of 80 degrees, in four steps of 20.
            assert_eq!((r.stepped, r.split, r.inserted), (1, 0, 3), "{cutter} {up}");
            assert!((r.largest_over.to_degrees() - 80.0).abs() < 1e-9);
            assert!(r.largest_kept <= lim.max + 1e-12);
            assert_eq!(runs.len(), 1);
            let after = &runs[0];
            for w in after.windows(2) {
                assert!(axis_change(&w[0], &w[1]) <= lim.max + 1e-12);
            }
            // The locations of the pass are all there, in order.
            let kept: Vec<Location> = after.iter().filter(|l| before.contains(l)).copied().collect();
            assert_eq!(kept, before);
            let pts = samples(&mesh, 40);
            for l in after.iter().filter(|l| !before.contains(l)) {
                let a = l.axis();
                // Out of the part...
                assert!(check.clearance(l.cl, a, 10.0) <= GOUGE_TOL, "{cutter}: {l:?}");
                for p in &pts {
                    assert!(
                        !inside_tool(cutter, l.cl, a, 10.0, *p, 1e-6),
                        "{cutter}: {p:?} in {l:?}"
                    );
                }
                // ... and on it: a hundredth lower, it cuts in.
                assert!(check.clearance(l.cl - a * 0.01, a, 10.0) > 0.005, "{cutter}: {l:?}");
            }
        }
    }

    #[test]
    fn a_limit_too_fine_to_step_ends_the_run_instead() {
        // 60 degrees at a hundred-thousandth of a degree a step: far more
        // steps than are made, so the change is a lift, at once.
        let dc = DropCutter::new(&roof(10.0, true), Cutter::Flat { radius: 0.5 }).unwrap();
        let check = GougeCheck::new(&dc);
        let mut runs = vec![vec![leaning(0.0, -30.0), leaning(0.1, 30.0)]];
        let lim = AxisLimit {
            max: 1e-5f64.to_radians(),
            length: 10.0,
            steps: true,
        };
        let r = lim.apply(Some(&check), &mut runs);
        assert_eq!((r.stepped, r.split, r.inserted), (0, 1, 0));
    }

    #[test]
    fn a_step_with_nothing_under_it_ends_the_run_instead() {
        // Two locations far off the part with axes 60 degrees apart: no
        // step can be set down, so the run is split.
        let dc = DropCutter::new(&roof(10.0, true), Cutter::Flat { radius: 0.5 }).unwrap();
        let check = GougeCheck::new(&dc);
        let far = |x: f64, deg: f64| {
            let mut l = leaning(x, deg);
            l.cl.z += 100.0;
            l.axis_point.z += 100.0;
            l
        };
        let mut runs = vec![vec![far(0.0, -30.0), far(0.1, 30.0)]];
        let lim = AxisLimit {
            max: 20f64.to_radians(),
            length: 10.0,
            steps: true,
        };
        let r = lim.apply(Some(&check), &mut runs);
        assert_eq!((r.stepped, r.split, r.inserted), (0, 1, 0));
        assert_eq!(runs.len(), 2);
    }

    fn lifts(max_deg: f64) -> AxisLimit {
        AxisLimit {
            max: max_deg.to_radians(),
            length: 10.0,
            steps: false,
        }
    }

    #[test]
    fn without_steps_runs_are_split_only_where_the_axis_turns_more_than_the_limit() {
        let angles = [0.0, 5.0, 10.0, 70.0, 65.0, 5.0, 5.0, 14.9];
        let run: Vec<Location> = angles.iter().enumerate().map(|(i, &a)| leaning(i as f64, a)).collect();
        let mut runs = vec![run.clone(), Vec::new(), vec![leaning(9.0, 40.0)]];
        let r = lifts(10.0).apply(None, &mut runs);
        // 10 -> 70 and 65 -> 5 are split; 0 -> 5 -> 10, 70 -> 65 and
        // 5 -> 14.9 (the largest kept) are not.
        assert_eq!((r.split, r.stepped, r.inserted), (2, 0, 0));
        assert!((r.largest_over.to_degrees() - 60.0).abs() < 1e-9);
        assert!((r.largest_kept.to_degrees() - 9.9).abs() < 1e-9);
        let lens: Vec<usize> = runs.iter().map(Vec::len).collect();
        assert_eq!(lens, vec![3, 2, 3, 0, 1]);
        // Every location kept, in order.
        let flat: Vec<Location> = runs.iter().flatten().copied().collect();
        let want: Vec<Location> = run.iter().chain([leaning(9.0, 40.0)].iter()).copied().collect();
        assert_eq!(flat, want);
    }

    #[test]
    fn a_limit_is_exceeded_only_by_a_change_over_it() {
        let run: Vec<Location> = [0.0, 5.0, 10.0, 70.0]
            .iter()
            .enumerate()
            .map(|(i, &a)| leaning(i as f64, a))
            .collect();
        let runs = vec![Vec::new(), vec![leaning(0.0, 80.0)], run];
        // 10 -> 70 is the only change over 20 degrees; none is over 61.
        assert!(lifts(20.0).exceeded(&runs));
        assert!(lifts(59.9).exceeded(&runs));
        assert!(!lifts(60.1).exceeded(&runs));
        // A lone location turns nowhere, whatever its neighbour run holds.
        assert!(!lifts(1.0).exceeded(&runs[..2]));
        // And `exceeded` agrees with what `apply` does.
        for max in [1.0, 20.0, 59.9, 60.1, 180.0] {
            let mut r = runs.clone();
            let report = lifts(max).apply(None, &mut r);
            assert_eq!(lifts(max).exceeded(&runs), report.split > 0, "limit {max}");
        }
    }

    #[test]
    fn a_limit_of_half_a_turn_splits_nothing() {
        let run: Vec<Location> = [0.0, 90.0, -90.0, 0.0]
            .iter()
            .enumerate()
            .map(|(i, &a)| leaning(i as f64, a))
            .collect();
        let mut runs = vec![run.clone()];
        let r = lifts(180.0).apply(None, &mut runs);
        assert_eq!(
            r,
            AxisReport {
                largest_kept: std::f64::consts::PI,
                ..Default::default()
            }
        );
        assert_eq!(runs, vec![run]);
    }

    #[test]
    fn on_every_corpus_mesh_the_steps_stay_out_of_it_and_within_the_limit() {
        // Facet-normal passes across each corpus mesh (the axis jumps at
        // facet edges), the changes over 10 degrees stepped: every added
        // step clears the part, and no two neighbours of a run are more
        // than 10 degrees apart.
        let (mut stepped, mut added, mut split) = (0, 0, 0);
        let ran = on_corpus_passes(|f, gc, size, fa, xy| {
            let dc = gc.drop_cutter();
            let Ok(mut runs) = fa.pass(dc, xy) else { return };
            let before: Vec<Location> = runs.iter().flatten().copied().collect();
            let lim = AxisLimit {
                max: 10f64.to_radians(),
                length: fa.axis_length,
                steps: true,
            };
            let r = lim.apply(Some(gc), &mut runs);
            let after: Vec<Location> = runs.iter().flatten().copied().collect();
            assert_eq!(after.len(), before.len() + r.inserted, "{f:?}");
            for run in &runs {
                for w in run.windows(2) {
                    assert!(axis_change(&w[0], &w[1]) <= lim.max + 1e-12, "{f:?}");
                }
            }
            for l in after.iter().filter(|l| !before.contains(l)) {
                assert!(
                    gc.clearance(l.cl, l.axis(), fa.axis_length) <= GOUGE_TOL * size.max(1.0),
                    "{f:?}: step {l:?} cuts into the part"
                );
            }
            (stepped, added, split) = (stepped + r.stepped, added + r.inserted, split + r.split);
        });
        if ran.is_none() {
            crate::corpus::skip("corpus_meshes_axis_steps_clear_them");
            return;
        }
        crate::corpus::record("corpus_meshes_axis_steps_clear_them", added);
        assert!(stepped > 10, "{stepped}");
        println!("corpus meshes: {stepped} changes over 10 degrees turned in {added} steps, {split} split");
    }
}
