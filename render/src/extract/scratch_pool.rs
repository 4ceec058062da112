//! One extraction scratch per worker thread, kept across the runs of leaves that thread takes.
//!
//! The thread pool hands a chunk's leaves out in runs whose number grows with stealing (on
//! `tiny` at two threads, about 60 runs where one thread takes 6). A scratch made for each run
//! starts with empty buffers and memos: its first leaves fault in fresh pages (the
//! [`AroundMemo`](super::band::AroundMemo) alone is 40) and redo what the thread's previous run
//! had remembered. A run takes its thread's scratch from the pool and gives it back at its end.
//! What a scratch holds never changes a leaf's refs or counts (a run already reuses it from
//! leaf to leaf, and which leaves share a run depends on stealing), so neither does the pool.

use std::sync::Mutex;

use super::cell_tiles::CellTiles;
use super::cull::Shared;
use super::leaf::Scratch;

/// Scratches for the threads of the current thread pool, one slot each, plus one for a caller
/// outside it.
pub struct ScratchPool<'s> {
    slots: Vec<Mutex<Option<Box<Scratch<'s>>>>>,
    shared: Shared<'s>,
    tiles: Option<&'s CellTiles>,
}

impl<'s> ScratchPool<'s> {
    /// An empty pool of scratches reading the tables of `shared` and the cell tiles `tiles`.
    pub fn new(shared: Shared<'s>, tiles: Option<&'s CellTiles>) -> Self {
        Self {
            slots: (0..=rayon::current_num_threads())
                .map(|_| Mutex::new(None))
                .collect(),
            shared,
            tiles,
        }
    }

    /// The calling thread's slot.
    fn slot(&self) -> &Mutex<Option<Box<Scratch<'s>>>> {
        let last = self.slots.len() - 1;
        let i = rayon::current_thread_index().map_or(last, |i| i.min(last));
        &self.slots[i]
    }

    /// The scratch this thread gave back last, or a new one. Boxed: a fold moves its state from
    /// leaf to leaf.
    pub fn take(&self) -> Box<Scratch<'s>> {
        let kept = self.slot().lock().unwrap_or_else(|e| e.into_inner()).take();
        kept.unwrap_or_else(|| Box::new(Scratch::new(self.shared, self.tiles)))
    }

    /// Keeps `scratch` for this thread's next [`Self::take`].
    pub fn give(&self, scratch: Box<Scratch<'s>>) {
        *self.slot().lock().unwrap_or_else(|e| e.into_inner()) = Some(scratch);
    }
}
