//! What a dump holds, from its metadata alone (no cell is read): its format, fields, levels,
//! boxes and cells, when in the simulation it was written, and what its `.amrk` file would
//! take; `amr-convert info` prints it before a long conversion is started.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::chombo::plotfile::{Plotfile as ChomboPlotfile, Writer};
use crate::dump::{detect, DumpError, InputFormat};
use crate::hierarchy_to_amrk::AmrSource;
use crate::{amrex, enzo};

/// One level of a dump.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelDescription {
    /// Boxes (grids, patches) on the level.
    pub boxes: usize,
    /// Valid cells in them.
    pub cells: u64,
    /// Physical cell size per axis.
    pub cell_size: [f64; 3],
    /// The level's index domain, lower corner (inclusive) and upper corner (exclusive).
    pub domain: [[i64; 3]; 2],
    /// Refinement ratio to the next finer level (`[1, 1, 1]` on the finest).
    pub ratio_to_next: [u32; 3],
}

/// A dump's metadata.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DumpDescription {
    /// The dump as given.
    pub path: PathBuf,
    /// What it is: "AMReX plotfile", "AMReX HDF5 plotfile", "Chombo HDF5 file", "Enzo dataset".
    pub format: &'static str,
    /// Field names, in the dump's order.
    pub fields: Vec<String>,
    /// Levels, coarsest first.
    pub levels: Vec<LevelDescription>,
    /// The simulation time, when the dump records it.
    pub time: Option<f64>,
    /// The simulation step, when the dump records it.
    pub step: Option<i64>,
    /// Valid cells over every level.
    pub cells: u64,
    /// Bytes of cell data in an `.amrk` file of one field (4 a cell, uncompressed).
    pub amrk_bytes_per_field: u64,
}

impl DumpDescription {
    /// The description of `source`, a dump of `format` at `path`.
    fn of(path: &Path, format: &'static str, source: &impl AmrSource) -> Self {
        let specs = source.level_specs();
        let boxes = source.boxes();
        let levels: Vec<LevelDescription> = specs
            .iter()
            .zip(&boxes)
            .map(|(spec, boxes)| LevelDescription {
                boxes: boxes.len(),
                cells: boxes.iter().filter_map(|b| b.num_cells()).sum(),
                cell_size: spec.cell_size,
                domain: [spec.domain.lo, spec.domain.hi],
                ratio_to_next: spec.ratio_to_next,
            })
            .collect();
        let cells = levels.iter().map(|l| l.cells).sum::<u64>();
        let (time, step) = source.simulation();
        DumpDescription {
            path: path.to_path_buf(),
            format,
            fields: source.fields().to_vec(),
            levels,
            time,
            step,
            cells,
            amrk_bytes_per_field: cells.saturating_mul(4),
        }
    }
}

/// Reads the metadata of `input` (format detected), no cell data.
pub fn describe(input: &Path) -> Result<DumpDescription, DumpError> {
    let failed = |format: &'static str, e: &dyn std::error::Error| DumpError::Reading {
        format,
        path: input.to_path_buf(),
        detail: crate::dump::chain(e),
    };
    match detect(input)? {
        InputFormat::Amrex => {
            let format = "AMReX plotfile";
            let plotfile = amrex::Plotfile::open(input).map_err(|e| failed(format, &e))?;
            Ok(DumpDescription::of(input, format, &plotfile))
        }
        InputFormat::ChomboHdf5 => {
            let plotfile = ChomboPlotfile::open(input).map_err(|e| failed("HDF5 file", &e))?;
            let format = match plotfile.writer {
                Writer::AmrexHdf5 => "AMReX HDF5 plotfile",
                Writer::Chombo => "Chombo HDF5 file",
            };
            Ok(DumpDescription::of(input, format, &plotfile))
        }
        InputFormat::Enzo { params, hierarchy } => {
            let format = "Enzo dataset";
            let dataset =
                enzo::Dataset::open(&params, &hierarchy).map_err(|e| failed(format, &e))?;
            Ok(DumpDescription::of(input, format, &dataset))
        }
        InputFormat::Amrk => Err(DumpError::Unrecognised {
            path: input.to_path_buf(),
            reason: "an .amrk file, not a dump: `amr-render info FILE` describes it".into(),
        }),
    }
}

/// Bytes in binary units, three significant digits: `1.50 GiB`.
fn bytes(n: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < units.len() {
        v /= 1024.0;
        u += 1;
    }
    match u {
        0 => format!("{n} B"),
        _ => format!("{v:.3} {}", units[u]),
    }
}

impl fmt::Display for DumpDescription {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}: {}", self.path.display(), self.format)?;
        // Shortest round-trip digits, in scientific notation far from 1.
        let time = |t: f64| match t != 0.0 && !(1e-4..1e9).contains(&t.abs()) {
            true => format!("{t:e}"),
            false => t.to_string(),
        };
        match (self.time, self.step) {
            (Some(t), Some(s)) => writeln!(f, "simulation: time {} step {s}", time(t))?,
            (Some(t), None) => writeln!(f, "simulation: time {}", time(t))?,
            (None, Some(s)) => writeln!(f, "simulation: step {s}")?,
            (None, None) => {}
        }
        writeln!(f, "fields: {}", self.fields.len())?;
        for name in &self.fields {
            writeln!(f, "  {name}")?;
        }
        let names: Vec<&str> = self.fields.iter().map(String::as_str).collect();
        let vectors = amr_render::coloring::vector_fields(&names);
        if let Some(first) = vectors.first() {
            let all: Vec<String> = vectors.iter().map(ToString::to_string).collect();
            let components = first.fields().join(",");
            writeln!(
                f,
                "vectors: {} (store a length or a vorticity with --derive 'speed={first}' \
                 --derive 'vorticity=curl({components})', or convert the components and paint \
                 by a length: --color-by '{first}')",
                all.join(" ")
            )?;
        }
        writeln!(f, "levels: {}", self.levels.len())?;
        for (l, level) in self.levels.iter().enumerate() {
            let [lo, hi] = level.domain;
            write!(
                f,
                "  level {l}: boxes {} cells {} domain {lo:?}..{hi:?} cell size {:?}",
                level.boxes, level.cells, level.cell_size
            )?;
            match l + 1 < self.levels.len() {
                true => writeln!(f, " ratio to next {:?}", level.ratio_to_next)?,
                false => writeln!(f)?,
            }
        }
        writeln!(f, "cells: {}", self.cells)?;
        let all = self
            .amrk_bytes_per_field
            .saturating_mul(self.fields.len() as u64);
        write!(
            f,
            ".amrk cell data (4 bytes a cell, before --compress): {} a field, {} for all {} \
             (convert fewer with --field NAME)",
            bytes(self.amrk_bytes_per_field),
            bytes(all),
            self.fields.len()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::bytes;

    #[test]
    fn bytes_read_in_binary_units() {
        assert_eq!(bytes(512), "512 B");
        assert_eq!(bytes(1536), "1.500 KiB");
        assert_eq!(bytes(3 << 30), "3.000 GiB");
    }
}
