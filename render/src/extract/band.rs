//! Value bounds around coarse leaf cells, shared by every leaf and isovalue of one field: for a
//! leaf cell `Q` of level `q`, the range of the leaf cells within one `Q`-cell of `Q`, or the fact
//! that a leaf cell coarser than `q` lies there ([`super::cull`]).
//!
//! The bound around `Q` is the union of the bounds of the 27 level-`q` cells around it, each the
//! range of the leaf cells of level `q` or finer inside the cell. Those are gathered a tile of
//! `4^3` level-`q` cells at a time, each tile once per file from one pass over the leaves
//! overlapping it (every leaf cell read once), and kept: a coarse cell next to many small leaves
//! costs a few look-ups per leaf, and no leaf gathers the leaves around it. The tiles kept are
//! bounded ([`MAX_TILES`]): past that, all are forgotten and gathered again when asked, so the
//! memory stays flat on files of any size.
//!
//! Around a cell at most [`DIRECT_SCALE`] finest cells wide, the 27 cells span a few finest
//! cells, so few leaves overlap them: the bound is then the exact range of those leaves' cells
//! there ([`LeafTree::exact_range_over`]: the same cells, so the same bound), with no tile. A
//! tile would gather 64 cells for a bound that reads 27, and small leaves' coarse neighbours
//! rarely share tiles. Where a neighbourhood being settled asks about many such cells of one
//! block of `4^3`, the block's bounds are computed together instead, from one pass over the
//! leaves around it ([`super::around_block`]), and kept in the thread's [`AroundMemo`].

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hash, Hasher};

use rustc_hash::FxHasher;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use crate::error::Result;
use amr_format::IBox;

use super::around_block::{around_block, BLOCK, BLOCK_CELLS};
use super::blocks::{level_box, BlockRanges, BLOCK as TABLE_BLOCK};
use super::leaf_tree::{LeafTree, Met};
use super::local::div_floor;
use super::tight::{pack, unpack};
use crate::reconstruct::grid::axes;
use crate::reconstruct::Sampler;

/// Folds the values of the cells `cells` (level-`fine` indices, inside the brick's cells `bc`)
/// of brick data `values` into the bounds `lo`/`hi` of the cells of grid `g` of a level whose
/// cells are `ratio` fine cells wide; cells outside `g` are ignored.
pub fn fold_cell_bounds(
    values: &[f32],
    bc: &IBox,
    cells: &IBox,
    ratio: [i64; 3],
    g: &IBox,
    (lo, hi): (&mut [f32], &mut [f32]),
) {
    if cells.is_empty() {
        return;
    }
    let e = g.extent();
    let first = axes(|a| div_floor(cells.lo[a], ratio[a]));
    if (0..3).all(|a| div_floor(cells.hi[a] - 1, ratio[a]) == first[a]) {
        // All the cells lie in one cell of `g` (a small finer leaf's part, often): one scan.
        if !g.contains_cell(first) {
            return;
        }
        let i = g.linear_index(first);
        let (mut l, mut h) = (lo[i], hi[i]);
        let w = cells.extent()[0] as usize;
        for z in cells.lo[2]..cells.hi[2] {
            for y in cells.lo[1]..cells.hi[1] {
                let src = bc.linear_index([cells.lo[0], y, z]);
                for &v in &values[src..src + w] {
                    // Comparisons, not f32::min: a NaN compares false and is left out.
                    if v < l {
                        l = v;
                    }
                    if v > h {
                        h = v;
                    }
                }
            }
        }
        (lo[i], hi[i]) = (l, h);
        return;
    }
    // The x-range of fine cells inside `g`'s cells.
    let x0 = cells.lo[0].max(g.lo[0] * ratio[0]);
    let x1 = cells.hi[0].min(g.hi[0] * ratio[0]);
    if x0 >= x1 {
        return;
    }
    for z in cells.lo[2]..cells.hi[2] {
        let gz = div_floor(z, ratio[2]) - g.lo[2];
        if !(0..e[2]).contains(&gz) {
            continue;
        }
        for y in cells.lo[1]..cells.hi[1] {
            let gy = div_floor(y, ratio[1]) - g.lo[1];
            if !(0..e[1]).contains(&gy) {
                continue;
            }
            let src = bc.linear_index([x0, y, z]);
            let row = ((gz * e[1] + gy) * e[0]) as usize;
            let mut x = x0;
            while x < x1 {
                let gx = div_floor(x, ratio[0]);
                let end = ((gx + 1) * ratio[0]).min(x1);
                let i = row + (gx - g.lo[0]) as usize;
                let (mut l, mut h) = (lo[i], hi[i]);
                for &v in &values[src + (x - x0) as usize..src + (end - x0) as usize] {
                    // Comparisons, not f32::min: a NaN compares false and is left out.
                    if v < l {
                        l = v;
                    }
                    if v > h {
                        h = v;
                    }
                }
                (lo[i], hi[i]) = (l, h);
                x = end;
            }
        }
    }
}

