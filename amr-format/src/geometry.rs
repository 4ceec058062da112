//! Integer boxes in a level's index space and the arithmetic between levels.

/// A half-open box of cells `[lo, hi)` in some level's integer index space.
///
/// Every box in this crate is half-open; readers of formats that store inclusive upper
/// corners (AMReX, Chombo) add one when they build an `IBox`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct IBox {
    /// Lowest cell index on each axis (inclusive).
    pub lo: [i64; 3],
    /// One past the highest cell index on each axis (exclusive).
    pub hi: [i64; 3],
}

impl IBox {
    /// A box from its inclusive lower and exclusive upper corners.
    pub const fn new(lo: [i64; 3], hi: [i64; 3]) -> Self {
        Self { lo, hi }
    }

    /// Number of cells along each axis (0 for an empty or inverted axis).
    #[inline]
    pub fn extent(&self) -> [i64; 3] {
        [0, 1, 2].map(|a| (self.hi[a] - self.lo[a]).max(0))
    }

    /// True when the box holds no cell.
    #[inline]
    pub fn is_empty(&self) -> bool {
        (0..3).any(|a| self.hi[a] <= self.lo[a])
    }

    /// Number of cells, or `None` on overflow.
    #[inline]
    pub fn num_cells(&self) -> Option<u64> {
        let e = self.extent();
        (e[0] as u64)
            .checked_mul(e[1] as u64)?
            .checked_mul(e[2] as u64)
    }

    /// The common part of two boxes (possibly empty).
    #[inline]
    pub fn intersect(&self, other: &IBox) -> IBox {
        IBox {
            lo: [0, 1, 2].map(|a| self.lo[a].max(other.lo[a])),
            hi: [0, 1, 2].map(|a| self.hi[a].min(other.hi[a])),
        }
    }

    /// The smallest box holding both boxes.
    #[inline]
    pub fn union(&self, other: &IBox) -> IBox {
        IBox {
            lo: [0, 1, 2].map(|a| self.lo[a].min(other.lo[a])),
            hi: [0, 1, 2].map(|a| self.hi[a].max(other.hi[a])),
        }
    }

    /// True when the boxes share at least one cell.
    #[inline]
    pub fn overlaps(&self, other: &IBox) -> bool {
        (0..3).all(|a| self.lo[a] < other.hi[a] && other.lo[a] < self.hi[a])
    }

    /// True when the closed boxes share at least a point (a shared face, edge or corner counts).
    #[inline]
    pub fn touches(&self, other: &IBox) -> bool {
        (0..3).all(|a| self.lo[a] <= other.hi[a] && other.lo[a] <= self.hi[a])
    }

    /// True when `other` lies entirely inside `self`.
    #[inline]
    pub fn contains_box(&self, other: &IBox) -> bool {
        (0..3).all(|a| self.lo[a] <= other.lo[a] && other.hi[a] <= self.hi[a])
    }

    /// True when the cell `p` lies inside the box.
    #[inline]
    pub fn contains_cell(&self, p: [i64; 3]) -> bool {
        (0..3).all(|a| self.lo[a] <= p[a] && p[a] < self.hi[a])
    }

    /// The box grown by `by[a]` cells on both sides of each axis.
    #[inline]
    pub fn grow(&self, by: [i64; 3]) -> IBox {
        IBox {
            lo: [0, 1, 2].map(|a| self.lo[a] - by[a]),
            hi: [0, 1, 2].map(|a| self.hi[a] + by[a]),
        }
    }

    /// The same cells in an index space `factor` times finer (`None` on overflow).
    #[inline]
    pub fn refine(&self, factor: [i64; 3]) -> Option<IBox> {
        let mut out = IBox::default();
        for a in 0..3 {
            out.lo[a] = self.lo[a].checked_mul(factor[a])?;
            out.hi[a] = self.hi[a].checked_mul(factor[a])?;
        }
        Some(out)
    }

    /// The coarse cells, `factor` times coarser, that cover this box.
    #[inline]
    pub fn coarsen(&self, factor: [i64; 3]) -> IBox {
        IBox {
            lo: [0, 1, 2].map(|a| self.lo[a].div_euclid(factor[a])),
            hi: [0, 1, 2].map(|a| (self.hi[a] + factor[a] - 1).div_euclid(factor[a])),
        }
    }

    /// Linear index of cell `p` inside this box, x fastest. `p` must lie inside.
    #[inline]
    pub fn linear_index(&self, p: [i64; 3]) -> usize {
        let e = self.extent();
        let (x, y, z) = (p[0] - self.lo[0], p[1] - self.lo[1], p[2] - self.lo[2]);
        (x + e[0] * (y + e[1] * z)) as usize
    }

