//! Point location through a uniform grid over the kd-tree: one table read names the kd-tree
//! leaf holding a finest-level cell, or the deepest node whose region holds the cell's whole
//! grid cell, from which a short walk finds the leaf.
//!
//! Every entry is either a leaf whose box contains its grid cell or a node whose region
//! contains it (the root when nothing better is known), so [`LeafGrid::find_leaf`] gives
//! [`TreeView::find_leaf`]'s answer for every cell, whatever the table's resolution.
//!
//! [`LazyLeafGrid`] builds the table on first need: a file of many small leaves whose
//! extraction locates few cells walks the kd-tree for those instead of paying for the table.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::OnceLock;

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
/// Kd-tree leaves, at most, of a tree whose [`LazyLeafGrid`] builds its table at once: below
/// this the table costs less than the check of whether it is built.
const EAGER_LEAVES: usize = 2048;
/// Kd-tree leaves per walk a [`LazyLeafGrid`] makes before it builds its table. A walk costs
/// about what the table's fill costs per leaf (on 54,387 leaves, 21 deep: 237 instructions a
/// walk, 175 per leaf and 256 fresh pages for the table), so the walks stop near where they
/// have paid for the table, as a renter buys once the rent has reached the price: an
/// extraction that locates few cells never builds it, and one that locates many pays at most
/// about twice the least it could. At 16 leaves per walk that file (`big` cut into boxes of 2
/// to 4 cells) built it at iso 12 after 3,400 walks (`docs/benchmarks-extract.md`, `pieces`).
const LEAVES_PER_WALK: u64 = 2;

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

    /// The table's entry for finest-level cell `p`: the leaf holding it, or the node to walk
    /// from ([`TreeView::find_leaf_from`]); `None` outside the domain. [`Self::find_leaf`]
    /// spells the same read out: written through this, it cost a render 0.3 M instructions.
    #[inline]
    pub fn entry(&self, p: [i64; 3]) -> Option<Entry> {
        if (0..3).any(|a| p[a] < 0 || p[a] >= self.extent[a]) {
            return None;
        }
        let g = p.map(|x| x >> self.shift);
        let entry = self.table[(g[0] + self.dims[0] * (g[1] + self.dims[1] * g[2])) as usize];
        Some(if entry & NODE == 0 {
            Entry::Leaf(entry)
        } else {
            Entry::Node((entry & !NODE) as usize)
        })
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

/// A [`LeafGrid`]'s answer for one finest-level cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// The kd-tree leaf holding the cell.
    Leaf(u32),
    /// A node whose region holds the cell, to walk down from.
    Node(usize),
}

/// A [`LeafGrid`] built on first need: until then (for a tree of more than [`EAGER_LEAVES`]
/// leaves) each query walks the kd-tree, and the table is built once the walks reach one per
/// [`LEAVES_PER_WALK`] leaves. The answers are the same either way, so while one thread builds
/// the table the others go on walking instead of waiting for it.
#[derive(Debug)]
pub struct LazyLeafGrid {
    grid: OnceLock<LeafGrid>,
    /// Queries answered by a walk so far.
    walks: AtomicU64,
    /// Walks made before the table is built.
    allowance: u64,
    /// Set by the thread that builds the table.
    building: AtomicBool,
}

impl LazyLeafGrid {
    /// The grid over `tree`, built now when the tree has at most [`EAGER_LEAVES`] leaves.
    pub fn new(tree: &TreeView<'_>) -> Self {
        let grid = OnceLock::new();
        if tree.num_leaves() <= EAGER_LEAVES {
            let _ = grid.set(LeafGrid::new(tree));
        }
        Self {
            grid,
            walks: AtomicU64::new(0),
            allowance: tree.num_leaves() as u64 / LEAVES_PER_WALK,
            building: AtomicBool::new(false),
        }
    }

    /// The leaf of `tree` (the tree this grid is over) containing finest-level cell `p`, or
    /// `None` outside the domain: [`LeafGrid::find_leaf`]'s answer.
    #[inline]
    pub fn find_leaf(&self, tree: &TreeView<'_>, p: [i64; 3]) -> Option<u32> {
        match self.grid.get() {
            Some(g) => g.find_leaf(tree, p),
            None => self.find_leaf_unbuilt(tree, p),
        }
    }

