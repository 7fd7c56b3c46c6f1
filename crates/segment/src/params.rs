//! Parameters of the segment stage, their defaults and documentation.

use serde::{Deserialize, Serialize};

use crate::Error;

/// How markers are grouped into rigid segments.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Normalised spectral clustering of the affinity matrix (Aguiar et al. 2006, Sect. 3).
    #[default]
    Spectral,
    /// Greedy maximal rigid cliques under the distance tolerance (local-fitting paper, Sect. 3.1).
    Cliques,
    /// Agglomerative clustering on ρ cut at the tolerance, then orphans rejoin.
    Linkage,
}

/// How the ρ between two groups of markers is summarised in agglomerative clustering.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Linkage {
    /// The largest cross-pair ρ: every pair must keep its distance (rigidity).
    #[default]
    Complete,
    /// The mean cross-pair ρ: tolerant of one sliding marker, blurs joints near a marker.
    Average,
}

/// How the standard deviation ρ of a pair's distance becomes an affinity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Affinity {
    /// Eq. 1 as printed: exp(-ρ / 2σ²), σ = (1/N²)·Σ_f dist (per pair; underflows on long captures).
    Paper,
    /// Self-tuning local scaling: exp(-ρ² / (s_i·s_j)), s_i = ρ to the k-th nearest marker, floored.
    #[default]
    Local,
    /// One absolute scale: exp(-ρ² / (2·scale_mm²)).
    Absolute,
}

/// Parameters of the segment stage (`segment.*`); see [`PARAM_DOCS`] for meanings and defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Grouping method.
    pub method: Method,
    /// Affinity of the spectral method.
    pub affinity: Affinity,
    /// Linkage of the agglomerative method.
    pub linkage: Linkage,
    /// Agglomerative split: a group smaller than min_segment_markers rejoins its most rigid group within max(tolerance, this × its own scale).
    pub rejoin_factor: f64,
    /// Agglomerative method: divide each ρ by √(s_i s_j), s = ρ to the linkage_k-th nearest marker floored at the noise.
    pub linkage_scaled: bool,
    /// Neighbour rank of the scale of `linkage_scaled`.
    pub linkage_k: usize,
    /// Cut of the scaled linkage (dimensionless).
    pub linkage_cut: f64,
    /// Local scaling: the neighbour rank k whose ρ sets a marker's scale.
    pub local_k: usize,
    /// Local scaling: floor on every marker's scale, mm.
    pub min_scale_mm: f64,
    /// Absolute affinity: the scale, mm.
    pub scale_mm: f64,
    /// Number of segments to find; 0 = from the largest eigen-gap.
    pub segments: usize,
    /// Largest segment count the eigen-gap may choose.
    pub max_segments: usize,
    /// k-means restarts (best inertia wins).
    pub restarts: usize,
    /// Seed of the k-means++ initialisation.
    pub seed: u64,
    /// A marker seen in fewer frames than this is unassigned.
    pub min_visible_frames: usize,
    /// A marker seen in less than this fraction of the frames is unassigned.
    pub min_visible_fraction: f64,
    /// A track seen in less than this fraction of the median track's frames leaves its
    /// spectral cluster before the rigidity check, which places it as a lone marker, where
    /// the median track is seen in half the frames or more; 0 = none does.
    pub brief_track_fraction: f64,
    /// A marker whose positions' RMS spread over the capture is within this many times the
    /// RMS of its steps between frames never moves: grouped apart, before anything else,
    /// from every marker that moves; 0 = none is.
    pub stationary_jitter_factor: f64,
    /// Markers whose single-linkage tree on ρ links them to the rest only by links at least
    /// this many times as wide as every link within (and wider than the markers' spacing)
    /// move independently: each such body is segmented on its own; 0 = one body (default
    /// 2.5).
    pub body_gap_ratio: f64,
    /// A pair seen together in fewer frames than this has no affinity and no ρ.
    pub min_overlap_frames: usize,
    /// Groups with fewer markers than this are not segments (but see `singleton_steady_factor`).
    pub min_segment_markers: usize,
    /// After spectral clustering: split non-rigid clusters, move misplaced markers, merge rigid neighbours.
    pub rigidity_check: bool,
    /// Rigidity check: split clusters by the linkage method's agglomeration instead of the average-linkage split.
    pub split_linkage: bool,
    /// Rigidity tolerance on ρ, mm; 0 = automatic from the noise level and the rigid spread.
    pub tolerance_mm: f64,
    /// Automatic tolerances = max(tolerance_min_mm, tolerance_factor × noise or spread).
    pub tolerance_factor: f64,
    /// The factor instead of `tolerance_factor` where the scatter about rigidity is white
    /// measurement noise (`white_noise_smoothness`); 0 = always `tolerance_factor`.
    pub tolerance_factor_white: f64,
    /// Scatter whose frame-to-frame smoothness (lag-one autocorrelation) is below this is
    /// white noise, not skin.
    pub white_noise_smoothness: f64,
    /// Where the scatter is white noise, the spectral affinity reads each pair's ρ with the
    /// noise level taken out in quadrature.
    pub white_noise_excess: bool,
    /// Smallest automatic tolerance, mm.
    pub tolerance_min_mm: f64,
    /// The rigid spread read off the spectral clusters counts for at most this × the noise level; 0 = no bound.
    pub spread_max_noise_factor: f64,
    /// When the spectral clusters could not measure the rigid spread, measure it on the segments the noise's tolerance gives and segment again with it.
    pub spread_second_pass: bool,
    /// A marker slides when its RMS ρ to its mates exceeds this ratio × its mates' RMS ρ among themselves.
    pub slide_ratio: f64,
    /// ... and exceeds this, mm.
    pub slide_min_mm: f64,
    /// A lone marker takes a marker it is rigid with (ρ ≤ tolerance) from a group that keeps ≥ 3.
    pub pair_orphans: bool,
    /// A lone marker is a 1-marker segment when its steadiest ρ ≤ this × the tolerance; else unassigned.
    pub singleton_steady_factor: f64,
    /// ... or when it swings about a point of a body of ≥ 3: a sphere or circle in that body's frame, residual ≤ this × the tolerance; 0 = off.
    pub singleton_swing_factor: f64,
    /// ... or when its steadiest partner is in a group of one or two markers (nothing to test a swing against).
    pub singleton_next_to_small: bool,
    /// A marker whose steadiest ρ in its group exceeds this × the tolerance leaves it as a lone marker (and a lone marker rigid with a whole group joins it); 0 = off.
    pub loose_marker_factor: f64,
    /// A cluster of 4–10 markers splits in two when its rigid-fit σ exceeds this × the best bipartition's pooled σ; 0 = off.
    pub fit_split_ratio: f64,
    /// ... and exceeds this × the typical segment's fit σ (the median over the clusters of ≥ 2 markers).
    pub fit_split_floor: f64,
    /// A marker moves to another cluster of ≥ 3 when that body holds it this many times stiller than its own does; 0 = off.
    pub reassign_ratio: f64,
    /// Joint test: a cluster splits where its parts' relative rotation has a robust Mahalanobis length above this; 0 = off.
    pub joint_split_z: f64,
    /// ... or where one part's centroid travels in the other's frame with a robust Mahalanobis length above this; 0 = rotation only.
    pub joint_travel_z: f64,
    /// ... and a centre of rotation fixed in both parts leaves at most this fraction of their relative translation.
    pub joint_centre_fraction: f64,
    /// A rotation above joint_split_z (and at most joint_rotation_alone_z) counts only when the worse posed part's centroid travels in the other's frame with a Mahalanobis length above this; 0 = any.
    #[serde(default = "default_joint_rotation_travel_z")]
    pub joint_rotation_travel_z: f64,
    /// ... unless the rotation's Mahalanobis length is above this; 0 = never.
    #[serde(default = "default_joint_rotation_alone_z")]
    pub joint_rotation_alone_z: f64,
    /// Joint test's pair route, run where at least this share of the clusters of ≥ 2 markers hold two (a sparse marker set): a cluster of 5 to 16 markers the test leaves whole splits off the two markers that fit best as a pair beside the rest when, in the rest's frame, the pair's midpoint travels (joint_travel_z) or its direction turns (joint_split_z) about one centre; 0 = always, above 1 = never.
    #[serde(default = "default_joint_pair_share")]
    pub joint_pair_share: f64,
    /// ... and one centre fixed in the rest keeps both markers at constant distances within this fraction of the midpoint's travel.
    #[serde(default = "default_joint_pair_centre_fraction")]
    pub joint_pair_centre_fraction: f64,
    /// ... read only in the frames whose seen markers pose the rest with a rotation noise about its worst axis of at most this many degrees.
    #[serde(default = "default_joint_pair_max_spin_deg")]
    pub joint_pair_max_spin_deg: f64,
    /// After every other step, a cluster that neither the joint test nor the rigid merge has judged is put to the joint test.
    pub joint_retest: bool,
    /// Three clusters that are two segments regroup (see `regroup`): a cluster of ≤ 4
    /// markers shared out between two of its three nearest, where the two bodies pass the
    /// joint test and fit within this × the three's pooled σ; 0 = off.
    #[serde(default = "default_regroup_ratio")]
    pub regroup_ratio: f64,
    /// A marker its own cluster (≥ 5) holds this many times worse than the median of its cluster-mates becomes a group of its own; 0 = off.
    pub eject_ratio: f64,
    /// Neighbouring clusters whose relative rotation scores below this on the joint test move as one body and merge; 0 = off.
    pub joint_merge_z: f64,
    /// A two-marker cluster dissolves when two different other bodies hold its markers (a one-marker cluster when one does) within this × the typical fit σ; 0 = off.
    pub pair_hold: f64,
    /// A two-marker cluster one body holds within pair_hold rejoins it when spectral clustering had them together and its scatter there is within this × the body's fit σ; 0 = off.
    pub pair_rejoin_ratio: f64,
    /// A pair only one of whose markers a body holds re-pairs: the free marker takes a steadier partner, the held one joins its holder.
    pub pair_repartner: bool,
    /// Clusters of one or two markers that spectral clustering had together join where their union fits within the fit split's floor.
    pub join_small: bool,
    /// Find label swaps (two markers' trajectories exchanged for a while), undo them and segment again.
    pub repair_swaps: bool,
    /// Join pieces of one marker's trajectory a body carries across their gap, and segment again.
    pub join_pieces: bool,
    /// Last, a track rigid with its own cluster and as rigid with another, seen only while the two moved against each other less than a third as much as over the capture, is left out: the data cannot tell which it is on.
    pub leave_out_undecided: bool,
    /// A sample is a glitch (a gap to segmentation) when most of its marker's steadiest partners are off by more than this × their robust scatter; 0 = off.
    pub glitch_factor: f64,
    /// A segment the joint test left whole is reported as maybe two (`Segmentation::near_joints`) when its best cut scores this fraction of joint_split_z or joint_travel_z; 0 = off.
    #[serde(default = "default_near_joint_fraction")]
    pub near_joint_fraction: f64,
    /// Markers that are one segment, by label (`*` patterns as in `mocap-io.exclude_markers`): each group is a segment of exactly those markers, taken out of the segments found without it; default none.
    pub groups: Vec<Vec<String>>,
}

