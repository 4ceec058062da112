//! Per-brick tables of the value ranges of blocks of cells, so that a bound over a box of a
//! brick's cells costs one entry per block instead of a scan of its cells.
//!
//! A box's range is exact: the blocks lying inside it from the table, the slabs around them
//! scanned. Files of layout version 2 store a table per brick and field (`amr_format::blocks`,
//! written while the converter streams), read in place; they also give a looser bound read
//! without touching the brick's data at all ([`BlockRanges::bound_in`]: the union of the blocks
//! a box overlaps). Files of version 1 have none: a table of `4^3` blocks is built in memory the
//! first time a box covering at least half of a small brick (at most `16^3` cells) asks; boxes
//! of other bricks are scanned.

use std::sync::OnceLock;

use amr_format::blocks::{block_ranges, blocks_per_axis};
use amr_format::{AmrkFile, IBox, RangeAccumulator};

use crate::error::Result;
use crate::reconstruct::{Grid, Sampler};

/// Cells per axis of a block of the tables built in memory (files of layout version 1).
pub const BLOCK: i64 = 4;
/// A brick gets a built table when a box asks for blocks holding at least 1/`SHARE` of its
/// cells (a smaller box is scanned: the table would read the whole brick for a small part).
const SHARE: i64 = 2;
/// Only bricks of at most this many cells get a built table: small bricks are where a leaf's
/// region spans many bricks; larger ones are scanned, keeping the tables' memory small.
const MAX_TABLE_CELLS: u64 = 16 * 16 * 16;

/// The block range tables of every brick of one field: the file's, or built on demand from
/// any thread.
pub struct BlockRanges {
    /// Cells per axis of the file's stored blocks; `None` when the tables are built.
    stored: Option<i64>,
    /// [`Self::range_in`] gives the looser [`Self::bound_in`] (stored tables only).
    loose: bool,
    /// Each brick's table, built on first need (when the file stores none).
    built: Vec<OnceLock<BlockTable>>,
}

/// One brick's built table: the `(min, max)` of each of its blocks.
type BlockTable = Box<[(f32, f32)]>;

impl BlockRanges {
    /// The tables of `file`: its stored ones, or none built yet when it has none.
    pub fn new<D: AsRef<[u8]>>(file: &AmrkFile<D>) -> Self {
        let stored = file.block_cells().map(i64::from);
        let bricks = if stored.is_some() {
            0
        } else {
            file.num_bricks()
        };
        Self {
            stored,
            loose: false,
            built: (0..bricks).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The stored tables of the same file whose [`Self::range_in`] is [`Self::bound_in`]: bounds
    /// that never read brick data. Without stored tables, ranges stay exact (and no table is
    /// built: use `self` for that).
    pub fn loose(&self) -> Self {
        Self {
            stored: self.stored,
            loose: self.stored.is_some(),
            built: Vec::new(),
        }
    }

    /// True when the file stores its tables (bounds never read brick data).
    pub fn stored(&self) -> bool {
        self.stored.is_some()
    }

    /// The exact range of the cells of brick `brick` (of level `level`) that overlap the
    /// finest-level box `part` ([`Self::bound_in`] for [`Self::loose`] tables); `(+inf, -inf)`
    /// when there are none (NaNs are left out).
    pub fn range_in<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        brick: u32,
        level: u32,
        part: &IBox,
    ) -> Result<(f32, f32)> {
        if self.loose {
            if let Some(bound) = self.bound_in(sampler, brick, level, part) {
                return Ok(bound);
            }
        }
        let grid = sampler.grid();
        let cells = level_cells(grid.scale(level), grid.offset(), part);
        self.range_of_cells(sampler, brick, &cells)
    }

    /// A range holding the cells of brick `brick` (of level `level`) that overlap the
    /// finest-level box `part`, read from the stored tables alone (the union of the blocks those
    /// cells overlap), without touching the brick's data; `None` when the file stores no tables.
    pub fn bound_in<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        brick: u32,
        level: u32,
        part: &IBox,
    ) -> Option<(f32, f32)> {
        let block = self.stored?;
        let bc = sampler.brick_cells(brick);
        let grid = sampler.grid();
        let (s, o) = (grid.scale(level), grid.offset());
        let (mut x, mut y) = (f32::INFINITY, f32::NEG_INFINITY);
        // The blocks overlapping the brick's cells that overlap `part`, of `n` per axis.
        let (mut lo, mut hi, mut n) = ([0i64; 3], [0i64; 3], [0i64; 3]);
        for a in 0..3 {
            let first = floor_div1(part.lo[a] + o[a], s[a]).max(bc.lo[a]);
            let end = floor_div1(part.hi[a] + o[a] + s[a] - 1, s[a]).min(bc.hi[a]);
            if first >= end {
                return Some((x, y));
            }
            lo[a] = floor_div1(first - bc.lo[a], block);
            hi[a] = floor_div1(end - bc.lo[a] + block - 1, block);
            n[a] = floor_div1(bc.hi[a] - bc.lo[a] + block - 1, block);
        }
        fold_stored(sampler, brick, &n, (lo, hi), (&mut x, &mut y));
        Some((x, y))
    }

