//! Point location through a uniform grid over the kd-tree: one table read names the kd-tree
//! leaf holding a finest-level cell, or the deepest node whose region holds the cell's whole
//! grid cell, from which a short walk finds the leaf.
//!
//! Every entry is either a leaf whose box contains its grid cell or a node whose region
//! contains it (the root when nothing better is known), so [`LeafGrid::find_leaf`] gives
//! [`TreeView::find_leaf`]'s answer for every cell, whatever the table's resolution.
//!
//! Entries are filled on first use, by one walk from the root per grid cell: an extraction
//! asks for few of them (2,932 of 373,248 on a file of 60,860 leaves of 2 to 4 cells, where
//! filling them all cost 10 M instructions, more than the walks the table saves).

use std::sync::atomic::{AtomicU32, Ordering};

use amr_format::kdtree::{KdNode, TreeView};

/// Flags a table entry naming a node to walk from rather than a leaf.
const NODE: u32 = 1 << 31;
/// An entry not filled yet (a node index no tree of the sizes [`LeafGrid::new`] fills has).
const UNKNOWN: u32 = u32::MAX;

/// Fewest grid cells the table is allowed, whatever the number of leaves.
const MIN_ENTRIES: u64 = 1 << 15;
/// Most grid cells the table may have (16 MiB).
const MAX_ENTRIES: u64 = 1 << 22;
/// Grid cells allowed per kd-tree leaf.
const ENTRIES_PER_LEAF: u64 = 16;

/// A uniform grid of cubes of `2^shift` finest cells over the domain, naming per cube the leaf or
/// the node to walk from.
#[derive(Debug)]
pub struct LeafGrid {
    /// log2 of a grid cell's edge in finest cells.
    shift: u32,
    /// Grid cells per axis.
    dims: [i64; 3],
    /// The domain's extent in finest cells.
    extent: [i64; 3],
    /// Per grid cell, x fastest: a leaf index, or [`NODE`] with the index of a node, or
    /// [`UNKNOWN`] until first asked.
    table: Vec<AtomicU32>,
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
        // Indices must leave the flag bit free and differ from `UNKNOWN`; otherwise every walk
        // starts at the root.
        let fits = tree.num_nodes() < (NODE - 1) as usize && tree.num_leaves() < NODE as usize;
        let start = if fits { UNKNOWN } else { NODE };
        Self {
            shift,
            dims,
            extent,
            table: (0..entries).map(|_| AtomicU32::new(start)).collect(),
        }
    }

    /// The entry of grid cell `g`: the deepest node whose region contains the grid cell
    /// (clipped to the domain), a leaf or the first split whose plane cuts it.
    #[cold]
    fn resolve(&self, tree: &TreeView<'_>, g: [i64; 3]) -> u32 {
        let lo = g.map(|v| v << self.shift);
        let hi: [i64; 3] = std::array::from_fn(|a| ((g[a] + 1) << self.shift).min(self.extent[a]));
        let mut i = 0;
        loop {
            match tree.node(i) {
                Some(KdNode::Leaf { leaf }) => return leaf,
                Some(KdNode::Split {
                    axis,
                    pos,
                    low,
                    high,
                }) => {
                    if hi[axis] <= pos {
                        i = low;
                    } else if lo[axis] >= pos {
                        i = high;
                    } else {
                        return NODE | i as u32;
                    }
                }
                None => return NODE,
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
        let slot = &self.table[(g[0] + self.dims[0] * (g[1] + self.dims[1] * g[2])) as usize];
        let mut entry = slot.load(Ordering::Relaxed);
        if entry & NODE == 0 {
            return Some(entry);
        }
        if entry == UNKNOWN {
            // Every thread that asks computes the same entry.
            entry = self.resolve(tree, g);
            slot.store(entry, Ordering::Relaxed);
            if entry & NODE == 0 {
                return Some(entry);
            }
        }
        tree.find_leaf_from((entry & !NODE) as usize, p)
    }

    /// log2 of a grid cell's edge in finest cells.
    pub fn shift(&self) -> u32 {
        self.shift
    }

    /// Table entries naming a leaf directly (of those filled so far), and all entries.
    pub fn resolved(&self) -> (usize, usize) {
        let leaves = self
            .table
            .iter()
            .filter(|e| e.load(Ordering::Relaxed) & NODE == 0)
            .count();
        (leaves, self.table.len())
    }
}
