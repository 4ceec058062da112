//! Walking a stored kd-tree: typed nodes, point location, region queries and the front-to-back
//! order, over the raw node arrays.

use crate::geometry::IBox;
use crate::raw::{self, KdLeaf, KD_LEAF};

/// One kd-tree node, decoded from its stored [`raw::KdNode`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KdNode {
    /// A leaf: index `leaf` into the leaf table.
    Leaf {
        /// The leaf's index.
        leaf: u32,
    },
    /// An inner node splitting its region at plane `pos` on `axis`.
    Split {
        /// 0, 1 or 2 (x, y, z).
        axis: usize,
        /// The plane, in finest-level cells relative to the domain's lower corner: cells below
        /// it go to `low`, the others to `high`.
        pos: i64,
        /// Index of the child below the plane (the node right after this one).
        low: usize,
        /// Index of the child at or above the plane.
        high: usize,
    },
}

impl KdNode {
    /// Decodes node `index` as stored in `node`.
    #[inline]
    pub fn decode(index: usize, node: &raw::KdNode) -> Self {
        let (a, b) = (node.a.get(), node.b.get());
        if b & 3 == KD_LEAF {
            KdNode::Leaf { leaf: a }
        } else {
            KdNode::Split {
                axis: (b & 3) as usize,
                pos: i64::from(a),
                low: index + 1,
                high: (b >> 2) as usize,
            }
        }
    }

    /// The two halves of `region` split by this node (`None` for a leaf).
    #[inline]
    pub fn halves(&self, region: &IBox) -> Option<(IBox, IBox)> {
        let KdNode::Split { axis, pos, .. } = *self else {
            return None;
        };
        let (mut low, mut high) = (*region, *region);
        low.hi[axis] = pos;
        high.lo[axis] = pos;
        Some((low, high))
    }
}

/// A kd-tree read in place: its nodes, its leaves and the domain the root covers.
///
/// The node arrays must be a proper tree whose split planes lie inside their regions, as
/// [`crate::AmrkFile::open`] checks and the builder produces: that is what makes every walk
/// terminate and every leaf box the region the walk reaches it with.
#[derive(Clone, Copy, Debug)]
pub struct TreeView<'a> {
    /// Nodes as stored, depth first (decode with [`TreeView::node`]).
    pub nodes: &'a [raw::KdNode],
    /// Leaves.
    pub leaves: &'a [KdLeaf],
    /// The root's region: `[0, extent)` in finest-level cells.
    pub domain: IBox,
}

impl<'a> TreeView<'a> {
    /// Node `i`, decoded; `None` past the end.
    #[inline]
    pub fn node(&self, i: usize) -> Option<KdNode> {
        self.nodes.get(i).map(|n| KdNode::decode(i, n))
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of leaves.
    pub fn num_leaves(&self) -> usize {
        self.leaves.len()
    }

    /// The leaf containing finest-level cell `p`, or `None` outside the domain.
    pub fn find_leaf(&self, p: [i64; 3]) -> Option<u32> {
        if !self.domain.contains_cell(p) {
            return None;
        }
        self.find_leaf_from(0, p)
    }

    /// The leaf containing finest-level cell `p`, walking down from node `node`, whose box must
    /// contain `p` (a shortcut past the upper levels for callers that know such a node);
    /// `None` for a node index out of range.
    pub fn find_leaf_from(&self, node: usize, p: [i64; 3]) -> Option<u32> {
        let mut i = node;
        loop {
            match self.node(i)? {
                KdNode::Leaf { leaf } => return Some(leaf),
                KdNode::Split {
                    axis,
                    pos,
                    low,
                    high,
                } => i = if p[axis] < pos { low } else { high },
            }
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
            let Some(node) = self.node(i) else { continue };
            match node {
                KdNode::Leaf { leaf } => f(leaf),
                KdNode::Split { low, high, .. } => {
                    let (lo_half, hi_half) = node.halves(&r).expect("a split has halves");
                    if region.touches(&hi_half) {
                        stack.push((high, hi_half));
                    }
                    if region.touches(&lo_half) {
                        stack.push((low, lo_half));
                    }
                }
            }
        }
    }

    /// Every leaf front to back as seen from `eye` (finest-level cell coordinates): at each
    /// split the eye's side comes first, so any ray from the eye meets leaves in this order.
    pub fn front_to_back(&self, eye: [f64; 3]) -> Vec<u32> {
        let mut order = Vec::with_capacity(self.leaves.len());
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            match self.node(i) {
                None => {}
                Some(KdNode::Leaf { leaf }) => order.push(leaf),
                Some(KdNode::Split {
                    axis,
                    pos,
                    low,
                    high,
                }) => {
                    if eye[axis] < pos as f64 {
                        stack.extend([high, low]);
                    } else {
                        stack.extend([low, high]);
                    }
                }
            }
        }
        order
    }

    /// The box of leaf `leaf` in finest-level cells relative to the domain.
    #[inline]
    pub fn leaf_box(&self, leaf: u32) -> IBox {
        leaf_bounds(&self.leaves[leaf as usize])
    }
}

/// The box of a stored leaf, its corners widened to `i64` (spelled out per axis: a map over the
/// arrays was not always inlined, and each leaf's box is read at open and by every walk).
#[inline]
pub fn leaf_bounds(l: &KdLeaf) -> IBox {
    let (lo, hi) = (&l.lo, &l.hi);
    IBox::new(
        [lo[0].get().into(), lo[1].get().into(), lo[2].get().into()],
        [hi[0].get().into(), hi[1].get().into(), hi[2].get().into()],
    )
}
