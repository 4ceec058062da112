//! What the integration tests share: one random generator, fixture writers that follow each
//! code's own writer (AMReX, Chombo, Enzo), analytic grids and the real-data folder.

pub mod amrex;
pub mod amrex_hdf5;
pub mod block_grid;
pub mod chombo;
pub mod enzo;
pub mod golden;
pub mod half_refined;
pub mod hierarchy;
pub mod render;
pub mod rng;
pub mod synth_file;
