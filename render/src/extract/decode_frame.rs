//! What decoding keeps of the leaf decoded last: its [`LeafFrame`], its extent for turning
//! local cell indices into cells, and the box of merged dual cells whose eight cells lie in the
//! leaf, so that a decode tests six bounds instead of locating two cells.

use amr_format::IBox;

use super::dual_index::DualIndex;
use super::leaf::LeafFrame;
use super::refs::LocalVoxel;
use super::LocatedVoxel;
use crate::reconstruct::grid::Grid;

/// A leaf's frame as [`super::Extractor::decode_with`] keeps it between decodes.
#[derive(Clone, Copy, Debug)]
pub struct DecodeFrame {
    /// The leaf's frame.
    pub frame: LeafFrame,
    /// The leaf's level cells per axis along x and y.
    pub extent: (u32, u32),
    /// Its level cells.
    pub cells: i64,
    /// The lowest cells of the merged dual cells whose eight cells are cells of the leaf, read
    /// where the leaf's finest cells say (the finest cell at each cell's centre lies in the leaf
    /// and in that cell).
    pub duals: IBox,
    /// Where the dual cells of [`Self::duals`] read their values in the leaf's brick, when the
    /// brick holds all their cells ([`Self::index_duals_in`]; `None` until then).
    pub dual_index: Option<DualIndex>,
    /// The doubled centre of its lowest level cell (`cells.lo`).
    lowest: [i64; 3],
    /// The width of one of its level cells in finest cells.
    scale: [i64; 3],
}

impl DecodeFrame {
    /// The decode frame of `frame`; `None` when its extent does not fit 32-bit indices.
    pub fn new(grid: &Grid, frame: LeafFrame) -> Option<Self> {
        let e = frame.cells.extent();
        let (Ok(e0), Ok(e1)) = (u32::try_from(e[0]), u32::try_from(e[1])) else {
            return None;
        };
        // Each axis decides on its own, and the cells it keeps are a run: trim both ends, all
        // three axes a step at a time (a leaf's box is rarely more than one cell off its run).
        let (mut lo, mut hi) = (frame.cells.lo, frame.cells.hi);
        loop {
            let keep = owned(grid, &frame, lo);
            let trim = [0, 1, 2].map(|a| !keep[a] && lo[a] < hi[a]);
            if trim == [false; 3] {
                break;
            }
            for a in 0..3 {
                lo[a] += i64::from(trim[a]);
            }
        }
        loop {
            let keep = owned(grid, &frame, hi.map(|h| h - 1));
            let trim = [0, 1, 2].map(|a| !keep[a] && lo[a] < hi[a]);
            if trim == [false; 3] {
                break;
            }
            for a in 0..3 {
                hi[a] -= i64::from(trim[a]);
            }
        }
        // A dual cell's lowest cell is one below the highest cell owned on each axis.
        let duals = IBox::new(lo, [0, 1, 2].map(|a| (hi[a] - 1).max(lo[a])));
        Some(Self {
            frame,
            extent: (e0, e1),
            cells: e[0] * e[1] * e[2],
            duals,
            dual_index: None,
            lowest: grid.centre(frame.level, frame.cells.lo),
            scale: grid.scale(frame.level),
        })
    }

    /// Keeps [`Self::dual_index`] for the leaf's brick, whose cells are `brick`.
    pub fn index_duals_in(&mut self, brick: &IBox) {
        self.dual_index = DualIndex::new(brick, &self.duals);
    }

    /// The value of level cell `c` in the leaf's brick values `values` (read in place) when `c`
    /// is a corner of a dual cell of [`Self::duals`] (so a cell of the leaf as its finest cells
    /// say, the value locating it gives) and [`Self::dual_index`] is kept; else `None`.
    #[inline(always)]
    pub fn corner_value(&self, values: &[f32], c: [i64; 3]) -> Option<f32> {
        let index = self.dual_index?;
        let (lo, hi) = (self.duals.lo, self.duals.hi);
        if !(0..3).all(|a| lo[a] <= c[a] && c[a] <= hi[a]) {
            return None;
        }
        index.cell(values, c)
    }

    /// The level cell (absolute index) of local cell index `index`, `None` past the leaf.
    #[inline]
    pub fn cell(&self, index: u32) -> Option<[i64; 3]> {
        let d = self.offset(index)?;
        Some([0, 1, 2].map(|a| self.frame.cells.lo[a] + d[a]))
    }

    /// The voxel `local` of this leaf located: its level cell ([`Self::cell`]) and its box,
    /// the one [`super::Extractor::voxel_box`] gives, taken from the leaf's lowest cell's
    /// centre (no level lookups); `None` past the leaf.
    #[inline(always)]
    pub fn locate(&self, local: LocalVoxel) -> Option<LocatedVoxel> {
        let (index, octant) = match local {
            LocalVoxel::Octant { cell, octant } => (cell, Some(octant)),
            LocalVoxel::Dual { cell } => (cell, None),
        };
        let d = self.offset(index)?;
        let s = self.scale;
        let c = [0, 1, 2].map(|a| self.lowest[a] + 2 * d[a] * s[a]);
        let (lo, hi) = match octant {
            None => (c, [0, 1, 2].map(|a| c[a] + 2 * s[a])),
            Some(octant) => {
                // Octant bit `a` set: the upper half of the cell on axis `a`, which starts at `c`.
                let up = |a: usize| octant >> a & 1 != 0;
                let lo = [0, 1, 2].map(|a| if up(a) { c[a] } else { c[a] - s[a] });
                (lo, [0, 1, 2].map(|a| lo[a] + s[a]))
            }
        };
        Some(LocatedVoxel {
            level: self.frame.level,
            cell: [0, 1, 2].map(|a| self.frame.cells.lo[a] + d[a]),
            octant,
            lo,
            hi,
        })
    }

    /// The offsets from the leaf's lowest level cell of the cell of local index `index`,
    /// `None` past the leaf.
    #[inline(always)]
    fn offset(&self, index: u32) -> Option<[i64; 3]> {
        if i64::from(index) >= self.cells {
            return None;
        }
        let (e0, e1) = self.extent;
        let row = index / e0;
        Some([index % e0, row % e1, row / e1].map(i64::from))
    }
}

/// Per axis, whether level cell `c` of `frame`'s level is a cell of its leaf as the finest cells
/// say: the finest cell at its centre lies in the leaf and in `c`.
#[inline(always)]
fn owned(grid: &Grid, frame: &LeafFrame, c: [i64; 3]) -> [bool; 3] {
    let at = grid.finest_cell(grid.centre(frame.level, c), 7);
    let back = grid.cell_of(frame.level, at);
    [0, 1, 2].map(|a| frame.finest.lo[a] <= at[a] && at[a] < frame.finest.hi[a] && back[a] == c[a])
}
