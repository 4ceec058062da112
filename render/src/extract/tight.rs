//! Tight per-leaf value ranges, computed from cell values the first time a leaf is visited and
//! kept for later isovalues.
//!
//! The file's stored leaf ranges are unions of whole-brick ranges (the writer never re-reads
//! data), so a leaf far from the surface is often visited because some other part of a
//! neighbouring brick straddles the isovalue. The tight range is a range of the cells
//! within reach of the leaf (read through [`super::blocks`]: on files that store block tables,
//! the union of the stored blocks the region overlaps, so that no brick data is read; else
//! exact), widened for round-off:
//! - when no leaf coarser than the leaf's level `L` touches the leaf grown by one level-`L` cell
//!   (its neighbourhood), that grown box: every corner of every voxel the leaf owns is then the
//!   value of, or a mean of, leaf cells of level `L` or finer inside it (the argument of
//!   [`super::cull`], with no coarser cell in any 27-cell neighbourhood);
//! - otherwise the stored range's reach rule (`amr-format/src/kdtree/ranges.rs`: the leaf grown by
//!   two cells of the coarsest level met, until that level stops changing) with one more
//!   level-`L` cell of margin; nodes of the [`super::leaf_tree`] lying within that reach again
//!   count whole, so the cost is the nodes along the region's boundary.
//!
//! A leaf whose tight range does not hold the isovalue has no active voxel and is skipped before
//! its neighbourhood is built. Files of layout version 3 store these ranges
//! ([`super::tight_tables_of`] computes them for the writer); the extractor then starts with all
//! of them known and never visits a leaf whose range excludes the isovalue. The argument holds point by point, so [`box_range`] bounds a part
//! of a leaf the same way ([`super::parts`]).

use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::Result;
use amr_format::kdtree::widen_range;
use amr_format::raw::LeafRange;
use amr_format::IBox;

use super::blocks::BlockRanges;
use super::leaf_tree::LeafTree;
use crate::reconstruct::Sampler;

/// Not computed yet (the bits of two NaNs, which no computed range holds).
const UNKNOWN: u64 = u64::MAX;

/// Per-leaf tight ranges of one field, filled on demand from any thread.
pub struct TightRanges<'f> {
    /// The ranges the file stores, all known, read in place (a copy would be a fresh page per
    /// 512 leaves).
    stored: Option<&'f [LeafRange]>,
    /// Without stored ranges: per leaf, its range once computed.
    bits: Vec<AtomicU64>,
}

impl TightRanges<'_> {
    /// Unknown ranges for `leaves` leaves.
    pub fn new(leaves: usize) -> Self {
        Self {
            stored: None,
            bits: (0..leaves).map(|_| AtomicU64::new(UNKNOWN)).collect(),
        }
    }
}

impl<'f> TightRanges<'f> {
    /// The tight ranges `file` stores for field `field` (layout version 3), known from the
    /// start; unknown ranges when it stores none.
    pub fn of_file<D: AsRef<[u8]>>(file: &'f amr_format::AmrkFile<D>, field: usize) -> Self {
        match file.tight_range_table(field) {
            Some(stored) => Self {
                stored: Some(stored),
                bits: Vec::new(),
            },
            None => Self::new(file.num_leaves()),
        }
    }

    /// The tight range of `leaf` if the file stores it. (One computed in this session is left
    /// out: whether another thread has computed it yet depends on timing.)
    #[inline]
    pub fn stored(&self, leaf: u32) -> Option<(f32, f32)> {
        let r = self.stored?.get(leaf as usize)?;
        Some((r.min.get(), r.max.get()))
    }

    /// The tight range of `leaf`, computed on first need from the block ranges and the leaf
    /// tree.
    pub fn get<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        bounds: (&BlockRanges, &LeafTree),
        leaf: u32,
    ) -> Result<(f32, f32)> {
        self.get_with(leaf, || compute(sampler, bounds, leaf))
    }

    /// The tight range of `leaf`, computed on first need by `compute` (which must give what
    /// [`Self::get`] would, or a range inside it).
    pub fn get_with(
        &self,
        leaf: u32,
        compute: impl FnOnce() -> Result<(f32, f32)>,
    ) -> Result<(f32, f32)> {
        if let Some(stored) = self.stored {
            let r = &stored[leaf as usize];
            return Ok((r.min.get(), r.max.get()));
        }
        let slot = &self.bits[leaf as usize];
        let known = slot.load(Ordering::Relaxed);
        if known != UNKNOWN {
            return Ok(unpack(known));
        }
        let range = compute()?;
        slot.store(pack(range), Ordering::Relaxed);
        Ok(range)
    }
}

/// A range as the bits of its two ends.
pub(super) fn pack((lo, hi): (f32, f32)) -> u64 {
    u64::from(lo.to_bits()) << 32 | u64::from(hi.to_bits())
}

