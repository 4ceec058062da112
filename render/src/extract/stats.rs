//! What one extraction did: counts, time, decompressions and touched pages.

use std::fmt;

/// Statistics of one extraction.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ExtractStats {
    /// The field's name.
    pub field: String,
    /// The isovalue.
    pub iso: f32,
    /// Active voxels emitted (merged dual cells and single octants).
    pub active: u64,
    /// Active voxels that are merged dual cells.
    pub active_duals: u64,
    /// Leaves whose conservative range holds the isovalue, which were therefore visited.
    pub leaves_visited: u64,
    /// Of those, leaves skipped because their tight range (from cell values, computed once per
    /// leaf and kept) excludes the isovalue.
    pub leaves_skipped: u64,
    /// Leaves in the tree.
    pub leaves_total: u64,
    /// Voxels whose eight corners were evaluated.
    pub evaluated: u64,
    /// Of those, single octants next to a level boundary (the rest are merged dual cells).
    pub boundary_evaluated: u64,
    /// Cells next to a level boundary whose octants were skipped unevaluated, because the value
    /// bound of their neighbourhood excludes the isovalue.
    pub culled_cells: u64,
    /// Octants next to a level boundary skipped unevaluated, in cells not culled, because the
    /// value bound of the eight cells around their outer corner excludes the isovalue.
    pub culled_octants: u64,
    /// Parts of large leaves skipped whole because the stored block ranges around them exclude
    /// the isovalue (files with block range tables).
    pub parts_skipped: u64,
    /// Cells in the file (all bricks, all levels).
    pub file_cells: u64,
    /// Wall-clock seconds of the extraction.
    pub seconds: f64,
    /// Threads the extraction ran on.
    pub threads: usize,
    /// Bricks decompressed during this extraction.
    pub decompressions: u64,
    /// Bytes of the file mapping this process has touched, when known: with pages released after
    /// each chunk of leaves, the sum over chunks of the bytes resident at the chunk's end (a page
    /// two chunks touch counts twice); otherwise the bytes resident after the extraction.
    pub resident_bytes: Option<u64>,
    /// Size of the file in bytes.
    pub file_bytes: u64,
}

impl ExtractStats {
    /// File cells per core-second: `file_cells / (seconds * threads)`.
    pub fn cells_per_core_second(&self) -> f64 {
        self.file_cells as f64 / (self.seconds * self.threads.max(1) as f64)
    }

    /// Emitted voxels per second.
    pub fn active_per_second(&self) -> f64 {
        self.active as f64 / self.seconds
    }
}

impl fmt::Display for ExtractStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "field '{}' iso {}: {} active voxels ({} merged dual cells), {} of {} leaves visited ({} skipped by tight range), \
             {} voxels evaluated ({} boundary octants; {} boundary cells and {} boundary octants culled; {} leaf parts skipped), {:.3} s on {} threads ({:.1} M file cells per core-second, \
             {:.1} M voxels per second), {} bricks decompressed",
            self.field,
            self.iso,
            self.active,
            self.active_duals,
            self.leaves_visited,
            self.leaves_total,
            self.leaves_skipped,
            self.evaluated,
            self.boundary_evaluated,
            self.culled_cells,
            self.culled_octants,
            self.parts_skipped,
            self.seconds,
            self.threads,
            self.cells_per_core_second() / 1e6,
            self.active_per_second() / 1e6,
            self.decompressions,
        )?;
        if let Some(r) = self.resident_bytes {
            write!(
                f,
                ", {:.1} MiB of map pages touched (summed over chunks of leaves; the map is {:.1} MiB)",
                r as f64 / 1048576.0,
                self.file_bytes as f64 / 1048576.0
            )?;
        }
        Ok(())
    }
}
