//! Conservative culling of a leaf's boundary cells: a cell none of whose octants can hold the
//! surface is skipped before any of its octant corners is evaluated.
//!
//! Every octant vertex value is either the mean of the leaf cells around the vertex or the
//! trilinear interpolant of a coarser leaf cell's octant at the vertex (`docs/reconstruction.md`).
//! The vertices of the octants of a level-`L` cell `C` lie on `C`'s closure, so the leaf cells
//! around them lie in the 27 level-`L` neighbourhood cells around `C`, and so does a finest cell
//! of the coarse octant that gives a fine-side value (the nudge that chose it). Hence every corner
//! of every octant of `C` lies in the union of those cells' bounds, where a cell's bound covers the
//! leaf cells of level `L` or finer inside it and the corners of the coarse octants overlapping it.
//! Means never leave the range of their inputs (rounding is monotone and halving exact); a
//! trilinear interpolation can by a few ulps, so coarse contributions are widened.

use crate::error::Result;
use amr_format::IBox;

use super::band::{AroundMemo, CoarseBounds};
use super::blocks::{level_box, BlockRanges};
use super::leaf_tree::LeafTree;
use super::local::{Neighbourhood, ABOVE, BELOW, COARSER, PENDING};
use super::tight::TightRanges;
use crate::reconstruct::grid::axes;
use crate::reconstruct::sampler::Locate;
use crate::reconstruct::{LeafCell, Sampler, VertexMemo};

/// The neighbourhood-index offsets of the 27 cells around a cell, in a neighbourhood whose
/// rows hold `row` cells and whose slabs hold `slab` cells, relative to the lowest of them.
pub fn around_offsets(row: usize, slab: usize) -> [usize; 27] {
    std::array::from_fn(|k| k % 3 + k / 3 % 3 * row + k / 9 * slab)
}

/// The tables every leaf's cull reads, shared by the threads of one field's extraction.
#[derive(Clone, Copy)]
pub struct Shared<'s> {
    /// The bricks' block ranges.
    pub blocks: &'s BlockRanges,
    /// The kd leaves' boxes by region.
    pub leaves: &'s LeafTree,
    /// The bounds around coarse leaf cells, kept for every leaf.
    pub coarse: &'s CoarseBounds,
    /// The kd leaves' tight ranges.
    pub tight: &'s TightRanges<'s>,
}

/// True unless the octants of the cell at neighbourhood index `i` certainly do not straddle
/// `iso` ([`Neighbourhood::classify`] must have run for `iso`). `around` comes from
/// [`around_offsets`]. Bounds of coarser neighbours are computed on first need (from `coarse`, which
/// keeps them for every leaf, gathering them from the leaves of `leaves` through `blocks`) and kept
/// in `hood`.
pub fn cell_may_hold<D: AsRef<[u8]>>(
    (sampler, shared): (&Sampler<'_, D>, Shared<'_>),
    hood: &mut Neighbourhood,
    (memo, near): (&mut VertexMemo, &mut AroundMemo),
    (i, around): (usize, &[usize; 27]),
    iso: f32,
) -> Result<bool> {
    let e = hood.cells.extent();
    let base = i - 1 - e[0] as usize - (e[0] * e[1]) as usize;
    let union = union_around(hood.codes(), base, around);
    if union & (ABOVE | BELOW) == ABOVE | BELOW {
        return Ok(true);
    }
    if union & PENDING == 0 {
        return Ok(false);
    }
    // The cells asked about next lie anywhere in the neighbourhood.
    let all = hood.cells;
    let mut pending = pending_around(hood.codes(), base, around);
    while pending != 0 {
        let j = base + around[pending.trailing_zeros() as usize];
        pending &= pending - 1;
        // An earlier cell's settling may have settled this one.
        if hood.codes()[j] & PENDING != 0 {
            settle_coarse(
                (sampler, shared),
                hood,
                (memo, near),
                (j, Some(&all)),
                Some(iso),
            )?;
        }
    }
    // Settling only widens the bounds of pending cells, so their codes only gain bits: the
    // union now is that of the codes before, without `PENDING`, and of the settled codes.
    let union = union_around(hood.codes(), base, around);
    Ok(union & (ABOVE | BELOW) == ABOVE | BELOW)
}

/// Settles neighbourhood cell `j` if it is pending, as [`cell_may_hold`] settles the cells
/// around a cell: afterwards its code holds its whole bound for `iso`.
pub fn settle_pending<D: AsRef<[u8]>>(
    sources: (&Sampler<'_, D>, Shared<'_>),
    hood: &mut Neighbourhood,
    (memo, near): (&mut VertexMemo, &mut AroundMemo),
    j: usize,
    iso: f32,
) -> Result<()> {
    if hood.codes()[j] & PENDING != 0 {
        let all = hood.cells;
        settle_coarse(sources, hood, (memo, near), (j, Some(&all)), Some(iso))?;
    }
    Ok(())
}

