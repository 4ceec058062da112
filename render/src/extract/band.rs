//! Value bounds of leaf cells gathered onto the grid of a coarser level: per cell of level `q`,
//! the range of the leaf cells of level `q` or finer inside it, or the fact that a leaf cell
//! coarser than `q` overlaps it.
//!
//! [`CoarseBand`] holds them around one leaf for one coarser level, each computed on first need,
//! so that the bound of a coarse neighbour cell `Q` (the range of the leaf cells within one
//! `Q`-cell of `Q`, [`super::cull`]) is the union of 27 entries, each shared by the coarse cells
//! next to it, instead of a scan of every brick near `Q`.

use crate::error::Result;
use amr_format::IBox;

use super::blocks::BlockRanges;
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
    let e = g.extent();
    for z in cells.lo[2]..cells.hi[2] {
        let gz = z.div_euclid(ratio[2]) - g.lo[2];
        if !(0..e[2]).contains(&gz) {
            continue;
        }
        for y in cells.lo[1]..cells.hi[1] {
            let gy = y.div_euclid(ratio[1]) - g.lo[1];
            if !(0..e[1]).contains(&gy) {
                continue;
            }
            let src = bc.linear_index([cells.lo[0], y, z]);
            let row = ((gz * e[1] + gy) * e[0]) as usize;
            let mut x = cells.lo[0];
            while x < cells.hi[0] {
                let gx = x.div_euclid(ratio[0]);
                let end = ((gx + 1) * ratio[0]).min(cells.hi[0]);
                let gx = gx - g.lo[0];
                if (0..e[0]).contains(&gx) {
                    let run = &values
                        [src + (x - cells.lo[0]) as usize..src + (end - cells.lo[0]) as usize];
                    let i = row + gx as usize;
                    for &v in run {
                        lo[i] = lo[i].min(v);
                        hi[i] = hi[i].max(v);
                    }
                }
                x = end;
            }
        }
    }
}

/// Owner of a band cell: no leaf with data overlaps it.
const EMPTY: u32 = u32::MAX;
/// Owner of a band cell: a leaf cell coarser than the band's level overlaps it.
const COARSER: u32 = u32::MAX - 1;
/// Owner of a band cell: several leaves overlap it.
const SHARED: u32 = u32::MAX - 2;

/// The bounds of the leaf cells on the grid of one coarser level around one leaf.
#[derive(Default)]
pub struct CoarseBand {
    /// The level `q` of the grid.
    pub level: u32,
    /// The level-`q` cells held (absolute indices): [`Self::inner`] grown by one, clipped to the
    /// domain.
    pub cells: IBox,
    /// The level-`q` cells overlapping the region the band was prepared for.
    pub inner: IBox,
    /// Per cell: the index in [`Self::parts`] of the one leaf with data overlapping it, or
    /// [`EMPTY`], [`COARSER`], [`SHARED`].
    owner: Vec<u32>,
    /// Per cell: its bound once computed.
    lo: Vec<f32>,
    hi: Vec<f32>,
    known: Vec<bool>,
    /// True once the bounds of every [`SHARED`] cell are known.
    shared_known: bool,
    /// The leaves touching the band.
    touching: Vec<u32>,
    /// The leaves of level `q` or finer overlapping the band, with data.
    parts: Vec<BandPart>,
}

/// A leaf of level `q` or finer overlapping a band.
struct BandPart {
    brick: u32,
    /// Its level-`lv` cells that its brick holds.
    cells: IBox,
    /// The width of a level-`q` cell in level-`lv` cells.
    ratio: [i64; 3],
}

impl CoarseBand {
    /// Prepares the band of level `level` holding every level-`level` cell overlapping the
    /// finest-level box `region`, and the cells next to them: records which leaves overlap each
    /// cell. No brick data is read until [`Self::range_around`].
    pub fn prepare<D: AsRef<[u8]>>(&mut self, sampler: &Sampler<'_, D>, level: u32, region: &IBox) {
        let grid = sampler.grid();
        let inner = grid.level_box(level, region);
        let g = inner.grow([1; 3]).intersect(&grid.domain(level));
        let n = g.num_cells().unwrap_or(0) as usize;
        self.level = level;
        self.inner = inner;
        self.cells = g;
        self.owner.clear();
        self.owner.resize(n, EMPTY);
        self.known.clear();
        self.known.resize(n, false);
        self.shared_known = false;
        self.lo.resize(n, f32::INFINITY);
        self.hi.resize(n, f32::NEG_INFINITY);
        self.touching.clear();
        self.parts.clear();
        if n == 0 {
            return;
        }
        let finest = self.finest_box(sampler, &g);
        let tree = sampler.file().tree();
        tree.for_each_leaf_touching(&finest, |l| self.touching.push(l));
        let s = grid.scale(level);
        for &l in &self.touching {
            let leaf_box = tree.leaf_box(l);
            let part = leaf_box.intersect(&finest);
            let Some((brick, lv)) = sampler.leaf_top(l) else {
                continue;
            };
            if part.is_empty() {
                continue;
            }
            let mark = if lv < level {
                COARSER
            } else {
                let sf = grid.scale(lv);
                self.parts.push(BandPart {
                    brick,
                    cells: grid
                        .level_box(lv, &leaf_box)
                        .intersect(&sampler.brick_cells(brick)),
                    ratio: [0, 1, 2].map(|a| s[a] / sf[a]),
                });
                (self.parts.len() - 1) as u32
            };
            let block = grid.level_box(level, &part).intersect(&g);
            for z in block.lo[2]..block.hi[2] {
                for y in block.lo[1]..block.hi[1] {
                    let row = g.linear_index([block.lo[0], y, z]);
                    for owner in &mut self.owner[row..row + block.extent()[0] as usize] {
                        *owner = match (*owner, mark) {
                            (_, COARSER) | (COARSER, _) => COARSER,
                            (EMPTY, _) => mark,
                            _ => SHARED,
                        };
                    }
                }
            }
        }
    }

