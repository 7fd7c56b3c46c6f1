//! skeleton.osim and skeleton.mot: the skeleton as an OpenSim 4 model and its motion as
//! the model's coordinates, so an OpenSim user opens the model, loads the motion and sees
//! the subject move, or runs inverse kinematics on the capture's own markers (placed on
//! the model's bodies) or on joints.trc's joint centres (a marker at every joint).
//!
//! One body per segment of the tree (`segment_<id>`, as skeleton.json's ids), its frame
//! the segment's rest frame (the BVH's: global axes at the segment's reference frame)
//! with its origin at the segment's parent joint (the root point for the root). Joints:
//! the root hangs on the ground by a `FreeJoint`; a ball joint is a `BallJoint`, a hinge a
//! `PinJoint` about its fitted axis, a universal joint a `UniversalJoint` about its two
//! fitted axes, a rigid pair a `WeldJoint`; each sits at the skeleton's constant offset,
//! so with every coordinate at the motion's value (see [`motion`]) the joints are where
//! forward kinematics puts them: exactly below ball joints and the root, and below a hinge
//! or universal joint as near as its one or two turns can put them (the skeleton's
//! rotation also carries what skin tilts off the axes; `export.osim_ball_joints` makes
//! every joint a ball).
//! Markers: the root point and every joint centre (named as in joints.trc) and every
//! marker of a tree segment at its median place in that segment's frame over the frames
//! both are known. Drawn as the BVH is (OpenSim shows a body only through its geometry): a
//! sphere at each body's joint and a cylinder along each bone to the next joint or, past
//! a leaf, to its End Site, sized by the median bone. Metres and radians in the model,
//! degrees in the motion.
//!
//! Mass and inertia cannot be read off marker motion: every body has a nominal 1 kg at
//! its markers' centroid and a 0.001 kg·m² inertia so the model loads and its
//! kinematics (inverse kinematics, the coordinates' plots) work; dynamics needs real
//! ones. With `export.y_up` the ground's child frame turns the capture's Z-up to
//! OpenSim's Y-up, as joints.trc is turned; the bodies keep the capture's axes.

use std::collections::BTreeSet;
use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt::Write;

use glam::{DMat3, DQuat, DVec3, Vec3Swizzles};
use jointfit::JointKind;

use crate::bvh::{children, held_root_translations};
use crate::report::escape;
use crate::{Error, Inputs, Params};

/// Nominal mass of every body (kg): marker motion does not measure it.
const NOMINAL_MASS_KG: f64 = 1.0;

/// At most this many frames, evenly strided, place the markers (a median needs no more).
const MAX_MARKER_FRAMES: usize = 2000;

/// Nominal principal moments of inertia of every body (kg·m²).
const NOMINAL_INERTIA: f64 = 0.001;

/// Radius of the sphere drawn at a joint, as a share of the median bone length.
const JOINT_RADIUS_SHARE: f64 = 0.08;

/// Radius of the cylinder drawn along a bone, as a share of the median bone length.
const BONE_RADIUS_SHARE: f64 = 0.04;

/// The OpenSim joint types the model uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum JointType {
    /// The root on the ground: three turns (body-fixed X-Y-Z), then three translations.
    Free,
    /// Three turns, body-fixed X-Y-Z.
    Ball,
    /// One turn about the frame's Z.
    Pin,
    /// A turn about the frame's X, then one about the turned Y.
    Universal,
    /// No motion.
    Weld,
}

impl JointType {
    /// The element's tag in the model file.
    fn tag(self) -> &'static str {
        match self {
            JointType::Free => "FreeJoint",
            JointType::Ball => "BallJoint",
            JointType::Pin => "PinJoint",
            JointType::Universal => "UniversalJoint",
            JointType::Weld => "WeldJoint",
        }
    }
}

/// One joint of the model: its OpenSim type, the orientation of both of its offset
/// frames in their bodies (the frames coincide at the rest pose) and its coordinates.
struct ModelJoint {
    /// OpenSim joint type.
    kind: JointType,
    /// Orientation of the joint frame in the parent's (and the child's) rest frame.
    frame: DMat3,
    /// Coordinate names, in the joint's order.
    coordinates: Vec<String>,
    /// The joints the child carries (skeleton indices): a hinge's angle is the one that
    /// puts these best.
    carried_joints: Vec<usize>,
    /// Where the child carries no joint, its markers' places in its rest frame (mm),
    /// which the hinge's angle puts best instead.
    carried_markers: Vec<DVec3>,
}

