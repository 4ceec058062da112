//! Synthetic AMR datasets for tests, benchmarks and the demo: analytic fields, hierarchies refined around their isosurfaces, and
//! their values streamed brick by brick into an `.amrk` writer.
//!
//! - [`fields`]: the analytic functions ([`Case`], [`AnalyticField`]), public as ground truth.
//! - [`params`]: what a dataset is made of ([`SynthParams`]) and its [`LevelSpec`]s.
//! - [`refine`]: the brick hierarchy, metadata only, in integer index space.
//! - [`boxes`]: hierarchies of many small irregular boxes with mixed ratios.
//! - [`target`]: choosing the resolution that gives a requested total number of cells.
//! - [`stream`]: evaluating bricks in parallel and writing them in order.
//!
//! [`LevelSpec`]: amr_format::LevelSpec

#![warn(missing_docs)]

pub mod boxes;
pub mod fields;
pub mod params;
pub mod refine;
pub mod stream;
pub mod target;

pub use boxes::{build_box_hierarchy, BoxParams};
pub use fields::{AnalyticField, Case, Placed};
pub use params::SynthParams;
pub use refine::{build_hierarchy, build_hierarchy_by, near_surface, Block};
pub use stream::{eval_brick, write_spec, write_synth, SynthSummary};
pub use target::{count_cells, fit_cells};
