//! Point sampling's per-thread scratch: the kd-tree leaves located last, and the vertex values
//! and octant corners computed last, so that samples near each other skip the kd-tree walks and
//! the vertex evaluations they share.
//!
//! A leaf cell is located from the leaf that answered last when the finest cell lies in its box;
//! otherwise the sampler names the leaf ([`Sampler::find_leaf`]). A leaf whose brick is read in
//! place is then read directly and becomes the last one; one whose brick is decoded is read
//! from the remembered leaves (which keep their decoded bricks at hand) or remembered.
//! Leaves tile the domain and a leaf's finest brick holds every cell of it, so both ways give
//! [`Sampler::locate`]'s answer: the scratch changes how fast a sample is, never its value.

use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use amr_format::IBox;

use crate::error::Result;

use super::grid::{axes, index_in};
use super::sampler::{block_in_brick, LeafCell, Locate, Sampler, Slab, VertexMemo};

/// Leaves remembered: a sample's neighbourhood touches at most eight leaves.
const RECENT_LEAVES: usize = 8;

/// One remembered kd-tree leaf and its finest brick.
struct RecentLeaf {
    /// The leaf's box in finest-level cells (relative to the domain).
    finest: IBox,
    leaf: u32,
    brick: u32,
    level: u32,
    /// The brick's cells (absolute indices of `level`).
    cells: IBox,
    /// log2 of the level's cell width in finest cells, when every axis is a power of two.
    shift: Option<[u32; 3]>,
    /// The brick's values when decoded into the sampler's cache; `None` when read in place.
    decoded: Option<Arc<[f32]>>,
}

/// The kd-tree leaves located last, replaced in turn, and the one that answered last.
#[derive(Default)]
struct RecentLeaves {
    leaves: RefCell<Vec<RecentLeaf>>,
    last: Cell<usize>,
    next: Cell<usize>,
    /// The last leaf whose brick is read in place, and its box.
    last_in_place: Cell<Option<(u32, IBox)>>,
}

/// A sampler's per-thread scratch for [`Sampler::sample_with`] and for decoding voxels: pure
/// caches, so a scratch never changes a result. It serves one sampler at a time and forgets
/// everything when handed to another.
pub struct SampleScratch {
    /// The sampler served, by [`Sampler::id`] (0: none yet).
    owner: u64,
    leaves: RecentLeaves,
    /// Vertex values and octant corners computed so far.
    pub memo: VertexMemo,
}

impl Default for SampleScratch {
    fn default() -> Self {
        Self {
            owner: 0,
            leaves: RecentLeaves::default(),
            memo: VertexMemo::with_octant_bits(SCRATCH_OCTANT_BITS),
        }
    }
}

/// log2 of the octants a scratch remembers: 16384 (1.1 MiB per thread); the default 1024
/// thrashes on the octants that smooth normals of neighbouring rows share.
const SCRATCH_OCTANT_BITS: u32 = 14;

/// Locates through a scratch's remembered leaves, then through the sampler's kd-tree.
pub struct RecentLocator<'a, 's, 'f, D> {
    sampler: &'s Sampler<'f, D>,
    leaves: &'a RecentLeaves,
}

/// Source of [`Sampler::id`]s.
static NEXT_SAMPLER_ID: AtomicU64 = AtomicU64::new(1);

/// A new sampler identity, never 0.
pub(super) fn next_sampler_id() -> u64 {
    NEXT_SAMPLER_ID.fetch_add(1, Ordering::Relaxed)
}

impl SampleScratch {
    /// The locator and the memo for sampling `sampler`, forgetting what was remembered for
    /// another sampler.
    #[inline]
    pub fn bind<'a, 's, 'f, D: AsRef<[u8]>>(
        &'a mut self,
        sampler: &'s Sampler<'f, D>,
    ) -> (RecentLocator<'a, 's, 'f, D>, &'a mut VertexMemo) {
        if self.owner != sampler.id() {
            self.owner = sampler.id();
            self.leaves = RecentLeaves::default();
            self.memo.clear();
        }
        (
            RecentLocator {
                sampler,
                leaves: &self.leaves,
            },
            &mut self.memo,
        )
    }
}