impl ModelJoint {
    /// Appends to `values` the joint's coordinate values (radians) for a child-in-parent
    /// rotation `local`, where `targets` pairs each point the child carries (in its rest
    /// frame, from the joint) with where it should be (in the parent's rest frame, from
    /// the joint).
    fn push_values(&self, local: DMat3, targets: &[(DVec3, DVec3)], values: &mut Vec<f64>) {
        // The joint turns its frame by F⁻¹ L F when the child turns by L in the parent.
        let m = self.frame.transpose() * local * self.frame;
        // In the joint's frame: each carried point and its target, and the frame's own
        // axes where the rotation takes them (at 1 mm, so they only settle what the
        // points leave free, as when nothing is carried off the axis).
        let back = self.frame.transpose();
        let pairs = || {
            targets
                .iter()
                .map(move |&(u, w)| (back * u, back * w))
                .chain([DVec3::X, DVec3::Y, DVec3::Z].map(|e| (e, m * e)))
        };
        match self.kind {
            JointType::Ball => values.extend(xyz_angles(m)),
            JointType::Pin => {
                values.push(turn_about_x(pairs().map(|(u, w)| (u.zxy(), w.zxy()))));
            }
            // Rx(a)·Ry(b), each angle best for the other in turn (a few rounds settle it).
            JointType::Universal => {
                let (mut a, mut b) = (f64::atan2(m.col(1).z, m.col(1).y), 0.0);
                for _ in 0..ROUNDS {
                    let undo_a = DMat3::from_rotation_x(-a);
                    b = turn_about_x(pairs().map(|(u, w)| (u.yzx(), (undo_a * w).yzx())));
                    let turn_b = DMat3::from_rotation_y(b);
                    a = turn_about_x(pairs().map(|(u, w)| (turn_b * u, w)));
                }
                values.extend([a, b]);
            }
            JointType::Free | JointType::Weld => {}
        }
    }

    /// The child-in-parent rotation the joint makes at coordinate `values`.
    fn rotation(&self, values: &[f64]) -> DMat3 {
        let turn = match (self.kind, values) {
            (JointType::Ball, &[a, b, c]) => {
                DMat3::from_rotation_x(a) * DMat3::from_rotation_y(b) * DMat3::from_rotation_z(c)
            }
            (JointType::Pin, &[a]) => DMat3::from_rotation_z(a),
            (JointType::Universal, &[a, b]) => {
                DMat3::from_rotation_x(a) * DMat3::from_rotation_y(b)
            }
            _ => DMat3::IDENTITY,
        };
        self.frame * turn * self.frame.transpose()
    }
}

/// Rounds of a universal joint's alternating fit of its two angles.
const ROUNDS: usize = 8;

/// The angle a of Rx(a) that puts each `u` nearest its `w` (least squares).
fn turn_about_x(pairs: impl Iterator<Item = (DVec3, DVec3)>) -> f64 {
    let (mut sin, mut cos) = (0.0, 0.0);
    for (u, w) in pairs {
        sin += u.y * w.z - u.z * w.y;
        cos += u.y * w.y + u.z * w.z;
    }
    f64::atan2(sin, cos)
}

/// Angles (a, b, c) of R = Rx(a)·Ry(b)·Rz(c), OpenSim's body-fixed X-Y-Z sequence.
fn xyz_angles(m: DMat3) -> [f64; 3] {
    let r = |i: usize, j: usize| m.col(j)[i];
    let b = r(0, 2).clamp(-1.0, 1.0).asin();
    if r(0, 2).abs() < 1.0 - 1e-12 {
        [
            f64::atan2(-r(1, 2), r(2, 2)),
            b,
            f64::atan2(-r(0, 1), r(0, 0)),
        ]
    } else {
        // Gimbal lock: only a ± c is fixed; put it all in a.
        [f64::atan2(r(2, 1), r(1, 1)), b, 0.0]
    }
}

/// A frame whose Z is `axis` (unit), for a hinge's offset frames.
fn frame_with_z(axis: DVec3) -> DMat3 {
    let z = axis.normalize();
    let x = z.any_orthonormal_vector();
    DMat3::from_cols(x, z.cross(x), z)
}

/// A frame whose X is `first` and whose Y is `second` made square to it, for a universal
/// joint (exact where the fitted axes are square, as a cardan joint's are).
fn frame_with_xy(first: DVec3, second: DVec3) -> DMat3 {
    let x = first.normalize();
    let y = (second - x * second.dot(x))
        .try_normalize()
        .unwrap_or_else(|| x.any_orthonormal_vector());
    DMat3::from_cols(x, y, x.cross(y))
}

