//! The material-removal engine, without I/O: moves and a cutter in, chip
//! volume per block and per step out. gsim's report writes what it returns
//! to CSV; feedopt schedules feeds from it.
//!
//! A move is cut in steps (Bayesteh 2013 §3.1: pieces of feed per tooth ×
//! a scale factor, or any fixed length the caller chooses); each step is
//! cut as straight pieces (arcs as chords) on a [`Workpiece`]. Pieces are
//! queued and cut in batches, so a parallel workpiece keeps both cores
//! busy, and the finished blocks come out in program order.

use super::stock::Stock;
use super::time::MoveClass;
use crate::cutter::Cutter;
use crate::geometry::{Arc3, P3};
use std::collections::VecDeque;

/// Material the engine cuts: the height field today, dexels next.
pub trait Workpiece {
    /// Cut straight tool-tip moves in order; the volume each removed, mm³.
    fn cut_lines(&mut self, pieces: &[(P3, P3)], cutter: &Cutter) -> Vec<f64>;
    /// The straight pieces an arc is cut as, fine enough for this
    /// workpiece's resolution.
    fn arc_chords(&self, arc: &Arc3) -> Vec<(P3, P3)>;
    /// Material volume left, mm³.
    fn volume(&self) -> f64;
}

impl Workpiece for Stock {
    fn cut_lines(&mut self, pieces: &[(P3, P3)], cutter: &Cutter) -> Vec<f64> {
        Stock::cut_lines(self, pieces, cutter)
    }
    fn arc_chords(&self, arc: &Arc3) -> Vec<(P3, P3)> {
        Stock::arc_chords(self, arc)
    }
    fn volume(&self) -> f64 {
        Stock::volume(self)
    }
}

/// Pieces cut together: large enough to keep two cores busy, small enough
/// that the queue stays a few hundred kilobytes.
const BATCH_PIECES: usize = 4096;

/// One move for the engine.
#[derive(Debug, Clone, Copy)]
pub struct CutMove {
    /// Source line (or record) the move came from, carried through.
    pub line: Option<u64>,
    /// Rapid, line or arc (carried through to the block; rapids cut too).
    pub class: MoveClass,
    /// Tool tip where the move starts, mm.
    pub from: P3,
    /// Tool tip where it ends, mm.
    pub to: P3,
    /// The arc when the move is one (its start is `from`, its end `to`).
    pub arc: Option<Arc3>,
    /// Path length of the move, mm.
    pub length_mm: f64,
    /// Step length, mm; `None` cuts the move as one step.
    pub step_mm: Option<f64>,
}

/// One step of a move and the chip it removed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutStep {
    /// Tool tip at the end of the step.
    pub end: P3,
    /// Material the step removed, mm³.
    pub volume_mm3: f64,
}

/// A move after cutting.
#[derive(Debug, Clone, PartialEq)]
pub struct CutBlock {
    /// The move's source line, as given in [`CutMove::line`].
    pub line: Option<u64>,
    /// The move's class, as given.
    pub class: MoveClass,
    /// The move's path length, mm, as given.
    pub length_mm: f64,
    /// True when the move was cut in steps of a given length.
    pub stepped: bool,
    /// The steps in path order, all of length `length_mm / steps.len()`.
    pub steps: Vec<CutStep>,
    /// Volume removed by the whole move, mm³.
    pub volume_mm3: f64,
    /// Largest step volume, mm³.
    pub max_step_mm3: f64,
}

/// A block waiting for its batch: per step its end point, first piece and
/// piece count.
struct Queued {
    line: Option<u64>,
    class: MoveClass,
    length_mm: f64,
    stepped: bool,
    steps: Vec<(P3, usize, usize)>,
}

/// Cuts moves on a workpiece in batches and hands back the finished blocks
/// in order.
pub struct Engine<S: Workpiece> {
    /// The material; read it (volume, heights) between batches, after
    /// [`Engine::flush`].
    pub stock: S,
    /// The cutter the next batch cuts with: flush before changing it, or
    /// queued moves are cut with the new one.
    pub cutter: Cutter,
    pieces: Vec<(P3, P3)>,
    queued: Vec<Queued>,
    done: VecDeque<CutBlock>,
}

impl<S: Workpiece> Engine<S> {
    /// An engine cutting `stock` with `cutter`.
    pub fn new(stock: S, cutter: Cutter) -> Self {
        Engine {
            stock,
            cutter,
            pieces: Vec::new(),
            queued: Vec::new(),
            done: VecDeque::new(),
        }
    }

