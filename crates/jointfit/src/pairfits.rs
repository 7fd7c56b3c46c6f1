//! The jointfit stage's artifact: segment poses and a joint fit for every segment pair.

use serde::{Deserialize, Serialize};

/// Schema version of [`PairFits`]; bump when its fields or the algorithm's output change.
pub const SCHEMA_VERSION: u32 = 34;

/// Per-frame rigid poses of every segment and the joint fitted to every segment pair.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairFits {
    /// Number of frames of the capture.
    pub frames: usize,
    /// One entry per segment, indexed by segment id.
    pub poses: Vec<SegmentPoses>,
    /// One entry per unordered segment pair `(a, b)` with `a < b`, in lexicographic order.
    pub pairs: Vec<PairFit>,
}

impl PairFits {
    /// The fit between segments x and y (either order); `None` when there is none.
    pub fn pair(&self, x: usize, y: usize) -> Option<&PairFit> {
        self.pair_index(x, y).map(|i| &self.pairs[i])
    }

    /// Where the fit between segments x and y (either order) sits in `pairs`.
    pub fn pair_index(&self, x: usize, y: usize) -> Option<usize> {
        let (a, b) = (x.min(y), x.max(y));
        let n = self.poses.len();
        let is_it = |i: &usize| self.pairs.get(*i).is_some_and(|p| (p.a, p.b) == (a, b));
        // Lexicographic order of (a, b), a < b: the pairs before row a, then b's place in
        // it; a search where the fits are not laid out so.
        let at = (a < b && b < n).then(|| a * n - a * (a + 1) / 2 + (b - a - 1));
        at.filter(is_it)
            .or_else(|| self.pairs.iter().position(|p| (p.a, p.b) == (a, b)))
    }
}

/// The rigid motion of one segment: local frame → global frame at every frame.
///
/// Local frame: origin at the centroid of the reference shape, axes of the global frame
/// at the reference. Global position of a local point `p` at frame `f`:
/// `rotations[f] * p + translations[f]` (millimetres).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentPoses {
    /// Segment id.
    pub segment: usize,
    /// Reference positions of the segment's markers in the local frame (mm), in the
    /// segment's marker order; NaN for a marker never seen together with the others.
    #[serde(with = "mocap_io::bulk::vec3s")]
    pub reference: Vec<[f64; 3]>,
    /// Unit quaternion `[x, y, z, w]` per frame; NaN where the pose is unknown.
    #[serde(with = "mocap_io::bulk::vec4s")]
    pub rotations: Vec<[f64; 4]>,
    /// Translation per frame (mm); NaN where the pose is unknown.
    #[serde(with = "mocap_io::bulk::vec3s")]
    pub translations: Vec<[f64; 3]>,
    /// RMS distance of the visible markers from the posed reference, per frame (mm); NaN where unknown.
    #[serde(with = "mocap_io::bulk::f64s")]
    pub rms_mm: Vec<f64>,
}

/// How two segments are articulated, as far as the fit can tell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Three rotational degrees of freedom about a point.
    Ball,
    /// One rotational degree of freedom about an axis.
    Hinge,
    /// Two rotational degrees of freedom.
    Universal,
    /// No relative motion: the two are one body.
    Rigid,
}

