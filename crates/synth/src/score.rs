//! Scoring a pipeline result (skeleton.json) against a trial's truth.
//!
//! Conventions:
//! - Segmentation: adjusted Rand index over the truth's markers. A marker the estimate
//!   leaves unassigned (or does not mention) counts as a cluster of its own, so leaving
//!   markers out costs agreement; labels the truth does not know are ignored.
//! - Each estimated segment maps to the true segment holding most of its markers (ties
//!   to the lower index); a segment with no known marker maps to nothing.
//! - An estimated joint matches a true joint when its two segments map to that joint's
//!   two segments, in either order (edges are undirected). Each true joint is matched at
//!   most once, by the first estimated joint that maps to it.
//! - Coincident joints: true joints whose centres coincide in every frame (a random tree
//!   hangs several children on one parent's tip) make every tree over their segments
//!   kinematically identical: with children C1, C2 both at P's tip, C2 turns about the
//!   same point whether it hangs on P or on C1, so no motion can tell. An estimated joint
//!   left unmatched above whose two segments map into one such group takes an unmatched
//!   true joint of the group (counted in `equivalent_joints`; its centre is scored, its
//!   kind is not, the kind of a pair that is not a true joint being undefined).
//! - Joint error: distance between matched joints' centres over frames where both are
//!   known, pooled over all matched joints: mean and worst, mm and % of `height_mm`.
//! - Bone-length constancy: for every estimated joint whose parent segment is the child
//!   of another estimated joint, the std (population) over frames of the distance
//!   between the two centres; mean over such bones, mm.

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{Error, Truth};

/// A pipeline result as written to skeleton.json (the DESIGN.md output contract);
/// unknown fields are ignored.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// Length unit of `positions`: "mm" (default), "cm" or "m".
    #[serde(default = "millimetres")]
    pub units: String,
    /// Frames per second.
    #[serde(default)]
    pub frame_rate: f64,
    /// Number of frames.
    #[serde(default)]
    pub frame_count: usize,
    /// Estimated segments.
    pub segments: Vec<EstimatedSegment>,
    /// Markers in no segment.
    #[serde(default)]
    pub unassigned_markers: Vec<String>,
    /// Id of the root segment.
    #[serde(default)]
    pub root_segment: Option<usize>,
    /// Estimated joints.
    #[serde(default)]
    pub joints: Vec<EstimatedJoint>,
}

fn millimetres() -> String {
    "mm".into()
}

/// An estimated segment: an id (referenced by joints) and its marker labels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatedSegment {
    /// Segment id.
    pub id: usize,
    /// Marker labels.
    pub markers: Vec<String>,
}

/// An estimated joint between two segments (by id), with its centre per frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatedJoint {
    /// Joint name.
    pub name: String,
    /// Parent segment id.
    pub parent_segment: usize,
    /// Child segment id.
    pub child_segment: usize,
    /// "ball", "hinge", or anything else (counted as not a hinge).
    #[serde(default)]
    pub kind: String,
    /// Centre per frame in `units`, global frame; `None` where unknown.
    #[serde(default)]
    pub positions: Vec<Option<[f64; 3]>>,
}

impl Estimate {
    /// A perfect estimate built from the truth: its segments, joints and centres.
    pub fn from_truth(truth: &Truth) -> Self {
        Self {
            units: "mm".into(),
            frame_rate: truth.frame_rate,
            frame_count: truth.frame_count,
            segments: truth
                .segments
                .iter()
                .enumerate()
                .map(|(id, s)| EstimatedSegment {
                    id,
                    markers: s.markers.clone(),
                })
                .collect(),
            unassigned_markers: Vec::new(),
            root_segment: Some(truth.root_segment),
            joints: truth
                .joints
                .iter()
                .map(|j| EstimatedJoint {
                    name: j.name.clone(),
                    parent_segment: j.parent_segment,
                    child_segment: j.child_segment,
                    kind: j.kind.clone(),
                    positions: j.positions.iter().map(|p| Some(*p)).collect(),
                })
                .collect(),
        }
    }

