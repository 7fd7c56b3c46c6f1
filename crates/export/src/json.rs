//! skeleton.json: the output contract's fields first, quality fields beside them.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::{Error, Inputs};

/// Below this range of motion (degrees) a joint centre is poorly determined.
const LOW_RANGE_OF_MOTION_DEG: f64 = 20.0;

/// Above this centre misfit (degrees, [`centre_misfit_deg`]) the two segments may not turn
/// about one point. Joints of the real captures in ../shared/data whose tree is right stay
/// at or under 5.5° (CMU 02_01 at most 1.2°); the PhoeniX dance (c3d.org sample 13), which has
/// no shank or forearm markers, joins thigh to foot and upper arm to hand at 6.9-18.7°
/// (three of the four above this), and CMU 49_04's cluster of an upper-arm, a sternum and a
/// shoulder marker sits at 9°. Synthetic skin of 5-15 mm on segments a few centimetres
/// across goes further: 1.7 % of the hard preset's true joints (16 seeds) are above it.
const CENTRE_MISFIT_WARN_DEG: f64 = 8.0;

/// Above this [`jointfit::centre_gain`] a ball or universal joint turned about one axis
/// almost only, and its centre along that axis is hardly fixed (bonefit's default
/// `hinge_free_gain`, where a hinge's axis counts as a free line). The synthetic hard
/// trials' ball joints turning every way are at 2–6; the real captures' ball joints, mostly
/// walks, at 10–20 for three in four (129 of 174 above 10), which the warning would drown.
const LOOSE_CENTRE_GAIN: f64 = 20.0;

/// Above this share of the capture's size ([`capture_extent_mm`]), a joint centre's
/// distance to the nearest marker of its two segments means the data did not place it: a
/// real joint sits among its segments' markers. Over 63 hard trials (seven subjects, three
/// seeds, 3:6, 2:3 and 1:3 markers per segment; sizes 0.8–2.2 m) that distance is 63 mm
/// at the median and 153 mm at the 95th percentile of 622 joints, and at most 0.39 of the
/// size but for one: a one-marker segment posed through a pair that turned 2° put
/// human-hard-s20002's knee 3.3 m off (`--markers 1:3`), 1.54 of the size.
const FAR_CENTRE_SHARE: f64 = 0.5;

/// Below this ratio of a joint's runner-up cost to its own (`topo::RunnerUp`) the tree is
/// uncertain there. With the true segments (`cargo xtask eval --presets hard
/// --true-segments`, seeds 20001..20050 and 30001..30050) 36 of the 37 wrong trees have a
/// joint below it, and 35 of their 52 wrong joints are, against 317 of 7586 right ones
/// (123 of the 663 right trees have one).
const RUNNER_UP_WARN_RATIO: f64 = 1.2;

/// Whether a joint's runner-up says anything about the tree: not for a rigid pair, which
/// topo takes before every cost (`rigid_first`) and says so in the topology's notes.
pub fn runner_up_applies(pair: &jointfit::PairFit) -> bool {
    pair.tree_kind() != jointfit::JointKind::Rigid
}

/// Frames sampled, evenly strided, for the distances behind [`FAR_CENTRE_SHARE`].
const FAR_CENTRE_FRAMES: usize = 200;