/// The joint fitted between segments `a` and `b`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairFit {
    /// Lower segment id.
    pub a: usize,
    /// Higher segment id.
    pub b: usize,
    /// Method that produced the fit ("aguiar", "score", "local").
    pub method: String,
    /// The pair cost the topology is built from (lower = more likely a real joint), per
    /// marker and per frame so segments with few markers are not favoured.
    pub cost: f64,
    /// Joint centre in `a`'s local frame (mm).
    pub centre_in_a: [f64; 3],
    /// Joint centre in `b`'s local frame (mm).
    pub centre_in_b: [f64; 3],
    /// Joint centre in the global frame at every frame (mm): both segments' views, each
    /// weighted by how precisely its pose puts the centre; NaN where it cannot be known.
    /// Empty as the stage writes it: the centres and poses give it
    /// ([`PairFits::joint_positions`]), and a capture's pairs outnumber its tree's joints
    /// by the segment count over two (153 pairs, 17 joints for 18 segments), which the
    /// artifact would hold for every frame. A caller fills in the pairs it reads
    /// ([`PairFits::fill_positions`]) and may change them there.
    #[serde(with = "mocap_io::bulk::vec3s")]
    pub positions: Vec<[f64; 3]>,
    /// Articulation kind.
    pub kind: JointKind,
    /// Hinge axis in `a`'s local frame (unit vector), for hinges.
    pub axis_in_a: Option<[f64; 3]>,
    /// Hinge axis in `b`'s local frame (unit vector), for hinges: the same line as `axis_in_a`.
    pub axis_in_b: Option<[f64; 3]>,
    /// For universal joints: the axis fixed in `a`'s local frame and the axis fixed in
    /// `b`'s (unit vectors), whose angle stays constant.
    #[serde(default)]
    pub universal_axes: Option<[[f64; 3]; 2]>,
    /// RMS over frames of the distance between the centre as `a` and as `b` carry it (mm).
    pub residual_rms_mm: f64,
    /// Frames in which both segments have a pose.
    pub frames_used: usize,
    /// Range of motion: RMS angle of the relative rotation (b-local → a-local) from its mean
    /// over the frames used (degrees); NaN when not identifiable.
    pub rotation_rms_deg: f64,
    /// Largest angle of the relative rotation from its mean (degrees); NaN when not identifiable.
    pub rotation_max_deg: f64,
    /// How much each of the three principal directions of the relative rotation tilts
    /// (approximately RMS, degrees), ascending: a hinge has one near 0, a rigid pair all three.
    pub wobble_deg: [f64; 3],
    /// Human-readable evidence for `kind` (conditioning, range of motion).
    pub evidence: String,
    /// The centre was set from a posed-through segment's marker distances, which fixed it
    /// in every direction: hinge placement must not slide it along the axis (never so for a
    /// hinge under `Params::anchor_hinge_slides`: distances do not fix a point of its axis).
    #[serde(default)]
    pub centre_from_distances: bool,
    /// Every pose started from this joint: no segment had a pose of its own, and one of
    /// its two-marker segments was posed from both segments' markers' common centre.
    #[serde(default)]
    pub seeded: bool,
    /// The segment of the two whose poses come through this joint (posed from its markers
    /// and the centre as the other segment carries it; see `anchor.rs`), if any: the cost
    /// is then low partly by construction and is no scale for another pair's.
    #[serde(default)]
    pub posed_through: Option<usize>,
    /// Where a segment is posed through this joint: the other posed neighbour whose centre
    /// held that segment's markers next best, and its radial residual over this joint's
    /// (below 1, the tree pass kept this joint on a worse fit than another's).
    #[serde(default)]
    pub next_best_anchor: Option<(usize, f64)>,
    /// The kind the first pass (the segments' own poses) gave, where a second pass along
    /// the tree changed it and `Params::tree_from_second_pass` is off: topo's rules read it
    /// with the first pass's cost and rotation, so the tree is the one those poses
    /// support; `kind` fits this pair's centre.
    #[serde(default)]
    pub first_pass_kind: Option<JointKind>,
    /// How far the two segments disagree about the centre against what their poses' noise
    /// predicts, from the same pass as `cost` (`Params::tree_from_second_pass`): the RMS
    /// over frames of the disagreement's Mahalanobis length per coordinate, about 1 for a
    /// joint whose residual that noise explains; NaN where either segment has no noise
    /// measure (fewer than three markers fitted together) or the data are exact. See
    /// `Params::cost_noise_power`.
    #[serde(default = "not_measured")]
    pub misfit_over_noise: f64,
}

/// What an artifact written before a measure existed reads for it.
fn not_measured() -> f64 {
    f64::NAN
}

impl PairFit {
    /// The joint centre in segment `s`'s local frame (mm); `s` is `a` or `b`.
    pub fn centre_in(&self, s: usize) -> [f64; 3] {
        if self.a == s {
            self.centre_in_a
        } else {
            self.centre_in_b
        }
    }

    /// The kind topo's rules read: the first pass's where it is kept (see `first_pass_kind`).
    pub fn tree_kind(&self) -> JointKind {
        self.first_pass_kind.unwrap_or(self.kind)
    }

    /// A hinge whose centre may slide along its axis: every point of the axis fits the
    /// motion, and no marker distances fixed it.
    pub fn free_hinge(&self) -> bool {
        self.kind == JointKind::Hinge && !self.centre_from_distances
    }
}
