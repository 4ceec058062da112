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
//! The threads share the tiles, in a direct-mapped table of [`SLOTS`] tiles per worker thread,
//! each behind its own lock: a tile is filled once whichever thread asks first (the threads
//! work on leaves far apart, so a lock is seldom contended), and the memory is bounded; a tile
//! pushed out is filled again when asked, with the same cells.

use std::sync::{Mutex, OnceLock};

use amr_format::IBox;

use super::band::AroundMemo;
use super::cull::{settle_in, Shared};
use super::leaf_tree::Met;
use super::local::Neighbourhood;
use crate::error::Result;
use crate::reconstruct::{Sampler, VertexMemo};

/// log2 of [`TILE`].
const TILE_SHIFT: u32 = 3;
/// Cells per axis of a tile.
pub const TILE: i64 = 1 << TILE_SHIFT;
/// File cells per leaf, on average, at most, for the tiles to be used.
const MAX_MEAN_CELLS: u64 = 32;
/// Tiles kept per worker thread, at most (about 7 KB each). Few enough that the tiles reuse
/// their memory: every page first touched costs a fault that, on the small boxes tiles are for,
/// outweighs refilling a tile pushed out (`docs/benchmarks-extract.md`, "Tile slots").
const SLOTS: usize = 1024;

/// The tiles of every level of one field.
pub struct CellTiles {
    /// The tiles, [`SLOTS`] per worker thread, made on first use.
    slots: OnceLock<Box<[Mutex<Neighbourhood>]>>,
    /// Per thread, the leaves met by the tile it is filling: one list for all its fills.
    touching: Vec<Mutex<Vec<Met>>>,
}

impl Default for CellTiles {
    fn default() -> Self {
        Self {
            slots: OnceLock::new(),
            touching: (0..rayon::current_num_threads() + 1)
                .map(|_| Mutex::default())
                .collect(),
        }
    }
}

impl CellTiles {
    /// True when a file of `cells` cells in `leaves` leaves has at most [`MAX_MEAN_CELLS`]
    /// cells per leaf on average: the neighbourhoods of its leaves (each grown by one cell)
    /// then overlap enough that classifying each cell once, in tiles, costs less than filling
    /// each neighbourhood from the leaves around it.
    pub fn pays(cells: u64, leaves: usize) -> bool {
        cells <= MAX_MEAN_CELLS.saturating_mul(leaves as u64)
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
        self.each_tile(sources, locs, level, g, |tile, _| hood.copy_tile(tile))?;
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
        let n = self.touching.len();
        let i = rayon::current_thread_index().map_or(0, |i| 1 + i % (n - 1).max(1));
        // The thread's list first, then one tile at a time: one order, no deadlock.
        let mut touching = self.touching[i.min(n - 1)]
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        let slots = self.slots.get_or_init(|| {
            (0..SLOTS * (n - 1).max(1))
                .map(|_| Mutex::default())
                .collect()
        });
        let tiles = IBox::new(
            g.lo.map(|v| v >> TILE_SHIFT),
            g.hi.map(|v| (v + TILE - 1) >> TILE_SHIFT),
        );
        for tz in tiles.lo[2]..tiles.hi[2] {
            for ty in tiles.lo[1]..tiles.hi[1] {
                for tx in tiles.lo[0]..tiles.hi[0] {
                    let t = [tx, ty, tz];
                    let cells = IBox::new(t.map(|v| v * TILE), t.map(|v| (v + 1) * TILE));
                    let mut tile = slots[slot_of(level, t, slots.len())]
                        .lock()
                        .unwrap_or_else(|e| e.into_inner());
                    if !tile.holds(level, &cells) {
                        let sources = (sources.0, sources.1 .1);
                        tile.fill_region_using(sources, level, cells, &mut touching)?;
                    }
                    let part = g.intersect(&cells);
                    settle_in(sources, &mut tile, (&mut *memo, &mut *near), &part)?;
                    f(&tile, &part);
                }
            }
        }
        Ok(())
    }
}

/// The memos settling reads through.
pub type Memos<'a> = (&'a mut VertexMemo, &'a mut AroundMemo);

/// The slot of tile `t` of level `level` among `slots`.
fn slot_of(level: u32, t: [i64; 3], slots: usize) -> usize {
    let h = (t[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (t[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (t[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ u64::from(level).wrapping_mul(0x27D4_EB2F_1656_67C5);
    (h >> 40) as usize % slots
}
