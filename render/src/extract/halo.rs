//! The leaves around one leaf, gathered once from the [`LeafTree`], so that the bounds of the
//! leaf's parts ([`super::parts`]) ask a short list instead of walking the tree once or more per
//! part.
//!
//! The list holds every leaf whose closed box touches the leaf's reach ([`reach_region`]), the
//! largest region a bound of the leaf or of a part of it reads, so every query inside that region
//! gets the answer the tree would give (the coarsest level met), or a range at least as tight
//! (leaves are bounded one by one, never as a whole tree node).

use amr_format::IBox;

use super::blocks::BlockRanges;
use super::leaf_tree::LeafTree;
use super::tight::{reach_region, Regions};
use crate::error::Result;
use crate::reconstruct::Sampler;

/// One leaf around: its box, finest brick and level (`None` without data) and id.
#[derive(Clone, Copy, Debug)]
struct Around {
    leaf: u32,
    bounds: IBox,
    top: Option<(u32, u32)>,
}

/// The leaves touching a region, answering [`Regions`] queries inside it.
pub struct Halo<'a, 'f, D> {
    sampler: &'a Sampler<'f, D>,
    blocks: &'a BlockRanges,
    tree: &'a LeafTree,
    region: IBox,
    /// In order of level, coarsest first; the leaves without data last.
    leaves: Vec<Around>,
}

/// Leaves around, at most: past that (small leaves within a coarse level's reach), the tree's
/// queries, which count whole nodes inside the reach at once, cost less than the list's.
pub const MAX_AROUND: usize = 64;

impl<'a, 'f, D: AsRef<[u8]>> Halo<'a, 'f, D> {
    /// The leaves around finest-level box `own` (a leaf of level `level`) within the reach of
    /// any bound of a box inside it, ranges read through `blocks`; `None` when there are more
    /// than [`MAX_AROUND`].
    pub fn new(
        sampler: &'a Sampler<'f, D>,
        (blocks, tree): (&'a BlockRanges, &'a LeafTree),
        own: &IBox,
        level: u32,
    ) -> Option<Self> {
        let region = reach_region(sampler, tree, own, level);
        let mut leaves = Vec::new();
        tree.for_each_leaf_touching(&region, |l| {
            leaves.push(Around {
                leaf: l,
                bounds: tree.leaf_box(l),
                top: sampler.leaf_top(l),
            })
        });
        if leaves.len() > MAX_AROUND {
            return None;
        }
        // Coarsest first, and of the leaf's own level the leaf itself first (it touches every
        // region asked about), so that [`Regions::coarsest_touching`] stops at the first leaf
        // touching: no leaf after it is coarser.
        leaves.sort_by_key(|a| match a.top {
            Some((_, lv)) => (lv, !a.bounds.contains_box(own)),
            None => (u32::MAX, true),
        });
        Some(Self {
            sampler,
            blocks,
            tree,
            region,
            leaves,
        })
    }
}

impl<D: AsRef<[u8]>> Regions for Halo<'_, '_, D> {
    fn coarsest_touching(&self, region: &IBox) -> Option<u32> {
        debug_assert!(self.region.contains_box(region));
        self.leaves
            .iter()
            .filter(|a| a.bounds.touches(region))
            .find_map(|a| a.top.map(|(_, lv)| lv))
    }

    fn range_over(&self, region: &IBox, _slack: [i64; 3]) -> Result<(f32, f32)> {
        debug_assert!(self.region.contains_box(region));
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for a in &self.leaves {
            let Some((brick, lv)) = a.top else {
                continue;
            };
            let part = a.bounds.intersect(region);
            if part.is_empty() {
                continue;
            }
            let (x, y) = if region.contains_box(&a.bounds) {
                self.tree.leaf_range(self.sampler, self.blocks, a.leaf)?
            } else {
                self.blocks.range_in(self.sampler, brick, lv, &part)?
            };
            lo = lo.min(x);
            hi = hi.max(y);
        }
        Ok((lo, hi))
    }
}
