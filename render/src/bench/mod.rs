//! `amr-render bench`: measurements whose numbers go into `docs/benchmarks.md`.
//!
//! Each measurement repeats its work and reports the median, so that numbers quoted side by
//! side come from one run on one machine.

pub mod bvh;
pub mod open;
pub mod read;
pub mod suite;

use std::time::Duration;

/// The median of `samples` (which it sorts).
pub fn median(samples: &mut [Duration]) -> Duration {
    samples.sort_unstable();
    samples.get(samples.len() / 2).copied().unwrap_or_default()
}
