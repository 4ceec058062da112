//! A bounded cache of decoded bricks shared by all threads, for files whose bricks are
//! compressed (or otherwise not readable in place).
//!
//! Each brick is decoded by exactly one thread while the cache holds it; other threads asking
//! for it meanwhile wait for that decode. When a shard exceeds its share of the byte budget,
//! its oldest entries are dropped (threads still holding one keep it alive).

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use amr_format::FormatError;

use crate::error::RenderError;
use crate::error::Result;

const SHARDS: usize = 64;

type Slot = Arc<OnceLock<std::result::Result<Arc<[f32]>, Arc<FormatError>>>>;

#[derive(Default)]
struct Shard {
    map: HashMap<u32, Slot>,
    order: VecDeque<(u32, usize)>,
    bytes: usize,
}

/// Decoded bricks keyed by brick index, bounded by a byte budget.
pub struct BrickCache {
    shards: Vec<Mutex<Shard>>,
    budget_per_shard: usize,
    decodes: AtomicU64,
}

impl BrickCache {
    /// A cache holding about `budget_bytes` of decoded values.
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            shards: (0..SHARDS).map(|_| Mutex::new(Shard::default())).collect(),
            budget_per_shard: budget_bytes / SHARDS,
            decodes: AtomicU64::new(0),
        }
    }

    /// Number of bricks decoded since the cache was made.
    pub fn decodes(&self) -> u64 {
        self.decodes.load(Ordering::Relaxed)
    }

    /// Brick `brick`'s values, decoding them with `decode` (which must yield `cells` values)
    /// when the cache does not hold them.
    pub fn get(
        &self,
        brick: u32,
        cells: usize,
        decode: impl FnOnce() -> Result<Vec<f32>>,
    ) -> Result<Arc<[f32]>> {
        let slot = {
            let mut shard = self.shards[brick as usize % SHARDS]
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            if let Some(slot) = shard.map.get(&brick) {
                slot.clone()
            } else {
                let slot: Slot = Arc::default();
                shard.map.insert(brick, slot.clone());
                shard.order.push_back((brick, cells * 4));
                shard.bytes += cells * 4;
                while shard.bytes > self.budget_per_shard && shard.order.len() > 1 {
                    if let Some((old, bytes)) = shard.order.pop_front() {
                        shard.map.remove(&old);
                        shard.bytes -= bytes;
                    }
                }
                slot
            }
        };
        let value = slot.get_or_init(|| {
            self.decodes.fetch_add(1, Ordering::Relaxed);
            decode().map(Arc::from).map_err(|e| {
                Arc::new(match e {
                    RenderError::Format(e) => e,
                    e => FormatError::Corrupt(e.to_string()),
                })
            })
        });
        value
            .clone()
            .map_err(|e| RenderError::Format(FormatError::Shared(e)))
    }
}
