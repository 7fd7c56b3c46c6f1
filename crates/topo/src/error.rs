//! Errors of the topo stage.

/// Why the topology could not be built.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The segmentation holds no segment, so there is nothing to connect.
    #[error(
        "topo: the segmentation has no segments, so there is nothing to build a tree from \
         ({unassigned} markers unassigned{first_reason}); a capture needs enough frames in which \
         markers are seen together (see segment.min_visible_frames)"
    )]
    NoSegments {
        /// Markers the segment stage left unassigned.
        unassigned: usize,
        /// The first unassigned marker's reason, as ", e.g. marker 3: …", or empty.
        first_reason: String,
    },
    /// The pair fits and the segmentation disagree on the number of segments.
    #[error(
        "topo: the pair fits hold poses for {poses} segments but the segmentation has {segments}; \
         rerun jointfit on this segmentation"
    )]
    SegmentCountMismatch {
        /// Segments in the segmentation.
        segments: usize,
        /// Segment pose tracks in the pair fits.
        poses: usize,
    },
    /// A pair fit names a segment that does not exist, or is not ordered `a < b`.
    #[error(
        "topo: pair fit {pair} joins segments {a} and {b}, but only segments 0..{segments} exist \
         (and a < b is required); the pair fits do not belong to this segmentation"
    )]
    BadPair {
        /// Index in `PairFits::pairs`.
        pair: usize,
        /// Its first segment.
        a: usize,
        /// Its second segment.
        b: usize,
        /// Number of segments.
        segments: usize,
    },
    /// The forced root (`topo.root`) is not a segment of the tree.
    #[error(
        "topo: topo.root = {root} is not usable: {reason}; pick one of the tree's segments {tree:?}"
    )]
    BadRoot {
        /// The requested root, as given.
        root: String,
        /// Why it cannot be used.
        reason: String,
        /// Segments of the tree that could be the root.
        tree: Vec<usize>,
    },
    /// The segment `topo.body` names is not one of the segmentation's.
    #[error("topo: topo.body = {body} is not usable: {reason}")]
    BadBody {
        /// The requested segment, as given.
        body: String,
        /// Why it cannot be used.
        reason: String,
    },
    /// A pair `topo.joints` names cannot be a tree edge.
    #[error("topo: topo.joints pair [{a}, {b}]: {reason}")]
    BadJoint {
        /// Its first segment, as given.
        a: String,
        /// Its second segment, as given.
        b: String,
        /// Why it cannot be used.
        reason: String,
    },
}
