//! Open time: map a file and validate its metadata, repeated; no brick data is read.

use std::path::Path;
use std::time::{Duration, Instant};

use amr_render::mapping::open_mapped;

/// Median time to open (map and validate) `path`, over `runs` opens, and the file's size and
/// brick count.
pub fn open_time(path: &Path, runs: usize) -> amr_format::Result<(Duration, u64, usize)> {
    let mut samples = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let f = open_mapped(path)?;
        samples.push(t.elapsed());
        last = Some((f.bytes().len() as u64, f.num_bricks()));
    }
    let (bytes, bricks) = last.unwrap_or_default();
    Ok((crate::median(&mut samples), bytes, bricks))
}
