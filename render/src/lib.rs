//! Rendering isosurfaces of `.amrk` files: mapping, reconstruction, extraction, tracing, output.
#![warn(missing_docs)]

pub mod bench;
pub mod info;
pub mod mapping;