/// The model's joints, in skeleton order, with the root's free joint last; `places` are
/// the bodies' markers (see [`marker_places`]), in metres.
fn model_joints(
    input: &Inputs<'_>,
    places: &[Vec<(usize, DVec3)>],
    all_ball: bool,
) -> Vec<ModelJoint> {
    let skel = input.skeleton;
    let mut joints: Vec<ModelJoint> = skel
        .joints
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let carried_joints: Vec<usize> = (0..skel.joints.len())
                .filter(|&k| skel.joints[k].parent == Some(j))
                .collect();
            let carried_markers: Vec<DVec3> = if carried_joints.is_empty() {
                places[j].iter().map(|&(_, p)| p * 1000.0).collect()
            } else {
                Vec::new()
            };
            let pair = input.fits.pairs.get(joint.pair).filter(|_| !all_ball);
            let name = |suffix: &str| format!("{}_{suffix}", joint.name);
            // An axis fixed in the parent segment's frame: the pair's a or b side.
            let in_parent = |a: [f64; 3], b: [f64; 3]| {
                let on_a = pair.is_some_and(|p| p.a == joint.parent_segment);
                Some(DVec3::from_array(if on_a { a } else { b }))
                    .filter(|v| v.is_finite() && v.length() > 0.0)
            };
            let hinge_axis = pair
                .filter(|p| p.kind == JointKind::Hinge)
                .and_then(|p| in_parent(p.axis_in_a?, p.axis_in_b?));
            let cardan_axes = pair
                .filter(|p| p.kind == JointKind::Universal)
                .and_then(|p| p.universal_axes)
                .and_then(|[a, b]| Some((in_parent(a, b)?, in_parent(b, a)?)));
            let (kind, frame, coordinates) = if let Some(axis) = hinge_axis {
                (JointType::Pin, frame_with_z(axis), vec![name("angle")])
            } else if let Some((first, second)) = cardan_axes {
                let coordinates = vec![name("rx"), name("ry")];
                (
                    JointType::Universal,
                    frame_with_xy(first, second),
                    coordinates,
                )
            } else if pair.is_some_and(|p| p.kind == JointKind::Rigid) {
                (JointType::Weld, DMat3::IDENTITY, Vec::new())
            } else {
                let coordinates = vec![name("rx"), name("ry"), name("rz")];
                (JointType::Ball, DMat3::IDENTITY, coordinates)
            };
            ModelJoint {
                kind,
                frame,
                coordinates,
                carried_joints,
                carried_markers,
            }
        })
        .collect();
    let root = &skel.root_name;
    joints.push(ModelJoint {
        kind: JointType::Free,
        frame: DMat3::IDENTITY,
        coordinates: ["rx", "ry", "rz", "tx", "ty", "tz"]
            .iter()
            .map(|s| format!("{root}_{s}"))
            .collect(),
        carried_joints: Vec::new(),
        carried_markers: Vec::new(),
    });
    joints
}

/// Every frame's coordinate values, joints in skeleton order then the root's six
/// (three rotations, then the root point in metres, held where unknown as in the BVH);
/// each angle unwrapped along the frames so a turn past ±180° does not jump.
///
/// Root to leaves, each joint's values are read against the model's own pose of its
/// parent (not the skeleton's), so what a hinge cannot follow is not added up down the
/// chain: a ball joint turns its child exactly as the skeleton does, a hinge by the angle
/// that puts the child's joints (or markers) nearest where the skeleton has them.
fn motion(input: &Inputs<'_>, joints: &[ModelJoint]) -> Vec<Vec<f64>> {
    let skel = input.skeleton;
    let n = skel.joints.len();
    let root_translations = held_root_translations(&skel.root_translations);
    let mut rows: Vec<Vec<f64>> = Vec::with_capacity(skel.frame_count);
    let mut targets: Vec<(DVec3, DVec3)> = Vec::new();
    let mut turns: Vec<DQuat> = Vec::with_capacity(n + 1);
    let mut rotations: Vec<DMat3> = Vec::with_capacity(n + 1);
    let mut places: Vec<DVec3> = Vec::with_capacity(n);
    let mut model_rotations: Vec<DMat3> = vec![DMat3::IDENTITY; n + 1];
    let mut model_places: Vec<DVec3> = vec![DVec3::ZERO; n];
    for (f, &root_point) in root_translations.iter().enumerate() {
        // The skeleton's pose: every body's rotation, every joint's place (full FK).
        segment_rotations(skel, f, &mut turns);
        rotations.clear();
        rotations.extend(turns.iter().map(|&q| DMat3::from_quat(q)));
        places.clear();
        for joint in &skel.joints {
            let (origin, turn) = match joint.parent {
                Some(p) => (places[p], rotations[p]),
                None => (root_point, rotations[n]),
            };
            places.push(origin + turn * DVec3::from_array(joint.offset));
        }
        // The model's pose, built as the values are read.
        model_rotations[n] = rotations[n];
        let mut row = Vec::with_capacity(rows.last().map_or(0, Vec::len));
        for (j, (joint, model)) in skel.joints.iter().zip(joints).enumerate() {
            let (origin, turn) = match joint.parent {
                Some(p) => (model_places[p], model_rotations[p]),
                None => (root_point, model_rotations[n]),
            };
            let at = origin + turn * DVec3::from_array(joint.offset);
            model_places[j] = at;
            let back = turn.transpose();
            targets.clear();
            targets.extend(model.carried_joints.iter().map(|&k| {
                (
                    DVec3::from_array(skel.joints[k].offset),
                    back * (places[k] - at),
                )
            }));
            targets.extend(
                model
                    .carried_markers
                    .iter()
                    .map(|&u| (u, back * (rotations[j] * u + places[j] - at))),
            );
            let first = row.len();
            model.push_values(back * rotations[j], &targets, &mut row);
            model_rotations[j] = turn * model.rotation(&row[first..]);
        }
        row.extend(xyz_angles(rotations[n]));
        row.extend((root_point / 1000.0).to_array());
        if let Some(before) = rows.last() {
            let angles = row.len() - 3;
            for (value, &previous) in row[..angles].iter_mut().zip(before) {
                *value -= 2.0 * PI * ((*value - previous) / (2.0 * PI)).round();
            }
        }
        rows.push(row);
    }
    rows
}

