//! Reconstructing a continuous field from cell-centred AMR bricks.
//!
//! - [`grid`]: doubled finest-level integer coordinates, where every location is exact.
//! - [`interp`]: trilinear interpolation and averages in one fixed evaluation order.
//! - [`cache`]: a bounded cache of decoded (decompressed) bricks.
//! - [`leaf_grid`]: point location in one table read over the kd-tree.
//! - [`leaf_hints`]: the kd-tree leaves located last, tried before walking the kd-tree.
//! - [`recent`]: per-thread scratch that makes nearby point samples cheap.
//! - [`sampler`]: leaf-cell location and the octant method's vertex values.
//! - [`whole_bricks`]: the bricks no finer brick overlaps, which a leaf reads past its own box.
//! - [`vertex_sides`]: a vertex's sides as its value reads them (levels, values, leaves).
//! - [`stitch`]: stitched vertex values from the coarse corners of non-zero weight alone.
//! - [`level_gradient`]: smooth normals' central differences inside one level, from a brick.
//! - [`level_blend`]: smooth normals' differences of two levels weighed near a level boundary.
//! - [`cell_octants`]: several octants of one leaf cell next to other levels, computed together.
//! - [`mixed`]: octant corners next to other levels, from one table of the cells they read.
//! - [`methods`]: point sampling with `nearest`, `current`, `finest` and `octant`.
//!
//! `docs/reconstruction.md` gives the rules and the reasons for them.

pub mod cache;
mod cell_octants;
pub mod grid;
pub mod interp;
pub mod leaf_grid;
mod leaf_hints;
pub mod level_blend;
pub mod level_gradient;
pub mod methods;
mod mixed;
pub mod recent;
pub mod sampler;
mod stitch;
mod vertex_sides;
mod whole_bricks;

pub use grid::Grid;
pub use methods::Reconstruction;
pub use recent::SampleScratch;
pub use sampler::{LeafCell, Locate, Octant, Sampler, Slab, VertexMemo};
