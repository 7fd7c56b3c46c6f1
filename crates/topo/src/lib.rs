//! topo: the tree of segments.
//!
//! Takes the segmentation and the jointfit stage's pair fits ([`jointfit::PairFits`]) and
//! gives a [`Topology`]: a minimum spanning tree over the pair costs (Kruskal, as the
//! Aguiar et al. paper does), a root segment, and one [`TreeJoint`] per tree edge in
//! breadth-first order from the root, parent before child.
//!
//! Choices, documented here because they shape every output downstream:
//! - Pairs whose cost is NaN or infinite are not edges (no usable fit). Segments left
//!   without an edge, and components other than the tree's, are `detached_segments`.
//! - Where the pairs that fit a joint (residual within `max_residual_ratio` times the
//!   typical joint's, or within the longest segment that moves) leave the segments in
//!   several bodies (two subjects, or a subject and a prop), no pair from one body to
//!   another is an edge: the spanning tree would join them by one junk joint whose
//!   constant bone bends both. `bodies` lists them, biggest first; the tree spans the
//!   biggest, or the one `topo.body` names. The segment of the markers that never move
//!   (the room; segment's `stationary_segment`) joins a body only by a pair that fits
//!   as tightly as a typical joint (`stationary_residual_ratio`, `stationary_misfit`: a
//!   fixed base's), and alone it is the last body, never the tree's by default; in the
//!   tree it is the root (a fixed mechanism's ground link). So do bodies the segment stage
//!   saw move independently (segment's `bodies`: a prop let go of is no joint, while a
//!   limb that only sparse markers hold across its joint can be one).
//! - Pairs of kind `rigid` (no relative motion: the two are one body; the kind
//!   `PairFit::tree_kind` gives, like every kind the rules read) are taken before every
//!   other edge, because two segments that never move relative to each other are
//!   certainly neighbours; the topology's `notes` say so, since a rigid pair usually means
//!   the segmentation split one body in two.
//! - Near-ties in cost (within `tie_absolute + tie_relative × cost` of a run's cheapest
//!   edge) are taken in order of the pair's RMS relative rotation, smallest first: where
//!   segments meet at one point (siblings on one parent) every pair among them fits the
//!   point equally well, and the false sibling pair turns the most because its relative
//!   motion composes both true joints' motions. Exact ties after that go by the lower
//!   segment ids, so the tree is deterministic.
//! - A pair that looks like the composite of two joints through a third segment (both
//!   of those pairs about as cheap and both turning, and it turns clearly more than
//!   either: its motion composes theirs) is taken after them (`composite_rotation_ratio`,
//!   `composite_turn_share`): with skin, two clavicles on the sternum fit a common centre
//!   as well as each fits the thorax. "After them" is when they are taken: two siblings'
//!   pairs with a third sibling are composites too, and wait for the hub's joints.
//!   Kinds are stronger evidence than costs: a pair that is not a hinge, turning at least
//!   as much as two hinges through a third segment, is their composite even when they
//!   cost more (`composite_hinge_cost_ratio`; the kinds read with the costs, see
//!   `PairFit::tree_kind`): two hinges on one hub compose to two degrees of freedom, and
//!   were it a joint, one of those two pairs would compose its motion with another
//!   joint's and read as no hinge. Independence is evidence too
//!   (`composite_independence_margin`): two joints on one hub turn independently, so
//!   seen from the hub its two pairs' rotations do not correlate, while seen from either
//!   other segment of the three its two pairs share that segment's joint and do; a pair
//!   (b, c) whose third segment a sees its two pairs correlate clearly less than b and c
//!   see theirs is taken after a's, at costs alike (`composite_independence_cost_ratio`).
//! - Twins hang on one parent: a segment the tree hung on a segment built like it (what
//!   hangs below each is the same chain of at least two bones, bone lengths alike) moves
//!   to that segment's parent where their pair is a fair joint too (`twin_cost_ratio`,
//!   `twin_length_tolerance`): like limbs meet their body close together, so one clavicle
//!   or coxa can fit a centre with the other as well as with the body. Where the edge is
//!   cheap by construction (one of the two posed through it), the twin's own joint with
//!   the parent is the scale. A leaf hung on one of two twins that fits the other twin and
//!   their parent about as well (`twin_leaf_cost_ratio`) moves to the parent: it sits
//!   where the twins meet it, as a head between the clavicles, not on one twin's far side.
//!   A leaf posed through its joint with the twin (two markers: that pair is cheap by
//!   construction) moves when the parent's centre holds its markers next best, nearly as
//!   well (`twin_leaf_anchor_ratio`).
//! - Root: the segment of the markers that never move where the tree holds it (a fixed
//!   base), else the tree's centre (minimum eccentricity in hops), ties by the smaller sum
//!   of hops to every segment, then most markers, then the smaller mean distance to the
//!   other segments over the capture, then lowest id; it lands on the pelvis or torso of
//!   a human and the body of an animal, and not on whichever of two like centres the
//!   capture's marker order numbered first (the root shapes every chained pose below it).
//!   `topo.root` forces a segment, by id or by a marker's label (its component becomes the
//!   tree).
//! - `topo.joints` names pairs of segments the tree joins first, before rigid pairs; the
//!   rules above never move them. The data cannot always decide (a limb between like
//!   twins, a two-marker segment), and whoever put the markers on knows the body.
//! - Each joint names its runner-up ([`RunnerUp`]): the cheapest other pair across the cut
//!   the joint makes, the edge that would replace it. Where that costs little more than
//!   the joint, or less (a rule above chose the joint), the data hardly decide the tree
//!   there; export says so.
//!
//! It does not fit joints, bone lengths or rotations (jointfit and bonefit do), and does
//! no I/O.
mod error;
mod independence;
mod mst;
mod topology;
mod twins;