/// Bit `k` set when the code at `base + around[k]` is [`PENDING`], read nine words at a time as
/// in [`union_around`].
#[inline]
fn pending_around(codes: &[u8], base: usize, around: &[usize; 27]) -> u32 {
    let end = base + around[24] + 4;
    if end > codes.len() {
        return (0..27).fold(0, |m, k| {
            m | u32::from(codes[base + around[k]] & PENDING != 0) << k
        });
    }
    let rows = &codes[base..end];
    let mut mask = 0u32;
    for r in 0..9 {
        let word = word_at(rows, around[3 * r]);
        let p = word >> PENDING.trailing_zeros() & 0x0001_0101;
        mask |= (p & 1 | p >> 7 & 2 | p >> 14 & 4) << (3 * r);
    }
    mask
}

/// The four codes from `rows[o]` as a little-endian word, for the first offset `o` of a row of
/// three of `around` (read unchecked: a checked read costs `mid` 4 % of its extraction).
#[inline(always)]
fn word_at(rows: &[u8], o: usize) -> u32 {
    debug_assert!(o + 4 <= rows.len());
    // SAFETY: the callers pass `rows = codes[base..base + around[24] + 4]` and `o = around[3 r]`
    // with `r < 9`, `around` from [`around_offsets`]: `around[3 r] = (r % 3) row + (r / 3) slab`
    // is at most `around[24] = 2 row + 2 slab`, so the four bytes at `o` lie inside `rows`.
    // `read_unaligned` needs no alignment.
    u32::from_le(unsafe { rows.as_ptr().add(o).cast::<u32>().read_unaligned() })
}

/// The union (OR) of the codes of the 27 cells at `base + around[k]`: each of the nine rows of
/// three read as one little-endian word of four codes, the fourth masked off, where the last
/// row's word lies inside `codes`.
#[inline(always)]
fn union_around(codes: &[u8], base: usize, around: &[usize; 27]) -> u8 {
    let end = base + around[24] + 4;
    if end > codes.len() {
        return around.iter().fold(0u8, |u, &d| u | codes[base + d]);
    }
    let rows = &codes[base..end];
    let mut words = 0u32;
    for r in 0..9 {
        words |= word_at(rows, around[3 * r]);
    }
    let words = words & 0x00ff_ffff;
    (words | words >> 8 | words >> 16) as u8
}

/// Settles the pending cells of box `b` of `hood` (the bounds of its cells inside coarser leaf
/// cells), as [`cell_may_hold`] does on need; the isovalue bits of the codes then mean nothing
/// until the next [`Neighbourhood::classify`]. With `together`, the bounds around the coarse
/// cells may be computed a block at a time ([`CoarseBounds::range_around_memo`]); not for the
/// parts of cell tiles, whose coarse cells lie few to a block among many small leaves.
pub fn settle_in<D: AsRef<[u8]>>(
    (sampler, shared): (&Sampler<'_, D>, Shared<'_>),
    hood: &mut Neighbourhood,
    (memo, near): (&mut VertexMemo, &mut AroundMemo),
    (b, together): (&IBox, bool),
) -> Result<()> {
    if !hood.has_pending() || b.is_empty() || !hood.may_pend_in(b) {
        return Ok(());
    }
    let (e, be) = (hood.cells.extent(), b.extent());
    let (w, row, slab) = (be[0] as usize, e[0] as usize, (e[0] * e[1]) as usize);
    let first = hood.index(b.lo);
    for z in 0..be[2] as usize {
        for y in 0..be[1] as usize {
            let r = first + z * slab + y * row;
            // Most rows hold no pending cell: one pass over the row's codes finds out.
            if !hood.codes()[r..r + w].iter().any(|&c| c & PENDING != 0) {
                continue;
            }
            for j in r..r + w {
                if hood.codes()[j] & PENDING != 0 {
                    let wanted = together.then_some(b);
                    settle_coarse((sampler, shared), hood, (memo, near), (j, wanted), None)?;
                }
            }
        }
    }
    Ok(())
}

