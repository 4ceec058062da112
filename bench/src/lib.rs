//! Measurements of the `amr-iso` renderer whose numbers go into `docs/benchmarks*.md`: open and
//! read times, the BVH in chunks against one BVH, the cost of a point sample, and the suite that regenerates
//! `docs/benchmarks-suite.md` with its plots. The `amr-bench` binary is the front end.
//!
//! Each measurement repeats its work and reports the median, so that numbers quoted side by
//! side come from one run on one machine.

pub mod bvh;
pub mod open;
pub mod probe;
pub mod read;
pub mod sample;
pub mod suite;

use std::time::Duration;

/// The median of `samples` (which it sorts).
pub fn median(samples: &mut [Duration]) -> Duration {
    samples.sort_unstable();
    samples.get(samples.len() / 2).copied().unwrap_or_default()
}