pub use error::Error;
pub use mst::{run, typical_joint_residual};
pub use topology::*;

use serde::{Deserialize, Serialize};

/// Name of this stage (cache keys, artifact headers).
pub const STAGE: &str = "topo";

/// Parameters of the topo stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Segment to force as the root; `None` (default) picks the tree's centre.
    pub root: Option<SegmentRef>,
    /// Where the capture holds several bodies, a segment of the one whose tree to build;
    /// `None` (default) builds the biggest's.
    pub body: Option<SegmentRef>,
    /// Take `rigid` pairs before all other edges (default true); false uses their cost as is.
    pub rigid_first: bool,
    /// Costs within this much (cost units, mm for `score`) of a run's cheapest cost are
    /// tied and taken by smallest relative rotation (default 0.1).
    pub tie_absolute: f64,
    /// Plus this fraction of the run's cheapest cost (default 0: on noisy data the
    /// sibling pair's cost is already higher, and a relative tie only reshuffled wrong trees).
    pub tie_relative: f64,
    /// A pair that turns at least this many times as much as both pairs through a third
    /// segment is their composite and is taken after them (default 1.1; 0 = off).
    pub composite_rotation_ratio: f64,
    /// ... when those two cost at most this many times as much as it (default 1.5).
    pub composite_cost_ratio: f64,
    /// ... and the quieter of those two turns at least this share of the other (default
    /// 0.4; 0 = any).
    pub composite_turn_share: f64,
    /// A pair that is not a hinge and turns at least as much as two hinges through a third
    /// segment, costing at most this many times as much as it, is their composite
    /// (default 3; 0 = off).
    pub composite_hinge_cost_ratio: f64,
    /// A pair (b, c) is the composite of a–b and a–c when a's two pairs' rotations
    /// correlate (in units of chance correlation) at least this much less than b's two
    /// pairs' and c's (default 2; 0 = off).
    pub composite_independence_margin: f64,
    /// ... and a–b and a–c cost at most this many times as much as it (default 1.5).
    pub composite_independence_cost_ratio: f64,
    /// A segment hung on a twin (what hangs below it is built like what else hangs below
    /// the twin) moves to the twin's parent when that pair costs at most this many times
    /// the edge it replaces (default 2; 0 = off).
    pub twin_cost_ratio: f64,
    /// Twins' bones agree within this share of the longer (default 0.4).
    pub twin_length_tolerance: f64,
    /// A leaf hung on one of two twins moves to their parent when its pairs with the
    /// parent and with the other twin each cost at most this many times its edge
    /// (default 3; 0 = off).
    pub twin_leaf_cost_ratio: f64,
    /// ... or, where the leaf is posed through its joint with that twin (its pair there
    /// cheap by construction), when the parent's centre holds its markers next best,
    /// within this many times that joint's radial residual (default 1.5; 0 = off).
    pub twin_leaf_anchor_ratio: f64,
    /// Pairs of segments the tree joins before any other edge, as the user knows them
    /// (default none).
    pub joints: Vec<[SegmentRef; 2]>,
    /// A pair whose fit residual exceeds this many times the typical joint's, and the
    /// longest segment, is no joint where that leaves the segments in several bodies
    /// (default 40; 0 = off; see [`typical_joint_residual`]).
    pub max_residual_ratio: f64,
    /// A pair with the segment of the markers that never move (the room; segment's
    /// `stationary_segment`), or between bodies the segment stage saw move independently
    /// (segment's `bodies`), is a joint only where its residual is at most this many times
    /// the typical joint's, or its misfit at most `stationary_misfit` (default 2; 0 = as
    /// any other pair; with `max_residual_ratio` 0 no pair is refused).
    pub stationary_residual_ratio: f64,
    /// ... or where its misfit over the poses' noise (jointfit's `misfit_over_noise`, about
    /// 1 for a joint that noise explains) is at most this (default 3).
    pub stationary_misfit: f64,
}