/// `Params::joint_rotation_travel_z`'s default, for artifacts written before it existed.
fn default_joint_rotation_travel_z() -> f64 {
    2.5
}

/// `Params::joint_rotation_alone_z`'s default, for artifacts written before it existed.
fn default_joint_rotation_alone_z() -> f64 {
    8.0
}

/// `Params::joint_pair_share`'s default, for artifacts written before it existed.
fn default_joint_pair_share() -> f64 {
    0.15
}

/// `Params::joint_pair_centre_fraction`'s default, for artifacts written before it existed.
fn default_joint_pair_centre_fraction() -> f64 {
    0.3
}

/// `Params::joint_pair_max_spin_deg`'s default, for artifacts written before it existed.
fn default_joint_pair_max_spin_deg() -> f64 {
    20.0
}

fn default_regroup_ratio() -> f64 {
    1.15
}

/// `Params::near_joint_fraction`'s default, for artifacts written before it existed.
fn default_near_joint_fraction() -> f64 {
    0.75
}

impl Default for Params {
    fn default() -> Self {
        Self {
            method: Method::Spectral,
            affinity: Affinity::Local,
            linkage: Linkage::Complete,
            rejoin_factor: 3.0,
            linkage_scaled: true,
            linkage_k: 1,
            linkage_cut: 6.0,
            local_k: 2,
            min_scale_mm: 1.0,
            scale_mm: 5.0,
            segments: 0,
            max_segments: 40,
            restarts: 10,
            seed: 0,
            min_visible_frames: 10,
            min_visible_fraction: 0.05,
            brief_track_fraction: 0.25,
            stationary_jitter_factor: 3.0,
            body_gap_ratio: 2.5,
            min_overlap_frames: 10,
            min_segment_markers: 2,
            rigidity_check: true,
            split_linkage: true,
            tolerance_mm: 0.0,
            tolerance_factor: 5.0,
            tolerance_factor_white: 3.0,
            white_noise_smoothness: 0.1,
            white_noise_excess: true,
            tolerance_min_mm: 2.0,
            spread_max_noise_factor: 4.0,
            spread_second_pass: true,
            slide_ratio: 2.0,
            slide_min_mm: 1.0,
            pair_orphans: true,
            singleton_steady_factor: 1.0,
            singleton_swing_factor: 0.5,
            singleton_next_to_small: true,
            loose_marker_factor: 2.0,
            fit_split_ratio: 2.0,
            fit_split_floor: 2.0,
            reassign_ratio: 2.0,
            joint_split_z: 4.0,
            joint_travel_z: 5.0,
            joint_centre_fraction: 1.0,
            joint_rotation_travel_z: default_joint_rotation_travel_z(),
            joint_rotation_alone_z: default_joint_rotation_alone_z(),
            joint_pair_share: default_joint_pair_share(),
            joint_pair_centre_fraction: default_joint_pair_centre_fraction(),
            joint_pair_max_spin_deg: default_joint_pair_max_spin_deg(),
            joint_retest: true,
            regroup_ratio: default_regroup_ratio(),
            eject_ratio: 8.0,
            joint_merge_z: 4.0,
            pair_hold: 3.0,
            pair_rejoin_ratio: 8.0,
            pair_repartner: true,
            join_small: true,
            repair_swaps: true,
            join_pieces: true,
            leave_out_undecided: true,
            glitch_factor: 8.0,
            near_joint_fraction: default_near_joint_fraction(),
            groups: Vec::new(),
        }
    }
}

