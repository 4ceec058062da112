//! The one error type of this crate: what went wrong, and where in the file.

use std::path::PathBuf;

/// Everything that can go wrong while writing, opening or verifying an `.amrk` file.
///
/// Variants say which part of the file is at fault; callers add the file name
/// (see [`FormatError::in_file`]).
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// The bytes do not start with the `.amrk` magic: this is not an `.amrk` file.
    #[error("not an .amrk file (wrong magic bytes at {at})")]
    BadMagic {
        /// Where the magic was expected ("header" or "footer").
        at: &'static str,
    },
    /// Not an `.amrk` file at all, with what it looks like instead (a directory, a simulation
    /// dump to convert first).
    #[error("{0}")]
    NotAmrk(String),
    /// The file was written with a layout this reader does not know.
    #[error("layout version {got} is not supported (this build reads versions 1 to {expected}); upgrade amr-render or re-convert")]
    Version {
        /// The newest version this build reads.
        expected: u32,
        /// The version the file declares.
        got: u32,
    },
    /// The file is shorter than its own tables say: it was truncated or is not finished.
    #[error("file is truncated or incomplete: {0}")]
    Truncated(String),
    /// A stored checksum does not match the bytes it covers.
    #[error("checksum mismatch in {what}: stored {stored:#010x}, computed {computed:#010x} (the file is corrupt)")]
    Checksum {
        /// Which part of the file (metadata, or a brick of a field).
        what: String,
        /// The checksum stored in the file.
        stored: u32,
        /// The checksum of the bytes as they are.
        computed: u32,
    },
    /// A count, offset or value in the file is impossible.
    #[error("corrupt file: {0}")]
    Corrupt(String),
    /// The tight leaf ranges handed to the writer could not be computed or are not valid.
    #[error("tight leaf ranges: {0}")]
    TightRanges(String),
    /// The input handed to the writer is inconsistent (overlapping bricks, a bad ratio, ...).
    #[error("invalid hierarchy: {0}")]
    InvalidHierarchy(String),
    /// A brick value is NaN, infinite or out of the f32 range.
    #[error("non-finite value {value} in field '{field}', level {level}, brick {brick} (cells {lo:?}..{hi:?})")]
    NonFinite {
        /// The field's name.
        field: String,
        /// The brick's level.
        level: u32,
        /// The brick's index in the brick table.
        brick: usize,
        /// The brick's lower cell corner.
        lo: [i64; 3],
        /// The brick's upper (exclusive) cell corner.
        hi: [i64; 3],
        /// The offending value.
        value: f64,
    },
    /// A caller misused the writer (a brick written twice, a missing brick at finish, ...).
    #[error("writer misuse: {0}")]
    Usage(String),
    /// An operating-system error.
    // The message includes the cause, so it is not also exposed as `source()`: printing the
    // chain (`{:#}`) would repeat it.
    #[error("{context}: {cause}")]
    Io {
        /// What was being done.
        context: String,
        /// The underlying error.
        cause: std::io::Error,
    },
    /// An error about a named file.
    #[error("{}: {error}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it (its message is part of this one's).
        error: Box<FormatError>,
    },
    /// An error met once and shared by everyone asking for the same thing again (a brick that
    /// does not decode, for every reader of it).
    #[error("{0}")]
    Shared(std::sync::Arc<FormatError>),
    /// An output path that would replace something it must not (an input, a device, a
    /// directory), or whose file system has no room for it.
    #[error("{}: {reason}", path.display())]
    Output {
        /// The output path as given.
        path: PathBuf,
        /// Why it is refused.
        reason: String,
    },
}

impl FormatError {
    /// Wraps the error with the name of the file it concerns.
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        match self {
            e if e.names_a_file() => e,
            e => FormatError::InFile {
                path: path.into(),
                error: Box::new(e),
            },
        }
    }

    /// True when the message already names a file.
    pub fn names_a_file(&self) -> bool {
        match self {
            FormatError::InFile { .. } | FormatError::Output { .. } => true,
            FormatError::Shared(e) => e.names_a_file(),
            _ => false,
        }
    }

    /// An operating-system error met while doing `context`.
    pub fn io(context: impl Into<String>, cause: std::io::Error) -> Self {
        FormatError::Io {
            context: context.into(),
            cause,
        }
    }
}

/// Result with [`FormatError`].
pub type Result<T, E = FormatError> = std::result::Result<T, E>;