impl<D: AsRef<[u8]>> RecentLocator<'_, '_, '_, D> {
    /// The leaf cell at finest cell `finest`, which lies in remembered leaf `l`, read from the
    /// leaf's brick; `None` when the brick does not hold it (the sampler then answers).
    #[inline(always)]
    fn read(&self, l: &RecentLeaf, finest: [i64; 3]) -> Option<LeafCell> {
        let offset = self.sampler.grid().offset();
        let cell = match l.shift {
            Some(sh) => axes(|a| (finest[a] + offset[a]) >> sh[a]),
            None => self.sampler.grid().cell_of(l.level, finest),
        };
        let values: &[f32] = match &l.decoded {
            Some(v) => v,
            None => self.sampler.values_in_place(l.brick)?,
        };
        if !l.cells.contains_cell(cell) {
            return None;
        }
        let value = *values.get(index_in(&l.cells, cell))?;
        Some(LeafCell {
            leaf: l.leaf,
            brick: l.brick,
            level: l.level,
            cell,
            value,
        })
    }
}

impl<D: AsRef<[u8]>> Locate for RecentLocator<'_, '_, '_, D> {
    #[inline(always)]
    fn locate_cell(&self, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        if let Some((leaf, b)) = self.leaves.last_in_place.get() {
            if b.contains_cell(finest) {
                return self.sampler.leaf_cell(leaf, finest);
            }
        }
        {
            let leaves = self.leaves.leaves.borrow();
            let last = self.leaves.last.get();
            if let Some(l) = leaves.get(last).filter(|l| l.finest.contains_cell(finest)) {
                if let Some(found) = self.read(l, finest) {
                    return Ok(Some(found));
                }
            }
        }
        let Some(leaf) = self.sampler.find_leaf(finest) else {
            return Ok(None);
        };
        let Some((brick, level)) = self.sampler.leaf_top(leaf) else {
            return Ok(None);
        };
        if self.sampler.values_in_place(brick).is_some() {
            // Read in place: only the leaf and its box are remembered.
            let b = self.sampler.leaf_box(leaf);
            self.leaves.last_in_place.set(Some((leaf, b)));
            return self.sampler.leaf_cell(leaf, finest);
        }
        {
            let leaves = self.leaves.leaves.borrow();
            if let Some(i) = leaves.iter().position(|l| l.leaf == leaf) {
                if let Some(found) = self.read(&leaves[i], finest) {
                    self.leaves.last.set(i);
                    return Ok(Some(found));
                }
            }
        }
        let recent = RecentLeaf {
            finest: self.sampler.leaf_box(leaf),
            leaf,
            brick,
            level,
            cells: self.sampler.brick_cells(brick),
            shift: self.sampler.grid().shift(level),
            decoded: match self.sampler.values(brick)? {
                Slab::Shared(v) => Some(v),
                Slab::Borrowed(_) => None,
            },
        };
        let found = self.read(&recent, finest);
        let mut leaves = self.leaves.leaves.borrow_mut();
        let slot = if leaves.len() < RECENT_LEAVES {
            leaves.push(recent);
            leaves.len() - 1
        } else {
            let slot = self.leaves.next.get();
            self.leaves.next.set((slot + 1) % RECENT_LEAVES);
            leaves[slot] = recent;
            slot
        };
        self.leaves.last.set(slot);
        match found {
            Some(found) => Ok(Some(found)),
            None => self.sampler.locate(finest),
        }
    }

    #[inline]
    fn block_of_level(&self, lo: [i64; 3], hi: [i64; 3], level: u32) -> Option<[f32; 8]> {
        let leaves = self.leaves.leaves.borrow();
        let last = leaves.get(self.leaves.last.get()).filter(|l| {
            l.level == level && l.finest.contains_cell(lo) && l.finest.contains_cell(hi)
        });
        let Some(l) = last else {
            return self.sampler.block_of_level(lo, hi, level);
        };
        let offset = self.sampler.grid().offset();
        let cell_of = |f: [i64; 3]| match l.shift {
            Some(sh) => axes(|a| (f[a] + offset[a]) >> sh[a]),
            None => self.sampler.grid().cell_of(level, f),
        };
        let values: &[f32] = match &l.decoded {
            Some(v) => v,
            None => self.sampler.values_in_place(l.brick)?,
        };
        block_in_brick(&l.cells, values, cell_of(lo), cell_of(hi))
    }
}
