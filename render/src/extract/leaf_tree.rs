//! A bounding-box tree over the kd-tree's leaves, holding each node's coarsest level and, once
//! asked, a range of its cells: region queries for tight ranges cost the nodes along the
//! region's boundary, not one visit per leaf inside it.
//!
//! The tree is the file's kd-tree itself with its subtrees of at most [`BUCKET`] leaves
//! collapsed into bottom nodes: one pass over the stored nodes, no sorting. A kd-tree deeper than
//! [`MAX_KD_DEPTH`] (which the writers never produce, but a file may hold) is replaced by a tree
//! split at the median of the longest axis, balanced whatever the file.

use std::convert::Infallible;
use std::sync::atomic::{AtomicU64, Ordering};

use amr_format::kdtree::{leaf_bounds, KdNode, TreeView};
use amr_format::raw::KdLeaf;
use amr_format::IBox;
use zerocopy::FromZeros;

use super::blocks::{level_box, scan, scan_short, BlockRanges, SHORT_ROW};
use super::tight::{pack, unpack};
use crate::error::Result;
use crate::reconstruct::grid::axes;
use crate::reconstruct::Sampler;

/// Leaves per bottom node, at most.
const BUCKET: usize = 8;
/// Cells per axis (at its own level) of a leaf that counts whole in a region it overlaps.
const SMALL: i64 = 4;
/// Deepest kd-tree whose shape the tree takes; the walks' stacks of 64 nodes stay far from full.
const MAX_KD_DEPTH: u32 = 48;
/// Cells of a leaf's part, at most, that [`LeafTree::exact_range_over`] scans without asking
/// the block tables (a part this small holds no whole block of them).
const SCAN_CELLS: u64 = 64;
/// A range not computed yet: a slot holds a computed range's [`pack`] inverted, and never this
/// (two NaNs, which no computed range holds), so that the tables start as zeroed memory, whose
/// pages the kernel only hands over when a range is kept in them.
const UNKNOWN: u64 = 0;

/// One node: the leaves `order[first..end]`.
struct Node {
    /// The union of its leaves' boxes (finest-level cells).
    bounds: LeafBox,
    /// The coarsest level of its leaves with data (`u32::MAX` when none has data).
    coarsest: u32,
    /// True when every one of its leaves has data.
    complete: bool,
    first: u32,
    end: u32,
    /// Its two children, for a node of more than [`BUCKET`] leaves.
    children: Option<(u32, u32)>,
}

/// Every leaf's box (the file's) and the level of its finest brick (`u32::MAX` without data),
/// by leaf id: read from the file and the sampler, not copied.
struct Leaves<'a, 's, D> {
    tree: &'a TreeView<'a>,
    sampler: &'a Sampler<'s, D>,
}

impl<D: AsRef<[u8]>> Leaves<'_, '_, D> {
    /// Leaf `l`'s box, `None` past the last leaf.
    #[inline]
    fn get(&self, l: u32) -> Option<IBox> {
        self.tree.leaves.get(l as usize).map(leaf_bounds)
    }

    /// The level of leaf `l`'s finest brick, `u32::MAX` without data.
    #[inline]
    fn level(&self, l: u32) -> u32 {
        self.sampler.leaf_top(l).map_or(u32::MAX, |(_, lv)| lv)
    }
}

/// A leaf's box as the file stores it (finest-level cells relative to the domain, which spans
/// at most `u32::MAX` cells per axis): half the bytes of an [`IBox`].
#[derive(Clone, Copy)]
struct LeafBox {
    lo: [u32; 3],
    hi: [u32; 3],
}

impl LeafBox {
    /// The box of a stored leaf.
    #[inline]
    fn of(l: &KdLeaf) -> Self {
        let (lo, hi) = (&l.lo, &l.hi);
        Self {
            lo: [lo[0].get(), lo[1].get(), lo[2].get()],
            hi: [hi[0].get(), hi[1].get(), hi[2].get()],
        }
    }

