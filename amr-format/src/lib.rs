//! The `.amrk` file: block-structured AMR bricks, one region per field, and an AMR-KDTree built
//! in integer finest-level coordinates, laid out to be memory-mapped and read in place.
//!
//! - [`raw`]: the on-disk structs, nothing else.
//! - [`blocks`]: block range tables (the value range of each `4^3` block of a brick).
//! - [`box_join`]: runs of small boxes joined into bricks.
//! - [`AmrkWriter`]: streams bricks into a new file and writes the tables and tree last.
//! - [`AmrkFile`]: opens a file from any bytes (`Vec<u8>`, a memory map) in O(metadata),
//!   validating every count and offset; [`AmrkFile::verify`] checks everything else.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod blocks;
pub mod box_join;
pub mod compress;
pub mod error;
pub mod geometry;
pub mod hierarchy;
pub mod kdtree;
mod meta_copy;
pub mod output;
pub mod progress;
pub mod raw;
pub mod reader;
pub mod tight_sink;
pub mod value_range;
pub mod verify;
pub mod writer;

pub use error::{FormatError, Result};
pub use geometry::{copy_subbox, paste_subbox, IBox};
pub use hierarchy::{BrickSpec, HierarchySpec, LevelSpec};
pub use reader::{AmrkFile, BrickInfo, BrickLocation, FieldInfo, LeafInfo, LevelInfo};
pub use tight_sink::TightSink;
pub use value_range::{finite_range, value_range, RangeAccumulator};
pub use writer::{AmrkWriter, Compression, WriteSummary, WriterOptions};
