//! The error type of the Chombo reader: every variant names the file and what is wrong with it.

use std::path::PathBuf;

use crate::hierarchy_to_amrk::ConvertError;

/// Everything that can go wrong while reading a Chombo plotfile or converting it.
#[derive(Debug, thiserror::Error)]
pub enum ChomboError {
    /// The file cannot be opened at all (missing, unreadable).
    #[error("cannot open {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The HDF5 library refused an operation (the file is not HDF5, is unreadable, or an object
    /// has a type that cannot be read as asked).
    #[error("{}: {what}", path.display())]
    Hdf5 {
        /// The HDF5 file.
        path: PathBuf,
        /// What was being read.
        what: String,
        /// The library's error.
        #[source]
        source: hdf5_metno::Error,
    },
    /// The file is HDF5 but not a consistent Chombo plotfile: a missing attribute or dataset,
    /// offsets beyond the data, a box outside the domain, ...
    #[error("{}: not a valid Chombo-layout HDF5 file: {msg}", path.display())]
    Invalid {
        /// The HDF5 file.
        path: PathBuf,
        /// What is missing or disagrees, and where (`level_N/...`).
        msg: String,
    },
    /// The file holds no cell data at all (boxes only, as Chombo's mesh tests write).
    #[error("{}: no data to convert: {why}", path.display())]
    NoData {
        /// The HDF5 file.
        path: PathBuf,
        /// What is missing.
        why: String,
    },
    /// A valid plotfile uses a feature this reader does not support (2D, integer data, ...).
    #[error("{}: not supported: {msg}", path.display())]
    Unsupported {
        /// The HDF5 file.
        path: PathBuf,
        /// The feature, and why it is not supported.
        msg: String,
    },
    /// A cell value cannot be stored as a finite `f32`.
    #[error(transparent)]
    BadValue(Box<BadValue>),
    /// The shared conversion failed: an unknown field, or the `.amrk` writer.
    #[error(transparent)]
    Convert(#[from] ConvertError),
}

/// A cell value that cannot be stored as a finite `f32`, and where it is.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}: level {level}, box {index} (cells {lo:?}..={hi:?}), field '{field}': value {value:e} at cell {cell:?} is {why}; .amrk stores finite f32 values",
    path.display()
)]
pub struct BadValue {
    /// The HDF5 file.
    pub path: PathBuf,
    /// The box's level.
    pub level: usize,
    /// The box's index in its level's `boxes` dataset.
    pub index: usize,
    /// Lower corner of the box (inclusive, as Chombo writes it).
    pub lo: [i64; 3],
    /// Upper corner of the box (inclusive, as Chombo writes it).
    pub hi: [i64; 3],
    /// The cell holding the value.
    pub cell: [i64; 3],
    /// The field's name.
    pub field: String,
    /// The offending value.
    pub value: f64,
    /// "NaN", "infinite" or "outside the f32 range".
    pub why: &'static str,
}

/// Result with [`ChomboError`].
pub type Result<T, E = ChomboError> = std::result::Result<T, E>;

impl ChomboError {
    pub(crate) fn hdf5(
        path: impl Into<PathBuf>,
        what: impl Into<String>,
        source: hdf5_metno::Error,
    ) -> Self {
        ChomboError::Hdf5 {
            path: path.into(),
            what: what.into(),
            source,
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        ChomboError::Invalid {
            path: path.into(),
            msg: msg.into(),
        }
    }

    pub(crate) fn unsupported(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        ChomboError::Unsupported {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
