//! Octant corners next to other levels, from one table of the leaf cells they read.
//!
//! Every corner of an octant but the cell centre is the value at a vertex computed from the eight
//! finest cells the vertex is nudged into. Per axis those cells lie at four finest-level
//! coordinates (the two faces of the octant's box, nudged toward `-` and toward `+`), so all the
//! corners read from one 4x4x4 table of finest cells, each cell used by exactly one corner. The
//! table is filled once, position by position (the cell and its seven neighbours of the same
//! level around the octant's outer corner): a position whose located leaf cell covers it whole
//! fills its entries with that cell, the others read their cells from the position's or the
//! octant's kd-tree leaf, or locate them. The corners then follow from the table in
//! [`Sampler::vertex_value_in`]'s order and operations, so the values are its values bit for bit.

use amr_format::IBox;

use crate::error::Result;

use super::grid::axes;
use super::interp::avg8;
use super::sampler::{LeafCell, Locate, Octant, Position, Sampler, VertexMemo, NO_CELL};
use super::stitch::Stitches;

/// The finest cells of the table along one axis.
#[derive(Clone, Copy, Default)]
struct Axis {
    /// Per table index `2 * face + dir`: the finest coordinate (clamped into the domain).
    at: [i64; 4],
    /// Per table index: the axis's bit when the cell lies outside the octant's own cell.
    out: [usize; 4],
}

/// Branch-free: true when finest cell `p` lies in box `b`.
#[inline(always)]
pub(super) fn holds(b: &IBox, p: [i64; 3]) -> bool {
    (b.lo[0] <= p[0])
        & (p[0] < b.hi[0])
        & (b.lo[1] <= p[1])
        & (p[1] < b.hi[1])
        & (b.lo[2] <= p[2])
        & (p[2] < b.hi[2])
}

/// Per axis: the sides of a vertex (bit `n` for side `n`, as in [`Sampler::nudges`]) nudged
/// toward `-` on it.
pub(super) const SIDES_DOWN: [u8; 3] = [0x55, 0x33, 0x0F];

/// The sides of a vertex whose finest cell (`lo`/`hi` per axis, as [`Sampler::nudges`] gives
/// them) lies in box `b`, one bit per side: branch-free, two tests per axis for the eight cells.
#[inline(always)]
pub(super) fn sides_in(b: &IBox, lo: [i64; 3], hi: [i64; 3]) -> u8 {
    let mut m = 0xFF;
    for a in 0..3 {
        let l = (b.lo[a] <= lo[a]) & (lo[a] < b.hi[a]);
        let h = (b.lo[a] <= hi[a]) & (hi[a] < b.hi[a]);
        m &= (SIDES_DOWN[a] & 0u8.wrapping_sub(u8::from(l)))
            | (!SIDES_DOWN[a] & 0u8.wrapping_sub(u8::from(h)));
    }
    m
}

