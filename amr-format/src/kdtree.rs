//! The AMR-KDTree (Wald et al. 2017): built, walked and queried in integer finest-level cells.
//!
//! Coordinates here are finest-level cell indices relative to the domain's lower corner, so
//! every split plane is an exact integer and no leaf can overlap another through round-off.

mod build;
mod ranges;
mod view;

pub use build::{build, KdTree, TreeBrick};
pub use ranges::{leaf_ranges, widen_range};
pub use view::{leaf_bounds, KdNode, TreeView};