    /// The exact range of the cells `cells` (indices of the brick's level) of brick `brick`;
    /// `(+inf, -inf)` when there are none (NaNs are left out).
    pub fn range_of_cells<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        brick: u32,
        cells: &IBox,
    ) -> Result<(f32, f32)> {
        let bc = sampler.brick_cells(brick);
        let cells = cells.intersect(&bc);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        if cells.is_empty() {
            return Ok((lo, hi));
        }
        // The blocks lying inside `cells` come from the table, the slabs around them are
        // scanned: the range is exact, and costs a table entry per block inside.
        let block = self.stored.unwrap_or(BLOCK);
        let inner_lo = [0, 1, 2].map(|a| (cells.lo[a] - bc.lo[a] + block - 1) / block);
        let inner_hi = [0, 1, 2].map(|a| (cells.hi[a] - bc.lo[a]) / block);
        if (0..3).any(|a| inner_lo[a] >= inner_hi[a]) {
            return Ok(scan(&sampler.values(brick)?, &bc, &cells));
        }
        if self.stored.is_none() {
            let brick_cells = bc.num_cells().unwrap_or(u64::MAX);
            let inner_cells: i64 = (0..3)
                .map(|a| (inner_hi[a] - inner_lo[a]) * BLOCK)
                .product();
            let worth_a_table = match self.built.get(brick as usize) {
                None => false,
                Some(t) if t.get().is_some() => true,
                Some(_) => {
                    brick_cells <= MAX_TABLE_CELLS && inner_cells * SHARE >= brick_cells as i64
                }
            };
            if !worth_a_table {
                return Ok(scan(&sampler.values(brick)?, &bc, &cells));
            }
        }
        let values = sampler.values(brick)?;
        let inner = IBox::new(
            [0, 1, 2].map(|a| bc.lo[a] + inner_lo[a] * block),
            [0, 1, 2].map(|a| bc.lo[a] + inner_hi[a] * block),
        );
        let mut rest = cells;
        for a in (0..3).rev() {
            for slab in [(rest.lo[a], inner.lo[a]), (inner.hi[a], rest.hi[a])] {
                if slab.0 < slab.1 {
                    let mut part = rest;
                    (part.lo[a], part.hi[a]) = slab;
                    let (x, y) = scan(&values, &bc, &part);
                    lo = lo.min(x);
                    hi = hi.max(y);
                }
            }
            (rest.lo[a], rest.hi[a]) = (inner.lo[a], inner.hi[a]);
        }
        let n = blocks_per_axis(&bc, block);
        if self.stored.is_some() {
            fold_stored(sampler, brick, &n, (inner_lo, inner_hi), (&mut lo, &mut hi));
            return Ok((lo, hi));
        }
        let slot = &self.built[brick as usize];
        let table = match slot.get() {
            Some(t) => t,
            None => slot.get_or_init(|| block_ranges(&values, &bc, BLOCK).into_boxed_slice()),
        };
        fold_blocks(&n, (inner_lo, inner_hi), |row| {
            for &(a, b) in &table[row] {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        });
        Ok((lo, hi))
    }
}

/// Folds the stored table entries of the blocks `blocks` (block indices, of `n` per axis) of
/// brick `brick` into `lo`/`hi`.
fn fold_stored<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    brick: u32,
    n: &[i64; 3],
    blocks: ([i64; 3], [i64; 3]),
    (lo, hi): (&mut f32, &mut f32),
) {
    let table = sampler
        .file()
        .block_ranges(sampler.field(), brick as usize)
        .unwrap_or_default();
    // Two entries at a time, as four lanes `[min, max, min, max]` folded into a lane-wise
    // minimum and a lane-wise maximum (of which the even lanes of the first and the odd lanes
    // of the second are kept): one vector minimum and maximum per two entries, and no
    // comparison waiting for the one before. Selects, not branches (the order of the values is
    // unpredictable) nor f32::min (stored ranges hold no NaN; a NaN would compare false and be
    // left out).
    let (mut a, mut b) = ([*lo; 4], [*hi; 4]);
    fold_blocks(n, blocks, |row| {
        let row = table.get(row).unwrap_or_default();
        let mut pairs = row.chunks_exact(2);
        for p in &mut pairs {
            let v = [
                p[0].min.get(),
                p[0].max.get(),
                p[1].min.get(),
                p[1].max.get(),
            ];
            for k in 0..4 {
                a[k] = if v[k] < a[k] { v[k] } else { a[k] };
                b[k] = if v[k] > b[k] { v[k] } else { b[k] };
            }
        }
        if let [r] = pairs.remainder() {
            let (x, y) = (r.min.get(), r.max.get());
            a[0] = if x < a[0] { x } else { a[0] };
            b[1] = if y > b[1] { y } else { b[1] };
        }
    });
    let x = if a[2] < a[0] { a[2] } else { a[0] };
    let y = if b[3] > b[1] { b[3] } else { b[1] };
    (*lo, *hi) = (x, y);
}

