//! The segment stage's artifact: which markers move rigidly together.

use serde::{Deserialize, Serialize};

/// Schema version of [`Segmentation`]; bump when its fields or the algorithm's output change.
pub const SCHEMA_VERSION: u32 = 7;

/// The rigid segments found in a capture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segmentation {
    /// Segments, `id` = index in this vector, ordered by their smallest marker index.
    pub segments: Vec<Segment>,
    /// Markers in no segment, each with the reason.
    pub unassigned: Vec<UnassignedMarker>,
    /// Per-marker diagnostics, indexed like the capture's labels.
    pub markers: Vec<MarkerDiagnostics>,
    /// Noise level: median over markers of the smallest distance standard deviation ρ, mm.
    pub noise_mm: f64,
    /// Rigidity tolerance on ρ used by the rigidity check and the cliques, mm.
    pub tolerance_mm: f64,
    /// Top eigenvalues of D^-1/2 A D^-1/2, descending (spectral method; empty otherwise).
    pub eigenvalues: Vec<f64>,
    /// Cluster count spectral clustering chose (eigen-gap or forced), before the rigidity check; 0 for cliques.
    pub eigengap_segments: usize,
}

/// A set of markers that move as one rigid body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Index of this segment in [`Segmentation::segments`].
    pub id: usize,
    /// Marker indices into the capture's labels, ascending.
    pub markers: Vec<usize>,
}

/// A marker left out of every segment, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnassignedMarker {
    /// Marker index into the capture's labels.
    pub marker: usize,
    /// Why, in words ("visible in 3 of 1200 frames", ...).
    pub reason: String,
}

/// What the segment stage measured about one marker.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MarkerDiagnostics {
    /// Segment id, or `None` when unassigned.
    pub segment: Option<usize>,
    /// Frames in which the marker is visible.
    pub visible_frames: usize,
    /// RMS over its segment-mates of the standard deviation of their distance (mm); NaN if alone.
    pub rigidity_residual_mm: f64,
    /// True when the marker moves relative to its segment more than its mates do (skin slide).
    pub slides: bool,
}
