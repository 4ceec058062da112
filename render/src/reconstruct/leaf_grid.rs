//! Point location through a uniform grid over the kd-tree: one table read names the kd-tree
//! leaf holding a finest-level cell, or the deepest node whose region holds the cell's whole
//! grid cell, from which a short walk finds the leaf.
//!
//! Every entry is either a leaf whose box contains its grid cell or a node whose region
//! contains it (the root when nothing better is known), so [`LeafGrid::find_leaf`] gives
//! [`TreeView::find_leaf`]'s answer for every cell, whatever the table's resolution.

use amr_format::kdtree::{KdNode, TreeView};
use amr_format::IBox;

use super::grid::axes;

/// Flags a table entry naming a node to walk from rather than a leaf.
const NODE: u32 = 1 << 31;

/// Fewest grid cells the table is allowed, whatever the number of leaves.
const MIN_ENTRIES: u64 = 1 << 15;
/// Most grid cells the table may have (16 MiB).
const MAX_ENTRIES: u64 = 1 << 22;
/// Grid cells allowed per kd-tree leaf.
const ENTRIES_PER_LEAF: u64 = 16;

/// A uniform grid of cubes of `2^shift` finest cells over the domain, naming per cube the leaf or
/// the node to walk from.
#[derive(Clone, Debug)]
pub struct LeafGrid {
    /// log2 of a grid cell's edge in finest cells.
    shift: u32,
    /// Grid cells per axis.
    dims: [i64; 3],
    /// The domain's extent in finest cells.
    extent: [i64; 3],
    /// Per grid cell, x fastest: a leaf index, or [`NODE`] with the index of a node.
    table: Vec<u32>,
}

impl LeafGrid {
    /// The grid over `tree`, its resolution the finest whose table holds at most
    /// `ENTRIES_PER_LEAF` entries per leaf (within `MIN_ENTRIES..=MAX_ENTRIES`).
    pub fn new(tree: &TreeView<'_>) -> Self {
        let extent = tree.domain.extent();
        let leaves = tree.num_leaves() as u64;
        let budget = leaves
            .saturating_mul(ENTRIES_PER_LEAF)
            .clamp(MIN_ENTRIES, MAX_ENTRIES);
        let dims_of = |shift: u32| extent.map(|e| (e + (1 << shift) - 1) >> shift);
        let mut shift = 0;
        while shift < 62 && {
            let d = dims_of(shift);
            (d[0] as u64)
                .saturating_mul(d[1] as u64)
                .saturating_mul(d[2] as u64)
                > budget
        } {
            shift += 1;
        }
        let dims = dims_of(shift);
        let entries = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = Self {
            shift,
            dims,
            extent,
            table: vec![NODE; entries],
        };
        // Indices must leave the flag bit free; otherwise every walk starts at the root.
        if tree.num_nodes() < NODE as usize && tree.num_leaves() < NODE as usize {
            grid.fill(tree);
        }
        grid
    }

    /// The grid cells (per axis, half-open index ranges) whose clipped boxes lie inside `r`.
    fn inside(&self, r: &IBox) -> [(i64, i64); 3] {
        let g = 1i64 << self.shift;
        axes(|a| {
            let lo = (r.lo[a] + g - 1) >> self.shift;
            let hi = if r.hi[a] >= self.extent[a] {
                self.dims[a]
            } else {
                r.hi[a] >> self.shift
            };
            (lo, hi.max(lo))
        })
    }

    fn set(&mut self, range: [(i64, i64); 3], entry: u32) {
        for z in range[2].0..range[2].1 {
            for y in range[1].0..range[1].1 {
                let row = (self.dims[0] * (y + self.dims[1] * z)) as usize;
                let (x0, x1) = (range[0].0 as usize, range[0].1 as usize);
                self.table[row + x0..row + x1].fill(entry);
            }
        }
    }

    /// Names, for every grid cell, the deepest node whose region contains it: the leaf, or the
    /// first split whose plane cuts it.
    fn fill(&mut self, tree: &TreeView<'_>) {
        let root = self.inside(&tree.domain);
        if root.iter().any(|&(lo, hi)| lo >= hi) {
            return;
        }
        // Nodes with at least one grid cell inside their region, with the region and those
        // cells: a child has its parent's cells but on the split axis, and one with none is
        // never pushed.
        let mut stack = vec![(0usize, tree.domain, root)];
        while let Some((i, region, mut range)) = stack.pop() {
            let Some(node) = tree.node(i) else { continue };
            match node {
                KdNode::Leaf { leaf } => self.set(range, leaf),
                KdNode::Split {
                    axis,
                    pos,
                    low,
                    high,
                } => {
                    let (below, above) = node.halves(&region).expect("a split has halves");
                    let (lo, hi) = range[axis];
                    // The grid cells inside each half on the split axis.
                    let cut = pos >> self.shift;
                    let upper = ((pos + (1 << self.shift) - 1) >> self.shift).max(lo);
                    if cut << self.shift < pos && lo <= cut && cut < hi {
                        range[axis] = (cut, cut + 1);
                        self.set(range, NODE | i as u32);
                    }
                    if upper < hi {
                        range[axis] = (upper, hi);
                        stack.push((high, above, range));
                    }
                    if lo < cut.min(hi) {
                        range[axis] = (lo, cut.min(hi));
                        stack.push((low, below, range));
                    }
                }
            }
        }
    }

    /// The leaf of `tree` (the tree this grid was built over) containing finest-level cell `p`,
    /// or `None` outside the domain.
    #[inline]
    pub fn find_leaf(&self, tree: &TreeView<'_>, p: [i64; 3]) -> Option<u32> {
        if (0..3).any(|a| p[a] < 0 || p[a] >= self.extent[a]) {
            return None;
        }
        let g = p.map(|x| x >> self.shift);
        let entry = self.table[(g[0] + self.dims[0] * (g[1] + self.dims[1] * g[2])) as usize];
        if entry & NODE == 0 {
            return Some(entry);
        }
        tree.find_leaf_from((entry & !NODE) as usize, p)
    }

    /// log2 of a grid cell's edge in finest cells.
    pub fn shift(&self) -> u32 {
        self.shift
    }

    /// Table entries naming a leaf directly, and all entries.
    pub fn resolved(&self) -> (usize, usize) {
        let leaves = self.table.iter().filter(|&&e| e & NODE == 0).count();
        (leaves, self.table.len())
    }
}
