//! The ground truth of a trial, its JSON file, and writing a trial to disk.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::body::{Body, JointKind};
use crate::markers::MarkerSet;
use crate::motion::Motion;
use crate::{Error, Preset, Subject, SynthConfig};

/// Version of the truth file layout; bumped when a field changes meaning.
pub const TRUTH_SCHEMA_VERSION: u32 = 1;

/// Truth joint centres are rounded to this step, mm: finer than the C3D's f32 positions
/// (≈ 1.2e-4 mm at 2 m) and it keeps the file short.
pub const POSITION_STEP_MM: f64 = 1e-4;

/// What a trial really is: segments and their markers, joints and their centres, the tree.
///
/// Units: millimetres and degrees; global frame Z up. Frame indices are 0-based
/// positions in the trajectories (the C3D numbers them from 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// [`TRUTH_SCHEMA_VERSION`] of the writer.
    pub schema_version: u32,
    /// Trial name, `<subject>-<preset>-s<seed>`.
    pub name: String,
    /// The subject.
    pub subject: Subject,
    /// The degradation preset.
    pub preset: Preset,
    /// The seed.
    pub seed: u64,
    /// Always "mm".
    pub units: String,
    /// Frames per second.
    pub frame_rate: f64,
    /// Number of frames.
    pub frame_count: usize,
    /// Size used to express errors as a percentage, mm: a human's standing height, the
    /// snowman's stacked diameters, else the largest side of the rest pose's bounding box.
    pub height_mm: f64,
    /// Index of the root segment (the one no joint moves).
    pub root_segment: usize,
    /// Segments by index.
    pub segments: Vec<TruthSegment>,
    /// Joints, parents before children; joint `j`'s child segment is `joints[j].child_segment`.
    pub joints: Vec<TruthJoint>,
    /// Holes punched by the gaps and hard presets (empty otherwise).
    #[serde(default)]
    pub gaps: Vec<TruthGap>,
    /// Label swaps made by the swap preset (empty otherwise).
    #[serde(default)]
    pub swaps: Vec<TruthSwap>,
}

/// A rigid segment and the markers riding on it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthSegment {
    /// Anatomical or structural name ("l_thigh", "link3", "seg07").
    pub name: String,
    /// Index of the joint that moves this segment; `None` for the root.
    pub parent_joint: Option<usize>,
    /// Labels of its markers, sorted.
    pub markers: Vec<String>,
}

/// A joint between a parent and a child segment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthJoint {
    /// Name ("l_knee", "joint3").
    pub name: String,
    /// Index of the parent segment (closer to the root).
    pub parent_segment: usize,
    /// Index of the child segment.
    pub child_segment: usize,
    /// Index of the parent segment's own parent joint; `None` when the parent is the root.
    pub parent_joint: Option<usize>,
    /// "ball" (three rotations), "universal" (two) or "hinge" (one).
    pub kind: String,
    /// Hinge axis, unit vector in the global frame at frame 0; `None` for other kinds.
    pub axis: Option<[f64; 3]>,
    /// Range of motion per rotation, degrees `[min, max]`: a hinge's one angle; a ball's
    /// rotations about the parent's x, y, z, composed as Rz·Ry·Rx; a universal joint's
    /// about its first axis (in the parent) then its second (in the child).
    pub rom_deg: Vec<[f64; 2]>,
    /// Measured sweep (max − min over the trial) of each rotation in `rom_deg`, degrees.
    pub swept_deg: Vec<f64>,
    /// Constant distance to `parent_joint`'s centre, mm; `None` when the parent is the root.
    pub bone_length_mm: Option<f64>,
    /// Joint centre per frame, global mm (rounded to [`POSITION_STEP_MM`]).
    pub positions: Vec<[f64; 3]>,
}