    /// Millimetres per unit of `positions`.
    pub fn scale(&self) -> f64 {
        match self.units.trim().to_ascii_lowercase().as_str() {
            "cm" => 10.0,
            "m" => 1000.0,
            _ => 1.0,
        }
    }
}

/// Reads a skeleton.json file as an [`Estimate`].
pub fn read_estimate(path: &Path) -> Result<Estimate, Error> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
        path: path.to_path_buf(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|source| Error::Json {
        path: path.to_path_buf(),
        what: "skeleton",
        source,
    })
}

/// How one matched joint did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointScore {
    /// The true joint's name.
    pub truth: String,
    /// The estimated joint's name.
    pub estimate: String,
    /// Mean centre error over frames where both are known, mm (`None` if no such frame).
    pub mean_mm: Option<f64>,
    /// Worst centre error, mm.
    pub worst_mm: Option<f64>,
    /// Share of the truth's frames where the estimate is known.
    pub known_fraction: f64,
    /// Whether hinge vs not-hinge agrees; `None` for an `equivalent` match, whose
    /// estimated pair is not a true joint and so has no true kind.
    pub kind_correct: Option<bool>,
    /// Matched through a group of coincident true joints, not by its own segments.
    #[serde(default)]
    pub equivalent: bool,
}

/// Agreement of an estimate with the truth (see the module docs for definitions).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Adjusted Rand index of the marker segmentation (1 = identical, ~0 = chance).
    pub ari: f64,
    /// Number of true segments.
    pub true_segments: usize,
    /// Number of estimated segments.
    pub estimated_segments: usize,
    /// Truth markers the estimate assigns to no segment.
    pub unassigned_markers: usize,
    /// Number of true joints.
    pub true_joints: usize,
    /// Number of estimated joints.
    pub estimated_joints: usize,
    /// Estimated joints matching a true joint (each true joint once).
    pub matched_joints: usize,
    /// Of those, matched through a group of coincident true joints (see the module docs).
    #[serde(default)]
    pub equivalent_joints: usize,
    /// matched / estimated joints (1 when the estimate has none).
    pub topology_precision: f64,
    /// matched / true joints (1 when the truth has none).
    pub topology_recall: f64,
    /// Precision and recall both 1.
    pub topology_exact: bool,
    /// The estimated root maps to the true root.
    pub root_correct: bool,
    /// Mean joint-centre error over matched joints and frames, mm.
    pub joint_error_mean_mm: Option<f64>,
    /// Worst joint-centre error, mm.
    pub joint_error_worst_mm: Option<f64>,
    /// Mean error as % of the truth's `height_mm`.
    pub joint_error_mean_pct: Option<f64>,
    /// Worst error as % of the truth's `height_mm`.
    pub joint_error_worst_pct: Option<f64>,
    /// Share of (matched joint, frame) pairs where the estimated centre is known.
    pub known_fraction: f64,
    /// Mean over estimated bones of the std of bone length over frames, mm.
    pub bone_length_std_mm: Option<f64>,
    /// Share of matched joints whose kind (hinge or not) agrees.
    pub kind_accuracy: Option<f64>,
    /// Per matched joint, in truth joint order.
    pub joints: Vec<JointScore>,
}

impl fmt::Display for Score {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let opt = |v: Option<f64>, digits: usize| {
            v.map_or_else(|| "-".to_string(), |x| format!("{x:.digits$}"))
        };
        write!(
            f,
            "ARI {:.3} | segments {}/{} | topology P {:.2} R {:.2} {}{} | joints {}/{} err mean {} mm ({} %) worst {} mm ({} %) | known {:.2} | bone std {} mm | kind {}",
            self.ari,
            self.estimated_segments,
            self.true_segments,
            self.topology_precision,
            self.topology_recall,
            if self.topology_exact {
                "exact"
            } else {
                "inexact"
            },
            if self.equivalent_joints > 0 {
                format!(" ({} by coincident joints)", self.equivalent_joints)
            } else {
                String::new()
            },
            self.matched_joints,
            self.true_joints,
            opt(self.joint_error_mean_mm, 1),
            opt(self.joint_error_mean_pct, 2),
            opt(self.joint_error_worst_mm, 1),
            opt(self.joint_error_worst_pct, 2),
            self.known_fraction,
            opt(self.bone_length_std_mm, 2),
            opt(self.kind_accuracy, 2),
        )
    }
}