    /// [`Self::find_leaf`] before the table is built: a walk, or the table's build once the
    /// walks have used up their allowance (a walk again while another thread builds it).
    #[cold]
    #[inline(never)]
    fn find_leaf_unbuilt(&self, tree: &TreeView<'_>, p: [i64; 3]) -> Option<u32> {
        if self.walks.fetch_add(1, Ordering::Relaxed) < self.allowance
            || self.building.swap(true, Ordering::Relaxed)
        {
            return tree.find_leaf(p);
        }
        self.grid
            .get_or_init(|| LeafGrid::new(tree))
            .find_leaf(tree, p)
    }

    /// The table, once built.
    #[inline]
    pub fn built(&self) -> Option<&LeafGrid> {
        self.grid.get()
    }

    /// True once the table is built.
    pub fn is_built(&self) -> bool {
        self.grid.get().is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use amr_format::kdtree::{build, TreeBrick};

    /// Bricks of 2^3 cells over a 64 x 32 x 16 domain, a fifth of the 4,096 places left to a
    /// coarse brick under them all: a tree of more than [`EAGER_LEAVES`] leaves.
    fn many_small_leaves() -> (amr_format::kdtree::KdTree, IBox) {
        let domain = IBox::new([0; 3], [64, 32, 16]);
        let mut bricks = vec![TreeBrick {
            bounds: domain,
            level: 0,
        }];
        for z in 0..8 {
            for y in 0..16 {
                for x in 0..32 {
                    if (x * 7 + y * 3 + z) % 5 != 0 {
                        let lo = [2 * x, 2 * y, 2 * z];
                        bricks.push(TreeBrick {
                            bounds: IBox::new(lo, lo.map(|v| v + 2)),
                            level: 1,
                        });
                    }
                }
            }
        }
        (build(&bricks, domain).expect("a valid hierarchy"), domain)
    }

    /// The view of `tree` over `domain`.
    fn view_of(tree: &amr_format::kdtree::KdTree, domain: IBox) -> TreeView<'_> {
        TreeView {
            nodes: &tree.nodes,
            leaves: &tree.leaves,
            domain,
        }
    }

    /// A lazy grid over a tree of many small leaves answers as the kd-tree walk does, before its
    /// table is built (the walks) and after (the table), and builds the table once the walks'
    /// allowance is used up.
    #[test]
    fn lazy_grid_answers_as_the_tree_before_and_after_its_build() {
        let (tree, domain) = many_small_leaves();
        let view = view_of(&tree, domain);
        assert!(view.num_leaves() > EAGER_LEAVES);
        let lazy = LazyLeafGrid::new(&view);
        assert!(!lazy.is_built());
        let mut queries = 0u64;
        for z in -1..17 {
            for y in -1..33 {
                for x in -1..65 {
                    let p = [x, y, z];
                    assert_eq!(lazy.find_leaf(&view, p), view.find_leaf(p), "{p:?}");
                    queries += 1;
                    assert_eq!(
                        lazy.is_built(),
                        queries > view.num_leaves() as u64 / LEAVES_PER_WALK
                    );
                }
            }
        }
        assert!(lazy.is_built());
    }

    /// Threads asking at once, one of them building the table while the others walk, get the
    /// walk's answers, and the table is built once.
    #[test]
    fn threads_asking_while_the_table_is_built_get_the_same_answers() {
        let (tree, domain) = many_small_leaves();
        let view = view_of(&tree, domain);
        let lazy = LazyLeafGrid::new(&view);
        std::thread::scope(|s| {
            for t in 0..4i64 {
                let (lazy, view) = (&lazy, &view);
                s.spawn(move || {
                    for z in -1..17 {
                        for y in -1..33 {
                            for x in -1..65 {
                                let p = [(x + 13 * t).rem_euclid(66) - 1, y, z];
                                assert_eq!(lazy.find_leaf(view, p), view.find_leaf(p), "{p:?}");
                            }
                        }
                    }
                });
            }
        });
        assert!(lazy.is_built());
    }

    /// A tree of at most [`EAGER_LEAVES`] leaves has its table from the start.
    #[test]
    fn small_trees_build_at_once() {
        let domain = IBox::new([0; 3], [8, 8, 8]);
        let bricks = [TreeBrick {
            bounds: domain,
            level: 0,
        }];
        let tree = build(&bricks, domain).expect("a valid hierarchy");
        let view = view_of(&tree, domain);
        let lazy = LazyLeafGrid::new(&view);
        assert!(lazy.is_built());
        assert_eq!(lazy.find_leaf(&view, [3, 4, 5]), Some(0));
        assert_eq!(lazy.find_leaf(&view, [8, 0, 0]), None);
    }
}
