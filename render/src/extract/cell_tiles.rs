//! Classified, settled cells of each level kept a tile at a time, so that the neighbourhoods of
//! small leaves are copied rather than filled from the leaves around them.
//!
//! A cell's kind and bound depend on the cell alone, not on the box filled, and so does the
//! bound its settling gives (the coarse leaf cell holding its lowest corner, and the bound
//! around that cell). A tile of [`TILE`]`^3` cells of one level is filled from the leaves
//! overlapping it ([`Neighbourhood::fill_region`]) once; every neighbourhood of that level
//! overlapping the tile then copies its cells, after settling ([`settle_in`]) those of its
//! box inside coarser leaf cells in the tile, where they stay settled for the next ones. Without
//! tiles, each of the about 100 leaves around a small leaf's neighbourhood was visited again by
//! every neighbourhood holding part of it, and each coarse cell settled again in each.
//!
//! Each worker thread keeps its own tiles, [`SLOTS`] in sets of [`WAYS`], behind one lock that
//! only its thread takes, once per neighbourhood: a tile two threads need is filled by each, but
//! no thread writes the cache lines another reads (every request writes its set's use marks, and
//! a fill the tile's cells; shared sets cost `tiny` about a sixth of its two-thread extraction,
//! see `docs/benchmarks-extract.md`, `tinypar2`), and the memory is bounded. A set pushes
//! out its least recently used tile, which is filled again when asked, with the same cells;
//! the leaves come in kd-tree order, so the tiles in use are few and near each other, and a few
//! hundred tiles kept by use miss about as seldom as thousands placed by a hash alone.

use std::sync::Mutex;

use amr_format::IBox;

use super::band::AroundMemo;
use super::blocks::level_box;
use super::cull::{settle_in, Shared};
use super::leaf_tree::Met;
use super::local::Neighbourhood;
use crate::error::Result;
use crate::reconstruct::{Sampler, VertexMemo};

/// log2 of [`TILE`].
const TILE_SHIFT: u32 = 3;
/// Cells per axis of a tile.
pub const TILE: i64 = 1 << TILE_SHIFT;
/// How many times the leaves' own cells their neighbourhoods must hold for the tiles to pay
/// ([`CellTiles::pays`]): measured break-even is near 3 (files whose neighbourhoods hold 2.6 to
/// 2.9 times their cells extract about as fast either way, 4.2 and more faster with tiles).
const OVERLAP_PAYS: f64 = 3.2;
/// Tiles kept per worker thread, at most (about 6 KB each). Few enough that the tiles reuse
/// their memory: every page first touched costs a fault that, on the small boxes tiles are for,
/// outweighs refilling a cheap tile pushed out; enough that the tiles of coarse levels, whose
/// fills gather many finer leaves, are seldom pushed out by the finer ones passing
/// (`docs/benchmarks-extract.md`, "Tile slots" and `tiny11`).
const SLOTS: usize = 256;
/// Tiles of a set: a tile may be kept in any of them.
const WAYS: usize = 8;

/// Sets of tiles a thread keeps.
const SETS: usize = SLOTS / WAYS;

/// The tiles of every level of one field.
pub struct CellTiles {
    /// Per worker thread, its tiles; a caller outside the pool shares the first thread's.
    threads: Box<[OwnLines<Mutex<ThreadTiles>>]>,
}

impl Default for CellTiles {
    fn default() -> Self {
        Self {
            threads: (0..rayon::current_num_threads().max(1))
                .map(|_| OwnLines::default())
                .collect(),
        }
    }
}

/// One thread's tiles.
#[derive(Default)]
struct ThreadTiles {
    /// [`SETS`] sets of tiles, made on first use.
    sets: Vec<TileSet>,
    /// The leaves met by the tile being filled: one list for all the thread's fills.
    touching: Vec<Met>,
}

/// A value on cache lines of its own (128 bytes: a line and the one prefetched with it), so that
/// the lock of one thread's tiles never shares a line with another thread's.
#[derive(Default)]
#[repr(align(128))]
struct OwnLines<T>(T);

