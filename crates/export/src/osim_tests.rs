//! Tests of skeleton.osim and skeleton.mot: a small XML reader and OpenSim's joint
//! conventions, independent of the writer, pose the model at the motion's coordinates.

use std::collections::BTreeMap;

use crate::tests::{files, files_of, gappy_scene, json, json_point, skeleton, text};
use crate::{Inputs, Params};
use bonefit::testkit::scene;
use glam::{DMat3, DVec3};

/// An XML element: tag, `name` attribute, text and children.
struct Element {
    tag: String,
    name: String,
    text: String,
    children: Vec<Element>,
}

impl Element {
    /// The first child with this tag.
    fn child(&self, tag: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.tag == tag)
    }

    /// A child's text read as numbers.
    fn numbers(&self, tag: &str) -> Vec<f64> {
        self.child(tag)
            .map(|c| {
                c.text
                    .split_whitespace()
                    .map(|x| x.parse().unwrap_or(f64::NAN))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// A child's three numbers as a vector.
    fn vector(&self, tag: &str) -> DVec3 {
        match self.numbers(tag)[..] {
            [x, y, z] => DVec3::new(x, y, z),
            _ => panic!("{} {}: no three numbers in <{tag}>", self.tag, self.name),
        }
    }
}

/// Reads one XML document (no comments, no CDATA: what the writer makes).
fn parse_xml(text: &str) -> Element {
    let mut stack = vec![Element {
        tag: String::new(),
        name: String::new(),
        text: String::new(),
        children: Vec::new(),
    }];
    let mut rest = text;
    while let Some(open) = rest.find('<') {
        let before = &rest[..open];
        if let Some(top) = stack.last_mut() {
            top.text.push_str(before.trim());
        }
        let close = rest[open..]
            .find('>')
            .map(|c| open + c)
            .expect("unclosed tag");
        let tag = &rest[open + 1..close];
        rest = &rest[close + 1..];
        if tag.starts_with('?') {
            continue;
        }
        if let Some(end) = tag.strip_prefix('/') {
            let done = stack.pop().expect("unbalanced");
            assert_eq!(done.tag, end.trim(), "mismatched closing tag");
            stack.last_mut().expect("root").children.push(done);
            continue;
        }
        let self_closing = tag.ends_with('/');
        let tag = tag.trim_end_matches('/').trim();
        let (head, attributes) = tag.split_once(' ').unwrap_or((tag, ""));
        let name = attributes
            .split_once("name=\"")
            .and_then(|(_, r)| r.split_once('"'))
            .map_or(String::new(), |(n, _)| n.to_owned());
        let element = Element {
            tag: head.to_owned(),
            name,
            text: String::new(),
            children: Vec::new(),
        };
        if self_closing {
            stack.last_mut().expect("root").children.push(element);
        } else {
            stack.push(element);
        }
    }
    assert_eq!(stack.len(), 1, "unclosed elements");
    stack.pop().expect("root")
}

/// OpenSim's body-fixed X-Y-Z rotation.
fn xyz(a: f64, b: f64, c: f64) -> DMat3 {
    DMat3::from_rotation_x(a) * DMat3::from_rotation_y(b) * DMat3::from_rotation_z(c)
}

/// A rigid transform: rotation, then translation.
#[derive(Clone, Copy)]
struct Transform(DMat3, DVec3);

impl Transform {
    fn then(self, inner: Transform) -> Transform {
        Transform(self.0 * inner.0, self.0 * inner.1 + self.1)
    }
    fn inverse(self) -> Transform {
        let r = self.0.transpose();
        Transform(r, -(r * self.1))
    }
    fn apply(self, p: DVec3) -> DVec3 {
        self.0 * p + self.1
    }
}

/// The model: every body's pose in ground for coordinate values, and the markers.
struct Model {
    root: Element,
}

impl Model {
    fn read(text: &str) -> Self {
        let doc = parse_xml(text);
        let root = doc.children.into_iter().next().expect("an OpenSimDocument");
        assert_eq!(root.tag, "OpenSimDocument");
        Model { root }
    }

    fn model(&self) -> &Element {
        self.root.child("Model").expect("a Model")
    }

    fn joints(&self) -> Vec<&Element> {
        let set = self
            .model()
            .child("JointSet")
            .and_then(|s| s.child("objects"));
        set.map(|s| s.children.iter().collect()).unwrap_or_default()
    }

    /// Each body's pose in ground (metres) with the coordinates at `values` (radians and
    /// metres), parents before children as OpenSim requires of the joint set here.
    fn pose(&self, values: &BTreeMap<String, f64>) -> BTreeMap<String, Transform> {
        let mut bodies: BTreeMap<String, Transform> = BTreeMap::new();
        bodies.insert(
            "/ground".to_owned(),
            Transform(DMat3::IDENTITY, DVec3::ZERO),
        );
        for joint in self.joints() {
            let frames: Vec<&Element> = joint
                .child("frames")
                .map(|f| f.children.iter().collect())
                .unwrap_or_default();
            let frame = |socket: &str| {
                let wanted = &joint.child(socket).expect("socket").text;
                let f = frames.iter().find(|f| &f.name == wanted).expect("frame");
                let on = f.child("socket_parent").expect("parent").text.clone();
                let o = f.vector("orientation");
                (on, Transform(xyz(o.x, o.y, o.z), f.vector("translation")))
            };
            let (parent_body, parent_offset) = frame("socket_parent_frame");
            let (child_body, child_offset) = frame("socket_child_frame");
            let q: Vec<f64> = joint
                .child("coordinates")
                .map(|c| {
                    c.children
                        .iter()
                        .map(|c| {
                            *values
                                .get(&c.name)
                                .unwrap_or_else(|| panic!("no {}", c.name))
                        })
                        .collect()
                })
                .unwrap_or_default();
            let motion = match (joint.tag.as_str(), &q[..]) {
                ("FreeJoint", &[a, b, c, x, y, z]) => Transform(xyz(a, b, c), DVec3::new(x, y, z)),
                ("BallJoint", &[a, b, c]) => Transform(xyz(a, b, c), DVec3::ZERO),
                ("PinJoint", &[a]) => Transform(DMat3::from_rotation_z(a), DVec3::ZERO),
                ("UniversalJoint", &[a, b]) => Transform(xyz(a, b, 0.0), DVec3::ZERO),
                ("WeldJoint", &[]) => Transform(DMat3::IDENTITY, DVec3::ZERO),
                (kind, q) => panic!("{kind} with {} coordinates", q.len()),
            };
            let parent = *bodies.get(&parent_body).expect("parent posed first");
            let child = parent
                .then(parent_offset)
                .then(motion)
                .then(child_offset.inverse());
            bodies.insert(child_body, child);
        }
        bodies
    }

    /// Each marker's place in ground (mm) with the coordinates at `values`.
    fn markers(&self, values: &BTreeMap<String, f64>) -> BTreeMap<String, DVec3> {
        let bodies = self.pose(values);
        let set = self
            .model()
            .child("MarkerSet")
            .and_then(|s| s.child("objects"));
        set.map(|s| &s.children[..])
            .unwrap_or_default()
            .iter()
            .map(|m| {
                let body = &m.child("socket_parent_frame").expect("body").text;
                let pose = bodies.get(body).expect("marker on a body");
                (m.name.clone(), pose.apply(m.vector("location")) * 1000.0)
            })
            .collect()
    }
}

/// The motion's rows as coordinate values (radians, metres) by name, with the times.
fn read_motion(text: &str) -> (Vec<f64>, Vec<BTreeMap<String, f64>>) {
    let (header, table) = text.split_once("endheader\n").expect("a header");
    assert!(header.contains("inDegrees=yes"));
    let mut lines = table.lines();
    let columns: Vec<&str> = lines.next().expect("column names").split('\t').collect();
    assert_eq!(columns[0], "time");
    let mut times = Vec::new();
    let rows = lines
        .map(|line| {
            let values: Vec<f64> = line
                .split('\t')
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect();
            assert_eq!(values.len(), columns.len());
            times.push(values[0]);
            columns[1..]
                .iter()
                .zip(&values[1..])
                .map(|(c, &v)| {
                    let translation = ["_tx", "_ty", "_tz"].iter().any(|t| c.ends_with(t));
                    (c.to_string(), if translation { v } else { v.to_radians() })
                })
                .collect()
        })
        .collect();
    (times, rows)
}

/// Poses the model at every frame of the motion and compares its joint markers with the
/// JSON's positions (in `axes`) and its capture markers with the capture; returns the
/// largest joint and marker errors (mm) and how many joint positions were compared.
pub(crate) fn check_model(
    out: &crate::Outputs,
    input: &Inputs<'_>,
    axes: impl Fn(DVec3) -> DVec3,
) -> (f64, f64, usize) {
    let model = Model::read(&text(out, "skeleton.osim"));
    let (times, rows) = read_motion(&text(out, "skeleton.mot"));
    let doc = json(out);
    let rate = doc["frame_rate"].as_f64().unwrap_or(0.0);
    assert_eq!(
        rows.len(),
        doc["frame_count"].as_u64().unwrap_or(0) as usize
    );
    let (mut joint_error, mut marker_error, mut compared) = (0.0f64, 0.0f64, 0);
    let mut markers_compared = 0;
    for (f, values) in rows.iter().enumerate() {
        assert!(
            (times[f] - f as f64 / rate).abs() < 1e-6,
            "joints.trc's clock"
        );
        let markers = model.markers(values);
        let mut everything_known = !doc["root"]["positions"][f].is_null();
        for j in doc["joints"].as_array().into_iter().flatten() {
            let p = &j["positions"][f];
            if p.is_null() {
                everything_known = false;
                continue;
            }
            let name = j["name"].as_str().unwrap_or_default();
            let at = markers
                .get(name)
                .unwrap_or_else(|| panic!("no marker {name}"));
            joint_error = joint_error.max((*at - axes(json_point(p))).length());
            compared += 1;
        }
        // Where the skeleton does not know a segment, neither does the motion.
        if !everything_known {
            continue;
        }
        for (m, label) in input.trajectories.labels().iter().enumerate() {
            if let (Some(at), Some(p)) = (markers.get(label), input.trajectories.get(f, m)) {
                marker_error = marker_error.max((*at - axes(DVec3::from_array(p))).length());
                markers_compared += 1;
            }
        }
    }
    assert!(
        markers_compared > rows.len(),
        "markers compared in too few frames"
    );
    (joint_error, marker_error, compared)
}

#[test]
fn the_model_at_the_motions_coordinates_puts_joints_and_markers_where_the_json_has_them() {
    // Exact poses: a ball hip, a hinged knee (pure turns about its axis), a ball neck.
    let s = gappy_scene();
    let skeleton = skeleton(&s);
    let input = crate::tests::inputs(&s, &s.segmentation, &skeleton);
    for y_up in [false, true] {
        let out = files(
            &s,
            &Params {
                y_up,
                ..Params::default()
            },
        );
        let turn = |p: DVec3| if y_up { DVec3::new(p.x, p.z, -p.y) } else { p };
        let (joints, markers, compared) = check_model(&out, &input, turn);
        assert!(compared > 200, "only {compared} joint positions compared");
        assert!(joints < 0.01, "joint centres off by {joints} mm");
        // Markers sit at their median place in their segment; exact data, so exactly.
        assert!(markers < 0.01, "markers off by {markers} mm");
    }
    let out = files(&s, &Params::default());
    let model = Model::read(&text(&out, "skeleton.osim"));
    let kinds: Vec<&str> = model.joints().iter().map(|j| j.tag.as_str()).collect();
    // The root's free joint, then the skeleton's: hip and neck balls, the knee a pin.
    assert_eq!(kinds, ["FreeJoint", "BallJoint", "BallJoint", "PinJoint"]);
    let bodies = model
        .model()
        .child("BodySet")
        .and_then(|b| b.child("objects"));
    assert_eq!(bodies.map_or(0, |b| b.children.len()), 4);
    // Every capture marker and the root and three joint centres.
    let markers = model
        .model()
        .child("MarkerSet")
        .and_then(|m| m.child("objects"));
    assert_eq!(markers.map_or(0, |m| m.children.len()), 12 + 4);
    assert!(!text(&out, "skeleton.mot").contains("NaN"));
}

#[test]
fn a_hinge_turning_off_its_axis_keeps_its_turn_about_the_axis() {
    // The knee's skeleton rotation also tilts 0.2 rad about Y (skin tilting a hinge): the
    // pin cannot follow the tilt, but its angle is still the knee's turn about its axis.
    let s = scene(60, 60.0);
    let mut skeleton = skeleton(&s);
    let knee = skeleton
        .joints
        .iter()
        .position(|j| s.fits.pairs[j.pair].kind == jointfit::JointKind::Hinge)
        .expect("a hinge");
    for q in &mut skeleton.joints[knee].local_rotations {
        let tilted = glam::DQuat::from_array(*q) * glam::DQuat::from_rotation_y(0.2);
        *q = tilted.to_array();
    }
    let out = files_of(&s, &skeleton, &Params::default());
    let (_, rows) = read_motion(&text(&out, "skeleton.mot"));
    let name = format!("{}_angle", skeleton.joints[knee].name);
    for (f, values) in rows.iter().enumerate() {
        // The scene's knee turns by −(0.5 + 0.5 sin 3t) about X, its axis.
        let t = f as f64 / 60.0;
        let want = -(0.5 + 0.5 * (3.0 * t).sin());
        let got = values[&name];
        assert!(
            (got - want).abs() < 0.01,
            "frame {f}: {got} rad about the pin for {want} about the axis"
        );
    }
}

/// Sets the joints' positions to what the skeleton's rotations and offsets make.
fn forward_kinematics(skeleton: &mut bonefit::Skeleton) {
    for f in 0..skeleton.frame_count {
        let root = glam::DQuat::from_array(skeleton.root_rotations[f]);
        let mut turns: Vec<glam::DQuat> = Vec::new();
        for j in 0..skeleton.joints.len() {
            let joint = &skeleton.joints[j];
            let (origin, turn) = match joint.parent {
                Some(p) => (DVec3::from_array(skeleton.joints[p].positions[f]), turns[p]),
                None => (DVec3::from_array(skeleton.root_translations[f]), root),
            };
            let at = origin + turn * DVec3::from_array(joint.offset);
            turns.push(turn * glam::DQuat::from_array(joint.local_rotations[f]));
            skeleton.joints[j].positions[f] = at.to_array();
        }
    }
}

#[test]
fn with_ball_joints_the_model_follows_every_turn_exactly() {
    // Every joint also tilts 0.2 rad about Y, which the knee's pin cannot make.
    let s = scene(60, 60.0);
    let mut skeleton = skeleton(&s);
    for joint in &mut skeleton.joints {
        for q in &mut joint.local_rotations {
            *q = (glam::DQuat::from_array(*q) * glam::DQuat::from_rotation_y(0.2)).to_array();
        }
    }
    forward_kinematics(&mut skeleton);
    let input = crate::tests::inputs(&s, &s.segmentation, &skeleton);
    let kinds = |out: &crate::Outputs| -> Vec<String> {
        let model = Model::read(&text(out, "skeleton.osim"));
        model.joints().iter().map(|j| j.tag.clone()).collect()
    };
    let fitted = files_of(&s, &skeleton, &Params::default());
    assert!(kinds(&fitted).iter().any(|k| k == "PinJoint"));
    let params = Params {
        osim_ball_joints: true,
        ..Params::default()
    };
    let balls = files_of(&s, &skeleton, &params);
    assert_eq!(
        kinds(&balls),
        ["FreeJoint", "BallJoint", "BallJoint", "BallJoint"]
    );
    let (joints, _, compared) = check_model(&balls, &input, |p| p);
    assert!(
        compared > 100 && joints < 0.01,
        "{joints} mm over {compared}"
    );
}

#[test]
fn a_model_without_joints_is_one_free_body() {
    let s = scene(20, 60.0);
    let mut skeleton = skeleton(&s);
    skeleton.joints.clear();
    let out = files_of(&s, &skeleton, &Params::default());
    let model = Model::read(&text(&out, "skeleton.osim"));
    let kinds: Vec<&str> = model.joints().iter().map(|j| j.tag.as_str()).collect();
    assert_eq!(kinds, ["FreeJoint"]);
    let (_, rows) = read_motion(&text(&out, "skeleton.mot"));
    assert_eq!(rows.len(), 20);
    assert_eq!(rows[0].len(), 6);
}

#[test]
fn labels_opensim_refuses_are_renamed_and_escaped() {
    let mut s = scene(20, 60.0);
    let mut labels: Vec<String> = s.trajectories.labels().to_vec();
    labels[0] = "Subject:L ASI".to_owned();
    labels[1] = "a/b&<c>".to_owned();
    let positions = s.trajectories.positions().to_vec();
    s.trajectories = mocap_io::Trajectories::new(labels, 60.0, 1, 20, positions)
        .unwrap_or_else(|e| panic!("{e}"));
    let out = files(&s, &Params::default());
    let osim = text(&out, "skeleton.osim");
    assert!(osim.contains("<Marker name=\"Subject:L_ASI\">"));
    assert!(osim.contains("<Marker name=\"a_b&amp;&lt;c&gt;\">"));
}

#[test]
fn each_bone_is_drawn_from_its_joint_to_the_next() {
    let s = scene(20, 60.0);
    let out = files(&s, &Params::default());
    let model = Model::read(&text(&out, "skeleton.osim"));
    // Where each joint sits on its parent body: its parent offset frame's translation.
    let joint_at: BTreeMap<String, DVec3> = model
        .joints()
        .iter()
        .filter_map(|j| {
            let frames = j.child("frames")?;
            Some((
                j.name.clone(),
                frames.children.first()?.vector("translation"),
            ))
        })
        .collect();
    let bodies = model
        .model()
        .child("BodySet")
        .and_then(|b| b.child("objects"));
    let mut drawn = 0;
    for body in bodies.map(|b| &b.children[..]).unwrap_or_default() {
        let sphere = body
            .child("attached_geometry")
            .and_then(|g| g.child("Sphere"));
        assert!(
            sphere.is_some_and(|s| s.numbers("radius")[0] > 0.0),
            "{}",
            body.name
        );
        let frames = body.child("components").map(|c| &c.children[..]);
        for frame in frames.unwrap_or_default() {
            let cylinder = frame
                .child("attached_geometry")
                .and_then(|g| g.child("Cylinder"))
                .expect("a bone's cylinder");
            let half = cylinder.numbers("half_height")[0];
            let o = frame.vector("orientation");
            let axis = xyz(o.x, o.y, o.z) * DVec3::Y * half;
            let middle = frame.vector("translation");
            // One end at the body's origin (its joint), the other at the next joint.
            assert!(
                (middle - axis).length() < 1e-5,
                "{}: {middle} − {axis}",
                frame.name
            );
            if let Some(next) = frame.name.strip_prefix("bone_to_") {
                assert!(
                    (middle + axis - joint_at[next]).length() < 1e-5,
                    "{}",
                    frame.name
                );
            }
            drawn += 1;
        }
    }
    // A bone to each of the three joints, and one past each of the two leaves' joints.
    assert_eq!(drawn, 3 + 2);
}
