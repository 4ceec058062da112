//! Octant corners next to other levels, from one table of the leaf cells they read.
//!
//! Every corner of an octant but the cell centre is the value at a vertex computed from the eight
//! finest cells the vertex is nudged into. Per axis those cells lie at four finest-level
//! coordinates (the two faces of the octant's box, nudged toward `-` and toward `+`), so all the
//! corners read from one 4x4x4 table of finest cells, each cell used by exactly one corner. The
//! table is filled kd-tree leaf by kd-tree leaf: the entries in a leaf's box are read at once
//! from its finest brick (which holds every cell of the leaf), by one index part per axis and
//! coordinate. The corners then follow from the table in [`Sampler::vertex_value_in`]'s order
//! and operations, so the values are its values bit for bit.

use amr_format::IBox;

use crate::error::Result;

use super::grid::axes;
use super::interp::avg8;
use super::sampler::{LeafCell, Locate, Octant, Sampler, VertexMemo};
use super::stitch::Stitches;

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

/// Per axis: the table entries whose index along it is `i` (entry `x + 4 y + 16 z`), for
/// `i = 0` (shifted by `i << 2 a` for the others).
const SLAB: [u64; 3] = [0x1111_1111_1111_1111, 0x000F_000F_000F_000F, 0xFFFF];

/// The entries whose index along axis `a` is `i`.
#[inline(always)]
const fn slab(a: usize, i: usize) -> u64 {
    SLAB[a] << (i << (2 * a))
}

/// Per axis and 4-bit set of indices along it: the entries whose index along the axis is in
/// the set.
const ALONG: [[u64; 16]; 3] = {
    let mut t = [[0u64; 16]; 3];
    let mut a = 0;
    while a < 3 {
        let mut set = 0;
        while set < 16 {
            let mut i = 0;
            while i < 4 {
                if set >> i & 1 == 1 {
                    t[a][set] |= slab(a, i);
                }
                i += 1;
            }
            set += 1;
        }
        a += 1;
    }
    t
};

/// The table's finest coordinates: per axis, per index `2 * face + dir` along it (in
/// increasing order).
type Coords = [[i64; 4]; 3];

/// The table entries whose finest cell lies in box `b`: per axis the coordinates are in
/// increasing order, so those in the box are the indices from the number below `b.lo` to the
/// number below `b.hi`.
#[inline(always)]
fn entries_in(b: &IBox, at: &Coords) -> u64 {
    let mut m = u64::MAX;
    for a in 0..3 {
        let c = &at[a];
        let below = |x: i64| {
            usize::from(c[0] < x)
                + usize::from(c[1] < x)
                + usize::from(c[2] < x)
                + usize::from(c[3] < x)
        };
        let set = (1usize << below(b.hi[a])) - (1usize << below(b.lo[a]));
        m &= ALONG[a][set & 15];
    }
    m
}

/// The kd-tree leaves an octant's table was filled from: per leaf its box, its level and the
/// entries it filled.
struct Met {
    leaves: [(u32, IBox); 8],
    level: [u32; 8],
    entries: [u64; 8],
    len: usize,
}

impl Met {
    /// Remembers leaf `leaf` (box `b`), if there is room; its index or `None`.
    #[inline(always)]
    fn add(&mut self, leaf: u32, b: IBox) -> Option<usize> {
        let i = self.len;
        if i < self.leaves.len() {
            self.leaves[i] = (leaf, b);
            self.entries[i] = 0;
            self.level[i] = u32::MAX;
            self.len += 1;
            return Some(i);
        }
        None
    }
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// Fills entries `take` of `values`, whose finest cells (coordinates `at`) all lie in kd-tree
    /// leaf `leaf`, from the leaf's finest brick: one index part per axis and coordinate, the
    /// sum of three per entry when read in place, else cell by cell. The leaf's level, or
    /// `None` where the leaf is not covered by any brick.
    #[inline(always)]
    fn fill_from_leaf(
        &self,
        leaf: u32,
        take: u64,
        at: &Coords,
        values: &mut [f32; 64],
    ) -> Result<Option<u32>> {
        let mut m = take;
        let mut level = None;
        if let Some((brick, leaf_level, parts)) = self.leaf_table_parts(leaf, at) {
            level = Some(leaf_level);
            while m != 0 {
                let e = m.trailing_zeros() as usize;
                let i = parts[0][e & 3] + parts[1][e >> 2 & 3] + parts[2][e >> 4];
                let Some(&v) = brick.get(i as usize) else {
                    break;
                };
                m &= m - 1;
                values[e] = v;
            }
        }
        // A brick decoded through the cache (or not holding the cell): cell by cell.
        while m != 0 {
            let e = m.trailing_zeros() as usize;
            m &= m - 1;
            let f = [at[0][e & 3], at[1][e >> 2 & 3], at[2][e >> 4]];
            let Some(c) = self.leaf_cell(leaf, f)? else {
                return Ok(None);
            };
            values[e] = c.value;
            level = Some(c.level);
        }
        Ok(level)
    }

