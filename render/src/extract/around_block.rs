//! The bounds around every cell of a block of `4^3` coarse cells of one level, computed
//! together: one pass over the leaves overlapping the block grown by one cell gives each cell's
//! bound, and the 27-cell unions around the block's cells follow from those, a few comparisons
//! each ([`super::band`]).
//!
//! Each cell's bound is the range of the leaf cells of its level or finer inside it; the union
//! around a cell then covers exactly the cells [`super::leaf_tree::LeafTree::exact_range_over`]
//! folds for it (every leaf cell of the leaves overlapping the 27 cells, inside them), so both
//! give the same range: NaNs left out, `None` exactly when a coarser leaf cell lies there.

use amr_format::IBox;

use super::band::{mark_cells, Sources};
use super::blocks::level_box;
use super::local::div_floor;
use crate::error::Result;
use crate::reconstruct::grid::axes;

/// Cells per axis of a block.
pub const BLOCK: i64 = 4;
/// Cells per axis of a block grown by one cell.
const GROWN: usize = BLOCK as usize + 2;
/// Cells of a block grown by one cell.
const GROWN_CELLS: usize = GROWN * GROWN * GROWN;
/// Cells of a block.
pub const BLOCK_CELLS: usize = (BLOCK * BLOCK * BLOCK) as usize;

/// The bound around a cell of a block: the range of the leaf cells within one cell of it, or
/// `None` when a leaf cell coarser than the block's level lies there.
pub type Around = Option<(f32, f32)>;

/// The bounds around the cells of block `cells` (`4^3` level-`level` cells; x fastest), found
/// from the leaves overlapping it grown by one cell; `touching` is scratch.
pub fn around_block<D: AsRef<[u8]>>(
    (sampler, _, leaves): Sources<'_, '_, D>,
    level: u32,
    cells: &IBox,
    touching: &mut Vec<u32>,
) -> Result<[Around; BLOCK_CELLS]> {
    debug_assert_eq!(cells.extent(), [BLOCK; 3], "a block of another size");
    let grid = sampler.grid();
    let g = cells.grow([1; 3]);
    let (s, o) = (grid.scale(level), grid.offset());
    let finest = IBox::new(
        axes(|a| g.lo[a] * s[a] - o[a]),
        axes(|a| g.hi[a] * s[a] - o[a]),
    );
    let mut lo = [f32::INFINITY; GROWN_CELLS];
    let mut hi = [f32::NEG_INFINITY; GROWN_CELLS];
    let mut coarser = [false; GROWN_CELLS];
    let mut any_coarser = false;
    touching.clear();
    leaves.for_each_leaf_overlapping(&finest, |l| touching.push(l));
    for &l in touching.iter() {
        let Some((brick, lv)) = sampler.leaf_top(l) else {
            continue;
        };
        let part = leaves.leaf_box(l).intersect(&finest);
        if lv < level {
            mark_cells(
                &mut coarser,
                &g,
                &level_box(grid, level, &part).intersect(&g),
            );
            any_coarser = true;
            continue;
        }
        let bc = sampler.brick_cells(brick);
        let fine = level_box(grid, lv, &part).intersect(&bc);
        if fine.is_empty() {
            continue;
        }
        let sf = grid.scale(lv);
        let r = axes(|a| s[a] / sf[a]);
        let values = sampler.values(brick)?;
        let w = fine.extent()[0] as usize;
        let first = div_floor(fine.lo[0], r[0]);
        for z in fine.lo[2]..fine.hi[2] {
            let gz = div_floor(z, r[2]) - g.lo[2];
            for y in fine.lo[1]..fine.hi[1] {
                let gy = div_floor(y, r[1]) - g.lo[1];
                let src = bc.linear_index([fine.lo[0], y, z]);
                let mut i = ((gz * GROWN as i64 + gy) * GROWN as i64 + first - g.lo[0]) as usize;
                let mut end = (first + 1) * r[0];
                let (mut l, mut h) = (lo[i], hi[i]);
                for (x, &v) in (fine.lo[0]..).zip(&values[src..src + w]) {
                    if x == end {
                        (lo[i], hi[i]) = (l, h);
                        i += 1;
                        end += r[0];
                        (l, h) = (lo[i], hi[i]);
                    }
                    // Comparisons, not f32::min: a NaN compares false and is left out.
                    if v < l {
                        l = v;
                    }
                    if v > h {
                        h = v;
                    }
                }
                (lo[i], hi[i]) = (l, h);
            }
        }
    }
    // The unions of three cells along x, then y, then z.
    let (lo, hi, coarser) = (
        threes(&lo, |a, b| if b < a { b } else { a }),
        threes(&hi, |a, b| if b > a { b } else { a }),
        any_coarser.then(|| threes(&coarser, |a, b| a | b)),
    );
    Ok(std::array::from_fn(|k| {
        if coarser.is_some_and(|c| c[k]) {
            None
        } else {
            Some((lo[k], hi[k]))
        }
    }))
}

/// Per cell of the block (x fastest), `join` of the 27 values around it in `v` (the block
/// grown by one cell, x fastest), three along each axis in turn.
#[inline]
fn threes<T: Copy + Default>(v: &[T; GROWN_CELLS], join: impl Fn(T, T) -> T) -> [T; BLOCK_CELLS] {
    const B: usize = BLOCK as usize;
    let three = |a: T, b: T, c: T| join(join(a, b), c);
    let mut xs = [T::default(); GROWN * GROWN * B];
    for zy in 0..GROWN * GROWN {
        for x in 0..B {
            let i = zy * GROWN + x;
            xs[zy * B + x] = three(v[i], v[i + 1], v[i + 2]);
        }
    }
    let mut ys = [T::default(); GROWN * B * B];
    for z in 0..GROWN {
        for y in 0..B {
            for x in 0..B {
                let i = (z * GROWN + y) * B + x;
                ys[(z * B + y) * B + x] = three(xs[i], xs[i + B], xs[i + 2 * B]);
            }
        }
    }
    std::array::from_fn(|k| three(ys[k], ys[k + B * B], ys[k + 2 * B * B]))
}
