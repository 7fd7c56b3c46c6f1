//! bonefit: constant bones and the motion as animation files need it.
//!
//! Takes the capture (frame count and rate), the segmentation, jointfit's
//! [`jointfit::PairFits`] (segment poses, joint centres) and the [`topo::Topology`];
//! gives a [`Skeleton`]: a hierarchy with one constant offset per joint, the root point's
//! position and the root segment's rotation per frame, every joint's rotation relative to
//! its parent per frame, and every joint's global position given by forward kinematics
//! (FK) of exactly those numbers.
//!
//! How (see [`BoneMethod`]):
//! - `rigid` (default): a joint centre is fixed in both adjacent segments' local frames
//!   (`PairFit::centre_in_a` / `centre_in_b`), so a bone — from the parent joint of a
//!   segment to one of its child joints, both fixed in that segment's frame — is rigid by
//!   construction: the offset is the difference of the two centres in that segment's frame.
//! - `paper`: Aguiar et al. Eq. 5–6, root to leaves: each bone's constant length is the
//!   mean over frames of the distance from the (already adjusted) parent joint to the
//!   fitted joint; its direction in the parent segment's frame is the mean direction.
//! - The root point is the mean of the root segment's child-joint centres in its frame,
//!   carried by its pose, so it lies inside the body.
//! - Rotations: the root rotation is the root segment's orientation; a joint's local
//!   rotation is the orientation of its child segment relative to its parent segment.
//!   All local rotations identity = the rest pose = every segment at its reference
//!   orientation (segment frames have the global axes at the reference). How each
//!   segment's orientation is chosen per frame (see [`RotationMethod`]):
//!   - `fitted` (default): root to leaves, each segment's rotation about its parent joint
//!     (already placed by FK) is the weighted least-squares rotation (Horn, no translation)
//!     mapping its constant bone vectors onto the observed ones (jointfit's fitted child
//!     centres minus the FK parent joint), and its markers (relative to the parent joint,
//!     weight `marker_weight`) onto the observed markers. Every level re-anchors on
//!     observations, so per-joint mismatches do not add up down the chain, and a segment
//!     whose own pose is missing is still oriented by its children's centres (seen from
//!     the children's side) or by two markers and its parent joint. The root's pose is the
//!     same fit with a translation. Each segment's rotation relative to its parent in the
//!     frame before is a prior weighed as a turn at `rotation_prior_deg_s` against its
//!     markers' scatter (none on exact data); in the first frame, and with no scatter, the
//!     segment's pose from jointfit (or, unmeasured, that rotation again) is a weak prior
//!     that only settles what the observations leave free: observations on one line
//!     through the joint fix its direction, and the spin about it is the prior's.
//!   - `poses`: each segment's orientation is its marker pose from jointfit; FK chains the
//!     poses from the root (errors add up along the chain).
//! - Gaps: rotations are never NaN (slerp between the nearest measured poses, held at the
//!   ends; the root is interpolated between the frames its pose or observations fix it,
//!   other segments fall back to identity when never measured). A pose gap of at most `max_gap_s` between two
//!   measured poses is filled (slerp + linear translation) and counts as known. With
//!   `poses`, a joint's position is NaN wherever a pose on its chain from the root is
//!   neither measured nor filled. With `fitted`, a joint is known where its parent joint
//!   is known and its parent segment's rotation is fixed by observations (two
//!   non-parallel observed vectors, or the joint's own fitted centre) or by a measured or
//!   filled pose. Where the root is not known in a frame, the chains start from a joint
//!   whose child segment is posed on its own there (the one carrying the most joints):
//!   that joint sits at its observed position and counts as known, the segments on the
//!   way up to the root keep their prior orientations, and the root point goes where
//!   those reach it (`Skeleton::root_translations`, what animation files carry; the root
//!   point itself stays unknown), so what hangs below the joint is known as usual and
//!   forward kinematics still reproduces it. One root translation reaches one such
//!   joint, so the joints on the way up and off it stay unknown in that frame.
//!
//! - Hinges: with `place_hinges`, every hinge centre of the tree first slides along its
//!   axis (on a copy of the pair fits); the shift is `SkeletonJoint::hinge_shift_mm`.
//!   `hinge_placement = bone` (default): every hinge at once where its axis crosses its
//!   child's bone (`jointfit::place_hinges_across_bones`): the joints the child carries
//!   and the child's markers, and the parent side's joints and markers where they agree
//!   (a limb's parent bone crosses squarely too), each weighted by its precision, and
//!   where its axis meets the line of a segment's other joints, all in line
//!   (`hinge_lines`: branches along one bone). Which side is a hinge's child is judged
//!   from the segment that turns least in the world (`hinge_sides_from_steadiest`,
//!   `jointfit::steadiest_orientation`): the subject's root, where topo roots the tree at
//!   its centre.
//!   `child`: a hinge with ball joints on its child segment goes, by itself, nearest
//!   their mean; the others take the joint solve of all hinges
//!   (`jointfit::place_hinge_centres`) where that slide is at most
//!   `hinge_max_shift_ratio` of the bone. Every slide is kept only if it barely changes
//!   the pair's residual (`hinge_residual_increase`), or if it ends at a point two other
//!   segments' pair fit measured (`jointfit::HingePlacements::at_composite_point`: two
//!   joints on one tip), where skin's tilt of the axis, not doubt, grows the residual, or
//!   if the pair's rotation leaves its axis a free line and the residual at most doubles
//!   (`hinge_free_gain`): sliding along a wobbling axis grows the residual by the wobble.
//!   Where the line is less free (centre gain g below that bound G), the slide is kept in
//!   part, g² / (g² + G²) of it: the pair fit and the placement each weighed by the
//!   other's variance.
//!   Measured (`cargo xtask eval --seeds
//!   4001,4002,4003,7001,9001,1001,5001,5002 --compare
//!   bonefit.hinge_placement=child,bone`): clean 0.34 % → 0.10 % of height, hard 1.83 % →
//!   1.74 %; random-clean over seeds 4001–4016 1.20 % → 0.56 %.
//! - Centres and positions: with `tree_centres`, before the hinges are placed, the tree's
//!   joint centres are refitted all at once (`jointfit::tree_centres`: the gaps of joints
//!   on one segment err together), not pair by pair; with `tree_positions`, after the
//!   hinges are placed, every tree joint's observed position per frame (what the `fitted`
//!   rotations follow) is read from all the tree joints' views at once
//!   (`jointfit::tree_positions`).
//!
//! It does not fit joint centres (jointfit), choose the tree (topo) or write files (export).
mod error;
mod fit;
mod horn;
mod poses;
mod skeleton;
#[cfg(any(test, feature = "testkit"))]
pub mod testkit;

