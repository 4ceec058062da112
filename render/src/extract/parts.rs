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
//! The parts' bounds do not depend on the isovalue: files of layout version 4 store them (the
//! converter computes them with [`leaf_part_ranges`], in the tight ranges' pass); on older
//! files each leaf's are computed the first time it is extracted and kept ([`PartRanges`]),
//! 8 bytes per part, so a later isovalue only compares.

use std::sync::OnceLock;

use crate::error::{RenderError, Result};
use amr_format::kdtree::widen_range;
use amr_format::{FormatError, IBox};

use super::blocks::BlockRanges;
use super::halo::Halo;
use super::leaf::{extract_leaf, LeafCounts, LeafFrame, Scratch};
use super::leaf_tree::LeafTree;
use super::tight::{box_range_flat, box_range_in, Regions, TreeRegions};
use crate::reconstruct::interp::straddles;
use crate::reconstruct::Sampler;

/// Cells per axis of a part (rounded up to whole stored blocks): 8 took fewer instructions than
/// 4 or 16 on the 1e7-cell `blobs` file (`docs/benchmarks-extract.md`).
pub const PART_CELLS: i64 = 8;

/// One leaf's part bounds, once computed.
type LeafBounds = OnceLock<Box<[(f32, f32)]>>;

/// The bounds of the parts of every leaf: the file's, when it stores them for this part size,
/// else those of every leaf extracted so far, in part order (x fastest); filled from any thread.
pub struct PartRanges {
    stored: bool,
    /// Per leaf, once the first leaf's are computed (never, on a file that stores them).
    leaves: OnceLock<Box<[LeafBounds]>>,
    num_leaves: usize,
}

impl PartRanges {
    /// The part bounds of `sampler`'s field: the file's, when it stores them for
    /// [`part_cells`] and every leaf has as many as it has parts; else none yet. An error when
    /// a leaf stores another number of bounds than it has parts (a damaged file).
    pub fn of_file<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>) -> Result<Self> {
        let file = sampler.file();
        let computed = || Self {
            stored: false,
            leaves: OnceLock::new(),
            num_leaves: file.num_leaves(),
        };
        let (Some(stored), Some(block)) = (file.part_cells(), file.block_cells()) else {
            return Ok(computed());
        };
        if Some(stored) != part_cells(block) {
            return Ok(computed());
        }
        let Some(counts) = file.part_counts() else {
            return Ok(computed());
        };
        let (tree, grid, k) = (file.tree(), sampler.grid(), i64::from(stored));
        for (leaf, have) in (0..file.num_leaves() as u32).zip(counts) {
            // A leaf at most `k - 1` cells of its level wide on every axis overlaps at most `k`
            // of them however it is aligned, so it has no parts: most leaves of a file of small
            // boxes, checked without building their frame.
            let small = sampler.leaf_top(leaf).is_some_and(|(_, level)| {
                let (s, e) = (grid.scale(level), tree.leaf_box(leaf).extent());
                (0..3).all(|a| e[a] <= (k - 1).saturating_mul(s[a]))
            });
            let want = if small {
                Some(0)
            } else {
                LeafFrame::new(sampler, leaf)
                    .and_then(|f| PartGrid::of(sampler, &f))
                    .map_or(Some(0), |g| g.count())
            };
            if Some(have) != want {
                return Err(RenderError::Format(FormatError::Corrupt(format!(
                    "kd leaf {leaf} stores {have} part bounds; it has {} parts",
                    want.map_or("too many".to_string(), |n| n.to_string())
                ))));
            }
        }
        Ok(Self {
            stored: true,
            leaves: OnceLock::new(),
            num_leaves: file.num_leaves(),
        })
    }

    /// True when the bounds are the file's.
    pub fn stored(&self) -> bool {
        self.stored
    }
}

/// Cells per axis of a part of a file whose block range tables have blocks of `block` cells:
/// [`PART_CELLS`] rounded up to whole blocks; `None` for a block size of 0 or one that
/// overflows.
pub fn part_cells(block: u32) -> Option<u32> {
    let k = u32::try_from(PART_CELLS).ok()?;
    k.checked_next_multiple_of(block)
}

/// True when a leaf whose level-`level`-cells are `cells` is extracted in parts.
pub fn in_parts<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, cells: &IBox) -> bool {
    let Some(k) = sampler.file().block_cells().and_then(part_cells) else {
        return false;
    };
    cells.extent().iter().any(|&e| e > i64::from(k))
}

/// The parts of a leaf extracted in parts: the boxes of `k` cells per axis of its level,
/// aligned to the lower corner of its first brick, that overlap its cells; numbered x fastest
/// from `first` to `last` (inclusive).
struct PartGrid {
    k: i64,
    /// The first brick's lower corner.
    origin: [i64; 3],
    first: [i64; 3],
    last: [i64; 3],
}

