//! Per-brick tables of the value ranges of blocks of `4^3` cells, each built the first time its
//! brick is asked for, so that the range of a box of a brick's cells costs one entry per block
//! inside it and a scan of the cells around those blocks, not a scan of all its cells. A table
//! takes 8 bytes per 64 cells (1/8 byte per cell, 3 % of the brick's f32 data), and only small
//! bricks (at most `16^3` cells) near the leaves visited get one.

use std::sync::OnceLock;

use amr_format::{IBox, RangeAccumulator};

use crate::error::Result;
use crate::reconstruct::Sampler;

/// Cells per axis of a block.
pub const BLOCK: i64 = 4;
/// A brick gets a table when a box asks for blocks holding at least 1/`SHARE` of its cells
/// (a smaller box is scanned: the table would read the whole brick for a small part of it).
const SHARE: i64 = 2;
/// Only bricks of at most this many cells get a table: small bricks are where a leaf's region
/// spans many bricks; larger ones are scanned as before, keeping the tables' memory small.
const MAX_TABLE_CELLS: u64 = 16 * 16 * 16;

/// The block range tables of every brick of one field, built on demand from any thread.
pub struct BlockRanges {
    tables: Vec<OnceLock<Box<[(f32, f32)]>>>,
}

impl BlockRanges {
    /// No table yet, for `bricks` bricks.
    pub fn new(bricks: usize) -> Self {
        Self {
            tables: (0..bricks).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The range of the cells of brick `brick` (of level `level`) that overlap the finest-level
    /// box `part`; `(+inf, -inf)` when there are none (NaNs are left out).
    pub fn range_in<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        brick: u32,
        level: u32,
        part: &IBox,
    ) -> Result<(f32, f32)> {
        let cells = sampler.grid().level_box(level, part);
        self.range_of_cells(sampler, brick, &cells)
    }

    /// [`Self::range_in`] for the cells `cells` (indices of the brick's level).
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
        let inner_lo = [0, 1, 2].map(|a| (cells.lo[a] - bc.lo[a] + BLOCK - 1) / BLOCK);
        let inner_hi = [0, 1, 2].map(|a| (cells.hi[a] - bc.lo[a]) / BLOCK);
        let inner_cells: i64 = (0..3)
            .map(|a| (inner_hi[a] - inner_lo[a]).max(0) * BLOCK)
            .product();
        let brick_cells = bc.num_cells().unwrap_or(u64::MAX);
        let worth_a_table = self.tables[brick as usize].get().is_some()
            || (brick_cells <= MAX_TABLE_CELLS && inner_cells * SHARE >= brick_cells as i64);
        if (0..3).any(|a| inner_lo[a] >= inner_hi[a]) || !worth_a_table {
            return Ok(exact_range(&sampler.values(brick)?, &bc, &cells));
        }
        let values = sampler.values(brick)?;
        let inner = IBox::new(
            [0, 1, 2].map(|a| bc.lo[a] + inner_lo[a] * BLOCK),
            [0, 1, 2].map(|a| bc.lo[a] + inner_hi[a] * BLOCK),
        );
        let mut rest = cells;
        for a in (0..3).rev() {
            for slab in [(rest.lo[a], inner.lo[a]), (inner.hi[a], rest.hi[a])] {
                if slab.0 < slab.1 {
                    let mut part = rest;
                    (part.lo[a], part.hi[a]) = slab;
                    let (x, y) = exact_range(&values, &bc, &part);
                    lo = lo.min(x);
                    hi = hi.max(y);
                }
            }
            (rest.lo[a], rest.hi[a]) = (inner.lo[a], inner.hi[a]);
        }
        let table = self.table(sampler, brick)?;
        let n = blocks_per_axis(&bc);
        for z in inner_lo[2]..inner_hi[2] {
            for y in inner_lo[1]..inner_hi[1] {
                let row = ((z * n[1] + y) * n[0]) as usize;
                for &(a, b) in &table[row + inner_lo[0] as usize..row + inner_hi[0] as usize] {
                    lo = lo.min(a);
                    hi = hi.max(b);
                }
            }
        }
        Ok((lo, hi))
    }

    /// The table of brick `brick`, built on first need (NaNs are left out of the ranges).
    fn table<D: AsRef<[u8]>>(&self, sampler: &Sampler<'_, D>, brick: u32) -> Result<&[(f32, f32)]> {
        let slot = &self.tables[brick as usize];
        if let Some(t) = slot.get() {
            return Ok(t);
        }
        let bc = sampler.brick_cells(brick);
        let values = sampler.values(brick)?;
        let table = build_table(&values, &bc);
        Ok(slot.get_or_init(|| table))
    }
}

/// The range of the cells `cells` (inside the brick's cells `bc`) of brick data `values`.
fn exact_range(values: &[f32], bc: &IBox, cells: &IBox) -> (f32, f32) {
    let e = bc.extent();
    let (row, slab) = (e[0] as usize, (e[0] * e[1]) as usize);
    let w = cells.extent()[0] as usize;
    if w < 16 {
        // Short rows: one running pair, not the lanes of a vectorized accumulator.
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
        return (lo, hi);
    }
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

/// Blocks per axis of a brick whose cells are `bc`.
fn blocks_per_axis(bc: &IBox) -> [i64; 3] {
    bc.extent().map(|e| (e + BLOCK - 1) / BLOCK)
}

/// The block ranges of brick data `values` (cells `bc`, x fastest), blocks x fastest.
fn build_table(values: &[f32], bc: &IBox) -> Box<[(f32, f32)]> {
    let e = bc.extent().map(|v| v as usize);
    let n = blocks_per_axis(bc).map(|v| v as usize);
    let b = BLOCK as usize;
    let mut table = vec![(f32::INFINITY, f32::NEG_INFINITY); n[0] * n[1] * n[2]];
    for z in 0..e[2] {
        for y in 0..e[1] {
            let src = &values[(z * e[1] + y) * e[0]..][..e[0]];
            let row = &mut table[(z / b * n[1] + y / b) * n[0]..][..n[0]];
            for (slot, run) in row.iter_mut().zip(src.chunks(b)) {
                for &v in run {
                    // Comparisons, not f32::min: a NaN compares false and is left out.
                    if v < slot.0 {
                        slot.0 = v;
                    }
                    if v > slot.1 {
                        slot.1 = v;
                    }
                }
            }
        }
    }
    table.into_boxed_slice()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_holds_each_blocks_range() {
        let bc = IBox::new([10, 0, 0], [15, 6, 1]);
        let values: Vec<f32> = (0..30).map(|i| i as f32).collect();
        let table = build_table(&values, &bc);
        // Blocks are 4 wide: x 0..4 and 4..5; y 0..4 and 4..6.
        assert_eq!(table.len(), 4);
        assert_eq!(table[0], (0.0, 18.0));
        assert_eq!(table[1], (4.0, 19.0));
        assert_eq!(table[2], (20.0, 28.0));
        assert_eq!(table[3], (24.0, 29.0));
    }
}