/// Computes the bound of coarser neighbourhood cell `j` and of every pending cell sharing its
/// coarse leaf cell `Q`: the range of the leaf cells within one cell of `Q` at `Q`'s level
/// (which holds every corner of `Q`'s octants when none of them is coarser than `Q`), or else
/// the exact corners of the octants of `Q` overlapping cell `j`. The cells of `hood` being
/// settled lie in box `wanted`, if given: the bounds may then be computed a block at a time.
///
/// With `iso` (the cull's settling, whose codes are read for that isovalue alone), a stored tight
/// range of the kd leaf holding `Q` that lies wholly above or below `iso` is taken instead: it
/// holds every corner of `Q`'s octants, so the codes are the ones the bound above would give.
/// Without (`iso` `None`: bounds kept for any isovalue, as [`settle_in`] makes them), always
/// the bound above.
fn settle_coarse<D: AsRef<[u8]>>(
    (sampler, shared): (&Sampler<'_, D>, Shared<'_>),
    hood: &mut Neighbourhood,
    (memo, near): (&mut VertexMemo, &mut AroundMemo),
    (j, wanted): (usize, Option<&IBox>),
    iso: Option<f32>,
) -> Result<()> {
    let Shared {
        blocks,
        leaves,
        coarse,
        tight,
    } = shared;
    debug_assert_eq!(hood.kind(j), COARSER);
    let grid = sampler.grid();
    let level = hood.level;
    let s = grid.scale(level);
    let o = grid.offset();
    let x = hood.cell_at(j);
    let lower = axes(|a| x[a] * s[a] - o[a]);
    let code_iso = iso.unwrap_or(0.0);
    let Some(q) = sampler.locate_cell(lower)? else {
        hood.settle_coarse(j, (f32::INFINITY, f32::NEG_INFINITY), code_iso);
        return Ok(());
    };
    if q.level >= level {
        // Not a properly nested hierarchy here: never cull next to it.
        hood.settle_coarse(j, (f32::NEG_INFINITY, f32::INFINITY), code_iso);
        return Ok(());
    }
    let q_box = grid.finest_box(q.level, q.cell);
    let settle_all_in_q = |hood: &mut Neighbourhood, bound: (f32, f32)| {
        let inside = level_box(grid, level, &q_box).intersect(&hood.cells);
        hood.settle_pending_in(&inside, bound, code_iso);
    };
    if let Some(iso) = iso {
        if let Some(bound) = leaf_side_of(sampler, tight, &q, &q_box, iso) {
            settle_all_in_q(hood, bound);
            return Ok(());
        }
    }
    let asked = |w: &IBox, block: &IBox, enough: u32| {
        let sq = grid.scale(q.level);
        hood.pending_over(block, axes(|a| sq[a] / s[a]), w, enough)
    };
    let wanted = wanted.map(|w| (w, move |block: &IBox, enough| asked(w, block, enough)));
    if let Some(range) =
        coarse.range_around_memo((sampler, blocks, leaves), near, (q.level, q.cell), wanted)?
    {
        settle_all_in_q(hood, widen(range));
        return Ok(());
    }
    let bound = exact_bound((sampler, memo), &q, level, x)?;
    hood.settle_coarse(j, bound, code_iso);
    Ok(())
}

/// Settles the pending cells of `hood` for `iso` that lie in coarser kd leaves whose stored
/// tight range lies wholly on one side of `iso` (see [`one_sided_range`]), a block of cells per
/// leaf, where the leaf's box is whole cells of its level: then every coarse leaf cell holding
/// one of the block's cells lies inside the leaf. The codes are those [`cell_may_hold`] would
/// settle one cell at a time.
pub fn settle_by_leaf_ranges<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    tight: &TightRanges<'_>,
    hood: &mut Neighbourhood,
    iso: f32,
) {
    if !hood.has_pending() {
        return;
    }
    let grid = sampler.grid();
    let o = grid.offset();
    hood.settle_coarser_blocks(iso, |leaf, level| {
        let bound = one_sided_range(tight, leaf, iso)?;
        let (b, s) = (sampler.leaf_box(leaf), grid.scale(level));
        let whole_cells = (0..3).all(|a| {
            (b.lo[a] + o[a]).rem_euclid(s[a]) == 0 && (b.hi[a] + o[a]).rem_euclid(s[a]) == 0
        });
        whole_cells.then_some(bound)
    });
}

/// The tight range of the kd leaf holding coarse leaf cell `q` (whose finest cells are `q_box`)
/// as [`one_sided_range`] gives it, when `q` lies inside the leaf's box: the leaf then owns
/// every octant of `q`.
fn leaf_side_of<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    tight: &TightRanges<'_>,
    q: &LeafCell,
    q_box: &IBox,
    iso: f32,
) -> Option<(f32, f32)> {
    let bound = one_sided_range(tight, q.leaf, iso)?;
    sampler
        .leaf_box(q.leaf)
        .contains_box(q_box)
        .then_some(bound)
}