/// Global rotation of every joint's child segment (then the root's) in frame `f`, into
/// `global` (cleared first).
fn segment_rotations(skel: &bonefit::Skeleton, f: usize, global: &mut Vec<DQuat>) {
    let root = DQuat::from_array(skel.root_rotations[f]).normalize();
    global.clear();
    for joint in &skel.joints {
        let parent = joint.parent.map_or(root, |p| global[p]);
        global.push((parent * DQuat::from_array(joint.local_rotations[f])).normalize());
    }
    global.push(root);
}

/// Each tree segment's capture markers with their median place in the segment's body
/// frame (metres) over the frames (at most [`MAX_MARKER_FRAMES`], evenly strided) where
/// the marker and the segment's origin are known;
/// bodies indexed as the joints (child segment), the root last.
fn marker_places(input: &Inputs<'_>, bodies: &[usize]) -> Vec<Vec<(usize, DVec3)>> {
    let skel = input.skeleton;
    let traj = input.trajectories;
    let n = skel.joints.len();
    let mut samples: Vec<Vec<Vec<DVec3>>> = bodies
        .iter()
        .map(|&s| {
            let count = input
                .segmentation
                .segments
                .get(s)
                .map_or(0, |seg| seg.markers.len());
            vec![Vec::new(); count]
        })
        .collect();
    let frames = skel.frame_count.min(traj.frames());
    let mut rotations: Vec<DQuat> = Vec::with_capacity(n + 1);
    for f in (0..frames).step_by(frames.div_ceil(MAX_MARKER_FRAMES).max(1)) {
        segment_rotations(skel, f, &mut rotations);
        for (b, &s) in bodies.iter().enumerate() {
            let origin = if b == n {
                skel.root_positions[f]
            } else {
                skel.joints[b].positions[f]
            };
            let origin = DVec3::from_array(origin);
            let Some(segment) = input.segmentation.segments.get(s) else {
                continue;
            };
            if !origin.is_finite() {
                continue;
            }
            let inverse = rotations[b].inverse();
            for (k, &m) in segment.markers.iter().enumerate() {
                if let Some(p) = traj.get(f, m) {
                    samples[b][k].push(inverse * (DVec3::from_array(p) - origin) / 1000.0);
                }
            }
        }
    }
    bodies
        .iter()
        .zip(samples)
        .map(|(&s, per_marker)| {
            let markers = input
                .segmentation
                .segments
                .get(s)
                .map_or(&[][..], |seg| &seg.markers[..]);
            markers
                .iter()
                .zip(per_marker)
                .filter(|(_, v)| !v.is_empty())
                .map(|(&m, v)| (m, median_point(v)))
                .collect()
        })
        .collect()
}

/// Per-coordinate median of a non-empty set of points.
fn median_point(mut points: Vec<DVec3>) -> DVec3 {
    let mut out = [0.0; 3];
    for (axis, value) in out.iter_mut().enumerate() {
        points.sort_by(|a, b| a.to_array()[axis].total_cmp(&b.to_array()[axis]));
        let k = points.len();
        let at = |i: usize| points[i].to_array()[axis];
        *value = if k % 2 == 1 {
            at(k / 2)
        } else {
            0.5 * (at(k / 2 - 1) + at(k / 2))
        };
    }
    DVec3::from_array(out)
}