    /// A union of leaves' boxes (so its corners fit).
    #[inline]
    fn of_union(b: &IBox) -> Self {
        Self {
            lo: b.lo.map(|v| v as u32),
            hi: b.hi.map(|v| v as u32),
        }
    }

    /// The box, its corners widened.
    #[inline(always)]
    fn get(&self) -> IBox {
        let (lo, hi) = (&self.lo, &self.hi);
        IBox::new(
            [lo[0].into(), lo[1].into(), lo[2].into()],
            [hi[0].into(), hi[1].into(), hi[2].into()],
        )
    }
}

/// What [`LeafTree::for_each_overlapping_grouped`] hands over: a leaf, or a node taken whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Met {
    /// A leaf overlapping the region.
    Leaf(u32),
    /// A node inside the region that the caller takes whole ([`LeafTree::node_box`],
    /// [`LeafTree::exact_node_range`]).
    Node(u32),
}

/// Where a walk of the tree is ([`LeafTree::walk`]).
enum At<'a> {
    /// A node reached, with its index: enter it or not.
    Node(u32, &'a Node),
    /// An entered node to be taken leaf by leaf.
    Leaves(&'a Node),
}

/// What a walk does next ([`LeafTree::walk`]).
enum Visit {
    /// Leave this node's subtree out (or, after [`At::Leaves`], go on).
    Skip,
    /// Enter the node.
    Enter,
}

/// The tree over all leaves of one file, with lazily computed node ranges of one field.
pub struct LeafTree {
    nodes: Vec<Node>,
    /// Leaf ids, each node's contiguous.
    order: Vec<u32>,
    ranges: Vec<AtomicU64>,
    /// Per leaf, the range of its cells once asked.
    leaf_ranges: Vec<AtomicU64>,
    /// Per leaf, the exact range of its cells once asked.
    exact_ranges: Vec<AtomicU64>,
    /// Per node, the exact range of its leaves' cells once asked.
    exact_nodes: Vec<AtomicU64>,
    /// The boxes of the leaves of `order`, in its order: a bottom node's leaves' boxes are
    /// read one after another, without going through the leaf ids.
    ordered: Vec<LeafBox>,
    /// Per leaf, its place in `order` (and its box's in `ordered`).
    position: Vec<u32>,
}

impl LeafTree {
    /// The tree over every leaf of `sampler`'s file, in the kd-tree's shape unless that is
    /// deeper than [`MAX_KD_DEPTH`].
    pub fn new<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>) -> Self {
        Self::with_shape(sampler, sampler.file().tree_depth() <= MAX_KD_DEPTH)
    }

    /// The tree over every leaf of `sampler`'s file split at the median of the longest axis,
    /// whatever the kd-tree: what [`Self::new`] builds for a kd-tree too deep to follow.
    pub fn median<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>) -> Self {
        Self::with_shape(sampler, false)
    }

    /// The tree in the kd-tree's shape when `kd` (and the kd-tree has that form), else split at
    /// medians.
    fn with_shape<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, kd: bool) -> Self {
        let n = sampler.file().num_leaves() as u32;
        let mut nodes = Vec::with_capacity(4 * n as usize / BUCKET + 1);
        let mut order: Vec<u32> = Vec::with_capacity(n as usize);
        let tree = sampler.file().tree();
        let leaves = Leaves {
            tree: &tree,
            sampler,
        };
        let from_kd = kd && from_kd_tree(&tree, &leaves, &mut order, &mut nodes).is_some();
        if !from_kd && n > 0 {
            nodes.clear();
            order = (0..n).collect();
            build(&leaves, &mut order, 0, &mut nodes);
        }
        let ordered = order
            .iter()
            .map(|&l| LeafBox::of(&tree.leaves[l as usize]))
            .collect();
        let mut position = vec![0u32; n as usize];
        for (i, &l) in order.iter().enumerate() {
            position[l as usize] = i as u32;
        }
        Self {
            ordered,
            position,
            ranges: unknown(nodes.len()),
            leaf_ranges: unknown(n as usize),
            exact_ranges: unknown_written(n as usize),
            exact_nodes: unknown(nodes.len()),
            nodes,
            order,
        }
    }

    /// The coarsest level of the leaves with data whose closed boxes touch the closed `region`.
    pub fn coarsest_touching<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        region: &IBox,
    ) -> Option<u32> {
        let mut best = u32::MAX;
        let Ok(()) = self.walk::<Infallible>(|at| {
            Ok(match at {
                At::Node(_, node)
                    if node.coarsest >= best || !node.bounds.get().touches(region) =>
                {
                    Visit::Skip
                }
                At::Node(_, node) if region.contains_box(&node.bounds.get()) => {
                    best = node.coarsest;
                    Visit::Skip
                }
                At::Node(..) => Visit::Enter,
                At::Leaves(node) => {
                    for (&l, b) in self.leaves(node).iter().zip(self.leaf_boxes(node)) {
                        if let Some((_, lv)) = sampler.leaf_top(l) {
                            if lv < best && b.get().touches(region) {
                                best = lv;
                            }
                        }
                    }
                    Visit::Skip
                }
            })
        });
        (best != u32::MAX).then_some(best)
    }

    /// Calls `f` with every leaf whose closed box touches the closed `region`.
    pub fn for_each_leaf_touching(&self, region: &IBox, f: impl FnMut(u32)) {
        self.for_each_leaf_meeting::<false>(region, f);
    }

    /// Calls `f` with every leaf whose box overlaps `region` (shares at least one cell): the
    /// leaves that only touch its faces, edges or corners, and the nodes holding only those, are
    /// not visited.
    pub fn for_each_leaf_overlapping(&self, region: &IBox, f: impl FnMut(u32)) {
        self.for_each_leaf_meeting::<true>(region, f);
    }

    /// [`Self::for_each_leaf_overlapping`], except that a node inside `region` for which
    /// `whole(bounds, coarsest, complete)` holds (its box, the coarsest level of its leaves with
    /// data, and whether all have data) is handed over as one [`Met::Node`] instead of its
    /// leaves; the order is the same, the node standing where its leaves would.
    #[inline]
    pub fn for_each_overlapping_grouped(
        &self,
        region: &IBox,
        whole: impl Fn(&IBox, u32, bool) -> bool,
        mut f: impl FnMut(Met),
    ) {
        // Its own loop rather than `walk`, as in `exact_range_over`: through `walk` the fills
        // of `tiny`'s level-2 tiles, where no node is taken whole, cost 18 % more.
        // A child is tested before it is pushed: only nodes overlapping `region` are taken.
        let mut stack = [0u32; 64];
        let mut top = usize::from(
            self.nodes
                .first()
                .is_some_and(|n| n.bounds.get().overlaps(region)),
        );
        while top > 0 {
            top -= 1;
            let i = stack[top];
            let node = &self.nodes[i as usize];
            // `whole` first: it fails fast where nodes are never taken whole.
            let bounds = node.bounds.get();
            if whole(&bounds, node.coarsest, node.complete) && region.contains_box(&bounds) {
                f(Met::Node(i));
                continue;
            }
            match node.children {
                // The tree is balanced: its depth stays far below the stack's size.
                Some(children) if top + 2 <= stack.len() => {
                    top = self.push_children(children, |b| b.overlaps(region), &mut stack, top);
                }
                _ => {
                    let (first, end) = (node.first as usize, node.end as usize);
                    for (&l, b) in self.order[first..end].iter().zip(&self.ordered[first..end]) {
                        if b.get().overlaps(region) {
                            f(Met::Leaf(l));
                        }
                    }
                }
            }
        }
    }

    /// The box of node `i` (the union of its leaves' boxes).
    #[inline]
    pub fn node_box(&self, i: u32) -> IBox {
        self.nodes[i as usize].bounds.get()
    }

    /// The leaves of node `i`'s subtree.
    pub fn node_leaves(&self, i: u32) -> &[u32] {
        self.leaves(&self.nodes[i as usize])
    }

    /// Calls `f` with every leaf whose box overlaps `region` (`OVERLAP`) or touches it; nodes
    /// that fail the same test are skipped whole.
    fn for_each_leaf_meeting<const OVERLAP: bool>(&self, region: &IBox, mut f: impl FnMut(u32)) {
        let meets = |b: &IBox| match OVERLAP {
            true => b.overlaps(region),
            false => b.touches(region),
        };
        // Its own loop rather than `walk`, as in `exact_range_over`; a child is tested before
        // it is pushed, so that only nodes meeting `region` are taken from the stack.
        let mut stack = [0u32; 64];
        let mut top = usize::from(self.nodes.first().is_some_and(|n| meets(&n.bounds.get())));
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            match node.children {
                // The tree is balanced: its depth stays far below the stack's size.
                Some(children) if top + 2 <= stack.len() => {
                    top = self.push_children(children, meets, &mut stack, top);
                }
                _ => {
                    let (first, end) = (node.first as usize, node.end as usize);
                    for (&l, b) in self.order[first..end].iter().zip(&self.ordered[first..end]) {
                        if meets(&b.get()) {
                            f(l);
                        }
                    }
                }
            }
        }
    }

    /// Pushes those of a node's children `(a, b)` whose bounds `meet` the walk's region, `b`
    /// first so that `a` is taken first; returns the stack's new top.
    #[inline]
    fn push_children(
        &self,
        (a, b): (u32, u32),
        meets: impl Fn(&IBox) -> bool,
        stack: &mut [u32; 64],
        mut top: usize,
    ) -> usize {
        for child in [b, a] {
            if meets(&self.nodes[child as usize].bounds.get()) {
                stack[top] = child;
                top += 1;
            }
        }
        top
    }

    /// Walks the tree depth first, the first child first: `visit` is called with each node
    /// reached ([`At::Node`]) and says whether to enter it; an entered node without children
    /// (or one past the stack's depth) is handed back whole ([`At::Leaves`]). Stops at the
    /// first error.
    fn walk<E>(
        &self,
        mut visit: impl FnMut(At<'_>) -> std::result::Result<Visit, E>,
    ) -> std::result::Result<(), E> {
        let mut stack = [0u32; 64];
        let mut top = usize::from(!self.nodes.is_empty());
        while top > 0 {
            top -= 1;
            let i = stack[top];
            let node = &self.nodes[i as usize];
            if let Visit::Skip = visit(At::Node(i, node))? {
                continue;
            }
            match node.children {
                // The tree is balanced: its depth stays far below the stack's size.
                Some((a, b)) if top + 2 <= stack.len() => {
                    stack[top] = b;
                    stack[top + 1] = a;
                    top += 2;
                }
                _ => {
                    visit(At::Leaves(node))?;
                }
            }
        }
        Ok(())
    }

    /// The leaves of `node`'s subtree.
    #[inline]
    fn leaves(&self, node: &Node) -> &[u32] {
        &self.order[node.first as usize..node.end as usize]
    }

    /// The boxes of the leaves of `node`'s subtree, in [`Self::leaves`]'s order.
    #[inline]
    fn leaf_boxes(&self, node: &Node) -> &[LeafBox] {
        &self.ordered[node.first as usize..node.end as usize]
    }

    /// The box of leaf `l` (finest-level cells).
    #[inline]
    pub fn leaf_box(&self, l: u32) -> IBox {
        self.ordered[self.position[l as usize] as usize].get()
    }

    /// The exact range of the cells (NaNs left out) of the leaves with data overlapping
    /// `region` (finest-level cells), each leaf's cells inside it; `None` when one of those
    /// leaves is coarser than level `level`. A node inside `region` adds its kept exact range,
    /// a leaf inside it its own; a leaf partly inside adds its cells there, from the blocks.
    pub fn exact_range_over<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        region: &IBox,
        level: u32,
    ) -> Result<Option<(f32, f32)>> {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        // Its own loop rather than `walk`: through `walk` this query cost 7 % more of `big`'s
        // whole extraction (callgrind, 199.0 -> 213.2 M instructions at iso 10).
        // A child is tested before it is pushed: only nodes overlapping `region` are taken.
        let mut stack = [0u32; 64];
        let mut top = usize::from(
            self.nodes
                .first()
                .is_some_and(|n| n.bounds.get().overlaps(region)),
        );
        while top > 0 {
            top -= 1;
            let i = stack[top];
            let node = &self.nodes[i as usize];
            if node.coarsest >= level && region.contains_box(&node.bounds.get()) {
                let (a, b) = self.exact_node_range(sampler, i)?;
                lo = lo.min(a);
                hi = hi.max(b);
                continue;
            }
            match node.children {
                // The tree is balanced: its depth stays far below the stack's size.
                Some(children) if top + 2 <= stack.len() => {
                    top = self.push_children(children, |b| b.overlaps(region), &mut stack, top);
                }
                _ => {
                    let (first, end) = (node.first as usize, node.end as usize);
                    let leaves = self.order[first..end].iter().zip(&self.ordered[first..end]);
                    for (&l, leaf_box) in leaves {
                        let leaf_box = &leaf_box.get();
                        if !leaf_box.overlaps(region) {
                            continue;
                        }
                        let Some((brick, lv)) = sampler.leaf_top(l) else {
                            continue;
                        };
                        if lv < level {
                            return Ok(None);
                        }
                        let (a, b) = if region.contains_box(leaf_box) {
                            self.exact_range(sampler, l)?
                        } else {
                            part_range(sampler, blocks, (brick, lv), &leaf_box.intersect(region))?
                        };
                        lo = lo.min(a);
                        hi = hi.max(b);
                    }
                }
            }
        }
        Ok(Some((lo, hi)))
    }

    /// The exact range of node `i`'s leaves' cells ([`Self::exact_range`] of each), computed on
    /// first need.
    pub fn exact_node_range<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        i: u32,
    ) -> Result<(f32, f32)> {
        let slot = &self.exact_nodes[i as usize];
        if let Some(range) = known(slot) {
            return Ok(range);
        }
        let node = &self.nodes[i as usize];
        let range = match node.children {
            Some((a, b)) => {
                let (x0, y0) = self.exact_node_range(sampler, a)?;
                let (x1, y1) = self.exact_node_range(sampler, b)?;
                (x0.min(x1), y0.max(y1))
            }
            None => {
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for &l in &self.order[node.first as usize..node.end as usize] {
                    let (a, b) = self.exact_range(sampler, l)?;
                    lo = lo.min(a);
                    hi = hi.max(b);
                }
                (lo, hi)
            }
        };
        keep(slot, range);
        Ok(range)
    }

    /// A range holding the cells of the leaves (each leaf's finest brick) inside `region`, from
    /// the `blocks` they lie in; a node lying inside `region` grown by `slack` contributes its
    /// whole range, and so does a small leaf (at most [`SMALL`] cells per axis) partly inside
    /// it: its kept range costs a load where a bound of its part costs a table walk, and is
    /// about as tight (a few blocks of the stored tables span it).
    pub fn range_over<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        region: &IBox,
        slack: [i64; 3],
    ) -> Result<(f32, f32)> {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let loose = region.grow(slack);
        self.walk(|at| -> Result<Visit> {
            let (a, b) = match at {
                At::Node(_, node) if !node.bounds.get().overlaps(region) => return Ok(Visit::Skip),
                At::Node(i, node) if loose.contains_box(&node.bounds.get()) => {
                    self.node_range(sampler, blocks, i)?
                }
                At::Node(..) => return Ok(Visit::Enter),
                At::Leaves(node) => self.leaves_range(sampler, blocks, node, region)?,
            };
            lo = lo.min(a);
            hi = hi.max(b);
            Ok(Visit::Skip)
        })?;
        Ok((lo, hi))
    }

    /// A range holding the cells inside `region` of the leaves of `node` (or of its subtree),
    /// by [`Self::range_over`]'s rule for leaves.
    fn leaves_range<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        node: &Node,
        region: &IBox,
    ) -> Result<(f32, f32)> {
        let (mut a, mut b) = (f32::INFINITY, f32::NEG_INFINITY);
        for (&l, leaf_box) in self.leaves(node).iter().zip(self.leaf_boxes(node)) {
            let leaf_box = &leaf_box.get();
            if !leaf_box.overlaps(region) {
                continue;
            }
            let Some((brick, lv)) = sampler.leaf_top(l) else {
                continue;
            };
            let (x, y) = if region.contains_box(leaf_box) || small(sampler, leaf_box, lv) {
                self.leaf_range(sampler, blocks, l)?
            } else {
                blocks.range_in(sampler, brick, lv, &leaf_box.intersect(region))?
            };
            a = a.min(x);
            b = b.max(y);
        }
        Ok((a, b))
    }

    /// The range of node `i`'s cells, computed on first need.
    fn node_range<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        i: u32,
    ) -> Result<(f32, f32)> {
        let slot = &self.ranges[i as usize];
        if let Some(range) = known(slot) {
            return Ok(range);
        }
        let node = &self.nodes[i as usize];
        let range = match node.children {
            Some((a, b)) => {
                let (x0, y0) = self.node_range(sampler, blocks, a)?;
                let (x1, y1) = self.node_range(sampler, blocks, b)?;
                (x0.min(x1), y0.max(y1))
            }
            None => {
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for &l in &self.order[node.first as usize..node.end as usize] {
                    let (a, b) = self.leaf_range(sampler, blocks, l)?;
                    lo = lo.min(a);
                    hi = hi.max(b);
                }
                (lo, hi)
            }
        };
        keep(slot, range);
        Ok(range)
    }

    /// The smallest and largest value of leaf `l`'s cells (of its finest brick, NaNs left
    /// out), computed on first need; `(+inf, -inf)` when it has none. Unlike
    /// [`Self::leaf_range`], which the stored block ranges give, this is exact: the same as
    /// folding the leaf's cells one by one.
    pub fn exact_range<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        l: u32,
    ) -> Result<(f32, f32)> {
        let slot = &self.exact_ranges[l as usize];
        if let Some(range) = known(slot) {
            return Ok(range);
        }
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        if let Some((brick, lv)) = sampler.leaf_top(l) {
            let bc = sampler.brick_cells(brick);
            let cells = level_box(sampler.grid(), lv, &self.leaf_box(l)).intersect(&bc);
            if cells == bc {
                // The leaf holds its whole brick: the range the writer stored with the brick's
                // values (NaNs left out, as below), without reading them.
                (lo, hi) = sampler.file().brick_range(sampler.field(), brick as usize);
            } else if !cells.is_empty() {
                let values = sampler.values(brick)?;
                let w = cells.extent()[0] as usize;
                for z in cells.lo[2]..cells.hi[2] {
                    for y in cells.lo[1]..cells.hi[1] {
                        let src = bc.linear_index([cells.lo[0], y, z]);
                        for &v in &values[src..src + w] {
                            // Comparisons, not f32::min: a NaN compares false and is left out.
                            if v < lo {
                                lo = v;
                            }
                            if v > hi {
                                hi = v;
                            }
                        }
                    }
                }
            }
        }
        keep(slot, (lo, hi));
        Ok((lo, hi))
    }

    /// The range of leaf `l`'s cells (of its finest brick), computed on first need.
    pub fn leaf_range<D: AsRef<[u8]>>(
        &self,
        sampler: &Sampler<'_, D>,
        blocks: &BlockRanges,
        l: u32,
    ) -> Result<(f32, f32)> {
        let slot = &self.leaf_ranges[l as usize];
        if let Some(range) = known(slot) {
            return Ok(range);
        }
        let range = match sampler.leaf_top(l) {
            Some((brick, lv)) => {
                let leaf_box = sampler.file().tree().leaf_box(l);
                blocks.range_in(sampler, brick, lv, &leaf_box)?
            }
            None => (f32::INFINITY, f32::NEG_INFINITY),
        };
        keep(slot, range);
        Ok(range)
    }
}

