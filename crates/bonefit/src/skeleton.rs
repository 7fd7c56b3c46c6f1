//! The bonefit stage's artifact: a skeleton with constant bones and its motion.

use serde::{Deserialize, Serialize};

/// Schema version of [`Skeleton`]; bump when its fields or the algorithm's output change.
pub const SCHEMA_VERSION: u32 = 16;

/// A hierarchy with constant offsets and per-frame rotations, ready for animation files.
///
/// Forward kinematics: the root point is `root_translations[f]` (equal to
/// `root_positions[f]` wherever that is known); the root segment's rotation is
/// `root_rotations[f]`. A joint's global position is its parent's position (the root
/// point for children of the root) plus the parent's global rotation applied to the
/// joint's `offset`. A joint's global rotation is its parent's global rotation times its
/// `local_rotations[f]`; it is the orientation of the joint's child segment. Positions
/// given by this are exactly `positions` (where not NaN).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Skeleton {
    /// Frames per second.
    pub frame_rate: f64,
    /// Number of frames.
    pub frame_count: usize,
    /// Segment at the root.
    pub root_segment: usize,
    /// Name of the root node in animation files.
    pub root_name: String,
    /// How the constant offsets were fitted: "rigid" (joint centres fixed in each segment's
    /// frame) or "paper" (Aguiar et al. Eq. 5–6, root to leaves).
    #[serde(default)]
    pub method: String,
    /// How the per-frame orientations were chosen: "fitted" (rotation about the FK parent
    /// joint fitted to the child joint centres and markers) or "poses" (marker poses).
    #[serde(default)]
    pub rotation_method: String,
    /// The root point in the root segment's local frame (mm): where `root_positions` sits on
    /// the root segment (mean of the root's child joint centres).
    #[serde(default)]
    pub root_point_in_segment: [f64; 3],
    /// Root point per frame (mm, global); NaN where unknown.
    #[serde(with = "mocap_io::bulk::vec3s")]
    pub root_positions: Vec<[f64; 3]>,
    /// The root point forward kinematics starts from per frame (mm, global): the root
    /// point where it is known; where it is not but a segment posed on its own fixes the
    /// joint the chains start from, the point the rotations on the way up reach from it
    /// (not itself known); NaN where neither (animation files hold the last one).
    #[serde(with = "mocap_io::bulk::vec3s")]
    pub root_translations: Vec<[f64; 3]>,
    /// Root segment orientation per frame, unit quaternion `[x, y, z, w]`; never NaN
    /// (unknown frames carry an interpolated or held value; see `positions` for what is known).
    #[serde(with = "mocap_io::bulk::vec4s")]
    pub root_rotations: Vec<[f64; 4]>,
    /// Joints, every parent before its children (same order as the topology's joints).
    pub joints: Vec<SkeletonJoint>,
}

/// One joint of the skeleton.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkeletonJoint {
    /// Name shared with the topology, skeleton.json and the BVH.
    pub name: String,
    /// Index of the parent joint in `Skeleton::joints`; `None` when the parent is the root.
    pub parent: Option<usize>,
    /// Segment nearer the root.
    pub parent_segment: usize,
    /// Segment farther from the root.
    pub child_segment: usize,
    /// Index of the joint's fit in `PairFits::pairs`.
    #[serde(default)]
    pub pair: usize,
    /// Constant offset from the parent joint (or root point) in the parent's rest frame (mm).
    pub offset: [f64; 3],
    /// Constant bone length: the norm of `offset` (mm).
    pub bone_length: f64,
    /// Rotation of the child segment relative to the parent, per frame, `[x, y, z, w]`; never NaN.
    #[serde(with = "mocap_io::bulk::vec4s")]
    pub local_rotations: Vec<[f64; 4]>,
    /// Global position per frame given by forward kinematics (mm); NaN where unknown.
    #[serde(with = "mocap_io::bulk::vec3s")]
    pub positions: Vec<[f64; 3]>,
    /// Frames whose `positions` are known (not NaN).
    #[serde(default)]
    pub frames_known: usize,
    /// Of `frames_known`, frames known only through a short pose gap filled by interpolation.
    #[serde(default)]
    pub frames_interpolated: usize,
    /// RMS over frames of the distance between `positions` and jointfit's fitted centre
    /// (`PairFit::positions`) where both are known (mm); NaN when never both known.
    #[serde(default)]
    pub fit_rms_mm: f64,
    /// Range of motion of the child segment relative to the parent over the frames where
    /// both poses were measured (degrees, largest angle between two relative orientations,
    /// approximated by a two-sweep search); NaN when never both measured.
    #[serde(default)]
    pub range_of_motion_deg: f64,
    /// How far the hinge centre was slid along its axis from the pair fit's centre (mm);
    /// 0 for ball joints and when `place_hinges` is off.
    #[serde(default)]
    pub hinge_shift_mm: f64,
}