/// An OpenSim component name: OpenSim refuses whitespace, '/', '\\', '*' and '+' in
/// names, so those become '_'; markup's special characters are escaped (the report's
/// escaping: its `&#39;` is XML's too).
fn component_name(label: &str) -> String {
    let cleaned: String = label
        .chars()
        .map(|c| {
            if c.is_whitespace() || matches!(c, '/' | '\\' | '*' | '+') {
                '_'
            } else {
                c
            }
        })
        .collect();
    escape(&cleaned)
}

/// Three numbers to a micrometre (or microradian), no negative zero.
fn vec3(v: DVec3) -> String {
    let c = |x: f64| if x.abs() < 5e-7 { 0.0 } else { x };
    format!("{:.6} {:.6} {:.6}", c(v.x), c(v.y), c(v.z))
}

/// A joint's offset frame: fixed on a body (or the ground) at a place and orientation.
struct OffsetFrame {
    /// Frame name, unique within its joint.
    name: String,
    /// Path of the body (or ground) it is fixed on.
    on: String,
    /// Its origin in that body's frame (m).
    at: DVec3,
    /// Its orientation there, OpenSim's body-fixed X-Y-Z angles (rad).
    orientation: DVec3,
}

/// One joint element: its coordinates (with their defaults) and its two offset frames.
fn write_joint(
    out: &mut String,
    name: &str,
    model: &ModelJoint,
    defaults: &[f64],
    parent: &OffsetFrame,
    child: &OffsetFrame,
) {
    let tag = model.kind.tag();
    let _ = writeln!(out, "\t\t\t\t<{tag} name=\"{}\">", escape(name));
    let _ = writeln!(
        out,
        "\t\t\t\t\t<socket_parent_frame>{}</socket_parent_frame>",
        parent.name
    );
    let _ = writeln!(
        out,
        "\t\t\t\t\t<socket_child_frame>{}</socket_child_frame>",
        child.name
    );
    if !model.coordinates.is_empty() {
        out.push_str("\t\t\t\t\t<coordinates>\n");
        for (k, (coordinate, value)) in model.coordinates.iter().zip(defaults).enumerate() {
            // A free joint's last three coordinates are translations (m); the rest turn.
            let range = if model.kind == JointType::Free && k >= 3 {
                "-100 100"
            } else {
                "-3.1415926535897931 3.1415926535897931"
            };
            let _ = write!(
                out,
                "\t\t\t\t\t\t<Coordinate name=\"{}\">\n\t\t\t\t\t\t\t<default_value>{value:.6}</default_value>\n\
                 \t\t\t\t\t\t\t<range>{range}</range>\n\t\t\t\t\t\t</Coordinate>\n",
                escape(coordinate)
            );
        }
        out.push_str("\t\t\t\t\t</coordinates>\n");
    }
    out.push_str("\t\t\t\t\t<frames>\n");
    for frame in [parent, child] {
        let _ = write!(
            out,
            "\t\t\t\t\t\t<PhysicalOffsetFrame name=\"{}\">\n\
             \t\t\t\t\t\t\t<socket_parent>{}</socket_parent>\n\
             \t\t\t\t\t\t\t<translation>{}</translation>\n\
             \t\t\t\t\t\t\t<orientation>{}</orientation>\n\
             \t\t\t\t\t\t</PhysicalOffsetFrame>\n",
            frame.name,
            frame.on,
            vec3(frame.at),
            vec3(frame.orientation)
        );
    }
    out.push_str("\t\t\t\t\t</frames>\n");
    let _ = writeln!(out, "\t\t\t\t</{tag}>");
}

/// skeleton.mot: a row per frame on joints.trc's clock (frame index / rate), angles in
/// degrees, the root's translations (the last three columns) in metres.
fn write_motion(joints: &[ModelJoint], rows: &[Vec<f64>], rate: f64) -> String {
    let mut mot = String::new();
    let columns: Vec<&String> = joints.iter().flat_map(|j| j.coordinates.iter()).collect();
    let _ = write!(
        mot,
        "ossify_skeleton\nversion=1\nnRows={}\nnColumns={}\ninDegrees=yes\nendheader\ntime",
        rows.len(),
        columns.len() + 1
    );
    for c in &columns {
        let _ = write!(mot, "\t{c}");
    }
    mot.push('\n');
    let angles = columns.len().saturating_sub(3);
    for (f, row) in rows.iter().enumerate() {
        let _ = write!(mot, "{:.6}", f as f64 / rate);
        for (k, value) in row.iter().enumerate() {
            let shown = if k < angles {
                value.to_degrees()
            } else {
                *value
            };
            let _ = write!(mot, "\t{:.6}", if shown.abs() < 5e-7 { 0.0 } else { shown });
        }
        mot.push('\n');
    }
    mot
}

