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
fn drop_short(run: Vec<Segment>, m: &LaserSetup, dropped: &mut (usize, f64)) -> Vec<Vec<Segment>> {
    let n = run.len();
    if n == 0 {
        return Vec::new();
    }
    let min = m.min_cut();
    let cos = m.tangent_cos();
    let corner = |a: &Segment, b: &Segment| a.end_tangent().dot(&b.start_tangent()) < cos;
    let mut starts = vec![0];
    starts.extend((1..n).filter(|&i| corner(&run[i - 1], &run[i])));
    let mut stretches: Vec<Vec<(usize, usize)>> = starts
        .iter()
        .enumerate()
        .map(|(k, &a)| vec![(a, starts.get(k + 1).copied().unwrap_or(n))])
        .collect();
    let closed = (run[0].start() - run[n - 1].end()).norm() < 1e-9;
    if closed && stretches.len() > 1 && !corner(&run[n - 1], &run[0]) {
        // The seam is smooth: the last stretch runs on into the first.
        let first = stretches.remove(0);
        stretches.last_mut().expect("more than one").extend(first);
    }
    let lens: Vec<f64> = stretches
        .iter()
        .map(|v| v.iter().flat_map(|&(a, b)| &run[a..b]).map(Segment::length).sum())
        .collect();
    let Some(j) = lens.iter().position(|&l| l < min) else {
        return vec![run];
    };
    let k = stretches.len();
    // A closed run restarts after a dropped stretch, so what is kept stays
    // in one piece where it can.
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
            for &(a, b) in &stretches[i] {
                cur.extend_from_slice(&run[a..b]);
            }
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
            Some(prev) => match extend_arc(prev, e.end(), rmin) {
                Some(a) => *prev = a,
                None => out.push(e),
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
        .flat_map(|r| drop_short(r, m, dropped))
        .map(|r| merge_tiny(r, m.min_block(), m.min_radius()))
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