/// The whole of skeleton.json. Field order is the byte order of the file.
///
/// Contract fields (DESIGN.md): `units` … `joints`. Everything else is added quality
/// information; readers of the contract may ignore it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkeletonJson {
    /// Always "mm".
    pub units: String,
    /// Frames per second of the capture.
    pub frame_rate: f64,
    /// Number of frames; every `positions` list has this many entries.
    pub frame_count: usize,
    /// Segments: id and the labels of their markers.
    pub segments: Vec<SegmentJson>,
    /// Labels of markers in no segment.
    pub unassigned_markers: Vec<String>,
    /// Segment at the root of the tree.
    pub root_segment: usize,
    /// Joints, every parent before its children.
    pub joints: Vec<JointJson>,
    /// Program that wrote the file ("ossify").
    pub generator: String,
    /// Version of that program.
    pub ossify_version: String,
    /// Version of this file's layout (`export::SCHEMA_VERSION`).
    pub schema_version: u32,
    /// The capture's own number of frame index 0 (C3D frames start at 1).
    pub first_frame: i64,
    /// How the constant bones were fitted ("rigid" or "paper").
    pub bone_method: String,
    /// How the per-frame segment orientations were chosen ("fitted" to the joint centres
    /// and markers, or the segments' marker "poses").
    pub rotation_method: String,
    /// The root point the BVH ROOT sits at.
    pub root: RootJson,
    /// Per marker: its segment and diagnostics, in the capture's label order.
    pub markers: Vec<MarkerJson>,
    /// Segments not connected to the tree.
    pub detached_segments: Vec<usize>,
    /// Every body the capture holds where it holds more than one (two subjects, or a
    /// subject and a prop; no pair between two is a joint), biggest first; empty for one.
    /// `cargo xtask run` writes the files of each body but its main one (`topo.body`,
    /// default the biggest) into `<out>/<its name>/`, the main one's into `<out>/`.
    #[serde(default)]
    pub bodies: Vec<BodyJson>,
    /// The name of the body this file's tree spans (one of `bodies`); null for one body.
    #[serde(default)]
    pub body: Option<String>,
    /// Remarks from the topology stage, in words.
    pub notes: Vec<String>,
    /// Pairs of markers whose trajectories the capture had exchanged for a while (a
    /// tracker confusing markers that pass close); every stage used them swapped back, in
    /// this order (a marker can be in several: its partner seen in two tracks).
    #[serde(default)]
    pub label_swaps: Vec<LabelSwapJson>,
    /// The parameters the run set away from their defaults (`--set`), as `stage.param` →
    /// value; empty where every parameter had its default.
    #[serde(default)]
    pub settings: BTreeMap<String, serde_json::Value>,
    /// What the reader said about the capture file, in its words (units guessed or
    /// contradicted by the numbers, header counts disagreeing with the data, samples read
    /// as missing); empty where it said nothing.
    #[serde(default)]
    pub reader_warnings: Vec<String>,
}

/// One of several bodies in a capture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyJson {
    /// "body1", "body2", ... biggest first: the folder inside its output folder where
    /// `cargo xtask run` writes this body's files, unless it is the run's main body.
    pub name: String,
    /// Its segments' ids, ascending.
    pub segments: Vec<usize>,
    /// Markers on those segments.
    pub marker_count: usize,
}

impl SkeletonJson {
    /// Whether `body` is only the segment of the markers that never move (the room's),
    /// which no skeleton holds.
    pub fn is_room(&self, body: &BodyJson) -> bool {
        !body.segments.is_empty()
            && body
                .segments
                .iter()
                .all(|&id| self.segments.iter().any(|s| s.id == id && s.stationary))
    }

    /// The labels of the markers that never move (the `stationary` segment's), if any.
    pub fn stationary_markers(&self) -> Vec<&str> {
        self.segments
            .iter()
            .filter(|s| s.stationary)
            .flat_map(|s| s.markers.iter().map(String::as_str))
            .collect()
    }
}

/// Two markers whose trajectories were exchanged, and when.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabelSwapJson {
    /// The two markers' labels.
    pub markers: [String; 2],
    /// Frame index ranges `[first, last]` (0-based like `positions`, inclusive).
    pub frames: Vec<[usize; 2]>,
}

