//! Errors of the bonefit stage.

/// Why the skeleton could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An input's per-frame data does not cover the capture's frames.
    #[error(
        "bonefit: {what} has {found} frames but the capture has {expected}; the artifacts \
         come from different captures"
    )]
    FrameCountMismatch {
        /// Which input ("segment 3 poses", "pair 2 positions", ...).
        what: String,
        /// Frames in the capture.
        expected: usize,
        /// Frames in that input.
        found: usize,
    },
    /// The pair fits and the segmentation disagree on the number of segments.
    #[error(
        "bonefit: the pair fits hold poses for {poses} segments but the segmentation has \
         {segments}; rerun jointfit on this segmentation"
    )]
    SegmentCountMismatch {
        /// Segments in the segmentation.
        segments: usize,
        /// Segment pose tracks in the pair fits.
        poses: usize,
    },
    /// The topology's tree and detached segments do not cover the segmentation's segments.
    #[error(
        "bonefit: the topology covers {topology} segments (root, joints' children, detached) \
         but the segmentation has {segments}; rerun topo on this segmentation"
    )]
    TopologyMismatch {
        /// Segments in the segmentation.
        segments: usize,
        /// Segments the topology places: 1 root + one per joint + detached ones.
        topology: usize,
    },
    /// A topology joint refers to a segment or pair that the pair fits do not hold.
    #[error("bonefit: joint {joint}: {reason}; rerun topo on these pair fits")]
    BadJoint {
        /// Joint name.
        joint: String,
        /// What does not match.
        reason: String,
    },
    /// The root segment has no pose track.
    #[error(
        "bonefit: root segment {root} has no pose track (the pair fits hold {segments} segments)"
    )]
    BadRoot {
        /// Root segment id.
        root: usize,
        /// Segments with a pose track.
        segments: usize,
    },
    /// The joint's centre was never fitted (non-finite centre in a segment's frame).
    #[error(
        "bonefit: joint {joint} (pair {pair}) has no finite centre in segment {segment}'s frame; \
         jointfit could not fit it"
    )]
    UnfittedJoint {
        /// Joint name.
        joint: String,
        /// Index in `PairFits::pairs`.
        pair: usize,
        /// The segment whose frame lacks the centre.
        segment: usize,
    },
}