/// A frame whose Y is `direction` (a cylinder's axis), for a bone's drawing.
fn frame_with_y(direction: DVec3) -> DMat3 {
    let y = direction.normalize();
    let x = y.any_orthonormal_vector();
    DMat3::from_cols(x, y, x.cross(y))
}

/// The drawing of one body: a sphere at its origin (its joint) and a cylinder along each
/// bone it carries, `bones` from its origin (m), each on a frame of its own at the bone's
/// middle (a cylinder's axis is its frame's Y); `size` is the median bone length (m).
fn write_drawing(out: &mut String, bones: &[(String, DVec3)], size: f64) {
    let drawn: Vec<&(String, DVec3)> = bones.iter().filter(|(_, b)| b.length() > 1e-6).collect();
    if !drawn.is_empty() {
        out.push_str("\t\t\t\t\t<components>\n");
        for (name, bone) in drawn {
            let _ = write!(
                out,
                "\t\t\t\t\t\t<PhysicalOffsetFrame name=\"{name}\">\n\
                 \t\t\t\t\t\t\t<attached_geometry>\n\
                 \t\t\t\t\t\t\t\t<Cylinder name=\"{name}_geometry\">\n\
                 \t\t\t\t\t\t\t\t\t<socket_frame>..</socket_frame>\n\
                 \t\t\t\t\t\t\t\t\t<radius>{:.6}</radius>\n\
                 \t\t\t\t\t\t\t\t\t<half_height>{:.6}</half_height>\n\
                 \t\t\t\t\t\t\t\t</Cylinder>\n\
                 \t\t\t\t\t\t\t</attached_geometry>\n\
                 \t\t\t\t\t\t\t<socket_parent>..</socket_parent>\n\
                 \t\t\t\t\t\t\t<translation>{}</translation>\n\
                 \t\t\t\t\t\t\t<orientation>{}</orientation>\n\
                 \t\t\t\t\t\t</PhysicalOffsetFrame>\n",
                BONE_RADIUS_SHARE * size,
                bone.length() / 2.0,
                vec3(*bone / 2.0),
                vec3(DVec3::from_array(xyz_angles(frame_with_y(*bone))))
            );
        }
        out.push_str("\t\t\t\t\t</components>\n");
    }
    let _ = write!(
        out,
        "\t\t\t\t\t<attached_geometry>\n\t\t\t\t\t\t<Sphere name=\"joint_geometry\">\n\
         \t\t\t\t\t\t\t<socket_frame>..</socket_frame>\n\t\t\t\t\t\t\t<radius>{:.6}</radius>\n\
         \t\t\t\t\t\t</Sphere>\n\t\t\t\t\t</attached_geometry>\n",
        JOINT_RADIUS_SHARE * size
    );
}