/// Marks a coarse cell next to a leaf cell coarser than itself (the bits of two NaNs, which no
/// packed range holds).
const NEXT_TO_COARSER: u64 = u64::MAX - 1;
/// Finest cells per axis of a level-`q` cell, at most, for the bound around it to be computed
/// from the leaves overlapping its 27 cells rather than read from tiles: the region is then a
/// few finest cells wide, so few leaves overlap it, where a tile gathers 64 cells' leaves of
/// which one bound reads 27 (tiles pay for coarse cells, whose regions hold many leaves that
/// neighbouring bounds share).
const DIRECT_SCALE: i64 = 2;
/// Block slots of an [`AroundMemo`].
const BLOCK_SLOTS: usize = 128;
/// Cells of a block about to be asked about, at least, for the block to be computed whole.
const MIN_ASKED: u32 = 4;
/// Level-`q` cells per axis of a tile.
const TILE: i64 = 4;
/// Independently locked parts of the tables, so threads rarely wait on each other.
const SHARDS: usize = 64;
/// Tiles kept at most (about 600 bytes each with the table's entry: about 10 MB). Leaves are
/// visited in kd-tree order, so the tiles in use at any time are the few around the current
/// chunk of leaves; forgetting all of them at once costs a few tiles gathered twice.
const MAX_TILES: usize = 1 << 14;

/// The sources a tile is gathered from.
pub type Sources<'a, 'f, D> = (&'a Sampler<'f, D>, &'a BlockRanges, &'a LeafTree);

/// A table key: a level and a cell (or tile) of it.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Key(u32, [i64; 3]);

impl Hash for Key {
    fn hash<H: Hasher>(&self, h: &mut H) {
        h.write_u32(self.0);
        for v in self.1 {
            h.write_i64(v);
        }
    }
}
/// A table keyed by [`Key`], cut into [`SHARDS`] locked parts.
type Table<T> = Vec<Mutex<HashMap<Key, T, BuildHasherDefault<FxHasher>>>>;

/// The bounds of the coarse cells of the tiles asked for so far, of one field.
pub struct CoarseBounds {
    /// Per tile: each cell's bound, `(NaN, NaN)` where a coarser leaf cell overlaps it.
    tiles: Table<Arc<[(f32, f32)]>>,
    /// Tiles in [`Self::tiles`], about.
    kept: AtomicUsize,
}

impl Default for CoarseBounds {
    fn default() -> Self {
        Self {
            tiles: new_table(),
            kept: AtomicUsize::new(0),
        }
    }
}

/// Slots of an [`AroundMemo`] (a power of two).
const MEMO_SLOTS: usize = 4096;

/// One thread's memo of [`CoarseBounds::range_around`] answers, which do not depend on the
/// isovalue: a coarse cell is asked about again by each small leaf next to it. Direct-mapped:
/// a slot keeps the last cell hashed to it; beside the slots, the answers for whole blocks of
/// cells computed together ([`around_block`]), a slot keeping the last block hashed to it.
pub struct AroundMemo {
    slots: Vec<(u32, [i64; 3], u64)>,
    /// Per slot (made on first need: files of tiny leaves never ask): the level and block
    /// (its lowest cell over [`BLOCK`]) and each cell's answer.
    blocks: Vec<(u32, [i64; 3], [u64; BLOCK_CELLS])>,
    /// Per slot (hashed as [`Self::blocks`]): the level, block and box of cells being settled
    /// of the last block not computed for too few cells asked about, so that they are not
    /// counted again for the next cell asked about in that block and box.
    declined: Vec<(u32, [i64; 3], IBox)>,
    /// Scratch of [`around_block`].
    touching: Vec<u32>,
}