/// One hole in one marker: frames `first_frame .. first_frame + frames` are missing.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TruthGap {
    /// Marker label.
    pub label: String,
    /// First missing frame (0-based index).
    pub first_frame: usize,
    /// Number of missing frames.
    pub frames: usize,
    /// "short" (2–20 frames), "long" (10–30 % of the trial) or "lost" (second half).
    pub kind: String,
}

/// Two markers whose labels (trajectories) were exchanged for a stretch of frames.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TruthSwap {
    /// The two labels; each is listed in `segments` under the segment it really rides on
    /// outside the stretch.
    pub labels: [String; 2],
    /// First swapped frame (0-based index).
    pub first_frame: usize,
    /// Number of swapped frames.
    pub frames: usize,
}

/// Rounds to a multiple of `1 / per_unit`; dividing by an exact power of ten gives the
/// double nearest the short decimal, which JSON writes and reads back exactly.
fn round_to(x: f64, per_unit: f64) -> f64 {
    (x * per_unit).round() / per_unit
}

/// Assembles the truth of a generated trial.
pub(crate) fn build(
    config: &SynthConfig,
    body: &Body,
    markers: &MarkerSet,
    motion: &Motion,
    gaps: Vec<TruthGap>,
    swaps: Vec<TruthSwap>,
) -> Truth {
    let segments = body
        .segments
        .iter()
        .enumerate()
        .map(|(s, seg)| TruthSegment {
            name: seg.name.clone(),
            parent_joint: body.parent_joint(s),
            markers: markers
                .labels
                .iter()
                .zip(&markers.segment)
                .filter(|(_, ms)| **ms == s)
                .map(|(l, _)| l.clone())
                .collect(),
        })
        .collect();
    let joints = body
        .joints
        .iter()
        .map(|joint| {
            let parent_joint = body.parent_joint(joint.parent);
            let axis = match joint.kind {
                JointKind::Hinge { axis, .. } => {
                    let g = motion.rot(0, joint.parent) * axis;
                    Some(g.to_array().map(|c| round_to(c, 1e9)))
                }
                JointKind::Ball { .. } | JointKind::Universal { .. } => None,
            };
            let limits = joint.kind.limits();
            let mut lo = vec![f64::INFINITY; limits.len()];
            let mut hi = vec![f64::NEG_INFINITY; limits.len()];
            for f in 0..motion.frames {
                let rel = motion.rot(f, joint.parent).inverse() * motion.rot(f, joint.child);
                for (d, a) in joint.kind.angles(rel).into_iter().enumerate() {
                    lo[d] = lo[d].min(a);
                    hi[d] = hi[d].max(a);
                }
            }
            TruthJoint {
                name: joint.name.clone(),
                parent_segment: joint.parent,
                child_segment: joint.child,
                parent_joint,
                kind: joint.kind.name().into(),
                axis,
                rom_deg: limits.iter().map(|r| r.map(|a| round_to(a, 1e3))).collect(),
                swept_deg: lo
                    .iter()
                    .zip(&hi)
                    .map(|(l, h)| round_to(h - l, 1e3))
                    .collect(),
                bone_length_mm: parent_joint
                    .map(|_| round_to(joint.offset.length(), 1.0 / POSITION_STEP_MM)),
                positions: (0..motion.frames)
                    .map(|f| {
                        motion
                            .origin(f, joint.child)
                            .to_array()
                            .map(|c| round_to(c, 1.0 / POSITION_STEP_MM))
                    })
                    .collect(),
            }
        })
        .collect();
    Truth {
        schema_version: TRUTH_SCHEMA_VERSION,
        name: config.trial_name(),
        subject: config.subject,
        preset: config.preset,
        seed: config.seed,
        units: "mm".into(),
        frame_rate: config.rate,
        frame_count: motion.frames,
        height_mm: round_to(body.height_mm, 1e3),
        root_segment: 0,
        segments,
        joints,
        gaps,
        swaps,
    }
}