impl CellTiles {
    /// True when the neighbourhoods of the leaves with data (each leaf's box grown by one cell)
    /// hold at least [`OVERLAP_PAYS`] times the leaves' own cells: they overlap enough that
    /// classifying each cell once, in tiles, costs less than filling each neighbourhood from
    /// the leaves around it. A leaf of `4^3` cells has a neighbourhood of `6^3`, 3.4 times its
    /// cells; one of `8^3`, 2.0 times. The ratio follows the leaves where the cost is, not the
    /// boxes of the file: a level joined into large bricks whose kd leaves stay small (where
    /// finer levels cut them) keeps its tiles, and a few small leaves among large ones, where a
    /// tile serves one neighbourhood, do not turn them on (`docs/benchmarks-extract.md`,
    /// `pieces` and `join`).
    pub fn pays<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>) -> bool {
        let grid = sampler.grid();
        let (mut own, mut around) = (0u64, 0u64);
        for leaf in 0..sampler.file().num_leaves() as u32 {
            let Some((_, level)) = sampler.leaf_top(leaf) else {
                continue;
            };
            let cells = level_box(grid, level, &sampler.leaf_box(leaf));
            own = own.saturating_add(cells.num_cells().unwrap_or(0));
            around = around.saturating_add(cells.grow([1; 3]).num_cells().unwrap_or(0));
        }
        own > 0 && around as f64 >= OVERLAP_PAYS * own as f64
    }

    /// A range holding the bounds of the level-`level` cells of box `g` once settled (the
    /// union of [`Neighbourhood::range_in`] after [`settle_in`] of `g`), read from the tiles.
    pub fn range_in<D: AsRef<[u8]>>(
        &self,
        sources: (&Sampler<'_, D>, Shared<'_>),
        locs: Memos<'_>,
        level: u32,
        g: IBox,
    ) -> Result<(f32, f32)> {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        self.each_tile(sources, locs, level, g, |tile, part| {
            let (a, b) = tile.range_in(part);
            // Comparisons, not f32::min, as `range_in` does.
            if a < lo {
                lo = a;
            }
            if b > hi {
                hi = b;
            }
        })?;
        Ok((lo, hi))
    }

    /// Fills `hood` with the level-`level` cells of box `g`, settled, copied from the tiles
    /// holding them: what a fill and [`settle_in`] of `g` give.
    pub fn fill<D: AsRef<[u8]>>(
        &self,
        sources: (&Sampler<'_, D>, Shared<'_>),
        hood: &mut Neighbourhood,
        locs: Memos<'_>,
        level: u32,
        g: IBox,
    ) -> Result<()> {
        hood.begin_copies(level, g);
        self.each_tile(sources, locs, level, g, |tile, _| {
            hood.copy_tile(tile);
            hood.copy_mixed(tile);
        })?;
        hood.end_copies();
        Ok(())
    }

    /// Calls `f` with each tile overlapping level-`level` box `g` and the part of `g` inside
    /// it, after settling that part; a tile is filled on first need.
    fn each_tile<D: AsRef<[u8]>>(
        &self,
        sources: (&Sampler<'_, D>, Shared<'_>),
        (memo, near): Memos<'_>,
        level: u32,
        g: IBox,
        mut f: impl FnMut(&Neighbourhood, &IBox),
    ) -> Result<()> {
        let i = rayon::current_thread_index().map_or(0, |i| i % self.threads.len());
        let mut own = self.threads[i].0.lock().unwrap_or_else(|e| e.into_inner());
        let ThreadTiles { sets, touching } = &mut *own;
        if sets.is_empty() {
            sets.resize_with(SETS, TileSet::default);
        }
        let o = tile_origin(level, sources.0.grid().num_levels());
        let tiles = IBox::new(
            g.lo.map(|v| (v + o) >> TILE_SHIFT),
            g.hi.map(|v| (v + o + TILE - 1) >> TILE_SHIFT),
        );
        for tz in tiles.lo[2]..tiles.hi[2] {
            for ty in tiles.lo[1]..tiles.hi[1] {
                for tx in tiles.lo[0]..tiles.hi[0] {
                    let t = [tx, ty, tz];
                    let cells = IBox::new(t.map(|v| v * TILE - o), t.map(|v| (v + 1) * TILE - o));
                    let key = TileKey::new(level, t);
                    let set = &mut sets[key.set(SETS)];
                    let tile = match set.find(&key) {
                        Some(tile) => tile,
                        None => {
                            let tile = set.evict();
                            let sources = (sources.0, sources.1.leaves);
                            tile.fill_region_using(sources, level, cells, touching)?;
                            set.keep(key)
                        }
                    };
                    debug_assert!(tile.holds(level, &cells), "a tile kept under another key");
                    let part = g.intersect(&cells);
                    if tile.has_pending() {
                        settle_in(sources, tile, (&mut *memo, &mut *near), (&part, false))?;
                    }
                    f(tile, &part);
                }
            }
        }
        Ok(())
    }
}