/// The exact range of the cells of brick `brick` (of level `level`) overlapping the finest-level
/// box `part` (NaNs left out): scanned when they are fewer than [`SCAN_CELLS`] (a part this small
/// holds no whole block of the tables), else from `blocks`.
#[inline]
fn part_range<D: AsRef<[u8]>>(
    sampler: &Sampler<'_, D>,
    blocks: &BlockRanges,
    (brick, level): (u32, u32),
    part: &IBox,
) -> Result<(f32, f32)> {
    let grid = sampler.grid();
    let cells = match grid.shift(level) {
        // `level_box` with the shifts written out: it is not inlined here.
        Some(sh) => {
            let o = grid.offset();
            IBox::new(
                axes(|a| (part.lo[a] + o[a]) >> sh[a]),
                axes(|a| (part.hi[a] + o[a] + (1 << sh[a]) - 1) >> sh[a]),
            )
        }
        None => level_box(grid, level, part),
    };
    if cells.num_cells().is_some_and(|n| n <= SCAN_CELLS) {
        let bc = sampler.brick_cells(brick);
        let cells = cells.intersect(&bc);
        return Ok(match sampler.values_in_place(brick) {
            Some(values) if cells.extent()[0] < SHORT_ROW => scan_short(values, &bc, &cells),
            _ => scan(&sampler.values(brick)?, &bc, &cells),
        });
    }
    blocks.range_of_cells(sampler, brick, &cells)
}

