//! Top-level entities held back for expansion in batches, so that their
//! splines are fitted on the thread pool, many at once, while the reader
//! goes on with the next batch.
//!
//! A drawing of many splines spends most of its import fitting them (each
//! becomes a hundred arcs or more), one after the other on the reading
//! thread. From its first SPLINE on, the import hands top-level entities
//! to [`Batches`]; when a batch is full its splines are sent to the pool,
//! and the batch before it, whose fits are done meanwhile, is expanded
//! in order. The expansion is the one entity by entity: a fit made ahead
//! is used only where it is, piece for piece, what the fit in its turn
//! would make (see `Expander::fit`), so the segments, warnings, counts and
//! errors are the same as without batches, on any number of threads.

use super::curves::{Curve, fit_biarcs_one_by_one};
use super::entities::{Entity, EntityShape};
use super::expand::{Expander, Prefit, Sink};
use super::ocs::Affine;
use super::reader::Pos;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc;

/// Splines (one per copy of each) that make a batch full: enough for
/// every core to fit a share of.
const BATCH_CURVES: usize = 64;
/// Entities that make a batch full whatever it holds: after the last
/// spline, a batch of these ends the batching.
const BATCH_ENTITIES: usize = 4096;

/// The fits of one batch's splines.
enum Fits {
    /// Fewer than two splines: each is fitted in its turn (its long runs
    /// of intervals in parallel).
    None,
    /// Running on the pool.
    Running {
        done: mpsc::Receiver<Vec<(usize, Prefit)>>,
        /// Entities times copies: the numbering of the fits.
        slots: usize,
    },
    /// Done already, by number.
    Done(Vec<Option<Prefit>>),
}

impl Fits {
    /// Start fitting the splines of `batch`. `drawn`: segments in the
    /// drawing so far.
    fn start(x: &Expander, batch: &[Entity], tops: &[Affine], drawn: usize) -> Fits {
        use rayon::prelude::*;
        let curves = x.spline_curves(batch, tops);
        if curves.len() < 2 {
            return Fits::None;
        }
        // Room for one more piece than the bound leaves now: the drawing
        // only grows, so no spline's fit in turn is allowed more.
        let room = x.max_segments.saturating_sub(drawn).saturating_add(1);
        let tol = x.arc_tol;
        let fit_all = move |curves: Vec<(usize, Box<dyn Curve>)>| -> Vec<(usize, Prefit)> {
            curves
                .into_par_iter()
                .map(|(k, c)| {
                    let mut pieces = Vec::new();
                    let stats = fit_biarcs_one_by_one(c.as_ref(), tol, room, &mut pieces);
                    (k, Prefit { pieces, stats })
                })
                .collect()
        };
        let slots = batch.len() * tops.len();
        if rayon::current_thread_index().is_some() {
            // Called on the pool itself (an import inside a parallel
            // loop): waiting there for a job queued behind it could wait
            // for ever when every thread does the same. Fitted now, this
            // thread taking its share.
            return Fits::Done(numbered(fit_all(curves), slots));
        }
        let (tx, rx) = mpsc::channel();
        rayon::spawn(move || {
            // A fit that panics sends nothing: the splines are then
            // fitted in turn, on the reading thread, which reports it.
            if let Ok(fits) = catch_unwind(AssertUnwindSafe(|| fit_all(curves))) {
                // The import may have stopped on an error meanwhile.
                let _ = tx.send(fits);
            }
        });
        Fits::Running { done: rx, slots }
    }

    /// Wait for the fits, by number.
    fn wait(self) -> Vec<Option<Prefit>> {
        match self {
            Fits::None => Vec::new(),
            Fits::Running { done, slots } => done.recv().map_or_else(|_| Vec::new(), |d| numbered(d, slots)),
            Fits::Done(fits) => fits,
        }
    }
}

/// Fits by number, in `slots` places.
fn numbered(done: Vec<(usize, Prefit)>, slots: usize) -> Vec<Option<Prefit>> {
    let mut fits = Vec::new();
    fits.resize_with(slots, || None);
    for (k, f) in done {
        fits[k] = Some(f);
    }
    fits
}

/// Whether this thread's imports expand every entity as it is read (the
/// tests' reference): the import hands it to its placer thread.
#[cfg(test)]
pub(super) fn unbatched() -> bool {
    tests::UNBATCHED.get()
}

