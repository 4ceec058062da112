//! Brick read speed: decode every brick of a field from the map, raw or compressed.

use std::path::Path;
use std::time::{Duration, Instant};

use amr_render::mapping::open_mapped;

/// What reading every brick of one field cost.
#[derive(Clone, Debug)]
pub struct ReadReport {
    /// Wall time of the pass.
    pub time: Duration,
    /// Cells decoded.
    pub cells: u64,
    /// Stored bytes read.
    pub stored_bytes: u64,
    /// A sum of all values, so the work cannot be optimized away.
    pub checksum: f64,
}

/// Reads and decodes every brick of field `field` of `path` once, in file order.
pub fn read_all(path: &Path, field: usize) -> amr_format::Result<ReadReport> {
    let f = open_mapped(path)?;
    let t = Instant::now();
    let mut buf = Vec::new();
    let (mut cells, mut stored, mut sum) = (0u64, 0u64, 0f64);
    for b in 0..f.num_bricks() {
        f.brick_values_into(field, b, &mut buf)?;
        cells += buf.len() as u64;
        stored += f.brick_data(field, b).len;
        sum += buf.iter().map(|&v| v as f64).sum::<f64>();
    }
    Ok(ReadReport {
        time: t.elapsed(),
        cells,
        stored_bytes: stored,
        checksum: sum,
    })
}