    /// Splits the box into pieces of at most `max` cells per axis, in x-fastest order.
    ///
    /// The pieces start at `lo` and step by `max`; the last one on each axis may be smaller.
    pub fn split(&self, max: [i64; 3]) -> Vec<IBox> {
        let mut out = Vec::new();
        if self.is_empty() {
            return out;
        }
        let starts = |a: usize| (self.lo[a]..self.hi[a]).step_by(max[a].max(1) as usize);
        for z in starts(2) {
            for y in starts(1) {
                for x in starts(0) {
                    let lo = [x, y, z];
                    let hi = [0, 1, 2].map(|a| (lo[a] + max[a].max(1)).min(self.hi[a]));
                    out.push(IBox { lo, hi });
                }
            }
        }
        out
    }
}

/// Copies the cells of `dst_box` out of `src`, whose values cover `src_box` (x fastest).
///
/// `dst_box` must lie inside `src_box`; `src.len()` must equal `src_box`'s cell count.
pub fn copy_subbox<T: Copy>(src: &[T], src_box: &IBox, dst_box: &IBox, dst: &mut Vec<T>) {
    debug_assert!(src_box.contains_box(dst_box));
    dst.clear();
    let e = dst_box.extent();
    let row = e[0] as usize;
    for z in dst_box.lo[2]..dst_box.hi[2] {
        for y in dst_box.lo[1]..dst_box.hi[1] {
            let start = src_box.linear_index([dst_box.lo[0], y, z]);
            dst.extend_from_slice(&src[start..start + row]);
        }
    }
}

/// Writes `src`, the values of `src_box` (x fastest), into `dst`, the values of `dst_box`: the
/// inverse of [`copy_subbox`].
///
/// `src_box` must lie inside `dst_box`; the lengths must equal the boxes' cell counts.
pub fn paste_subbox<T: Copy>(src: &[T], src_box: &IBox, dst: &mut [T], dst_box: &IBox) {
    debug_assert!(dst_box.contains_box(src_box));
    let row = src_box.extent()[0] as usize;
    if row == 0 {
        return;
    }
    let mut rows = src.chunks_exact(row);
    for z in src_box.lo[2]..src_box.hi[2] {
        for y in src_box.lo[1]..src_box.hi[1] {
            let start = dst_box.linear_index([src_box.lo[0], y, z]);
            if let Some(values) = rows.next() {
                dst[start..start + row].copy_from_slice(values);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box's cell count, `None` past `u64` (a brick of such a box is never counted whole by
    /// the renderer's sampler), zero for an empty box.
    #[test]
    fn num_cells_is_checked() {
        assert_eq!(IBox::new([0; 3], [2, 3, 4]).num_cells(), Some(24));
        assert_eq!(IBox::new([5; 3], [5, 9, 9]).num_cells(), Some(0));
        let big = 1i64 << 32;
        assert_eq!(
            IBox::new([0; 3], [big, big / 2, 1]).num_cells(),
            Some(1 << 63)
        );
        assert_eq!(IBox::new([0; 3], [big, big, 1]).num_cells(), None);
    }

    #[test]
    fn split_covers_box_exactly() {
        let b = IBox::new([-3, 0, 5], [10, 7, 6]);
        let parts = b.split([4, 4, 4]);
        let total: u64 = parts.iter().map(|p| p.num_cells().unwrap()).sum();
        assert_eq!(total, b.num_cells().unwrap());
        for (i, p) in parts.iter().enumerate() {
            assert!(b.contains_box(p));
            for q in &parts[i + 1..] {
                assert!(!p.overlaps(q));
            }
        }
    }

    #[test]
    fn copy_subbox_picks_the_right_cells() {
        let src_box = IBox::new([0, 0, 0], [4, 3, 2]);
        let src: Vec<usize> = (0..24).collect();
        let dst_box = IBox::new([1, 1, 1], [3, 3, 2]);
        let mut dst = Vec::new();
        copy_subbox(&src, &src_box, &dst_box, &mut dst);
        let expect: Vec<usize> = [[1, 1, 1], [2, 1, 1], [1, 2, 1], [2, 2, 1]]
            .iter()
            .map(|&p| src_box.linear_index(p))
            .collect();
        assert_eq!(dst, expect);
    }

    #[test]
    fn paste_subbox_undoes_copy_subbox() {
        let whole = IBox::new([2, 0, 1], [6, 3, 3]);
        let src: Vec<u32> = (0..24).collect();
        let part = IBox::new([3, 1, 1], [5, 3, 2]);
        let mut cut = Vec::new();
        copy_subbox(&src, &whole, &part, &mut cut);
        let mut back = vec![99; 24];
        paste_subbox(&cut, &part, &mut back, &whole);
        for (i, (&b, &s)) in back.iter().zip(&src).enumerate() {
            let cell = [2 + i as i64 % 4, i as i64 / 4 % 3, 1 + i as i64 / 12];
            assert_eq!(
                b,
                if part.contains_cell(cell) { s } else { 99 },
                "cell {cell:?}"
            );
        }
    }

    #[test]
    fn coarsen_covers_and_refine_scales() {
        let b = IBox::new([-3, 1, 4], [5, 2, 8]);
        let c = b.coarsen([2, 2, 2]);
        assert_eq!(c, IBox::new([-2, 0, 2], [3, 1, 4]));
        assert!(c.refine([2, 2, 2]).unwrap().contains_box(&b));
    }
}
