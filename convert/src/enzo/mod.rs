//! Enzo datasets (packed-HDF5 output, and the older one-file-per-grid layout): reading the
//! parameter and hierarchy files, streaming the grids' fields, and converting to `.amrk`.
//!
//! A dataset `DD0010/NAME` is the parameter file `NAME`, the hierarchy `NAME.hierarchy` (one
//! text block per grid) and data files `NAME.cpuNNNN` holding one `GridNNNNNNNN` group per grid
//! (or `NAME.gridNNNN`, one file per grid). See `docs/enzo.md` for what is supported and why.

pub mod dataset;
pub mod error;
pub mod hierarchy;
pub mod parameters;
pub mod reader;
mod text;

use std::path::{Path, PathBuf};

pub use crate::bricking::{ConvertOptions, ConvertStats};
pub use dataset::Dataset;

use crate::hierarchy_to_amrk::ConvertError;
pub use error::{EnzoError, Result};

use amr_format::progress::Progress;

/// The suffix of the hierarchy file beside a parameter file.
pub const HIERARCHY_SUFFIX: &str = ".hierarchy";

/// The parameter file and hierarchy of the Enzo dataset `input` names, if it names one: a
/// parameter file with a `.hierarchy` beside it, the `.hierarchy` itself, another of the
/// dataset's files (`NAME.cpu0000`, `NAME.boundary`), or a directory holding exactly one
/// `.hierarchy`.
pub fn locate(input: &Path) -> Option<(PathBuf, PathBuf)> {
    if input.is_dir() {
        let mut found = std::fs::read_dir(input)
            .ok()?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && p.to_string_lossy().ends_with(HIERARCHY_SUFFIX));
        let h = found.next()?;
        if found.next().is_some() {
            return None;
        }
        return Some((strip_suffix(&h)?, h));
    }
    let s = input.to_string_lossy();
    if s.ends_with(HIERARCHY_SUFFIX) && input.is_file() {
        return Some((strip_suffix(input)?, input.to_path_buf()));
    }
    if !input.is_file() {
        return None;
    }
    // The parameter file `NAME`, or another file of the dataset (`NAME.cpu0000`,
    // `NAME.boundary`, `NAME.boundary.hdf`) with `NAME.hierarchy` beside it.
    let mut name = s.as_ref();
    for _ in 0..3 {
        let h = PathBuf::from(format!("{name}{HIERARCHY_SUFFIX}"));
        let params = PathBuf::from(name);
        if h.is_file() && params.is_file() {
            return Some((params, h));
        }
        let dot = name.rfind('.')?;
        if name[dot..].contains(std::path::MAIN_SEPARATOR) {
            return None;
        }
        name = &name[..dot];
    }
    None
}

fn strip_suffix(h: &Path) -> Option<PathBuf> {
    let s = h.to_string_lossy();
    Some(PathBuf::from(s.strip_suffix(HIERARCHY_SUFFIX)?))
}

/// Converts the Enzo dataset with parameter file `params` and hierarchy `hierarchy` into the
/// `.amrk` file `output` (see [`crate::hierarchy_to_amrk::convert`]). An output that would
/// replace one of the dataset's files (its parameter file, hierarchy or a grid data file) is
/// refused before anything is read.
pub fn convert(
    params: &Path,
    hierarchy: &Path,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertStats> {
    let dataset = Dataset::open(params, hierarchy)?;
    let mut inputs: Vec<&Path> = vec![params, hierarchy];
    inputs.extend(dataset.grids.iter().map(|g| g.file.as_path()));
    inputs.sort();
    inputs.dedup();
    amr_format::output::check_output(output, &inputs).map_err(ConvertError::RefusedOutput)?;
    crate::hierarchy_to_amrk::convert(&dataset, output, opts, progress)
}