/// Groups (≥ 2, ascending) of true joints whose centres coincide within 1 µm in every frame.
fn coincident_groups(truth: &Truth) -> Vec<Vec<usize>> {
    let n = truth.joints.len();
    let mut group: Vec<usize> = (0..n).collect();
    for j in 0..n {
        for k in (j + 1)..n {
            let (pj, pk) = (&truth.joints[j].positions, &truth.joints[k].positions);
            let same = !pj.is_empty()
                && pj.len() == pk.len()
                && pj.iter().zip(pk).all(|(a, b)| {
                    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2) <= 1e-6
                });
            if same {
                let (from, to) = (group[k], group[j]);
                for g in &mut group {
                    if *g == from {
                        *g = to;
                    }
                }
            }
        }
    }
    let mut out: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (j, g) in group.into_iter().enumerate() {
        out.entry(g).or_default().push(j);
    }
    out.into_values().filter(|g| g.len() >= 2).collect()
}

/// Adjusted Rand index of two labellings of the same items.
fn adjusted_rand_index(a: &[usize], b: &[usize]) -> f64 {
    let n = a.len();
    if n < 2 {
        return 1.0;
    }
    let mut table: BTreeMap<(usize, usize), u64> = BTreeMap::new();
    let mut rows: BTreeMap<usize, u64> = BTreeMap::new();
    let mut cols: BTreeMap<usize, u64> = BTreeMap::new();
    for (&x, &y) in a.iter().zip(b) {
        *table.entry((x, y)).or_default() += 1;
        *rows.entry(x).or_default() += 1;
        *cols.entry(y).or_default() += 1;
    }
    let pairs = |c: u64| (c * c.saturating_sub(1) / 2) as f64;
    let index: f64 = table.values().map(|&c| pairs(c)).sum();
    let sum_a: f64 = rows.values().map(|&c| pairs(c)).sum();
    let sum_b: f64 = cols.values().map(|&c| pairs(c)).sum();
    let total = pairs(n as u64);
    let expected = sum_a * sum_b / total;
    let max = 0.5 * (sum_a + sum_b);
    if (max - expected).abs() < 1e-12 {
        // Both partitions all-singletons or all-one-cluster: agreement is all or nothing.
        return if (index - expected).abs() < 1e-12 {
            1.0
        } else {
            0.0
        };
    }
    (index - expected) / (max - expected)
}

