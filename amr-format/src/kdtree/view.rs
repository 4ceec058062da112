//! Walking a stored kd-tree: point location and region queries over the raw node arrays.

use crate::geometry::IBox;
use crate::raw::{KdLeaf, KdNode, KD_LEAF};

/// A kd-tree read in place: its nodes, its leaves and the domain the root covers.
///
/// The node arrays must have passed the reader's structural checks (every inner node's
/// children come after it and exist), which is what makes every walk terminate.
#[derive(Clone, Copy, Debug)]
pub struct TreeView<'a> {
    /// Nodes, depth first.
    pub nodes: &'a [KdNode],
    /// Leaves.
    pub leaves: &'a [KdLeaf],
    /// The root's region: `[0, extent)` in finest-level cells.
    pub domain: IBox,
}

impl<'a> TreeView<'a> {
    /// The leaf containing finest-level cell `p`, or `None` outside the domain.
    pub fn find_leaf(&self, p: [i64; 3]) -> Option<u32> {
        if !self.domain.contains_cell(p) || self.nodes.is_empty() {
            return None;
        }
        let mut i = 0usize;
        loop {
            let n = self.nodes.get(i)?;
            let kind = n.b.get() & 3;
            if kind == KD_LEAF {
                return Some(n.a.get());
            }
            i = if p[kind as usize] < i64::from(n.a.get()) {
                i + 1
            } else {
                (n.b.get() >> 2) as usize
            };
        }
    }

    /// Calls `f` with every leaf whose closed box touches the closed `region`
    /// (sharing only a face, an edge or a corner counts).
    pub fn for_each_leaf_touching(&self, region: &IBox, mut f: impl FnMut(u32)) {
        if self.nodes.is_empty() || !self.domain.touches(region) {
            return;
        }
        let mut stack = vec![(0usize, self.domain)];
        while let Some((i, r)) = stack.pop() {
            let Some(n) = self.nodes.get(i) else { continue };
            let kind = n.b.get() & 3;
            if kind == KD_LEAF {
                f(n.a.get());
                continue;
            }
            let axis = kind as usize;
            let at = i64::from(n.a.get());
            let (mut left, mut right) = (r, r);
            left.hi[axis] = at;
            right.lo[axis] = at;
            if region.touches(&right) {
                stack.push(((n.b.get() >> 2) as usize, right));
            }
            if region.touches(&left) {
                stack.push((i + 1, left));
            }
        }
    }

    /// The box of leaf `leaf` in finest-level cells relative to the domain.
    #[inline]
    pub fn leaf_box(&self, leaf: u32) -> IBox {
        let l = &self.leaves[leaf as usize];
        IBox::new(
            l.lo.map(|v| i64::from(v.get())),
            l.hi.map(|v| i64::from(v.get())),
        )
    }
}