    /// The corners of octant `o` of a leaf cell of value `value` when the leaf cells `around`
    /// its outer corner (side `n` of the corner; [`Sampler::nudges`]' `same` axes repeat a side)
    /// are not all of the octant's level: the rest of [`Self::corners_gathered`]. `near` is a
    /// leaf cell already located and its kd-tree leaf's box. `None` where a cell involved is not
    /// covered by any brick.
    ///
    /// The table is filled kd-tree leaf by kd-tree leaf: first `near`'s leaf and the leaves of
    /// `around`, then, while entries are left, the leaf located at the first of them. Each leaf
    /// fills at once every entry left in its box.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn corners_mixed<L: Locate>(
        &self,
        loc: &L,
        o: &Octant,
        value: f32,
        (up, _same): ([bool; 3], usize),
        around: &[Option<LeafCell>; 8],
        near: Option<(LeafCell, IBox)>,
        memo: &mut VertexMemo,
    ) -> Result<Option<[f32; 8]>> {
        let level = o.level;
        let grid = self.grid();
        let s = grid.scale(level);
        let ext = grid.extent();
        // The corner at the cell centre.
        let down = (0..3).fold(0usize, |m, a| m | usize::from(!up[a]) << a);
        let (base, _) = self.octant_box(o);
        let mut at: Coords = [[0; 4]; 3];
        for (a, at) in at.iter_mut().enumerate() {
            for (i, f) in at.iter_mut().enumerate() {
                let x = base[a] + (i >> 1) as i64 * s[a];
                *f = if i & 1 == 0 { x - 1 } else { x }
                    .div_euclid(2)
                    .clamp(0, ext[a] - 1);
            }
        }
        // Side `i` of corner `n` is table entry `corner(n) + side_step(i)`.
        let corner = |n: usize| (n & 1) * 2 + (n >> 1 & 1) * 8 + (n >> 2 & 1) * 32;
        let side_step = |i: usize| (i & 1) + (i >> 1 & 1) * 4 + (i >> 2 & 1) * 16;
        // The centre corner's entries are never read.
        let mut todo = !(0..3).fold(u64::MAX, |m, a| {
            let side = down >> a & 1;
            m & (slab(a, 2 * side) | slab(a, 2 * side + 1))
        });
        let mut values = [0f32; 64];
        let mut met = Met {
            leaves: [(0, IBox::default()); 8],
            level: [0; 8],
            entries: [0; 8],
            len: 0,
        };
        // Entries filled from no leaf remembered (the leaves met were too many): their level.
        let mut extra = [0u32; 64];
        let mut extra_entries = 0u64;
        let seeds = near
            .map(|(c, b)| (c.leaf, Some(b)))
            .into_iter()
            .chain(around.iter().flatten().map(|c| (c.leaf, None)));
        for (leaf, leaf_box) in seeds {
            if todo == 0 {
                break;
            }
            if met.leaves[..met.len].iter().any(|(l, _)| *l == leaf) {
                continue;
            }
            let b = leaf_box.unwrap_or_else(|| self.leaf_box(leaf));
            let Some(i) = met.add(leaf, b) else {
                break;
            };
            let take = entries_in(&b, &at) & todo;
            if take != 0 {
                let Some(l) = self.fill_from_leaf(leaf, take, &at, &mut values)? else {
                    return Ok(None);
                };
                (met.level[i], met.entries[i]) = (l, take);
                todo &= !take;
            }
        }
        while todo != 0 {
            let e = todo.trailing_zeros() as usize;
            let f = [at[0][e & 3], at[1][e >> 2 & 3], at[2][e >> 4]];
            let Some(c) = loc.locate_cell(f)? else {
                return Ok(None);
            };
            values[e] = c.value;
            let b = self.leaf_box(c.leaf);
            let take = entries_in(&b, &at) & todo & !(1 << e);
            todo &= !(take | 1 << e);
            if take != 0
                && self
                    .fill_from_leaf(c.leaf, take, &at, &mut values)?
                    .is_none()
            {
                return Ok(None);
            }
            match met.add(c.leaf, b) {
                Some(i) => (met.level[i], met.entries[i]) = (c.level, take | 1 << e),
                None => {
                    let mut m = take | 1 << e;
                    extra_entries |= m;
                    while m != 0 {
                        extra[m.trailing_zeros() as usize] = c.level;
                        m &= m - 1;
                    }
                }
            }
        }
        let mut coarse = 0u64;
        for i in 0..met.len {
            coarse |= met.entries[i] & 0u64.wrapping_sub(u64::from(met.level[i] < level));
        }
        let mut m = extra_entries;
        while m != 0 {
            let e = m.trailing_zeros() as usize;
            m &= m - 1;
            coarse |= u64::from(extra[e] < level) << e;
        }
        // The level of entry `e` and the leaf it was read from.
        let level_of = |e: usize| -> (u32, u32) {
            match (0..met.len).find(|&i| met.entries[i] >> e & 1 == 1) {
                Some(i) => (met.level[i], met.leaves[i].0),
                None => (extra[e], u32::MAX),
            }
        };
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
        // The stitch memory, made in place (about 1.3 KB) once some corner is known stitched,
        // knowing the leaves the table met.
        let mut stitches = Stitches::new();
        if let Some((c, b)) = near {
            stitches.add_leaf(c.leaf, b);
        }
        for (n, slot) in out.iter_mut().enumerate() {
            if n == down {
                // The corner at the cell centre carries the cell's value.
                *slot = value;
                continue;
            }
            let entry = |i: usize| corner(n) + side_step(i);
            // The corner's eight entries: bits 0, 1, 4, 5, 16, 17, 20 and 21 from `corner(n)`.
            *slot = if coarse >> corner(n) & 0x0033_0033 != 0 {
                let lv: [u32; 8] = std::array::from_fn(|i| level_of(entry(i)).0);
                let coarsest = lv.iter().copied().fold(u32::MAX, u32::min);
                let v = axes(|a| base[a] + (n >> a & 1) as i64 * s[a]);
                let side = lv.iter().position(|&l| l == coarsest).unwrap_or(0);
                let e = entry(side);
                let f = [at[0][e & 3], at[1][e >> 2 & 3], at[2][e >> 4]];
                // The leaf cell of the entry, read again from its leaf (or located): the same
                // answer.
                let q = match level_of(e).1 {
                    u32::MAX => loc.locate_cell(f)?,
                    leaf => self.leaf_cell(leaf, f)?,
                };
                let Some(q) = q else {
                    return Ok(None);
                };
                let octant = self.octant_toward(v, &q, side);
                if self.bounded() {
                    // A corner of the coarse octant: the interpolant there is that corner's
                    // value (`lerp` at 0 and 1 keeps an operand, exactly when it is not zero),
                    // the value at `v` seen from `q`'s level, which is the coarsest around `v`:
                    // the `avg8` of the corner's own entries.
                    let (olo, ohi) = self.octant_box(&Octant {
                        level: q.level,
                        cell: q.cell,
                        octant,
                    });
                    if (0..3).all(|a| (v[a] == olo[a]) | (v[a] == ohi[a])) {
                        let x = avg8(&std::array::from_fn(|i| values[entry(i)]));
                        if x != 0.0 {
                            stitches.add_vertex(v, q.level, Some(x));
                            *slot = x;
                            continue;
                        }
                    }
                }
                match self.stitched_value(loc, v, &q, octant, &mut stitches, memo)? {
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