/// See [`unbatched`].
#[cfg(test)]
pub(super) fn set_unbatched(on: bool) {
    tests::UNBATCHED.set(on);
}

/// Entities waiting for expansion: the batch being filled and the one
/// whose splines are being fitted.
#[derive(Default)]
pub(super) struct Batches {
    filling: Vec<Entity>,
    /// Splines in `filling`, one per copy.
    curves: usize,
    fitting: Option<(Vec<Entity>, Fits)>,
}

impl Batches {
    /// Take `e` into the batch being filled, or give it back to be
    /// expanded at once: nothing is held and it is no spline.
    pub fn offer(&mut self, e: Entity, copies: usize) -> Option<Entity> {
        #[cfg(test)]
        if tests::UNBATCHED.get() {
            return Some(e);
        }
        let spline = matches!(e.shape, EntityShape::Spline { .. });
        if !spline && self.filling.is_empty() && self.fitting.is_none() {
            return Some(e);
        }
        if spline {
            self.curves += copies;
        }
        self.filling.push(e);
        None
    }

    /// Whether the batch being filled is full: call [`Batches::advance`].
    pub fn full(&self) -> bool {
        self.curves >= BATCH_CURVES || self.filling.len() >= BATCH_ENTITIES
    }

    /// Start fitting the batch being filled and expand the one before it
    /// (an error there stops the expansion and is returned). A batch
    /// without splines is expanded at once, with the one before it, and
    /// the batching ends until the next spline.
    pub fn advance<E>(&mut self, to: &mut Expansion<impl FnMut(&mut Sink, Pos) -> Result<(), E>>) -> Result<(), E> {
        let batch = std::mem::take(&mut self.filling);
        let curves = std::mem::replace(&mut self.curves, 0);
        let done = if curves == 0 {
            self.finish_fitting(to).and_then(|()| to.expand(&batch, Vec::new()))
        } else {
            let fits = Fits::start(to.x, &batch, to.tops, to.sink.segments.len());
            match self.fitting.replace((batch, fits)) {
                Some((before, fits)) => to.expand(&before, fits.wait()),
                None => Ok(()),
            }
        };
        self.drop_on_error(done)
    }

    /// Expand everything held, in order.
    pub fn finish<E>(&mut self, to: &mut Expansion<impl FnMut(&mut Sink, Pos) -> Result<(), E>>) -> Result<(), E> {
        if self.filling.is_empty() && self.fitting.is_none() {
            return Ok(());
        }
        let batch = std::mem::take(&mut self.filling);
        let fits = Fits::start(to.x, &batch, to.tops, to.sink.segments.len());
        self.curves = 0;
        let done = self.finish_fitting(to).and_then(|()| to.expand(&batch, fits.wait()));
        self.drop_on_error(done)
    }

    /// After an error in the expansion, whatever is still held comes after
    /// the entity that failed: it is dropped, never expanded (a later
    /// [`Batches::finish`], as the import calls on a read error, has then
    /// nothing to do).
    fn drop_on_error<E>(&mut self, done: Result<(), E>) -> Result<(), E> {
        if done.is_err() {
            *self = Batches::default();
        }
        done
    }

    fn finish_fitting<E>(&mut self, to: &mut Expansion<impl FnMut(&mut Sink, Pos) -> Result<(), E>>) -> Result<(), E> {
        match self.fitting.take() {
            Some((batch, fits)) => to.expand(&batch, fits.wait()),
            None => Ok(()),
        }
    }
}

/// Where held entities are expanded: each top-level entity under every
/// transform of `tops` into `sink`, then `after` with its position (the
/// import's check of the bound and of bad geometry, which may stop it).
pub(super) struct Expansion<'a, 'b, F> {
    pub x: &'a Expander<'b>,
    pub tops: &'a [Affine],
    pub sink: &'a mut Sink,
    pub after: F,
}

