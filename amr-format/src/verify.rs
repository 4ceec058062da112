//! Full verification: data checksums and ranges, the tree's tiling, brick lists and value ranges.

use std::fmt;

use crate::blocks::block_ranges;
use crate::error::{FormatError, Result};
use crate::geometry::IBox;
use crate::kdtree::leaf_ranges;
use crate::reader::AmrkFile;
use crate::value_range::finite_range;

/// What [`AmrkFile::verify`] checked.
#[derive(Clone, Debug, Default)]
pub struct VerifyReport {
    /// (field, brick) pairs whose data was decoded and checksummed.
    pub bricks_checked: u64,
    /// Bytes of brick data read.
    pub data_bytes: u64,
    /// Leaves checked.
    pub leaves: u64,
    /// Depth of the deepest leaf (the root is depth 0).
    pub max_depth: u32,
    /// Finest-level cells covered by leaves (equals the domain's cell count).
    pub covered_cells: u128,
}

impl fmt::Display for VerifyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} brick-fields ({} bytes) checksummed; {} leaves tile {} finest cells; tree depth {}",
            self.bricks_checked, self.data_bytes, self.leaves, self.covered_cells, self.max_depth
        )
    }
}

impl<D: AsRef<[u8]>> AmrkFile<D> {
    /// Reads everything and checks it: every brick's checksum, values, stored range and block
    /// range table (version 2); that the
    /// leaves tile the domain with no gap or overlap; that each leaf lists exactly the bricks
    /// overlapping it, the unique finest covering one first; that every leaf range contains the
    /// conservative range recomputed from the data.
    pub fn verify(&self) -> Result<VerifyReport> {
        let mut report = VerifyReport::default();
        let nb = self.num_bricks();
        let mut actual: Vec<Vec<(f32, f32)>> = Vec::with_capacity(self.fields().len());
        let mut values = Vec::new();
        for (f, field) in self.fields().iter().enumerate() {
            let mut ranges = Vec::with_capacity(nb);
            let (mut fmin, mut fmax) = (f32::INFINITY, f32::NEG_INFINITY);
            for b in 0..nb {
                // Checks the brick's checksum before decoding it.
                self.brick_values_into(f, b, &mut values)?;
                let Some((lo, hi)) = finite_range(&values) else {
                    let v = values.iter().find(|v| !v.is_finite()).copied();
                    return Err(FormatError::Corrupt(format!(
                        "field '{}', brick {b}: value {}",
                        field.name,
                        v.unwrap_or(f32::NAN)
                    )));
                };
                if (lo, hi) != self.brick_range(f, b) {
                    return Err(FormatError::Corrupt(format!(
                        "field '{}', brick {b}: stored range {:?}, data range {:?}",
                        field.name,
                        self.brick_range(f, b),
                        (lo, hi)
                    )));
                }
                if let (Some(block), Some(stored)) = (self.block_cells(), self.block_ranges(f, b)) {
                    let want = block_ranges(&values, &self.brick(b).cells, i64::from(block));
                    let differs = want.len() != stored.len()
                        || want
                            .iter()
                            .zip(stored)
                            .any(|(w, s)| w.0 != s.min.get() || w.1 != s.max.get());
                    if differs {
                        return Err(FormatError::Corrupt(format!(
                            "field '{}', brick {b}: the block range table does not match the data",
                            field.name
                        )));
                    }
                }
                fmin = fmin.min(lo);
                fmax = fmax.max(hi);
                ranges.push((lo, hi));
                report.bricks_checked += 1;
                report.data_bytes += self.brick_data(f, b).len;
            }
            if (fmin, fmax) != (field.min, field.max) {
                return Err(FormatError::Corrupt(format!(
                    "field '{}': stored range {}..{}, data range {fmin}..{fmax}",
                    field.name, field.min, field.max
                )));
            }
            actual.push(ranges);
        }
        self.verify_tiling(&mut report)?;
        self.verify_brick_lists()?;
        self.verify_ranges(&actual)?;
        Ok(report)
    }