/// Writes skeleton.osim and skeleton.mot (see the module docs).
pub(crate) fn write(input: &Inputs<'_>, params: &Params) -> Result<(Vec<u8>, Vec<u8>), Error> {
    let skel = input.skeleton;
    children(skel)?;
    let n = skel.joints.len();
    // Bodies as the joints (each joint's child segment), the root's segment last.
    let bodies: Vec<usize> = skel
        .joints
        .iter()
        .map(|j| j.child_segment)
        .chain(std::iter::once(skel.root_segment))
        .collect();
    let body_name = |b: usize| format!("segment_{}", bodies[b]);
    let places = marker_places(input, &bodies);
    let joints = model_joints(input, &places, params.osim_ball_joints);
    let rows = motion(input, &joints);

    let mut out = String::new();
    out.push_str(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<OpenSimDocument Version=\"40000\">\n",
    );
    out.push_str("\t<Model name=\"ossify_skeleton\">\n");
    out.push_str(
        "\t\t<credits>ossify: segments, joints and motion found from the markers alone; \
         mass and inertia are nominal</credits>\n",
    );
    out.push_str("\t\t<length_units>meters</length_units>\n\t\t<force_units>N</force_units>\n");
    out.push_str(
        "\t\t<Ground name=\"ground\" />\n\t\t<BodySet name=\"bodyset\">\n\t\t\t<objects>\n",
    );
    // Bones as the BVH draws them: to each child joint, and from a leaf's joint to its
    // End Site; the drawing is sized by the median bone.
    let mut bones: Vec<Vec<(String, DVec3)>> = vec![Vec::new(); n + 1];
    for (j, joint) in skel.joints.iter().enumerate() {
        let bone = DVec3::from_array(joint.offset) / 1000.0;
        bones[joint.parent.unwrap_or(n)].push((format!("bone_to_{}", escape(&joint.name)), bone));
        if !skel.joints.iter().any(|child| child.parent == Some(j)) {
            let end = crate::bvh::end_site(input, j) / 1000.0;
            bones[j].push((format!("bone_past_{}", escape(&joint.name)), end));
        }
    }
    let mut lengths: Vec<f64> = skel.joints.iter().map(|j| j.bone_length / 1000.0).collect();
    lengths.retain(|l| l.is_finite() && *l > 0.0);
    lengths.sort_by(f64::total_cmp);
    let size = lengths.get(lengths.len() / 2).copied().unwrap_or(0.1);
    for (b, markers) in places.iter().enumerate() {
        let centroid = if markers.is_empty() {
            DVec3::ZERO
        } else {
            markers.iter().map(|(_, p)| *p).sum::<DVec3>() / markers.len() as f64
        };
        let _ = writeln!(out, "\t\t\t\t<Body name=\"{}\">", body_name(b));
        write_drawing(&mut out, &bones[b], size);
        let _ = write!(
            out,
            "\t\t\t\t\t<mass>{NOMINAL_MASS_KG}</mass>\n\
             \t\t\t\t\t<mass_center>{}</mass_center>\n\
             \t\t\t\t\t<inertia>{i} {i} {i} 0 0 0</inertia>\n\t\t\t\t</Body>\n",
            vec3(centroid),
            i = NOMINAL_INERTIA
        );
    }
    out.push_str(
        "\t\t\t</objects>\n\t\t</BodySet>\n\t\t<JointSet name=\"jointset\">\n\t\t\t<objects>\n",
    );
    // Frame 0's coordinates are the defaults: the model opens in the capture's first
    // pose. The motion's columns are the joints' coordinates in `joints` order.
    let mut first = rows.first().cloned().unwrap_or_default().into_iter();
    let defaults: Vec<Vec<f64>> = joints
        .iter()
        .map(|j| {
            j.coordinates
                .iter()
                .map(|_| first.next().unwrap_or(0.0))
                .collect()
        })
        .collect();
    let child_frame = |b: usize| OffsetFrame {
        name: format!("{}_offset", body_name(b)),
        on: format!("/bodyset/{}", body_name(b)),
        at: DVec3::ZERO,
        orientation: DVec3::from_array(xyz_angles(joints[b].frame)),
    };
    // The root hangs on a frame of the ground turned to Y-up with `y_up` (joints.trc's
    // axes); the bodies keep the capture's.
    let ground = OffsetFrame {
        name: "ground_offset".to_owned(),
        on: "/ground".to_owned(),
        at: DVec3::ZERO,
        orientation: if params.y_up {
            DVec3::new(-FRAC_PI_2, 0.0, 0.0)
        } else {
            DVec3::ZERO
        },
    };
    let root_joint = format!("ground_{}", skel.root_name);
    write_joint(
        &mut out,
        &root_joint,
        &joints[n],
        &defaults[n],
        &ground,
        &child_frame(n),
    );
    for (j, joint) in skel.joints.iter().enumerate() {
        let parent = OffsetFrame {
            name: format!("{}_in_parent", escape(&joint.name)),
            on: format!("/bodyset/{}", body_name(joint.parent.unwrap_or(n))),
            at: DVec3::from_array(joint.offset) / 1000.0,
            orientation: DVec3::from_array(xyz_angles(joints[j].frame)),
        };
        write_joint(
            &mut out,
            &joint.name,
            &joints[j],
            &defaults[j],
            &parent,
            &child_frame(j),
        );
    }
    out.push_str(
        "\t\t\t</objects>\n\t\t</JointSet>\n\t\t<MarkerSet name=\"markerset\">\n\t\t\t<objects>\n",
    );
    let mut taken: BTreeSet<String> = BTreeSet::new();
    let mut marker = |out: &mut String, name: String, body: usize, at: DVec3| {
        if taken.insert(name.clone()) {
            let _ = write!(
                out,
                "\t\t\t\t<Marker name=\"{name}\">\n\
                 \t\t\t\t\t<socket_parent_frame>/bodyset/{}</socket_parent_frame>\n\
                 \t\t\t\t\t<location>{}</location>\n\t\t\t\t\t<fixed>true</fixed>\n\t\t\t\t</Marker>\n",
                body_name(body),
                vec3(at)
            );
        }
    };
    // Joint centres first (joints.trc's names: a child body's origin is its joint), then
    // the capture's markers; a label already taken by a joint centre is left out.
    marker(&mut out, component_name(&skel.root_name), n, DVec3::ZERO);
    for (j, joint) in skel.joints.iter().enumerate() {
        marker(&mut out, component_name(&joint.name), j, DVec3::ZERO);
    }
    let labels = input.trajectories.labels();
    for (b, markers) in places.iter().enumerate() {
        for &(m, at) in markers {
            if let Some(label) = labels.get(m) {
                marker(&mut out, component_name(label), b, at);
            }
        }
    }
    out.push_str("\t\t\t</objects>\n\t\t</MarkerSet>\n\t</Model>\n</OpenSimDocument>\n");
    let mot = write_motion(&joints, &rows, skel.frame_rate);
    Ok((out.into_bytes(), mot.into_bytes()))
}

