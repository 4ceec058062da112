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
    #[error("no field '{name}'{} (fields: {})", same_but_case(name, available), available.join(", "))]
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

/// ` (did you mean 'density'?)` when a field of `available` is `name` but for letter case.
pub fn same_but_case(name: &str, available: &[String]) -> String {
    available
        .iter()
        .find(|f| f.eq_ignore_ascii_case(name))
        .map(|f| format!(" (did you mean '{f}'?)"))
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_field_lists_the_fields_and_the_one_differing_in_case() {
        let available: Vec<String> = ["x_velocity", "density"].map(String::from).to_vec();
        let e = RenderError::NoField {
            name: "Density".into(),
            available: available.clone(),
        };
        assert_eq!(
            e.to_string(),
            "no field 'Density' (did you mean 'density'?) (fields: x_velocity, density)"
        );
        let e = RenderError::NoField {
            name: "temp".into(),
            available,
        };
        assert_eq!(
            e.to_string(),
            "no field 'temp' (fields: x_velocity, density)"
        );
    }
}
