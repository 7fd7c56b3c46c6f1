//! Parameters of the jointfit stage.

use serde::{Deserialize, Serialize};

use crate::error::Error;

/// Joint-centre estimator for every segment pair.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// The paper's Eq. 2 (Aguiar et al. 2006): variance of joint-to-marker distances plus
    /// `alpha` × mean distance, minimised by L-BFGS in the first segment's frame.
    Aguiar,
    /// Symmetrical centre of rotation (Ehrig et al. 2006), closed-form linear least squares,
    /// with the hinge axis (SARA, Ehrig et al. 2007) from the same system.
    #[default]
    Score,
    /// Local fitting (the local-fitting paper, Sect. 3.3): a density-weighted sphere (or,
    /// for planar trajectories, circle) per marker in the other segment's frame by
    /// Levenberg–Marquardt, centres averaged with weight attachment / radius.
    Local,
}

impl Method {
    /// The name written to `PairFit::method`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Aguiar => "aguiar",
            Method::Score => "score",
            Method::Local => "local",
        }
    }
}

/// Parameters of the jointfit stage (see [`PARAM_DOCS`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Joint-centre estimator.
    pub method: Method,
    /// Weight of the mean-distance penalty in Eq. 2 (mm⁻¹ relative to the variance in mm²).
    pub alpha: f64,
    /// Pairs with fewer frames in which both segments have a pose get cost +∞.
    pub min_frames: usize,
    /// RMS relative rotation (degrees) below which a pair is called rigid.
    pub rigid_deg: f64,
    /// Hinge when the least-moving direction wobbles less than this fraction of the next one.
    pub hinge_ratio: f64,
    /// Also hinge, under this wobble ratio, when the least-moving direction wobbles no more
    /// than `hinge_noise_factor` times what the two segments' pose noise alone gives.
    pub hinge_noise_ratio: f64,
    /// See `hinge_noise_ratio`; 0 = off.
    pub hinge_noise_factor: f64,
    /// A pair the wobble ratio calls a hinge is not one when its least-moving direction
    /// wobbles beyond this many times the two segments' pose noise (+ 1°); 0 = off.
    pub hinge_max_noise_factor: f64,
    /// A pair that is neither hinge nor rigid is a universal joint when the pair of axes
    /// (one fixed in each segment) whose angle changes least changes it, beyond what the
    /// joint's two angles explain linearly and beyond noise, by under this fraction of the
    /// RMS relative rotation; 0 = off.
    pub universal_ratio: f64,
    /// Minimum RMS extent (mm) of the visible markers across their second principal
    /// direction for a pose to be fitted (nearly collinear markers fix no spin).
    pub min_spread_mm: f64,
    /// Largest standard error (degrees) of a pose's spin that a frame's fit may have,
    /// predicted from the segment's fit scatter and the visible markers' lever, where that
    /// lever is under half the whole segment's (nearly collinear markers left visible); a
    /// frame beyond it has no pose of its own; 0 = off.
    pub max_spin_deg: f64,
    /// Pose again along the tree the costs make: segments whose own poses turn too freely
    /// (beyond `max_spin_deg` with all markers seen) through a tree neighbour's joint, and
    /// anchors and gap fills through tree neighbours first; costs and relative rotations
    /// stay the first pass's.
    pub tree_poses: bool,
    /// Where the second pass runs, topo reads its costs, relative rotations and kinds
    /// (default true); false keeps the first pass's (the segments' own poses) for them.
    pub tree_from_second_pass: bool,
    /// First pass, `score` only: a pair with one loose segment (beyond `max_spin_deg`)
    /// corrects that segment's spin about its marker line per frame as noise of its
    /// predicted size, in the pair's centres and cost.
    pub spin_corrected_cost: bool,
    /// `score` only: the centres come from SCoRE weighted, frame by frame, by the
    /// precision of the two poses' disagreement at the centre (each pose's fit scatter
    /// through its markers' lever); the pair's cost stays the unweighted fit's.
    pub weighted_centres: bool,
    /// `score` only: each pair's cost is its residual (mm) times its `misfit_over_noise` to
    /// this power, where every pair of the capture has that measure (default 0.25; 0 = the
    /// residual).
    pub cost_noise_power: f64,
    /// A marker farther than this × the segment's median per-frame fit RMS from its fitted
    /// place leaves that frame's pose fit (and the reference shape), while ≥ 3 others stay
    /// (with 3 left and one still beyond, the frame has no pose); 0 = off.
    pub pose_outlier_factor: f64,
    /// ... and farther than this, mm.
    pub pose_outlier_floor_mm: f64,
    /// L-BFGS iteration limit for the `aguiar` method.
    pub max_iters: u64,
    /// Pose segments with fewer than 3 markers through a joint with a posed neighbour,
    /// and fill frames where only 2 of a segment's markers are visible.
    pub anchor: bool,
    /// Anchoring: least RMS angle (degrees) the markers must turn about the common centre.
    pub anchor_min_excursion_deg: f64,
    /// Anchoring: a neighbour whose centre fits S's markers with a residual below this
    /// fraction of the best identified neighbour's (with none yet, of the anchor taken next
    /// anywhere) is a candidate however little S turns about it (default 0.7; 0 = off).
    pub anchor_steadier_ratio: f64,
    /// Along the tree (second pass), a segment whose own markers fix its spin too loosely
    /// is anchored to a neighbour off the first pass's tree too, where that neighbour's
    /// centre fits its markers with a residual below this fraction of the best tree
    /// neighbour's (default 0.85; 0 = tree neighbours only).
    pub loose_off_tree_ratio: f64,
    /// Along the tree (second pass), a segment posed through a tree neighbour's joint
    /// although another posed neighbour's centre holds its markers with a radial residual
    /// below this fraction of that joint's (`PairFit::next_best_anchor`) is posed again,
    /// along the tree with that neighbour's edge in place of the first (a third pass;
    /// default 0.6; 0 = off).
    pub anchor_swap_ratio: f64,
    /// Anchoring: largest RMS radial residual (mm) of an acceptable common centre.
    pub anchor_max_rms_mm: f64,
    /// Anchoring: a common centre turned about less than the excursion bounds above still
    /// qualifies when its radial residual over the excursion (radians), how far the
    /// distances could let the centre stray, is within this (mm).
    pub anchor_exact_centre_mm: f64,
    /// Anchoring of 2-marker segments: pin the centre's coordinate along the marker line
    /// to the line's least-moving point (a prior weighted by its uncertainty).
    pub anchor_line_prior: bool,
    /// Joints of a segment posed through an anchor are centred by its markers' distances
    /// (the anchor's common centre; for its other joints, the common centre in the other
    /// segment's frame) instead of a refit on the poses built through the anchor.
    pub anchor_centres_by_distance: bool,
    /// `anchor_centres_by_distance` for a segment's joints other than its anchor: least RMS
    /// angle (degrees) its markers must turn about the centre for the distances to place it.
    pub anchor_refit_min_excursion_deg: f64,
    /// A hinge centred by marker distances (`anchor_centres_by_distance`) still slides along
    /// its axis in hinge placement.
    pub anchor_hinge_slides: bool,
    /// Along the tree, pose a two-marker segment posed through one joint from its markers
    /// and both its joints' centres.
    pub anchor_two_centres: bool,
    /// Where no segment can be posed by its own markers, pose one of two two-marker
    /// segments from its markers plus their common centre (`seed.rs`), and anchor on from it.
    pub anchor_seed: bool,
    /// When > 0, a hinge's centre is placed along its axis only if that raises the pair
    /// residual by at most this factor over the least-squares centre (+0.1 mm); 0 = always.
    pub hinge_slide_max_rise: f64,
    /// Method score: strength of the prior that a joint centre lies between its two
    /// segments, times (pair residual / their distance)²; 0 = none.
    pub centre_prior: f64,
    /// local only: voxel divisions per axis of the sample-density grid.
    pub local_voxels: usize,
    /// local only: a trajectory is planar (circle fit) when its smallest RMS principal
    /// extent is below this fraction of the middle one.
    pub local_planar_ratio: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            method: Method::Score,
            alpha: 0.2,
            min_frames: 30,
            rigid_deg: 2.0,
            hinge_ratio: 0.3,
            hinge_noise_ratio: 0.6,
            hinge_noise_factor: 1.5,
            hinge_max_noise_factor: 4.0,
            universal_ratio: 0.04,
            min_spread_mm: 2.0,
            max_spin_deg: 10.0,
            tree_poses: true,
            tree_from_second_pass: true,
            spin_corrected_cost: true,
            weighted_centres: true,
            cost_noise_power: 0.25,
            pose_outlier_factor: 4.0,
            pose_outlier_floor_mm: 20.0,
            max_iters: 200,
            anchor: true,
            anchor_min_excursion_deg: 10.0,
            anchor_steadier_ratio: 0.7,
            loose_off_tree_ratio: 0.85,
            anchor_swap_ratio: 0.6,
            anchor_max_rms_mm: 25.0,
            anchor_exact_centre_mm: 10.0,
            anchor_line_prior: true,
            anchor_centres_by_distance: true,
            anchor_refit_min_excursion_deg: 5.0,
            anchor_hinge_slides: true,
            anchor_two_centres: true,
            anchor_seed: true,
            hinge_slide_max_rise: 0.0,
            centre_prior: 1.0,
            local_voxels: 8,
            local_planar_ratio: 0.1,
        }
    }
}

