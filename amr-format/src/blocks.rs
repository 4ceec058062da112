//! Block range tables: the value range of each block of `b^3` cells of a brick, x fastest, so
//! that a reader can bound any box of a brick's cells without reading its values. The writer
//! stores one per brick and field (layout version 2); readers of older files build them.

use crate::geometry::IBox;

/// Blocks per axis of a brick whose cells are `cells`, for blocks of `block` cells per axis
/// (the last block along an axis is cut short by the brick's end).
pub fn blocks_per_axis(cells: &IBox, block: i64) -> [i64; 3] {
    cells.extent().map(|e| (e.max(0) + block - 1) / block)
}

/// Number of blocks of a brick whose cells are `cells`; `None` on overflow.
pub fn block_count(cells: &IBox, block: i64) -> Option<u64> {
    blocks_per_axis(cells, block)
        .iter()
        .try_fold(1u64, |n, &k| n.checked_mul(u64::try_from(k).ok()?))
}

/// The block ranges of brick data `values` (cells `cells`, x fastest), blocks x fastest, each
/// `(min, max)`. NaNs are left out: a block of NaNs only gets `(+inf, -inf)`.
pub fn block_ranges(values: &[f32], cells: &IBox, block: i64) -> Vec<(f32, f32)> {
    let e = cells.extent().map(|v| v as usize);
    let n = blocks_per_axis(cells, block).map(|v| v as usize);
    let b = block as usize;
    let mut table = vec![(f32::INFINITY, f32::NEG_INFINITY); n[0] * n[1] * n[2]];
    for z in 0..e[2] {
        for y in 0..e[1] {
            let src = &values[(z * e[1] + y) * e[0]..][..e[0]];
            let row = &mut table[(z / b * n[1] + y / b) * n[0]..][..n[0]];
            for (slot, run) in row.iter_mut().zip(src.chunks(b)) {
                for &v in run {
                    // Comparisons, not f32::min: a NaN compares false and is left out.
                    if v < slot.0 {
                        slot.0 = v;
                    }
                    if v > slot.1 {
                        slot.1 = v;
                    }
                }
            }
        }
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_holds_each_blocks_range() {
        let bc = IBox::new([10, 0, 0], [15, 6, 1]);
        let values: Vec<f32> = (0..30).map(|i| i as f32).collect();
        let table = block_ranges(&values, &bc, 4);
        // Blocks are 4 wide: x 0..4 and 4..5; y 0..4 and 4..6.
        assert_eq!(table.len(), 4);
        assert_eq!(block_count(&bc, 4), Some(4));
        assert_eq!(table[0], (0.0, 18.0));
        assert_eq!(table[1], (4.0, 19.0));
        assert_eq!(table[2], (20.0, 28.0));
        assert_eq!(table[3], (24.0, 29.0));
    }

    #[test]
    fn nan_only_block_is_empty() {
        let bc = IBox::new([0, 0, 0], [2, 1, 1]);
        assert_eq!(
            block_ranges(&[f32::NAN, f32::NAN], &bc, 4),
            vec![(f32::INFINITY, f32::NEG_INFINITY)]
        );
    }
}
