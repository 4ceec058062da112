//! Refs vectors of runs already appended to the result, emptied and handed to later runs.

use std::sync::Mutex;

/// Emptied refs vectors kept for the runs of the next chunks: a run takes one
/// ([`Self::take`]) rather than growing a new vector from nothing (each doubling a fresh
/// allocation and its pages), and gives it back ([`Self::give`]) once its refs are appended to
/// the result. Only capacity is reused: a vector is empty when a run takes it.
#[derive(Default)]
pub struct SpareRefs(Mutex<Vec<Vec<u64>>>);

impl SpareRefs {
    /// An empty vector, with the capacity of the last one given back if any.
    pub fn take(&self) -> Vec<u64> {
        self.0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop()
            .unwrap_or_default()
    }

    /// Keeps `refs`' capacity for a later [`Self::take`].
    pub fn give(&self, mut refs: Vec<u64>) {
        refs.clear();
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(refs);
    }
}