    /// The finest-level box of level-`q` cells `cells`.
    fn finest_box<D: AsRef<[u8]>>(&self, sampler: &Sampler<'_, D>, cells: &IBox) -> IBox {
        let grid = sampler.grid();
        let s = grid.scale(self.level);
        let o = grid.offset();
        IBox::new(
            [0, 1, 2].map(|a| cells.lo[a] * s[a] - o[a]),
            [0, 1, 2].map(|a| cells.hi[a] * s[a] - o[a]),
        )
    }

    /// True when the band is of level `level` and holds cell `c` (absolute index) and, inside
    /// the domain, the cells next to it.
    pub fn covers(&self, level: u32, c: [i64; 3]) -> bool {
        self.level == level && self.inner.contains_cell(c)
    }

    /// A range holding the leaf cells within one cell of level-`q` cell `c` (absolute index),
    /// read through `blocks`; `None` when a leaf cell coarser than `q` lies there. `c`
    /// must be [`Self::covers`]ed.
    pub fn range_around<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        c: [i64; 3],
    ) -> Result<Option<(f32, f32)>> {
        let near = IBox::new(c.map(|v| v - 1), c.map(|v| v + 2)).intersect(&self.cells);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for z in near.lo[2]..near.hi[2] {
            for y in near.lo[1]..near.hi[1] {
                let row = self.cells.linear_index([near.lo[0], y, z]);
                for (k, i) in (row..row + near.extent()[0] as usize).enumerate() {
                    if self.owner[i] == COARSER {
                        return Ok(None);
                    }
                    if self.owner[i] == SHARED && !self.shared_known {
                        self.settle_shared(sampler, blocks)?;
                    }
                    if !self.known[i] {
                        let cell = [near.lo[0] + k as i64, y, z];
                        (self.lo[i], self.hi[i]) = self.compute(sampler, blocks, i, cell)?;
                        self.known[i] = true;
                    }
                    lo = lo.min(self.lo[i]);
                    hi = hi.max(self.hi[i]);
                }
            }
        }
        Ok(Some((lo, hi)))
    }

    /// Computes the bounds of every [`SHARED`] cell in one pass over the parts, each part
    /// folding into the cells it overlaps (rather than every part visiting every shared cell).
    fn settle_shared<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
    ) -> Result<()> {
        let g = self.cells;
        for i in 0..self.owner.len() {
            if self.owner[i] == SHARED {
                (self.lo[i], self.hi[i]) = (f32::INFINITY, f32::NEG_INFINITY);
            }
        }
        for part in &self.parts {
            let r = part.ratio;
            let over = IBox::new(
                [0, 1, 2].map(|a| part.cells.lo[a].div_euclid(r[a])),
                [0, 1, 2].map(|a| (part.cells.hi[a] + r[a] - 1).div_euclid(r[a])),
            )
            .intersect(&g);
            for z in over.lo[2]..over.hi[2] {
                for y in over.lo[1]..over.hi[1] {
                    for x in over.lo[0]..over.hi[0] {
                        let i = g.linear_index([x, y, z]);
                        if self.owner[i] != SHARED {
                            continue;
                        }
                        let c = [x, y, z];
                        let inside = IBox::new(
                            [0, 1, 2].map(|a| c[a] * r[a]),
                            [0, 1, 2].map(|a| (c[a] + 1) * r[a]),
                        )
                        .intersect(&part.cells);
                        let (a, b) = blocks.range_of_cells(sampler, part.brick, &inside)?;
                        self.lo[i] = self.lo[i].min(a);
                        self.hi[i] = self.hi[i].max(b);
                    }
                }
            }
        }
        for i in 0..self.owner.len() {
            if self.owner[i] == SHARED {
                self.known[i] = true;
            }
        }
        self.shared_known = true;
        Ok(())
    }

    /// A range holding the leaf cells inside band cell `i` (cell `cell`), which no coarser leaf
    /// cell overlaps.
    fn compute<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        i: usize,
        cell: [i64; 3],
    ) -> Result<(f32, f32)> {
        let parts = match self.owner[i] {
            EMPTY => return Ok((f32::INFINITY, f32::NEG_INFINITY)),
            SHARED => &self.parts[..],
            one => std::slice::from_ref(&self.parts[one as usize]),
        };
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for part in parts {
            let r = part.ratio;
            let inside = IBox::new(
                [0, 1, 2].map(|a| cell[a] * r[a]),
                [0, 1, 2].map(|a| (cell[a] + 1) * r[a]),
            )
            .intersect(&part.cells);
            if inside.is_empty() {
                continue;
            }
            let (a, b) = blocks.range_of_cells(sampler, part.brick, &inside)?;
            lo = lo.min(a);
            hi = hi.max(b);
        }
        Ok((lo, hi))
    }
}