impl Default for AroundMemo {
    fn default() -> Self {
        Self {
            slots: vec![(u32::MAX, [0; 3], 0); MEMO_SLOTS],
            blocks: Vec::new(),
            declined: Vec::new(),
            touching: Vec::new(),
        }
    }
}

impl CoarseBounds {
    /// A range holding the leaf cells within one cell of level-`level` cell `c` (absolute
    /// index); `None` when a leaf cell coarser than `level` lies there: the union of the 27
    /// cells' entries, from the tiles holding them.
    pub fn range_around<D: AsRef<[u8]>>(
        &self,
        sources: Sources<'_, '_, D>,
        level: u32,
        c: [i64; 3],
    ) -> Result<Option<(f32, f32)>> {
        let bits = self.compute_around(sources, level, c)?;
        Ok((bits != NEXT_TO_COARSER).then(|| unpack(bits)))
    }

    /// [`Self::range_around`], answered from `memo` when it holds the cell.
    ///
    /// A cell at most [`DIRECT_SCALE`] finest cells wide is answered from its block of
    /// [`BLOCK`]`^3` cells when the memo holds that, or, given `(wanted, asked)`, when
    /// `asked(block, n)` (the caller is about to ask about at least `n` cells of the block's
    /// box while settling its cells `wanted`) holds for [`MIN_ASKED`] cells: the block is then
    /// computed whole ([`around_block`]), for less than that many leaf-tree queries. A block
    /// found to hold too few is not counted again for the same `wanted`.
    pub fn range_around_memo<D: AsRef<[u8]>>(
        &self,
        sources: Sources<'_, '_, D>,
        memo: &mut AroundMemo,
        (level, c): (u32, [i64; 3]),
        wanted: Option<(&IBox, impl FnOnce(&IBox, u32) -> bool)>,
    ) -> Result<Option<(f32, f32)>> {
        let k = (hash_of(&Key(level, c)) >> 20) as usize % MEMO_SLOTS;
        let bits = if memo.slots[k].0 == level && memo.slots[k].1 == c {
            memo.slots[k].2
        } else {
            let block = match wanted {
                Some(wanted) => self.block_answer(sources, memo, (level, c), wanted)?,
                None => None,
            };
            let bits = match block {
                Some(bits) => bits,
                None => self.compute_around(sources, level, c)?,
            };
            memo.slots[k] = (level, c, bits);
            bits
        };
        Ok((bits != NEXT_TO_COARSER).then(|| unpack(bits)))
    }

    /// The packed answer for cell `c` from its block, computed if `asked` holds enough of its
    /// cells ([`Self::range_around_memo`]); `None` when the block is not computed.
    fn block_answer<D: AsRef<[u8]>>(
        &self,
        sources: Sources<'_, '_, D>,
        memo: &mut AroundMemo,
        (level, c): (u32, [i64; 3]),
        (wanted, asked): (&IBox, impl FnOnce(&IBox, u32) -> bool),
    ) -> Result<Option<u64>> {
        if sources
            .0
            .grid()
            .scale(level)
            .iter()
            .any(|&v| v > DIRECT_SCALE)
        {
            return Ok(None);
        }
        if memo.blocks.is_empty() {
            memo.blocks = vec![(u32::MAX, [0; 3], [0; BLOCK_CELLS]); BLOCK_SLOTS];
            memo.declined = vec![(u32::MAX, [0; 3], IBox::default()); BLOCK_SLOTS];
        }
        let at = c.map(|v| v.div_euclid(BLOCK));
        let cells = IBox::new(at.map(|v| v * BLOCK), at.map(|v| (v + 1) * BLOCK));
        let b = (hash_of(&Key(level, at)) >> 20) as usize % BLOCK_SLOTS;
        if !(memo.blocks[b].0 == level && memo.blocks[b].1 == at) {
            let declined = &mut memo.declined[b];
            if *declined == (level, at, *wanted) {
                return Ok(None);
            }
            if !asked(&cells, MIN_ASKED) {
                *declined = (level, at, *wanted);
                return Ok(None);
            }
            let answers = around_block(sources, level, &cells, &mut memo.touching)?;
            let bits = answers.map(|a| a.map_or(NEXT_TO_COARSER, pack));
            memo.blocks[b] = (level, at, bits);
        }
        Ok(Some(memo.blocks[b].2[cells.linear_index(c)]))
    }