    /// Counts the leaves and the cells they cover, which must be the domain's: the tree's shape
    /// (a proper tree, splits inside their regions, stored boxes equal to the walked regions) was
    /// checked by `open`, so this is a second look at the tiling from the stored boxes alone.
    fn verify_tiling(&self, report: &mut VerifyReport) -> Result<()> {
        let tree = self.tree();
        report.leaves = tree.num_leaves() as u64;
        report.max_depth = self.tree_depth();
        report.covered_cells = (0..tree.num_leaves() as u32)
            .map(|l| cell_count(&tree.leaf_box(l)))
            .sum();
        let domain_cells = cell_count(&tree.domain);
        if report.covered_cells != domain_cells {
            return Err(FormatError::Corrupt(format!(
                "leaves cover {} cells, the domain has {domain_cells}",
                report.covered_cells
            )));
        }
        Ok(())
    }

    /// Each leaf's brick list is exactly the set of bricks overlapping it; the first is the only
    /// brick of the finest level there and covers the leaf; the rest go from fine to coarse.
    fn verify_brick_lists(&self) -> Result<()> {
        let tree = self.tree();
        let origin = self.finest_domain().lo;
        let mut expected: Vec<Vec<u32>> = vec![Vec::new(); self.num_leaves()];
        for b in 0..self.num_bricks() {
            let bounds = self.brick_finest_bounds(b, origin);
            tree.for_each_leaf_touching(&bounds, |leaf| {
                if tree.leaf_box(leaf).overlaps(&bounds) {
                    expected[leaf as usize].push(b as u32);
                }
            });
        }
        for (leaf, want) in expected.iter_mut().enumerate() {
            let info = self.leaf(leaf as u32);
            let mut got: Vec<u32> = info.bricks.iter().map(|b| b.get()).collect();
            let bad = |m: String| Err(FormatError::Corrupt(format!("kd leaf {leaf}: {m}")));
            // `open` checked that the first brick covers the leaf.
            if let Some(&first) = got.first() {
                let level = self.brick(first as usize).level;
                let levels: Vec<u32> = got.iter().map(|&b| self.brick(b as usize).level).collect();
                if levels[1..].iter().any(|&l| l >= level) || levels.windows(2).any(|w| w[1] > w[0])
                {
                    return bad(format!(
                        "bricks are not finest-unique then coarser: levels {levels:?}"
                    ));
                }
            }
            got.sort_unstable();
            want.sort_unstable();
            if got != *want {
                return bad(format!("lists bricks {got:?}, but {want:?} overlap it"));
            }
        }
        Ok(())
    }

    /// Every stored leaf range contains the conservative range recomputed from the data.
    fn verify_ranges(&self, actual: &[Vec<(f32, f32)>]) -> Result<()> {
        let tree = self.tree();
        let leaf_level: Vec<Option<u32>> = (0..self.num_leaves() as u32)
            .map(|l| {
                self.leaf(l)
                    .bricks
                    .first()
                    .map(|b| self.brick(b.get() as usize).level)
            })
            .collect();
        let scales: Vec<[i64; 3]> = self.levels().iter().map(|l| l.finest_scale).collect();
        for (f, ranges) in actual.iter().enumerate() {
            let want = leaf_ranges(
                &tree,
                &leaf_level,
                |l| ranges[self.leaf(l).bricks[0].get() as usize],
                &scales,
            );
            for (leaf, &(lo, hi)) in want.iter().enumerate() {
                let (slo, shi) = self.leaf_range(f, leaf as u32);
                if leaf_level[leaf].is_some() && !(slo <= lo && hi <= shi) {
                    return Err(FormatError::Corrupt(format!(
                        "field '{}', kd leaf {leaf}: stored range {slo}..{shi} does not contain {lo}..{hi}",
                        self.fields()[f].name
                    )));
                }
            }
        }
        Ok(())
    }
}

/// The number of cells of `b`, exact even where it exceeds `u64` (a finest domain may be
/// 2^32 - 1 cells per axis).
fn cell_count(b: &IBox) -> u128 {
    b.extent().iter().map(|&e| e.max(0) as u128).product()
}
