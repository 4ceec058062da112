//! Progress reporting for long library calls: the library calls a [`Progress`]; a binary decides
//! how to show it (a terminal bar, nothing).

/// Receives progress from a long-running library call.
pub trait Progress {
    /// Sets the amount of work (for conversions: input bytes) the call will do.
    fn set_total(&self, n: u64);
    /// Records `n` more units of work done.
    fn advance(&self, n: u64);
    /// Marks the work as complete.
    fn finish(&self);
}

/// Discards all progress reports.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;

impl Progress for NoProgress {
    fn set_total(&self, _n: u64) {}
    fn advance(&self, _n: u64) {}
    fn finish(&self) {}
}