/// A segment as the user names it: by id, or by the label of a marker it holds (ids follow
/// the segmentation; a label names the same segment in every trial of a marker set).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum SegmentRef {
    /// The segment's id, as skeleton.json and the findings give it.
    Id(usize),
    /// The label of a marker of the segment (`*` patterns allowed where every marker they
    /// match is on that one segment).
    Marker(String),
}

impl<'de> Deserialize<'de> for SegmentRef {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        /// Reads an id or a label, saying which two forms a wrong value could have had.
        struct Either;
        impl serde::de::Visitor<'_> for Either {
            type Value = SegmentRef;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a segment id (0, 1, …) or the label of a marker on it (\"LKNE\")")
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<SegmentRef, E> {
                usize::try_from(v)
                    .map(SegmentRef::Id)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(v), &self))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<SegmentRef, E> {
                Ok(SegmentRef::Marker(v.to_owned()))
            }
        }
        d.deserialize_any(Either)
    }
}

impl std::fmt::Display for SegmentRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SegmentRef::Id(id) => write!(f, "{id}"),
            SegmentRef::Marker(label) => write!(f, "{label:?}"),
        }
    }
}

impl Default for Params {
    fn default() -> Self {
        Self {
            root: None,
            body: None,
            rigid_first: true,
            tie_absolute: 0.1,
            tie_relative: 0.0,
            composite_rotation_ratio: 1.1,
            composite_cost_ratio: 1.5,
            composite_turn_share: 0.4,
            composite_hinge_cost_ratio: 3.0,
            composite_independence_margin: 2.0,
            composite_independence_cost_ratio: 1.5,
            twin_cost_ratio: 2.0,
            twin_length_tolerance: 0.4,
            twin_leaf_cost_ratio: 3.0,
            twin_leaf_anchor_ratio: 1.5,
            joints: Vec::new(),
            max_residual_ratio: 40.0,
            stationary_residual_ratio: 2.0,
            stationary_misfit: 3.0,
        }
    }
}

