//! Converters from AMR simulation dumps to `.amrk` files.
pub mod amrex;
pub mod bricking;
pub mod chombo;
pub mod convert_cmd;
pub mod isolate;
pub mod progress;
pub mod synth_cmd;
