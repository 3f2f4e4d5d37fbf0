//! From chip geometry per step to feed per tooth: the linear map of
//! Bayesteh 2013 eq. 3.2 as its text and figures intend, the moving
//! average, the chip cap, one feed per block, and sub-blocks chosen by
//! dynamic programming so none is shorter than the controller's minimum
//! block time.
//!
//! The thesis prints eq. 3.2 as `(f_max - f_min)(V - V_min)/(V_max - V_min)`,
//! which gives 0 at the smallest chip and rises with the chip; its text and
//! Fig. 3-3 say the opposite (f_max at the smallest chip, f_min at the
//! largest). The map here is `f_max - (f_max - f_min)(V - V_min)/(V_max -
//! V_min)`.

/// One step of the simulated path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Path distance at the end of the step, mm (all feed moves, in order).
    pub s_mm: f64,
    /// Chip cross-section: volume removed per mm of path, mm². The chip
    /// volume per tooth is this times the feed per tooth.
    pub area_mm2: f64,
    /// Scheduled: a feed move with travel in XY that removes material.
    pub cutting: bool,
}

/// The chip-volume band of a program: the smallest and largest chip
/// cross-section over the scheduled steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// The smallest chip cross-section of a cutting step, mm².
    pub area_min_mm2: f64,
    /// The largest chip cross-section of a cutting step, mm².
    pub area_max_mm2: f64,
}

impl Band {
    /// The band over the cutting steps; `None` when none cuts.
    pub fn of(steps: &[Step]) -> Option<Band> {
        let mut it = steps.iter().filter(|s| s.cutting).map(|s| s.area_mm2);
        let first = it.next()?;
        let (lo, hi) = it.fold((first, first), |(lo, hi), a| (lo.min(a), hi.max(a)));
        Some(Band {
            area_min_mm2: lo,
            area_max_mm2: hi,
        })
    }

    /// Eq. 3.2 corrected: feed per tooth (mm) for chip cross-section `a`
    /// (mm²), `fz_max` at the band's bottom, `fz_min` at its top and
    /// beyond; `fz_min` when the band has no width.
    pub fn map(&self, a: f64, fz_min: f64, fz_max: f64) -> f64 {
        let span = self.area_max_mm2 - self.area_min_mm2;
        if span <= 0.0 {
            return fz_min;
        }
        let t = ((a - self.area_min_mm2) / span).clamp(0.0, 1.0);
        fz_max - (fz_max - fz_min) * t
    }
}

/// Moving average of `u` over the cutting steps within `window_mm / 2` of
/// path on either side of each step (non-cutting steps keep their value and
/// take no part). Two pointers: linear in the number of steps.
pub fn moving_average(steps: &[Step], u: &[f64], window_mm: f64) -> Vec<f64> {
    let idx: Vec<usize> = (0..steps.len()).filter(|&i| steps[i].cutting).collect();
    let mut out = u.to_vec();
    if window_mm <= 0.0 || idx.is_empty() {
        return out;
    }
    let h = 0.5 * window_mm;
    let (mut lo, mut hi) = (0usize, 0usize);
    let mut sum = 0.0;
    for k in 0..idx.len() {
        let s = steps[idx[k]].s_mm;
        while hi < idx.len() && steps[idx[hi]].s_mm <= s + h {
            sum += u[idx[hi]];
            hi += 1;
        }
        while steps[idx[lo]].s_mm < s - h {
            sum -= u[idx[lo]];
            lo += 1;
        }
        out[idx[k]] = sum / (hi - lo) as f64;
    }
    out
}

/// Per-step feed-per-tooth targets (mm) over the whole series, indexed by
/// step; [`Targets::feed`] reduces a block's sub-range of them.
pub struct Targets<'a> {
    /// The target after the moving average.
    pub smooth: &'a [f64],
    /// The target before smoothing ([`By::Max`] takes its smallest).
    pub raw: &'a [f64],
    /// The largest feed per tooth that keeps the step's chip within the
    /// cap (the largest chip at f_min).
    pub cap: &'a [f64],
    /// Which steps are scheduled; the others take no part.
    pub cutting: &'a [bool],
}

/// How a block's feed is taken from its steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum By {
    /// Mean of the smoothed targets (the thesis' average chip volume).
    Mean,
    /// The target of the largest chip (the smallest raw target).
    Max,
}

impl Targets<'_> {
    /// Feed per tooth (mm) for steps `i..j`, by `by` and never above any of
    /// their caps, or `None` when none of them cuts.
    pub fn feed(&self, i: usize, j: usize, by: By) -> Option<f64> {
        let (mut sum, mut n, mut lo_raw, mut cap) = (0.0, 0usize, f64::INFINITY, f64::INFINITY);
        for k in i..j {
            if self.cutting[k] {
                sum += self.smooth[k];
                n += 1;
                lo_raw = lo_raw.min(self.raw[k]);
                cap = cap.min(self.cap[k]);
            }
        }
        if n == 0 {
            return None;
        }
        let f = match by {
            By::Mean => sum / n as f64,
            By::Max => lo_raw,
        };
        Some(f.min(cap))
    }
}

/// Part of a block: a range of its steps and the feed it runs at. The
/// feed is mm/s out of [`split_block`] and [`merge_similar`], in the
/// program's feed unit once the schedule converts it for writing.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// First step of the block in the segment (0-based).
    pub start: usize,
    /// One past its last step.
    pub end: usize,
    /// The segment's feed.
    pub feed: f64,
}

