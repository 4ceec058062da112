//! AMReX plotfiles: reading the text headers, streaming the FAB data, and converting to `.amrk`.
//!
//! A plotfile is a directory: `Header` (fields, levels, geometry), and per level `Level_N/Cell_H`
//! (boxes and where their data is) with `Level_N/Cell_D_*` data files. See `docs/amrex.md` for
//! what is supported and why.

pub mod cell_header;
pub mod error;
pub mod fab;
pub mod header;
pub mod plotfile;
pub mod reader;
mod text;

pub use crate::bricking::{ConvertOptions, ConvertStats};
pub use error::{AmrexError, Result};
pub use header::looks_like_version;
pub use plotfile::Plotfile;