/// The tight range of kd leaf `leaf`, widened, when the file stores it and it lies wholly on one
/// side of `iso`. It bounds every octant the leaf owns: a leaf's tight range holds every corner of every
/// voxel it owns ([`super::tight`]), and a vertex that takes its value from such an octant takes
/// a trilinear interpolant of its corners, which [`widen`] covers. Its code for `iso` is then
/// the code of any bound inside it that is not empty.
fn one_sided_range(tight: &TightRanges<'_>, leaf: u32, iso: f32) -> Option<(f32, f32)> {
    let (lo, hi) = widen(tight.stored(leaf)?);
    (hi < iso || lo >= iso).then_some((lo, hi))
}

/// The bound of level-`level` cell `x`, which lies in leaf cell `q` coarser than it: the range
/// of the corners of the octants of `q` overlapping `x` (computed through `memo`), widened.
fn exact_bound<D: AsRef<[u8]>>(
    (sampler, memo): (&Sampler<'_, D>, &mut VertexMemo),
    q: &LeafCell,
    level: u32,
    x: [i64; 3],
) -> Result<(f32, f32)> {
    let grid = sampler.grid();
    let s = grid.scale(level);
    let o = grid.offset();
    let lower = axes(|a| x[a] * s[a] - o[a]);
    let c = grid.centre(q.level, q.cell);
    let (x0, x1) = (
        lower.map(|v| 2 * v),
        [0, 1, 2].map(|a| 2 * (lower[a] + s[a])),
    );
    let mut lo = f32::INFINITY;
    let mut hi = f32::NEG_INFINITY;
    for octant in 0..8u8 {
        let overlaps = (0..3).all(|a| {
            if octant >> a & 1 == 1 {
                x1[a] > c[a]
            } else {
                x0[a] < c[a]
            }
        });
        if !overlaps {
            continue;
        }
        if let Some(corners) = sampler.leaf_octant_corners_in(sampler, q, octant, memo)? {
            for v in corners {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    Ok(widen((lo, hi)))
}

/// The bound [`settle_coarse`] gives level-`level` cell `x` (inside a coarser leaf cell) where
/// no bound of the leaf cells around that coarse cell is used: the range of the corners of the
/// coarse cell's octants overlapping `x`, widened. Every value a vertex takes from a coarse
/// octant through a finest cell of `x` lies in it; tighter than the settled bound, and dearer.
pub fn coarse_cell_bound<D: AsRef<[u8]>>(
    (sampler, memo): (&Sampler<'_, D>, &mut VertexMemo),
    level: u32,
    x: [i64; 3],
) -> Result<(f32, f32)> {
    let grid = sampler.grid();
    let (s, o) = (grid.scale(level), grid.offset());
    let lower = axes(|a| x[a] * s[a] - o[a]);
    match sampler.locate_cell(lower)? {
        None => Ok((f32::INFINITY, f32::NEG_INFINITY)),
        Some(q) if q.level >= level => Ok((f32::NEG_INFINITY, f32::INFINITY)),
        Some(q) => exact_bound((sampler, memo), &q, level, x),
    }
}

/// Widens a range of corner values by the round-off a trilinear interpolation of them can add.
fn widen((lo, hi): (f32, f32)) -> (f32, f32) {
    if lo > hi {
        return (lo, hi);
    }
    let slack = lo.abs().max(hi.abs()) * 4.0e-6 + f32::from_bits(64);
    (lo - slack, hi + slack)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The union of the codes around a cell read a row of three at a time equals the union of
    /// the 27 codes one by one, for every cell of a neighbourhood, its last ones included.
    #[test]
    fn union_around_is_the_union_of_the_27_codes() {
        let (row, slab) = (5, 5 * 4);
        // Few cells with a bit each, so that a fourth code read along would show.
        let mut state = 12345u32;
        let codes: Vec<u8> = (0..slab * 3)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                let r = state >> 16;
                if r.is_multiple_of(5) {
                    1 << (r / 5 % 4)
                } else {
                    0
                }
            })
            .collect();
        let around = around_offsets(row, slab);
        for base in 0..=codes.len() - 1 - around[26] {
            let each = around.iter().fold(0u8, |u, &d| u | codes[base + d]);
            assert_eq!(
                union_around(&codes, base, &around),
                each,
                "cells from {base}"
            );
            let pending = (0..27).fold(0, |m, k| {
                m | u32::from(codes[base + around[k]] & PENDING != 0) << k
            });
            assert_eq!(
                pending_around(&codes, base, &around),
                pending,
                "cells from {base}"
            );
        }
    }
}