/// One segment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentJson {
    /// Segment id.
    pub id: usize,
    /// Labels of its markers.
    pub markers: Vec<String>,
    /// Number of markers.
    pub marker_count: usize,
    /// Frames in which its rigid pose was measured.
    pub frames_with_pose: usize,
    /// How well its markers fix its rotation: the standard error (degrees) of its turn
    /// about its markers' line with all of them seen; large where they nearly line up, 180
    /// where they do not fix that turn at all. Absent for fewer than 3 markers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spin_deg: Option<f64>,
    /// Where the segment may be two that turn little about a joint: the cut the joint test
    /// weighed came near its bounds (or passed one, failing its other conditions) and was
    /// not made. Absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_joint: Option<NearJointJson>,
    /// True where `segment.groups` named this segment (the user's grouping, not the
    /// data's). Absent otherwise.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub named: bool,
    /// True for the segment of the markers that never move (floor and reference markers,
    /// stray reflections; `segment.stationary_jitter_factor`): the room's, or a fixed
    /// base's where a joint joins it. Absent otherwise.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub stationary: bool,
}

/// A cut of a segment that came near the joint test's bounds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NearJointJson {
    /// The two parts' marker labels.
    pub parts: [Vec<String>; 2],
    /// Rotation score of the parts' relative turn (the test cuts above `segment.joint_split_z`).
    pub rotation_z: f64,
    /// Travel score of one part's centroid in the other's frame (the test cuts above
    /// `segment.joint_travel_z`).
    pub travel_z: f64,
}

/// One joint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointJson {
    /// Name, shared with the BVH: `j<child_segment>`.
    pub name: String,
    /// Segment nearer the root.
    pub parent_segment: usize,
    /// Segment farther from the root.
    pub child_segment: usize,
    /// "ball", "hinge", "universal" or "rigid".
    pub kind: String,
    /// Global joint centre per frame (mm, rounded to 0.001), null where unknown.
    pub positions: Vec<Option<[f64; 3]>>,
    /// Name of the parent joint, null when the parent is the root.
    pub parent: Option<String>,
    /// Joint-centre method that fitted it ("aguiar", "score", "local").
    pub method: String,
    /// RMS distance between the centre as the two segments carry it (mm).
    pub residual_rms_mm: Option<f64>,
    /// RMS distance between `positions` (constant bones) and the fitted centre (mm).
    pub fk_residual_rms_mm: Option<f64>,
    /// `residual_rms_mm` as an angle seen from the two segments' markers: over the RMS
    /// distance of their markers from the centre (degrees). A few degrees of skin on a
    /// joint; far more where the segments do not turn about one point.
    pub centre_misfit_deg: Option<f64>,
    /// `residual_rms_mm` against what the two segments' pose noise predicts at the centre
    /// (`jointfit::PairFit::misfit_over_noise`: RMS over frames of the Mahalanobis length
    /// per coordinate): about 1 where the joint fits as well as its markers allow, several
    /// where the segments do not turn about one point. Absent where a segment has fewer
    /// than three markers fitted together, or the data are exact.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual_over_noise: Option<f64>,
    /// How far an error in the two segments' poses can move the centre along the
    /// direction their relative rotation fixes least, in times that error
    /// (`jointfit::centre_gain`): 2–6 for a ball joint turning every way, large for a hinge
    /// (along its axis the centre is placed, see `hinge_shift_mm`, not measured).
    pub centre_gain: Option<f64>,
    /// Range of motion of the child segment relative to the parent (degrees).
    pub range_of_motion_deg: Option<f64>,
    /// Why `kind` was chosen, in words.
    pub kind_evidence: String,
    /// Hinge axis in the parent segment's local frame (unit vector), for hinges.
    pub hinge_axis_in_parent: Option<[f64; 3]>,
    /// For universal joints: the axis fixed in the parent segment's local frame, then the
    /// axis fixed in the child's (unit vectors); the angle between them never changes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub universal_axes: Option<[[f64; 3]; 2]>,
    /// How far bonefit slid the hinge centre along its axis towards the adjacent joints
    /// (mm); 0 when not slid.
    pub hinge_shift_mm: f64,
    /// Constant bone length from the parent joint (or root point) (mm).
    pub bone_length_mm: f64,
    /// Constant offset from the parent joint in the parent's rest frame (mm): the BVH OFFSET.
    pub offset_mm: [f64; 3],
    /// Frames with a known position.
    pub frames_known: usize,
    /// Of those, frames known through an interpolated short pose gap.
    pub frames_interpolated: usize,
    /// The pair that would join the tree's two sides again were this joint left out;
    /// absent when no other pair crosses (see [`RunnerUpJson`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub runner_up: Option<RunnerUpJson>,
    /// Problems a user should know about.
    pub warnings: Vec<String>,
}