    /// The packed union of the bounds of the 27 cells around `c`, or [`NEXT_TO_COARSER`]: for
    /// cells at most [`DIRECT_SCALE`] finest cells wide, the exact range of the leaf cells
    /// overlapping them (the same cells, so the same range); else from the tiles.
    fn compute_around<D: AsRef<[u8]>>(
        &self,
        sources: Sources<'_, '_, D>,
        level: u32,
        c: [i64; 3],
    ) -> Result<u64> {
        let near = IBox::new(c.map(|v| v - 1), c.map(|v| v + 2));
        let (sampler, blocks, leaves) = sources;
        let grid = sampler.grid();
        let s = grid.scale(level);
        if s.iter().all(|&v| v <= DIRECT_SCALE) {
            let o = grid.offset();
            let finest = IBox::new(
                [0, 1, 2].map(|a| near.lo[a] * s[a] - o[a]),
                [0, 1, 2].map(|a| near.hi[a] * s[a] - o[a]),
            );
            let range = leaves.exact_range_over(sampler, blocks, &finest, level)?;
            return Ok(range.map_or(NEXT_TO_COARSER, pack));
        }
        let tiles = near.coarsen([TILE; 3]);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for tz in tiles.lo[2]..tiles.hi[2] {
            for ty in tiles.lo[1]..tiles.hi[1] {
                for tx in tiles.lo[0]..tiles.hi[0] {
                    let t = [tx, ty, tz];
                    let bounds = self.tile(sources, level, t)?;
                    let tile_cells = tile_box(t);
                    let part = near.intersect(&tile_cells);
                    for z in part.lo[2]..part.hi[2] {
                        for y in part.lo[1]..part.hi[1] {
                            let row = tile_cells.linear_index([part.lo[0], y, z]);
                            let w = part.extent()[0] as usize;
                            for &(a, b) in &bounds[row..row + w] {
                                if a.is_nan() {
                                    return Ok(NEXT_TO_COARSER);
                                }
                                lo = lo.min(a);
                                hi = hi.max(b);
                            }
                        }
                    }
                }
            }
        }
        Ok(pack((lo, hi)))
    }

    /// The cell bounds of tile `t` of level `level`, gathered on first need.
    fn tile<D: AsRef<[u8]>>(
        &self,
        sources: Sources<'_, '_, D>,
        level: u32,
        t: [i64; 3],
    ) -> Result<Arc<[(f32, f32)]>> {
        let key = Key(level, t);
        let shard = &self.tiles[shard_of(&key)];
        if let Some(known) = shard.lock().ok().and_then(|m| m.get(&key).cloned()) {
            return Ok(known);
        }
        let bounds: Arc<[(f32, f32)]> = gather_tile(sources, level, &tile_box(t))?.into();
        if self.kept.fetch_add(1, Ordering::Relaxed) >= MAX_TILES {
            self.kept.store(0, Ordering::Relaxed);
            for other in &self.tiles {
                if let Ok(mut m) = other.lock() {
                    m.clear();
                    m.shrink_to_fit();
                }
            }
        }
        if let Ok(mut m) = shard.lock() {
            m.insert(key, bounds.clone());
        }
        Ok(bounds)
    }
}

/// An empty table.
fn new_table<T>() -> Table<T> {
    (0..SHARDS).map(|_| Mutex::default()).collect()
}

/// The level cells of tile `t`.
fn tile_box(t: [i64; 3]) -> IBox {
    IBox::new(t.map(|v| v * TILE), t.map(|v| (v + 1) * TILE))
}

