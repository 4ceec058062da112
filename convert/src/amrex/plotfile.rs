//! An opened plotfile: the `Header` and every level's `Cell_H`, checked against each other.
//! Opening reads only metadata; [`super::reader`] streams the data.

use std::path::{Path, PathBuf};

use amr_format::{IBox, LevelSpec};

use super::cell_header::{read_cell_header, CellHeader};
use super::error::{AmrexError, Result};
use super::header::{read_header, PlotHeader};
use super::reader::stream;
use crate::hierarchy_to_amrk::{AmrSource, Slab};
use amr_format::progress::Progress;

/// One level: its `Cell_H` and the directory its data files are in.
#[derive(Clone, Debug)]
pub struct PlotLevel {
    /// The parsed `Cell_H`.
    pub cells: CellHeader,
    /// The path of the `Cell_H` file.
    pub cell_h: PathBuf,
    /// The directory holding the level's data files.
    pub dir: PathBuf,
}

/// A plotfile whose metadata has been read and checked.
#[derive(Clone, Debug)]
pub struct Plotfile {
    /// The plotfile directory.
    pub dir: PathBuf,
    /// The parsed `Header`.
    pub header: PlotHeader,
    /// Levels, coarsest first.
    pub levels: Vec<PlotLevel>,
}

impl Plotfile {
    /// Reads the `Header` and all `Cell_H` files of the plotfile directory `dir`.
    pub fn open(dir: &Path) -> Result<Plotfile> {
        let header_path = dir.join("Header");
        let header = read_header(&header_path)?;
        let mut levels = Vec::with_capacity(header.levels.len());
        for (l, hl) in header.levels.iter().enumerate() {
            let cell_h = dir.join(format!("{}_H", hl.cell_prefix));
            let level_dir = cell_h
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_else(|| dir.to_path_buf());
            let cells = read_cell_header(&cell_h)?;
            if cells.ncomp != header.fields.len() {
                return Err(AmrexError::invalid(
                    &cell_h,
                    format!(
                        "{} components, but the Header lists {} fields",
                        cells.ncomp,
                        header.fields.len()
                    ),
                ));
            }
            if cells.boxes.len() != hl.ngrids {
                return Err(AmrexError::invalid(
                    &cell_h,
                    format!(
                        "{} boxes, but the Header lists {} grids for level {l}",
                        cells.boxes.len(),
                        hl.ngrids
                    ),
                ));
            }
            for (i, b) in cells.boxes.iter().enumerate() {
                if !hl.domain.contains_box(b) {
                    return Err(AmrexError::invalid(
                        &cell_h,
                        format!(
                            "box {i} {} lies outside the level {l} domain {}",
                            show(b),
                            show(&hl.domain)
                        ),
                    ));
                }
            }
            levels.push(PlotLevel {
                cells,
                cell_h,
                dir: level_dir,
            });
        }
        Ok(Plotfile {
            dir: dir.to_path_buf(),
            header,
            levels,
        })
    }

    /// The path of the `Header` file.
    pub fn header_path(&self) -> PathBuf {
        self.dir.join("Header")
    }

    /// The levels as the `.amrk` writer wants them.
    pub fn level_specs(&self) -> Vec<LevelSpec> {
        let h = &self.header;
        h.levels
            .iter()
            .map(|l| LevelSpec {
                cell_size: l.cell_size,
                origin: [0, 1, 2].map(|a| h.prob_lo[a] - l.domain.lo[a] as f64 * l.cell_size[a]),
                ratio_to_next: l.ratio_to_next,
                domain: l.domain,
            })
            .collect()
    }
}

impl AmrSource for Plotfile {
    type Error = AmrexError;

    fn path(&self) -> &Path {
        &self.dir
    }

    fn fields(&self) -> &[String] {
        &self.header.fields
    }

    fn simulation(&self) -> (Option<f64>, Option<i64>) {
        (Some(self.header.time), self.header.step)
    }

    fn level_specs(&self) -> Vec<LevelSpec> {
        Plotfile::level_specs(self)
    }

    fn boxes(&self) -> Vec<&[IBox]> {
        self.levels
            .iter()
            .map(|l| l.cells.boxes.as_slice())
            .collect()
    }

    fn stream_order(&self) -> Vec<(usize, usize)> {
        super::reader::stream_order(self)
    }

    fn stream(
        &self,
        comps: &[usize],
        chunk: i64,
        progress: &dyn Progress,
        sink: &mut dyn FnMut(Slab) -> Result<()>,
    ) -> Result<u64> {
        Ok(stream(self, comps, chunk, progress, sink)?.bytes_read)
    }
}

/// A box as AMReX writes it, with inclusive upper corner.
pub fn show(b: &IBox) -> String {
    let hi = b.hi.map(|h| h - 1);
    format!(
        "({},{},{})..=({},{},{})",
        b.lo[0], b.lo[1], b.lo[2], hi[0], hi[1], hi[2]
    )
}
