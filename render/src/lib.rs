//! Rendering isosurfaces of `.amrk` files: mapping, reconstruction, extraction, tracing, output.
#![warn(missing_docs)]

pub mod bench;
pub mod bvh;
pub mod camera;
pub mod extract;
pub mod extract_cmd;
pub mod info;
pub mod mapping;
pub mod mpi;
pub mod output;
pub mod reconstruct;
pub mod render_cmd;
pub mod sample_mode;
pub mod shade;
pub mod sigbus;
pub mod trace;