/// `n` range slots, every one [`UNKNOWN`].
fn unknown(n: usize) -> Vec<AtomicU64> {
    AtomicU64::new_vec_zeroed(n).unwrap_or_else(|_| (0..n).map(|_| AtomicU64::new(0)).collect())
}

/// `n` range slots, every one [`UNKNOWN`], written now: for a table that most leaves visited
/// read and then fill, where a zeroed page costs two faults (the read maps the zero page, the
/// first range kept copies it) and a written one one.
fn unknown_written(n: usize) -> Vec<AtomicU64> {
    (0..n).map(|_| AtomicU64::new(UNKNOWN)).collect()
}

/// The range kept in `slot`, if any.
#[inline]
fn known(slot: &AtomicU64) -> Option<(f32, f32)> {
    let bits = slot.load(Ordering::Relaxed);
    (bits != UNKNOWN).then(|| unpack(!bits))
}

/// Keeps `range` (never NaN, so never stored as [`UNKNOWN`]) in `slot`.
#[inline]
fn keep(slot: &AtomicU64, range: (f32, f32)) {
    slot.store(!pack(range), Ordering::Relaxed);
}

/// Fills `nodes` and `order` with the tree of the kd-tree `tree`'s shape (the file checked it
/// at open: children after their parent, every node reached once); `None`, leaving them in any
/// state, for a tree not of that form. `all` holds every leaf's box and level.
fn from_kd_tree<D: AsRef<[u8]>>(
    tree: &TreeView<'_>,
    all: &Leaves<'_, '_, D>,
    order: &mut Vec<u32>,
    nodes: &mut Vec<Node>,
) -> Option<()> {
    order.clear();
    nodes.clear();
    if tree.num_nodes() > 0 {
        from_kd_node(tree, all, 0, tree.num_nodes(), order, nodes)?;
    }
    (order.len() == all.tree.leaves.len()).then_some(())
}