/// The cheapest other segment pair across the cut a joint makes in the tree: near 1 or
/// below, the data hardly decide between this joint and that pair (siblings meeting
/// within a few centimetres, a segment turning little).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunnerUpJson {
    /// Its segment on the joint's parent side.
    pub parent_side_segment: usize,
    /// Its segment on the joint's child side.
    pub child_side_segment: usize,
    /// Its pair cost over this joint's (both `jointfit` pair costs, mm for `score`).
    pub cost_ratio: f64,
}

/// The root point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RootJson {
    /// Name of the BVH ROOT.
    pub name: String,
    /// The root point in the root segment's local frame (mm).
    pub point_in_segment: [f64; 3],
    /// Global root point per frame (mm, rounded to 0.001), null where unknown.
    pub positions: Vec<Option<[f64; 3]>>,
}

/// One marker's diagnostics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MarkerJson {
    /// Its label in the capture.
    pub label: String,
    /// Its segment, null when unassigned.
    pub segment: Option<usize>,
    /// Frames in which it is visible.
    pub visible_frames: usize,
    /// Visible frames every stage read as gaps: the marker left its steadiest partners (a glitch).
    #[serde(default)]
    pub glitch_frames: usize,
    /// RMS over its segment-mates of the standard deviation of their distance (mm).
    pub rigidity_residual_mm: Option<f64>,
    /// True when it moves relative to its segment (skin slide).
    pub slides: bool,
    /// Why it is in no segment, when it is in none.
    pub unassigned_reason: Option<String>,
    /// The label of the track whose trajectory this one continues after a gap (the same
    /// marker, cut in pieces by an unlabeled reconstruction; the segment stage's `pieces`),
    /// null when none.
    #[serde(default)]
    pub piece_of: Option<String>,
    /// Samples markers.trc fills from its segment's pose where the capture, as the pipeline
    /// read it, misses the marker (0 for a marker in no segment).
    #[serde(default)]
    pub filled_frames: usize,
}

/// Rounds to `decimals` places; None for NaN/infinite; no negative zero.
pub(crate) fn round(v: f64, decimals: i32) -> Option<f64> {
    if !v.is_finite() {
        return None;
    }
    let scale = 10f64.powi(decimals);
    let r = (v * scale).round() / scale;
    Some(if r == 0.0 { 0.0 } else { r })
}

/// A position rounded to 0.001 mm, None where unknown.
fn position(p: [f64; 3]) -> Option<[f64; 3]> {
    Some([round(p[0], 3)?, round(p[1], 3)?, round(p[2], 3)?])
}

/// A finite vector rounded to 0.001 mm (zeros where not finite).
fn vector(p: [f64; 3]) -> [f64; 3] {
    p.map(|c| round(c, 3).unwrap_or(0.0))
}