pub use error::Error;
pub use fit::run;
pub use skeleton::*;

use serde::{Deserialize, Serialize};

/// Name of this stage (cache keys, artifact headers).
pub const STAGE: &str = "bonefit";

/// How the constant bone offsets are fitted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BoneMethod {
    /// Offsets from the joint centres fixed in each segment's frame (rigid by construction).
    #[default]
    Rigid,
    /// Aguiar et al. Eq. 5–6: root-to-leaf least squares on the fitted joint positions.
    Paper,
}

/// Where a hinge centre goes on its axis (a hinge fixes a line, not a point).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HingePlacement {
    /// `jointfit::place_hinge_centres`: every hinge of the tree at once, bones to all
    /// adjacent joints as short as possible, slides capped by `hinge_max_shift_ratio`.
    Tree,
    /// Each hinge by itself, nearest the mean of its child segment's ball child joints;
    /// hinges with none take the capped `tree` slide.
    Child,
    /// As `child`, and a hinge with no ball child joint goes nearest its (already
    /// placed) hinge child joints.
    Chain,
    /// `jointfit::place_hinges_across_bones`: every hinge at once where its axis
    /// crosses the child's bone (the child's joints and markers; the parent side's where
    /// they agree), each by its precision; no length cap.
    #[default]
    Bone,
}

