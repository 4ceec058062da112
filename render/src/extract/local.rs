//! The level-`L` neighbourhood of one leaf: each cell of the leaf's box grown by one cell,
//! classified as a leaf cell of level `L` (with its value), coarser, refined, outside the
//! domain or uncovered.
//!
//! It is filled from the leaves touching that box, one block per leaf, so no per-cell tree walk
//! is needed; it decides which dual cells can be merged and which octants touch a boundary.

use amr_format::{IBox, Result};

use crate::reconstruct::Sampler;

/// A leaf cell of the leaf's own level.
pub const LEAF: u8 = 0;
/// Inside a coarser leaf cell.
pub const COARSER: u8 = 1;
/// Refined: covered by finer leaf cells.
pub const FINER: u8 = 2;
/// Outside the domain.
pub const OUTSIDE: u8 = 3;
/// Inside the domain, but no brick covers it.
pub const UNCOVERED: u8 = 4;

/// Per-thread scratch: the classified neighbourhood of the leaf being processed.
#[derive(Default)]
pub struct Neighbourhood {
    /// The cells held: the leaf's level-`L` box grown by one cell.
    pub cells: IBox,
    kind: Vec<u8>,
    value: Vec<f32>,
    /// Cells of `cells` within one cell of a cell that is not [`LEAF`].
    pub near_boundary: Vec<bool>,
    /// True when every cell is [`LEAF`].
    pub all_leaf: bool,
    touching: Vec<u32>,
}

impl Neighbourhood {
    /// Fills the neighbourhood of `leaf` (level `level`, level-`level` box `own`).
    pub fn fill<D: AsRef<[u8]>>(
        &mut self,
        sampler: &Sampler<'_, D>,
        level: u32,
        own: &IBox,
    ) -> Result<()> {
        let grid = sampler.grid();
        let g = own.grow([1; 3]);
        let n = g.num_cells().unwrap_or(0) as usize;
        self.cells = g;
        self.kind.clear();
        self.kind.resize(n, UNCOVERED);
        self.value.clear();
        self.value.resize(n, 0.0);
        let domain = grid.domain(level);
        let s = grid.scale(level);
        let o = grid.offset();
        let region = IBox::new(
            [0, 1, 2].map(|a| g.lo[a] * s[a] - o[a]),
            [0, 1, 2].map(|a| g.hi[a] * s[a] - o[a]),
        );
        self.touching.clear();
        let tree = sampler.file().tree();
        tree.for_each_leaf_touching(&region, |l| self.touching.push(l));
        for i in 0..self.touching.len() {
            let l = self.touching[i];
            let lb = tree.leaf_box(l);
            if !lb.overlaps(&region) {
                continue;
            }
            let block = grid.level_box(level, &lb).intersect(&g);
            if block.is_empty() {
                continue;
            }
            match sampler.leaf_top(l) {
                None => self.set_block(&block, UNCOVERED),
                Some((_, lv)) if lv < level => self.set_block(&block, COARSER),
                Some((_, lv)) if lv > level => self.set_block(&block, FINER),
                Some((brick, _)) => {
                    let values = sampler.values(brick)?;
                    let bc = sampler.brick_cells(brick);
                    let block = block.intersect(&bc);
                    if block.is_empty() {
                        continue;
                    }
                    for z in block.lo[2]..block.hi[2] {
                        for y in block.lo[1]..block.hi[1] {
                            let src = bc.linear_index([block.lo[0], y, z]);
                            let dst = g.linear_index([block.lo[0], y, z]);
                            let w = (block.hi[0] - block.lo[0]) as usize;
                            self.kind[dst..dst + w].fill(LEAF);
                            self.value[dst..dst + w].copy_from_slice(&values[src..src + w]);
                        }
                    }
                }
            }
        }
        let outside = |c: [i64; 3]| !domain.contains_cell(c);
        if (0..3).any(|a| g.lo[a] < domain.lo[a] || g.hi[a] > domain.hi[a]) {
            for z in g.lo[2]..g.hi[2] {
                for y in g.lo[1]..g.hi[1] {
                    for x in g.lo[0]..g.hi[0] {
                        if outside([x, y, z]) {
                            let i = g.linear_index([x, y, z]);
                            self.kind[i] = OUTSIDE;
                        }
                    }
                }
            }
        }
        self.all_leaf = self.kind.iter().all(|&k| k == LEAF);
        self.near_boundary.clear();
        if !self.all_leaf {
            self.near_boundary.resize(n, false);
            let e = g.extent();
            for z in 0..e[2] {
                for y in 0..e[1] {
                    for x in 0..e[0] {
                        if self.kind[(x + e[0] * (y + e[1] * z)) as usize] == LEAF {
                            continue;
                        }
                        for dz in (z - 1).max(0)..(z + 2).min(e[2]) {
                            for dy in (y - 1).max(0)..(y + 2).min(e[1]) {
                                for dx in (x - 1).max(0)..(x + 2).min(e[0]) {
                                    self.near_boundary[(dx + e[0] * (dy + e[1] * dz)) as usize] =
                                        true;
                                }
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn set_block(&mut self, block: &IBox, kind: u8) {
        let g = self.cells;
        for z in block.lo[2]..block.hi[2] {
            for y in block.lo[1]..block.hi[1] {
                let dst = g.linear_index([block.lo[0], y, z]);
                let w = (block.hi[0] - block.lo[0]).max(0) as usize;
                self.kind[dst..dst + w].fill(kind);
            }
        }
    }

    /// Index of cell `c` (absolute level index, inside [`Self::cells`]).
    #[inline]
    pub fn index(&self, c: [i64; 3]) -> usize {
        self.cells.linear_index(c)
    }

    /// The kind of the cell at index `i`.
    #[inline]
    pub fn kind(&self, i: usize) -> u8 {
        self.kind[i]
    }

    /// The value of the cell at index `i` (meaningful for [`LEAF`] cells).
    #[inline]
    pub fn value(&self, i: usize) -> f32 {
        self.value[i]
    }
}