/// Split a block of `n` equal steps of `step_mm` into segments whose time
/// at their feed is at least `t_min_s`, minimising the block's time plus
/// `penalty_s` per segment (so near-equal neighbours merge). `feed(i, j)`
/// gives a segment's feed in mm/s. Steps are grouped so the search stays
/// under `max_nodes²` work. Returns `None` when even the whole block as one
/// segment has no feed.
pub fn split_block(
    n: usize,
    step_mm: f64,
    t_min_s: f64,
    penalty_s: f64,
    max_nodes: usize,
    feed: &dyn Fn(usize, usize) -> Option<f64>,
) -> Option<Vec<Segment>> {
    let whole = feed(0, n)?;
    let g = n.div_ceil(max_nodes.max(1)).max(1);
    let nodes: Vec<usize> = (0..n).step_by(g).chain(std::iter::once(n)).collect();
    let m = nodes.len() - 1;
    let mut best = vec![f64::INFINITY; m + 1];
    let mut from = vec![usize::MAX; m + 1];
    let mut seg_feed = vec![0.0; m + 1];
    best[0] = 0.0;
    for b in 1..=m {
        for a in (0..b).rev() {
            if !best[a].is_finite() {
                continue;
            }
            let (i, j) = (nodes[a], nodes[b]);
            let Some(f) = feed(i, j) else { continue };
            let len = (j - i) as f64 * step_mm;
            let t = len / f;
            // The whole block may be shorter than the minimum: it is the
            // block the program already has.
            if t < t_min_s && !(a == 0 && b == m) {
                continue;
            }
            let c = best[a] + t + penalty_s;
            if c < best[b] {
                best[b] = c;
                from[b] = a;
                seg_feed[b] = f;
            }
        }
    }
    if !best[m].is_finite() {
        return Some(vec![Segment {
            start: 0,
            end: n,
            feed: whole,
        }]);
    }
    let mut segs = Vec::new();
    let mut b = m;
    while b > 0 {
        let a = from[b];
        segs.push(Segment {
            start: nodes[a],
            end: nodes[b],
            feed: seg_feed[b],
        });
        b = a;
    }
    segs.reverse();
    Some(segs)
}

/// Merge neighbouring segments whose feeds differ by less than `tol`
/// (relative), re-taking the merged feed from `feed`.
pub fn merge_similar(mut segs: Vec<Segment>, tol: f64, feed: &dyn Fn(usize, usize) -> Option<f64>) -> Vec<Segment> {
    let mut k = 0;
    while k + 1 < segs.len() {
        let (a, b) = (&segs[k], &segs[k + 1]);
        if (a.feed - b.feed).abs() <= tol * a.feed.max(b.feed) {
            let (start, end) = (a.start, b.end);
            let f = feed(start, end).unwrap_or(a.feed.min(b.feed));
            segs[k] = Segment { start, end, feed: f };
            segs.remove(k + 1);
        } else {
            k += 1;
        }
    }
    segs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(areas: &[f64]) -> Vec<Step> {
        areas
            .iter()
            .enumerate()
            .map(|(i, &a)| Step {
                s_mm: 0.01 * (i + 1) as f64,
                area_mm2: a,
                cutting: a > 0.0,
            })
            .collect()
    }

    #[test]
    fn the_map_gives_f_max_at_the_smallest_chip_and_f_min_at_the_largest() {
        let st = steps(&[0.0, 0.02, 0.05, 0.08]);
        let b = Band::of(&st).unwrap();
        assert_eq!(b.area_min_mm2, 0.02, "air takes no part");
        assert_eq!(b.map(0.02, 1.0, 1.5), 1.5);
        assert_eq!(b.map(0.08, 1.0, 1.5), 1.0);
        assert!((b.map(0.05, 1.0, 1.5) - 1.25).abs() < 1e-12);
    }

    #[test]
    fn the_moving_average_spans_its_window_and_skips_air() {
        let st = steps(&[1.0, 1.0, 0.0, 1.0, 1.0]);
        let u = [1.0, 2.0, 9.0, 3.0, 4.0];
        let m = moving_average(&st, &u, 0.025);
        assert_eq!(m[2], 9.0, "air keeps its value");
        assert!((m[1] - 1.5).abs() < 1e-12, "{m:?}");
        assert!((m[3] - 3.5).abs() < 1e-12, "{m:?}");
        assert_eq!(moving_average(&st, &u, 0.0), u.to_vec());
    }

    #[test]
    fn splits_respect_the_minimum_time_and_beat_one_feed() {
        // First half light (3 mm/s), second half heavy (2 mm/s); 2 mm in
        // 200 steps; minimum block 0.133 s (0.4 mm at 3 mm/s).
        // A segment reaching into the heavy half takes the heavy feed.
        let f = |_i: usize, j: usize| -> Option<f64> { Some(if j <= 100 { 3.0 } else { 2.0 }) };
        let segs = split_block(200, 0.01, 0.133, 1e-4, 400, &f).unwrap();
        assert_eq!(segs.len(), 2, "{segs:?}");
        assert_eq!((segs[0].end, segs[0].feed), (100, 3.0));
        for s in &segs {
            assert!((s.end - s.start) as f64 * 0.01 / s.feed >= 0.133);
        }
        // Too short to split: one segment.
        let segs = split_block(40, 0.01, 0.133, 1e-4, 400, &f).unwrap();
        assert_eq!(segs.len(), 1);
        let merged = merge_similar(
            vec![
                Segment {
                    start: 0,
                    end: 5,
                    feed: 2.0,
                },
                Segment {
                    start: 5,
                    end: 9,
                    feed: 2.05,
                },
            ],
            0.05,
            &|_, _| Some(2.0),
        );
        assert_eq!(
            merged,
            vec![Segment {
                start: 0,
                end: 9,
                feed: 2.0
            }]
        );
    }
}
