//! Errors of the export stage.

/// Why the output files could not be made.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The inputs do not belong together (different captures or stage runs).
    #[error("export: {0}; the artifacts come from different runs: rerun the pipeline")]
    Mismatch(String),
    /// A BVH needs a frame time, so the capture must have a frame rate.
    #[error(
        "export: the capture's frame rate is {rate} Hz; BVH needs a positive frame rate \
         (set it on the input)"
    )]
    BadFrameRate {
        /// The capture's frame rate (Hz).
        rate: f64,
    },
    /// A file's format cannot hold this much (GLB lengths are 32-bit).
    #[error(
        "export: {file} would be {bytes} bytes, more than its format can hold (4 GiB); \
         export a shorter stretch of the capture"
    )]
    TooLarge {
        /// The file that cannot be written.
        file: &'static str,
        /// Its size (bytes).
        bytes: usize,
    },
    /// serde_json could not write skeleton.json.
    #[error("export: writing skeleton.json: {0}")]
    Json(#[from] serde_json::Error),
}
