//! Errors of the jointfit stage.

use thiserror::Error;

/// Why the jointfit stage could not run.
#[derive(Debug, Error)]
pub enum Error {
    /// The segmentation names a marker the trajectories do not have.
    #[error(
        "segment {segment} lists marker index {marker}, but the capture has only {markers} markers \
         (segmentation made from a different capture?)"
    )]
    MarkerOutOfRange {
        /// Segment id.
        segment: usize,
        /// The offending marker index.
        marker: usize,
        /// Markers in the capture.
        markers: usize,
    },
    /// The segmentation's segment ids do not match their positions.
    #[error("segment at position {position} has id {id}; ids must equal positions")]
    SegmentId {
        /// Position in `Segmentation::segments`.
        position: usize,
        /// The id it carries.
        id: usize,
    },
    /// A parameter is out of its valid range.
    #[error("jointfit.{name} = {value}: {reason}")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// The value given, as text.
        value: String,
        /// What is allowed.
        reason: &'static str,
    },
}
