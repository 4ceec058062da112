//! The error type of the Enzo reader: every variant names the file and what is wrong with it.

use std::path::PathBuf;

use crate::hierarchy_to_amrk::ConvertError;

/// Everything that can go wrong while reading an Enzo dataset or converting it.
#[derive(Debug, thiserror::Error)]
pub enum EnzoError {
    /// The operating system refused a read.
    #[error("{}: {what}: {cause}", path.display())]
    Io {
        /// The file being read.
        path: PathBuf,
        /// What was being done.
        what: String,
        /// The underlying error (its message is part of this one's, so it is not also the
        /// error's `source()`: printing the chain would repeat it).
        cause: std::io::Error,
    },
    /// A line of the parameter or hierarchy file does not parse.
    #[error("{}, line {line}: {msg}", path.display())]
    Syntax {
        /// The text file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What was expected and what was found.
        msg: String,
    },
    /// The dataset is well formed but inconsistent: a missing parameter, a grid off its level's
    /// cell grid or outside its parent, a data file that disagrees with the hierarchy.
    #[error("{}: {msg}", path.display())]
    Invalid {
        /// The file at fault.
        path: PathBuf,
        /// What disagrees with what, naming the grid.
        msg: String,
    },
    /// A valid dataset uses a feature this reader does not support.
    #[error("{}: not supported: {msg}", path.display())]
    Unsupported {
        /// The file using the feature.
        path: PathBuf,
        /// The feature, and why it is not supported.
        msg: String,
    },
    /// The HDF5 library refused an operation on a data file.
    #[error("{}: {what}: {cause}", path.display())]
    Hdf5 {
        /// The HDF5 file.
        path: PathBuf,
        /// What was being read.
        what: String,
        /// The library's error (its message is part of this one's, so it is not also the
        /// error's `source()`: printing the chain would repeat it).
        cause: hdf5_metno::Error,
    },
    /// A cell value cannot be stored as a finite `f32`.
    #[error(
        "{}: grid {grid} (level {level}), field '{field}': value {value:e} at cell {cell:?} is {why}; .amrk stores finite f32 values",
        path.display()
    )]
    BadValue {
        /// The data file.
        path: PathBuf,
        /// The grid's number in the hierarchy.
        grid: usize,
        /// The grid's level.
        level: usize,
        /// The field's name.
        field: String,
        /// The cell, in the level's index space.
        cell: [i64; 3],
        /// The offending value.
        value: f64,
        /// "NaN", "infinite" or "outside the f32 range".
        why: &'static str,
    },
    /// The shared conversion failed: an unknown field, or the `.amrk` writer.
    #[error(transparent)]
    Convert(#[from] ConvertError),
}

/// Result with [`EnzoError`].
pub type Result<T, E = EnzoError> = std::result::Result<T, E>;

impl EnzoError {
    pub(crate) fn io(
        path: impl Into<PathBuf>,
        what: impl Into<String>,
        source: std::io::Error,
    ) -> Self {
        EnzoError::Io {
            path: path.into(),
            what: what.into(),
            cause: source,
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        EnzoError::Invalid {
            path: path.into(),
            msg: msg.into(),
        }
    }

    pub(crate) fn unsupported(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        EnzoError::Unsupported {
            path: path.into(),
            msg: msg.into(),
        }
    }

    pub(crate) fn hdf5(
        path: impl Into<PathBuf>,
        what: impl Into<String>,
        source: hdf5_metno::Error,
    ) -> Self {
        EnzoError::Hdf5 {
            path: path.into(),
            what: what.into(),
            cause: source,
        }
    }
}
