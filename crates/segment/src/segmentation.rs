//! The segment stage's artifact: which markers move rigidly together.

use std::borrow::Cow;

use mocap_io::{MISSING, Trajectories};
use serde::{Deserialize, Serialize};

/// Schema version of [`Segmentation`]; bump when its fields or the algorithm's output change.
pub const SCHEMA_VERSION: u32 = 53;

/// The rigid segments found in a capture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segmentation {
    /// Segments, `id` = index in this vector, ordered by their smallest marker index.
    pub segments: Vec<Segment>,
    /// Markers in no segment, each with the reason.
    pub unassigned: Vec<UnassignedMarker>,
    /// Per-marker diagnostics, indexed like the capture's labels.
    pub markers: Vec<MarkerDiagnostics>,
    /// Noise level: median over markers of the smallest distance standard deviation ρ, mm
    /// (of the biggest body's markers, where bodies that move independently were segmented
    /// apart: `Params::body_gap_ratio`; so the tolerance and scatter smoothness).
    pub noise_mm: f64,
    /// Rigidity tolerance on ρ for pieces of 1-2 markers, the later checks and the cliques, mm (from the rigid spread; markers move and posed clusters merge within tolerance_factor × noise_mm).
    pub tolerance_mm: f64,
    /// How smoothly the scatter about rigidity runs from frame to frame: the median lag-one
    /// autocorrelation of each marker's distance to its steadiest partner (about 0 for white
    /// measurement noise, which takes `tolerance_factor_white`; near 1 for skin); `None`
    /// when no marker has such a partner.
    #[serde(default)]
    pub scatter_smoothness: Option<f64>,
    /// Top eigenvalues of D^-1/2 A D^-1/2, descending (spectral method; empty otherwise;
    /// every body's together where bodies were segmented apart).
    pub eigenvalues: Vec<f64>,
    /// Cluster count spectral clustering chose (eigen-gap or forced; summed over bodies
    /// segmented apart), before the rigidity check; 0 for cliques.
    pub eigengap_segments: usize,
    /// Pairs of markers whose trajectories the capture has exchanged for a while, undone in
    /// this order (a marker can be in several); later stages read the trajectories
    /// through [`Segmentation::repaired`].
    #[serde(default)]
    pub swaps: Vec<LabelSwap>,
    /// Markers' samples read as gaps because they left their steadiest partners (in the
    /// capture with the swaps undone); later stages read them as gaps too.
    #[serde(default)]
    pub glitches: Vec<Glitch>,
    /// Segments the joint test left whole whose best cut came near its bounds
    /// (`Params::near_joint_fraction`): maybe two segments that turn little about a joint.
    #[serde(default)]
    pub near_joints: Vec<NearJoint>,
    /// The capture's marker labels, indexed like `markers`: so later stages can name a
    /// marker (`topo.joints` by label) without the capture.
    #[serde(default)]
    pub labels: Vec<String>,
    /// Ids of the segments `Params::groups` named (the user's, not the data's), ascending.
    #[serde(default)]
    pub named_segments: Vec<usize>,
    /// Tracks read as pieces of one marker's trajectory (each ascending, never seen
    /// together; `Params::join_pieces`): segmented as one marker, each piece in its
    /// marker's segment; later stages read them joined (see [`Segmentation::repaired`]).
    #[serde(default)]
    pub pieces: Vec<Vec<usize>>,
    /// The segment of the markers that never move (the room's, or a fixed base's; see
    /// `Params::stationary_jitter_factor`), grouped apart from everything that moves.
    #[serde(default)]
    pub stationary_segment: Option<usize>,
    /// Where the capture holds bodies that move independently of each other (a subject
    /// and the props it does not hold, two subjects; `Params::body_gap_ratio`), each
    /// body's segment ids, ascending, the biggest body first; empty where it holds one.
    #[serde(default)]
    pub bodies: Vec<Vec<usize>>,
}

/// A segment the joint test left whole although its best cut came near the test's bounds:
/// maybe two segments that turn little about a joint, as skin leaves it (a diagnostic).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NearJoint {
    /// Index into [`Segmentation::segments`].
    pub segment: usize,
    /// The cut's two parts (marker indices, ascending), the first holding the segment's
    /// smallest marker index.
    pub parts: [Vec<usize>; 2],
    /// The joint test's rotation score of the cut (it cuts above `joint_split_z`).
    pub rotation_z: f64,
    /// The joint test's centroid travel score of the cut (it cuts above `joint_travel_z`).
    pub travel_z: f64,
}

/// The frames in which one marker was off its steadiest partners (`glitch_factor`): a
/// misreconstruction, not the marker's motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Glitch {
    /// Marker index into the capture's labels.
    pub marker: usize,
    /// Frame index ranges `[first, last]` (0-based, inclusive).
    pub frames: Vec<[usize; 2]>,
}

/// Two markers of different segments whose trajectories were exchanged (a tracker
/// confuses markers that pass close to each other), and when.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabelSwap {
    /// The two marker indices into the capture's labels.
    pub markers: [usize; 2],
    /// Frame index ranges `[first, last]` (0-based, inclusive) where each marker's
    /// trajectory holds the other's.
    pub frames: Vec<[usize; 2]>,
}

