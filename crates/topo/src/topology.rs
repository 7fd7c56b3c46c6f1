//! The topo stage's artifact: the tree of segments.

use serde::{Deserialize, Serialize};

/// Schema version of [`Topology`]; bump when its fields or the algorithm's output change.
pub const SCHEMA_VERSION: u32 = 9;

/// A tree over the segments: a root and one joint per edge, parent to child.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Topology {
    /// Segment at the root of the tree.
    pub root_segment: usize,
    /// Joints in breadth-first order from the root: every parent before its children.
    pub joints: Vec<TreeJoint>,
    /// Segments not connected to the tree (no usable pair fit), if any.
    pub detached_segments: Vec<usize>,
    /// Things a user should know about the tree, in words (rigid pairs joined, detached
    /// segments and why, a forced root).
    #[serde(default)]
    pub notes: Vec<String>,
    /// Every body the capture holds, where it holds more than one (two subjects, or a
    /// subject and a prop): each body's segments ascending, biggest body first; empty for
    /// one. Pairs from one body to another are no joint (`Params::max_residual_ratio`).
    #[serde(default)]
    pub bodies: Vec<Vec<usize>>,
    /// Index in `bodies` of the body the tree spans; `None` where `bodies` is empty or
    /// holds none of the tree's segments.
    #[serde(default)]
    pub body: Option<usize>,
}

/// The name of the `k`-th body (0-based, biggest first, [`Topology::bodies`]) of a
/// capture that holds several: "body1", "body2", ...
pub fn body_name(k: usize) -> String {
    format!("body{}", k + 1)
}

/// One edge of the tree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TreeJoint {
    /// Joint name, shared by skeleton.json and the BVH: `j<child_segment>`.
    pub name: String,
    /// Segment nearer the root.
    pub parent_segment: usize,
    /// Segment farther from the root.
    pub child_segment: usize,
    /// Index of the pair's fit in `PairFits::pairs`.
    pub pair: usize,
    /// Index in `joints` of the joint at the parent segment's own proximal end; `None` when
    /// the parent is the root segment.
    pub parent_joint: Option<usize>,
    /// The pair's cost (`PairFit::cost`) that put this edge in the tree.
    #[serde(default)]
    pub cost: f64,
    /// The pair that would join the tree's two sides again were this edge left out;
    /// `None` when no pair with a finite cost crosses.
    #[serde(default)]
    pub runner_up: Option<RunnerUp>,
    /// Whether `topo.joints` named this pair: the user's choice, which the data's doubts
    /// (its runner-up, a better anchor) do not question.
    #[serde(default)]
    pub named: bool,
}

/// The cheapest pair across a tree edge's cut other than the edge itself: where its cost
/// is near the edge's (or below it, where a rule chose the edge against the costs), the
/// data hardly decide between the two trees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunnerUp {
    /// Its segment on the parent's side of the cut.
    pub parent_side: usize,
    /// Its segment on the child's side.
    pub child_side: usize,
    /// Index of its fit in `PairFits::pairs`.
    pub pair: usize,
    /// Its cost (`PairFit::cost`).
    pub cost: f64,
}