/// Builds the document from the inputs.
pub(crate) fn document(input: &Inputs<'_>) -> Result<SkeletonJson, Error> {
    let traj = input.trajectories;
    let seg = input.segmentation;
    let fits = input.fits;
    let skel = input.skeleton;
    let labels = traj.labels();
    let label = |m: usize, what: &str| {
        labels.get(m).cloned().ok_or_else(|| {
            Error::Mismatch(format!(
                "{what} names marker {m} but the capture has {} markers",
                labels.len()
            ))
        })
    };
    if skel.frame_count != traj.frames() {
        return Err(Error::Mismatch(format!(
            "the skeleton has {} frames, the capture {}",
            skel.frame_count,
            traj.frames()
        )));
    }

    let mut segments = Vec::with_capacity(seg.segments.len());
    for s in &seg.segments {
        let markers = s
            .markers
            .iter()
            .map(|&m| label(m, &format!("segment {}", s.id)))
            .collect::<Result<Vec<_>, _>>()?;
        let frames_with_pose = fits.poses.get(s.id).map_or(0, |p| {
            p.rotations
                .iter()
                .filter(|q| q.iter().all(|c| c.is_finite()))
                .count()
        });
        let spin_deg = fits
            .poses
            .get(s.id)
            .and_then(jointfit::segment_spin_deg)
            .map(|d| (d * 100.0).round() / 100.0);
        let near_joint = match seg.near_joints.iter().find(|n| n.segment == s.id) {
            Some(n) => {
                let names = |part: &[usize]| {
                    part.iter()
                        .map(|&m| label(m, &format!("segment {}'s near joint", s.id)))
                        .collect::<Result<Vec<_>, _>>()
                };
                Some(NearJointJson {
                    parts: [names(&n.parts[0])?, names(&n.parts[1])?],
                    rotation_z: (n.rotation_z * 100.0).round() / 100.0,
                    travel_z: (n.travel_z * 100.0).round() / 100.0,
                })
            }
            None => None,
        };
        segments.push(SegmentJson {
            id: s.id,
            marker_count: markers.len(),
            markers,
            frames_with_pose,
            spin_deg,
            near_joint,
            named: seg.named_segments.contains(&s.id),
            stationary: seg.stationary_segment == Some(s.id),
        });
    }
    let unassigned_markers = seg
        .unassigned
        .iter()
        .map(|u| label(u.marker, "the unassigned list"))
        .collect::<Result<Vec<_>, _>>()?;

    let label_swaps = seg
        .swaps
        .iter()
        .map(|s| {
            Ok(LabelSwapJson {
                markers: [
                    label(s.markers[0], "a label swap")?,
                    label(s.markers[1], "a label swap")?,
                ],
                frames: s.frames.clone(),
            })
        })
        .collect::<Result<Vec<_>, Error>>()?;

    let sampled: Vec<usize> = {
        let frames = traj.frames();
        let stride = frames.div_ceil(FAR_CENTRE_FRAMES).max(1);
        (0..frames).step_by(stride).collect()
    };
    let extent = capture_extent_mm(traj, &sampled);
    let mut joints = Vec::with_capacity(skel.joints.len());
    for j in &skel.joints {
        let pair = fits.pairs.get(j.pair).ok_or_else(|| {
            Error::Mismatch(format!(
                "joint {} uses pair {} but there are {} pair fits",
                j.name,
                j.pair,
                fits.pairs.len()
            ))
        })?;
        if (pair.a, pair.b)
            != (
                j.parent_segment.min(j.child_segment),
                j.parent_segment.max(j.child_segment),
            )
        {
            return Err(Error::Mismatch(format!(
                "joint {} joins segments {} and {} but its pair {} joins {} and {}",
                j.name, j.parent_segment, j.child_segment, j.pair, pair.a, pair.b
            )));
        }
        if j.positions.len() != skel.frame_count {
            return Err(Error::Mismatch(format!(
                "joint {} has {} positions for {} frames",
                j.name,
                j.positions.len(),
                skel.frame_count
            )));
        }
        let kind = match serde_json::to_value(pair.kind)? {
            serde_json::Value::String(s) => s,
            other => other.to_string(),
        };
        let mut warnings = Vec::new();
        let rom = round(j.range_of_motion_deg, 2);
        match rom {
            Some(r) if r < LOW_RANGE_OF_MOTION_DEG => warnings.push(format!(
                "range of motion {r:.1}° is below {LOW_RANGE_OF_MOTION_DEG}°: the joint centre is poorly determined"
            )),
            None => warnings.push(
                "the two segments were never both measured: no range of motion".to_owned(),
            ),
            _ => {}
        }
        if j.frames_known == 0 {
            warnings.push("position never known".to_owned());
        }
        let misfit = centre_misfit_deg(&fits.poses, pair);
        if let Some(m) = misfit.filter(|&m| m > CENTRE_MISFIT_WARN_DEG) {
            warnings.push(format!(
                "the two segments disagree about their common centre by {m:.1}° of their \
                 markers' distance to it (above {CENTRE_MISFIT_WARN_DEG}°): they may not turn \
                 about one point (a segment between them without markers, a wrong pair, or \
                 two bodies that share no joint: two subjects, or a subject and a prop, in one \
                 capture)"
            ));
        }
        let gain = jointfit::centre_gain(fits, j.pair).filter(|g| g.is_finite());
        let loose = matches!(
            pair.kind,
            jointfit::JointKind::Ball | jointfit::JointKind::Universal
        );
        if let Some(g) = gain.filter(|&g| loose && g > LOOSE_CENTRE_GAIN) {
            warnings.push(format!(
                "it turned about one axis almost only: a pose error moves its centre up to {g:.0} \
                 times as far along that axis (above {LOOSE_CENTRE_GAIN}), so the centre's \
                 place along it is uncertain"
            ));
        }
        let markers_of = |segment: usize| {
            seg.segments
                .iter()
                .find(|x| x.id == segment)
                .map_or(&[][..], |x| &x.markers[..])
        };
        let near = [markers_of(j.parent_segment), markers_of(j.child_segment)].concat();
        if let (Some(d), Some(e)) = (
            nearest_marker_mm(traj, &j.positions, &near, &sampled),
            extent,
        ) && d > FAR_CENTRE_SHARE * e
        {
            warnings.push(format!(
                "its centre lies {d:.0} mm from the nearest marker of its two segments, more \
                 than {FAR_CENTRE_SHARE} of the capture's size ({e:.0} mm): the data did not \
                 place it (too little turn, or a segment posed only through this joint)"
            ));
        }
        let tree_joint = input.topology.joints.iter().find(|t| t.pair == j.pair);
        // A joint the user named (topo.joints) is theirs: the data's doubts are not warned.
        let named = tree_joint.is_some_and(|t| t.named);
        let runner_up = tree_joint.and_then(|t| {
            let r = t.runner_up.as_ref()?;
            Some(RunnerUpJson {
                parent_side_segment: r.parent_side,
                child_side_segment: r.child_side,
                cost_ratio: round(r.cost / t.cost, 3)?,
            })
        });
        if let Some(r) = runner_up
            .as_ref()
            .filter(|r| !named && r.cost_ratio < RUNNER_UP_WARN_RATIO && runner_up_applies(pair))
        {
            warnings.push(format!(
                "the tree could join segments {a} and {b} instead: that pair's fit costs {:.2} \
                 times this joint's (below {RUNNER_UP_WARN_RATIO}), so the tree is uncertain here \
                 (--set 'topo.joints=[[{a}, {b}]]' joins them where you know it should)",
                r.cost_ratio,
                a = r.parent_side_segment,
                b = r.child_side_segment,
            ));
        }
        if let (Some(s), Some((x, ratio))) = (pair.posed_through, pair.next_best_anchor)
            && ratio < 1.0
            && !named
        {
            warnings.push(format!(
                "segment {s} is posed through this joint although segment {x}'s centre holds its \
                 markers better ({ratio:.2} times this one's residual): the tree kept this joint, \
                 and may be wrong here"
            ));
        }
        if pair.seeded {
            warnings.push(
                "every pose starts here: no segment has three markers of its own, so one of \
                 these two was posed from both segments' markers' common centre"
                    .to_owned(),
            );
        }
        // The hinge axis is stored in the lower segment's frame; give it in the parent's.
        let hinge_axis_in_parent = if pair.a == j.parent_segment {
            pair.axis_in_a
        } else {
            pair.axis_in_b
        }
        .map(|a| a.map(|c| round(c, 6).unwrap_or(0.0)));
        // Universal axes are stored (axis in a, axis in b); give them (parent's, child's).
        let universal_axes = pair.universal_axes.map(|[in_a, in_b]| {
            let (parent, child) = if pair.a == j.parent_segment {
                (in_a, in_b)
            } else {
                (in_b, in_a)
            };
            [parent, child].map(|a| a.map(|c| round(c, 6).unwrap_or(0.0)))
        });
        joints.push(JointJson {
            name: j.name.clone(),
            parent_segment: j.parent_segment,
            child_segment: j.child_segment,
            kind,
            positions: j.positions.iter().map(|&p| position(p)).collect(),
            parent: j
                .parent
                .and_then(|p| skel.joints.get(p))
                .map(|p| p.name.clone()),
            method: pair.method.clone(),
            residual_rms_mm: round(pair.residual_rms_mm, 3),
            fk_residual_rms_mm: round(j.fit_rms_mm, 3),
            centre_misfit_deg: misfit.and_then(|m| round(m, 3)),
            residual_over_noise: round(pair.misfit_over_noise, 3),
            centre_gain: gain.and_then(|g| round(g, 1)),
            range_of_motion_deg: rom,
            kind_evidence: pair.evidence.clone(),
            hinge_axis_in_parent,
            universal_axes,
            hinge_shift_mm: round(j.hinge_shift_mm, 3).unwrap_or(0.0),
            bone_length_mm: round(j.bone_length, 3).unwrap_or(0.0),
            offset_mm: vector(j.offset),
            frames_known: j.frames_known,
            frames_interpolated: j.frames_interpolated,
            runner_up,
            warnings,
        });
    }

    let mut markers = Vec::with_capacity(labels.len());
    for (m, l) in labels.iter().enumerate() {
        let diagnostics = seg.markers.get(m);
        markers.push(MarkerJson {
            label: l.clone(),
            segment: diagnostics.and_then(|d| d.segment),
            visible_frames: diagnostics.map_or(0, |d| d.visible_frames),
            glitch_frames: diagnostics.map_or(0, |d| d.glitch_frames),
            rigidity_residual_mm: diagnostics.and_then(|d| round(d.rigidity_residual_mm, 3)),
            slides: diagnostics.is_some_and(|d| d.slides),
            piece_of: seg
                .pieces
                .iter()
                .find(|g| g.len() > 1 && g[1..].contains(&m))
                .and_then(|g| labels.get(g[0]).cloned()),
            unassigned_reason: seg
                .unassigned
                .iter()
                .find(|u| u.marker == m)
                .map(|u| u.reason.clone()),
            // Set by `crate::run` from the fill, which the document does not make.
            filled_frames: 0,
        });
    }

    Ok(SkeletonJson {
        units: "mm".to_owned(),
        frame_rate: skel.frame_rate,
        frame_count: skel.frame_count,
        segments,
        unassigned_markers,
        root_segment: skel.root_segment,
        joints,
        generator: "ossify".to_owned(),
        ossify_version: env!("CARGO_PKG_VERSION").to_owned(),
        schema_version: crate::SCHEMA_VERSION,
        first_frame: traj.first_frame(),
        bone_method: skel.method.clone(),
        rotation_method: skel.rotation_method.clone(),
        root: RootJson {
            name: skel.root_name.clone(),
            point_in_segment: vector(skel.root_point_in_segment),
            positions: skel.root_positions.iter().map(|&p| position(p)).collect(),
        },
        markers,
        detached_segments: input.topology.detached_segments.clone(),
        bodies: input
            .topology
            .bodies
            .iter()
            .enumerate()
            .map(|(k, segments)| BodyJson {
                name: topo::body_name(k),
                segments: segments.clone(),
                marker_count: segments
                    .iter()
                    .filter_map(|&s| input.segmentation.segments.get(s))
                    .map(|s| s.markers.len())
                    .sum(),
            })
            .collect(),
        body: input.topology.body.map(topo::body_name),
        notes: input.topology.notes.clone(),
        label_swaps,
        settings: input.settings.clone(),
        reader_warnings: input.reader_warnings.to_vec(),
    })
}