    /// Queue a move; its block comes out of [`Self::pop`] once its batch is
    /// cut (at the latest after [`Self::flush`]).
    pub fn push(&mut self, mv: &CutMove) {
        let (from, to) = (mv.from, mv.to);
        let n = match mv.step_mm {
            Some(st) if mv.length_mm > 0.0 => ((mv.length_mm / st).ceil() as usize).clamp(1, 1 << 24),
            _ => 1,
        };
        // Sub-arcs are built without extra turns: keep each under a turn.
        let n = match &mv.arc {
            Some(a) if n > 1 => n.max(4 * (a.extra_turns as usize + 1)),
            _ => n,
        };
        let mut prev = from;
        let mut steps = Vec::with_capacity(n);
        for k in 1..=n {
            let t = k as f64 / n as f64;
            let first = self.pieces.len();
            let p = match &mv.arc {
                Some(a) => {
                    let p = if k == n { to } else { a.point_at(t) };
                    let sub = if n == 1 {
                        Some(*a)
                    } else {
                        Arc3::new(a.center, prev, p, a.ccw, a.plane, 0)
                    };
                    if let Some(sa) = sub {
                        self.pieces.extend(self.stock.arc_chords(&sa));
                    }
                    p
                }
                None => {
                    let p = if k == n { to } else { from + (to - from) * t };
                    self.pieces.push((prev, p));
                    p
                }
            };
            steps.push((p, first, self.pieces.len() - first));
            prev = p;
        }
        self.queued.push(Queued {
            line: mv.line,
            class: mv.class,
            length_mm: mv.length_mm,
            stepped: mv.step_mm.is_some(),
            steps,
        });
        if self.pieces.len() >= BATCH_PIECES {
            self.flush();
        }
    }

    /// Cut everything queued.
    pub fn flush(&mut self) {
        if self.queued.is_empty() {
            return;
        }
        let vols = self.stock.cut_lines(&self.pieces, &self.cutter);
        for q in std::mem::take(&mut self.queued) {
            let (mut v, mut vmax) = (0.0_f64, 0.0_f64);
            let mut steps = Vec::with_capacity(q.steps.len());
            for (p, first, count) in &q.steps {
                let vk: f64 = vols[*first..first + count].iter().sum();
                steps.push(CutStep {
                    end: *p,
                    volume_mm3: vk,
                });
                v += vk;
                vmax = vmax.max(vk);
            }
            self.done.push_back(CutBlock {
                line: q.line,
                class: q.class,
                length_mm: q.length_mm,
                stepped: q.stepped,
                steps,
                volume_mm3: v,
                max_step_mm3: vmax,
            });
        }
        self.pieces.clear();
    }

    /// The next finished block, in program order.
    pub fn pop(&mut self) -> Option<CutBlock> {
        self.done.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slot(step: Option<f64>) -> Vec<CutBlock> {
        let stock = Stock::new(P3::new(-1.0, -1.0, -1.0), P3::new(3.0, 1.0, 0.0), 0.01).unwrap();
        let mut e = Engine::new(stock, Cutter::Flat { radius: 0.4 });
        let a = P3::new(0.0, 0.0, -0.1);
        let b = P3::new(2.0, 0.0, -0.1);
        for (from, to, class) in [(P3::new(0.0, 0.0, 1.0), a, MoveClass::Rapid), (a, b, MoveClass::Line)] {
            e.push(&CutMove {
                line: None,
                class,
                from,
                to,
                arc: None,
                length_mm: (to - from).norm(),
                step_mm: step.filter(|_| class != MoveClass::Rapid),
            });
        }
        e.flush();
        std::iter::from_fn(|| e.pop()).collect()
    }

    #[test]
    fn steps_add_up_to_their_block_and_a_slot_removes_width_times_depth() {
        let whole = slot(None);
        let stepped = slot(Some(0.01));
        assert_eq!(whole.len(), 2);
        let (w, s) = (&whole[1], &stepped[1]);
        assert_eq!(s.steps.len(), 200);
        let sum: f64 = s.steps.iter().map(|x| x.volume_mm3).sum();
        assert!((sum - s.volume_mm3).abs() < 1e-12);
        assert!((s.volume_mm3 - w.volume_mm3).abs() < 1e-9, "same stock, same cut");
        // Mid-slot a step removes width × depth × length.
        let mid = s.steps[100].volume_mm3;
        assert!((mid - 0.8 * 0.1 * 0.01).abs() < 0.05 * mid, "{mid}");
        assert_eq!(s.steps[199].end, P3::new(2.0, 0.0, -0.1));
    }
}