/// How each segment's orientation per frame is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RotationMethod {
    /// Root to leaves, the rotation about the FK parent joint that best fits the fitted
    /// child joint centres and the segment's markers (re-anchored at every level).
    #[default]
    Fitted,
    /// The segment's marker pose from jointfit, chained from the root.
    Poses,
}

impl RotationMethod {
    /// The method's name as written in params and skeleton.json.
    pub fn name(self) -> &'static str {
        match self {
            Self::Fitted => "fitted",
            Self::Poses => "poses",
        }
    }
}

impl BoneMethod {
    /// The method's name as written in params and skeleton.json.
    pub fn name(self) -> &'static str {
        match self {
            Self::Rigid => "rigid",
            Self::Paper => "paper",
        }
    }
}

/// Parameters of the bonefit stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Offset fit: `rigid` (default) or `paper`.
    pub method: BoneMethod,
    /// Per-frame segment orientations: `fitted` (default) or `poses`.
    pub rotations: RotationMethod,
    /// Weight of each visible marker relative to a fitted joint centre in the `fitted`
    /// rotation fit (default 0.1).
    pub marker_weight: f64,
    /// How fast a segment is expected to turn relative to its parent, degrees per second:
    /// each `fitted` rotation is pulled towards the frame before's by the weight of that
    /// turn against the segment's marker scatter (default 600; 0 = only the weak prior).
    pub rotation_prior_deg_s: f64,
    /// Longest pose gap filled by interpolation, in seconds (default 0.1 s).
    pub max_gap_s: f64,
    /// Slide every hinge centre of the tree along its axis (see `hinge_placement`)
    /// before fitting the bones (default true).
    pub place_hinges: bool,
    /// A hinge keeps its slid centre only if the pair's residual (the centre as the two
    /// segments carry it) grows by at most this fraction (+0.1 mm) (default 0.1).
    pub hinge_residual_increase: f64,
    /// A slid hinge centre is also kept where a pose error moves the pair's centre along
    /// its axis at least this many times as far (`jointfit::centre_gain`) and the residual
    /// grows by at most `hinge_free_residual_increase`: the rotation leaves that line
    /// free, and a slide along it grows the residual by the axis's wobble; at a gain g
    /// below it, g² / (g² + this²) of the slide is kept (default 20; 0 = never).
    pub hinge_free_gain: f64,
    /// See `hinge_free_gain` (default 1: the residual may double).
    pub hinge_free_residual_increase: f64,
    /// A `tree` slide (also `child`'s fallback) is kept only if it is at most this
    /// fraction of the bone from the parent joint (default 0.1).
    pub hinge_max_shift_ratio: f64,
    /// Where hinge centres go on their axes: `bone` (default), `child`, `chain` or `tree`.
    pub hinge_placement: HingePlacement,
    /// For `bone` placement, judge which side of each hinge is its child from the segment
    /// that turns least in the world, not from the tree's root (default true).
    pub hinge_sides_from_steadiest: bool,
    /// For `bone` placement, a hinge whose axis meets the line of one of its segments'
    /// other joints, all in line (branches along one bone), goes there as the evidence's
    /// precision allows (default true).
    pub hinge_lines: bool,
    /// Read the tree joints' positions from every tree joint's views at once
    /// (`jointfit::tree_positions`: a segment's pose error shows at all its joints),
    /// after the hinge placement (default true).
    pub tree_positions: bool,
    /// Refit the tree joints' centres all at once (`jointfit::tree_centres`), before the
    /// hinge placement (default true).
    pub tree_centres: bool,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            method: BoneMethod::Rigid,
            rotations: RotationMethod::Fitted,
            marker_weight: 0.1,
            rotation_prior_deg_s: 600.0,
            max_gap_s: 0.1,
            place_hinges: true,
            hinge_residual_increase: 0.1,
            hinge_free_gain: 20.0,
            hinge_free_residual_increase: 1.0,
            hinge_max_shift_ratio: 0.1,
            hinge_placement: HingePlacement::Bone,
            hinge_sides_from_steadiest: true,
            hinge_lines: true,
            tree_positions: true,
            tree_centres: true,
        }
    }
}