/// Every parameter: (field name, "meaning, units, default").
pub const PARAM_DOCS: &[(&str, &str)] = &[
    (
        "method",
        "joint-centre estimator: \"score\" (symmetric centre of rotation, closed form, with SARA \
         hinge axes) or \"aguiar\" (the paper's Eq. 2 by L-BFGS) or \"local\" (per-marker density-weighted \
         sphere/circle fits by Levenberg-Marquardt, averaged); default \"score\"",
    ),
    (
        "local_voxels",
        "local only: divisions per axis of the voxel grid over a marker trajectory's bounding \
         box; each sample weighs 1 / (samples in its voxel), so dwelling poses do not dominate \
         (the paper uses 5 or 10); count; default 8",
    ),
    (
        "local_planar_ratio",
        "local only: a marker trajectory whose smallest RMS principal extent is below this \
         fraction of the middle one is fitted with a circle in its plane instead of a sphere; \
         ratio; default 0.1",
    ),
    (
        "alpha",
        "aguiar only: weight of the mean joint-to-marker distance (mm) against the variance \
         of that distance (mm²) in Eq. 2; default 0.2",
    ),
    (
        "min_frames",
        "pairs with fewer frames where both segments have a pose get cost +inf and no \
         positions; frames; default 30",
    ),
    (
        "rigid_deg",
        "RMS relative rotation between two segments below which the pair is kind \"rigid\"; \
         degrees; default 2.0",
    ),
    (
        "hinge_ratio",
        "kind \"hinge\" when the least-moving relative direction wobbles less than this \
         fraction of the next one; also, anchoring a two-marker segment in line with its \
         neighbour's centre along that line needs the line's swing planar to this ratio \
         (out-of-plane over in-plane spread: robot arm and quadruped hinges 0.15-0.20, a \
         hexapod body on a ball hip 0.60); ratio; default 0.3 (synthetic hard trials: \
         hinges ≤ 0.26, ball joints ≥ 0.32)",
    ),
    (
        "hinge_noise_ratio",
        "also kind \"hinge\" below this wobble ratio when the least-moving direction wobbles \
         no more than hinge_noise_factor times what the two segments' pose noise alone gives \
         (each segment's fit scatter over its markers' inertia, turning about the two \
         directions across the axis): skin wobbles a hinge's axis beyond hinge_ratio on \
         compact or few markers. cargo xtask eval --presets clean,hard --seeds 8101..8124,8201..8230 \
         --compare jointfit.hinge_noise_factor=0,1.5: hard hinge-vs-not right 3180 of 3406 -> 3264 of \
         3405 joints with a kind, mean 1.99 -> 1.96 % of height, clean identical; ratio 0.5-0.99 within \
         0.002 %. A segment of two markers posed through a joint turns about that joint's centre: \
         its noise is its markers' radial scatter about the centre over their moments about it \
         (before, it had none and the test never applied: 2-3 markers per segment, S16 hard, \
         hinge-vs-not right 641 -> 692 of 793); default 0.6",
    ),
    (
        "hinge_noise_factor",
        "see hinge_noise_ratio: how many times the pose-noise wobble the least-moving direction \
         may wobble (1, 1.5, 2: hard mean 1.97, 1.96, 1.97 % on the seeds above); 0 = off; \
         default 1.5",
    ),
    (
        "hinge_max_noise_factor",
        "a pair the wobble ratio calls a hinge is not one (a ball joint, or universal) when \
         its least-moving direction wobbles beyond this many times what the two segments' \
         pose noise tilts it by, + 1°: two rotations that move together look like one axis \
         to the ratio, a true hinge's axis wobbles only by the poses' errors (first pass, \
         seeds 20001..20030, every subject: true hinges reach 1.2 × on noise and 3.0 × on \
         hard, the universal and ball joints the ratio took for hinges 4.0-10.6 × on noise \
         and 0.8-3.8 × on hard, and 5-11° where noiseless poses predict none); 0 = off; \
         default 4",
    ),
    (
        "universal_ratio",
        "a pair that is neither a hinge nor rigid, and that a tree could use (cost at most 3 \
         times the larger of its segments' cheapest pair costs, + 1 mm), is a universal \
         joint (two axes, one fixed in each segment, whose angle never changes: a Hooke or \
         Cardan joint) when, for the pair of such axes whose angle changes least, what is left of \
         that change beyond a linear function of the joint's two angles (skin moves the \
         poses smoothly with them) and beyond frame-to-frame noise is under this fraction \
         of the RMS relative rotation (true segments, seeds 20001..20050, kind_table \
         example: below 0.03 / 0.04 / 0.05 fall, on the hard preset, 54 / 103 / 148 of the \
         snake's 299 universal joints and 0 / 0 / 2 of the 1548 ball joints of every \
         subject; on the noise preset 286 / 289 / 292 of 299 and 0 / 0 / 1 of 1548); 0 = \
         off; default 0.04",
    ),
    (
        "min_spread_mm",
        concat!(
            "a pose needs visible markers spread at least this RMS distance across their second \
             principal direction (collinear markers fix no spin); ",
            mocap_io::floor_scaled_mm!(),
            "; default 2.0"
        ),
    ),
    (
        "max_spin_deg",
        "a frame's pose needs its spin known to this standard error: the segment's fit \
         scatter over the visible markers' lever (√ of the least eigenvalue of their inertia \
         tensor), checked only where that lever is under half the whole segment's (a marker \
         hidden from a well-spread set); three markers nearly on a line under skin turn tens \
         of degrees about it; the frame is left to the anchor's centre (with the visible \
         markers) or to gap filling (cargo xtask eval --presets hard: seeds 8201-8230 2.09 → \
         2.06 % of height, trees unchanged; snowman-hard-s6001's neck 174 → 33 mm). A gap \
         fill (two visible markers and the anchor's centre) is held to the same bound, its \
         scatter the larger of the segment's and the centre's radial residual: two markers in \
         line with the centre leave its spin to noise (snowman-hard-s30038's waist and neck \
         134 / 152 → 31 / 12 mm; cargo xtask eval --presets hard, seeds \
         20001..20050,30001..30050 1.4492 → 1.4429 %, trees 548 → 547; 40001..40100 \
         1.4477 → 1.4346 %, 536 → 535; the trees lost are random ones whose runner-ups \
         cost less than the joints the rules chose; seeds 20001..20020 messy 1.394 → 1.401 \
         %, --markers 2:3 3.18 → 3.17 %, noise, skin and gaps unchanged, trees unchanged; \
         real captures' trees unchanged, Walking_Hybrid_1_1's left knee ball where it was a \
         hinge by a hair, wobble ratio 0.297 → 0.301 without 34 fills in line with its \
         shank); degrees; 0 = off; default 10",
    ),
    (
        "tree_poses",
        "a second pass along the minimum spanning tree of the first pass's costs, where some \
         segment is loose or anchored off that tree: a segment whose own poses turn beyond \
         max_spin_deg even with all its markers seen is posed through a tree neighbour's \
         joint (its own poses kept where none qualifies), and anchors and gap fills go \
         through tree neighbours first; (as measured then, the pairs kept the first pass's \
         costs and relative rotations, so the tree did not change; see \
         tree_from_second_pass); if a pair the first pass fitted would lose its centre the \
         first pass stands (cargo xtask eval --presets hard, before → \
         after: seeds 8101..8124 2.06 → 1.95 % of height, 8201..8230 2.06 → 2.03 %, 16 seeds \
         1.88 → 1.86 %, trees unchanged; --markers 2:3 3.21 → 3.08 %; skin / messy 2.17 → \
         2.11 / 2.19 → 2.13 %; clean identical); default true",
    ),
    (
        "tree_from_second_pass",
        "where the second pass (tree_poses) runs, topo reads its pairs' costs, relative \
         rotations and kinds instead of the first pass's: a segment posed again along the \
         tentative tree no longer makes all its pairs dear (human-hard-s30036's thorax: \
         thorax-right clavicle cost 27.9 on the first pass's poses, 7.6 on the second's, \
         against 15.1 for the false clavicle-clavicle pair, and the tree comes out exact). The pair through which a \
         segment is posed costs little by construction, but that pair is already in the first \
         pass's tree; only pairs the better poses make cheaper than its edges move it. cargo \
         xtask eval --presets hard --compare jointfit.tree_from_second_pass=false,true: seeds \
         20001..20050,30001..30050 543 -> 545/700 trees (human 77 -> 78, random 76 -> 77), \
         1.4533 -> 1.4490 %; 40001..40100 523 -> 530 (random 69 -> 74, human 77 -> 78, \
         quadruped 71 -> 72), 1.4477 -> 1.4486 %; --true-segments on the first set 657 -> \
         662. Seeds 20001..20020: skin 99 -> 100/140, --markers 2:3 50 -> 51 (3.30 -> 3.18 \
         %), --marker-arc 120 101 -> 102, --markers 1:3 5.25 -> 5.10 %, noise 0.208 -> 0.196 \
         %, messy 1.400 -> 1.391 %, clean and gaps unchanged, --sweep 0.2:0.4 21 -> 21; every \
         real capture's tree and kinds unchanged, runner-up warnings 16 -> 8 of 251 joints; \
         false: the first pass's, as before (topo's tree is then the one the segments' own \
         poses support); default true",
    ),
    (
        "weighted_centres",
        "method score: the joint centres from SCoRE with each frame's three equations weighted \
         by the precision of the two poses' disagreement there, (R_a Σ_a R_aᵀ + R_b Σ_b \
         R_bᵀ)⁻¹, Σ the covariance of where each segment's pose puts its centre (its fit \
         scatter σ through the Horn fit of its reference markers, σ²(I/n + [d]× J⁻¹ [d]×ᵀ), \
         d the centre's offset from their centroid, at the unweighted fit's centres): a \
         segment whose few or bunched markers sit far from the joint puts it less surely, \
         and the skin that moves its pose moves the unweighted centre with it. The pair's \
         cost (and so the tree) stays the unweighted fit's; not for a pair whose loose \
         segment's spin is corrected (spin_corrected_cost). cargo xtask eval --presets hard \
         --compare jointfit.weighted_centres=false,true on seeds 20001..20050,30001..30050: \
         1.669 → 1.574 % of height (each frame's misfit scale in both), trees unchanged; \
         default true",
    ),
    (
        "cost_noise_power",
        "method score: each pair's cost (its centres' RMS disagreement, mm) is \
         multiplied by its misfit_over_noise to this power: the disagreement measured against \
         the covariance both poses' noise gives it at the centre (σ²(I/n + [d]× J⁻¹ [d]×ᵀ) \
         per segment, as weighted_centres reads it), RMS over frames of the Mahalanobis \
         length per coordinate, about 1 for a joint that noise explains (0.94 for both joints \
         of a chain under 0.5 mm white noise, 26 for the pair across them). A segment with \
         few or bunched markers makes all its pairs dear in mm: human-hard-s20015's thorax \
         (three markers) hung the head from a clavicle, 14.6 against 15.6 mm for head-thorax. \
         The misfit alone forgives a false centre far along a small segment's lever, where \
         that segment's turn noise is large (quadruped-hard-s20007: upper leg-paw 1.30 \
         against the true upper-lower leg's 1.32), hence a small power that lets the noise \
         decide between pairs of like residual. Only where every pair with a cost has the \
         measure (a segment needs three markers fitted together for a noise figure, and exact \
         data have none): a weighed cost is not comparable with a bare one (AlbertoINT's \
         right forearm went from its upper arm to a two-marker segment when only the first \
         was weighed). cargo xtask eval --presets hard --compare \
         jointfit.cost_noise_power=0,0.25 (on the first pass's costs, before \
         tree_from_second_pass): seeds 20001..20050,30001..30050 539 -> 543/700 \
         trees (human 73 -> 77, no subject fewer), 1.4547 -> 1.4533 %; 40001..40100 520 -> \
         523 (human 74 -> 77, hexapod 24 -> 25, random 70 -> 69), 1.4484 -> 1.4477 %; with \
         --true-segments on the first set 651 -> 657; powers 0.5 / 0.75 / 1 (weighing every \
         pair): 542 / 538 / 523 on the first set. Seeds 20001..20020: messy 110 -> 112/140, \
         skin 98 -> 99, --marker-arc 120 100 -> 101, clean, noise, gaps, --markers 2:3, \
         --markers 1:3 and --sweep 0.2:0.4 trees unchanged; every real capture's tree \
         unchanged (10 of 29 weighed, their runner-up ratios up: Walking_Hybrid 3.30 -> 4.58 \
         at its first joint); 0 = off; default 0.25",
    ),
    (
        "spin_corrected_cost",
        "first pass, method score: a pair with one segment whose own markers fix its spin \
         beyond max_spin_deg (markers nearly on a line) treats that spin as noise of the \
         predicted size σ_φ: each frame's spin about the marker line is corrected by the φ \
         minimising |d(φ)|² + (σ²/σ_φ²) φ² (d the centres' disagreement, exact on the circle \
         the spin sweeps; σ² its variance along the line on the uncorrected poses, which no \
         spin moves, fixed), the centres are refitted on the corrected poses, alternately \
         until the cost settles (≤ 30 rounds), and the cost is the RMS of that objective, \
         whose mean square is 3σ² for a true joint like any pair's. On its own poses the \
         spin's noise made every pair of such a segment dear (human-hard-s20048's thorax, \
         ±16°: head-thorax 27.3 mm against 12.3 mm for head-clavicle, so the head hung from \
         the clavicle). Refused: a free spin per frame, and σ² re-estimated as the \
         corrections shrink the residual (the prior then weakens with it): both absorb real \
         turns about the line (hexapod-hard-s6006's femur: false femur-femur pairs 30-100 \
         mm -> 9 mm; seeds 40001-40100: 425 -> 425 trees with two lost, a clavicle's axial \
         rotation taken for noise); a linearised weighting of the spin's direction leaves \
         its curvature in the residual. cargo xtask eval --compare against false: hard on \
         seeds 20001-20050,30001-30050 exact trees 436 -> 442/600, none lost, 1.8573 -> \
         1.8572 %; 10001-10032 hard 147 -> 147, skin 136 -> 138/192; 40001-40100 (a \
         holdout no rule was drawn from) 425 -> 426/600, 1.8646 -> 1.8664 % \
         (human-hard-s40017 still lost to a clavicle's axial turn); 16 seeds (4001-4006, \
         6001-6006, 7001, 9001, 1001, 5001) clean, skin, hard, messy trees unchanged, hard \
         1.7798 -> 1.7810 %; --markers 2:3 hard 37 -> 38/96, 2.98 -> 2.95 %; --sweep \
         0.2:0.4 hard 10 -> 11/96; real captures' trees unchanged; default true",
    ),
    (
        "pose_outlier_factor",
        "a marker farther from its fitted place than this × the segment's median per-frame \
         fit RMS (and pose_outlier_floor_mm) is left out of that frame's pose and of the \
         reference shape, while ≥ 3 others remain (a frame left with 3 and one still beyond \
         has no pose): a swapped or glitching trajectory must not drag the pose (cargo xtask eval --presets swap: seeds 9001,9002,1001,1002,7001,7002 \
         0.58 → 0.47 % of height, seeds 3001-3004 0.55 → 0.33 %; clean identical, hard \
         unchanged); 0 = off; default 4.0",
    ),
    (
        "pose_outlier_floor_mm",
        concat!(
            "the smallest distance from its fitted place at which pose_outlier_factor leaves a \
             marker out: skin moves markers by up to a few cm, and at 10 mm the rejection already \
             reshuffled skin-only frames of the hard preset (±0.01 % of height); ",
            mocap_io::floor_scaled_mm!(),
            "; default 20.0"
        ),
    ),
    (
        "max_iters",
        "aguiar only: L-BFGS iteration limit per pair; iterations; default 200",
    ),
    (
        "anchor",
        "pose segments with 1 or 2 markers (or collinear ones) through the joint with the \
         posed neighbour whose frame sees their markers at the most constant distance from \
         one centre, and fill frames where only 2 of a segment's markers are visible from \
         those 2 plus that joint; bool; default true",
    ),
    (
        "anchor_steadier_ratio",
        "anchoring: a posed neighbour whose common centre fits a segment's markers with a \
         radial residual below this fraction of the best neighbour whose centre their turn \
         identifies (anchor_min_excursion_deg, anchor_exact_centre_mm) is a candidate too, \
         however little they turn about it: the segment keeps clearly steadier distances to \
         it; with no identified neighbour yet, below this fraction of the anchor the search \
         would take next anywhere. With two markers on every segment, 1 mm noise \
         (human-noise-s4003 --markers 2:2), the right foot's markers sit near the ankle and \
         turn 9.5 deg about it in the shank's frame (residual 1.85 mm) and 34.5 deg about \
         the knee with the whole leg (2.99 mm): the foot went to the thigh and the tree \
         skipped the shank; in human-noise-s4002 the left forearm (7.8 deg, 1.76 mm about \
         the elbow) waited while the hand hung from the upper arm at 13.3 mm. cargo xtask \
         eval --compare jointfit.anchor_steadier_ratio=0,0.7 (S16 = seeds 4001-4006, \
         6001-6006, 7001, 9001, 1001, 5001): --markers 2:2 noise trees 61 -> 65/96 (2.05 -> \
         1.97 %), hard 12 -> 18/96; --markers 2:3 hard 34 -> 36/96, skin 37 -> 39/96 (2.89 \
         -> 2.84 %); default markers hard S16 76/96 and 10001-10032 146/192 unchanged, means \
         1.786 -> 1.784 % and 1.841 -> 1.835 %, skin 1.843 -> 1.819 %; --markers 1:3 clean \
         2.20 -> 2.29 %, hard 5.00 -> 4.93 %. At 1.0 (any steadier fit) 2:2 noise 65/96 at \
         2.02 % against 1.97 (worst trial 68.9 % against 29.7), 2:3 hard 38/96 at 3.05 % \
         against 36 at 2.98. Real: Gait.trc's left upper arm (two \
         markers, with a one-marker wrist) 215 -> 325 mm, its ankles ball joints, the right \
         one 21 -> 9 mm from the malleoli's midpoint; CMU 02_01's limbs unchanged. Also: \
         a two-marker segment in line with its best neighbour's centre (no spin to fit) is \
         posed along that line through it only below this fraction of every other posed \
         neighbour's residual (and where hinge_ratio finds the line's swing planar; see \
         anchor.rs); 0 = off; default 0.7",
    ),
    (
        "anchor_min_excursion_deg",
        "anchoring: a neighbour qualifies only if the markers turn at least this RMS angle \
         about the common centre (less: the joint is not identifiable); degrees; default 10",
    ),
    (
        "anchor_exact_centre_mm",
        concat!(
            "anchoring: a neighbour whose markers turn less than anchor_min_excursion_deg (or \
             anchor_refit_min_excursion_deg) about the common centre still qualifies when the \
             radial residual divided by that excursion in radians, the distance the centre could \
             stray for it, is at most this: such a centre is pinned better than that of a \
             neighbour turning 10 deg with a residual of 1.75 mm. A segment that barely moves \
             against its true neighbour must not go to one that moves more and fits worse: the \
             OpenSim walk's right upper arm (2 markers) turns 7.1 deg about the trunk with a \
             residual of 1.05 mm (8.5 mm of stray) and went to the left thigh (14.4 deg, 5.14 mm, \
             20 mm), which swings in phase with it; with 10 its tree is the body's (pelvis to \
             thighs and trunk, trunk to arms and head, upper arms to wrists; left thigh, hip to \
             knee, 369 -> 462 mm against the right's 449), the nine other shared captures \
             unchanged. Synthetic trials (joints sweep 70-95 % of their range) rarely have such \
             a neighbour: cargo xtask eval, 3 -> 10, S16 = seeds 4001-4006, \
             6001-6006, 7001, 9001, 1001, 5001: hard 76 -> 76/96 trees, 1.784 -> \
             1.786 %; skin 65 -> 65, 1.821 -> 1.818 %; noise 0.344 -> 0.345 %; seeds \
             10001-10032 hard 143 -> 143/192, 1.848 -> 1.848 %, noise 0.374 -> 0.380 % \
             (hexapods 0.599 -> 0.633); --markers 2:3 on S16 clean 93 -> 93, 0.184 -> 0.185 %, \
             skin 33 -> 34, 2.936 -> 2.965 %, hard 33 -> 33, 3.083 -> 3.078 %; --sweep 0.2:0.4 \
             unchanged. 3 (noise-free hexapod coxae turning 9 deg about the body, which must \
             not go to a leg) was its first value; 0 = off; ",
            mocap_io::floor_scaled_mm!(),
            "; default 10"
        ),
    ),
    (
        "loose_off_tree_ratio",
        "along the tree (second pass), a segment whose own markers fix its spin too loosely \
         (max_spin_deg) is posed through a neighbour's joint; its edges in the first pass's \
         tree came from its own poses, whose spin was unknown, so a neighbour off that tree \
         is taken instead where its common centre fits the segment's markers with a radial \
         residual below this fraction of the best tree neighbour's. random-hard-s20022's \
         seg08 (markers nearly in line) hung from seg05, no neighbour of it (3.68 mm), while \
         its parent's centre fitted at 2.18 mm. cargo xtask eval --presets hard --compare \
         jointfit.loose_off_tree_ratio=0,0.85: seeds 20001..20050,30001..30050 550 -> 550 \
         exact trees, 1.4002 -> 1.3935 % of height (hexapod-hard-s20023 8.30 -> 3.86 %: its \
         three unmatched hips found); 40001..40100 535 -> 535, 1.4022 -> 1.3994 %; at 0.7 / \
         0.8 / 0.9 / 1 (any better fit): 550 / 550 / 551 / 551 and 535 / 535 / 535 / 532 \
         trees (at 1, three human clavicles hang from the other clavicle, 5.22 against the \
         thorax's 5.69 mm); 0 = tree neighbours only; default 0.85",
    ),
    (
        "anchor_swap_ratio",
        "along the tree (second pass), a segment posed through a tree neighbour's joint \
         although another posed neighbour's centre holds its markers with a radial residual \
         below this fraction of that joint's (PairFit::next_best_anchor) is posed again, \
         along the tree with that neighbour's edge in place of the first (a third pass): the \
         first pass's tree came from greedy anchors, whose pairs are cheap by construction. \
         With the true segments at --markers 2:3 (seeds 20001..20050,30001..30050, hard) no \
         right tree edge had a ratio below 0.6 and 13 wrong ones did; cargo xtask eval \
         --presets hard --markers 2:3 [--true-segments] on those seeds: 294 -> 296 exact \
         trees (+2 -0) and 452 -> 456 (+4 -0) at 0.6, 458 (+10 -4) at 0.8; the default \
         markers identical trial for trial; 0 = off; default 0.6",
    ),
    (
        "anchor_max_rms_mm",
        concat!(
            "anchoring: a neighbour qualifies only if the markers' distances to the common \
             centre vary by at most this RMS; ",
            mocap_io::floor_scaled_mm!(),
            "; default 25"
        ),
    ),
    (
        "anchor_seed",
        "where anchoring finds no posed neighbour left for a segment of two markers (every \
         segment of the marker set has two, say), fit the common centre of the two markers of \
         each of two such segments (four constant distances meeting at one point in every \
         frame), pose one of them from its markers plus that centre and anchor on from it. \
         cargo xtask eval --markers 2:2 --seeds 10001..10032: clean 0 -> 180 exact trees of \
         192 (0.40 % of height; joints known in 2.6 -> 100 % of frames), noise 0 -> 99 \
         (181 and 114 since the segment stage's typical sigma counts pairs where most \
         markers sit in them); bool; default true",
    ),
    (
        "anchor_line_prior",
        "anchoring of a 2-marker segment through a ball joint: besides the markers' constant \
         distances to the centre (which fix the centre along the limb only through the arc's \
         curvature), use the point nearest all the marker lines (first order, blind to markers \
         sliding along the limb) as a prior on the centre's coordinate across any hinge-like \
         axis, weighted by the lines' own scatter, a bias bound (distance from the lines x \
         sqrt of the swing's minor/major variance) and the residuals' effective sample count. \
         CMU 02_01: femurs 385/383 -> 407/416 mm (Vicon 429/428), tibias 431/425 -> 434/418 \
         (Vicon 411/407); synthetic 2-3-marker hard trials within +-3.5 mm (synth_eval 404); \
         cargo xtask eval hard 1.67 -> 1.69 %; bool; default true",
    ),
    (
        "anchor_centres_by_distance",
        "joints of a segment posed through an anchor joint (1 or 2 markers, or collinear \
         ones) are centred by its markers' distances (the anchor's common centre; for its \
         other joints the common centre in the other segment's frame, see \
         anchor_refit_min_excursion_deg) rather than refitted on the poses built through the \
         anchor, whose twist about the marker line is only as good as that centre; kept only \
         where it lies no farther (1 mm) from the pair's markers than the refit's (mean \
         nearest-marker distance), since where the two disagree a nearly free direction was \
         settled by bias; hinge placement then leaves it; default true",
    ),
    (
        "anchor_two_centres",
        "a two-marker segment posed through one joint is posed again from its two markers \
         and both its joints' centres when a second neighbour's frame sees its markers keep \
         their distances to a common centre (anchor_refit_min_excursion_deg's bar; along the \
         tree in the second pass, tree_poses, which then always runs where such a segment \
         has two tree neighbours) and the anchor's centre fits no more than 3 times as \
         loosely as that one, plus min_spread_mm; a two-marker segment no single joint can \
         pose is posed from the two centres that fit best. One centre near the line of the \
         two markers leaves the segment free to spin about it (BTK Gait.trc: a knee marker \
         14 mm from the knee centre; the shank turned 178° against the thigh and the ankles \
         sat 190 and 149 mm off the malleoli's midpoint, now 8 and 23 mm; CMU 02_01 right \
         femur 2.5 % → 0.2 % short of Vicon's). cargo xtask eval --compare \
         jointfit.anchor_two_centres=false,true on seeds 4001-4006,6001-6006,7001,9001,1001, \
         5001: the same trees everywhere but --markers 2:3 skin 35 → 36/96, means hard \
         1.788 → 1.786 %, skin 1.853 → 1.844 %, --markers 2:3 hard 3.018 → 2.967 %, skin \
         2.944 → 2.898 %, clean 0.185 → 0.187 %, --sweep 0.2:0.4 hard 4.027 → 4.031 %; on \
         10001-10032 noise 0.372 → 0.364 %, hard 1.851 → 1.847 %; default true",
    ),
    (
        "anchor_refit_min_excursion_deg",
        "anchor_centres_by_distance, for a posed-through segment's joints other than its \
         anchor: the distances place the centre only if the segment's markers turn at least \
         this RMS angle about it (lower than anchor_min_excursion_deg: the tree already says \
         the pair is a joint; CMU 02_01's left shoulder turns 8.5 deg); degrees; default 5",
    ),
    (
        "anchor_hinge_slides",
        "a joint of hinge kind that anchor_centres_by_distance centred by marker distances \
         keeps that centre across its axis but still slides along the axis in hinge \
         placement (bonefit): every point of a hinge's axis keeps its distance to every \
         marker turning about it, so where the distances pin one point they are fitting a \
         marker that sits on the axis, or skin (BTK Gait.trc: R.Knee.Medial, an epicondyle \
         marker, stays put in the thigh's frame and the knee centres sat next to it, 62 and \
         50 mm along the axis from the epicondyles' midpoint; now 4 and 19 mm along it, 22 \
         and 26 mm from it in all; the right ankle, placed from the knee, 8 -> 21 mm from \
         the malleoli's midpoint; CMU 02_01's left humerus +0.1 -> +1.7 % of Vicon's). \
         cargo xtask eval --compare jointfit.anchor_hinge_slides=false,true on seeds \
         4001-4006,6001-6006,7001,9001,1001,5001: no tree changes anywhere; noise 0.344 -> \
         0.343 %, skin 1.844 -> 1.843 %, --markers 2:3 hard 2.967 -> 2.957 %, --sweep \
         0.2:0.4 hard 4.07 -> 4.03 %, --markers 2:2 hard 4.70 -> 4.71 %, noise 2.05 -> \
         2.05 %; on 10001-10032 hard 1.847 -> 1.842 %, skin 1.898 -> 1.895 %; default true",
    ),
    (
        "centre_prior",
        "method score: the joint centre is pulled toward the midpoint of the two segments' \
         origins by a prior whose weight (added to every eigenvalue of SCoRE's normal \
         matrix, per frame) is this × (the pair's residual RMS / the mean distance between \
         the origins)². Joints lie between the segments they join; the prior matters only \
         along directions the motion barely fixes (a knee's axis when it also wobbles, a ball \
         turning little), where skin otherwise settles the centre: human-hard-s20004's left \
         knee, read as a ball (wobble ratio 0.319, condition 190), sat 172 mm along its axis, \
         its fit 238 mm from the midpoint. On exact data the residual and so the prior \
         vanish. cargo xtask eval --presets hard --compare jointfit.centre_prior=0,1,3,10: \
         seeds 20001..20050,30001..30050 1.4429 / 1.4069 / 1.4079 / 1.4332 % (every subject \
         better at 1: hexapod 4.042 → 3.845, human 0.801 → 0.794, random 1.651 → 1.637), \
         trees 547 / 547 / 548 / 547; 40001..40100 (0, 1, 3) 1.4346 / 1.4071 / 1.4069 %, \
         535 / 535 / 534; clean identical (0.0581 %, 700 trees, kinds 7625/7625); seeds \
         20001..20020 (0 → 1) skin 1.337 → 1.301 %, messy 1.401 → 1.366, noise 0.196 → \
         0.200, gaps unchanged, --markers 2:3 3.17 → 3.15, --markers 1:3 5.21 → 5.13, \
         --marker-arc 120 2.05 → 2.04, --sweep 0.2:0.4 3.89 → 3.66, trees unchanged (but \
         --marker-arc 120 100 → 101); every real \
         capture's tree and kinds unchanged (bone lengths move up to 41 mm: AlbertoINT, \
         OpenSim's walk); 0 = none; default 1.0",
    ),
    (
        "hinge_slide_max_rise",
        "when > 0, a hinge's centre (whose axis component the data leave open) is placed \
         nearest the segments' midpoint only if that raises the pair residual by at most this \
         factor over the least-squares centre (+0.1 mm), else the least-squares centre is kept \
         (a ball joint moving mostly about one axis, like a shoulder in walking, otherwise slides \
         along a spurious axis: CMU 02_01 left humerus 199 -> 289 mm, Vicon 275, with 1.05; but \
         synthetic hard 2-3-marker humans get worse, 26 -> 36 mm); ratio; default 0 (always place)",
    ),
];

