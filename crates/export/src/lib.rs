//! export: the skeleton as files people open.
//!
//! Takes the capture (with what its reader warned), segmentation, pair fits, topology and
//! [`bonefit::Skeleton`] (as [`Inputs`]) and gives [`Outputs`]: file name → bytes, or hands
//! the files over one at a time ([`run_each`]) so a long capture's are never all in memory.
//! It is the only stage that makes file bytes, and it still writes nothing: the runner
//! does.
//! - `skeleton.json`: DESIGN.md's output contract (units, frame_rate, frame_count,
//!   segments, unassigned_markers, root_segment, joints with name, parent/child segment,
//!   kind and one position per frame or null), then quality fields beside them (see
//!   [`SkeletonJson`]). Millimetres in the capture's global frame; positions rounded to
//!   0.001 mm; deterministic bytes.
//! - `skeleton.bvh`: the same joint names nested by hierarchy; a ROOT at the root point
//!   with `OFFSET 0 0 0` and 6 channels, JOINTs with 3 rotation channels in ZXY order
//!   (R = Rz·Rx·Ry), End Sites toward the leaf segment's marker centroid; millimetres in
//!   the capture's frame, or Y-up with `export.y_up`. Where the root point is unknown the
//!   last known root position is held (the JSON has null there).
//! - `joints.csv`: `frame,joint,x,y,z`, one row per joint per frame where known; `frame`
//!   is the 0-based frame index (the capture's own number is `first_frame + frame`), mm.
//! - `joints.trc`: the root point and every joint centre as virtual markers named as in
//!   the BVH, at the capture's rate and first frame, empty where unknown; opens in OpenSim
//!   and other marker tools like a capture. Y-up with `export.y_up`.
//! - `joints.c3d`: the same as a C3D file (float, mm) for Visual3D, Nexus, Mokka and ezc3d;
//!   numbered from 1 where the capture's frame numbers leave C3D's 1–65535, and left out
//!   for a capture longer than 65535 frames.
//! - `markers.trc`, `markers.c3d`: the capture's markers as the pipeline read them (label
//!   swaps undone, glitch samples out, an unlabeled capture's pieces of one marker joined),
//!   each gap filled where its segment's pose is known (see `fill`), so a marker tool gets
//!   the capture gap-filled; skeleton.json's `filled_frames` counts each marker's fill.
//! - `skeleton.glb`: the BVH's hierarchy and motion as binary glTF 2.0 (an armature
//!   from a skin over the root, joint and End Site nodes, a mesh of one octahedral bone
//!   per offset, one animation keyed per frame) in metres; Blender, three.js, Unity and
//!   Godot import it. glTF is Y-up: a Z-up capture wants `export.y_up`.
//! - `skeleton.osim` and `skeleton.mot`: an OpenSim 4 model (a body per segment, a joint
//!   of the fitted kind at every joint, the capture's markers and the joint centres as
//!   markers) and its coordinates per frame; see `osim`.
//! - `report.html`: the same document for a person, one self-contained page (no script):
//!   a summary, what the reader said about the file, the skeleton drawn at its best-known
//!   frame in three projections, tables of joints (kind with its evidence, residuals,
//!   range of motion, warnings), segments and markers, label swaps, notes and the run's
//!   settings.
//!
//! It fits nothing of the skeleton; every number comes from the inputs, and the parameters
//! the run set (`Inputs::settings`) are recorded as given. Its one computation is
//! markers.trc's fill (`fill`): a segment's marker placed by the pose the inputs hold, or
//! where they hold none by a rigid fit of its other markers and its joints' centres.
mod bvh;
mod csv;
mod error;
mod fill;
mod glb;
mod json;
mod osim;
#[cfg(test)]
mod osim_tests;
mod report;
#[cfg(test)]
mod tests;
mod trc;

pub use error::Error;
pub use json::{
    BodyJson, JointJson, LabelSwapJson, MarkerJson, NearJointJson, RootJson, RunnerUpJson,
    SegmentJson, SkeletonJson, runner_up_applies,
};

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// Name of this stage (cache keys, artifact headers).
pub const STAGE: &str = "export";

