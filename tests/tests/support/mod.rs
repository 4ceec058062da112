//! What the integration tests share: one random generator, fixture writers that follow each
//! code's own writer, analytic grids and the real-data folder.

pub mod amrex;
pub mod block_grid;
pub mod chombo;
pub mod hierarchy;
pub mod render;
pub mod rng;