impl Segmentation {
    /// Replaces the segments by `groups` (marker indices; empty groups dropped), in the
    /// stage's order (by smallest marker); a marker in none is unassigned, with the stage's
    /// reason where it gave one and `why_left_out` otherwise. The near joints go; the other
    /// diagnostics stay the stage's. For diagnostics that feed later stages other segments
    /// (the truth).
    pub fn regroup(&mut self, groups: &[Vec<usize>], why_left_out: &str) {
        let mut groups: Vec<Vec<usize>> = groups
            .iter()
            .filter(|markers| !markers.is_empty())
            .map(|markers| {
                let mut markers = markers.clone();
                markers.sort_unstable();
                markers
            })
            .collect();
        groups.sort_unstable_by_key(|markers| markers[0]);
        self.segments = groups
            .into_iter()
            .enumerate()
            .map(|(id, markers)| Segment { id, markers })
            .collect();
        // The stage's near joints and named groups name its own segments.
        self.near_joints.clear();
        self.named_segments.clear();
        for d in &mut self.markers {
            d.segment = None;
        }
        for s in &self.segments {
            for &m in &s.markers {
                if let Some(d) = self.markers.get_mut(m) {
                    d.segment = Some(s.id);
                }
            }
        }
        let stage_said: Vec<UnassignedMarker> = std::mem::take(&mut self.unassigned);
        self.unassigned = (0..self.markers.len())
            .filter(|&m| self.markers[m].segment.is_none())
            .map(|m| {
                stage_said
                    .iter()
                    .find(|u| u.marker == m)
                    .cloned()
                    .unwrap_or_else(|| UnassignedMarker {
                        marker: m,
                        reason: why_left_out.into(),
                    })
            })
            .collect();
    }

    /// The capture's trajectories as segmentation read them: every label swap undone, then
    /// every glitch sample missing, then each group of pieces of one marker in its first
    /// track (the others left empty); borrowed unchanged when there is none of these. Markers or
    /// frames out of the capture's range are left alone.
    pub fn repaired<'a>(&self, traj: &'a Trajectories) -> Cow<'a, Trajectories> {
        if self.swaps.is_empty() && self.glitches.is_empty() && self.pieces.is_empty() {
            return Cow::Borrowed(traj);
        }
        let mut positions = self.unswapped_unglitched(traj);
        join_pieces(&mut positions, traj.markers(), &self.pieces);
        Cow::Owned(with_positions(traj, positions))
    }

    /// As [`Segmentation::repaired`], with each piece of one marker left in its own track.
    pub(crate) fn repaired_apart(&self, traj: &Trajectories) -> Trajectories {
        with_positions(traj, self.unswapped_unglitched(traj))
    }

    /// `traj`'s samples with every label swap undone and every glitch sample missing.
    fn unswapped_unglitched(&self, traj: &Trajectories) -> Vec<[f64; 3]> {
        let (n, frames) = (traj.markers(), traj.frames());
        let mut positions = untangled_positions(traj, &self.swaps);
        for glitch in self.glitches.iter().filter(|g| g.marker < n) {
            for &[first, last] in &glitch.frames {
                for f in (first..=last).take_while(|&f| f < frames) {
                    positions[f * n + glitch.marker] = MISSING;
                }
            }
        }
        positions
    }
}

/// Moves each group's samples (frame-major `positions` of `n` markers) into its first track
/// and leaves the others empty; groups naming a marker out of range are left alone.
pub(crate) fn join_pieces(positions: &mut [[f64; 3]], n: usize, groups: &[Vec<usize>]) {
    for group in groups.iter().filter(|g| g.iter().all(|&m| m < n)) {
        let Some((&kept, pieces)) = group.split_first() else {
            continue;
        };
        for frame in positions.chunks_exact_mut(n.max(1)) {
            for &p in pieces {
                if mocap_io::is_present(frame[p]) {
                    frame[kept] = frame[p];
                    frame[p] = MISSING;
                }
            }
        }
    }
}

/// `traj` with the trajectories of each swap's two markers exchanged back in its frames;
/// markers or frames out of range are left alone.
pub fn untangle(traj: &Trajectories, swaps: &[LabelSwap]) -> Trajectories {
    with_positions(traj, untangled_positions(traj, swaps))
}

/// `traj`'s samples with each swap's two trajectories exchanged back (see [`untangle`]).
fn untangled_positions(traj: &Trajectories, swaps: &[LabelSwap]) -> Vec<[f64; 3]> {
    let (n, frames) = (traj.markers(), traj.frames());
    let mut positions = traj.positions().to_vec();
    for swap in swaps {
        let [a, b] = swap.markers;
        if a >= n || b >= n {
            continue;
        }
        for &[first, last] in &swap.frames {
            for f in (first..=last).take_while(|&f| f < frames) {
                positions.swap(f * n + a, f * n + b);
            }
        }
    }
    positions
}

/// `traj` with its samples replaced by `positions` (rearranged or some made missing, so
/// valid wherever `traj` was; `traj` itself should they somehow not be).
pub(crate) fn with_positions(traj: &Trajectories, positions: Vec<[f64; 3]>) -> Trajectories {
    traj.with_positions(positions)
        .unwrap_or_else(|_| traj.clone())
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
    /// Visible frames read as gaps because the marker left its steadiest partners (`glitch_factor`).
    #[serde(default)]
    pub glitch_frames: usize,
    /// RMS over its segment-mates of the standard deviation of their distance (mm); NaN if alone.
    pub rigidity_residual_mm: f64,
    /// True when the marker moves relative to its segment more than its mates do (skin slide).
    pub slides: bool,
}