/// Every parameter: (field name, "meaning, units, default").
pub const PARAM_DOCS: &[(&str, &str)] = &[
    (
        "joints",
        "[[a, b], ...]: pairs of segments, each by id (as the run's findings and skeleton.json \
         number them) or by the label of a marker on it (\"LKNE\": the same segment in every \
         trial of a marker set, where ids follow the segmentation), the tree joins before any \
         other edge, where you know the body better than the \
         data show (the findings say 'the tree could join segments a and b instead' where \
         they hardly decide); the rules after the spanning tree (twin_*) leave these joints \
         alone. An id the segmentation has not, a pair without a usable joint fit, or pairs \
         that close a loop are errors; default []",
    ),
    (
        "max_residual_ratio",
        "a pair whose fit residual (skeleton.json's residual_rms_mm: how far the two segments \
         disagree about their common centre) exceeds this many times the typical joint's, \
         and the capture's longest segment (the largest distance between two markers of one \
         segment), is not a joint and never an edge where that leaves the segments in \
         several bodies (two subjects, or a subject and a prop, in one capture), whose \
         junction would bend both skeletons; within one body nothing changes. The typical \
         joint's residual is the lower median over the edges of the pairs' plain minimum \
         spanning tree, and at least the capture's measurement noise (segment's noise_mm). \
         True joints stay below: each joint's residual over its tree's median in \
         skeleton.json is at most 14.6 on the real captures in ../shared/data (c3d.org \
         sample 34's body-model points, 24.8 mm against 1.7 mm) and 6.4 on the hard preset \
         (84 trials, seven subjects, seeds 20001-20012); segments of one or two markers go \
         further (up to 121 mm against a typical 0 on clean trials with 1-3 markers per \
         segment), which the longest segment bounds. cargo xtask eval on seeds \
         20001..20050,30001..30050 (hard, clean), 70001..70100 (hard), 20001..20050 (messy; \
         hard at 2-3 markers per segment) and 20001..20030 (clean, noise, skin, hard at 1-3) \
         gives the same trees as without it. Two hard synthetic subjects in one capture, \
         each walking its own circle (the 21 pairs of the seven kinds), come out as two \
         bodies in 21 cases 3 m apart, 19 at 1.2 m and 15 at 0.6 m; the other six are one \
         tree as before, their joint across 284-504 mm, 35-55 times its tree's median. A \
         pair topo.joints names is joined whatever its residual; dimensionless; 0 = off; \
         default 40",
    ),
    (
        "stationary_residual_ratio",
        "a pair with the segment of the markers that never move (floor and reference markers, \
         stray reflections; segment.stationary_jitter_factor) is a joint only where its \
         residual is at most this many times the typical joint's (see max_residual_ratio), \
         or its misfit over the poses' noise at most stationary_misfit: a fixed robot's base \
         turns its first link about an axis as truly as any joint does (a synthetic robot arm \
         held still by its base, cargo xtask synth --preset noise, seeds 7-9: 0.7-1.6 times, \
         misfit 0.97-1.04), while a subject on a treadmill, or walking a circle, keeps a point \
         nearly still in the room only up to its sway (OpenSim's subject01_walk1 beside six \
         floor markers: its trunk 3.9 times, misfit 16.4; a hard synthetic human walking its \
         circle: its pelvis 8.3 times, misfit 4.5). Where that leaves the room a body of its \
         own, no skeleton holds it. So is a pair between bodies the segment stage saw move \
         independently (segment.body_gap_ratio): three props beside OpenSim's \
         subject01_walk1 each stay a body of their own, where one hung on the pelvis by a \
         joint whose centres disagreed by 403 mm (within the 40 times the typical joint's \
         and the longest segment that other pairs may reach); two hard synthetic subjects \
         0.6 m apart (cargo xtask synth --preset hard --frames 480, seeds 7 and 8, the 21 \
         pairs of the seven kinds) come out as two bodies in 18 of 21, 17 before bodies \
         were told apart. \
         Dimensionless; 0 = as any other pair; default 2",
    ),
    (
        "stationary_misfit",
        "... or where its misfit over the poses' noise (jointfit's misfit_over_noise: the \
         disagreement about the centre against what the two poses' noise predicts, about 1 \
         for a joint that noise explains; 2.4 at most over the 1037 true tree joints of 105 hard \
         synthetic trials that have one, seeds 20001-20015 of each subject) is at most this; \
         dimensionless; default 3",
    ),
    (
        "body",
        "where the capture holds several bodies (two subjects, or a subject and a prop; see \
         max_residual_ratio), the one whose tree to build, by the id of a segment in it or the \
         label of a marker on it; `cargo xtask run` writes every other body's files into \
         <out>/body<k>/ with this set; default none: the biggest body (most segments, then \
         markers)",
    ),
    (
        "root",
        "segment forced as the tree's root, by id or by the label of a marker on it; default \
         none: the segment of the markers that never move where the tree holds it (a fixed \
         base: every other segment's motion is read in the room), else the tree's centre \
         (fewest hops to the farthest segment, ties by most markers, then lowest id)",
    ),
    (
        "rigid_first",
        "take pairs of kind rigid (no relative motion) before all other edges; default true",
    ),
    (
        "tie_absolute",
        "pair costs within tie_absolute + tie_relative x cost of a run's cheapest cost are \
         tied (cost units: mm for jointfit.method=score); tied pairs are taken by smallest \
         RMS relative rotation, so siblings meeting at one point are not joined to each \
         other; default 0.1",
    ),
    (
        "tie_relative",
        "fraction of the run's cheapest cost added to tie_absolute (dimensionless); \
         default 0",
    ),
    (
        "composite_rotation_ratio",
        "a pair (b, c) whose RMS relative rotation is at least this many times both of a-b's \
         and a-c's, for some third segment a whose two pairs cost at most \
         composite_cost_ratio x its cost, is the composite of those two joints (its motion \
         composes both) and is taken after them: where two joints are close (the clavicles \
         on the sternum) the composite can fit a centre as well as they do. Measured (cargo \
         xtask eval --presets clean,hard on 16 seeds, 4001-4006, 6001-6006, 7001, 9001, \
         1001, 5001): hard exact trees 69 -> 71/96, clean unchanged; on real captures \
         MACsample's thigh goes to the shank instead of the foot and Sample_Jump2's left \
         forearm to the left upper arm instead of the right arm. 1.2 -> 1.1 (with \
         composite_turn_share 0.4): a composite of a joint turning r1 and one turning r2 < r1 \
         turns about √(r1² + r2²), only 1.1 r1 at r2 = 0.47 r1 (human-hard-s30019: head-left \
         clavicle 44.4° against neck 38.8° and sternoclavicular 18.2°, which 1.2 let in \
         as the head's joint). cargo xtask eval --presets hard with --set \
         topo.composite_rotation_ratio=1.2 --set topo.composite_turn_share=0 (as before) \
         against the defaults: seeds 20001..20050,30001..30050 545 -> \
         548/700 trees (human 78 -> 81; 5 gained, 2 random trees lost), 1.4490 -> 1.4492 % \
         of height; 40001..40100 530 -> 536 (7 gained, 1 lost), 1.4486 -> 1.4477 %; \
         --true-segments on the first set 662 -> 664; seeds 20001..20020: noise 135 -> \
         136/140, skin 100 -> 101, --markers 2:3 51 -> 52, --sweep 0.2:0.4 21 -> 23, \
         --marker-arc 120 102 -> 100, messy 112 -> 112, clean, gaps and --markers 1:3 \
         unchanged (clean on the first set 700/700 both); 1.05 (without the share): 547 on the first set; \
         0 = off; default 1.1",
    ),
    (
        "composite_cost_ratio",
        "see composite_rotation_ratio: how much dearer (times) the two pairs through the \
         third segment may be; default 1.5",
    ),
    (
        "composite_turn_share",
        "see composite_rotation_ratio: the quieter of the two pairs through the third \
         segment must turn at least this share of the other. Where one barely turns (the \
         third segment nearly rigid with one of the two), the pair across it turns about as \
         much as the other joint whichever is the composite, and the rotations cannot say \
         which: MACsample's left thigh turns 15.9° on the pelvis and 14.1° on a torso \
         segment that turns 5.2° on the pelvis (share 0.37), and at ratio 1.1 without this \
         the true hip was taken for the composite. cargo xtask eval --presets hard with \
         ratio 1.1: shares 0 / 0.3 / 0.4 / 0.5 give 548 / 548 / 548 / 546 exact trees of \
         700 on seeds 20001..20050,30001..30050 and 536 / 536 / 536 / 536 on \
         40001..40100; dimensionless; 0 = any; default 0.4",
    ),
    (
        "composite_hinge_cost_ratio",
        "a pair (b, c) that is not a hinge (ball or universal) and turns at least as much as \
         both a-b and a-c, where both of those are hinges costing at most this many times \
         its cost, is their composite and is taken after them: two hinges on one hub with \
         different axes compose to two degrees of freedom, and were b-c a joint, a-b or a-c \
         would compose its motion with another joint's and read as no hinge; the kinds hold \
         where costs, pulled by skin on a poorly posed hub, do not. Measured \
         (cargo xtask eval --presets hard, seeds 20001-20050 and 30001-30050, every subject): \
         exact trees 427 -> 434/600 (random 67 -> 74), none lost; on 16 seeds (4001-4006, \
         6001-6006, 7001, 9001, 1001, 5001) hard 76 -> 77, skin 64 -> 66, messy 74 -> 75, \
         clean unchanged; seeds 10001-10032 hard 146 -> 147, noise 188 -> 189, skin 133 -> \
         135/192; an offline copy of this stage over the same pair fits gains the same trees \
         at 2 to 5 and loses two human trees at 100; 0 = off; default 3",
    ),
    (
        "composite_independence_margin",
        "a pair (b, c) is the composite of a-b and a-c, and is taken after them, when those \
         two cost at most composite_independence_cost_ratio x its cost, the quieter of them \
         turns at least composite_turn_share of the other, and a's two pairs' rotations \
         correlate at least this much less than b's two pairs' and c's: two joints on one \
         hub turn independently, while seen from either other segment its two pairs share \
         that segment's joint (the pair to the hub is that joint's motion, the pair to the \
         other segment composes it with the other joint). Correlation: each pair's rotation \
         relative to the hub (rotation vector about its mean, in the hub's frame), trace \
         form, over the RMS of the same correlation with one series shifted by 10-40 % of \
         the frames, since smooth motions of a few cycles correlate by chance that much \
         (at most 600 frames read, at a stride beyond). It decides where the costs favour \
         the sibling pair and the rotations' sizes cannot tell: in random-hard-s30029 \
         (true segments) seg00 and seg02 both hang on seg01 (pairs cost 17.05 and 7.67, \
         turning 27.9 and 37.7 deg RMS), yet the sibling pair costs 15.50 and turns only \
         29.4 deg, so the tree hung seg00 on seg02. cargo xtask eval --presets hard, cost \
         ratio 1.5: seeds 20001..20050,30001..30050 \
         --true-segments margins 1.5 / 2 / 3 give 676 / 676 / 674 exact trees of 700 (674 \
         off: hexapod s20048, random s30029 gained, none lost); at margin 2 the pipeline's \
         segments 558 -> 559, 40001..40100 543 -> 543, 50001..50100 547 -> 548, none lost; \
         on the first seeds --frames 2400 578 -> 577 (random-hard-s30018: a sibling pair \
         the score accepts as coincident joints, seg01-seg12, given up for seg03-seg01, \
         which it does not), and clean, --markers 4:8 and, on 20001..20050, skin, messy, \
         noise and --markers 2:3 the same trees; \
         the plain correlation (no chance units) at margin 0.3 gained as many but lost \
         random-hard-s40097 (its true hub's two pairs correlating 0.49) and \
         snake-hard-s50042. Skin that moves a small segment's markers with its \
         neighbour's joint angle correlates its pose error with that joint, the limit of \
         this evidence: a hexapod's coxa turning 9.2 deg on the body reads as independent \
         of its femur seen from the body (hexapod-hard-s20005), and at cost ratio 2 / 3 \
         two / four hexapod trees are lost (--true-segments, margin 2). Dimensionless (chance \
         correlations); 0 = off; default 2",
    ),
    (
        "composite_independence_cost_ratio",
        "see composite_independence_margin: how much dearer (times) the two pairs through \
         the third segment may be. Wider, the rule reaches real motion, whose joints do not \
         turn independently (a walk, a jump or a dance moves hip, knee and ankle with one \
         rhythm): at 3 the synthetic suites gain and lose nothing (cargo xtask eval \
         --presets hard --set topo.composite_independence_cost_ratio=3: seeds \
         20001..20050,30001..30050 559 -> 561, 40001..40100 543 -> 544, 50001..50100 548 -> \
         550, the first seeds at --frames 240 500 -> 506), but 11 real captures' trees \
         change (five trials): c3d.org's Dance hangs a foot plate (Channel129) on the pelvis \
         plate (Channel113) instead of the thigh (Channel121), and Sample_Jump2 gives up its \
         pelvis-right thigh joint for pelvis-left foot (Eb015's and AlbertoINT's trees change \
         for the better); default 1.5",
    ),
    (
        "twin_cost_ratio",
        "after the spanning tree, a segment Y hung on a segment X is moved to X's parent P \
         when what hangs below Y is built like what else hangs below X (the same chain of \
         at least two bones, no branching, bones alike within twin_length_tolerance) and \
         the pair P-Y costs at \
         most this many times X-Y: like limbs meet their body close together and fit a \
         centre with each other about as well as with it. cargo xtask eval --presets hard \
         --compare topo.twin_cost_ratio=0,1.5,2,3: seeds 20001..20050,30001..30050 550 -> \
         551 / 552 / 552 exact trees of 700 (human s20022, s20037: a clavicle on the \
         other), 1.3935 -> 1.3937 % of height at 2; --true-segments 668 -> 671 (hexapod \
         coxae on each other); seeds 40001..40100 535 -> 537 at 2 (human s40027, s40042); \
         no tree lost; 20001..20020 --marker-arc 120 102 -> 103, --markers 2:3 \
         --true-segments 87 -> 88, and noise, skin, messy, gaps, --markers 2:3 and --sweep \
         0.2:0.4 the same trees, clean on 20001..20050,30001..30050 too; every real capture's \
         skeleton.json unchanged. Where X or Y is posed through the X-Y joint (two markers \
         and its centre: that cost is low by construction), the bound is this many times \
         the larger of X-Y and X's own joint with P (a twin hung on P costs about what its \
         twin's joint there does): --markers 2:3, seeds 20001..20050,30001..30050 283 -> \
         292 exact trees, 40001..40100 279 -> 284, 50001..50100 297 -> 301 (humans: a \
         two-marker clavicle posed through the other), --true-segments 439 -> 448, no tree \
         lost; at the default 3-6 markers every trial of the three seed sets identical; \
         0 = off; default 2",
    ),
    (
        "twin_leaf_cost_ratio",
        "after the twins move, a leaf L hung on one of two twins X, Y (siblings on P, built \
         alike as twin_cost_ratio reads them, leaves like L aside) moves to P when its pairs \
         with P and with Y each cost at most this many times its pair with X: a segment \
         hung on a limb sits at its far side, away from the mirror twin; one that fits both \
         twins and P alike sits where the twins meet P (a head between the clavicles, which \
         also hid the clavicles' twinship). cargo xtask eval --presets hard --compare \
         topo.twin_leaf_cost_ratio=0,1.5,2,3,5,10, seeds 20001..20050,30001..30050: 552 / \
         554 / 555 / 555 / 555 / 554 exact trees of 700 (human s20019, s20046, s20049; 10 \
         loses random-hard-s20002), 1.3937 -> 1.3935 % of height at 3; 3 is the middle of \
         that flat run; --true-segments 671 -> 674 at 2 and 3; seeds 40001..40100 537 -> \
         538 at 2, 539 at 3 (human s40017, s40070), --true-segments 663 -> 666 at 2, 667 at \
         3; seeds 50001..50100, on which nothing was chosen, 539 -> 544 at 3 (five \
         humans); no tree lost; on 20001..20020 skin 101 -> 102 and messy 112 -> 113 \
         (human s20019), noise, gaps, --markers 2:3 (also with --true-segments), --marker-arc 120 and --sweep \
         0.2:0.4 the same trees (the sweep's mean 3.6793 -> 3.6808 %), clean on \
         20001..20050,30001..30050 700/700 and 0.0581 % as before; every real capture's \
         skeleton.json unchanged; 0 = off; default 3",
    ),
    (
        "twin_leaf_anchor_ratio",
        "see twin_leaf_cost_ratio: a leaf posed through its joint with the twin it hangs on \
         (two markers, say: jointfit's pair there is cheap by construction, so no other pair \
         of the leaf's costs as little) moves to the twins' parent when the parent's centre \
         holds its markers next best (PairFit::next_best_anchor), within this many times \
         the chosen joint's radial residual. human-hard-s30020 at --markers 2:3 with the \
         true segments: the head posed through the right clavicle at a radial residual of \
         5.41 mm, the thorax next best at 6.88 (1.27 times); its pairs with the thorax and the left clavicle cost 3.20 \
         and 5.27 times the head's edge, beyond twin_leaf_cost_ratio. 0 = off; default 1.5",
    ),
    (
        "twin_length_tolerance",
        "see twin_cost_ratio: two twins' corresponding bones (joint to joint, in the \
         segment's frame) differ by at most this share of the longer. A hinge's centre \
         sits anywhere along its axis before bonefit places it, so bones read here are \
         loose. cargo xtask eval --presets hard, seeds 20001..20050,30001..30050: \
         --true-segments 0.25 / 0.4 / 0.6 give 670 / 671 / 671 exact trees \
         (hexapod-hard-s30046's twins differ by 0.27); the pipeline's segments 0.4 / 0.6 / \
         1 (bones unchecked) 552 / 552 / 551 (random-hard-s30046 lost), at 0.3 551 \
         (human-hard-s20037's clavicle twins lost). Seeds 40001..40100 --true-segments: \
         661 -> 663 at 0.4 (3 gained; random-hard-s40010 lost, two 2-bone chains alike by \
         chance), 663 at 0.3 and 0.25 (2 gained, none lost); dimensionless; default 0.4",
    ),
];