impl<E, F: FnMut(&mut Sink, Pos) -> Result<(), E>> Expansion<'_, '_, F> {
    /// Expand `batch` in order, entity `i` under transform `j` with the
    /// fit numbered `i * tops.len() + j`, if any.
    fn expand(&mut self, batch: &[Entity], mut fits: Vec<Option<Prefit>>) -> Result<(), E> {
        for (i, e) in batch.iter().enumerate() {
            for (j, t) in self.tops.iter().enumerate() {
                let prefit = fits.get_mut(i * self.tops.len() + j).and_then(Option::take);
                self.x.entity_prefitted(e, t, prefit, self.sink);
            }
            (self.after)(self.sink, e.pos)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{ImportOptions, import};
    use super::*;
    use crate::geometry::V3;
    use std::cell::Cell;
    use std::fmt::Write;

    thread_local! {
        /// Every entity expanded as it is read: the reference.
        pub(super) static UNBATCHED: Cell<bool> = const { Cell::new(false) };
    }

    #[derive(Debug, Clone)]
    enum Ent {
        /// A cubic spline through `n` control points on a wave.
        Spline {
            n: usize,
            amp: f64,
            layer: u8,
        },
        /// A spline with a control point a kilometre out: bad input.
        FarSpline,
        /// A spline with one control point: left out with a warning.
        LoneSpline,
        Line {
            x: f64,
            layer: u8,
        },
        Circle {
            r: f64,
        },
        /// An insert of the block holding a spline and a line.
        Insert {
            x: f64,
        },
    }

    fn text(ents: &[(Ent, f64)], cut: Option<usize>) -> String {
        let mut t = String::from(
            "0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n2\nB\n10\n0\n20\n0\n\
             0\nSPLINE\n71\n3\n10\n0\n20\n0\n10\n1\n20\n2\n10\n2\n20\n-1\n10\n3\n20\n0\n10\n4\n20\n1\n\
             0\nLINE\n10\n0\n20\n0\n11\n4\n21\n1\n0\nENDBLK\n0\nENDSEC\n0\nSECTION\n2\nENTITIES\n",
        );
        for (k, (e, y)) in ents.iter().enumerate() {
            if cut == Some(k) {
                // A group code without its value: the file ends there.
                t += "0\nLINE\n10\n";
                return t;
            }
            match e {
                Ent::Spline { n, amp, layer } => {
                    let _ = write!(t, "0\nSPLINE\n8\nL{layer}\n71\n3\n");
                    for i in 0..*n {
                        let _ = write!(t, "10\n{}\n20\n{}\n30\n0\n", i, y + amp * ((i * 7) % 5) as f64);
                    }
                }
                Ent::FarSpline => {
                    let _ = write!(
                        t,
                        "0\nSPLINE\n71\n3\n10\n0\n20\n{y}\n10\n1\n20\n1e12\n10\n2\n20\n0\n10\n3\n20\n1\n"
                    );
                }
                Ent::LoneSpline => t += "0\nSPLINE\n71\n3\n10\n0\n20\n0\n",
                Ent::Line { x, layer } => {
                    let _ = write!(t, "0\nLINE\n8\nL{layer}\n10\n{x}\n20\n{y}\n11\n{}\n21\n{y}\n", x + 1.0);
                }
                Ent::Circle { r } => {
                    let _ = write!(t, "0\nCIRCLE\n10\n0\n20\n{y}\n40\n{r}\n");
                }
                Ent::Insert { x } => {
                    let _ = write!(t, "0\nINSERT\n2\nB\n10\n{x}\n20\n{y}\n");
                }
            }
        }
        t + "0\nENDSEC\n0\nEOF\n"
    }

    /// Everything an import gives, or its error, as text to compare.
    fn outcome(t: &str, opts: &ImportOptions, unbatched: bool) -> String {
        UNBATCHED.set(unbatched);
        let r = import(Box::new(std::io::Cursor::new(t.as_bytes().to_vec())), opts);
        UNBATCHED.set(false);
        match r {
            Ok(i) => format!(
                "{:?}\n{:?} {:?} {:?} {} {} {} {:?}",
                i.sink.segments,
                i.sink.layers,
                i.sink.warnings,
                i.sink.used,
                i.sink.curves,
                i.sink.curve_pieces,
                i.sink.curve_chords,
                i.skipped
            ),
            Err(e) => format!("error: {e}"),
        }
    }

    fn ent() -> impl proptest::strategy::Strategy<Value = Ent> {
        use proptest::prelude::*;
        prop_oneof![
            12 => (4usize..14, 0.5f64..4.0, 0u8..2).prop_map(|(n, amp, layer)| Ent::Spline { n, amp, layer }),
            1 => Just(Ent::FarSpline),
            1 => Just(Ent::LoneSpline),
            3 => (-5.0f64..5.0, 0u8..2).prop_map(|(x, layer)| Ent::Line { x, layer }),
            1 => (0.5f64..3.0).prop_map(|r| Ent::Circle { r }),
            1 => (-5.0f64..5.0).prop_map(|x| Ent::Insert { x }),
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        /// Batches change nothing: the same segments (to the bit), layers,
        /// warnings and counts, or the same error (a spline out of range,
        /// the segment bound crossed, a file cut short), as expanding each
        /// entity as it is read. Drawings of up to 260 entities, so that
        /// batches fill, are fitted while the next fills, and end on a
        /// section's end, an error or the bound; one or two copies; with
        /// and without a layer filter.
        #[test]
        fn batches_import_what_one_by_one_imports(
            ents in proptest::collection::vec((ent(), -50.0f64..50.0), 1..260),
            bound in proptest::sample::select(vec![usize::MAX, 40, 700, 2_500, 6_000]),
            two_copies: bool,
            filter: bool,
            cut in proptest::option::weighted(0.2, 0usize..260),
            far_at in proptest::option::weighted(0.2, 0usize..260),
        ) {
            let mut ents = ents;
            if let Some(k) = far_at.filter(|&k| k < ents.len()) {
                ents[k].0 = Ent::FarSpline;
            }
            let t = text(&ents, cut);
            let opts = ImportOptions {
                max_segments: bound,
                layers: if filter { vec!["L1".into()] } else { Vec::new() },
                copies: if two_copies {
                    vec![Affine::translate(V3::zeros()), Affine::translate(V3::new(100.0, 0.0, 0.0))]
                } else {
                    Vec::new()
                },
                ..Default::default()
            };
            let want = outcome(&t, &opts, true);
            let got = outcome(&t, &opts, false);
            proptest::prop_assert!(got == want, "batched:\n{}\none by one:\n{}", &got[..got.len().min(600)], &want[..want.len().min(600)]);
        }
    }

    #[test]
    fn an_import_on_the_pool_itself_does_not_wait_for_itself() {
        // One thread in the pool, and the import runs on it: a batch
        // whose fits were queued behind the import would never be fitted.
        let ents: Vec<(Ent, f64)> = (0..150)
            .map(|k| {
                (
                    Ent::Spline {
                        n: 6,
                        amp: 1.0,
                        layer: 0,
                    },
                    k as f64,
                )
            })
            .collect();
        let t = text(&ents, None);
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let imp = pool.install(|| {
                import(
                    Box::new(std::io::Cursor::new(t.as_bytes().to_vec())),
                    &ImportOptions::default(),
                )
            });
            let _ = tx.send(
                imp.map(|i| (i.sink.curves, i.sink.prefits_used))
                    .map_err(|e| e.to_string()),
            );
        });
        let got = rx
            .recv_timeout(std::time::Duration::from_secs(60))
            .expect("the import hung");
        assert_eq!(got, Ok((150, 150)));
    }

    #[test]
    fn a_drawing_of_splines_has_them_fitted_ahead() {
        // The property above compares with the reference; this checks
        // that the batches are used at all: 200 splines, a line and a
        // circle among them, every spline fitted ahead but the few of
        // the last batch when it holds fewer than two.
        let mut ents: Vec<(Ent, f64)> = (0..200)
            .map(|k| {
                (
                    Ent::Spline {
                        n: 8,
                        amp: 2.0,
                        layer: 0,
                    },
                    k as f64,
                )
            })
            .collect();
        ents.insert(70, (Ent::Line { x: 1.0, layer: 0 }, 0.0));
        ents.insert(150, (Ent::Circle { r: 1.0 }, 0.0));
        let t = text(&ents, None);
        let opts = ImportOptions::default();
        let imp = import(Box::new(std::io::Cursor::new(t.as_bytes().to_vec())), &opts).unwrap();
        assert_eq!(imp.sink.curves, 200);
        assert_eq!(imp.sink.prefits_used, 200);
        UNBATCHED.set(true);
        let one = import(Box::new(std::io::Cursor::new(t.as_bytes().to_vec())), &opts).unwrap();
        UNBATCHED.set(false);
        assert_eq!(one.sink.prefits_used, 0);
        assert_eq!(imp.sink.segments, one.sink.segments);
    }
}