/// Appends the node of the leaves under kd node `i`, whose subtree is the kd nodes `i..end`,
/// and its descendants to `nodes`, and those leaves to `order`; returns the node's index.
///
/// The kd nodes are stored depth first (checked at open): a subtree's nodes are contiguous, a
/// split's first child's subtree runs from the node after it to its second child, and a
/// subtree of `k` nodes holds `(k + 1) / 2` leaves, met in order by a scan of its nodes.
fn from_kd_node<D: AsRef<[u8]>>(
    tree: &TreeView<'_>,
    all: &Leaves<'_, '_, D>,
    i: usize,
    end: usize,
    order: &mut Vec<u32>,
    nodes: &mut Vec<Node>,
) -> Option<u32> {
    let index = nodes.len() as u32;
    let first = order.len() as u32;
    match tree.node(i)? {
        KdNode::Split { low, high, .. } if (end - i).div_ceil(2) > BUCKET => {
            if !(low < high && high < end) {
                return None;
            }
            nodes.push(Node {
                bounds: LeafBox {
                    lo: [0; 3],
                    hi: [0; 3],
                },
                coarsest: u32::MAX,
                complete: false,
                first,
                end: first,
                children: None,
            });
            let a = from_kd_node(tree, all, low, high, order, nodes)?;
            let b = from_kd_node(tree, all, high, end, order, nodes)?;
            let (na, nb) = (&nodes[a as usize], &nodes[b as usize]);
            let bounds = LeafBox::of_union(&na.bounds.get().union(&nb.bounds.get()));
            let coarsest = na.coarsest.min(nb.coarsest);
            let complete = na.complete && nb.complete;
            let node = &mut nodes[index as usize];
            node.bounds = bounds;
            node.coarsest = coarsest;
            node.complete = complete;
            node.end = order.len() as u32;
            node.children = Some((a, b));
        }
        _ => {
            // At most `BUCKET` leaves: gathered in depth-first order into one bottom node.
            let mut bounds: Option<IBox> = None;
            let mut coarsest = u32::MAX;
            let mut complete = true;
            for (j, n) in tree.nodes.get(i..end)?.iter().enumerate() {
                let KdNode::Leaf { leaf } = KdNode::decode(i + j, n) else {
                    continue;
                };
                let (b, lv) = (all.get(leaf)?, all.level(leaf));
                order.push(leaf);
                bounds = Some(bounds.map_or(b, |u| u.union(&b)));
                coarsest = coarsest.min(lv);
                complete &= lv != u32::MAX;
            }
            nodes.push(Node {
                bounds: LeafBox::of_union(&bounds?),
                coarsest,
                complete,
                first,
                end: order.len() as u32,
                children: None,
            });
        }
    }
    Some(index)
}