/// How many cells below a multiple of [`TILE`] the tiles of level `level` (of `levels`) start:
/// tile `t` holds cells `t * TILE - origin .. (t + 1) * TILE - origin` along each axis.
///
/// The finest level's tiles start at multiples of [`TILE`]: its leaves start at even cells, so
/// their grown boxes cut few tiles at all six faces. The coarser levels' tiles start one cell
/// lower, where the grown boxes of leaves at multiples of [`TILE`] start: a coarse tile's fill
/// gathers many finer leaves, and the neighbourhoods then meet fewer tiles, so fewer are
/// filled (`tiny` iso 6: -3.5 % instructions; `docs/benchmarks-extract.md`, `tiny14` and
/// `tiny16`). Any origin gives the same cells; only the work differs.
#[inline]
fn tile_origin(level: u32, levels: usize) -> i64 {
    i64::from((level as usize) + 1 < levels)
}

/// The memos settling reads through.
pub type Memos<'a> = (&'a mut VertexMemo, &'a mut AroundMemo);

/// The level of a tile and its place among the tiles of that level (its lowest cell plus
/// [`tile_origin`], over [`TILE`]), with a hash of them.
#[derive(Clone, Copy, PartialEq, Eq)]
struct TileKey {
    /// A hash of the level and place, never 0.
    hash: u64,
    level: u32,
    t: [i64; 3],
}

impl TileKey {
    fn new(level: u32, t: [i64; 3]) -> Self {
        let h = (t[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (t[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (t[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
            ^ u64::from(level).wrapping_mul(0x27D4_EB2F_1656_67C5);
        Self {
            hash: h | 1,
            level,
            t,
        }
    }

    /// The set of this tile among `sets`.
    #[inline]
    fn set(&self, sets: usize) -> usize {
        (self.hash >> 40) as usize % sets
    }
}

/// The tiles of one set: [`WAYS`] tiles, the key of each and when it was last asked for.
#[derive(Default)]
struct TileSet {
    tiles: [Neighbourhood; WAYS],
    /// The hash of each tile's key, 0 while it holds no complete fill: compared first.
    hashes: [u64; WAYS],
    /// The key of each tile (meaningful where its hash is not 0).
    keys: [Option<TileKey>; WAYS],
    /// The value of [`Self::clock`] when each tile was last asked for.
    used: [u64; WAYS],
    /// Requests so far.
    clock: u64,
    /// The tile [`Self::evict`] chose.
    victim: usize,
}

impl TileSet {
    /// The tile kept under `key`, marked as the most recently used.
    #[inline]
    fn find(&mut self, key: &TileKey) -> Option<&mut Neighbourhood> {
        let w = (0..WAYS)
            .find(|&w| self.hashes[w] == key.hash && self.keys[w].as_ref() == Some(key))?;
        self.clock += 1;
        self.used[w] = self.clock;
        Some(&mut self.tiles[w])
    }

    /// The least recently used tile (an unused one first), its key forgotten until
    /// [`Self::keep`], so that a fill that fails leaves no tile under a key.
    fn evict(&mut self) -> &mut Neighbourhood {
        let w = (0..WAYS).min_by_key(|&w| self.used[w]).unwrap_or(0);
        self.hashes[w] = 0;
        self.keys[w] = None;
        self.victim = w;
        &mut self.tiles[w]
    }

    /// Keeps the tile [`Self::evict`] chose, now filled, under `key`.
    fn keep(&mut self, key: TileKey) -> &mut Neighbourhood {
        let w = self.victim;
        self.hashes[w] = key.hash;
        self.keys[w] = Some(key);
        self.clock += 1;
        self.used[w] = self.clock;
        &mut self.tiles[w]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A set keeps the tiles asked for last: a full set pushes out the one asked for least
    /// recently, and a tile whose fill failed is kept under no key.
    #[test]
    fn a_set_pushes_out_its_least_recently_used_tile() {
        let mut set = TileSet::default();
        let key = |x: i64| TileKey::new(3, [x, 0, 0]);
        for x in 0..WAYS as i64 {
            assert!(set.find(&key(x)).is_none());
            set.evict();
            set.keep(key(x));
        }
        // Tile 0 asked for again: tile 1 is now the least recently used.
        assert!(set.find(&key(0)).is_some());
        set.evict();
        set.keep(key(100));
        assert!(set.find(&key(1)).is_none());
        for x in [0, 2, 100] {
            assert!(set.find(&key(x)).is_some(), "tile {x}");
        }
        // An eviction not followed by a kept fill leaves its tile under no key.
        set.evict();
        assert_eq!(set.keys.iter().filter(|k| k.is_some()).count(), WAYS - 1);
        // The same place on another level is another tile.
        assert!(set.find(&TileKey::new(2, [0, 0, 0])).is_none());
    }
}