/// The range [`pack`] stored.
pub(super) fn unpack(bits: u64) -> (f32, f32) {
    (
        f32::from_bits((bits >> 32) as u32),
        f32::from_bits(bits as u32),
    )
}

/// A range holding the leaf cells within reach of `leaf`, widened for
/// round-off.
pub fn compute<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    bounds: (&BlockRanges, &LeafTree),
    leaf: u32,
) -> Result<(f32, f32)> {
    let Some((_, level)) = sampler.leaf_top(leaf) else {
        return Ok((f32::INFINITY, f32::NEG_INFINITY));
    };
    let own = sampler.file().tree().leaf_box(leaf);
    box_range(sampler, bounds, &own, level)
}

/// The region queries a bound needs: the coarsest level touching a region and a range of the
/// leaf cells inside one.
pub trait Regions {
    /// The coarsest level of the leaves with data whose closed boxes touch the closed `region`.
    fn coarsest_touching(&self, region: &IBox) -> Option<u32>;
    /// A range holding the leaf cells inside `region`; whatever lies inside `region` grown by
    /// `slack` may be counted too.
    fn range_over(&self, region: &IBox, slack: [i64; 3]) -> Result<(f32, f32)>;
}

/// [`Regions`] answered by walking the [`LeafTree`], ranges read through the block ranges.
pub struct TreeRegions<'a, 'f, D> {
    /// The sampler of the file.
    pub sampler: &'a Sampler<'f, D>,
    /// The block ranges ranges are read through.
    pub blocks: &'a BlockRanges,
    /// The leaf tree.
    pub leaves: &'a LeafTree,
}

impl<D: AsRef<[u8]>> Regions for TreeRegions<'_, '_, D> {
    fn coarsest_touching(&self, region: &IBox) -> Option<u32> {
        self.leaves.coarsest_touching(self.sampler, region)
    }

    fn range_over(&self, region: &IBox, slack: [i64; 3]) -> Result<(f32, f32)> {
        self.leaves
            .range_over(self.sampler, self.blocks, region, slack)
    }
}

/// The region whose leaf cells bound the voxels owned by finest-level box `own` (of level
/// `level`), and the slack by which it may be grown: the module's reach rule.
fn reach<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    coarsest_touching: impl Fn(&IBox) -> Option<u32>,
    own: &IBox,
    level: u32,
) -> (IBox, [i64; 3]) {
    let grid = sampler.grid();
    let margin = grid.scale(level);
    let hood = own.grow(margin);
    let mut coarsest = coarsest_touching(&hood).unwrap_or(level);
    if coarsest >= level {
        return (hood, [0; 3]);
    }
    loop {
        let reach = [0, 1, 2].map(|a| 2 * grid.scale(coarsest)[a] + margin[a]);
        let region = own.grow(reach);
        let met = coarsest_touching(&region).unwrap_or(coarsest);
        if met >= coarsest {
            // Nodes lying within the reach again count whole.
            return (region, reach);
        }
        coarsest = met;
    }
}

/// The largest region a bound of finest-level box `own` (of level `level`) or of any box inside
/// it reads ([`box_range`]): a smaller box meets no coarser level, so its reach is no larger.
pub fn reach_region<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    leaves: &LeafTree,
    own: &IBox,
    level: u32,
) -> IBox {
    reach(
        sampler,
        |r| leaves.coarsest_touching(sampler, r),
        own,
        level,
    )
    .0
}

/// A range holding every corner of every voxel whose lower corner lies in the finest-level box
/// `own` (the box of a leaf of level `level`, or a part of it), widened for round-off: the
/// module's argument, which holds point by point.
pub fn box_range<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    (blocks, leaves): (&BlockRanges, &LeafTree),
    own: &IBox,
    level: u32,
) -> Result<(f32, f32)> {
    let tree = TreeRegions {
        sampler,
        blocks,
        leaves,
    };
    box_range_in(sampler, &tree, own, level)
}

/// [`box_range`] with its region queries answered by `regions`.
pub fn box_range_in<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    regions: &(impl Regions + ?Sized),
    own: &IBox,
    level: u32,
) -> Result<(f32, f32)> {
    let (region, slack) = reach(sampler, |r| regions.coarsest_touching(r), own, level);
    let (lo, hi) = regions.range_over(&region, slack)?;
    if lo > hi {
        return Ok((f32::INFINITY, f32::NEG_INFINITY));
    }
    Ok(widen_range(lo, hi))
}

/// [`box_range`] of a box `own` whose grown box no leaf coarser than `level` touches (as
/// when it lies in a leaf of level `level` for which that holds), without asking for levels.
pub fn box_range_flat(
    grid_scale: [i64; 3],
    regions: &(impl Regions + ?Sized),
    own: &IBox,
) -> Result<(f32, f32)> {
    let hood = own.grow(grid_scale);
    let (lo, hi) = regions.range_over(&hood, [0; 3])?;
    if lo > hi {
        return Ok((f32::INFINITY, f32::NEG_INFINITY));
    }
    Ok(widen_range(lo, hi))
}