/// Schema version of [`Outputs`] and of skeleton.json's layout; bump when either changes.
pub const SCHEMA_VERSION: u32 = 24;

/// Everything the files are made from.
#[derive(Clone, Copy, Debug)]
pub struct Inputs<'a> {
    /// The capture (labels, frame rate, first frame).
    pub trajectories: &'a mocap_io::Trajectories,
    /// Segments and per-marker diagnostics.
    pub segmentation: &'a segment::Segmentation,
    /// Segment poses and joint fits (kind, method, residuals).
    pub fits: &'a jointfit::PairFits,
    /// The tree (detached segments, notes).
    pub topology: &'a topo::Topology,
    /// The skeleton and its motion.
    pub skeleton: &'a bonefit::Skeleton,
    /// The parameters the run set away from their defaults, as `stage.param` → value
    /// (written to skeleton.json and the report, so a file says how it was made).
    pub settings: &'a BTreeMap<String, serde_json::Value>,
    /// What the reader said about the capture file (`mocap_io::CaptureInfo::warnings`:
    /// guesses made, disagreements resolved, data skipped), kept with the outputs.
    pub reader_warnings: &'a [String],
}

/// The files, by name; the runner writes them.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Outputs {
    /// File name → file bytes (skeleton.json, skeleton.bvh, skeleton.glb, joints.csv,
    /// joints.trc, joints.c3d, markers.trc, markers.c3d, skeleton.osim, skeleton.mot,
    /// report.html).
    #[serde(with = "byte_files")]
    pub files: BTreeMap<String, Vec<u8>>,
}

/// Parameters of the export stage.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Rotate the BVH, the glTF, joints.trc, joints.c3d, markers.trc and markers.c3d from
    /// Z-up to Y-up (x, y, z) → (x, z, −y) for Y-up consumers (Blender's BVH import, glTF
    /// viewers, OpenSim), and hang skeleton.osim's root on a ground frame turned the same
    /// way; the JSON and CSV stay in the capture's frame. Default false.
    pub y_up: bool,
    /// Make every joint of skeleton.osim a ball joint, so skeleton.mot reproduces the
    /// skeleton's motion exactly, instead of each joint's fitted kind (a hinge a pin, a
    /// universal joint a universal joint), which follows only the turns that kind makes.
    /// Default false.
    pub osim_ball_joints: bool,
}

/// Every parameter: (field name, "meaning, units, default").
pub const PARAM_DOCS: &[(&str, &str)] = &[
    (
        "y_up",
        "rotate the BVH, skeleton.glb, joints.trc, joints.c3d, markers.trc and markers.c3d \
         from the capture's Z-up to Y-up ((x, y, z) -> (x, z, -y)) for Y-up consumers (glTF \
         and OpenSim's ground are Y-up), and hang skeleton.osim's root on a ground frame \
         turned the same way; skeleton.json and joints.csv stay in the capture's frame; \
         default false",
    ),
    (
        "osim_ball_joints",
        "make every joint of skeleton.osim a ball joint, so skeleton.mot reproduces the \
         skeleton's motion exactly, instead of each joint's fitted kind (hinge -> PinJoint, \
         universal -> UniversalJoint, rigid -> WeldJoint), which follows only the turns that \
         kind makes; default false",
    ),
];

/// Makes skeleton.json, skeleton.bvh, skeleton.glb, joints.csv, joints.trc, joints.c3d,
/// markers.trc, markers.c3d (each C3D where the capture fits C3D's 65535 frames),
/// skeleton.osim, skeleton.mot and report.html, all held at once; [`run_each`] hands them
/// over one by one.
pub fn run(input: &Inputs<'_>, params: &Params) -> Result<Outputs, Error> {
    let mut files = BTreeMap::new();
    run_each(input, params, |name, bytes| -> Result<(), Error> {
        files.insert(name.to_owned(), bytes);
        Ok(())
    })?;
    Ok(Outputs { files })
}