/// The sides of a vertex that are not repeats: side `n` repeats side `n & !same` ([`Sampler::nudges`]).
#[inline(always)]
pub(super) fn distinct_sides(same: usize) -> u8 {
    (0..3).fold(0xFF, |m, a| {
        m & (SIDES_DOWN[a] | 0u8.wrapping_sub(u8::from(same >> a & 1 == 0)))
    })
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// The corners of octant `o` of a leaf cell of value `value` when the leaf cells `around`
    /// its outer corner (side `n` of the corner; [`Sampler::nudges`]' `same` axes repeat a side)
    /// are not all of the octant's level: the rest of [`Self::corners_gathered`]. `near` is a
    /// leaf cell already located and its kd-tree leaf's box. `None` where a cell involved is not
    /// covered by any brick.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn corners_mixed<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        value: f32,
        (up, same): ([bool; 3], usize),
        around: &[Option<LeafCell>; 8],
        near: Option<(LeafCell, IBox)>,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let Octant { level, cell, .. } = *o;
        let grid = self.grid();
        let s = grid.scale(level);
        let ext = grid.extent();
        // Position `k` is the cell's neighbour on the octant's side of every axis `a` whose bit
        // is set in `k`; side `n` of the outer corner lies in position `n ^ down`.
        let down = (0..3).fold(0usize, |m, a| m | usize::from(!up[a]) << a);
        let domain = IBox::new([0; 3], ext);
        let own = grid.finest_box(level, cell);
        // Position `k`'s located leaf cell; a set bit of `same` is an axis where the outer
        // corner lies on the domain's face (no position beyond it).
        let cell_at = |k: usize| around[k ^ down].filter(|_| k & same == 0);
        let step = axes(|a| if up[a] { s[a] } else { -s[a] });
        // Per position: its cell's kd-tree leaf's box, and its cell's level and value when the
        // cell covers the whole position.
        let mut boxes = [IBox::default(); 8];
        let mut whole = 0u8;
        let mut whole_level = [0u32; 8];
        let mut whole_value = [0f32; 8];
        // The kd-tree leaf whose box was found last: neighbouring positions often share one.
        let mut last = near.map(|(n, nb)| (n.leaf, nb));
        for k in 0..8 {
            let Some(c) = cell_at(k) else {
                continue;
            };
            let b = IBox::new(
                axes(|a| own.lo[a] + step[a] * (k >> a & 1) as i64),
                axes(|a| own.hi[a] + step[a] * (k >> a & 1) as i64),
            );
            let leaf_box = match last {
                Some((leaf, lb)) if leaf == c.leaf => lb,
                _ => {
                    let lb = self.read_box(c.leaf);
                    last = Some((c.leaf, lb));
                    lb
                }
            };
            boxes[k] = leaf_box;
            if c.level <= level && leaf_box.contains_box(&b.intersect(&domain)) {
                whole |= 1 << k;
                (whole_level[k], whole_value[k]) = (c.level, c.value);
            }
        }
        let position = |k: usize| {
            cell_at(k).map(|cell| Position {
                cell,
                whole: whole >> k & 1 == 1,
                leaf_box: boxes[k],
            })
        };
        let (base, _) = self.octant_box(o);
        let mut axis = [Axis::default(); 3];
        for (a, ax) in axis.iter_mut().enumerate() {
            for i in 0..4 {
                let x = base[a] + (i >> 1) as i64 * s[a];
                let f = if i & 1 == 0 { x - 1 } else { x }.div_euclid(2);
                let f = f.clamp(0, ext[a] - 1);
                ax.at[i] = f;
                ax.out[i] = usize::from((f < own.lo[a]) | (f >= own.hi[a])) << a;
            }
        }
        // The table, entry `x + 4 y + 16 z`: each finest cell's leaf-cell value and level (for a
        // cell read or located, its own; for the others, their whole position's), and, bit per
        // entry, whether the cell was read or located rather than its position's and whether its
        // level is coarser than the octant's.
        let mut levels = [0u32; 64];
        let mut values = [0f32; 64];
        let mut read = 0u64;
        let mut coarse = 0u64;
        // Per axis: the entries whose index along it is `i`.
        const SLAB: [u64; 3] = [0x1111_1111_1111_1111, 0x000F_000F_000F_000F, 0xFFFF];
        let slab = |a: usize, i: usize| SLAB[a] << (i << (2 * a));
        // Per axis and position bit: the entries whose cell along the axis lies in the own cell
        // (bit 0) or in the neighbour (bit 1), and the lowest and highest finest coordinate.
        let mut part = [[0u64; 2]; 3];
        let mut span = [[(i64::MAX, i64::MIN); 2]; 3];
        for (a, ax) in axis.iter().enumerate() {
            for i in 0..4 {
                let bit = usize::from(ax.out[i] != 0);
                part[a][bit] |= slab(a, i);
                span[a][bit] = (span[a][bit].0.min(ax.at[i]), span[a][bit].1.max(ax.at[i]));
            }
        }
        // The centre corner's entries are never read.
        let centre = !(0..3).fold(u64::MAX, |m, a| {
            let side = down >> a & 1;
            m & (slab(a, 2 * side) | slab(a, 2 * side + 1))
        });
        // The entries of position `k`.
        let entries_of = |k: usize| part[0][k & 1] & part[1][k >> 1 & 1] & part[2][k >> 2 & 1];
        // Every entry first takes its position's cell's value and level when that cell covers
        // the whole position (coarser levels are marked in `coarse` below); the entries of the
        // other positions are read or located below. A row along x holds two positions: `k`
        // and, where x lies outside the own cell, `k | 1`.
        let beyond = axis[0].out.map(|kx| kx != 0);
        for (z, &kz) in axis[2].out.iter().enumerate() {
            for (y, &ky) in axis[1].out.iter().enumerate() {
                let k = (ky | kz) & 6;
                let (v0, v1) = (whole_value[k], whole_value[k | 1]);
                let (l0, l1) = (whole_level[k], whole_level[k | 1]);
                let row = 4 * y + 16 * z;
                values[row..row + 4].copy_from_slice(&beyond.map(|b| if b { v1 } else { v0 }));
                levels[row..row + 4].copy_from_slice(&beyond.map(|b| if b { l1 } else { l0 }));
            }
        }
        let mut wholes = whole;
        while wholes != 0 {
            let k = wholes.trailing_zeros() as usize;
            wholes &= wholes - 1;
            coarse |= entries_of(k) & 0u64.wrapping_sub(u64::from(whole_level[k] < level));
        }
        // The first coarser cells read or located, by entry: a stitched corner's coarse cell
        // is one of them, found again without reading it again.
        let mut coarse_read = [(usize::MAX, NO_CELL); 4];
        let mut num_coarse_read = 0;
        let mut partial = !whole;
        while partial != 0 {
            let k = partial.trailing_zeros() as usize;
            partial &= partial - 1;
            let p = position(k);
            let mut mask = entries_of(k) & centre;
            read |= mask;
            // The position's kd-tree leaf, when it holds all the position's cells.
            let leaf = p.map_or(u32::MAX, |p| {
                let r: [usize; 3] = axes(|a| k >> a & 1);
                let lo = axes(|a| span[a][r[a]].0);
                let hi = axes(|a| span[a][r[a]].1);
                if holds(&p.leaf_box, lo) & holds(&p.leaf_box, hi) {
                    p.cell.leaf
                } else {
                    u32::MAX
                }
            });
            // A leaf coarser than the octant: its cells are read whole, to be remembered.
            let coarse_leaf = p.is_some_and(|p| p.cell.level < level);
            while mask != 0 {
                let e = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                // Both nudges of a face may meet one finest cell: read again, the same answer.
                let (x, y, z) = (e & 3, e >> 2 & 3, e >> 4);
                let f = [axis[0].at[x], axis[1].at[y], axis[2].at[z]];
                let c = if leaf == u32::MAX {
                    None
                } else if coarse_leaf {
                    self.cell_in_leaf_numbered(leaf, f)
                } else if let Some(v) = self.value_in_leaf(leaf, f) {
                    // Of the leaf's level, which is not coarser than the octant's.
                    (levels[e], values[e]) = (p.map_or(0, |p| p.cell.level), v);
                    continue;
                } else {
                    None
                };
                let c = match c {
                    Some(c) => c,
                    None => match self.position_cell(
                        loc,
                        p.as_ref(),
                        near.as_ref(),
                        f,
                        &mut memo.hints,
                    )? {
                        Some(c) => c,
                        None => return Ok(None),
                    },
                };
                (levels[e], values[e]) = (c.level, c.value);
                if c.level < level {
                    coarse |= 1 << e;
                    if num_coarse_read < coarse_read.len() {
                        coarse_read[num_coarse_read] = (e, c);
                        num_coarse_read += 1;
                    }
                }
            }
        }
        // Side `i` of corner `n` is table entry `corner(n) + side_step(i)`.
        let corner = |n: usize| (n & 1) * 2 + (n >> 1 & 1) * 8 + (n >> 2 & 1) * 32;
        let side_step = |i: usize| (i & 1) + (i >> 1 & 1) * 4 + (i >> 2 & 1) * 16;
        let mut out = [0f32; 8];
        if coarse == 0 {
            // No corner is stitched.
            for (n, slot) in out.iter_mut().enumerate() {
                // The corner at the cell centre carries the cell's value.
                *slot = if n == down {
                    value
                } else {
                    avg8(&std::array::from_fn(|i| values[corner(n) + side_step(i)]))
                };
            }
            return Ok(Some(out));
        }
        // The stitch memory, made in place (about 1.3 KB) when the first stitched corner needs
        // it.
        let mut stitches = None::<Stitches>;
        for (n, slot) in out.iter_mut().enumerate() {
            if n == down {
                // The corner at the cell centre carries the cell's value.
                *slot = value;
                continue;
            }
            let entry = |i: usize| corner(n) + side_step(i);
            // The corner's eight entries: bits 0, 1, 4, 5, 16, 17, 20 and 21 from `corner(n)`.
            *slot = if coarse >> corner(n) & 0x0033_0033 != 0 {
                let v = axes(|a| base[a] + (n >> a & 1) as i64 * s[a]);
                let lv: [u32; 8] = std::array::from_fn(|i| levels[entry(i)]);
                let coarsest = lv.iter().copied().fold(u32::MAX, u32::min);
                let side = lv.iter().position(|&l| l == coarsest).unwrap_or(0);
                let e = entry(side);
                let (x, y, z) = (e & 3, e >> 2 & 3, e >> 4);
                let k = axis[0].out[x] | axis[1].out[y] | axis[2].out[z];
                let q = if read >> e & 1 == 0 {
                    cell_at(k)
                } else if let Some(&(_, c)) =
                    coarse_read[..num_coarse_read].iter().find(|(i, _)| *i == e)
                {
                    Some(c)
                } else {
                    // The cell read or located for the entry: the same answer again.
                    let f = [axis[0].at[x], axis[1].at[y], axis[2].at[z]];
                    self.position_cell(
                        loc,
                        position(k).as_ref(),
                        near.as_ref(),
                        f,
                        &mut memo.hints,
                    )?
                };
                let Some(q) = q else {
                    return Ok(None);
                };
                match self.stitched_corner(
                    loc,
                    v,
                    (&q, side),
                    || std::array::from_fn(|i| values[entry(i)]),
                    &mut stitches,
                    near,
                    memo,
                )? {
                    Some(x) => x,
                    None => return Ok(None),
                }
            } else {
                avg8(&std::array::from_fn(|i| values[entry(i)]))
            };
        }
        Ok(Some(out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `sides_in` gives the sides whose finest cell lies in the box, for every placement
    /// of the two nudges against a box's faces on every axis.
    #[test]
    fn sides_in_are_the_sides_in_the_box() {
        let b = IBox::new([2, 5, -3], [4, 9, 1]);
        let near = |a: usize| {
            [
                b.lo[a] - 2,
                b.lo[a] - 1,
                b.lo[a],
                b.hi[a] - 1,
                b.hi[a],
                b.hi[a] + 1,
            ]
        };
        for x in near(0) {
            for y in near(1) {
                for z in near(2) {
                    for same in 0..8usize {
                        let lo = [x, y, z];
                        let hi = axes(|a| lo[a] + i64::from(same >> a & 1 == 0));
                        let expected = (0..8).fold(0u8, |m, n| {
                            let f = axes(|a| if n >> a & 1 == 1 { hi[a] } else { lo[a] });
                            m | u8::from(b.contains_cell(f)) << n
                        });
                        assert_eq!(sides_in(&b, lo, hi), expected, "{lo:?} {hi:?}");
                    }
                }
            }
        }
    }
}
