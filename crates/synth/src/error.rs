//! The one error type of synth.

use std::path::PathBuf;

/// Everything that can go wrong generating, writing, reading or scoring a synthetic trial.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A configuration value is out of its documented range.
    #[error("synth config: `{field}` {problem}")]
    InvalidConfig {
        /// The [`crate::SynthConfig`] field at fault.
        field: &'static str,
        /// What is wrong with it and what is allowed.
        problem: String,
    },
    /// A subject or preset name that does not exist.
    #[error("unknown {kind} `{name}` (expected one of: {expected})")]
    UnknownName {
        /// "subject" or "preset".
        kind: &'static str,
        /// The name given.
        name: String,
        /// The valid names, comma-separated.
        expected: String,
    },
    /// Reading or writing a capture file failed (mocap-io's error carries the path).
    #[error(transparent)]
    Capture(#[from] mocap_io::IoError),
    /// A truth or estimate JSON file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A truth or estimate JSON file does not decode.
    #[error("{path}: not a valid {what} JSON file: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// "truth" or "skeleton".
        what: &'static str,
        /// The decoder's message (line and column).
        source: serde_json::Error,
    },
    /// Encoding the truth as JSON failed (a bug: the truth holds a non-finite number).
    #[error("trial {trial}: cannot encode truth JSON: {source}")]
    Encode {
        /// The trial's name.
        trial: String,
        /// The encoder's message.
        source: serde_json::Error,
    },
}
