//! Value bounds around coarse leaf cells, shared by every leaf and isovalue of one field: for a
//! leaf cell `Q` of level `q`, the range of the leaf cells within one `Q`-cell of `Q`, or the fact
//! that a leaf cell coarser than `q` lies there ([`super::cull`]).
//!
//! Each bound is answered once per file from the [`LeafTree`] (whose nodes inside the region
//! count whole) and kept: a coarse cell next to many small leaves costs one region query, not one
//! per leaf, and no leaf gathers the leaves around it.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::Mutex;

use crate::error::Result;
use amr_format::IBox;

use super::blocks::BlockRanges;
use super::leaf_tree::LeafTree;
use super::tight::{pack, unpack};
use crate::reconstruct::Sampler;

/// Folds the values of the cells `cells` (level-`fine` indices, inside the brick's cells `bc`)
/// of brick data `values` into the bounds `lo`/`hi` of the cells of grid `g` of a level whose
/// cells are `ratio` fine cells wide; cells outside `g` are ignored.
pub fn fold_cell_bounds(
    values: &[f32],
    bc: &IBox,
    cells: &IBox,
    ratio: [i64; 3],
    g: &IBox,
    (lo, hi): (&mut [f32], &mut [f32]),
) {
    let e = g.extent();
    for z in cells.lo[2]..cells.hi[2] {
        let gz = z.div_euclid(ratio[2]) - g.lo[2];
        if !(0..e[2]).contains(&gz) {
            continue;
        }
        for y in cells.lo[1]..cells.hi[1] {
            let gy = y.div_euclid(ratio[1]) - g.lo[1];
            if !(0..e[1]).contains(&gy) {
                continue;
            }
            let src = bc.linear_index([cells.lo[0], y, z]);
            let row = ((gz * e[1] + gy) * e[0]) as usize;
            let mut x = cells.lo[0];
            while x < cells.hi[0] {
                let gx = x.div_euclid(ratio[0]);
                let end = ((gx + 1) * ratio[0]).min(cells.hi[0]);
                let gx = gx - g.lo[0];
                if (0..e[0]).contains(&gx) {
                    let run = &values
                        [src + (x - cells.lo[0]) as usize..src + (end - cells.lo[0]) as usize];
                    let i = row + gx as usize;
                    for &v in run {
                        lo[i] = lo[i].min(v);
                        hi[i] = hi[i].max(v);
                    }
                }
                x = end;
            }
        }
    }
}

/// Marks a coarse cell next to a leaf cell coarser than itself (the bits of two NaNs, which no
/// packed range holds).
const NEXT_TO_COARSER: u64 = u64::MAX - 1;
/// Independently locked parts of the table, so threads rarely wait on each other.
const SHARDS: usize = 64;

/// The bound around each coarse leaf cell asked for so far, of one field.
pub struct CoarseBounds {
    shards: Vec<Mutex<HashMap<(u32, [i64; 3]), u64, BuildHasherDefault<CellHasher>>>>,
}

impl Default for CoarseBounds {
    fn default() -> Self {
        Self {
            shards: (0..SHARDS).map(|_| Mutex::default()).collect(),
        }
    }
}

impl CoarseBounds {
    /// A range holding the leaf cells within one cell of level-`level` cell `c` (absolute
    /// index); `None` when a leaf cell coarser than `level` lies there. Computed on first need.
    pub fn range_around<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        (blocks, leaves): (&BlockRanges, &LeafTree),
        level: u32,
        c: [i64; 3],
    ) -> Result<Option<(f32, f32)>> {
        let key = (level, c);
        let shard = &self.shards[shard_of(&key)];
        let known = shard.lock().map(|m| m.get(&key).copied()).unwrap_or(None);
        let bits = match known {
            Some(bits) => bits,
            None => {
                let grid = sampler.grid();
                let region = grid.finest_box(level, c).grow(grid.scale(level));
                let bits = if leaves.any_coarser_overlapping(sampler, &region, level) {
                    NEXT_TO_COARSER
                } else {
                    pack(leaves.range_over(sampler, blocks, &region, [0; 3])?)
                };
                if let Ok(mut m) = shard.lock() {
                    m.insert(key, bits);
                }
                bits
            }
        };
        Ok((bits != NEXT_TO_COARSER).then(|| unpack(bits)))
    }
}

/// The shard of key `k`.
fn shard_of(k: &(u32, [i64; 3])) -> usize {
    let mut h = CellHasher::default();
    h.write_u32(k.0);
    for v in k.1 {
        h.write_i64(v);
    }
    (h.finish() >> 40) as usize % SHARDS
}

/// A multiplicative hash of cell keys (a few integers; no untrusted input reaches it).
#[derive(Default)]
pub struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        // The product's high bits hold all of the key: fold them into the low bits too.
        self.0 ^ self.0 >> 29
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u32(&mut self, v: u32) {
        self.write_u64(u64::from(v));
    }

    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}