/// Per level-`level` cell of `g` (x fastest): the range of the leaf cells of level `level` or
/// finer inside it, `(+inf, -inf)` when there are none, `(NaN, NaN)` when a coarser leaf cell
/// overlaps it. One pass over the leaves overlapping `g`, each of their cells inside `g` read
/// once, or through the block ranges where a level-`level` cell holds whole blocks.
fn gather_tile<D: AsRef<[u8]>>(
    (sampler, blocks, leaves): Sources<'_, '_, D>,
    level: u32,
    g: &IBox,
) -> Result<Vec<(f32, f32)>> {
    let grid = sampler.grid();
    let n = g.num_cells().unwrap_or(0) as usize;
    let mut lo = vec![f32::INFINITY; n];
    let mut hi = vec![f32::NEG_INFINITY; n];
    let mut coarser = vec![false; n];
    let s = grid.scale(level);
    let o = grid.offset();
    let finest = IBox::new(
        [0, 1, 2].map(|a| g.lo[a] * s[a] - o[a]),
        [0, 1, 2].map(|a| g.hi[a] * s[a] - o[a]),
    );
    // A node or leaf of leaves no coarser than `level` inside one cell adds its kept exact
    // range to that cell: the range of the same cells.
    let one_cell = |b: &IBox| {
        (0..3).all(|a| b.hi[a] - b.lo[a] <= s[a])
            && level_box(grid, level, b).num_cells() == Some(1)
    };
    let whole = |b: &IBox, coarsest: u32, _| coarsest >= level && one_cell(b);
    let mut touching = Vec::new();
    leaves.for_each_overlapping_grouped(&finest, whole, |m| touching.push(m));
    for m in touching {
        let l = match m {
            Met::Leaf(l) => l,
            Met::Node(n) => {
                let b = leaves.node_box(n);
                let (a, z) = leaves.exact_node_range(sampler, n)?;
                let i = g.linear_index(level_box(grid, level, &b).lo);
                lo[i] = lo[i].min(a);
                hi[i] = hi[i].max(z);
                continue;
            }
        };
        let leaf_box = leaves.leaf_box(l);
        let part = leaf_box.intersect(&finest);
        let Some((brick, lv)) = sampler.leaf_top(l) else {
            continue;
        };
        if part.is_empty() {
            continue;
        }
        if lv >= level && part == leaf_box && one_cell(&leaf_box) {
            let (a, z) = leaves.exact_range(sampler, l)?;
            let i = g.linear_index(level_box(grid, level, &leaf_box).lo);
            lo[i] = lo[i].min(a);
            hi[i] = hi[i].max(z);
            continue;
        }
        if lv < level {
            mark_cells(&mut coarser, g, &level_box(grid, level, &part).intersect(g));
            continue;
        }
        let bc = sampler.brick_cells(brick);
        let cells = level_box(grid, lv, &part).intersect(&bc);
        if cells.is_empty() {
            continue;
        }
        let sf = grid.scale(lv);
        let r = axes(|a| s[a] / sf[a]);
        if r.iter().all(|&v| v >= TABLE_BLOCK) {
            let over = cells.coarsen(r).intersect(g);
            for z in over.lo[2]..over.hi[2] {
                for y in over.lo[1]..over.hi[1] {
                    for x in over.lo[0]..over.hi[0] {
                        let c = [x, y, z];
                        let inside = IBox::new(axes(|a| c[a] * r[a]), axes(|a| (c[a] + 1) * r[a]))
                            .intersect(&cells);
                        let (a, b) = blocks.range_of_cells(sampler, brick, &inside)?;
                        let i = g.linear_index(c);
                        lo[i] = lo[i].min(a);
                        hi[i] = hi[i].max(b);
                    }
                }
            }
            continue;
        }
        let values = sampler.values(brick)?;
        fold_cell_bounds(&values, &bc, &cells, r, g, (&mut lo, &mut hi));
    }
    Ok((0..n)
        .map(|i| {
            if coarser[i] {
                (f32::NAN, f32::NAN)
            } else {
                (lo[i], hi[i])
            }
        })
        .collect())
}

/// The shard of key `k`.
fn shard_of(k: &Key) -> usize {
    (hash_of(k) >> 40) as usize % SHARDS
}

/// The hash of key `k`.
fn hash_of(k: &Key) -> u64 {
    let mut h = FxHasher::default();
    k.hash(&mut h);
    h.finish()
}

/// Sets the flags of the cells of box `b`, which lies inside box `within`, in `flags`: one per
/// cell of `within`, x fastest.
pub(super) fn mark_cells(flags: &mut [bool], within: &IBox, b: &IBox) {
    if b.is_empty() {
        return;
    }
    let w = b.extent()[0] as usize;
    for z in b.lo[2]..b.hi[2] {
        for y in b.lo[1]..b.hi[1] {
            let row = within.linear_index([b.lo[0], y, z]);
            flags[row..row + w].fill(true);
        }
    }
}
