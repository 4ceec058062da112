//! Converters from AMR simulation dumps to `.amrk` files.
pub mod amrex;
pub mod bricking;
pub mod chombo;
pub mod convert_cmd;
pub mod enzo;
pub mod finite;
pub mod hierarchy_to_amrk;
pub mod isolate;
pub mod progress;
pub mod synth_cmd;