impl Truth {
    /// The truth as pretty JSON with every innermost array (a position, an axis, a marker
    /// list) on one line; deterministic bytes.
    pub fn to_json(&self) -> Result<String, Error> {
        let pretty = serde_json::to_string_pretty(self).map_err(|source| Error::Encode {
            trial: self.name.clone(),
            source,
        })?;
        let mut out = inline_leaf_arrays(&pretty);
        out.push('\n');
        Ok(out)
    }

    /// Parses a truth file's text.
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(text)
    }
}

/// Reads a `<name>.truth.json` file.
pub fn read_truth(path: &Path) -> Result<Truth, Error> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
        path: path.to_path_buf(),
        source,
    })?;
    Truth::from_json(&text).map_err(|source| Error::Json {
        path: path.to_path_buf(),
        what: "truth",
        source,
    })
}

/// Collapses every JSON array that holds no array or object onto one line.
fn inline_leaf_arrays(pretty: &str) -> String {
    let mut out = String::with_capacity(pretty.len());
    // Per open container: (is array, start offset in `out`, holds a container).
    let mut stack: Vec<(bool, usize, bool)> = Vec::new();
    let mut in_string = false;
    let mut escaped = false;
    for c in pretty.chars() {
        if in_string {
            out.push(c);
            in_string = still_in_string(c, &mut escaped);
            continue;
        }
        match c {
            '"' => in_string = true,
            '[' | '{' => {
                if let Some(top) = stack.last_mut() {
                    top.2 = true;
                }
                stack.push((c == '[', out.len(), false));
            }
            ']' => {
                if let Some((true, start, false)) = stack.pop() {
                    let inner = compact(&out[start + 1..]);
                    out.truncate(start + 1);
                    out.push_str(&inner);
                }
            }
            '}' => {
                stack.pop();
            }
            _ => {}
        }
        out.push(c);
    }
    out
}

/// After character `c` inside a JSON string: whether the string goes on (`escaped`
/// carries a pending backslash between calls).
fn still_in_string(c: char, escaped: &mut bool) -> bool {
    if *escaped {
        *escaped = false;
        true
    } else if c == '\\' {
        *escaped = true;
        true
    } else {
        c != '"'
    }
}

/// Removes whitespace outside strings and puts one space after each comma.
fn compact(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut in_string = false;
    let mut escaped = false;
    for c in text.chars() {
        if in_string {
            out.push(c);
            in_string = still_in_string(c, &mut escaped);
            continue;
        }
        match c {
            '"' => {
                in_string = true;
                out.push(c);
            }
            ',' => out.push_str(", "),
            c if c.is_whitespace() => {}
            c => out.push(c),
        }
    }
    out
}

/// Writes `<name>.c3d`, `<name>.truth.json` and, when `trc`, `<name>.trc` into `dir`
/// (created if needed); returns the paths written, in that order.
pub fn write_trial(dir: &Path, trial: &crate::Trial, trc: bool) -> Result<Vec<PathBuf>, Error> {
    let c3d = dir.join(format!("{}.c3d", trial.name));
    mocap_io::write_c3d(&c3d, &trial.trajectories)?;
    let truth = dir.join(format!("{}.truth.json", trial.name));
    mocap_io::artifact::write_atomic(&truth, trial.truth.to_json()?.as_bytes())?;
    let mut written = vec![c3d, truth];
    if trc {
        let path = dir.join(format!("{}.trc", trial.name));
        mocap_io::write_trc(&path, &trial.trajectories)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaf_arrays_go_on_one_line_and_strings_are_untouched() {
        let v = serde_json::json!({"a": [[1.5, 2.0], [3.0, null]], "b": ["x, [y]", "z"], "c": []});
        let pretty = serde_json::to_string_pretty(&v).unwrap();
        let out = inline_leaf_arrays(&pretty);
        assert!(out.contains("[1.5, 2.0]"), "{out}");
        assert!(out.contains("[\"x, [y]\", \"z\"]"), "{out}");
        let back: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(back, v);
    }
}
