//! The kd-tree leaves an evaluation located last, tried before the kd-tree is walked again.
//!
//! The vertices a thread evaluates one after another lie close together, so the leaf holding a
//! vertex's first side is often one that held a side of the vertex before. A finest cell inside
//! a remembered leaf's box lies in that leaf (leaves tile the domain), whose finest brick holds
//! its leaf cell: read from the brick when it is read in place, that is the locate's answer. A
//! hint therefore changes how fast a cell is found, never which cell.

use amr_format::IBox;

use crate::error::Result;

use super::leaf_grid::Entry;
use super::mixed::holds;
use super::sampler::{LeafCell, Locate, Sampler, VertexMemo};

/// Leaves remembered: the last few a neighbourhood of vertices touches.
const HINTS: usize = 4;

/// The kd-tree leaves located last (with their boxes, relative finest cells) for one sampler,
/// replaced in turn.
#[derive(Clone, Copy)]
pub(super) struct LeafHints {
    /// The sampler the leaves are of ([`Sampler::id`]; 0: none yet).
    owner: u64,
    leaves: [(u32, IBox); HINTS],
    /// Leaves remembered so far (at most [`HINTS`]).
    len: usize,
    /// The slot the next leaf replaces once all are in use.
    next: usize,
}

impl Default for LeafHints {
    fn default() -> Self {
        Self {
            owner: 0,
            leaves: [(0, IBox::new([0; 3], [0; 3])); HINTS],
            len: 0,
            next: 0,
        }
    }
}

impl LeafHints {
    /// Forgets every leaf.
    pub(super) fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    fn remember(&mut self, leaf: u32, b: IBox) {
        if self.len < HINTS {
            self.leaves[self.len] = (leaf, b);
            self.len += 1;
        } else {
            self.leaves[self.next] = (leaf, b);
            self.next = (self.next + 1) % HINTS;
        }
    }
}

impl<D: AsRef<[u8]>> Sampler<'_, D> {
    /// The leaf cell at finest cell `f` ([`Locate::locate_cell`]'s answer) and its kd-tree
    /// leaf's box. Where the leaf grid names a node to walk from, a leaf of `hints` whose box
    /// holds `f` is taken instead of the walk (and a leaf walked to is remembered there). A
    /// cell of a leaf whose brick is read in place is read from it, the others located through
    /// `loc`.
    #[inline(always)]
    pub(super) fn locate_hinted<L: Locate>(
        &self,
        loc: &L,
        f: [i64; 3],
        hints: &mut LeafHints,
    ) -> Result<Option<(LeafCell, IBox)>> {
        let leaf = match self.grid_entry(f) {
            Some(Entry::Leaf(leaf)) => Some(leaf),
            Some(Entry::Node(node)) => {
                if hints.owner != self.id() {
                    *hints = LeafHints {
                        owner: self.id(),
                        ..LeafHints::default()
                    };
                }
                let hint = hints.leaves[..hints.len]
                    .iter()
                    .find(|(_, b)| holds(b, f))
                    .copied();
                if let Some((leaf, b)) = hint {
                    if let Some(c) = self.cell_in_leaf_numbered(leaf, f) {
                        return Ok(Some((c, b)));
                    }
                }
                let leaf = self.find_leaf_from(node, f);
                if let Some(c) = leaf.and_then(|l| self.cell_in_leaf_numbered(l, f)) {
                    let b = self.leaf_box(c.leaf);
                    hints.remember(c.leaf, b);
                    return Ok(Some((c, b)));
                }
                leaf
            }
            None => None,
        };
        if let Some(c) = leaf.and_then(|l| self.cell_in_leaf_numbered(l, f)) {
            return Ok(Some((c, self.leaf_box(c.leaf))));
        }
        let Some(c) = loc.locate_cell(f)? else {
            return Ok(None);
        };
        Ok(Some((c, self.leaf_box(c.leaf))))
    }

    /// The leaf cell at finest cell `f`, [`Self::locate`]'s answer: read from the brick of the
    /// kd-tree leaf found last (`last`, with its box) when that box holds `f`, else located
    /// through the leaves `memo` remembers ([`Self::locate_hinted`]); the leaf found becomes
    /// `last`. For callers that locate several nearby cells in turn.
    #[inline]
    pub fn locate_near(
        &self,
        f: [i64; 3],
        memo: &mut VertexMemo,
        last: &mut Option<(LeafCell, IBox)>,
    ) -> Result<Option<LeafCell>> {
        if let Some(c) = last.and_then(|(c, b)| self.cell_in_leaf(&c, &b, f)) {
            return Ok(Some(c));
        }
        let found = self.locate_hinted(self, f, &mut memo.hints)?;
        if found.is_some() {
            *last = found;
        }
        Ok(found.map(|(c, _)| c))
    }
}
