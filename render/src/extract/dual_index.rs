//! Where the merged dual cells of a leaf read their eight values in the leaf's brick, worked out
//! once per leaf, so that decoding one of them is an index and eight loads.

use amr_format::IBox;

/// The x-fastest index in a brick's values of a level cell `c`, as
/// `origin + c[0] + c[1] * row + c[2] * layer`, for a box of dual cells whose eight cells all lie
/// in the brick ([`DualIndex::new`]).
#[derive(Clone, Copy, Debug)]
pub struct DualIndex {
    origin: i64,
    row: i64,
    layer: i64,
}

impl DualIndex {
    /// The index into a brick of cells `brick` for the dual cells whose lowest cells are `duals`;
    /// `None` unless the brick holds the eight cells of each of them (the lowest cell and the one
    /// above it on every axis).
    pub fn new(brick: &IBox, duals: &IBox) -> Option<Self> {
        let inside = (0..3).all(|a| {
            duals.lo[a] < duals.hi[a] && brick.lo[a] <= duals.lo[a] && duals.hi[a] < brick.hi[a]
        });
        if !inside {
            return None;
        }
        let e = brick.extent();
        let (row, layer) = (e[0], e[0] * e[1]);
        Some(Self {
            origin: -(brick.lo[0] + brick.lo[1] * row + brick.lo[2] * layer),
            row,
            layer,
        })
    }

    /// The value of level cell `c` (a corner of a dual cell of the box this index was made for)
    /// in the brick's values `values`: the one [`Self::block`] reads for that corner. `None`
    /// when `values` is too short.
    #[inline(always)]
    pub fn cell(&self, values: &[f32], c: [i64; 3]) -> Option<f32> {
        let at = (self.origin + c[0] + c[1] * self.row + c[2] * self.layer) as usize;
        values.get(at).copied()
    }

    /// The values of the dual cell whose lowest cell is `cell` (one of the box this index was
    /// made for) in the brick's values `values`, corner `n` taking the upper cell on axis `a` when
    /// bit `a` of `n` is set: [`crate::reconstruct::Sampler::brick_block`]'s values, read at the
    /// same indices (the index is the same integer), without its per-cell bounds. `None` when
    /// `values` is too short.
    #[inline(always)]
    pub fn block(&self, values: &[f32], cell: [i64; 3]) -> Option<[f32; 8]> {
        let first = (self.origin + cell[0] + cell[1] * self.row + cell[2] * self.layer) as usize;
        let (row, layer) = (self.row as usize, self.layer as usize);
        let b = values.get(first..=first + 1 + row + layer)?;
        let up = layer + row;
        Some([
            b[0],
            b[1],
            b[row],
            b[row + 1],
            b[layer],
            b[layer + 1],
            b[up],
            b[up + 1],
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_what_the_checked_block_reads() {
        let brick = IBox::new([-3, 2, 5], [4, 7, 9]);
        let values: Vec<f32> = (0..7 * 5 * 4).map(|i| i as f32 * 0.5 - 3.0).collect();
        let duals = IBox::new([-3, 2, 5], [3, 6, 8]);
        let index = DualIndex::new(&brick, &duals).unwrap();
        for z in duals.lo[2]..duals.hi[2] {
            for y in duals.lo[1]..duals.hi[1] {
                for x in duals.lo[0]..duals.hi[0] {
                    let c = [x, y, z];
                    let want = [0, 1, 2, 3, 4, 5, 6, 7].map(|n: usize| {
                        let at = [0, 1, 2].map(|a| c[a] + (n >> a & 1) as i64 - brick.lo[a]);
                        values[(at[0] + 7 * (at[1] + 5 * at[2])) as usize]
                    });
                    assert_eq!(index.block(&values, c), Some(want), "{c:?}");
                }
            }
        }
        assert_eq!(
            index.block(&values[..values.len() - 1], [3 - 1, 6 - 1, 8 - 1]),
            None
        );
        let corner = [3, 6, 8];
        let at = [0, 1, 2].map(|a| corner[a] - brick.lo[a]);
        let want = values[(at[0] + 7 * (at[1] + 5 * at[2])) as usize];
        assert_eq!(index.cell(&values, corner), Some(want));
    }

    #[test]
    fn only_for_duals_whose_cells_lie_in_the_brick() {
        let brick = IBox::new([0, 0, 0], [4, 4, 4]);
        assert!(DualIndex::new(&brick, &IBox::new([0, 0, 0], [3, 3, 3])).is_some());
        assert!(DualIndex::new(&brick, &IBox::new([0, 0, 0], [4, 3, 3])).is_none());
        assert!(DualIndex::new(&brick, &IBox::new([-1, 0, 0], [3, 3, 3])).is_none());
        assert!(DualIndex::new(&brick, &IBox::new([0, 0, 0], [0, 3, 3])).is_none());
    }
}