/// Appends the node of the leaves `leaves` (which start at `order[first]`) and its descendants to
/// `nodes`, reordering `leaves` so that each child's are contiguous; returns the node's index.
/// `all` holds every leaf's box and level (`u32::MAX` without data).
fn build<D: AsRef<[u8]>>(
    all: &Leaves<'_, '_, D>,
    leaves: &mut [u32],
    first: u32,
    nodes: &mut Vec<Node>,
) -> u32 {
    let mut bounds = leaf_bounds(&all.tree.leaves[leaves[0] as usize]);
    let mut coarsest = u32::MAX;
    let mut complete = true;
    for &l in leaves.iter() {
        let lv = all.level(l);
        bounds = bounds.union(&leaf_bounds(&all.tree.leaves[l as usize]));
        coarsest = coarsest.min(lv);
        complete &= lv != u32::MAX;
    }
    let index = nodes.len() as u32;
    let end = first + leaves.len() as u32;
    nodes.push(Node {
        bounds: LeafBox::of_union(&bounds),
        coarsest,
        complete,
        first,
        end,
        children: None,
    });
    if leaves.len() > BUCKET {
        let e = bounds.extent();
        let axis = (0..3).max_by_key(|&a| e[a]).unwrap_or(0);
        let mid = leaves.len() / 2;
        leaves.select_nth_unstable_by_key(mid, |&l| {
            let b = &all.tree.leaves[l as usize];
            u64::from(b.lo[axis].get()) + u64::from(b.hi[axis].get())
        });
        let (left, right) = leaves.split_at_mut(mid);
        let a = build(all, left, first, nodes);
        let b = build(all, right, first + mid as u32, nodes);
        nodes[index as usize].children = Some((a, b));
    }
    index
}

/// True when the finest-level box `b` of a leaf of level `level` spans at most [`SMALL`] cells
/// of that level per axis.
fn small<D: AsRef<[u8]>>(sampler: &Sampler<'_, D>, b: &IBox, level: u32) -> bool {
    let s = sampler.grid().scale(level);
    (0..3).all(|a| b.hi[a] - b.lo[a] <= SMALL * s[a])
}
