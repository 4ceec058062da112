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
pub mod to_amrk;

pub use crate::bricking::{ConvertOptions, ConvertStats};
pub use error::{ChomboError, Result};
pub use plotfile::{Level, Plotfile, Precision};
pub use to_amrk::convert;