/// Scores an estimate against the truth.
pub fn score(truth: &Truth, estimate: &Estimate) -> Score {
    // Truth marker → true segment.
    let mut true_of: BTreeMap<&str, usize> = BTreeMap::new();
    for (s, seg) in truth.segments.iter().enumerate() {
        for m in &seg.markers {
            true_of.insert(m.as_str(), s);
        }
    }
    // Estimated marker → position of its segment in `estimate.segments` (first wins).
    let mut est_of: BTreeMap<&str, usize> = BTreeMap::new();
    for (e, seg) in estimate.segments.iter().enumerate() {
        for m in &seg.markers {
            est_of.entry(m.as_str()).or_insert(e);
        }
    }
    let singles = estimate.segments.len();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut unassigned = 0;
    for (i, (label, &t)) in true_of.iter().enumerate() {
        a.push(t);
        match est_of.get(label) {
            Some(&e) => b.push(e),
            None => {
                unassigned += 1;
                b.push(singles + i);
            }
        }
    }
    let ari = adjusted_rand_index(&a, &b);

    // Estimated segment id → true segment by majority of its markers.
    let mut maps_to: BTreeMap<usize, usize> = BTreeMap::new();
    for seg in &estimate.segments {
        let mut votes: BTreeMap<usize, usize> = BTreeMap::new();
        for m in &seg.markers {
            if let Some(&t) = true_of.get(m.as_str()) {
                *votes.entry(t).or_default() += 1;
            }
        }
        // max_by_key keeps the last maximum: iterate in reverse to prefer the lower index.
        if let Some((&t, _)) = votes.iter().rev().max_by_key(|(_, c)| **c) {
            maps_to.entry(seg.id).or_insert(t);
        }
    }
    let edge = |p: usize, c: usize| (p.min(c), p.max(c));
    let true_edges: BTreeMap<(usize, usize), usize> = truth
        .joints
        .iter()
        .enumerate()
        .map(|(j, tj)| (edge(tj.parent_segment, tj.child_segment), j))
        .collect();
    // True joint → estimated joint.
    let mut matched: BTreeMap<usize, usize> = BTreeMap::new();
    let mut mapped_edges = Vec::new();
    for (e, ej) in estimate.joints.iter().enumerate() {
        let (Some(&p), Some(&c)) = (
            maps_to.get(&ej.parent_segment),
            maps_to.get(&ej.child_segment),
        ) else {
            continue;
        };
        if p == c {
            continue;
        }
        mapped_edges.push((e, p, c));
        if let Some(&t) = true_edges.get(&edge(p, c)) {
            matched.entry(t).or_insert(e);
        }
    }
    // Estimated joints left over, matched within groups of coincident true joints.
    let groups = coincident_groups(truth);
    let mut equivalent = std::collections::BTreeSet::new();
    for (e, p, c) in mapped_edges {
        // A duplicate of a true edge (a true segment split in two, both halves hung on
        // one neighbour) is an extra joint, not a re-hung one.
        if matched.values().any(|&m| m == e) || true_edges.contains_key(&edge(p, c)) {
            continue;
        }
        let in_group = |g: &Vec<usize>| {
            let touches = |s: usize| {
                g.iter().any(|&j| {
                    truth.joints[j].parent_segment == s || truth.joints[j].child_segment == s
                })
            };
            touches(p) && touches(c)
        };
        let free = groups
            .iter()
            .filter(|g| in_group(g))
            .flat_map(|g| g.iter().copied())
            .find(|t| !matched.contains_key(t));
        if let Some(t) = free {
            matched.insert(t, e);
            equivalent.insert(t);
        }
    }
    let est_joints = estimate.joints.len();
    let true_joints = truth.joints.len();
    let precision = if est_joints == 0 {
        1.0
    } else {
        matched.len() as f64 / est_joints as f64
    };
    let recall = if true_joints == 0 {
        1.0
    } else {
        matched.len() as f64 / true_joints as f64
    };

    // Joint errors over matched joints, serial sums in truth order for stable bytes.
    let scale = estimate.scale();
    let frames = truth.frame_count;
    let (mut sum, mut count, mut worst) = (0.0, 0usize, f64::NEG_INFINITY);
    let mut known = 0usize;
    let mut kind_ok = 0usize;
    let mut joints = Vec::new();
    for (&t, &e) in &matched {
        let tj = &truth.joints[t];
        let ej = &estimate.joints[e];
        let (mut js, mut jc, mut jw) = (0.0, 0usize, f64::NEG_INFINITY);
        for (tp, ep) in tj.positions.iter().zip(&ej.positions) {
            let Some(ep) = ep.filter(|p| p.iter().all(|c| c.is_finite())) else {
                continue;
            };
            let d = ((ep[0] * scale - tp[0]).powi(2)
                + (ep[1] * scale - tp[1]).powi(2)
                + (ep[2] * scale - tp[2]).powi(2))
            .sqrt();
            js += d;
            jc += 1;
            jw = jw.max(d);
        }
        sum += js;
        count += jc;
        worst = worst.max(jw);
        known += jc;
        let is_equivalent = equivalent.contains(&t);
        let kind_correct = (!is_equivalent).then(|| (tj.kind == "hinge") == (ej.kind == "hinge"));
        kind_ok += usize::from(kind_correct == Some(true));
        joints.push(JointScore {
            truth: tj.name.clone(),
            estimate: ej.name.clone(),
            mean_mm: (jc > 0).then(|| js / jc as f64),
            worst_mm: (jc > 0).then_some(jw),
            known_fraction: if frames == 0 {
                0.0
            } else {
                jc as f64 / frames as f64
            },
            kind_correct,
            equivalent: is_equivalent,
        });
    }
    let mean = (count > 0).then(|| sum / count as f64);
    let worst = (count > 0).then_some(worst);
    let pct = |v: Option<f64>| {
        v.filter(|_| truth.height_mm > 0.0)
            .map(|x| 100.0 * x / truth.height_mm)
    };

    // Bones: estimated joint pairs (parent joint → joint) through a shared segment.
    let mut bone_stds = Vec::new();
    for ej in &estimate.joints {
        let Some(parent) = estimate
            .joints
            .iter()
            .find(|k| k.child_segment == ej.parent_segment)
        else {
            continue;
        };
        let lengths: Vec<f64> = ej
            .positions
            .iter()
            .zip(&parent.positions)
            .filter_map(|(a, b)| {
                let (a, b) = ((*a)?, (*b)?);
                let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                    .sqrt()
                    * scale;
                d.is_finite().then_some(d)
            })
            .collect();
        if lengths.len() >= 2 {
            let m = lengths.iter().sum::<f64>() / lengths.len() as f64;
            let var = lengths.iter().map(|l| (l - m).powi(2)).sum::<f64>() / lengths.len() as f64;
            bone_stds.push(var.sqrt());
        }
    }

    let root_correct = match (estimate.root_segment, maps_to.is_empty()) {
        (Some(r), false) => maps_to.get(&r) == Some(&truth.root_segment),
        _ => false,
    };
    Score {
        ari,
        true_segments: truth.segments.len(),
        estimated_segments: estimate.segments.len(),
        unassigned_markers: unassigned,
        true_joints,
        estimated_joints: est_joints,
        matched_joints: matched.len(),
        equivalent_joints: equivalent.len(),
        topology_precision: precision,
        topology_recall: recall,
        topology_exact: matched.len() == est_joints && matched.len() == true_joints,
        root_correct,
        joint_error_mean_mm: mean,
        joint_error_worst_mm: worst,
        joint_error_mean_pct: pct(mean),
        joint_error_worst_pct: pct(worst),
        known_fraction: if matched.is_empty() || frames == 0 {
            0.0
        } else {
            known as f64 / (matched.len() * frames) as f64
        },
        bone_length_std_mm: (!bone_stds.is_empty())
            .then(|| bone_stds.iter().sum::<f64>() / bone_stds.len() as f64),
        kind_accuracy: (matched.len() > equivalent.len())
            .then(|| kind_ok as f64 / (matched.len() - equivalent.len()) as f64),
        joints,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ari_of_known_partitions() {
        assert_eq!(adjusted_rand_index(&[0, 0, 1, 1], &[5, 5, 7, 7]), 1.0);
        // Hubert–Arabie by hand: index 1, expected 2·1/6, max 1.5 → 4/7.
        let v = adjusted_rand_index(&[0, 0, 1, 1], &[0, 0, 1, 2]);
        assert!((v - 0.571_428_571_4).abs() < 1e-9, "{v}");
        // Crossed partitions share no pair: index 0, expected 6·3/15 = 1.2, max 4.5 → −4/11.
        let v = adjusted_rand_index(&[0, 0, 0, 1, 1, 1], &[0, 1, 2, 0, 1, 2]);
        assert!((v + 4.0 / 11.0).abs() < 1e-9, "{v}");
    }
}