/// `v` divided by `d` per axis, rounded toward minus infinity (`d > 0`); a shift when `d` is a
/// power of two, as the scales of refinement ratios 2 and 4 and the block sizes are.
#[inline]
fn floor_div(v: [i64; 3], d: [i64; 3]) -> [i64; 3] {
    [
        floor_div1(v[0], d[0]),
        floor_div1(v[1], d[1]),
        floor_div1(v[2], d[2]),
    ]
}

/// [`floor_div`] on one axis.
#[inline(always)]
fn floor_div1(v: i64, d: i64) -> i64 {
    if d.count_ones() == 1 {
        v >> d.trailing_zeros()
    } else {
        v.div_euclid(d)
    }
}

/// The cells of a level whose cells are `scale` finest cells wide (the grid's index offset
/// `offset`) that overlap finest-level box `finest`: `Grid::level_box`, with shifts where it can.
#[inline]
pub fn level_cells(scale: [i64; 3], offset: [i64; 3], finest: &IBox) -> IBox {
    let (lo, hi) = (finest.lo, finest.hi);
    let end = |a: usize| hi[a] + offset[a] + scale[a] - 1;
    IBox::new(
        floor_div(
            [lo[0] + offset[0], lo[1] + offset[1], lo[2] + offset[2]],
            scale,
        ),
        floor_div([end(0), end(1), end(2)], scale),
    )
}

/// [`Grid::level_box`] through [`level_cells`]: shifts where the scale is a power of two.
#[inline]
pub fn level_box(grid: &Grid, level: u32, finest: &IBox) -> IBox {
    level_cells(grid.scale(level), grid.offset(), finest)
}

/// Calls `f` with the table index range of each x-row of the blocks `lo..hi` (block indices) of
/// a table of `n` blocks per axis.
fn fold_blocks(
    n: &[i64; 3],
    (lo, hi): ([i64; 3], [i64; 3]),
    mut f: impl FnMut(std::ops::Range<usize>),
) {
    for z in lo[2]..hi[2] {
        for y in lo[1]..hi[1] {
            let row = ((z * n[1] + y) * n[0]) as usize;
            f(row + lo[0] as usize..row + hi[0] as usize);
        }
    }
}

/// Rows of fewer cells than this are folded by [`scan_short`]: one running pair, not the lanes
/// of a vectorized accumulator.
pub const SHORT_ROW: i64 = 16;

/// [`scan`] for rows of fewer than [`SHORT_ROW`] cells, inlined into its callers: most of a
/// small part's cost is the set-up around a few cells.
#[inline(always)]
pub fn scan_short(values: &[f32], bc: &IBox, cells: &IBox) -> (f32, f32) {
    let e = bc.extent();
    let (row, slab) = (e[0] as usize, (e[0] * e[1]) as usize);
    let w = cells.extent()[0] as usize;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut z_start = bc.linear_index(cells.lo);
    for _ in cells.lo[2]..cells.hi[2] {
        let mut src = z_start;
        for _ in cells.lo[1]..cells.hi[1] {
            for &v in &values[src..src + w] {
                // Comparisons, not f32::min: a NaN compares false and is left out.
                if v < lo {
                    lo = v;
                }
                if v > hi {
                    hi = v;
                }
            }
            src += row;
        }
        z_start += slab;
    }
    (lo, hi)
}

/// The range of the cells `cells` (inside the brick's cells `bc`) of brick data `values`; NaNs
/// are left out.
pub fn scan(values: &[f32], bc: &IBox, cells: &IBox) -> (f32, f32) {
    if cells.extent()[0] < SHORT_ROW {
        return scan_short(values, bc, cells);
    }
    let e = bc.extent();
    let (row, slab) = (e[0] as usize, (e[0] * e[1]) as usize);
    let w = cells.extent()[0] as usize;
    let mut range = RangeAccumulator::new();
    let mut z_start = bc.linear_index(cells.lo);
    for _ in cells.lo[2]..cells.hi[2] {
        let mut src = z_start;
        for _ in cells.lo[1]..cells.hi[1] {
            range.add(&values[src..src + w]);
            src += row;
        }
        z_start += slab;
    }
    range.range()
}
