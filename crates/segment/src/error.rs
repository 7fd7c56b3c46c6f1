//! The one error type of the segment stage.

/// What can stop the segment stage; poor data quality is reported in the output instead.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The capture has no frames or no markers, so there is nothing to segment.
    #[error("segment: the capture has {frames} frames and {markers} markers; nothing to segment")]
    EmptyCapture {
        /// Frames in the capture.
        frames: usize,
        /// Markers in the capture.
        markers: usize,
    },
    /// A parameter is outside its meaningful range.
    #[error("segment: parameter segment.{name} = {value}: {why}")]
    InvalidParam {
        /// Parameter name as in `PARAM_DOCS`.
        name: &'static str,
        /// The value given, as text.
        value: String,
        /// What it must be instead.
        why: &'static str,
    },
    /// The eigen-decomposition of the affinity matrix failed to converge.
    #[error(
        "segment: eigen-decomposition of the {markers}×{markers} affinity matrix failed: {detail}"
    )]
    Eigen {
        /// Size of the affinity matrix (markers taking part).
        markers: usize,
        /// What faer reported.
        detail: String,
    },
    /// A group of `segment.groups` does not fit the capture (a label it has not, a marker
    /// two groups name).
    #[error("segment: parameter segment.groups, group {group} {labels:?}: {detail}")]
    Group {
        /// The group's place in the list, from 1.
        group: usize,
        /// The group as given.
        labels: Vec<String>,
        /// What is wrong.
        detail: String,
    },
}