/// The document as compact JSON bytes with a final newline.
pub(crate) fn to_bytes(document: &SkeletonJson) -> Result<Vec<u8>, Error> {
    let mut bytes = serde_json::to_vec(document)?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// The capture's size (mm): the median over `frames` of the diagonal of the box holding
/// every marker seen in that frame; `None` when no frame has two markers.
fn capture_extent_mm(traj: &mocap_io::Trajectories, frames: &[usize]) -> Option<f64> {
    let mut diagonals: Vec<f64> = frames
        .iter()
        .filter_map(|&f| {
            let mut seen = (0..traj.markers()).filter_map(|m| traj.get(f, m));
            let first = glam::DVec3::from_array(seen.next()?);
            let (lo, hi, count) = seen.fold((first, first, 1), |(lo, hi, n), p| {
                let p = glam::DVec3::from_array(p);
                (lo.min(p), hi.max(p), n + 1)
            });
            (count > 1).then(|| (hi - lo).length())
        })
        .collect();
    median(&mut diagonals)
}

/// The median over `frames` of a joint's distance (mm) to the nearest of `markers` seen
/// in that frame, where its position is known; `None` when no such frame.
fn nearest_marker_mm(
    traj: &mocap_io::Trajectories,
    positions: &[[f64; 3]],
    markers: &[usize],
    frames: &[usize],
) -> Option<f64> {
    let mut nearest: Vec<f64> = frames
        .iter()
        .filter_map(|&f| {
            let joint = glam::DVec3::from_array(*positions.get(f)?);
            if !joint.is_finite() {
                return None;
            }
            markers
                .iter()
                .filter_map(|&m| traj.get(f, m))
                .map(|p| glam::DVec3::from_array(p).distance(joint))
                .min_by(f64::total_cmp)
        })
        .collect();
    median(&mut nearest)
}

/// The median of `values` (reordered); `None` when empty.
fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    Some(values[values.len() / 2])
}

