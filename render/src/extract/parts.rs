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
//! ([`BlockRanges::loose`]), its region queries answered by the leaves around the leaf, gathered
//! once ([`Halo`]), unless they are too many.
//! Parts that are kept and adjacent are extracted together (runs along x, joined across rows
//! and layers when their extents match), so that the cells shared by their neighbourhoods are
//! filled once.
//!
//! The parts' bounds do not depend on the isovalue: each leaf's are computed the first time it
//! is extracted and kept ([`PartRanges`]), 8 bytes per part, so a later isovalue only compares.

use std::sync::OnceLock;

use crate::error::Result;
use amr_format::kdtree::widen_range;
use amr_format::IBox;

use super::blocks::BlockRanges;
use super::halo::Halo;
use super::leaf::{extract_leaf, LeafCounts, LeafFrame, Scratch};
use super::leaf_tree::LeafTree;
use super::tight::{box_range_flat, box_range_in, pack, unpack, Regions, TreeRegions};
use crate::reconstruct::interp::straddles;
use crate::reconstruct::Sampler;

/// Cells per axis of a part (rounded up to whole stored blocks): 8 took fewer instructions than
/// 4 or 16 on the 1e7-cell `blobs` file (`docs/benchmarks-extract.md`).
pub const PART_CELLS: i64 = 8;

/// The bounds of the parts of every leaf extracted so far, in part order (x fastest), packed
/// ([`pack`]); filled from any thread.
pub struct PartRanges {
    leaves: Box<[OnceLock<Box<[u64]>>]>,
}

impl PartRanges {
    /// No bounds yet, for `leaves` leaves.
    pub fn new(leaves: usize) -> Self {
        Self {
            leaves: (0..leaves).map(|_| OnceLock::new()).collect(),
        }
    }
}

/// True when a leaf whose level-`level`-cells are `cells` is extracted in parts.
pub fn in_parts<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, cells: &IBox) -> bool {
    let Some(block) = sampler.file().block_cells().map(i64::from) else {
        return false;
    };
    let k = (PART_CELLS + block - 1) / block * block;
    cells.extent().iter().any(|&e| e > k)
}

/// [`extract_leaf`] of `frame`, part by part when the file stores block ranges and the leaf
/// spans more than one part; the active voxels appended to `out` are sorted by id. `around`:
/// the leaves around the leaf ([`Halo::new`] of its box and level over the stored blocks alone),
/// when the caller gathered them already.
pub fn extract_in_parts<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    frame: &LeafFrame,
    iso: f32,
    (scratch, bounds, kept): (&mut Scratch<'_>, (&BlockRanges, &LeafTree), &PartRanges),
    around: Option<&Halo<'_, '_, D>>,
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
    let part_box = |p: [i64; 3]| -> IBox {
        let cells = IBox::new(
            [0, 1, 2].map(|a| bc.lo[a] + p[a] * k),
            [0, 1, 2].map(|a| bc.lo[a] + (p[a] + 1) * k),
        )
        .intersect(&c);
        IBox::new(
            [0, 1, 2].map(|a| cells.lo[a] * s[a] - o[a]),
            [0, 1, 2].map(|a| cells.hi[a] * s[a] - o[a]),
        )
        .intersect(&frame.finest)
    };
    let slot = &kept.leaves[frame.leaf as usize];
    let ranges = match slot.get() {
        Some(r) => r,
        None => {
            // The leaves around the leaf, once: the parts' bounds ask them, not the tree.
            let loose = bounds.0.loose();
            let gathered;
            let tree = TreeRegions {
                sampler,
                blocks: &loose,
                leaves: bounds.1,
            };
            let around: &dyn Regions = match around {
                Some(h) => h,
                None => {
                    gathered = Halo::new(sampler, (&loose, bounds.1), &frame.finest, frame.level);
                    match &gathered {
                        Some(h) => h,
                        None => &tree,
                    }
                }
            };
            // With no coarser leaf around the leaf, none is around its parts either.
            let grown = frame.finest.grow(s);
            let flat = around.coarsest_touching(&grown).unwrap_or(frame.level) >= frame.level;
            let mut r = Vec::new();
            for pz in first[2]..=last[2] {
                for py in first[1]..=last[1] {
                    for px in first[0]..=last[0] {
                        let finest = part_box([px, py, pz]);
                        let range = if finest.is_empty() {
                            (f32::INFINITY, f32::NEG_INFINITY)
                        } else {
                            part_range(sampler, frame, (bounds.0, around), flat, &finest)?
                        };
                        r.push(pack(range));
                    }
                }
            }
            slot.get_or_init(|| r.into_boxed_slice())
        }
    };
    let mut counts = LeafCounts::default();
    let mut runs: Vec<IBox> = Vec::new();
    let mut ranges = ranges.iter();
    for pz in first[2]..=last[2] {
        for py in first[1]..=last[1] {
            let mut kept: Option<IBox> = None;
            for px in first[0]..=last[0] {
                let (lo, hi) = unpack(ranges.next().copied().unwrap_or(u64::MAX));
                let finest = part_box([px, py, pz]);
                if finest.is_empty() {
                    runs.extend(kept.take());
                    continue;
                }
                if straddles(lo, hi, iso) {
                    kept = Some(match kept {
                        Some(r) => IBox::new(r.lo, finest.hi),
                        None => finest,
                    });
                } else {
                    counts.parts_skipped += 1;
                    runs.extend(kept.take());
                }
            }
            runs.extend(kept.take());
        }
    }
    for finest in merge_runs(runs) {
        let part = frame.part(sampler, finest);
        let n = extract_leaf(sampler, &part, iso, scratch, out)?;
        counts.evaluated += n.evaluated;
        counts.boundary += n.boundary;
        counts.culled += n.culled;
    }
    // Runs of sorted refs, one per run of parts: the stable sort merges them.
    out[start..].sort();
    Ok(counts)
}

