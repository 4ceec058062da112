//! The error type of the AMReX reader: every variant names the file and what is wrong with it.

use std::path::PathBuf;

use crate::hierarchy_to_amrk::ConvertError;

/// Everything that can go wrong while reading an AMReX plotfile or converting it.
#[derive(Debug, thiserror::Error)]
pub enum AmrexError {
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
    /// A text header (`Header`, `Cell_H`, a FAB header line) does not parse.
    #[error("{}, line {line}: {msg}", path.display())]
    Syntax {
        /// The header file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What was expected and what was found.
        msg: String,
    },
    /// The plotfile is well formed but inconsistent (counts, boxes or sizes disagree).
    #[error("{}: {msg}", path.display())]
    Invalid {
        /// The file at fault.
        path: PathBuf,
        /// What disagrees with what.
        msg: String,
    },
    /// A valid plotfile uses a feature this reader does not support.
    #[error("{}: not supported: {msg}", path.display())]
    Unsupported {
        /// The file using the feature.
        path: PathBuf,
        /// The feature, and why it is not supported.
        msg: String,
    },
    /// A data file is shorter than the headers say.
    #[error("{}: truncated: {msg}", path.display())]
    Truncated {
        /// The data file.
        path: PathBuf,
        /// Which box needs which bytes.
        msg: String,
    },
    /// A cell value cannot be stored as a finite `f32`.
    #[error(
        "{}: level {level}, box {index} {cells}, field '{field}': {why} ({value}); .amrk stores finite f32 values",
        path.display()
    )]
    BadValue {
        /// The data file holding the value.
        path: PathBuf,
        /// The box's level.
        level: usize,
        /// The box's index in its level's `Cell_H`.
        index: usize,
        /// The box's cells, with inclusive corners as AMReX writes them.
        cells: String,
        /// The field's name.
        field: String,
        /// The offending value.
        value: f64,
        /// "a NaN", "an infinite value" or "a value outside the f32 range".
        why: &'static str,
    },
    /// The shared conversion failed: an unknown field, or the `.amrk` writer.
    #[error(transparent)]
    Convert(#[from] ConvertError),
}

/// Result with [`AmrexError`].
pub type Result<T, E = AmrexError> = std::result::Result<T, E>;

impl AmrexError {
    pub(crate) fn io(
        path: impl Into<PathBuf>,
        what: impl Into<String>,
        source: std::io::Error,
    ) -> Self {
        AmrexError::Io {
            path: path.into(),
            what: what.into(),
            cause: source,
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        AmrexError::Invalid {
            path: path.into(),
            msg: msg.into(),
        }
    }

    pub(crate) fn unsupported(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        AmrexError::Unsupported {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