/// A pair fit's residual as an angle seen from its two segments' markers (degrees): the
/// residual RMS over the RMS distance of both segments' reference markers from the centre
/// each carries. Pose errors of a few degrees (skin) put a joint at a few degrees; two
/// segments that do not turn about one point, far more. `None` without a finite residual,
/// centre or marker.
pub(crate) fn centre_misfit_deg(
    poses: &[jointfit::SegmentPoses],
    pair: &jointfit::PairFit,
) -> Option<f64> {
    let spread = |segment: usize, centre: [f64; 3]| -> Option<(f64, usize)> {
        let c = glam::DVec3::from_array(centre);
        let (sum, n) = poses
            .get(segment)?
            .reference
            .iter()
            .map(|&m| glam::DVec3::from_array(m))
            .filter(|m| m.is_finite())
            .fold((0.0, 0), |(s, n), m| (s + m.distance_squared(c), n + 1));
        c.is_finite().then_some((sum, n))
    };
    let (sa, na) = spread(pair.a, pair.centre_in_a)?;
    let (sb, nb) = spread(pair.b, pair.centre_in_b)?;
    let lever = ((sa + sb) / (na + nb) as f64).sqrt();
    let residual = pair.residual_rms_mm;
    (residual.is_finite() && lever > 0.0).then(|| (residual / lever).atan().to_degrees())
}