/// The runs of kept parts `runs` (boxes along x, in row order: z, then y), joined into fewer
/// boxes holding the same cells: runs of the same x-extent in adjacent rows of a layer, then
/// boxes of the same x- and y-extent in adjacent layers. A neighbourhood holds a box grown by
/// one cell, so fewer, larger boxes fill fewer cells and ask for the leaves around them fewer
/// times.
fn merge_runs(runs: Vec<IBox>) -> Vec<IBox> {
    let same = |a: &IBox, b: &IBox, axes: std::ops::Range<usize>| {
        axes.into_iter()
            .all(|k| a.lo[k] == b.lo[k] && a.hi[k] == b.hi[k])
    };
    let mut rows: Vec<IBox> = Vec::with_capacity(runs.len());
    for r in runs {
        // The boxes of this layer are the last ones.
        let joined = rows
            .iter_mut()
            .rev()
            .take_while(|b| same(b, &r, 2..3))
            .find(|b| same(b, &r, 0..1) && b.hi[1] == r.lo[1]);
        match joined {
            Some(b) => b.hi[1] = r.hi[1],
            None => rows.push(r),
        }
    }
    let mut boxes: Vec<IBox> = Vec::with_capacity(rows.len());
    for r in rows {
        match boxes
            .iter_mut()
            .find(|b| same(b, &r, 0..2) && b.hi[2] == r.lo[2])
        {
            Some(b) => b.hi[2] = r.hi[2],
            None => boxes.push(r),
        }
    }
    boxes
}

/// A range holding every corner of every voxel of `frame` whose lower corner lies in
/// finest-level box `finest` (see the module documentation); `(+inf, -inf)` when there is
/// none. `around`: the region queries of the leaf's neighbourhood; `flat`: no leaf coarser than the leaf touches the
/// leaf grown by one cell.
fn part_range<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    frame: &LeafFrame,
    (blocks, around): (&BlockRanges, &dyn Regions),
    flat: bool,
    finest: &IBox,
) -> Result<(f32, f32)> {
    let empty = (f32::INFINITY, f32::NEG_INFINITY);
    let s = sampler.grid().scale(frame.level);
    let (lo, hi) = if frame.finest.contains_box(&finest.grow(s)) {
        // Only merged dual cells: those whose lowest cell lies in the part, so their cells lie
        // in the part grown by one cell upwards.
        let up = IBox::new(finest.lo, [0, 1, 2].map(|a| finest.hi[a] + s[a]));
        let Some((lo, hi)) = blocks.bound_in(sampler, frame.brick, frame.level, &up) else {
            return Ok((f32::NEG_INFINITY, f32::INFINITY));
        };
        if lo > hi {
            return Ok(empty);
        }
        widen_range(lo, hi)
    } else if flat {
        box_range_flat(s, around, finest)?
    } else {
        box_range_in(sampler, around, finest, frame.level)?
    };
    Ok(if lo <= hi { (lo, hi) } else { empty })
}
