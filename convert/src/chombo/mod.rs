//! Chombo HDF5 plotfiles (the format GRChombo writes): reading the metadata, streaming the
//! boxes, and converting to `.amrk`.
//!
//! A plotfile is one HDF5 file: root attributes name the components and count the levels, and
//! each `level_N` group holds its boxes and all their data in one flat dataset. See
//! `docs/chombo.md` for the layout, what is supported, and why.

pub mod error;
pub mod plotfile;
mod props;
pub mod raw;
pub mod reader;

pub use crate::bricking::{ConvertOptions, ConvertStats};
pub use error::{ChomboError, Result};
pub use plotfile::{Level, Plotfile, Precision};

use std::path::Path;

use amr_format::progress::Progress;

/// Converts the Chombo file `input` into the `.amrk` file `output`
/// (see [`crate::hierarchy_to_amrk::convert`]).
pub fn convert(
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertStats> {
    crate::hierarchy_to_amrk::convert(&Plotfile::open(input)?, output, opts, progress)
}
