//! Converters from AMR simulation dumps to `.amrk` files: one reader per format (AMReX
//! plotfiles, Chombo HDF5, Enzo), the bricking they share, and [`dump::convert_dump`], which
//! detects a dump's format and converts it (or rewrites an `.amrk` file, [`rewrite`], with
//! fields derived by formulas, [`derive`]). The `amr-convert` program is a thin front end.
pub mod amrex;
pub mod bricking;
pub mod chombo;
pub mod derive;
pub mod describe;
pub mod differential;
pub mod dump;
pub mod enzo;
pub mod finite;
pub mod hierarchy_to_amrk;
pub mod rewrite;
