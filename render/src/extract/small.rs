//! Tight ranges of small leaves read off their own neighbourhood.
//!
//! The corners of every voxel a leaf owns lie in the union of the bounds of the cells of its
//! neighbourhood (the leaf grown by one cell of its level), once the bounds of the cells inside
//! coarser leaf cells are settled: the argument of [`super::cull`], which bounds each cell's
//! octants by the 27 cells around it. So that union, widened for round-off, is a tight range
//! for the leaf: exact leaf and finer cells, and the coarse bounds the cull reads. For a small
//! leaf it is read from the settled cells of [`super::cell_tiles`], which the leaf's extraction
//! then copies its neighbourhood from: each cell is classified once per file, not once per
//! neighbourhood holding it.

use amr_format::kdtree::widen_range;

use super::blocks::level_box;
use super::cull::settle_in;
use super::leaf::Scratch;
use super::leaf_tree::LeafTree;
use crate::error::Result;
use crate::reconstruct::Sampler;
use amr_format::IBox;

/// Cells per axis (at its own level) of a leaf whose tight range comes from its neighbourhood,
/// at most.
pub const MAX_CELLS: i64 = 8;
/// Cells of a neighbourhood filled for a run of leaves, at most.
const MAX_REGION: u64 = 16 * 16 * 16;
/// Leaves after the first of a run sharing one neighbourhood, at most.
const MAX_RUN: u32 = 32;

/// The tight range of `leaf` from its neighbourhood's settled cells, read from the tiles of
/// `scratch`, when the leaf spans at most [`MAX_CELLS`] cells per axis; `None` for a larger leaf
/// or one without data.
pub fn hood_range<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    scratch: &mut Scratch<'_>,
    leaf: u32,
) -> Result<Option<(f32, f32)>> {
    let Some((_, level)) = sampler.leaf_top(leaf) else {
        return Ok(None);
    };
    let Scratch {
        hood,
        memo,
        shared,
        near,
        tiles,
        ..
    } = scratch;
    let leaves = shared.leaves;
    let finest = leaves.leaf_box(leaf);
    let cells = level_box(sampler.grid(), level, &finest);
    if cells.extent().iter().any(|&e| e > MAX_CELLS) {
        return Ok(None);
    }
    let g = cells.grow([1; 3]);
    let Some(tiles) = tiles else {
        if !hood.holds(level, &g) {
            let region = run_region(sampler, leaves, leaf, level, g);
            hood.fill_region((sampler, leaves), level, region)?;
        }
        let settled = settle_in((sampler, *shared), hood, (memo, near), (&g, true));
        settled?;
        let (lo, hi) = hood.range_in(&g);
        if lo > hi {
            return Ok(Some((f32::INFINITY, f32::NEG_INFINITY)));
        }
        return Ok(Some(widen_range(lo, hi)));
    };
    let range = tiles.range_in((sampler, *shared), (memo, near), level, g);
    let (lo, hi) = range?;
    if lo > hi {
        return Ok(Some((f32::INFINITY, f32::NEG_INFINITY)));
    }
    Ok(Some(widen_range(lo, hi)))
}

/// The box of level-`level` cells holding `g`, the grown box of `leaf`, and those of the small
/// leaves of the same level right after it, while it has no more cells than their grown boxes
/// together and at most [`MAX_REGION`].
fn run_region<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    leaves: &LeafTree,
    leaf: u32,
    level: u32,
    g: IBox,
) -> IBox {
    let grid = sampler.grid();
    let n = sampler.file().num_leaves() as u32;
    let (mut region, mut sum) = (g, volume(&g));
    for next in leaf.saturating_add(1)..n.min(leaf.saturating_add(1 + MAX_RUN)) {
        if sampler.leaf_top(next).map(|(_, lv)| lv) != Some(level) {
            break;
        }
        let cells = level_box(grid, level, &leaves.leaf_box(next));
        if cells.extent().iter().any(|&e| e > MAX_CELLS) {
            break;
        }
        let grown = cells.grow([1; 3]);
        let union = IBox::new(
            [0, 1, 2].map(|a| region.lo[a].min(grown.lo[a])),
            [0, 1, 2].map(|a| region.hi[a].max(grown.hi[a])),
        );
        sum += volume(&grown);
        let v = volume(&union);
        if v > sum || v > MAX_REGION {
            break;
        }
        region = union;
    }
    region
}

/// Cells of `b`.
fn volume(b: &IBox) -> u64 {
    b.num_cells().unwrap_or(u64::MAX)
}
