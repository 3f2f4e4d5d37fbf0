//! The second half of the import pipeline: entities placed as geometry on
//! a thread of their own while the reader goes on parsing.
//!
//! Reading an ASCII drawing is three kinds of work: tokenizing (on the
//! reader's block threads), the entity state machine over the tags, and
//! the expansion (blocks, units, transforms, arcs, splines) into segments.
//! The last two ran one after the other on the calling thread and were
//! most of the import; now the reader's thread parses and sends what it
//! finds, in file order, as [`Event`]s to a placer thread, which does
//! exactly what the one-thread loop did with each in turn. Nothing is
//! reordered, so the segments, counts, warnings and errors are the same;
//! an error on either side stops both (the placer drops its receiver and
//! the parser's next send fails).

use super::batch::{self, Batches};
use super::entities::{Entity, EntityShape};
use super::expand::{BlockDef, Sink};
use super::ocs::Affine;
use super::reader::DxfError;
use super::{ImportOptions, expander, finish, stopped};
use std::collections::HashMap;
use std::sync::mpsc::{Receiver, SyncSender};

/// What the parser found, in file order.
pub(super) enum Event {
    /// A SECTION, ENDSEC or EOF: whatever the batches hold is expanded.
    SectionBoundary,
    /// A BLOCK definition, name in upper case.
    Block(String, BlockDef),
    /// The transforms of the top-level entities (units and the user's
    /// copies), fixed at the first tag of the first top-level entity.
    Tops(Vec<Affine>),
    /// A top-level entity to place.
    Entity(Entity),
    /// The file was read to its EOF: place what is left.
    End,
    /// Reading stopped here: place what came before, then fail.
    Error(DxfError),
}

/// Events per message: the channel costs a wake-up per message, not per
/// entity.
const CHUNK: usize = 256;
/// Messages in flight: the parser runs at most this far ahead.
const IN_FLIGHT: usize = 64;

/// The parser's end of the channel, sending in chunks.
pub(super) struct Events {
    tx: SyncSender<Vec<Event>>,
    chunk: Vec<Event>,
}

/// The placer has stopped (it met an error of its own, which is the one
/// the import reports): the parser stops too.
pub(super) struct Stopped;

impl Events {
    /// Queue `e`; `Err` when the placer no longer listens.
    pub fn send(&mut self, e: Event) -> Result<(), Stopped> {
        let last = matches!(e, Event::End | Event::Error(_));
        self.chunk.push(e);
        if last || self.chunk.len() >= CHUNK {
            let full = std::mem::replace(&mut self.chunk, Vec::with_capacity(CHUNK));
            self.tx.send(full).map_err(|_| Stopped)?;
        }
        Ok(())
    }
}

/// A channel between the parser and [`place`].
pub(super) fn channel() -> (Events, Receiver<Vec<Event>>) {
    let (tx, rx) = std::sync::mpsc::sync_channel(IN_FLIGHT);
    (
        Events {
            tx,
            chunk: Vec::with_capacity(CHUNK),
        },
        rx,
    )
}

/// Place every event from `rx` in order, as the one-thread import did:
/// the result, or the first error in file order.
pub(super) fn place(rx: Receiver<Vec<Event>>, opts: &ImportOptions) -> Result<Sink, DxfError> {
    let mut st = State {
        blocks: HashMap::new(),
        pending: Vec::new(),
        sink: Sink::default(),
        tops: None,
        batches: Batches::default(),
    };
    match st.run(&rx, opts) {
        Ok(()) => Ok(st.sink),
        Err(e) => {
            // Entities read before the error come first: one of them may
            // have an error of its own to report.
            finish(&mut st.batches, &st.blocks, &st.tops, &mut st.sink, opts)?;
            Err(e)
        }
    }
}

struct State {
    blocks: HashMap<String, BlockDef>,
    /// INSERTs of blocks not defined yet (BLOCKS after ENTITIES, which is
    /// not standard): placed at the end.
    pending: Vec<Entity>,
    sink: Sink,
    tops: Option<Vec<Affine>>,
    batches: Batches,
}

impl State {
    fn run(&mut self, rx: &Receiver<Vec<Event>>, opts: &ImportOptions) -> Result<(), DxfError> {
        // A closed channel without End or Error: the parser stopped for a
        // reason of its own (it only does after this side has stopped).
        while let Ok(chunk) = rx.recv() {
            for e in chunk {
                match e {
                    Event::SectionBoundary => {
                        finish(&mut self.batches, &self.blocks, &self.tops, &mut self.sink, opts)?
                    }
                    Event::Block(name, block) => {
                        self.blocks.insert(name, block);
                    }
                    Event::Tops(t) => self.tops = Some(t),
                    Event::Entity(e) => self.entity(e, opts)?,
                    Event::End => return self.end(opts),
                    Event::Error(e) => return Err(e),
                }
            }
        }
        Ok(())
    }

    fn entity(&mut self, mut e: Entity, opts: &ImportOptions) -> Result<(), DxfError> {
        let top = self.tops.as_deref().unwrap_or(&[]);
        if let EntityShape::Insert(ins) = &mut e.shape {
            ins.block = ins.block.to_uppercase();
            if !self.blocks.contains_key(&ins.block) {
                self.pending.push(e);
                return Ok(());
            }
        }
        let Some(e) = self.batches.offer(e, top.len()) else {
            if self.batches.full() {
                self.batches.advance(&mut batch::Expansion {
                    x: &expander(&self.blocks, opts),
                    tops: top,
                    sink: &mut self.sink,
                    after: |sink: &mut Sink, pos| stopped(sink, pos, opts.max_segments),
                })?;
            }
            return Ok(());
        };
        let x = expander(&self.blocks, opts);
        for t in top {
            x.entity(&e, t, None, 0, &mut self.sink);
        }
        stopped(&mut self.sink, e.pos, opts.max_segments)
    }

    /// The EOF was read: the batches, then the INSERTs that waited for
    /// their blocks.
    fn end(&mut self, opts: &ImportOptions) -> Result<(), DxfError> {
        finish(&mut self.batches, &self.blocks, &self.tops, &mut self.sink, opts)?;
        let top = self.tops.as_deref().unwrap_or(&[]);
        let x = expander(&self.blocks, opts);
        for e in &self.pending {
            for t in top {
                x.entity(e, t, None, 0, &mut self.sink);
            }
            stopped(&mut self.sink, e.pos, opts.max_segments)?;
        }
        Ok(())
    }
}
