//! The schedule turned into a program: each feed move's feed from its
//! steps' targets, one per block or split into sub-blocks no shorter than
//! the minimum block time, and the program text rewritten with them (F
//! words changed in place, marked sub-block lines inserted).

use super::schedule::{self, By, Segment, Targets};
use super::{Mode, MoveInfo, Options, from_fz, text};
use crate::gcode::Dialect;
use crate::model::toolpath::{MotionKind, Record};

/// The schedule's inputs, shared by the modes.
pub(super) struct FeedPlan<'a> {
    pub(super) o: &'a Options,
    pub(super) dialect: Dialect,
    pub(super) targets: &'a Targets<'a>,
    pub(super) moves: &'a [Option<MoveInfo>],
    /// Shortest sub-block, s.
    pub(super) t_min: f64,
}

impl FeedPlan<'_> {
    /// Program feed of steps `i..j` of a move, or the air feed.
    fn feed(&self, mi: &MoveInfo, i: usize, j: usize, by: By) -> f64 {
        let o = self.o;
        match self.targets.feed(mi.first + i, mi.first + j, by) {
            Some(fz) => from_fz(fz.clamp(o.fz_min_mm, o.fz_max_mm), mi.rpm, o.flutes, self.dialect),
            None if mi.plunge => mi.feed,
            None => o
                .air_feed
                .unwrap_or_else(|| from_fz(o.fz_max_mm, mi.rpm, o.flutes, self.dialect)),
        }
    }

    /// Segments per move (`None` for rapids): one per block, or split.
    pub(super) fn segments(&self, mode: Mode, incremental: bool) -> Vec<Option<Vec<Segment>>> {
        let lines_with_many = {
            let mut count = std::collections::HashMap::new();
            for mi in self.moves.iter().flatten() {
                *count.entry(mi.line).or_insert(0u32) += 1;
            }
            count
        };
        self.moves
            .iter()
            .map(|mi| {
                let mi = mi.as_ref()?;
                let one = vec![Segment {
                    start: 0,
                    end: mi.n,
                    feed: self.feed(mi, 0, mi.n, self.o.by),
                }];
                let splittable = mode != Mode::PerBlock
                    && !incremental
                    && matches!(mi.kind, MotionKind::Line)
                    && !mi.plunge
                    && lines_with_many.get(&mi.line) == Some(&1)
                    && self.targets.feed(mi.first, mi.first + mi.n, By::Mean).is_some();
                if !splittable {
                    return Some(one);
                }
                let f = |i: usize, j: usize| -> Option<f64> {
                    self.targets.feed(mi.first + i, mi.first + j, By::Mean)?;
                    let pf = self.feed(mi, i, j, By::Mean);
                    Some(pf * self.dialect.feed_unit().to_mm_per_s())
                };
                if mode == Mode::Naive {
                    let segs: Vec<Segment> = (0..mi.n)
                        .map(|k| Segment {
                            start: k,
                            end: k + 1,
                            feed: self.feed(mi, k, k + 1, By::Mean),
                        })
                        .collect();
                    return Some(segs);
                }
                // A margin over the minimum for the 0.0001 mm rounding of
                // the sub-block ends.
                let t_min = self.t_min * 1.01 + 1e-4;
                let segs = schedule::split_block(mi.n, mi.step_mm, t_min, 0.02 * self.t_min, 300, &f)?;
                let segs = schedule::merge_similar(segs, self.o.merge_tol, &f);
                let unit = self.dialect.feed_unit().to_mm_per_s();
                Some(
                    segs.into_iter()
                        .map(|s| Segment {
                            feed: s.feed / unit,
                            ..s
                        })
                        .collect(),
                )
            })
            .collect()
    }

    /// The program with these feeds; returns it and the number of source
    /// lines changed.
    pub(super) fn write(&self, base: &str, recs: &[Record], segs: &[Option<Vec<Segment>>]) -> (String, usize) {
        let d = self.dialect;
        let lines = text::lines(base);
        // Per source line: the feed to write (smallest of its moves) and
        // the sub-blocks to insert before it.
        let mut feed_of: Vec<Option<f64>> = vec![None; lines.len()];
        let mut keep: Vec<bool> = vec![true; lines.len()];
        let mut inserts: Vec<Vec<String>> = vec![Vec::new(); lines.len()];
        let mut k = 0;
        for r in recs {
            let Record::Move(m) = r else { continue };
            let (Some(mi), Some(sg)) = (&self.moves[k], &segs[k]) else {
                k += 1;
                continue;
            };
            k += 1;
            let Some(l) = m
                .block
                .and_then(|b| (b as usize).checked_sub(1))
                .filter(|l| *l < lines.len())
            else {
                continue;
            };
            let last = sg.last().map_or(mi.feed, |s| s.feed);
            feed_of[l] = Some(feed_of[l].map_or(last, |f: f64| f.min(last)));
            keep[l] &= mi.plunge;
            if sg.len() > 1
                && let Some(axes) = text::plain_linear(lines[l].body, d)
            {
                for s in &sg[..sg.len() - 1] {
                    let t = s.end as f64 / mi.n as f64;
                    let p = mi.from + (mi.to - mi.from) * t;
                    let mut to = [None; 3];
                    for a in 0..3 {
                        if let Some(v) = axes[a] {
                            let off = mi.to[a] - v;
                            to[a] = Some(p[a] - off);
                        }
                    }
                    inserts[l].push(text::sub_block(d, to, &text::format_feed(s.feed, d)));
                }
            }
        }
        let mut out = String::with_capacity(base.len() + base.len() / 8);
        let mut changed = 0;
        for (l, line) in lines.iter().enumerate() {
            for ins in &inserts[l] {
                out.push_str(ins);
                out.push_str(if line.eol.is_empty() { "\n" } else { line.eol });
            }
            match feed_of[l] {
                Some(f) if !keep[l] || text::f_words(line.body, d).is_empty() => {
                    let b = text::set_feed(line.body, d, &text::format_feed(f, d));
                    if b != line.body {
                        changed += 1;
                    }
                    out.push_str(&b);
                }
                _ => out.push_str(line.body),
            }
            out.push_str(line.eol);
        }
        (out, changed)
    }
}