/// Every parameter: (field name, "meaning, units, default").
pub const PARAM_DOCS: &[(&str, &str)] = &[
    (
        "method",
        "grouping method: \"spectral\" (Ng–Jordan–Weiss on the affinity, then the rigidity check), \"linkage\" (agglomerative clustering on ρ alone, see linkage*) or \"cliques\" (greedy maximal rigid cliques under the tolerance); default \"spectral\"",
    ),
    (
        "affinity",
        "spectral affinity from the distance std ρ: \"local\" (exp(-ρ²/(s_i s_j)), s_i = ρ to the local_k-th nearest marker), \"paper\" (Eq. 1 as printed), \"absolute\" (exp(-ρ²/2scale_mm²)); default \"local\"",
    ),
    (
        "linkage",
        "linkage method: group-to-group ρ is \"complete\" (largest cross-pair ρ: the union is rigid only if every pair is) or \"average\" (mean cross-pair ρ); default \"complete\"",
    ),
    (
        "rejoin_factor",
        "linkage method and split_linkage: a group smaller than min_segment_markers joins the group it is most rigid with when its RMS ρ to it is within the tolerance or within rejoin_factor × its own scale (ρ to its nearest marker, floored at the noise); else its markers are unassigned; default 3.0",
    ),
    (
        "linkage_scaled",
        "linkage method: divide each pair's ρ by √(s_i·s_j), s = the marker's ρ to its linkage_k-th nearest marker, never below the noise level, and cut at linkage_cut instead of the tolerance; default true",
    ),
    (
        "linkage_k",
        "linkage method: neighbour rank of the scale; default 1",
    ),
    (
        "linkage_cut",
        "linkage method and split_linkage, with linkage_scaled: largest scaled linkage (ρ / √(s_i s_j)) that still merges (dimensionless); default 6.0",
    ),
    (
        "local_k",
        "local affinity: rank of the neighbour whose ρ is a marker's scale (clamped to the markers available); 2 keeps the scale inside a 3-marker segment (each marker has 2 mates); default 2",
    ),
    (
        "min_scale_mm",
        concat!(
            "local affinity: floor on each marker's scale so noiseless rigid data does not collapse, ",
            mocap_io::floor_scaled_mm!(),
            "; default 1.0"
        ),
    ),
    ("scale_mm", "absolute affinity: the scale, mm; default 5.0"),
    (
        "segments",
        "force this many spectral clusters; 0 = the largest eigen-gap decides; default 0",
    ),
    (
        "max_segments",
        "largest cluster count the eigen-gap may choose; default 40",
    ),
    (
        "restarts",
        "k-means restarts from seeded k-means++ (lowest inertia wins); default 10",
    ),
    ("seed", "seed of the k-means++ initialisation; default 0"),
    (
        "min_visible_frames",
        "markers visible in fewer frames are unassigned, frames; default 10",
    ),
    (
        "min_visible_fraction",
        "markers visible in less than this fraction of all frames are unassigned; default 0.05",
    ),
    (
        "brief_track_fraction",
        "a track seen in less than this fraction of the frames the median track is seen in leaves its spectral cluster before the rigidity check, which places it as a lone marker: its ρ is measured over a stretch where the joints between segments may have held still, so its cluster can hold markers of several segments that it alone ties together, and cut at ρ such a cluster keeps them wrongly paired (an unlabeled capture's short pieces: snake-hard-s20011 at 2–3 markers per segment, an 83-frame piece of a link3 marker, seen while the chain barely moved, took a base marker into a cluster with it). Only where the median track is seen in half the frames or more: where most tracks are pieces, the briefest are no outliers (c3d.org's Dance hidden 1.1–2.6 s every 3 s, tests/it/unlabeled.rs: 3 → 4 wrong of 25 → 23 groups joined without that condition). Spectral clustering itself still sees every track: without a brief track the eigen-gap count moves (tried: on the real captures cut at their gaps, pairs of markers one segment in the labelled run and not in the cut one or the other way round went 141 → 183 over twelve, CMU 02_01's trunk and pelvis one segment). cargo xtask eval --presets hard --seeds 20001..20050,30001..30050 --unlabeled: 0 → 0.25 at --markers 2:3 283 → 292 exact trees of 700, 3.028 → 3.005 % of height; at 3–6 markers 563 → 564, 1.393 → 1.392 %; labelled trials the same, trial by trial; measured with fractions of the capture's frames rather than of the median track's (there the median segmented track is seen in 94–100 % of the frames), 0.15 / 0.35 / 0.5 gave 286 / 290 / 285 at 2:3; 0 = none; default 0.25",
    ),
    (
        "stationary_jitter_factor",
        "a marker whose positions stay within this many times its frame-to-frame jitter of one place (RMS spread about its mean over the RMS of its steps between consecutive frames: white measurement noise alone gives about 0.7, a marker a body carries tens or more) never moves: floor and reference markers, a calibration frame, stray reflections. Such markers are set aside before anything else, where some marker moves, and come back as one segment of their own (the room, or a fixed base that a joint may join; skeleton.json's segment says \"stationary\": true) or, one alone, unassigned with the reason: among the moving markers they shifted the noise level, the marker spacing and the eigen-gap count (one static point beside CMU 02_01 regrouped three of its markers; on OpenSim's subject01_walk1 one joined the pelvis). 0 = none is; default 3",
    ),
    (
        "body_gap_ratio",
        "bodies that move independently of each other (a subject and the props it does not hold, two subjects apart) are segmented each on its own, so that none shifts another's noise level, tolerance, typical fit σ, millimetre floors or k-means, and topo joins them only by a joint as tight as a typical one (topo.stationary_residual_ratio, as the room): where the single-linkage tree on ρ (each marker linked to its steadiest partner, and on) has links at least this many times as wide as every link it keeps and at least the markers' typical spacing, those links part bodies of ≥ 3 markers (smaller parts stay with the biggest body; none where segments forces the cluster count, which is the whole capture's). Where the median track is seen in half the frames or more, tracks and overlaps briefer than brief_track_fraction of it tie nothing (over a brief stretch any pair keeps its distance: an unlabeled capture's short pieces tied props to the subject, cargo xtask eval --presets hard --seeds 20001..20050,30001..30050 --unlabeled --props 3 gave 516 exact trees of 700, now 552, against 564 without props). Within a body the markers nearest each joint keep their distance within tens of mm; between bodies the steadiest pair varies by hundreds. Three 4-marker props moving on their own (synth::with_props) regrouped 24 of 140 hard synthetic subjects before (cargo run --release -p segment --example props_segment all hard 20001..20020; hexapod 12 of 20), none now, and beside CMU 02_01 they moved four of its markers (both upper-arm markers into one segment). Over seeds 20001-20100 of every subject, hard, messy and clean, no subject alone is split (BODIES_ONLY=1 props_segment ... 3 RATIO), with two or three markers per segment 2 of 700 (a limb whose widest link stands 3.4 times above the next; their trees as before); the three props come out as the subject and a body each in 93-100 of 100 trials per subject and preset at 2.5, 92-100 at 2, 66-99 at 4 (the rest: a prop whose steadiest pair with the subject varies by less than the spacing, or by less than 2.5 times the subject's widest link). The real captures give the same files. About 0.01 s of segment's 0.28 on cargo xtask bench's capture; 0 = one body; default 2.5",
    ),
    (
        "min_overlap_frames",
        "pairs seen together in fewer frames get no ρ and zero affinity, frames; default 10",
    ),
    (
        "min_segment_markers",
        "groups smaller than this rejoin a group they are rigid with or, failing that, are not segments and their markers are unassigned (a lone marker may still be a 1-marker segment, see singleton_steady_factor); default 2",
    ),
    (
        "rigidity_check",
        "after spectral clustering split clusters that are not rigid within the tolerance, move markers rigid with another cluster, merge clusters rigid with each other; default true (false = the paper)",
    ),
    (
        "split_linkage",
        "rigidity check: split each spectral cluster with the linkage method (linkage, linkage_scaled, linkage_cut) and rejoin orphans within rejoin_factor × tolerance, instead of the average-linkage split with a 4 × tolerance rejoin; default true",
    ),
    (
        "tolerance_mm",
        "rigidity tolerance on ρ (distance std), mm; 0 = automatic: max(tolerance_min_mm, tolerance_factor × spread), spread = median over the markers of spectral clusters of ≥ 4 of the second-smallest ρ to a cluster-mate (or the noise level, the median smallest ρ, when such clusters hold under half the markers), for merging pieces of 1-2 markers and the later checks; markers move and posed clusters merge within max(tolerance_min_mm, tolerance_factor × noise); default 0",
    ),
    (
        "tolerance_factor",
        "automatic tolerance as a multiple of the rigid spread (or the noise level); default 5.0",
    ),
    (
        "tolerance_factor_white",
        "the automatic tolerance's multiple instead of tolerance_factor where the capture's scatter about rigidity is white measurement noise (see white_noise_smoothness): a rigid pair's ρ is then the noise itself, the same for every pair but for the scatter of a standard deviation measured over N frames (1/√(2N) of it: 3 % at 480), while skin gives each pair its own ρ. cargo xtask eval --presets noise: seeds 20001-20050 and 30001-30050 675 -> 683 of 700 exact trees (8 gained, none lost), 40001-40100 682 -> 685 (5 gained; 2 lost, hexapod-noise-s40039's femur cut in two); every other preset unchanged; 0 = always tolerance_factor; default 3.0",
    ),
    (
        "white_noise_smoothness",
        "the capture's scatter about rigidity is white measurement noise when the median over markers of the lag-one autocorrelation of the distance to their steadiest partner (the smallest ρ) is below this: -0.03 to 0.04 for noise alone or none (the noise and clean presets, seeds 20001-20010, 70 trials each; ART's labelled bodies in c3d.org's arthuman 0.00), 1.00 for skin alone, 0.11-0.65 for the hard preset's skin plus 1 mm of noise, 0.19 (c3d.org sample 02) to 0.99 (Sample_Jump2) on the other shared captures; default 0.1",
    ),
    (
        "white_noise_excess",
        "where the capture's scatter about rigidity is white noise (see white_noise_smoothness), the spectral affinity reads every pair's ρ with the noise level (the median steadiest-pair ρ) taken out in quadrature, √(ρ² − noise²): the noise's share is then the same for every pair and hides the little a joint that turns little adds (a small body's markers went to the coxae around it). cargo xtask eval --presets noise: seeds 20001-20050 and 30001-30050 683 -> 686 of 700 exact trees, 676 -> 681 exact segmentations; 40001-40100 685 -> 688 and 674 -> 684; clean, hard and the shared captures unchanged; default true",
    ),
    (
        "tolerance_min_mm",
        concat!(
            "smallest automatic tolerance, ",
            mocap_io::floor_scaled_mm!(),
            "; default 2.0"
        ),
    ),
    (
        "slide_ratio",
        "a marker slides when its RMS ρ to its mates exceeds slide_ratio × the mates' RMS ρ among themselves; default 2.0",
    ),
    (
        "slide_min_mm",
        concat!(
            "... and also exceeds slide_min_mm so noise alone never counts as sliding; ",
            mocap_io::floor_scaled_mm!(),
            "; default 1.0"
        ),
    ),
    (
        "pair_orphans",
        "a marker left alone (a group of one) takes the marker it keeps its distance to best (ρ ≤ tolerance) from a group of 4 or more, so a marker near a joint axis (LANK: rigid with shank and foot alike) goes where both segments stay poseable; never pairs markers whose ρ exceeds the tolerance; default true",
    ),
    (
        "singleton_steady_factor",
        "a marker still alone (rigid with no group) is a 1-marker segment when its smallest ρ to any marker is ≤ this × the tolerance (a steady partner across a joint: jointfit poses it as a swing about the neighbour's joint); otherwise, and always when 0, it is unassigned as sliding or unexplained (unassigned also covers markers with too little data); default 1.0",
    ),
    (
        "spread_max_noise_factor",
        "the rigid spread (each marker's second-smallest ρ in its spectral cluster, median; see tolerance_factor) counts for at most this × the noise level (the smallest ρ): skin raises it to 1.5-2.8 × the noise on noiseless synthetic skin (rigid_spread) and up to 2.4 × on the real captures (Sample_Jump2), while spectral clusters that mix segments, as on a sparse marker set, raise it without bound (human clean --markers 1:3 s6002: a 21.5 mm tolerance on noiseless data, thigh and pelvis merged). --markers 1:3 clean, seeds 10001-10032: 81 -> 84 of 192 exact trees, joint precision 0.85 -> 0.88, recall 0.80 -> 0.84; seeds 4001-4006,6001-6006,7001,9001,1001,5001: 31 -> 32 of 96; no other suite and no real capture changes; 0 = no bound; default 4.0",
    ),
    (
        "spread_second_pass",
        "when the spectral clusters of ≥ 4 markers hold under half the markers, so the rigid spread cannot be read off them and the tolerance stands on the noise level, the spread is read off the segments that tolerance gives (same rule, same bound) and, when larger than the noise level, the capture is segmented again with it. Low noise under skin is the case: two markers of one segment with alike skin have a tiny ρ, the local affinity fragments segments, the eigen-gap picks too many clusters (human-hard-s20005 at --noise 0.3: 24 for 18 segments), and a tolerance on the noise (8.0 mm against 13.0 from the segments) cuts skin-loose segments apart. Sparse marker sets (--markers 2:3) and the real captures whose clusters are mostly of three keep the noise's tolerance: their segments cannot measure the spread either. cargo xtask eval: skin on seeds 4001-4006,6001-6006,7001,9001,1001,5001 66 -> 68/96 exact trees (1.7693 -> 1.7664 %), on 10001-10032 135 -> 136/192 (1.8638 -> 1.8572 %); hard --noise 0.3 on 20001-20020 74 -> 78/120; hard on 10001-10032 147 -> 147 (1.8251 -> 1.8239 %); clean, noise, gaps, swap, messy, hard on the 16 seeds, --markers 2:3 (clean, skin, hard), hard --noise 0.5 on 10001-10016 and every real capture's segmentation unchanged; default true",
    ),
    (
        "singleton_swing_factor",
        "a marker still alone is also a 1-marker segment when it swings about a point of a body of ≥ 3 markers, as a marker on a segment of its own does about its joint: its trajectory in that body's frame fits a sphere (about a hinge, a circle) whose residual (the spread of its distance to the centre, what ρ is for a pair) is ≤ this × the tolerance, while it moves ≥ 2 tolerances (RMS) along an arc that turns ≳ 25° (radius ≤ 8 × that spread). --markers 1:3 on seeds 4001-4006,6001-6006,7001,9001,1001,5001, loose pairs split, --compare segment.singleton_swing_factor=0,0.5: clean 5 -> 7/96 exact trees, joint precision 0.66 -> 0.74, recall 0.46 -> 0.56; hard 5 -> 5, recall 0.38 -> 0.40; no other suite or real capture changes but c3d.org FP1.C3D's PT07 (a 1-marker segment on a ball joint sweeping 52°); 0 = off; default 0.5",
    ),
    (
        "singleton_next_to_small",
        "a marker still alone is also a 1-marker segment when its steadiest partner (least ρ) is in a group of one or two markers: a segment hanging from a neighbour that carries one or two markers has no body of three to swing about, and moving against every group it is a segment of its own as far as the markers can tell; jointfit anchors it through a joint or leaves it detached. A marker sliding on a segment of three or more has its steadiest partner there, and must pass the swing test. Sparse sets (--markers 1:3, seeds 4001-4006,6001-6006,7001,9001,1001,5001): clean 12 -> 31/96 exact trees (1.60 -> 2.18 % of height: the joints of segments found now, most of them one-marker, are the least exact), hard 5 -> 6 (5.04 -> 5.00 %); no other suite and no real capture changes (none has such a marker); default true",
    ),
    (
        "loose_marker_factor",
        "last, a marker whose steadiest ρ to the other markers of its group exceeds this × the tolerance is rigid with none of them and leaves the group as a lone marker (singleton_steady_factor, singleton_swing_factor and singleton_next_to_small judge it; a loose pair is two), and a lone marker whose ρ to every marker of a group of two or more is within the tolerance joins that group (a sparse set's three-marker segment came out as a pair and a lone marker: robotarm clean --markers 1:3 s4001's link1; on seeds 10001-10032 hard 145 -> 146/192 exact trees, skin 132 -> 133, S16 --markers 2:3 skin 36 -> 37, --markers 1:3 clean 10 -> 12 and 1.69 -> 1.60 %, nothing else changed). Scaled linkage keeps markers that are each other's nearest however loose: on a sparse marker set (one marker on the shank, one on the foot) such pairs and triples formed across joints (human clean --markers 1:3 s4001: shank + foot at ρ 19.7 mm, tolerance 2 mm); a marker of a true segment under skin keeps its steadiest ρ within about 1.3 tolerances (at 1×, two --markers 2:3 skin trees broke); 0 = off; default 2.0",
    ),
    (
        "fit_split_ratio",
        "after clustering, each cluster of 4–10 markers is fitted as one rigid body per frame (Horn, reference shape from mean distances) and as the best two bodies (every bipartition into parts of ≥ 2); it splits when its residual σ (per coordinate, degrees-of-freedom corrected) exceeds fit_split_ratio × the two bodies' pooled σ and fit_split_floor × the typical cluster's σ, recursively. A fit sees a joint's rotation to first order where ρ sees it to second order near a straight limb; 0 = off; default 2.0",
    ),
    (
        "fit_split_floor",
        "fit split: the cluster's fit σ must also exceed this × the typical segment's (the median fit σ of the clusters of ≥ 2 markers: skin artefact sets it, not the noise), and tolerance_min_mm; a split piece rejoins the cluster (of the three it keeps its distances to best) whose union with it stays within this floor, smallest union σ first; default 2.0",
    ),
    (
        "reassign_ratio",
        "after the fit split, every cluster of ≥ 3 markers is posed per frame (Horn) and each marker's trajectory is expressed in each body's frame; its scatter there (per coordinate, 75th-percentile frame) is skin and noise on its own body but lever arm × angle on a neighbour's, first order in the joint angle. A marker moves when another body holds it this many times stiller than its own body posed without it, and its own scatter exceeds tolerance_min_mm; the donor keeps ≥ 2 markers; 0 = off; default 2.0",
    ),
    (
        "joint_merge_z",
        "after the joint test, two clusters of ≥ 3 markers with some marker pair within 2 × the tolerance of ρ merge when the joint test's rotation score of the pair is below this and the second's centroid stays within 2 × the part σ bound in the first's frame: they move as one rigid body (a rigid body's best cut scores about 2, true joints 4 and up). The default is joint_split_z's: a pair the joint test would not cut apart is one body; at 3.0 a pair scoring between the two stayed split (snowman-hard-s8104: a root split in two by skin, z 4.29). cargo xtask eval --compare segment.joint_merge_z=3,4.5: hard trees on seeds 8101-8124 90 -> 92/144, 8201-8230 130 -> 131/180, 4001-4006/6001-6006/7001/9001/1001/5001 71 -> 71/96 (and with --markers 2:3 unchanged); messy 8101-8112 40 -> 41/72, skin mean 2.30 -> 2.22 %; noise, gaps, swap, clean and every real capture's segmentation unchanged; most rigid pair first, repeatedly; 4.5 -> 4 with joint_split_z (see there); 0 = off; default 4.0",
    ),
    (
        "pair_hold",
        "after the rigid merge, a two-marker cluster whose markers are held by two different other clusters' bodies (≥ 3 markers each) within this × the typical segment fit σ (and tolerance_min_mm) dissolves, each marker joining the body that holds it: two markers near one joint axis, one per side, keep a steady distance and pair up although each moves with its own segment. A pair one body holds both of stays: it may be a segment that moved little against that body (Gait.trc's ASIS pair on the trunk, MACsample's heel and toe on the shank, arthuman's labelled bodies), and a true two-marker segment has a marker no other body holds (CMU's THI, SHN). A one-marker cluster a body holds within the same bound joins it (a trajectory swapped or glitching in a minority of frames; Sample_Jump2's virtual hip point VLHI joins its virtual pelvis); cargo xtask eval --presets swap on seeds 9001,9002,1001,1002,7001,7002: 25 -> 29/36 exact, 0.70 -> 0.58 %; 3001-3004: 17 -> 18/24. eval_segment 480, seeds 3001-3006, 5001, 5002: swap exact 23 -> 38/48, skin 19 -> 21, noise 47 -> 48, hard/clean/gaps unchanged; cargo xtask eval --presets swap --seeds 1001,1002: topology 6 -> 10/12; every real capture's segmentation unchanged; 0 = off; default 3.0",
    ),
    (
        "pair_rejoin_ratio",
        "with pair_hold: a two-marker cluster whose markers one body (≥ 3 markers) holds both of, within pair_hold's bound, rejoins that body when spectral clustering had put the pair and some of the body's markers in one cluster (the rigidity check's linkage cut them apart) and the pair's larger scatter in the body is within this × the body's own rigid-fit σ. Skin (5-15 mm, with two markers' skin alike) cuts a true segment into k + 2 this way when noise is low; exact data (σ near zero: arthuman's labelled bodies, whose pairs move 1.5-2 mm against a body of σ about 3e-5 mm) keeps its pairs. cargo xtask eval --compare segment.pair_rejoin_ratio=0,8: skin on seeds 10001-10032 82 -> 94/192 exact trees (4: 91, 16 and 100: 95), on 4001-4006,6001-6006,7001,9001,1001,5001 47 -> 52/96, hard --noise 0.5 there 56 -> 60/96; hard (there 71/96, on 10001-10032 137/192), clean, noise, gaps, swap, --sweep 0.4:0.6 and --markers 2:3 unchanged; messy on 10001-10032 124 -> 123/192 (quadruped-messy-s10010: a pair joined a cluster that already mixed two segments); every real capture's segmentation unchanged; 0 = off; default 8.0",
    ),
    (
        "pair_repartner",
        "with pair_hold: a two-marker cluster only one of whose markers a body holds within pair_hold's bound re-pairs when both markers are steadier elsewhere: the free marker takes the partner pair_orphans would give it were it alone (ρ within the tolerance and no looser than that partner's RMS ρ to its own group, which keeps 3 markers) if its ρ to it is below the pair's own, and the held marker, whose RMS ρ to the holder's markers is below the pair's ρ too, joins the holder; failing that, the free marker joins a two-marker cluster its RMS ρ to which is below the pair's ρ and with which it fits as one segment (rigid σ within the fit split's floor), and the held marker joins the holder. Two markers of different segments can keep a steady distance through a capture: CMU 02_01's right upper-arm marker left the head cluster with a forehead marker (the fit split's parts have ≥ 2 markers) while its true partner RSHO stayed in the torso; a knee or elbow marker a neighbour holds loosely stays with its thigh or upper-arm marker (its RMS ρ to the holder is not below the pair's). With pairs counted in the typical segment σ, CMU 02_01 needs it (measured at 84cb8c8: without, RUPA pairs with LFHD and the right humerus comes out 399 mm against Vicon's 284; with, 275 mm, the left 277 against 275); cargo xtask eval --compare segment.pair_repartner=false,true changes no tree and no mean beyond 0.01 % on seeds 4001-4006,6001-6006,7001,9001,1001,5001 (every preset; --markers 2:3 clean, skin, hard; --markers 2:2 clean, noise, hard) or 10001-10032 (noise, skin, hard); default true",
    ),
    (
        "join_small",
        "after pair_hold, clusters of one or two markers join each other where spectral clustering had put all their markers in one cluster (a later step cut them apart) and their union (≥ 3 markers) fits as one rigid body within the fit split's floor (fit_split_floor × the typical segment's fit σ, and tolerance_min_mm), smallest union σ first: skin cuts a segment into pairs whose own distances stay steady, and no body of ≥ 3 is left to hold them (human-skin-s10012: a foot as two pairs, union σ 1.21 × typical). Without the spectral condition two true two-marker segments across a joint that turns little joined too (--markers 2:3 --presets clean 93 -> 89/96 exact trees). cargo xtask eval with and without it: skin on seeds 10001-10032 130 -> 132/192 exact trees, messy on 4001-4006,6001-6006,7001,9001,1001,5001 73 -> 74/96; every other suite there and on 10001-10032 (noise, hard), --markers 2:3 (clean, skin, hard) and --sweep 0.2:0.4 the same trees; every real capture's segmentation unchanged; default true",
    ),
    (
        "glitch_factor",
        "before anything else, a sample is a glitch, read as a gap by every segmentation step and by jointfit and bonefit (Segmentation::glitches), when in that frame its marker is off its median distance to most of its 3 steadiest partners seen there (of its 6 steadiest; scatter: the 90th percentile of the distance's deviation from its median, in σ of Gaussian scatter) by more than this × that pair's scatter and tolerance_min_mm. A joint moves a marker against another segment's markers, never against its own, and skin or noise by about its usual scatter; a misreconstructed marker leaves them all at once (c3d.org Eb015: RSK1 off its shank plate by up to 50 mm in frames 136-166 of 450, ρ 8.6 mm against the plate's 0.5-1 mm, and the plate came out as two pairs). The 90th percentile, not the median absolute deviation: with the latter AlbertoINT had 6068 samples of 19 markers masked and its arm segments changed. Label swaps are still looked for in the capture as it was. Each marker's count is in skeleton.json (glitch_frames). Read as gaps by jointfit and bonefit too: Eb015pr's knee and ankle joints' largest frame-to-frame acceleration over frames 125-175 fell from 14.4 and 14.1 to 9.1 and 10.7 mm/frame², its joints' fit residuals by 3.3 mm in sum; synthetic S16 unchanged but messy's kind count (964 -> 963/1011), V messy 124 -> 125/192. cargo xtask eval --compare segment.glitch_factor=0,8: on seeds 4001-4006,6001-6006,7001,9001,1001,5001 clean, noise, skin, gaps, swap and hard unchanged, messy 66 -> 67/96 exact trees; on 10001-10032 swap, hard and messy unchanged (192, 137 and 123/192); real captures: Eb015 (6 files) and TESTBPI/TESTDPI keep the RSK plate whole, every other capture's segmentation unchanged; 0 = off; default 8.0",
    ),
    (
        "repair_swaps",
        "look for label swaps on the finished segmentation: two markers of different segments whose distances to their segment-mates (to a nearby cluster's markers, for a marker left in a group of one or two) leave their usual values in the same minority of frames, and in those frames each sits at the other's usual distances from the other's segment (bound: max(pair_hold, 1) × the typical segment fit σ, at least tolerance_min_mm, or 3 × the marker's own median change if looser; ≥ 3 such frames, ≥ 90 % of frames explained either way). The swap's frames are those the exchange explains better, each end then moved to the frame where exchanging back joins both markers' paths again (each corrected step within 4 × the marker's median step); a swap with an end that no step nearby joins, every step seen, is dropped: undoing an exchange that never happened puts a jump of the markers' separation into both (hexapod-skin-s5001 had one, 32-42 mm apart). cargo xtask eval against the build before: messy on seeds 4001-4006,6001-6006,7001,9001,1001,5001 75 -> 75/96 exact, 1.8093 -> 1.8068 %; on 10001-10032 136 -> 137/192, 1.8633 -> 1.8629 %; swap unchanged; hard S16 1.7674 -> 1.7798 % (hexapod-hard-s4003, which has no swap, lost a false one that had happened to help); last, two markers that jump in one step each onto the other's path, and again later, are a swap whatever the clusters made of them (a swap can pull a marker into its partner's cluster, where neither is a suspect: robotarm-messy-s9001); cargo xtask eval against the build before it: messy on 10001-10032 137 -> 145/192 exact, 1.8629 -> 1.8354 %, on 4001-4006,6001-6006,7001,9001,1001,5001 75 -> 76/96, 1.8068 -> 1.8048 %, swap there 95 -> 96/96, 0.0698 -> 0.0591 %, on 3001-3004,9002,1002,7002 messy 29 -> 31/42; every preset without a swap unchanged; one of the two may land within its jump bound when they were close, if the exchange explains the two steps better than none (snowman-messy-s10005), and each window end goes where the exchange explains the steps best: V messy 1.8354 -> 1.8340 %, S16 messy 1.8048 -> 1.8006 %, swaps found with their exact frames in V messy 154 -> 158/192; the other marker may be unseen across the step, for up to 20 frames, when one jumps (V messy 145 -> 146/192 trees, 1.8340 -> 1.8334 %, swaps with exact frames 158 -> 159: 18 missed, 15 with frames off near a close pass, none wrong); Each swap is undone, the capture segmented again, and the swaps listed in the artifact and skeleton.json (label_swaps); jointfit and bonefit read the trajectories with them undone. cargo xtask eval on seeds 9001,9002,1001,1002,7001,7002,4001,4002: swap 39 -> 47/48 exact trees, messy (hard + swap) 27 -> 29/48; on 24 swap trials (human, quadruped, snowman, robot arm, seeds 21-26) every swap found with its exact frames, on the same as messy 17 of 24 (23 of 24 with the two rules below, all with their exact frames: `cargo xtask synth --preset messy --seed 21..26` and `cargo xtask run`, against the truth's swaps); no swap reported on any real capture; an exchange step may also show on one side only, where the partner's track ends or starts (an unlabeled capture), or without a jump where both markers move fast and land on each other's paths; which frames are exchanged is chosen over the whole capture, undoing must bring both markers nearer their steadiest partners, and rounds look again with the swaps found undone (a marker can then be in several, undone in order): cargo xtask eval --presets messy,gaps --seeds 20001..20020 --unlabeled 245 -> 253/280 exact trees, labelled 256 both; default true",
    ),
    (
        "join_pieces",
        "after the reassignment, tracks that are pieces of one marker's trajectory (an unlabeled capture's, which the reader's stitch left apart: a gap over a second, or a rival near) are joined where a body of >= 3 markers holding either carries one's end to the other's start: the later piece's mean position in the body's frame over its first 0.5 s lies within half the way to the body's nearest marker seen with the earlier piece (at most the marker spacing) of the earlier piece's over its last 0.5 s, with no rival within twice that (see the pieces module); a track with two such continuations, or continuing two, joins none. The capture is then segmented again with each group as one marker (up to 4 rounds: joined tracks pose more bodies) and each piece put in its marker's segment (the artifact's pieces, skeleton.json's piece_of); jointfit and bonefit read each group as its first track. A labelled capture has nothing to join: cargo xtask eval --presets hard --seeds 20001..20050,30001..30050 scores every trial as before, and every real capture's skeleton is unchanged; with --unlabeled, 473 -> 497/700 exact trees, 1.6027 -> 1.5004 % of height, known 99.92 -> 99.93 %, the suite's time 136 s before, 138 and 151 s in two runs after (493 trees and 1.5331 % with the later stages reading the pieces apart); of the 1834 groups joined there (3761 tracks) one is wrong (a marker's first piece taken with another's third). Where no pose carries a piece across (a segment's other markers hidden or in pieces over the same stretch), a track never seen with a body's member joins it when seen with >= 2 of the body's other markers, rigidly (rho within the rigidity tolerance), at the distances the body's shape puts that member from them (RMS within half its distance to its nearest neighbour in the shape), no other member within twice that, no other track seen with it fitting too: with --unlabeled 530 -> 555 trees, 1.4256 -> 1.3897 %, known 99.95 -> 99.99 %, 7 of 2483 groups wrong (1 of 1885 without), each a marker's piece taken for another's of its segment; with --markers 2:3 --unlabeled 168 -> 228 trees, 3.6998 -> 3.4015 %, 25 of 1245 wrong (4 of 272 without), 5 across a joint. Looked for after the whole segmentation instead, one round: 488 trees at 1.9 x the time; after the reassignment, one round: 488. Where nothing else joins, a body of >= 3 tracks never seen with another, all starting after the other's end (a segment hidden whole), is that body again where a rotation and translation put the smaller one's shape on the other's within half the closest two markers' distance and twice the rigidity tolerance, RMS, no other map of the markers fitting within the tolerance (or twice the shapes' own distance scatter, their marker pairs' rho RMS, where that is less) or twice the best (so are tracks of a body's own cluster it cannot be posed with, where they pose a body of its shape): with --unlabeled 557 -> 558 trees, with --markers 2:3 --unlabeled 262 -> 263, --presets messy,gaps --seeds 20001..20020 --unlabeled 243 -> 245 of 280, labelled trials and real captures the same; default true",
    ),
    (
        "leave_out_undecided",
        "last (before the user's groups), a track is left out, unassigned with the reason, when it keeps its distance (rho within the rigidity tolerance, over >= min_overlap_frames) to every marker of its cluster it was seen with, and to every marker of another cluster it was seen with no worse (its largest rho there within its largest to its own; at least one of each), while over the frames it was seen the two clusters moved against each other by less than a third of what they do over the capture (the RMS ratio of each cross pair's rho over those frames to its rho over all its frames): seen only while the two held still against each other, it could be on either, and in the wrong one it poses that segment wrongly while it is seen (an unlabeled capture's short piece; a marker hidden most of the time). Rigid with two clusters that did turn against each other while it was seen, it sits at their joint and stays. A cluster keeps at least two markers; the user's groups are left alone. cargo xtask eval --presets hard --seeds 20001..20050,30001..30050 --markers 2:3 --unlabeled: 229 -> 245/700 exact trees (+16 -0), 3.3956 -> 3.2896 % of height, known 96.52 -> 96.49 %; --unlabeled 554 both, 1.3887 -> 1.3888 %; labelled at 3-6 and 2-3 markers every trial the same, every real capture's skeleton.json unchanged; default true",
    ),
    (
        "eject_ratio",
        "after the reassignment and the joint test, in a cluster of ≥ 5 the marker with the largest scatter in its own body posed without it (as reassign_ratio measures it) leaves the cluster as a group of its own when that exceeds tolerance_min_mm and this × the median of its cluster-mates' (measured without it) (one per cluster; it stays a 1-marker segment when singleton_steady_factor keeps it, else it is unassigned). ρ misses a marker whose distances to a cluster barely change while the body turns it by tens of mm (CMU 02_01: RUPA swings 36 mm RMS in the head's frame, the head markers 3-5 mm; it leaves the head, pairs with RSHO, and the right humerus goes from 463 to 228 mm, Vicon 284). The mates' median is floored at the typical segment fit σ (skin): net of their poses' own error it can come out near zero, and then any foot marker looked ejectable. Synthetic (eval_segment 480, seeds 3001-3006, 5001, 5002): every preset's exact count unchanged; at 4 instead of 8 a skin marker left a snowman on seed 9001 (cargo xtask eval --seeds 9001,9002: hard topology 6/12 -> 5/12); 0 = off; default 8.0",
    ),
    (
        "joint_retest",
        "last, a cluster of ≥ 6 markers that neither the joint test's rounds nor the rigid merge has judged (the pair holds, ejections, orphan pairings and lone-marker steps after them assembled it) is put to the joint test once; what the merge joined as one body is not cut again. human-hard-s20038's abdomen and thorax (3 + 3 markers) ended as one segment whose true cut scores z 5.05. cargo xtask eval --presets hard: seeds 20001..20050,30001..30050 555 -> 556 exact trees (human s20038), 1.3935 -> 1.3920 % of height; 40001..40100 539 -> 540 (snake s40055), 1.3992 -> 1.4040 % (three hexapods cut further, one of them 4.28 -> 6.64 %); 50001..50100 544 both, no trial changed; no tree lost. Retesting every final cluster instead (the merged ones too) gave +8 -4 trees over the three sets and raised every mean: the merge's one body cut again at another boundary; on 20001..20020 noise 136 -> 137 (hexapod s20001; 0.1947 -> 0.1967 %), skin, messy, gaps, --markers 2:3, --sweep 0.2:0.4 and --marker-arc 120 the same trees (skin 1.3290 -> 1.3291 %, the rest's means unchanged); clean on 20001..20050,30001..30050 700/700, 0.0581 %; every real capture's skeleton.json unchanged; default true",
    ),
    (
        "regroup_ratio",
        "after the joint retest, three clusters that are two segments regroup: a cluster of at most 4 markers and two of its three nearest (closest mean marker distance), together at most 12 markers, become two bodies, the two neighbours each taking the middle's markers that keep their distances to it best (mean ρ), when those two pass the joint test and their pooled fit σ is at most this × the three clusters' pooled σ; the lowest ratio first, repeatedly. Skin that moves markers with a joint's angle leaves a small cluster at a joint with some markers of each side, or cuts one segment in two whose halves never merge back; three true segments in two bodies fit clearly worse (one body spans a joint): over W's pipeline trees (human, quadruped, robot arm) the triples within 1.15 were all two true segments, the first three-segment one at 1.21. cargo xtask eval --presets hard, 0 -> 1.15: seeds 20001..20050,30001..30050 559 -> 568 exact trees (+9 -0), 1.3883 -> 1.3821 % of height; 40001..40100 543 -> 551 (+8 -0), 1.4005 -> 1.3955 %; 50001..50100 548 -> 556 (+8 -0), 1.4053 -> 1.3954 %; --frames 240 500 -> 509 (+11 -2); --markers 4:8 564 -> 574 (+10 -0), 1.1471 -> 1.1429 %; --markers 2:3 276 -> 275 (quadruped s20025 lost), 3.0269 -> 3.0278 %; clean 700/700 unchanged; every real capture's skeleton.json unchanged. Trying every way to share the middle's markers out and keeping the best fit gave the same trees on the first two sets and two more on the third (+10), at 2.2 x the eval time with --markers 2:3; this share-out costs about 2 %. 0 = off; default 1.15",
    ),
    (
        "joint_split_z",
        "after the fit split, each cluster of ≥ 6 markers is cut in the two parts of ≥ 3 that two free rigid bodies fit best (all bipartitions up to 12 markers, else spectral cuts of the ρ affinity refined by single moves); each part is posed per frame (Horn) and the deviation of their relative rotation from its mean is weighed by the covariance the parts' pose errors give on one body (σ² J⁻¹ per part, σ = the median fit σ of the clusters of ≥ 3, J = the part's inertia tensor). It splits when that robust Mahalanobis length (75th-percentile frame; ≈ 2 on one rigid body) exceeds this and a centre of rotation fixed in both parts (SCoRE) explains their relative motion (joint_centre_fraction); recursively. Skin moves markers one by one, a joint turns a whole group about one point. 4.5 -> 4 (with joint_merge_z): true single segments' weighed cuts score up to 3.97 on hard S16 (4.17 on skin S16, a quadruped's tail tip; 4.15 on V's human-skin-s10009, a clavicle), while 7 of the 32 quadruped carpi of hard S16 score 4.07-4.48 (joint_table example); cargo xtask eval (S16 = seeds 4001-4006, 6001-6006, 7001, 9001, 1001, 5001; V = 10001-10032): hard trees S16 71 -> 75/96 (quadruped 9 -> 12, robot arm 14 -> 15), V 137 -> 139/192; messy S16 67 -> 72, V 123 -> 124; skin S16 52 -> 53, V 94 -> 93; clean, noise, gaps, swap unchanged; 26 of 28 real captures segmented as before, btk Res16bits (a 100-frame standing trial, C3D and TRC) cuts its trunk-and-legs group in two (0.5-1 deg of sway); 0 = off; default 4.0",
    ),
    (
        "joint_travel_z",
        "the joint test also cuts where the centroid of one part (the worse posed: larger trace of J⁻¹) travels in the other's frame with a robust Mahalanobis length (75th-percentile frame) above this, under the covariance one rigid body gives it: both centroids' errors (σ²/n) and the frame part's rotation error σ² J⁻¹ swinging the lever arm (≈ 2 on one body); the same centre test applies, and neighbours scoring above it do not merge (joint_merge_z). A part of three markers nearly in line with a hinge's axis poses that rotation badly, so its rotation score stays low while its centroid visibly swings (hexapod-noise-s10019: body + left front coxa, 4 + 3 markers at a 31° hinge, rotation z 3.83, travel z 5.20). joint_table example, S16 seeds, true segments' weighed cuts (the false splits it could make) score travel z above 4 / 4.5 / 5 in 3 / 1 / 0 of 279 on hard and 4 / 1 / 0 on skin (rigid bodies ≈ 1.7-1.8), while 48 / 38 / 32 of the 97 true joints the rotation score leaves below 4 on hard score above it. cargo xtask eval against the code without it and without the joint test's second pass after the settling (S16 = seeds 4001-4006, 6001-6006, 7001, 9001, 1001, 5001; V = 10001-10032): hard trees V 143 -> 145/192 (human 26 -> 27, quadruped 21 -> 22), S16 76 -> 76/96; noise V 185 -> 188 (hexapod 26 -> 29, with the joint test run again after the settling); skin S16 65 -> 64 (human-skin-s4006 cuts a foot's two markers off); clean, gaps, swap, --markers 2:3 and ten real captures' trees unchanged; 0 = off; default 5.0",
    ),
    (
        "joint_centre_fraction",
        "joint test: the best centre of rotation fixed in both parts must leave a residual (75th-percentile frame, mm) of at most this fraction of the parts' relative translation (B's centroid about its median in A's frame); default 1.0",
    ),
    (
        "joint_rotation_travel_z",
        "joint test: a relative rotation above joint_split_z means articulation only when the worse posed part's centroid also travels in the other's frame with a robust Mahalanobis length above this (joint_travel_z's measure, about 2 on one rigid body). A part's pose error turns it about its own centroid, which stays put in the other part's frame, where a joint swings the centroid about the joint: snake-hard-s20030's link2 cut 3 + 3 turned 100° RMS (z 5.05) while the spinning part's centroid travelled 8.7 mm (travel z 2.04). merge_table example over every subject, seeds 20001..20050 (with MARKERS=4:8 all but the hexapod): of the pairs of final segments cut from one true segment that pass joint_split_z, 3 of 10 travel below 2.5 (4:8: 10 of 18); of the pairs a true joint joins, 9 of 3535 (4:8: 4 of 3076). cargo xtask eval --presets hard --compare segment.joint_rotation_travel_z=0,2,2.5,3: seeds 20001..20050,30001..30050 556 / 558 / 558 / 557 exact trees (1.3920 / 1.3918 / 1.3882 / 1.3939 %), 40001..40100 540 / 543 / 543 (1.4040 / 1.4008 / 1.4005 %), 50001..50100 544 / 544 / 546 (1.4058 / 1.4068 / 1.4068 %); with --markers 4:8 (the first seeds) 552 / 558 / 564 (with more markers a segment has more ways to be cut in halves that pass the rotation score); clean unchanged (700/700, 0.0581 %), every real capture's skeleton.json byte-identical. The rigid merge was left alone: merging pairs the rule would not cut lost 5 trees at 2.5. Rotations above joint_rotation_alone_z need no travel. 0 = any; default 2.5",
    ),
    (
        "joint_rotation_alone_z",
        "joint test: a relative rotation whose robust Mahalanobis length is above this means articulation without joint_rotation_travel_z's travel: no pose error turns a part that far, while a part seen from a long frame posed from markers near its line travels through a wide covariance (random-hard trees: true joints at rotation z 6-16 with 45-263 mm of travel score travel z 1.4-2.5 with their true parts, truth_evidence example). The trials in which every true joint passes with its true parts (truth_evidence, seeds 20001..20050 and 30001..30050), without the travel rule / with it / with it and this bound: random trees 92 / 84 / 90, humans 89 / 85 / 86, quadrupeds 65 / 61 / 61, hexapods 36 / 35 / 35. cargo xtask eval --presets hard: seeds 20001..20050,30001..30050 and 40001..40100 the same trees and means with and without it (558, 1.3882 %; 543, 1.4005 %), 50001..50100 546 -> 547 (snake s50052; 1.4068 -> 1.4065 %), --markers 4:8 the same 564; at 6.5 the first seeds lose human s20007 (a mixed cluster whose parts turn at z 6.87 with travel z 1.23). 0 = never; default 8.0 (twice joint_split_z's)",
    ),
    (
        "joint_pair_share",
        "the joint test's route for a part of two markers, run where at least this share of the clusters of ≥ 2 markers (after the reassignment, before the joint test) hold exactly two: a marker set with two markers on some segments, where a segment of two merged with its neighbour is a cluster the test's parts of ≥ 3 cannot cut. A cluster of 5 to 16 markers the test leaves whole is cut into the two markers that fit best as a pair beside the rest (smallest pooled σ of the rest's rigid fit and the pair's distance) and the rest, when in the rest's frame (posed per frame) the pair's midpoint travels with a robust Mahalanobis length above joint_travel_z (under the covariance one rigid body gives it: the rest's rotation error σ² J⁻¹ of the markers each frame saw, at the midpoint's lever, and both position errors; ≈ 2 on one body) while its direction turns with one above 2 (≈ 1.7 on one body), or its direction turns above joint_split_z while the midpoint travels above joint_rotation_travel_z, as the test weighs parts of ≥ 3; one centre fixed in the rest must keep both markers at constant distances (joint_pair_centre_fraction) on an arc that visibly turns (their distance to it at most 8 × the travel), the frames read must pose the rest well (joint_pair_max_spin_deg) and both must fit like ordinary segments. pair_table example (hard, seeds 20001..20012, every subject): of the 451 true joints between a 2-marker segment and one of ≥ 3 at --markers 2:3 that the route can read, its best cut of their union is the true one in 384 and passes in 314 (305 the true cut); of 466 final single-segment clusters of ≥ 5 markers at the default markers, none passes. The share of two-marker clusters when the joint test starts is 0.11 at most at the default 3-6 markers (median 0) and 0.43 median at 2-3 (p10 0.17; hard, seeds 20001..20008, every subject). Always on (0), cargo xtask eval --presets hard, seeds 20001..20050,30001..30050, the default markers lose 4 trees (568 -> 564; cuts in clusters a stray marker mixes) and --markers 2:3 gains 8 (275 -> 283, +8 -0); at 0.15 (--compare segment.joint_pair_share=2,0.15, --markers 2:3) 275 -> 283 (+8 -0, 3.0278 -> 3.0264 %), seeds 40001..40100 271 -> 279 (+8 -0), 50001..50100 291 -> 297 (+6 -0), and at the default markers every trial of the three sets unchanged; no real capture's segments change. 0 = always, above 1 = never; default 0.15",
    ),
    (
        "joint_pair_centre_fraction",
        "the pair route (joint_pair_share): one centre fixed in the rest that keeps both markers at constant distances (a shared-centre sphere fit) must leave a residual (75th-percentile frame) of at most this fraction of the midpoint's travel; default 0.3",
    ),
    (
        "joint_pair_max_spin_deg",
        "the pair route (joint_pair_share) reads only the frames whose seen markers of the rest pose it with a rotation noise about its worst axis (√(σ² λ_max(J⁻¹)) of those markers) of at most this: three markers nearly in a line (a body that lost its one marker off the line to a gap: snake-hard-s30030 at the default markers) spin about it far beyond the linearised covariance, and swing a pair on one rigid body with them on a circle any centre on that line fits; default 20",
    ),
    (
        "near_joint_fraction",
        "a diagnostic, nothing is cut: a final segment of ≥ 6 markers whose best cut (the one the joint test weighs, smallest pooled σ) scores at least this fraction of joint_split_z on its rotation or of joint_travel_z on its centroid's travel is listed in Segmentation::near_joints, in skeleton.json (the segment's near_joint, with both parts) and among the run's findings, as possibly two segments that turn little about a joint: skin leaves such joints under the test (a hexapod's coxae merged into its body, a quadruped's carpus into its forearm). The parts are the test's best cut, which skin can put elsewhere than the joint. cargo xtask eval --presets hard (its 'listed as maybe two' figures: segments of ≥ 6 markers holding ≥ 3 markers of each of two true segments, and the rest): seeds 20001-20050,30001-30050 102 of 140 and 131 of 2013 (hexapod 84 of 113 and 30 of 356, quadruped 15 of 20 and 36 of 445); at 0.7 112 and 225, at 0.8 82 and 85; seeds 40001-40100 117 of 175 and 145 of 2035 (measured with joint_rotation_travel_z, which this listing does not read: a cut it refuses as pose error is listed when its rotation scores this fraction). Of the real captures' 16 segments of ≥ 6 markers, 3 are listed: btk Res16bits' head, shoulder and arm with the hand as the other part (rotation z 4.67, failing the test's centre condition) in its C3D and its TRC, and OpenSim subject01_walk1's right foot (z 3.10). Costs the segment stage about 0.01 s of 0.27 on cargo xtask bench's capture; 0 = off; default 0.75",
    ),
    (
        "groups",
        "[[\"LABEL\", ...], ...]: markers that are one segment, by label as the capture names them (a repeated label's later markers LABEL#2, ...; * stands for any run of characters, as in mocap-io.exclude_markers): each group is a segment of exactly those markers, taken out of whatever segments the grouping put them in, and every other marker is grouped as without it (a segment left with fewer than min_segment_markers is unassigned). For what the data cannot decide: a segment the findings list as maybe two (a joint that turns no more than skin moves, as a hexapod's coxa on its body or a quadruped's carpus), two segments of one body, a marker put on the wrong side of a joint. A label or pattern that matches no marker, or a marker two groups name, is an error; skeleton.json marks a named segment \"named\": true, and the run's findings list one whose markers keep their distances clearly worse than the capture's segments do (a group across a joint); default []",
    ),
];

