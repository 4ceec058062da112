//! The bricks no finer brick overlaps, whose every cell a leaf of theirs may read in place.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

use amr_format::{AmrkFile, IBox};

use super::grid::Grid;

/// Per brick of a file, its finest cells (relative, `lo` then `hi`) when no finer brick overlaps
/// it, else all zero (a brick's `hi` is never zero); built once, by the first thread that asks
/// for it, while the threads asking meanwhile go on without it.
///
/// A thread that asks while another builds the table is told `None` rather than made to wait:
/// its caller reads the cells of the leaf's own box instead, located rather than read in place
/// beyond it, which gives the same values (`Sampler::read_box`). An extraction of thousands of
/// small bricks otherwise held every other thread for the build (about 1.5 ms for 46,000
/// bricks), at the first boundary octant of its first isovalue.
#[derive(Debug, Default)]
pub(super) struct AloneBricks {
    table: OnceLock<Vec<[u32; 6]>>,
    building: AtomicBool,
}

impl AloneBricks {
    /// The table, built now by this thread when no thread has started it; `None` while
    /// another thread builds it.
    #[inline(always)]
    pub(super) fn get<D: AsRef<[u8]>>(
        &self,
        file: &AmrkFile<D>,
        grid: &Grid,
    ) -> Option<&[[u32; 6]]> {
        match self.table.get() {
            Some(t) => Some(t),
            None => self.build(file, grid),
        }
    }

    /// Marks the table as being built by a thread that never finishes: every later
    /// [`Self::get`] answers `None`.
    pub(super) fn hold(&self) {
        self.building.store(true, Ordering::Relaxed);
    }

    #[cold]
    #[inline(never)]
    fn build<D: AsRef<[u8]>>(&self, file: &AmrkFile<D>, grid: &Grid) -> Option<&[[u32; 6]]> {
        if self.building.swap(true, Ordering::Acquire) {
            // Another thread builds it, or has just built it.
            return self.table.get().map(Vec::as_slice);
        }
        Some(self.table.get_or_init(|| alone_boxes(file, grid)))
    }
}

/// Per brick of `file`, its finest cells (relative, `lo` then `hi`) when no finer brick overlaps
/// it, else all zero.
///
/// A brick is so when the kd-tree leaves whose first brick it is fill it: `open` checked that
/// the leaves tile the domain and that a leaf's first brick covers the leaf, so those leaves lie
/// in the brick without overlapping, and every finest cell of the brick is in one.
fn alone_boxes<D: AsRef<[u8]>>(file: &AmrkFile<D>, grid: &Grid) -> Vec<[u32; 6]> {
    // Per brick: the finest cells of the leaves whose first brick it is (`u64::MAX` past `u64`).
    let mut first_of = vec![0u64; file.num_bricks()];
    for l in file.leaves() {
        if let Some(sum) = l
            .bricks
            .first()
            .and_then(|b| first_of.get_mut(b.get() as usize))
        {
            *sum = volume(&l.bounds)
                .and_then(|v| sum.checked_add(v))
                .unwrap_or(u64::MAX);
        }
    }
    file.bricks()
        .zip(&first_of)
        .map(|(b, &covered)| {
            // Cannot overflow: a brick lies in its level's domain, which refines into the
            // finest domain (32-bit coordinates).
            let f = grid.level_finest_box(b.level, &b.cells);
            let corners = [f.lo[0], f.lo[1], f.lo[2], f.hi[0], f.hi[1], f.hi[2]];
            match corners.map(|x| u32::try_from(x).ok()) {
                [Some(x0), Some(y0), Some(z0), Some(x1), Some(y1), Some(z1)]
                    if covered != u64::MAX && volume(&f) == Some(covered) =>
                {
                    [x0, y0, z0, x1, y1, z1]
                }
                _ => [0; 6],
            }
        })
        .collect()
}

/// The number of finest cells of box `b`, `None` past `u64`.
fn volume(b: &IBox) -> Option<u64> {
    b.extent()
        .iter()
        .try_fold(1u64, |n, &e| n.checked_mul(e.max(0) as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box's finest cells count, `None` past `u64` (a brick of such a box is never marked
    /// alone), zero for an empty box.
    #[test]
    fn volume_is_checked() {
        assert_eq!(volume(&IBox::new([0; 3], [2, 3, 4])), Some(24));
        assert_eq!(volume(&IBox::new([5; 3], [5, 9, 9])), Some(0));
        let big = 1i64 << 32;
        assert_eq!(volume(&IBox::new([0; 3], [big, big / 2, 1])), Some(1 << 63));
        assert_eq!(volume(&IBox::new([0; 3], [big, big, 1])), None);
    }
}
