//! From passes to paths: stretches too short for the shutter dropped,
//! pieces too short for a controller block merged into their neighbours,
//! and the passes of a region joined by beam-off Dubins links at V.

use crate::geometry::{P3, Plane, V2};
use crate::laser::constant_velocity::Tagged;
use crate::laser::dubins::connect;
use crate::laser::elem::MIN_PIECE;
use crate::laser::setup::LaserSetup;
use crate::model::chain::Segment;
use crate::model::toolpath::Role;

/// Split a run at its corners (joints the planner loops) and drop the
/// stretches shorter than the shutter's minimum exposure: it cannot expose
/// them reliably. Counts what was dropped in `dropped` (stretches, mm).
fn drop_short(mut run: Vec<Segment>, m: &LaserSetup, dropped: &mut (usize, f64)) -> Vec<Vec<Segment>> {
    let n = run.len();
    if n == 0 {
        return Vec::new();
    }
    let min = m.min_cut();
    let cos = m.tangent_cos();
    let corner = |a: &Segment, b: &Segment| a.end_tangent().dot(&b.start_tangent()) < cos;
    let mut starts = vec![0];
    starts.extend((1..n).filter(|&i| corner(&run[i - 1], &run[i])));
    let closed = (run[0].start() - run[n - 1].end()).norm() < 1e-9;
    if closed && starts.len() > 1 && !corner(&run[n - 1], &run[0]) {
        // The seam is smooth, inside a stretch, and the run is cut from
        // its start to its end: that stretch would become two cuts, one
        // at each end, each perhaps shorter than the shutter's minimum
        // exposure (the planner sees only the corners in between). Start
        // the run at its first corner instead; the seam is a corner then.
        let k = starts[1];
        run.rotate_left(k);
        starts = std::iter::once(0).chain(starts[2..].iter().map(|&s| s - k)).collect();
    }
    // Stretch i is run[starts[i]..starts[i + 1]].
    starts.push(n);
    let stretch = |i: usize| &run[starts[i]..starts[i + 1]];
    let k = starts.len() - 1;
    let lens: Vec<f64> = (0..k).map(|i| stretch(i).iter().map(Segment::length).sum()).collect();
    let Some(j) = lens.iter().position(|&l| l < min) else {
        return vec![run];
    };
    // A closed run (its seam a corner) restarts after a dropped stretch,
    // so what is kept stays in one piece where it can.
    let order: Vec<usize> = if closed {
        (1..=k).map(|i| (j + i) % k).collect()
    } else {
        (0..k).collect()
    };
    let mut out = Vec::new();
    let mut cur: Vec<Segment> = Vec::new();
    for i in order {
        if lens[i] < min {
            dropped.0 += 1;
            dropped.1 += lens[i];
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
        } else {
            cur.extend_from_slice(stretch(i));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Fold pieces shorter than the controller's least block (1 ms at V) into
/// a neighbouring line: a Turbo PMAC would stretch such a block and slow
/// down there. Pieces inside a stretch meet tangentially (within the
/// tangency tolerance), so the line barely turns.
fn merge_tiny(run: Vec<Segment>, min_block: f64, rmin: f64) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::with_capacity(run.len());
    let mut pending: Option<Segment> = None;
    for e in run {
        let e = match pending.take() {
            // A tiny piece before this line: the line starts earlier.
            Some(t) => match e {
                Segment::Line(_) => Segment::line(t.start(), e.end()),
                _ => match extend_arc(&e.reversed(), t.start(), rmin) {
                    Some(a) => a.reversed(),
                    None => {
                        out.push(t);
                        e
                    }
                },
            },
            None => e,
        };
        if e.length() >= min_block {
            out.push(e);
            continue;
        }
        match out.last_mut() {
            Some(prev @ Segment::Line(_)) => *prev = Segment::line(prev.start(), e.end()),
            // An arc that cannot reach over it (it would turn tighter than
            // the stage can at V): the next piece starts earlier instead.
            Some(prev) => match extend_arc(prev, e.end(), rmin) {
                Some(a) => *prev = a,
                None => pending = Some(e),
            },
            None => pending = Some(e),
        }
    }
    if let Some(t) = pending {
        out.push(t);
    }
    out
}

/// The arc leaving where `e` (an arc) starts, along its start direction,
/// and ending at `to`: `e` extended over a tiny piece that follows it.
/// None when that arc would be tighter than `rmin` or is degenerate.
fn extend_arc(e: &Segment, to: P3, rmin: f64) -> Option<Segment> {
    let Segment::Arc(_) = e else { return None };
    let a = e.start();
    let t = e.start_tangent();
    let n = crate::geometry::V3::new(-t.y, t.x, 0.0);
    let d = to - a;
    let den = 2.0 * n.dot(&d);
    if den.abs() < 1e-15 {
        return None;
    }
    let rho = d.norm_squared() / den;
    let arc = crate::geometry::arc::Arc3::new(a + n * rho, a, to, rho > 0.0, Plane::Xy, 0)?;
    (arc.radius() >= rmin * (1.0 - 1e-9)).then_some(Segment::Arc(arc))
}

/// Join runs of cut pieces into beam-off-linked paths: a Dubins link at
/// V from the end of one run to the start of the next, in the stage's
/// least radius and long enough for the shutter. Where no link exists the
/// path ends and the next starts (a rapid between).
pub(super) fn join_runs(runs: Vec<Vec<Segment>>, m: &LaserSetup, dropped: &mut (usize, f64)) -> Vec<Tagged> {
    let r = m.min_radius();
    let shape = m.connection_shape();
    let xy = |v: crate::geometry::V3| V2::new(v.x, v.y);
    let mut paths = Vec::new();
    let mut cur: Tagged = Vec::new();
    let runs: Vec<Vec<Segment>> = runs
        .into_iter()
        // Merged first: a merge can turn a smooth joint into a corner,
        // and the stretches must be those the planner will see.
        .map(|r| merge_tiny(r, m.min_block(), m.min_radius()))
        .flat_map(|r| drop_short(r, m, dropped))
        .collect();
    for run in runs {
        let Some(first) = run.first() else { continue };
        if let Some((last, _)) = cur.last() {
            let (din, dout) = (xy(last.end_tangent()), xy(first.start_tangent()));
            let link = (din.norm() > 1e-12 && dout.norm() > 1e-12)
                .then(|| {
                    connect(
                        last.end(),
                        din.normalize(),
                        first.start(),
                        dout.normalize(),
                        r,
                        shape,
                        Plane::Xy,
                    )
                })
                .flatten();
            match link {
                Some(link) => {
                    // A turn whose ends (almost) coincide is either a sliver
                    // or a whole loop, and a toolpath reader cannot tell
                    // which: drop a sliver, write a loop as two halves.
                    let mut at = last.end();
                    for e in link {
                        let pieces = match e {
                            Segment::Arc(_) if (e.end() - e.start()).norm() < 1e-6 => {
                                match e.split_at_length(0.5 * e.length(), MIN_PIECE) {
                                    Some((a, b)) if e.length() > 1e-6 => vec![a, b],
                                    _ => Vec::new(),
                                }
                            }
                            _ => vec![e],
                        };
                        for mut p in pieces {
                            p.set_start(at);
                            at = p.end();
                            cur.push((p, Role::Link));
                        }
                    }
                }
                None => paths.push(std::mem::take(&mut cur)),
            }
        }
        cur.extend(run.into_iter().map(|e| (e, Role::Cut)));
    }
    if !cur.is_empty() {
        paths.push(cur);
    }
    paths
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::arc::Arc3;
    use crate::laser::constant_velocity::{Note, plan_tagged};

    fn line(a: (f64, f64), b: (f64, f64)) -> Segment {
        Segment::line(P3::new(a.0, a.1, 0.0), P3::new(b.0, b.1, 0.0))
    }

    fn joined(run: &[Segment]) -> bool {
        run.windows(2).all(|w| (w[0].end() - w[1].start()).norm() < 1e-12)
    }

    #[test]
    fn a_tiny_piece_after_an_arc_too_tight_to_stretch_joins_the_next_line() {
        // A quarter turn at the stage's least radius, a corner turning on
        // the same way, a piece shorter than a block, then a long line on
        // from it: the arc cannot reach over the tiny piece (it would turn
        // tighter than the stage can), so the long line starts earlier. Seen on a
        // slice of a corpus mesh, where the tiny piece became a block a
        // Turbo PMAC stretched with the shutter open.
        let m = LaserSetup::default();
        let r = m.min_radius();
        let arc = Arc3::new(
            P3::new(0.0, r, 0.0),
            P3::new(0.0, 0.0, 0.0),
            P3::new(r, r, 0.0),
            true,
            Plane::Xy,
            0,
        )
        .expect("arc");
        let tiny = 0.5 * m.min_block();
        let run = vec![
            Segment::Arc(arc),
            line((r, r), (r - tiny, r)),
            line((r - tiny, r), (r - 0.3, r)),
        ];
        let out = merge_tiny(run.clone(), m.min_block(), r);
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(out.iter().all(|e| e.length() >= m.min_block()), "{out:?}");
        assert!(joined(&out));
        assert_eq!(out[0], run[0], "the arc is kept as it is");
        assert_eq!((out[1].start(), out[1].end()), (run[1].start(), run[2].end()));
    }

    #[test]
    fn a_closed_ring_with_a_smooth_seam_is_started_at_a_corner() {
        // A square ring whose seam lies 0.01 mm before a corner, on a
        // straight side: the stretch through the seam is a whole side, but
        // cut from the seam the planner would see a 0.01 mm cut at the
        // start (under the shutter's minimum exposure) and the rest of the
        // side at the end.
        let m = LaserSetup::default();
        let a = 1.0 - 0.01;
        let run = vec![
            line((a, 0.0), (1.0, 0.0)),
            line((1.0, 0.0), (1.0, 1.0)),
            line((1.0, 1.0), (0.0, 1.0)),
            line((0.0, 1.0), (0.0, 0.0)),
            line((0.0, 0.0), (a, 0.0)),
        ];
        assert!(run[0].length() < m.min_cut());
        let mut dropped = (0, 0.0);
        let out = drop_short(run.clone(), &m, &mut dropped);
        assert_eq!(dropped.0, 0, "nothing is short once the side is whole");
        assert_eq!(out.len(), 1);
        let ring = &out[0];
        assert_eq!(ring.len(), 5);
        assert_eq!(ring[0].start(), P3::new(1.0, 0.0, 0.0), "starts at the corner");
        assert!(joined(ring));
        assert_eq!(&ring[..], &[&run[1..], &run[..1]].concat()[..]);
        // Planned as one path, every cut is at least the minimum exposure.
        let path: Vec<_> = ring.iter().map(|&e| (e, Role::Cut)).collect();
        let mut notes = Vec::new();
        plan_tagged(&path, &m, &mut notes);
        assert!(!notes.iter().any(|n| matches!(n, Note::ShortCut { .. })), "{notes:?}");
        // The same ring cut from its seam, as before: a short cut.
        let path: Vec<_> = run.iter().map(|&e| (e, Role::Cut)).collect();
        let mut notes = Vec::new();
        plan_tagged(&path, &m, &mut notes);
        assert!(notes.iter().any(|n| matches!(n, Note::ShortCut { .. })), "{notes:?}");
    }

    #[test]
    fn a_short_stretch_of_a_ring_is_dropped_and_the_rest_kept_in_one_run() {
        // The same square with a notch: a 0.01 mm side between two corners
        // is dropped; the ring restarts after it, so what is left is one
        // run from the notch round to it.
        let m = LaserSetup::default();
        let run = vec![
            line((0.0, 0.0), (0.5, 0.0)),
            line((0.5, 0.0), (0.5, 0.01)),
            line((0.5, 0.01), (1.0, 0.01)),
            line((1.0, 0.01), (1.0, 1.0)),
            line((1.0, 1.0), (0.0, 1.0)),
            line((0.0, 1.0), (0.0, 0.0)),
        ];
        let mut dropped = (0, 0.0);
        let out = drop_short(run.clone(), &m, &mut dropped);
        assert_eq!(dropped.0, 1);
        assert!((dropped.1 - 0.01).abs() < 1e-12);
        assert_eq!(out, vec![[&run[2..], &run[..1]].concat()]);
    }
}