impl Params {
    /// The largest fit σ (mm) of an ordinary segment when the capture's typical segment
    /// fits to `typical_mm`: what the fit split leaves whole, and what each part of a joint
    /// must fit within. Never below `tolerance_min_mm`: on noiseless data every σ is
    /// rounding error.
    pub fn segment_sigma_mm(&self, typical_mm: f64) -> f64 {
        (self.fit_split_floor * typical_mm).max(self.tolerance_min_mm)
    }

    /// These parameters with their millimetre floors (`tolerance_min_mm`, `min_scale_mm`,
    /// `slide_min_mm`) times `scale` (≤ 1, [`mocap_io::Trajectories::floor_scale`]): floors
    /// set for markers a few centimetres apart would swallow a small subject's motion.
    pub fn with_floors_scaled(&self, scale: f64) -> Self {
        Self {
            tolerance_min_mm: self.tolerance_min_mm * scale,
            min_scale_mm: self.min_scale_mm * scale,
            slide_min_mm: self.slide_min_mm * scale,
            ..self.clone()
        }
    }

    /// Checks ranges; a bad value is an error naming the parameter.
    pub fn validate(&self) -> Result<(), Error> {
        fn bad(name: &'static str, value: impl ToString, why: &'static str) -> Error {
            Error::InvalidParam {
                name,
                value: value.to_string(),
                why,
            }
        }
        let positive = |name, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(name, v, "must be a finite number > 0"))
            }
        };
        let non_negative = |name, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(bad(name, v, "must be a finite number ≥ 0"))
            }
        };
        if self.local_k == 0 {
            return Err(bad("local_k", self.local_k, "must be ≥ 1"));
        }
        positive("min_scale_mm", self.min_scale_mm)?;
        non_negative("rejoin_factor", self.rejoin_factor)?;
        positive("linkage_cut", self.linkage_cut)?;
        if self.linkage_k == 0 {
            return Err(bad("linkage_k", self.linkage_k, "must be ≥ 1"));
        }
        positive("scale_mm", self.scale_mm)?;
        if self.max_segments == 0 {
            return Err(bad("max_segments", self.max_segments, "must be ≥ 1"));
        }
        if self.restarts == 0 {
            return Err(bad("restarts", self.restarts, "must be ≥ 1"));
        }
        if !(0.0..=1.0).contains(&self.min_visible_fraction) {
            return Err(bad(
                "min_visible_fraction",
                self.min_visible_fraction,
                "must be between 0 and 1",
            ));
        }
        non_negative("stationary_jitter_factor", self.stationary_jitter_factor)?;
        non_negative("body_gap_ratio", self.body_gap_ratio)?;
        if !(0.0..=1.0).contains(&self.brief_track_fraction) {
            return Err(bad(
                "brief_track_fraction",
                self.brief_track_fraction,
                "must be between 0 and 1",
            ));
        }
        if self.min_overlap_frames < 2 {
            return Err(bad(
                "min_overlap_frames",
                self.min_overlap_frames,
                "must be ≥ 2 (a standard deviation needs two frames)",
            ));
        }
        if self.min_segment_markers == 0 {
            return Err(bad(
                "min_segment_markers",
                self.min_segment_markers,
                "must be ≥ 1",
            ));
        }
        non_negative("tolerance_mm", self.tolerance_mm)?;
        positive("tolerance_factor", self.tolerance_factor)?;
        non_negative("tolerance_factor_white", self.tolerance_factor_white)?;
        non_negative("white_noise_smoothness", self.white_noise_smoothness)?;
        positive("tolerance_min_mm", self.tolerance_min_mm)?;
        positive("slide_ratio", self.slide_ratio)?;
        non_negative("slide_min_mm", self.slide_min_mm)?;
        non_negative("singleton_steady_factor", self.singleton_steady_factor)?;
        non_negative("singleton_swing_factor", self.singleton_swing_factor)?;
        non_negative("spread_max_noise_factor", self.spread_max_noise_factor)?;
        non_negative("loose_marker_factor", self.loose_marker_factor)?;
        non_negative("fit_split_ratio", self.fit_split_ratio)?;
        non_negative("fit_split_floor", self.fit_split_floor)?;
        non_negative("reassign_ratio", self.reassign_ratio)?;
        non_negative("joint_split_z", self.joint_split_z)?;
        non_negative("joint_travel_z", self.joint_travel_z)?;
        positive("joint_centre_fraction", self.joint_centre_fraction)?;
        non_negative("joint_rotation_travel_z", self.joint_rotation_travel_z)?;
        non_negative("joint_rotation_alone_z", self.joint_rotation_alone_z)?;
        non_negative("joint_pair_share", self.joint_pair_share)?;
        positive(
            "joint_pair_centre_fraction",
            self.joint_pair_centre_fraction,
        )?;
        positive("joint_pair_max_spin_deg", self.joint_pair_max_spin_deg)?;
        non_negative("eject_ratio", self.eject_ratio)?;
        non_negative("joint_merge_z", self.joint_merge_z)?;
        non_negative("pair_hold", self.pair_hold)?;
        non_negative("pair_rejoin_ratio", self.pair_rejoin_ratio)?;
        non_negative("glitch_factor", self.glitch_factor)?;
        non_negative("near_joint_fraction", self.near_joint_fraction)?;
        if self.groups.iter().any(Vec::is_empty) {
            return Err(bad(
                "groups",
                format!("{:?}", self.groups),
                "every group must name at least one marker",
            ));
        }
        Ok(())
    }
}