/// The names of the files [`run_each`] makes of `input`, in the order it makes them
/// (increasing).
pub fn file_names(input: &Inputs<'_>) -> Vec<&'static str> {
    let with_c3d = fits_c3d(input.trajectories);
    [
        "joints.c3d",
        "joints.csv",
        "joints.trc",
        "markers.c3d",
        "markers.trc",
        "report.html",
        "skeleton.bvh",
        "skeleton.glb",
        "skeleton.json",
        "skeleton.mot",
        "skeleton.osim",
    ]
    .into_iter()
    .filter(|name| with_c3d || !name.ends_with(".c3d"))
    .collect()
}

/// Makes the files of [`run`] and hands each to `emit` as it is made, in the order of
/// [`file_names`], so a long capture's files are never all in memory at once. An error
/// can come after some files were emitted: the caller keeps them only when all came.
pub fn run_each<E: From<Error> + Send>(
    input: &Inputs<'_>,
    params: &Params,
    mut emit: impl FnMut(&str, Vec<u8>) -> Result<(), E> + Send,
) -> Result<(), E> {
    // The document first: it checks that the inputs belong together, which the files
    // below take for granted.
    let mut document = json::document(input)?;
    // The trajectory files (markers.trc the biggest text: every marker at every frame) are
    // made and handed over first, beside the skeleton's files, which wait for their turn.
    let (skeleton_files, filled) = rayon::join(
        || -> Result<_, Error> {
            let (model, motion) = osim::write(input, params)?;
            Ok([
                ("skeleton.bvh", bvh::write(input, params)?),
                ("skeleton.glb", glb::write(input, params)?),
                ("skeleton.mot", motion),
                ("skeleton.osim", model),
            ])
        },
        || -> Result<_, E> {
            let (markers, joints) = rayon::join(
                || fill::filled_markers(input, params),
                || trc::joint_trajectories(input, params),
            );
            let joints = joints?;
            // `trc::c3d` gives none where the capture does not fit C3D (`file_names`).
            if let Some(c3d) = trc::c3d(&joints, "joints.c3d")? {
                emit("joints.c3d", c3d)?;
            }
            emit("joints.csv", csv::write(input.skeleton))?;
            emit("joints.trc", mocap_io::trc::write(&joints).into_bytes())?;
            drop(joints);
            let markers = markers?;
            if let Some(c3d) = trc::c3d(&markers.trajectories, "markers.c3d")? {
                emit("markers.c3d", c3d)?;
            }
            emit(
                "markers.trc",
                mocap_io::trc::write(&markers.trajectories).into_bytes(),
            )?;
            Ok(markers.filled)
        },
    );
    let [bvh, glb, mot, osim] = skeleton_files?;
    for (entry, &count) in document.markers.iter_mut().zip(&filled?) {
        entry.filled_frames = count;
    }
    emit("report.html", report::write(&document))?;
    for (name, bytes) in [bvh, glb] {
        emit(name, bytes)?;
    }
    emit("skeleton.json", json::to_bytes(&document)?)?;
    for (name, bytes) in [mot, osim] {
        emit(name, bytes)?;
    }
    Ok(())
}

/// "1 frame", "26 frames": how the report and the run's findings count frames.
pub fn frame_count(n: usize) -> String {
    if n == 1 {
        "1 frame".to_owned()
    } else {
        format!("{n} frames")
    }
}

/// True when a capture's frames fit C3D's 16-bit frame numbers (the C3D files are made).
pub(crate) fn fits_c3d(capture: &mocap_io::Trajectories) -> bool {
    capture.frames() <= usize::from(u16::MAX)
}

/// File bytes as CBOR byte strings, not arrays of small integers.
mod byte_files {
    use std::collections::BTreeMap;

    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    use serde_bytes::{ByteBuf, Bytes};

    pub fn serialize<S: Serializer>(
        files: &BTreeMap<String, Vec<u8>>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        let view: BTreeMap<&str, &Bytes> = files
            .iter()
            .map(|(k, v)| (k.as_str(), Bytes::new(v)))
            .collect();
        view.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<BTreeMap<String, Vec<u8>>, D::Error> {
        let raw = BTreeMap::<String, ByteBuf>::deserialize(d)?;
        Ok(raw.into_iter().map(|(k, v)| (k, v.into_vec())).collect())
    }
}
