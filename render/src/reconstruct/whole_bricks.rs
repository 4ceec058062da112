//! Whole bricks: those no finer brick overlaps, whose every cell a leaf of theirs may read in
//! place.

use amr_format::IBox;

/// Per brick, the finest cells of the kd-tree leaves whose first brick it is, summed while the
/// sampler reads the leaves; then, per brick, whether those leaves fill it.
///
/// They fill it when no finer brick overlaps it: `open` checked that the leaves tile the
/// domain and that a leaf's first brick covers the leaf, so those leaves lie in the brick
/// without overlapping, and every finest cell of the brick is in one.
pub(super) struct LeafCover {
    /// Per brick: the finest cells counted so far (`u64::MAX` past `u64`).
    cells: Vec<u64>,
}

impl LeafCover {
    /// Nothing counted yet, for `bricks` bricks.
    pub(super) fn new(bricks: usize) -> Self {
        Self {
            cells: vec![0; bricks],
        }
    }

    /// Counts a leaf of finest cells `bounds` whose first brick is `brick`.
    #[inline]
    pub(super) fn add(&mut self, brick: u32, bounds: &IBox) {
        if let Some(sum) = self.cells.get_mut(brick as usize) {
            *sum = bounds
                .num_cells()
                .and_then(|v| sum.checked_add(v))
                .unwrap_or(u64::MAX);
        }
    }

    /// Per brick (its finest cells, in brick order): true when the leaves counted fill it.
    pub(super) fn whole_bricks(self, finest: impl Iterator<Item = IBox>) -> Vec<bool> {
        finest
            .zip(&self.cells)
            .map(|(f, &covered)| covered != u64::MAX && f.num_cells() == Some(covered))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A brick is whole when its leaves' cells add up to its own, and not when a finer brick
    /// took part of it (its leaves then cover less) or the count passed `u64`.
    #[test]
    fn bricks_filled_by_their_leaves_are_whole() {
        let bricks = [
            IBox::new([0; 3], [4, 4, 4]),
            IBox::new([4, 0, 0], [8, 4, 4]),
            IBox::new([0; 3], [1 << 32, 1 << 32, 1]),
        ];
        let mut cover = LeafCover::new(bricks.len());
        // Brick 0 in two leaves; brick 1 with a quarter left to a finer brick.
        cover.add(0, &IBox::new([0; 3], [2, 4, 4]));
        cover.add(0, &IBox::new([2, 0, 0], [4, 4, 4]));
        cover.add(1, &IBox::new([4, 0, 0], [8, 4, 2]));
        cover.add(1, &IBox::new([4, 0, 2], [6, 4, 4]));
        cover.add(2, &bricks[2]);
        cover.add(2, &bricks[2]);
        // A brick number past the table is ignored.
        cover.add(7, &bricks[0]);
        assert_eq!(cover.whole_bricks(bricks.into_iter()), [true, false, false]);
    }
}
