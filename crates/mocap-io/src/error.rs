//! The one error type of mocap-io.

use std::path::PathBuf;

/// Where in a file a problem sits and what it is, before the file's path is known.
///
/// Parsers work on bytes and return this; [`crate::read_capture`] adds the path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{location}: {problem}")]
pub struct FormatError {
    /// Where: "byte 512 (header)", "parameter POINT:LABELS", "line 7, field 4", ...
    pub location: String,
    /// What is wrong, in words a user can act on.
    pub problem: String,
}

impl FormatError {
    /// A problem at a place.
    pub fn new(location: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            location: location.into(),
            problem: problem.into(),
        }
    }
}

/// Everything that can go wrong reading or writing captures and artifacts.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file could not be written (nothing is left half-written).
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file's content is not a valid capture of its format.
    #[error("{path}: {error}")]
    Format {
        /// The file.
        path: PathBuf,
        /// Where in it, and what is wrong.
        error: FormatError,
    },
    /// The file's extension and content match no format we read.
    #[error("{path}: unknown capture format (expected .c3d, .trc, .csv or .tsv)")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// An artifact that does not decode, or is not what the caller expected.
    #[error("{path}: not a valid ossify artifact: {problem}")]
    Artifact {
        /// The artifact file.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// Data that violates an in-memory invariant (a bug upstream, or a bad caller).
    #[error("invalid data: {0}")]
    Invalid(String),
}