#[cfg(test)]
mod tests {
    use glam::{DMat3, DVec3};

    use super::{JointType, ModelJoint, component_name, frame_with_xy, frame_with_z, xyz_angles};

    /// The values `joint` reads for `local` with `targets`.
    fn read_values(joint: &ModelJoint, local: DMat3, targets: &[(DVec3, DVec3)]) -> Vec<f64> {
        let mut out = Vec::new();
        joint.push_values(local, targets, &mut out);
        out
    }

    fn joint(kind: JointType, frame: DMat3) -> ModelJoint {
        ModelJoint {
            kind,
            frame,
            coordinates: Vec::new(),
            carried_joints: Vec::new(),
            carried_markers: Vec::new(),
        }
    }

    fn close(a: DMat3, b: DMat3) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() < 1e-6)
    }

    #[test]
    fn xyz_angles_are_rx_ry_rz_and_round_trip() {
        for &(a, b, c) in &[
            (0.3, -0.5, 0.7),
            (-2.9, 1.2, 3.0),
            (0.0, 0.0, 0.0),
            (1.0, -1.5, -0.2),
        ] {
            let m =
                DMat3::from_rotation_x(a) * DMat3::from_rotation_y(b) * DMat3::from_rotation_z(c);
            let [x, y, z] = xyz_angles(m);
            assert!((x - a).abs() < 1e-9 && (y - b).abs() < 1e-9 && (z - c).abs() < 1e-9);
        }
        // Gimbal lock: the angles still make the rotation.
        let m = DMat3::from_rotation_x(0.4) * DMat3::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let [x, y, z] = xyz_angles(m);
        let back =
            DMat3::from_rotation_x(x) * DMat3::from_rotation_y(y) * DMat3::from_rotation_z(z);
        assert!(close(back, m));
    }

    #[test]
    fn each_joint_reads_back_the_turns_it_can_make() {
        let axis = DVec3::new(0.3, -0.8, 0.5).normalize();
        let pin = joint(JointType::Pin, frame_with_z(axis));
        // The pin's frame is a rotation (orthonormal), so at 0 the child sits as at rest.
        assert!(close(pin.frame * pin.frame.transpose(), DMat3::IDENTITY));
        for angle in [-2.5, -0.3, 0.0, 1.1, 3.0] {
            let turn = DMat3::from_axis_angle(axis, angle);
            let values = read_values(&pin, turn, &[]);
            assert!((values[0] - angle).abs() < 1e-9, "{values:?} for {angle}");
            assert!(close(pin.rotation(&values), turn));
        }
        let second = DVec3::new(0.9, 0.1, 0.2);
        let cardan = joint(JointType::Universal, frame_with_xy(axis, second));
        let f = cardan.frame;
        assert!(
            (f * DVec3::X - axis).length() < 1e-12,
            "X is the first axis"
        );
        for (a, b) in [(0.4, -0.7), (-1.2, 0.3), (2.0, 1.0)] {
            let turn = f * DMat3::from_rotation_x(a) * DMat3::from_rotation_y(b) * f.transpose();
            let values = read_values(
                &cardan,
                turn,
                &[(
                    DVec3::new(0.0, 0.0, -400.0),
                    turn * DVec3::new(0.0, 0.0, -400.0),
                )],
            );
            assert!(
                (values[0] - a).abs() < 1e-6 && (values[1] - b).abs() < 1e-6,
                "{values:?}"
            );
            assert!(close(cardan.rotation(&values), turn));
        }
        let ball = joint(JointType::Ball, DMat3::IDENTITY);
        let turn = DMat3::from_axis_angle(axis, 1.3);
        assert!(close(ball.rotation(&read_values(&ball, turn, &[])), turn));
    }

    #[test]
    fn names_lose_what_opensim_refuses() {
        assert_eq!(component_name("Subject:LASI"), "Subject:LASI");
        assert_eq!(component_name("L ASI/2*x+y\\z"), "L_ASI_2_x_y_z");
        assert_eq!(component_name("a&b\"c"), "a&amp;b&quot;c");
    }
}