/// Every parameter: (field name, "meaning, units, default").
pub const PARAM_DOCS: &[(&str, &str)] = &[
    (
        "method",
        "bone offsets: \"rigid\" (joint centres fixed in each segment's frame; bones rigid by \
         construction) or \"paper\" (Aguiar et al. Eq. 5-6, root to leaves); default \"rigid\"",
    ),
    (
        "rotations",
        "per-frame segment orientations: \"fitted\" (root to leaves, the rotation about the \
         FK parent joint best fitting the fitted child joint centres and the segment's markers; \
         errors do not add up down the chain) or \"poses\" (each segment's marker pose, \
         chained from the root); default \"fitted\"",
    ),
    (
        "marker_weight",
        "weight of each visible marker relative to a fitted child joint centre in the \
         \"fitted\" rotation fit (dimensionless, >= 0); default 0.1",
    ),
    (
        "rotation_prior_deg_s",
        "how fast a segment is expected to turn relative to its parent (degrees per second, \
         >= 0): in the \"fitted\" rotation fit the segment's rotation relative to its parent \
         in the frame before is a prior of weight marker_weight x s^2 / t^2 (three unit \
         pairs; s the segment's median marker fit RMS, mm; t this speed over the frame rate, \
         radians), so a frame whose observations fix the turn poorly (a marker hidden, child \
         centres moving with a poorly posed segment, skin) follows them only as far as they \
         outweigh that turn; exact data (s = 0) are not held. cargo xtask eval --presets \
         hard --seeds 20001..20020 --compare bonefit.rotation_prior_deg_s=0,150,300,600,1200: \
         orientations (eval's orientation_error_deg, each tree segment against its true \
         segment after the best constant alignment of the two frames) 4.19 / 4.44 / 3.99 / \
         4.03 / 4.11 deg RMS, 111 trees and 1.37 % at every value; on seeds 20001..20050, \
         30001..30050 4.40 -> 4.25 deg at 600, clean 0.00 both, 539 trees and 1.455 % \
         both. The generator's joints turn slower than a sprint's, so 600 rather than 300 \
         leaves room for those. Turns over 30 deg from one frame to the next in the BVH \
         (a one-off count, hard seeds 20001-20030): 61 joints and 238 frames at 0, 22 and \
         54 at 600; the shared real captures 26 and 37 -> 24 and 34; CMU 02_01's limbs \
         unchanged; 0 = only the weak prior \
         that settles what the observations leave free; default 600",
    ),
    (
        "max_gap_s",
        "longest gap in a segment's pose (seconds) filled by slerp/linear interpolation and \
         counted as known; longer gaps leave joint positions unknown; default 0.1",
    ),
    (
        "place_hinges",
        "slide each hinge centre of the tree along its axis (a hinge fixes a line, not a \
         point) as hinge_placement says, before fitting bones and rotations; default true",
    ),
    (
        "hinge_residual_increase",
        "a slid hinge centre is kept only if the pair's residual RMS (mm, the centre as the \
         two segments carry it) grows by at most this fraction plus 0.1 mm; otherwise the \
         pair fit's centre stays (the axis is not a line of equally good centres); a \
         slide to a point two neighbouring segments' own fit measured (two joints on one \
         tip) is kept regardless; default 0.1",
    ),
    (
        "hinge_free_gain",
        "a slid hinge centre refused by hinge_residual_increase is kept when a pose error \
         moves the pair's centre along its axis at least this many times as far \
         (jointfit::centre_gain, 1 / sqrt(2 x the least eigenvalue of the SCoRE normal \
         matrix)) and the residual grows by at most hinge_free_residual_increase: the \
         rotation leaves that line free, so sliding along it grows the residual by the \
         axis's own wobble times the slide, not because the data place the centre elsewhere \
         (random-hard-s30034's joint06, 117 mm along its axis, was refused a 116 mm slide \
         for 10.0 -> 11.2 mm of residual at a gain of 43; 6 mm off with it). A ball joint \
         turning every way has a gain of 2-6. Measured (cargo xtask eval --presets hard, \
         seeds 20001-20050,30001-30050, every subject, against 0): mean 1.722 -> 1.715 % of \
         height (random trees 2.140 -> 2.085, robot arm 1.088 -> 1.094, hexapod 4.403 -> \
         4.407, the rest within 0.001), trees unchanged; 12, 15, 25 and 30 gave 1.721, 1.718, \
         1.717 and 1.719. At a gain g below it the slide is kept in part, g^2 / (g^2 + this^2) \
         of it (the pair fit places the centre along the axis to about g times its poses' \
         error, the placement to about this many times it; each counts by the other's \
         variance): random-hard-s30021's joint02, gain 16.9 with two child joints to place \
         it, had stayed 138 mm along its axis. Against keeping none of it (same runs, \
         trees unchanged): seeds 20001-20050,30001-30050 1.4069 -> 1.4014 % (random trees \
         1.637 -> 1.608, hexapod 3.845 -> 3.839, the rest within 0.003); 40001-40100 \
         1.4071 -> 1.4023 (random 1.549 -> 1.514); on seeds 20001-20020 --sweep 0.2:0.4 \
         3.662 -> 3.681, --markers 2:3 3.149 -> 3.133, --marker-arc 120 2.041 -> 2.040, clean \
         identical; the partial share for every slide (none whole) gave 1.4016 and 1.4047, \
         and without the residual bound 1.4005 and 1.4008 but CMU 02_01's shoulders (hinges \
         in that walk) slid 56-64 mm and its left humerus came out 257.8 mm against Vicon's \
         274.6; with it, CMU 02_01's right humerus 275.5 -> 286.7 mm (Vicon 283.7) while its \
         right elbow's centre went 85 -> 100 mm from Vicon's (vicon test), and every \
         other real capture's bones within 7.1 mm (Sample_Jump2, gait-raw, MACsample); ratio; \
         0 = off; default 20",
    ),
    (
        "hinge_free_residual_increase",
        "see hinge_free_gain: how much a slide along a free axis may grow the pair's residual \
         RMS (fraction, plus 0.1 mm); a several-fold growth means the data do place the \
         centre (CMU 02_01's elbows, which turn little and not quite about one axis in a \
         walk: 1.0 -> 5.8 and 2.3 -> 5.3 mm for slides of 121 and 100 mm that shortened the \
         upper arms by 9-12 %); W hard as for hinge_free_gain: 0.5 gave 1.716, unbounded \
         1.714 % with those upper arms 8.7 / 12.3 % short; default 1",
    ),
    (
        "hinge_max_shift_ratio",
        "a slid hinge centre is kept only if the slide is at most this fraction of the \
         joint's bone from its parent joint (dimensionless); larger slides come from \
         nearly parallel neighbouring axes or a noisy axis; applies to the \"tree\" \
         slides only; default 0.1",
    ),
    (
        "hinge_placement",
        "where a hinge centre goes on its axis: \"bone\" (jointfit::place_hinges_across_bones: \
         all hinges at once where each axis crosses its child's bone, from the child's \
         joints and markers and the parent side's where they agree, each weighted by its \
         precision), \"child\" (each hinge by itself, nearest the mean of its child \
         segment's ball child joints; hinges with none take the capped \"tree\" slide), \
         \"chain\" (as child, else nearest its placed hinge child joints) or \"tree\" \
         (jointfit::place_hinge_centres, all hinges at once toward every adjacent joint, \
         capped by hinge_max_shift_ratio); default \"bone\"",
    ),
    (
        "hinge_sides_from_steadiest",
        "with hinge_placement \"bone\": judge which side of each hinge is its child (the \
         bone the axis crosses squarely) with the tree's edges directed from the segment \
         whose orientation wanders least over the capture (1 - the largest singular value² \
         of its mean rotation matrix; jointfit::steadiest_orientation), when that is the \
         tree's root or wanders under half as much as the root, and then with a prior \
         probability of 1 % that a hinge's sides are the other way round instead of 10 %: the \
         subject's own root (a trunk, a robot's base, a random tree's first segment) turns \
         least, while topo roots the tree at its centre. The output tree keeps its root. \
         cargo xtask eval --compare bonefit.hinge_sides_from_steadiest=false,true: clean \
         random trees, seeds 20001-20100 and 30001-30100, 0.438 -> 0.318 % of height (33 \
         trials better, 14 worse; the generator's root forced as topo.root, with the 10 % \
         prior: 0.395); seeds 4001-4006, 6001-6006, 7001, 9001, 1001, 5001 and \
         10001-10032: clean 0.071 -> 0.062 %, hard 1.818 -> 1.815, skin 1.861 -> 1.852 \
         (robot arm hard 1.050 -> 1.055, human clean 0.041 -> 0.045); --markers 2:3 on the \
         first 16: clean 0.179 -> 0.146, hard 2.978 -> 2.974; seeds 20001-20050, \
         30001-30050: hard 1.875 -> 1.864, skin 1.889 -> 1.877 (random 2.25 -> 2.17, robot \
         arm 1.057 -> 1.084); trees unchanged everywhere. Of the shared real captures, CMU \
         02_01 moves 0.4 mm, c3d.org's gait-raw left knee 19.5 mm (36.6 -> 33.9 mm from \
         the LKNE marker), Sample_Jump2 and MACsample (both trees already odd) more, the \
         rest not at all; default true",
    ),
    (
        "hinge_lines",
        "with hinge_placement \"bone\": a hinge whose axis meets the line of one of its \
         segments' other joints (at least two, every one on that line within 3 standard \
         deviations of its fit; a free hinge among them where its child side puts it) goes \
         there, weighted by how precisely the crossing places it, where the test of that \
         meeting could tell the line from one missing by half the joints' spacing: a bone \
         is a line, and joints hung along it (a random tree's branches) are in line. cargo \
         xtask eval --presets clean --subjects random --seeds 20001..20050,30001..30050 \
         --compare bonefit.hinge_lines=false,true: 0.3067 -> 0.2318 % of height (held-out \
         30051..30080: 0.2843 -> 0.2495); hard, every subject, the same seeds: 1.3837 -> \
         1.3796 %, no tree changes; default true",
    ),
    (
        "tree_positions",
        "read each tree joint's position per frame from every tree joint's two views at once \
         (jointfit::tree_positions): a segment's pose error in a frame is one rigid error \
         that shows at all the joints it carries, so the gap between the views of one joint \
         tells the others something; the posterior mean under the pair fits' pose-precision \
         model, which for a joint alone is the pair's own precision-weighted mean; after the \
         hinge placement, before the bones. cargo xtask eval --presets hard --compare \
         bonefit.tree_positions=false,true (before tree_centres), seeds \
         20001-20050,30001-30050: 1.574 -> 1.567 % of height (true segments 1.452 -> 1.444), \
         40001-40100: 1.564 -> 1.556; trees and clean unchanged; default true",
    ),
    (
        "tree_centres",
        "refit the tree joints' centres all at once (jointfit::tree_centres): SCoRE's gaps of \
         all the tree's joints in a frame weighted by the inverse of their joint covariance \
         under the pose-precision model, where the pair fits weigh one joint at a time as if \
         two joints on one segment erred independently; a hinge keeps its place along its \
         axis; before the hinge placement. cargo xtask eval --presets hard --compare \
         bonefit.tree_centres=false,true, seeds 20001-20050,30001-30050: 1.567 -> 1.466 % of \
         height (true segments 1.444 -> 1.329), 40001-40100: 1.556 -> 1.456; trees and clean \
         unchanged; default true",
    ),
];
