//! A large leaf extracted part by part: its cells are cut into boxes aligned to its brick's
//! stored blocks, and a part whose bound excludes the isovalue is skipped before its
//! neighbourhood is built or its cells are read.
//!
//! A part's bound holds every corner of every voxel it owns (those whose lower corner lies in
//! it): when the part grown by one cell lies inside the leaf, those cells are all the leaf's own
//! (a leaf has one finest brick and nothing finer), so every voxel owned is a merged dual cell
//! whose lowest cell lies in the part, and the bound is the union of the stored blocks the part
//! grown by one cell upwards overlaps; otherwise it is the tight-range bound of the
//! part's box ([`super::tight::box_range`]) over the stored blocks alone
//! ([`BlockRanges::loose`]).
//! Parts that are kept and adjacent along x are extracted together, so that the cells shared
//! by their neighbourhoods are filled once.

use crate::error::Result;
use amr_format::kdtree::widen_range;
use amr_format::IBox;

use super::blocks::BlockRanges;
use super::leaf::{extract_leaf, LeafCounts, LeafFrame, Scratch};
use super::leaf_tree::LeafTree;
use super::tight::box_range;
use crate::reconstruct::interp::straddles;
use crate::reconstruct::Sampler;

/// Cells per axis of a part (rounded up to whole stored blocks): 8 took fewer instructions than
/// 4 or 16 on the 1e7-cell `blobs` file (`docs/benchmarks-extract.md`).
pub const PART_CELLS: i64 = 8;

/// [`extract_leaf`] of `frame`, part by part when the file stores block ranges and the leaf
/// spans more than one part; the active voxels appended to `out` are sorted by id.
pub fn extract_in_parts<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    frame: &LeafFrame,
    iso: f32,
    (scratch, bounds): (&mut Scratch<'_, '_, D>, (&BlockRanges, &LeafTree)),
    out: &mut Vec<u64>,
) -> Result<LeafCounts> {
    let Some(block) = sampler.file().block_cells().map(i64::from) else {
        return extract_leaf(sampler, frame, iso, scratch, out);
    };
    let k = (PART_CELLS + block - 1) / block * block;
    let c = frame.cells;
    if c.extent().iter().all(|&e| e <= k) {
        return extract_leaf(sampler, frame, iso, scratch, out);
    }
    let start = out.len();
    let grid = sampler.grid();
    let (s, o) = (grid.scale(frame.level), grid.offset());
    let bc = sampler.brick_cells(frame.brick);
    let first = [0, 1, 2].map(|a| (c.lo[a] - bc.lo[a]).div_euclid(k));
    let last = [0, 1, 2].map(|a| (c.hi[a] - 1 - bc.lo[a]).div_euclid(k));
    let mut counts = LeafCounts::default();
    let mut run = |run: &mut Option<IBox>, counts: &mut LeafCounts| -> Result<()> {
        if let Some(finest) = run.take() {
            let part = frame.part(sampler, finest);
            let n = extract_leaf(sampler, &part, iso, scratch, out)?;
            counts.evaluated += n.evaluated;
            counts.boundary += n.boundary;
            counts.culled += n.culled;
        }
        Ok(())
    };
    for pz in first[2]..=last[2] {
        for py in first[1]..=last[1] {
            let mut kept: Option<IBox> = None;
            for px in first[0]..=last[0] {
                let p = [px, py, pz];
                let cells = IBox::new(
                    [0, 1, 2].map(|a| bc.lo[a] + p[a] * k),
                    [0, 1, 2].map(|a| bc.lo[a] + (p[a] + 1) * k),
                )
                .intersect(&c);
                let finest = IBox::new(
                    [0, 1, 2].map(|a| cells.lo[a] * s[a] - o[a]),
                    [0, 1, 2].map(|a| cells.hi[a] * s[a] - o[a]),
                )
                .intersect(&frame.finest);
                if finest.is_empty() {
                    run(&mut kept, &mut counts)?;
                    continue;
                }
                if part_may_hold(sampler, frame, bounds, &finest, iso)? {
                    kept = Some(match kept {
                        Some(r) => IBox::new(r.lo, finest.hi),
                        None => finest,
                    });
                } else {
                    counts.parts_skipped += 1;
                    run(&mut kept, &mut counts)?;
                }
            }
            run(&mut kept, &mut counts)?;
        }
    }
    out[start..].sort_unstable();
    Ok(counts)
}

/// False when no voxel of `frame` whose lower corner lies in finest-level box `finest` can hold
/// `iso` (see the module documentation).
fn part_may_hold<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    frame: &LeafFrame,
    (blocks, leaves): (&BlockRanges, &LeafTree),
    finest: &IBox,
    iso: f32,
) -> Result<bool> {
    let s = sampler.grid().scale(frame.level);
    let range = if frame.finest.contains_box(&finest.grow(s)) {
        // Only merged dual cells: those whose lowest cell lies in the part, so their cells lie
        // in the part grown by one cell upwards.
        let up = IBox::new(finest.lo, [0, 1, 2].map(|a| finest.hi[a] + s[a]));
        let Some((lo, hi)) = blocks.bound_in(sampler, frame.brick, frame.level, &up) else {
            return Ok(true);
        };
        (lo <= hi).then(|| widen_range(lo, hi))
    } else {
        let (lo, hi) = box_range(sampler, (&blocks.loose(), leaves), finest, frame.level)?;
        (lo <= hi).then_some((lo, hi))
    };
    Ok(range.is_some_and(|(lo, hi)| straddles(lo, hi, iso)))
}