impl Params {
    /// These parameters with their millimetre floors and bounds (`min_spread_mm`,
    /// `pose_outlier_floor_mm`, `anchor_max_rms_mm`, `anchor_exact_centre_mm`) times
    /// `scale` (≤ 1, [`mocap_io::Trajectories::floor_scale`]): they were set for markers a
    /// few centimetres apart, and a small subject's segments are smaller than them.
    pub fn with_floors_scaled(&self, scale: f64) -> Self {
        Self {
            min_spread_mm: self.min_spread_mm * scale,
            pose_outlier_floor_mm: self.pose_outlier_floor_mm * scale,
            anchor_max_rms_mm: self.anchor_max_rms_mm * scale,
            anchor_exact_centre_mm: self.anchor_exact_centre_mm * scale,
            ..self.clone()
        }
    }

    /// Checks ranges; called by `run`.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |name, value: f64, reason| Error::InvalidParam {
            name,
            value: value.to_string(),
            reason,
        };
        for (name, value) in [
            ("alpha", self.alpha),
            ("rigid_deg", self.rigid_deg),
            ("hinge_noise_factor", self.hinge_noise_factor),
            ("hinge_max_noise_factor", self.hinge_max_noise_factor),
            ("universal_ratio", self.universal_ratio),
            ("min_spread_mm", self.min_spread_mm),
            ("max_spin_deg", self.max_spin_deg),
            ("pose_outlier_factor", self.pose_outlier_factor),
            ("pose_outlier_floor_mm", self.pose_outlier_floor_mm),
            ("anchor_min_excursion_deg", self.anchor_min_excursion_deg),
            (
                "anchor_refit_min_excursion_deg",
                self.anchor_refit_min_excursion_deg,
            ),
            ("anchor_exact_centre_mm", self.anchor_exact_centre_mm),
            ("anchor_steadier_ratio", self.anchor_steadier_ratio),
            ("loose_off_tree_ratio", self.loose_off_tree_ratio),
            ("anchor_swap_ratio", self.anchor_swap_ratio),
            ("hinge_slide_max_rise", self.hinge_slide_max_rise),
            ("centre_prior", self.centre_prior),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(bad(name, value, "must be a finite number ≥ 0"));
            }
        }
        for (name, value, range) in [
            ("hinge_ratio", self.hinge_ratio, 0.0..1.0),
            ("local_planar_ratio", self.local_planar_ratio, 0.0..1.0),
        ] {
            if !(value.is_finite() && range.contains(&value)) {
                return Err(bad(name, value, "must be in [0, 1)"));
            }
        }
        if !(self.hinge_noise_ratio.is_finite() && (0.0..=1.0).contains(&self.hinge_noise_ratio)) {
            return Err(bad(
                "hinge_noise_ratio",
                self.hinge_noise_ratio,
                "must be in [0, 1]",
            ));
        }
        if !(self.anchor_max_rms_mm.is_finite() && self.anchor_max_rms_mm > 0.0) {
            return Err(bad(
                "anchor_max_rms_mm",
                self.anchor_max_rms_mm,
                "must be a finite number > 0",
            ));
        }
        if !(1..=64).contains(&self.local_voxels) {
            return Err(bad(
                "local_voxels",
                self.local_voxels as f64,
                "must be between 1 and 64",
            ));
        }
        if self.min_frames == 0 {
            return Err(bad("min_frames", 0.0, "must be at least 1"));
        }
        if self.max_iters == 0 {
            return Err(bad("max_iters", 0.0, "must be at least 1"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_every_field_is_documented() {
        Params::default().validate().unwrap();
        let names: Vec<&str> = PARAM_DOCS.iter().map(|(n, _)| *n).collect();
        let debug = format!("{:?}", Params::default());
        for name in &names {
            assert!(
                debug.contains(&format!("{name}: ")),
                "{name} is not a field"
            );
        }
        // Every field appears in the Debug output as `name: `; count them against the docs.
        assert_eq!(debug.matches(": ").count(), names.len());
    }

    #[test]
    fn rejects_bad_values() {
        let p = Params {
            alpha: -1.0,
            ..Params::default()
        };
        assert!(matches!(
            p.validate(),
            Err(Error::InvalidParam { name: "alpha", .. })
        ));
    }
}
