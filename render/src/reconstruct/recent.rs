//! Point sampling's per-thread scratch: the kd-tree leaves located last, and the vertex values
//! and octant corners computed last, so that samples near each other skip the kd-tree walks and
//! the vertex evaluations they share.
//!
//! A leaf cell is located from a remembered leaf's box and finest brick when the finest cell
//! lies in that box; otherwise by the sampler's kd-tree walk, whose leaf is then remembered.
//! Leaves tile the domain and a leaf's finest brick holds every cell of it, so both ways give
//! [`Sampler::locate`]'s answer: the scratch changes how fast a sample is, never its value.

use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use amr_format::IBox;

use crate::error::Result;

use super::grid::axes;
use super::local::pow2_shift;
use super::sampler::{LeafCell, Locate, Sampler, Slab, VertexMemo};

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

/// log2 of the octants a scratch remembers: 16384 (768 KiB per thread); the default 1024
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

impl<D: AsRef<[u8]>> Locate for RecentLocator<'_, '_, '_, D> {
    #[inline]
    fn locate_cell(&self, finest: [i64; 3]) -> Result<Option<LeafCell>> {
        let offset = self.sampler.grid().offset();
        {
            let leaves = self.leaves.leaves.borrow();
            let last = self.leaves.last.get();
            let hit = match leaves.get(last) {
                Some(l) if l.finest.contains_cell(finest) => Some(last),
                _ => leaves.iter().position(|l| l.finest.contains_cell(finest)),
            };
            if let Some(i) = hit {
                let l = &leaves[i];
                let abs = axes(|a| finest[a] + offset[a]);
                let cell = match l.shift {
                    Some(sh) => axes(|a| abs[a] >> sh[a]),
                    None => self.sampler.grid().cell_of(l.level, finest),
                };
                let values: &[f32] = match &l.decoded {
                    Some(v) => v,
                    None => self.sampler.values_in_place(l.brick).unwrap_or(&[]),
                };
                let value = l
                    .cells
                    .contains_cell(cell)
                    .then(|| values.get(l.cells.linear_index(cell)))
                    .flatten();
                if let Some(&value) = value {
                    let found = LeafCell {
                        leaf: l.leaf,
                        brick: l.brick,
                        level: l.level,
                        cell,
                        value,
                    };
                    self.leaves.last.set(i);
                    return Ok(Some(found));
                }
            }
        }
        let found = self.sampler.locate(finest)?;
        if let Some(c) = &found {
            let recent = RecentLeaf {
                finest: self.sampler.leaf_box(c.leaf),
                leaf: c.leaf,
                brick: c.brick,
                level: c.level,
                cells: self.sampler.brick_cells(c.brick),
                shift: pow2_shift(self.sampler.grid().scale(c.level)),
                decoded: match self.sampler.values(c.brick)? {
                    Slab::Shared(v) => Some(v),
                    Slab::Borrowed(_) => None,
                },
            };
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
        }
        Ok(found)
    }

    #[inline]
    fn block_of_level(&self, lo: [i64; 3], hi: [i64; 3], level: u32) -> Option<[f32; 8]> {
        let leaves = self.leaves.leaves.borrow();
        let l = leaves.get(self.leaves.last.get())?;
        if l.level != level || !l.finest.contains_cell(lo) || !l.finest.contains_cell(hi) {
            return None;
        }
        let offset = self.sampler.grid().offset();
        let cell_of = |f: [i64; 3]| match l.shift {
            Some(sh) => axes(|a| (f[a] + offset[a]) >> sh[a]),
            None => self.sampler.grid().cell_of(level, f),
        };
        let (clo, chi) = (cell_of(lo), cell_of(hi));
        if !l.cells.contains_cell(clo) || !l.cells.contains_cell(chi) {
            return None;
        }
        let values: &[f32] = match &l.decoded {
            Some(v) => v,
            None => self.sampler.values_in_place(l.brick)?,
        };
        // The eight cells are `clo` plus, per axis, 0 or `chi - clo` (0 or 1) cells: one index
        // and three strides.
        let e = l.cells.extent();
        let stride = [1, e[0], e[0] * e[1]];
        let step: [usize; 3] = axes(|a| ((chi[a] - clo[a]) * stride[a]) as usize);
        let first = l.cells.linear_index(clo);
        let last = first + step[0] + step[1] + step[2];
        let block = values.get(first..=last)?;
        let mut out = [0f32; 8];
        for (n, slot) in out.iter_mut().enumerate() {
            let at = (n & 1) * step[0] + (n >> 1 & 1) * step[1] + (n >> 2 & 1) * step[2];
            *slot = block[at];
        }
        Some(out)
    }
}