impl PartGrid {
    /// The parts of `frame`'s leaf; `None` when it is extracted whole.
    fn of<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, frame: &LeafFrame) -> Option<Self> {
        let k = i64::from(sampler.file().block_cells().and_then(part_cells)?);
        let c = frame.cells;
        if c.extent().iter().all(|&e| e <= k) {
            return None;
        }
        let origin = sampler.brick_cells(frame.brick).lo;
        Some(Self {
            k,
            origin,
            first: [0, 1, 2].map(|a| (c.lo[a] - origin[a]).div_euclid(k)),
            last: [0, 1, 2].map(|a| (c.hi[a] - 1 - origin[a]).div_euclid(k)),
        })
    }

    /// The number of parts; `None` when it overflows.
    fn count(&self) -> Option<u64> {
        (0..3).try_fold(1u64, |n, a| {
            n.checked_mul(u64::try_from(self.last[a] - self.first[a] + 1).ok()?)
        })
    }

    /// Part `p`'s cells inside the leaf's, in finest-level cells.
    fn part_box<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        frame: &LeafFrame,
        p: [i64; 3],
    ) -> IBox {
        let grid = sampler.grid();
        let (s, o) = (grid.scale(frame.level), grid.offset());
        let (k, b) = (self.k, self.origin);
        let cells = IBox::new(
            [0, 1, 2].map(|a| b[a] + p[a] * k),
            [0, 1, 2].map(|a| b[a] + (p[a] + 1) * k),
        )
        .intersect(&frame.cells);
        IBox::new(
            [0, 1, 2].map(|a| cells.lo[a] * s[a] - o[a]),
            [0, 1, 2].map(|a| cells.hi[a] * s[a] - o[a]),
        )
        .intersect(&frame.finest)
    }
}

/// The bounds of the parts of `frame`'s leaf, in part order; empty for a leaf extracted whole. `bounds`: the block ranges (the file's, or built) and the leaf tree;
/// `around`: the leaves around the leaf ([`Halo::new`] of its box and level over the stored
/// blocks alone), when the caller gathered them already.
pub fn leaf_part_ranges<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    frame: &LeafFrame,
    bounds: (&BlockRanges, &LeafTree),
    around: Option<&Halo<'_, '_, D>>,
) -> Result<Vec<(f32, f32)>> {
    let Some(parts) = PartGrid::of(sampler, frame) else {
        return Ok(Vec::new());
    };
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
    let s = sampler.grid().scale(frame.level);
    let grown = frame.finest.grow(s);
    let flat = around.coarsest_touching(&grown).unwrap_or(frame.level) >= frame.level;
    let (first, last) = (parts.first, parts.last);
    let mut r = Vec::new();
    for pz in first[2]..=last[2] {
        for py in first[1]..=last[1] {
            for px in first[0]..=last[0] {
                let finest = parts.part_box(sampler, frame, [px, py, pz]);
                let range = if finest.is_empty() {
                    (f32::INFINITY, f32::NEG_INFINITY)
                } else {
                    part_range(sampler, frame, (bounds.0, around), flat, &finest)?
                };
                r.push(range);
            }
        }
    }
    Ok(r)
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
    let Some(parts) = PartGrid::of(sampler, frame) else {
        return extract_leaf(sampler, frame, iso, scratch, out);
    };
    let start = out.len();
    let stored = if kept.stored {
        sampler.file().part_ranges(sampler.field(), frame.leaf)
    } else {
        None
    };
    let computed = match stored {
        Some(_) => None,
        None => {
            let all = kept
                .leaves
                .get_or_init(|| (0..kept.num_leaves).map(|_| OnceLock::new()).collect());
            let slot = &all[frame.leaf as usize];
            Some(match slot.get() {
                Some(r) => r,
                None => {
                    let r = leaf_part_ranges(sampler, frame, bounds, around)?;
                    slot.get_or_init(|| r.into_boxed_slice())
                }
            })
        }
    };
    // Part `i`'s bound; every part has one (counts are checked when the file's are read), and
    // a missing one would keep the part.
    let bound = |i: usize| -> (f32, f32) {
        let b = match (stored, computed) {
            (Some(s), _) => s.get(i).map(|r| (r.min.get(), r.max.get())),
            (None, Some(c)) => c.get(i).copied(),
            (None, None) => None,
        };
        b.unwrap_or((f32::NEG_INFINITY, f32::INFINITY))
    };
    let mut counts = LeafCounts::default();
    let mut runs: Vec<IBox> = Vec::new();
    let (first, last) = (parts.first, parts.last);
    let mut i = 0;
    for pz in first[2]..=last[2] {
        for py in first[1]..=last[1] {
            let mut kept: Option<IBox> = None;
            for px in first[0]..=last[0] {
                let (lo, hi) = bound(i);
                i += 1;
                let finest = parts.part_box(sampler, frame, [px, py, pz]);
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
        counts.octants_culled += n.octants_culled;
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
