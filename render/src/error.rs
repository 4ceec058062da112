//! The renderer's one error type: what went wrong, named once, with the file it concerns.

use std::path::{Path, PathBuf};

use amr_format::FormatError;

use crate::camera::CameraError;

/// A renderer result.
pub type Result<T, E = RenderError> = std::result::Result<T, E>;

/// Everything that can go wrong while opening a scene, extracting, tracing or writing a frame.
///
/// Each variant's message is complete on its own; [`RenderError::InFile`] puts the file's name in
/// front once (see [`RenderError::in_file`]).
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The `.amrk` file is unreadable or invalid.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The file has no field of that name.
    #[error("no field '{name}' (fields: {})", available.join(", "))]
    NoField {
        /// The name asked for.
        name: String,
        /// The file's fields.
        available: Vec<String>,
    },
    /// A voxel reference names no voxel of the file: the file changed, or the reference was not
    /// made by this scene's extraction.
    #[error("voxel reference {r:#018x}: {what}")]
    BadVoxelRef {
        /// The reference.
        r: u64,
        /// What is wrong with it.
        what: String,
    },
    /// The camera cannot be set up.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// A scene or view setting is out of range.
    #[error("{0}")]
    Invalid(String),
    /// A combination this renderer does not support.
    #[error("not supported: {0}")]
    Unsupported(String),
    /// An operating-system error.
    #[error("{context}: {error}")]
    Io {
        /// What was being done.
        context: String,
        /// The underlying error.
        error: std::io::Error,
    },
    /// An output file could not be written.
    #[error("cannot write {}: {message}", path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// An error about a named file.
    #[error("{}: {inner}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        inner: Box<RenderError>,
    },
}

impl RenderError {
    /// This error, said of `path` (once: an error that already names a file is kept as it is).
    pub fn in_file(self, path: &Path) -> RenderError {
        match self {
            e @ (RenderError::InFile { .. } | RenderError::Output { .. }) => e,
            RenderError::Format(FormatError::InFile { path, error }) => RenderError::InFile {
                path,
                inner: Box::new(RenderError::Format(*error)),
            },
            RenderError::Format(e) if e.names_a_file() => RenderError::Format(e),
            e => RenderError::InFile {
                path: path.to_path_buf(),
                inner: Box::new(e),
            },
        }
    }

    /// An output error for `path`.
    pub fn output(path: &Path, message: impl std::fmt::Display) -> RenderError {
        RenderError::Output {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}
