//! Tests of the output files against a hand-made body with exact poses.

use std::f64::consts::FRAC_PI_2;

use glam::{DQuat, DVec3};
use serde_json::Value;

use crate::{Error, Inputs, Params, run};

/// A run at every parameter's default: nothing set.
static NO_SETTINGS: std::collections::BTreeMap<String, Value> = std::collections::BTreeMap::new();
use bonefit::testkit::{Scene, scene};

/// A node of a parsed BVH hierarchy.
struct Node {
    name: String,
    parent: Option<usize>,
    offset: DVec3,
    channels: Vec<String>,
}

/// A parsed BVH: nodes in file order, frame count, frame time, channel values per frame.
struct Bvh {
    nodes: Vec<Node>,
    frames: usize,
    frame_time: f64,
    motion: Vec<Vec<f64>>,
}

/// A small BVH reader, independent of the writer.
fn parse_bvh(text: &str) -> Bvh {
    let mut tokens = text.split_whitespace().peekable();
    let mut nodes: Vec<Node> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    let number = |t: Option<&str>| -> f64 { t.and_then(|s| s.parse().ok()).unwrap_or(f64::NAN) };
    assert_eq!(tokens.next(), Some("HIERARCHY"));
    loop {
        let Some(t) = tokens.next() else {
            panic!("no MOTION section")
        };
        match t {
            "ROOT" | "JOINT" | "End" => {
                let name = tokens.next().unwrap_or_default().to_owned();
                let name = if t == "End" {
                    format!("End {name}")
                } else {
                    name
                };
                assert_eq!(tokens.next(), Some("{"));
                nodes.push(Node {
                    name,
                    parent: stack.last().copied(),
                    offset: DVec3::NAN,
                    channels: Vec::new(),
                });
                stack.push(nodes.len() - 1);
            }
            "OFFSET" => {
                let o = DVec3::new(
                    number(tokens.next()),
                    number(tokens.next()),
                    number(tokens.next()),
                );
                let top = *stack.last().unwrap_or(&0);
                nodes[top].offset = o;
            }
            "CHANNELS" => {
                let count = number(tokens.next()) as usize;
                let top = *stack.last().unwrap_or(&0);
                for _ in 0..count {
                    nodes[top]
                        .channels
                        .push(tokens.next().unwrap_or_default().to_owned());
                }
            }
            "}" => {
                stack.pop();
            }
            "MOTION" => break,
            other => panic!("unexpected token {other}"),
        }
    }
    assert!(stack.is_empty(), "unbalanced braces");
    assert_eq!(tokens.next(), Some("Frames:"));
    let frames = number(tokens.next()) as usize;
    assert_eq!(tokens.next(), Some("Frame"));
    assert_eq!(tokens.next(), Some("Time:"));
    let frame_time = number(tokens.next());
    let per_frame: usize = nodes.iter().map(|n| n.channels.len()).sum();
    let values: Vec<f64> = tokens.map(|t| number(Some(t))).collect();
    assert_eq!(values.len(), frames * per_frame);
    let motion = values
        .chunks(per_frame.max(1))
        .map(<[f64]>::to_vec)
        .collect();
    Bvh {
        nodes,
        frames,
        frame_time,
        motion,
    }
}

/// Global position of every node at one frame: channels applied in their listed order
/// (intrinsic), a node's rotation = parent's × its own.
fn bvh_fk(bvh: &Bvh, frame: usize) -> Vec<DVec3> {
    let values = &bvh.motion[frame];
    let mut next = 0;
    let mut rotation: Vec<DQuat> = Vec::new();
    let mut position: Vec<DVec3> = Vec::new();
    for node in &bvh.nodes {
        let mut translation = node.offset;
        let mut local = DQuat::IDENTITY;
        for c in &node.channels {
            let v = values[next];
            next += 1;
            match c.as_str() {
                "Xposition" => translation.x += v,
                "Yposition" => translation.y += v,
                "Zposition" => translation.z += v,
                "Xrotation" => local *= DQuat::from_rotation_x(v.to_radians()),
                "Yrotation" => local *= DQuat::from_rotation_y(v.to_radians()),
                "Zrotation" => local *= DQuat::from_rotation_z(v.to_radians()),
                other => panic!("unknown channel {other}"),
            }
        }
        let (pr, pp) = match node.parent {
            Some(p) => (rotation[p], position[p]),
            None => (DQuat::IDENTITY, DVec3::ZERO),
        };
        position.push(pp + pr * translation);
        rotation.push(pr * local);
    }
    position
}

pub(crate) fn files(s: &Scene, params: &Params) -> crate::Outputs {
    files_of(s, &skeleton(s), params)
}

/// The scene's skeleton (bonefit's defaults).
pub(crate) fn skeleton(s: &Scene) -> bonefit::Skeleton {
    bonefit::run(
        &s.trajectories,
        &s.segmentation,
        &s.fits,
        &s.topology,
        &bonefit::Params::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// The files of the scene with `skeleton` in place of its own.
pub(crate) fn files_of(s: &Scene, skeleton: &bonefit::Skeleton, params: &Params) -> crate::Outputs {
    let input = inputs(s, &s.segmentation, skeleton);
    run(&input, params).unwrap_or_else(|e| panic!("{e}"))
}

/// The scene's inputs with `segmentation` and `skeleton` in place of its own.
pub(crate) fn inputs<'a>(
    s: &'a Scene,
    segmentation: &'a segment::Segmentation,
    skeleton: &'a bonefit::Skeleton,
) -> Inputs<'a> {
    Inputs {
        trajectories: &s.trajectories,
        segmentation,
        fits: &s.fits,
        topology: &s.topology,
        skeleton,
        settings: &NO_SETTINGS,
        reader_warnings: &[],
    }
}

pub(crate) fn text(out: &crate::Outputs, name: &str) -> String {
    String::from_utf8(out.files.get(name).cloned().unwrap_or_default()).unwrap_or_default()
}

/// How many of a JSON position array's entries are known (not null).
fn known(positions: &Value) -> usize {
    positions
        .as_array()
        .map_or(0, |p| p.iter().filter(|x| !x.is_null()).count())
}

/// A JSON position `[x, y, z]` (NaN where a coordinate is missing).
pub(crate) fn json_point(p: &Value) -> DVec3 {
    DVec3::from_array([0, 1, 2].map(|i| p[i].as_f64().unwrap_or(f64::NAN)))
}

pub(crate) fn json(out: &crate::Outputs) -> Value {
    serde_json::from_str(&text(out, "skeleton.json")).unwrap_or(Value::Null)
}

/// A scene with a torso pose gap (root unknown) and a long thigh gap: the poses, the
/// markers and (for the thigh) the knee's fitted centre and the shank's pose are missing there, so nothing can
/// orient those segments.
pub(crate) fn gappy_scene() -> Scene {
    let mut s = scene(120, 60.0);
    for f in 30..50 {
        s.fits.poses[0].rotations[f] = [f64::NAN; 4];
    }
    let knee = s.topology.joints[2].pair;
    for f in 70..100 {
        s.fits.poses[1].translations[f] = [f64::NAN; 3];
        // The shank unposed too, so the knee is not seen from its side either (bonefit
        // recomputes hinge positions from the poses).
        s.fits.poses[2].rotations[f] = [f64::NAN; 4];
        s.fits.pairs[knee].positions[f] = [f64::NAN; 3];
    }
    let t = &s.trajectories;
    let markers = t.markers();
    let mut positions = t.positions().to_vec();
    for (m, frames) in [
        (0, 30..50),
        (1, 30..50),
        (2, 30..50),
        (3, 70..100),
        (4, 70..100),
        (5, 70..100),
    ] {
        for f in frames {
            positions[f * markers + m] = [f64::NAN; 3];
        }
    }
    s.trajectories = t
        .with_positions(positions)
        .unwrap_or_else(|e| panic!("{e}"));
    s
}

/// Checks BVH forward kinematics against skeleton.json, mapping JSON points by `axes`.
fn check_round_trip(out: &crate::Outputs, axes: impl Fn(DVec3) -> DVec3) -> usize {
    let doc = json(out);
    let bvh = parse_bvh(&text(out, "skeleton.bvh"));
    assert_eq!(
        bvh.frames,
        doc["frame_count"].as_u64().unwrap_or(0) as usize
    );
    let rate = doc["frame_rate"].as_f64().unwrap_or(0.0);
    assert!((bvh.frame_time - 1.0 / rate).abs() < 1e-12);
    assert_eq!(bvh.nodes[0].name, "root");
    assert_eq!(bvh.nodes[0].offset, DVec3::ZERO);
    assert_eq!(bvh.nodes[0].channels.len(), 6);
    let joints = doc["joints"].as_array().cloned().unwrap_or_default();
    let mut checked = 0;
    for f in 0..bvh.frames {
        let fk = bvh_fk(&bvh, f);
        for j in &joints {
            let name = j["name"].as_str().unwrap_or_default();
            let node = bvh.nodes.iter().position(|n| n.name == name);
            let Some(node) = node else {
                panic!("joint {name} missing from the BVH")
            };
            // The BVH nests joints as the JSON's parents say.
            let parent_name = bvh.nodes[bvh.nodes[node].parent.unwrap_or(0)].name.as_str();
            assert_eq!(parent_name, j["parent"].as_str().unwrap_or("root"));
            let p = &j["positions"][f];
            if p.is_null() {
                continue;
            }
            let error = (fk[node] - axes(json_point(p))).length();
            assert!(error < 0.01, "{name} frame {f}: BVH FK off by {error} mm");
            checked += 1;
        }
    }
    checked
}

#[test]
fn bvh_forward_kinematics_reproduces_the_json() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let checked = check_round_trip(&out, |p| p);
    // 3 joints × 120 frames minus the unknown ones.
    assert!(checked > 200, "only {checked} positions compared");
    // The JSON positions are the truth (exact poses, rigid bones).
    let doc = json(&out);
    let got = json_point(&doc["joints"][2]["positions"][10]);
    let want = DVec3::from_array(s.truth[2][10]);
    assert!((got - want).length() < 0.001);
}

#[test]
fn y_up_bvh_is_the_same_motion_turned() {
    let s = gappy_scene();
    let out = files(
        &s,
        &Params {
            y_up: true,
            ..Params::default()
        },
    );
    // (x, y, z) Z-up → (x, z, −y) Y-up.
    let checked = check_round_trip(&out, |p| DVec3::new(p.x, p.z, -p.y));
    assert!(checked > 200);
    // The JSON is the same in both modes.
    let z_up = files(&s, &Params::default());
    assert_eq!(
        out.files.get("skeleton.json"),
        z_up.files.get("skeleton.json")
    );
    assert_ne!(
        out.files.get("skeleton.bvh"),
        z_up.files.get("skeleton.bvh")
    );
}

#[test]
fn bvh_layout_nesting_end_sites_and_held_root() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let bvh = parse_bvh(&text(&out, "skeleton.bvh"));
    let names: Vec<&str> = bvh.nodes.iter().map(|n| n.name.as_str()).collect();
    // j2 (shank) nests in j1 (thigh); head j3 after; leaves end in End Sites.
    assert_eq!(names, ["root", "j1", "j2", "End Site", "j3", "End Site"]);
    assert_eq!(bvh.nodes[2].parent, Some(1));
    assert_eq!(bvh.nodes[4].parent, Some(0));
    for n in &bvh.nodes[1..] {
        let want = if n.name == "End Site" { 0 } else { 3 };
        assert_eq!(n.channels.len(), want);
        assert_eq!(
            n.channels.join(" ").replace("rotation", ""),
            if want == 3 { "Z X Y" } else { "" }
        );
    }
    // End Site of the shank: from the knee (0,0,120) to the shank's centroid, in its frame.
    assert!((bvh.nodes[3].offset - DVec3::new(0.0, 0.0, -120.0)).length() < 1e-6);
    // OFFSETs are the skeleton's bones: knee 300 mm below the hip.
    assert!((bvh.nodes[2].offset - DVec3::new(0.0, 0.0, -300.0)).length() < 1e-6);
    // Root unknown at frames 30..50, but the thigh posed on its own: the BVH's root moves
    // to where its chain reaches the hip the thigh fixes (`check_round_trip`), though the
    // JSON's root point stays unknown.
    assert_ne!(bvh.motion[29][..3], bvh.motion[40][..3]);
    let doc = json(&out);
    assert!(doc["root"]["positions"][40].is_null());
    assert!(!doc["joints"][0]["positions"][40].is_null());
    assert!(doc["joints"][1]["positions"][40].is_null());
    // With nothing posed there at all, the BVH holds frame 29's root position.
    let mut s = gappy_scene();
    for f in 30..50 {
        for poses in &mut s.fits.poses {
            poses.rotations[f] = [f64::NAN; 4];
            poses.translations[f] = [f64::NAN; 3];
        }
        for pair in &mut s.fits.pairs {
            pair.positions[f] = [f64::NAN; 3];
        }
    }
    let out = files(&s, &Params::default());
    let bvh = parse_bvh(&text(&out, "skeleton.bvh"));
    assert_eq!(bvh.motion[29][..3], bvh.motion[40][..3]);
    assert_ne!(bvh.motion[29][..3], bvh.motion[28][..3]);
    let doc = json(&out);
    assert!(doc["root"]["positions"][40].is_null());
    assert!(doc["joints"][0]["positions"][40].is_null());
}

#[test]
fn json_contract_fields_and_types() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let doc = json(&out);
    assert_eq!(doc["units"], "mm");
    assert_eq!(doc["frame_rate"].as_f64(), Some(60.0));
    assert_eq!(doc["frame_count"].as_u64(), Some(120));
    let segments = doc["segments"].as_array().cloned().unwrap_or_default();
    assert_eq!(segments.len(), 4);
    assert_eq!(segments[1]["id"].as_u64(), Some(1));
    assert_eq!(
        segments[1]["markers"],
        serde_json::json!(["M003", "M004", "M005"])
    );
    assert_eq!(segments[0]["frames_with_pose"].as_u64(), Some(100));
    // Three well-spread markers fix the spin: a finite, small standard error.
    let spin = segments[1]["spin_deg"].as_f64();
    assert!(spin.is_some_and(|d| (0.0..1.0).contains(&d)), "{spin:?}");
    assert!(
        doc["unassigned_markers"]
            .as_array()
            .is_some_and(Vec::is_empty)
    );
    assert_eq!(doc["root_segment"].as_u64(), Some(0));
    assert_eq!(doc["bone_method"], "rigid");
    assert_eq!(doc["rotation_method"], "fitted");
    let joints = doc["joints"].as_array().cloned().unwrap_or_default();
    let names: Vec<&str> = joints.iter().filter_map(|j| j["name"].as_str()).collect();
    assert_eq!(names, ["j1", "j3", "j2"]);
    for j in &joints {
        assert!(j["parent_segment"].is_u64() && j["child_segment"].is_u64());
        assert!(matches!(j["kind"].as_str(), Some("ball" | "hinge")));
        let positions = j["positions"].as_array().cloned().unwrap_or_default();
        assert_eq!(positions.len(), 120);
        for p in &positions {
            assert!(
                p.is_null()
                    || p.as_array()
                        .is_some_and(|a| a.len() == 3 && a.iter().all(Value::is_f64))
            );
        }
        assert!(j["bone_length_mm"].is_f64());
        assert!(j["range_of_motion_deg"].is_f64());
        assert!(j["residual_rms_mm"].is_f64());
        assert!(j["hinge_shift_mm"].is_f64());
        assert!(j["warnings"].is_array());
    }
    assert_eq!(joints[2]["kind"], "hinge");
    assert_eq!(joints[2]["parent"], "j1");
    assert_eq!(joints[2]["bone_length_mm"].as_f64(), Some(300.0));
    // Knee: thigh poses missing at 70..100 (translation only) → position null there.
    assert!(joints[2]["positions"][80].is_null());
    assert!(!joints[2]["positions"][60].is_null());
    // The head nods ±0.4 rad about x only: range ≈ 45.8°, no warning.
    let head_rom = joints[1]["range_of_motion_deg"].as_f64().unwrap_or(0.0);
    assert!((head_rom - 0.8f64.to_degrees()).abs() < 2.0, "{head_rom}");
    assert_eq!(doc["markers"][4]["segment"].as_u64(), Some(1));
    assert_eq!(doc["markers"][4]["label"], "M004");
    assert_eq!(doc["generator"], "ossify");
    assert!(doc["ossify_version"].is_string());
    // Positions rounded to 0.001 mm.
    let x = joints[0]["positions"][0][0].as_f64().unwrap_or(0.0);
    assert_eq!((x * 1000.0).round() / 1000.0, x);
}

#[test]
fn low_range_of_motion_warns() {
    let mut s = scene(60, 60.0);
    // Make the head rigid on the torso: same rotation, translation through the joint.
    for f in 0..60 {
        let r0 = DQuat::from_array(s.fits.poses[0].rotations[f]);
        let t0 = DVec3::from_array(s.fits.poses[0].translations[f]);
        let centre = r0 * DVec3::new(0.0, 0.0, 180.0) + t0;
        s.fits.poses[3].rotations[f] = r0.to_array();
        s.fits.poses[3].translations[f] = (centre - r0 * DVec3::new(0.0, 0.0, -60.0)).to_array();
    }
    let doc = json(&files(&s, &Params::default()));
    let head = &doc["joints"][1];
    assert_eq!(head["name"], "j3");
    assert!(head["range_of_motion_deg"].as_f64().unwrap_or(99.0) < 1e-3);
    let warnings = head["warnings"].to_string();
    assert!(warnings.contains("below 20"), "{warnings}");
}

/// Whether skeleton.json's `joint` joins the two segments of `pair`, either way round.
fn joins(joint: &Value, pair: &jointfit::PairFit) -> bool {
    let ends = [
        joint["parent_segment"].as_u64(),
        joint["child_segment"].as_u64(),
    ];
    let (a, b) = (Some(pair.a as u64), Some(pair.b as u64));
    ends == [a, b] || ends == [b, a]
}

/// A joint whose two segments disagree about their centre by more than skin would (its
/// residual a sizeable fraction of its markers' distance from the centre) says so, with the
/// angle in `centre_misfit_deg`; the scene's other joints, fitted exactly, do not.
#[test]
fn a_joint_its_segments_disagree_about_warns() {
    let mut s = scene(60, 60.0);
    let knee = s.topology.joints[2].pair;
    s.fits.pairs[knee].residual_rms_mm = 100.0;
    let doc = json(&files(&s, &Params::default()));
    for joint in doc["joints"].as_array().into_iter().flatten() {
        let misfit = joint["centre_misfit_deg"]
            .as_f64()
            .expect("a misfit for every joint");
        let warned = joint["warnings"].to_string().contains("common centre");
        let is_knee = joins(joint, &s.fits.pairs[knee]);
        assert_eq!(warned, is_knee, "{joint}");
        assert_eq!(misfit > 8.0, is_knee, "{misfit}");
    }
}

/// A joint's residual over its poses' noise is written where the pair fit has it (rounded
/// to 0.001) and left out where it has none (a two-marker segment, exact data).
#[test]
fn a_joints_residual_over_noise_is_written_where_measured() {
    let mut s = scene(60, 60.0);
    let knee = s.topology.joints[2].pair;
    s.fits.pairs[knee].misfit_over_noise = 1.23456;
    let doc = json(&files(&s, &Params::default()));
    let mut written = 0;
    for joint in doc["joints"].as_array().into_iter().flatten() {
        let ratio = joint.get("residual_over_noise");
        if joins(joint, &s.fits.pairs[knee]) {
            assert_eq!(ratio.and_then(Value::as_f64), Some(1.235), "{joint}");
            written += 1;
        } else {
            assert!(ratio.is_none(), "{joint}");
        }
    }
    assert_eq!(written, 1);
}

/// A joint whose centre lies far from every marker of its two segments (more than half the
/// capture's size) says the data did not place it; the scene's others, among their
/// markers, do not.
#[test]
fn a_joint_far_from_its_segments_markers_warns() {
    let s = scene(60, 60.0);
    let mut skeleton = skeleton(&s);
    let head = skeleton
        .joints
        .iter()
        .position(|j| j.child_segment == 3)
        .expect("a joint into the head");
    for p in &mut skeleton.joints[head].positions {
        p[0] += 5000.0;
    }
    let doc = json(&files_of(&s, &skeleton, &Params::default()));
    for joint in doc["joints"].as_array().into_iter().flatten() {
        let warned = joint["warnings"].to_string().contains("did not place it");
        assert_eq!(warned, joint["child_segment"] == 3, "{joint}");
    }
}

/// A joint every pose started from (no segment with three markers of its own) says so, and
/// only that one.
#[test]
fn the_seeded_joint_warns() {
    let mut s = scene(60, 60.0);
    let seeded = s.fits.pairs.iter().position(|p| (p.a, p.b) == (0, 3));
    let seeded = seeded.expect("torso-head pair");
    s.fits.pairs[seeded].seeded = true;
    let doc = json(&files(&s, &Params::default()));
    for joint in doc["joints"].as_array().into_iter().flatten() {
        let warnings = joint["warnings"].to_string();
        let head = joint["child_segment"] == 3;
        assert_eq!(warnings.contains("every pose starts here"), head, "{joint}");
    }
}

/// A joint a segment is posed through warns where another neighbour's centre held that
/// segment's markers better (the tree pass kept it on the worse fit), and only there.
#[test]
fn a_joint_kept_on_a_worse_anchor_warns() {
    let mut s = scene(60, 60.0);
    let head = s.fits.pairs.iter().position(|p| (p.a, p.b) == (0, 3));
    let head = head.expect("torso-head pair");
    s.fits.pairs[head].posed_through = Some(3);
    s.fits.pairs[head].next_best_anchor = Some((1, 0.6));
    let thigh = s.fits.pairs.iter().position(|p| (p.a, p.b) == (0, 1));
    let thigh = thigh.expect("torso-thigh pair");
    s.fits.pairs[thigh].posed_through = Some(1);
    s.fits.pairs[thigh].next_best_anchor = Some((3, 1.4));
    let doc = json(&files(&s, &Params::default()));
    for joint in doc["joints"].as_array().into_iter().flatten() {
        let warnings = joint["warnings"].to_string();
        let warned = warnings.contains("holds its markers better");
        assert_eq!(warned, joint["child_segment"] == 3, "{joint}");
        assert_eq!(
            warned,
            warnings.contains("although segment 1's centre"),
            "{joint}"
        );
    }
}

/// The parameters a run set away from their defaults are in skeleton.json and the report;
/// at the defaults, `settings` is empty and the report has no such section.
#[test]
fn settings_are_written_where_the_run_set_any() {
    let s = scene(20, 60.0);
    let skeleton = skeleton(&s);
    let at_defaults = run(&inputs(&s, &s.segmentation, &skeleton), &Params::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(json(&at_defaults)["settings"], serde_json::json!({}));
    assert!(!text(&at_defaults, "report.html").contains("Settings"));
    let settings = std::collections::BTreeMap::from([(
        "topo.joints".to_string(),
        serde_json::json!([[1, "M<0>"]]),
    )]);
    let input = Inputs {
        settings: &settings,
        ..inputs(&s, &s.segmentation, &skeleton)
    };
    let out = run(&input, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        json(&out)["settings"],
        serde_json::json!({"topo.joints": [[1, "M<0>"]]})
    );
    let report = text(&out, "report.html");
    assert!(
        report.contains("<code>topo.joints=[[1,&quot;M&lt;0&gt;&quot;]]</code>"),
        "{report}"
    );
}

/// What the reader said about the file is in skeleton.json and at the report's top,
/// escaped; where it said nothing, `reader_warnings` is empty and the report has no such
/// section.
#[test]
fn reader_warnings_are_kept_with_the_outputs() {
    let s = scene(20, 60.0);
    let skeleton = skeleton(&s);
    let quiet = run(&inputs(&s, &s.segmentation, &skeleton), &Params::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(json(&quiet)["reader_warnings"], serde_json::json!([]));
    assert!(!text(&quiet, "report.html").contains("What the reader said"));
    let said = [
        "line 3: no usable DataRate; 120 Hz from the Time column".to_string(),
        "units <m> look wrong".to_string(),
    ];
    let input = Inputs {
        reader_warnings: &said,
        ..inputs(&s, &s.segmentation, &skeleton)
    };
    let out = run(&input, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(json(&out)["reader_warnings"], serde_json::json!(said));
    let report = text(&out, "report.html");
    let section = report
        .find("<h2>What the reader said about the file</h2>")
        .expect("the section");
    assert!(
        section < report.find("<h2>Joints</h2>").expect("joints"),
        "{report}"
    );
    assert!(
        report.contains("<li>units &lt;m&gt; look wrong</li>"),
        "{report}"
    );
}

/// Each joint carries its runner-up pair (topo's) as a cost ratio; one below 1.2 warns,
/// naming the pair and how to join it, unless the joint is a rigid pair (taken before
/// every cost) or one the user named.
#[test]
fn a_joint_with_a_close_runner_up_warns() {
    let mut s = scene(60, 60.0);
    // (child segment, runner-up's cost over the joint's, the runner-up's two sides)
    let close = [(1, 1.1, (3, 1)), (3, 1.5, (1, 3)), (2, 0.5, (3, 2))];
    for &(child, ratio, (parent_side, child_side)) in &close {
        let j = s
            .topology
            .joints
            .iter_mut()
            .find(|j| j.child_segment == child);
        let j = j.expect("a joint into that segment");
        j.runner_up = Some(topo::RunnerUp {
            parent_side,
            child_side,
            pair: j.pair,
            cost: ratio * j.cost,
        });
    }
    let knee = s.topology.joints.iter().find(|j| j.child_segment == 2);
    let knee = knee.expect("a knee").pair;
    s.fits.pairs[knee].first_pass_kind = Some(jointfit::JointKind::Rigid);
    let doc = json(&files(&s, &Params::default()));
    for &(child, ratio, (parent_side, child_side)) in &close {
        let joints = doc["joints"].as_array().into_iter().flatten();
        let joint = joints.clone().find(|j| j["child_segment"] == child);
        let joint = joint.expect("the joint in skeleton.json");
        let r = &joint["runner_up"];
        assert_eq!(r["parent_side_segment"], parent_side, "{joint}");
        assert_eq!(r["child_side_segment"], child_side, "{joint}");
        assert!(
            (r["cost_ratio"].as_f64().unwrap_or(f64::NAN) - ratio).abs() < 1e-9,
            "{r}"
        );
        let warned = joint["warnings"].to_string().contains(&format!(
            "could join segments {parent_side} and {child_side} instead"
        ));
        assert_eq!(warned, child == 1, "{joint}");
        assert!(
            joint["warnings"].to_string().contains(&format!(
                "--set 'topo.joints=[[{parent_side}, {child_side}]]'"
            )) == warned,
            "{joint}"
        );
    }
    // A joint the user named (topo.joints) is theirs: no doubt is warned.
    for j in s
        .topology
        .joints
        .iter_mut()
        .filter(|j| j.child_segment == 1)
    {
        j.named = true;
    }
    let doc = json(&files(&s, &Params::default()));
    let joints = doc["joints"].as_array().into_iter().flatten();
    let joint = joints.clone().find(|j| j["child_segment"] == 1);
    let joint = joint.expect("the joint in skeleton.json");
    assert!(
        !joint["warnings"].to_string().contains("could join"),
        "{joint}"
    );
    assert_eq!(joint["runner_up"]["parent_side_segment"], 3, "{joint}");
}

#[test]
fn csv_rows_only_where_known() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let csv = text(&out, "joints.csv");
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("frame,joint,x,y,z"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let doc = json(&out);
    let positions: usize = doc["joints"]
        .as_array()
        .map_or(0, |js| js.iter().map(|j| known(&j["positions"])).sum());
    assert_eq!(rows.len(), positions);
    assert!(rows.iter().all(|r| r.len() == 5));
    assert_eq!(rows[0][0], "0");
    assert_eq!(rows[0][1], "j1");
    let x: f64 = rows[0][2].parse().unwrap_or(f64::NAN);
    assert_eq!(Some(x), doc["joints"][0]["positions"][0][0].as_f64());
    // Frame 40: the torso (root) unknown, the thigh posed on its own: its hip and the knee
    // below it are known, the neck is not.
    let at_40: Vec<&str> = rows.iter().filter(|r| r[0] == "40").map(|r| r[1]).collect();
    assert_eq!(at_40, ["j1", "j2"]);
}

/// joints.trc read back by mocap-io's TRC reader, with the JSON's positions (root first,
/// then the joints) mapped by `axes`: same labels, rate, first frame and every sample, and
/// missing exactly where the JSON has null. Returns the samples compared.
fn check_trc(out: &crate::Outputs, axes: impl Fn([f64; 3]) -> [f64; 3]) -> usize {
    let compared = check_joint_markers(out, "joints.trc", &axes);
    // joints.c3d holds the same samples, as floats (within 0.001 mm of the rounded mm).
    assert_eq!(check_joint_markers(out, "joints.c3d", &axes), compared);
    compared
}

/// A joint-marker file read back by mocap-io's reader for its format: see [`check_trc`].
fn check_joint_markers(
    out: &crate::Outputs,
    name: &str,
    axes: impl Fn([f64; 3]) -> [f64; 3],
) -> usize {
    let doc = json(out);
    let bytes = out.files.get(name).cloned().unwrap_or_default();
    let options = mocap_io::ReadOptions::default();
    // TRC text holds the JSON's rounded mm and rate exactly; C3D's floats to their precision.
    let c3d = name.ends_with(".c3d");
    let tolerance = if c3d { 1e-3 } else { 0.0 };
    let capture = if c3d {
        mocap_io::c3d::parse(&bytes, &options)
    } else {
        mocap_io::trc::parse(&bytes, &options)
    };
    let capture = capture.unwrap_or_else(|e| panic!("{name} does not parse back: {e}"));
    let t = &capture.trajectories;
    let joints = doc["joints"].as_array().cloned().unwrap_or_default();
    let mut tracks = vec![(
        doc["root"]["name"].clone(),
        doc["root"]["positions"].clone(),
    )];
    tracks.extend(
        joints
            .iter()
            .map(|j| (j["name"].clone(), j["positions"].clone())),
    );
    let labels: Vec<&str> = tracks
        .iter()
        .map(|(n, _)| n.as_str().unwrap_or(""))
        .collect();
    assert_eq!(t.labels(), labels.as_slice());
    let rate = doc["frame_rate"].as_f64().unwrap_or(0.0);
    assert!(
        (t.frame_rate() - rate).abs() <= tolerance * rate,
        "{name}: rate"
    );
    assert_eq!(Some(t.first_frame()), doc["first_frame"].as_i64());
    assert_eq!(Some(t.frames() as u64), doc["frame_count"].as_u64());
    let mut compared = 0;
    for (m, (name, positions)) in tracks.iter().enumerate() {
        for f in 0..t.frames() {
            let p = &positions[f];
            let got = t.get(f, m);
            if p.is_null() {
                assert_eq!(
                    got, None,
                    "{name} frame {f}: unknown in the JSON, present in the TRC"
                );
                continue;
            }
            let want = DVec3::from_array(axes(json_point(p).to_array()));
            let off = got.map_or(f64::INFINITY, |g| (DVec3::from_array(g) - want).length());
            assert!(off <= tolerance, "{name} frame {f}: {got:?} for {want}");
            compared += 1;
        }
    }
    compared
}

#[test]
fn trc_has_the_json_positions_and_gaps() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let compared = check_trc(&out, |p| p);
    let doc = json(&out);
    let root = known(&doc["root"]["positions"]);
    let joints: usize = doc["joints"]
        .as_array()
        .map_or(0, |js| js.iter().map(|j| known(&j["positions"])).sum());
    assert_eq!(compared, root + joints);
    // The scene's gaps reach the file: fewer samples than frames × tracks.
    let tracks = 1 + doc["joints"].as_array().map_or(0, Vec::len);
    let frames = doc["frame_count"].as_u64().unwrap_or(0) as usize;
    assert!(compared < tracks * frames && compared > tracks * frames / 2);
    // Y-up is the same motion turned as the BVH is: (x, y, z) -> (x, z, -y).
    // The JSON is never turned, so the turned TRC is checked against the same positions.
    let turned = files(
        &s,
        &Params {
            y_up: true,
            ..Params::default()
        },
    );
    assert_eq!(json(&turned), doc);
    let neg = |c: f64| if c == 0.0 { 0.0 } else { -c };
    assert_eq!(check_trc(&turned, |[x, y, z]| [x, z, neg(y)]), compared);
}

/// markers.trc (and markers.c3d) read back: every marker of the capture, its samples
/// as the capture has them, and a gap filled where its segment is posed (by its own
/// pose, or where it has none by its other markers and its joints' centres), at the
/// hidden samples (the scene's markers are rigid, so the posed place is exact); where no
/// pose is known (gappy_scene's torso, frames 30–49) the marker stays missing. With
/// `y_up` the same samples turned as joints.trc's.
#[test]
fn markers_trc_fills_a_gap_where_its_segment_is_posed() {
    let full = gappy_scene();
    let mut s = gappy_scene();
    let t = &s.trajectories;
    let markers = t.markers();
    let mut positions = t.positions().to_vec();
    // The thigh's first marker hidden in frames 10..40, posed throughout.
    let thigh_marker = s.segmentation.segments[1].markers[0];
    for f in 10..40 {
        positions[f * markers + thigh_marker] = mocap_io::MISSING;
    }
    // In frames 15..25 the thigh has no pose of its own.
    for f in 15..25 {
        s.fits.poses[1].rotations[f] = [f64::NAN; 4];
    }
    s.trajectories = t
        .with_positions(positions)
        .unwrap_or_else(|e| panic!("{e}"));
    let turned = Params {
        y_up: true,
        ..Params::default()
    };
    for (params, name) in [
        (&Params::default(), "markers.trc"),
        (&Params::default(), "markers.c3d"),
        (&turned, "markers.trc"),
    ] {
        let out = files(&s, params);
        let bytes = out.files.get(name).cloned().unwrap_or_default();
        let options = mocap_io::ReadOptions::default();
        let back = if name.ends_with(".c3d") {
            mocap_io::c3d::parse(&bytes, &options)
        } else {
            mocap_io::trc::parse(&bytes, &options)
        }
        .unwrap_or_else(|e| panic!("{name} does not parse back: {e}"));
        let back = &back.trajectories;
        assert_eq!(back.labels(), full.trajectories.labels(), "{name}");
        assert_eq!(back.frames(), full.trajectories.frames(), "{name}");
        for f in 0..back.frames() {
            for m in 0..markers {
                let got = back.get(f, m);
                // The scene's own gaps: the torso's where it has no pose, the thigh's.
                let truth = full
                    .trajectories
                    .get(f, m)
                    .map(|[x, y, z]| if params.y_up { [x, z, -y] } else { [x, y, z] });
                match (got, truth) {
                    (Some(g), Some(w)) => {
                        let d = DVec3::from_array(g).distance(DVec3::from_array(w));
                        assert!(d < 2e-3, "{name} frame {f} marker {m}: {d} mm");
                    }
                    (None, None) => {}
                    _ => panic!("{name} frame {f} marker {m}: {got:?} against {truth:?}"),
                }
            }
        }
    }
    let doc = json(&files(&s, &Params::default()));
    let filled: Vec<u64> = doc["markers"]
        .as_array()
        .map(|ms| {
            ms.iter()
                .map(|m| m["filled_frames"].as_u64().unwrap_or(0))
                .collect()
        })
        .unwrap_or_default();
    let mut want = vec![0; markers];
    want[thigh_marker] = 30;
    assert_eq!(filled, want);
    // The report says what was filled, marker by marker.
    let html = text(&files(&s, &Params::default()), "report.html");
    let label = &s.trajectories.labels()[thigh_marker];
    let line = format!("fill 30 missing samples from their segments' poses: {label} (30).");
    assert!(html.contains(&line), "no fill line {line}");
}

/// The report names every joint, segment marker and kind, draws three projections with a
/// line per joint that has a position to hang from, and escapes what came from the capture.
#[test]
fn report_tabulates_the_document_and_escapes_labels() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let html = text(&out, "report.html");
    assert!(html.starts_with("<!doctype html>"));
    assert!(html.trim_end().ends_with("</html>"));
    assert_eq!(html.matches("<svg ").count(), 3);
    let doc = json(&out);
    let joints = doc["joints"].as_array().cloned().unwrap_or_default();
    // One line per joint in each view: every joint hangs from a joint or the root.
    assert_eq!(html.matches("<line ").count(), 3 * joints.len());
    for j in &joints {
        let name = j["name"].as_str().unwrap_or_default();
        assert!(
            html.contains(&format!("<tr><td>{name}</td>")),
            "no row for {name}"
        );
    }
    for s in doc["segments"].as_array().cloned().unwrap_or_default() {
        for m in s["markers"].as_array().cloned().unwrap_or_default() {
            assert!(html.contains(m.as_str().unwrap_or("?")));
        }
    }
    assert!(!html.contains("Jumped off their partners"));
    // A label from a file is text, never markup.
    let mut document: crate::SkeletonJson =
        serde_json::from_value(doc).unwrap_or_else(|e| panic!("{e}"));
    document.markers[0].label = "<b>\"L&R\"</b>".into();
    document.markers[0].segment = None;
    document.markers[0].unassigned_reason = Some("moves <alone>".into());
    document.markers[1].glitch_frames = 26;
    let html = String::from_utf8(crate::report::write(&document)).unwrap_or_default();
    assert!(html.contains("&lt;b&gt;&quot;L&amp;R&quot;&lt;/b&gt;"));
    assert!(html.contains("moves &lt;alone&gt;"));
    assert!(!html.contains("<b>"));
    // A glitching marker is named with its count of masked frames.
    let glitch = format!("{} (26 frames).</p>", document.markers[1].label);
    assert!(html.contains(&glitch), "no glitch line {glitch}");
}

#[test]
fn outputs_are_deterministic_and_round_trip_through_serde() {
    let s = gappy_scene();
    let a = files(&s, &Params::default());
    let b = files(&s, &Params::default());
    assert_eq!(a, b);
    assert_eq!(
        a.files.keys().map(String::as_str).collect::<Vec<_>>(),
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
            "skeleton.osim"
        ]
    );
    let json_bytes = serde_json::to_vec(&a).unwrap_or_default();
    let back: crate::Outputs = serde_json::from_slice(&json_bytes).unwrap_or_default();
    assert_eq!(back, a);
    // One at a time, the same files in the order `file_names` announces.
    let skeleton = skeleton(&s);
    let input = inputs(&s, &s.segmentation, &skeleton);
    let mut emitted = Vec::new();
    crate::run_each(
        &input,
        &Params::default(),
        |name, bytes| -> Result<(), Error> {
            assert!(a.files.get(name) == Some(&bytes), "{name} differs");
            emitted.push(name.to_owned());
            Ok(())
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(emitted, crate::file_names(&input));
}

#[test]
fn zxy_euler_is_rz_rx_ry_and_round_trips() {
    let (a, b, c) = (0.7, -0.4, 2.1);
    let q = DQuat::from_euler(glam::EulerRot::ZXY, a, b, c);
    let manual = DQuat::from_rotation_z(a) * DQuat::from_rotation_x(b) * DQuat::from_rotation_y(c);
    assert!(q.angle_between(manual) < 1e-12);
    // Near gimbal lock too (x = ±90°).
    for (z, x, y) in [
        (0.3, 1.2, -2.0),
        (-2.9, -0.2, 0.1),
        (1.0, FRAC_PI_2 - 1e-4, 0.5),
        (0.0, -FRAC_PI_2, 3.0),
    ] {
        let q = DQuat::from_rotation_z(z) * DQuat::from_rotation_x(x) * DQuat::from_rotation_y(y);
        let text = crate::bvh::euler_degrees(q);
        let v: Vec<f64> = text.split(' ').filter_map(|s| s.parse().ok()).collect();
        let back = DQuat::from_rotation_z(v[0].to_radians())
            * DQuat::from_rotation_x(v[1].to_radians())
            * DQuat::from_rotation_y(v[2].to_radians());
        assert!(q.angle_between(back) < 1e-6, "{z} {x} {y} → {text}");
    }
}

/// A segment the segmentation lists as maybe two carries the cut's labels and scores in
/// skeleton.json and the report; one naming a marker the capture lacks is a mismatch.
#[test]
fn a_near_joint_names_its_parts_by_label() {
    let s = gappy_scene();
    let skeleton = skeleton(&s);
    let mut seg = s.segmentation.clone();
    let markers = seg.segments[1].markers.clone();
    seg.near_joints = vec![segment::NearJoint {
        segment: 1,
        parts: [markers[..1].to_vec(), markers[1..].to_vec()],
        rotation_z: 3.456,
        travel_z: 2.0,
    }];
    let input = inputs(&s, &seg, &skeleton);
    let out = run(&input, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let doc = json(&out);
    let near = &doc["segments"][1]["near_joint"];
    assert_eq!(
        near["parts"],
        serde_json::json!([["M003"], ["M004", "M005"]])
    );
    assert_eq!(near["rotation_z"].as_f64(), Some(3.46));
    assert!(doc["segments"][0].get("near_joint").is_none());
    let report = text(&out, "report.html");
    assert!(
        report.contains("M003 | M004, M005"),
        "the report lists the cut"
    );
    let mut bad = seg.clone();
    bad.near_joints[0].parts[1].push(99);
    let input = Inputs {
        segmentation: &bad,
        ..input
    };
    assert!(matches!(
        run(&input, &Params::default()),
        Err(crate::Error::Mismatch(_))
    ));
}

#[test]
fn mismatched_inputs_are_errors() {
    let s = scene(10, 60.0);
    let skeleton = skeleton(&s);
    let mut seg = s.segmentation.clone();
    seg.segments[0].markers.push(99);
    let input = inputs(&s, &seg, &skeleton);
    assert!(matches!(
        run(&input, &Params::default()),
        Err(crate::Error::Mismatch(_))
    ));
    let mut skel = skeleton.clone();
    skel.frame_rate = 0.0;
    let input = Inputs {
        skeleton: &skel,
        segmentation: &s.segmentation,
        ..input
    };
    assert!(matches!(
        run(&input, &Params::default()),
        Err(crate::Error::BadFrameRate { .. })
    ));
}

#[test]
fn end_to_end_synthetic_robot_arm_bvh_reproduces_json() {
    let trial = synth::generate(&synth::SynthConfig {
        subject: synth::Subject::Robotarm,
        frames: 180,
        seed: 7,
        ..synth::SynthConfig::default()
    })
    .unwrap_or_else(|e| panic!("{e}"));
    let traj = &trial.trajectories;
    let seg = segment::run(traj, &segment::Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let fits =
        jointfit::run(traj, &seg, &jointfit::Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let topology =
        topo::run(&seg, &fits, &topo::Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let skeleton = bonefit::run(traj, &seg, &fits, &topology, &bonefit::Params::default())
        .unwrap_or_else(|e| panic!("{e}"));
    // Clean data: constant bones follow jointfit's centres closely.
    for j in &skeleton.joints {
        assert!(
            j.fit_rms_mm < 1.0,
            "{}: FK vs fitted {} mm",
            j.name,
            j.fit_rms_mm
        );
    }
    let input = Inputs {
        trajectories: traj,
        segmentation: &seg,
        fits: &fits,
        topology: &topology,
        skeleton: &skeleton,
        settings: &NO_SETTINGS,
        reader_warnings: &[],
    };
    let out = run(&input, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let checked = check_round_trip(&out, |p| p);
    assert_eq!(checked, skeleton.joints.len() * 180);
    assert_eq!(check_glb(&out, |p| p), checked);
    // Clean hinges turn about their fitted axes only: the OpenSim model's pins follow.
    let (joints, markers, compared) = crate::osim_tests::check_model(&out, &input, |p| p);
    assert_eq!(compared, checked);
    assert!(
        joints < 0.01 && markers < 0.01,
        "model off by {joints} / {markers} mm"
    );
    let y_up = run(
        &input,
        &Params {
            y_up: true,
            ..Params::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    check_round_trip(&y_up, |p| DVec3::new(p.x, p.z, -p.y));
    check_glb(&y_up, |p| DVec3::new(p.x, p.z, -p.y));
    let estimate: synth::score::Estimate =
        serde_json::from_slice(out.files.get("skeleton.json").map_or(&[][..], |v| v))
            .unwrap_or_else(|e| panic!("{e}"));
    let score = synth::score::score(&trial.truth, &estimate);
    assert!(score.topology_exact, "{score}");
}

#[test]
fn single_segment_bvh_ends_the_root_in_an_end_site_and_parses_back() {
    let mut s = scene(12, 100.0);
    s.topology = topo::Topology {
        root_segment: 2,
        joints: Vec::new(),
        detached_segments: vec![0, 1, 3],
        notes: Vec::new(),
        bodies: Vec::new(),
        body: None,
    };
    let out = files(&s, &Params::default());
    let text = text(&out, "skeleton.bvh");
    let bvh = parse_bvh(&text);
    let names: Vec<&str> = bvh.nodes.iter().map(|n| n.name.as_str()).collect();
    // Strict readers reject a ROOT with neither a JOINT nor an End Site.
    assert_eq!(names, ["root", "End Site"]);
    assert_eq!(bvh.nodes[1].parent, Some(0));
    assert!(bvh.nodes[1].offset.is_finite());
    assert!(bvh.nodes[1].channels.is_empty());
    assert_eq!(bvh.frames, 12);
    assert!(bvh.motion.iter().all(|m| m.len() == 6));
    // The root moves with the segment's pose: its point is the segment's origin.
    let fk = bvh_fk(&bvh, 3);
    let want = DVec3::from_array(s.fits.poses[2].translations[3]);
    assert!((fk[0] - want).length() < 1e-5, "{} vs {want}", fk[0]);
    // The glTF likewise: the root and its End Site, valid, animated.
    let glb = gltf::Gltf::from_slice(out.files.get("skeleton.glb").map_or(&[][..], |v| v))
        .unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<&str> = glb.nodes().map(|n| n.name().unwrap_or_default()).collect();
    assert_eq!(&names[..2], ["root", "root end"]);
    let (fk, _) = GlbMotion::read(&glb).at(3);
    assert!(
        (fk[0] * 1000.0 - want).length() < 1e-3,
        "{} vs {want}",
        fk[0]
    );
}

/// A parsed skeleton.glb's motion, read once: each node's parent, rest translation and
/// rotation, and its animated translation and rotation per keyframe where it has them.
struct GlbMotion {
    parent: Vec<Option<usize>>,
    translation: Vec<DVec3>,
    rotation: Vec<DQuat>,
    translations: Vec<Option<Vec<DVec3>>>,
    rotations: Vec<Option<Vec<DQuat>>>,
}

impl GlbMotion {
    fn read(doc: &gltf::Gltf) -> Self {
        let blob = doc.blob.as_deref().unwrap_or_default();
        let count = doc.nodes().count();
        let mut motion = GlbMotion {
            parent: vec![None; count],
            translation: Vec::new(),
            rotation: Vec::new(),
            translations: vec![None; count],
            rotations: vec![None; count],
        };
        for n in doc.nodes() {
            let (t, r, _) = n.transform().decomposed();
            motion.translation.push(DVec3::from_array(t.map(f64::from)));
            motion.rotation.push(DQuat::from_array(r.map(f64::from)));
            for c in n.children() {
                motion.parent[c.index()] = Some(n.index());
            }
        }
        for anim in doc.animations() {
            for channel in anim.channels() {
                let node = channel.target().node().index();
                match channel.reader(|_| Some(blob)).read_outputs() {
                    Some(gltf::animation::util::ReadOutputs::Translations(t)) => {
                        motion.translations[node] =
                            Some(t.map(|v| DVec3::from_array(v.map(f64::from))).collect());
                    }
                    Some(gltf::animation::util::ReadOutputs::Rotations(r)) => {
                        motion.rotations[node] = Some(
                            r.into_f32()
                                .map(|q| DQuat::from_array(q.map(f64::from)).normalize())
                                .collect(),
                        );
                    }
                    _ => panic!("unexpected channel on node {node}"),
                }
            }
        }
        motion
    }

    /// Global position (m) and rotation per node at one keyframe.
    fn at(&self, frame: usize) -> (Vec<DVec3>, Vec<DQuat>) {
        let count = self.parent.len();
        let mut position = vec![DVec3::ZERO; count];
        let mut global = vec![DQuat::IDENTITY; count];
        // Parents come before children in our files; resolve in index order.
        for i in 0..count {
            let (p, q) = self.parent[i].map_or((DVec3::ZERO, DQuat::IDENTITY), |p| {
                assert!(p < i, "node {i}'s parent {p} comes after it");
                (position[p], global[p])
            });
            let t = self.translations[i]
                .as_ref()
                .map_or(self.translation[i], |t| t[frame]);
            let r = self.rotations[i]
                .as_ref()
                .map_or(self.rotation[i], |r| r[frame]);
            position[i] = p + q * t;
            global[i] = q * r;
        }
        (position, global)
    }
}

/// Checks skeleton.glb (parsed and validated by the `gltf` crate) against skeleton.json:
/// names, nesting, per-frame forward kinematics (mm = 1000 × m, JSON points mapped by
/// `axes`), and the skinned bone mesh following its nodes. Gives the positions compared.
fn check_glb(out: &crate::Outputs, axes: impl Fn(DVec3) -> DVec3) -> usize {
    let bytes = out.files.get("skeleton.glb").cloned().unwrap_or_default();
    let glb = gltf::Gltf::from_slice(&bytes).unwrap_or_else(|e| panic!("invalid glTF: {e}"));
    let doc = json(out);
    let frames = doc["frame_count"].as_u64().unwrap_or(0) as usize;
    let names: Vec<String> = glb
        .nodes()
        .map(|n| n.name().unwrap_or_default().to_owned())
        .collect();
    assert_eq!(names[0], "root");
    let anim = glb
        .animations()
        .next()
        .unwrap_or_else(|| panic!("no animation"));
    let blob = glb.blob.as_deref().unwrap_or_default();
    let times: Vec<f32> = anim
        .channels()
        .next()
        .and_then(|c| c.reader(|_| Some(blob)).read_inputs())
        .map(Iterator::collect)
        .unwrap_or_default();
    assert_eq!(times.len(), frames);
    let rate = doc["frame_rate"].as_f64().unwrap_or(0.0);
    assert!((f64::from(times[frames - 1]) - (frames - 1) as f64 / rate).abs() < 1e-5);

    // The skinned bones: each vertex moves with its node (G · inverse bind · rest).
    let skin = glb.skins().next().unwrap_or_else(|| panic!("no skin"));
    let inverse_bind: Vec<[[f32; 4]; 4]> = skin
        .reader(|_| Some(blob))
        .read_inverse_bind_matrices()
        .map(Iterator::collect)
        .unwrap_or_default();
    let mesh = glb.meshes().next().unwrap_or_else(|| panic!("no mesh"));
    let primitive = mesh
        .primitives()
        .next()
        .unwrap_or_else(|| panic!("no primitive"));
    let reader = primitive.reader(|_| Some(blob));
    let vertices: Vec<[f32; 3]> = reader
        .read_positions()
        .map(Iterator::collect)
        .unwrap_or_default();
    let bound: Vec<[u16; 4]> = reader
        .read_joints(0)
        .map(|j| j.into_u16().collect())
        .unwrap_or_default();
    assert_eq!(vertices.len(), bound.len());
    assert!(!vertices.is_empty());

    // Every joint is a node nested as the JSON's parents say.
    let joints: Vec<(String, usize, Value)> = doc["joints"]
        .as_array()
        .cloned()
        .unwrap_or_default()
        .into_iter()
        .map(|j| {
            let name = j["name"].as_str().unwrap_or_default().to_owned();
            let Some(node) = names.iter().position(|n| *n == name) else {
                panic!("joint {name} missing from the glTF")
            };
            let parent = glb
                .nodes()
                .find(|n| n.children().any(|c| c.index() == node))
                .and_then(|n| n.name().map(str::to_owned));
            assert_eq!(
                parent.as_deref(),
                Some(j["parent"].as_str().unwrap_or("root"))
            );
            (name, node, j["positions"].clone())
        })
        .collect();
    let motion = GlbMotion::read(&glb);
    let mut checked = 0;
    for f in 0..frames {
        let (fk, turn) = motion.at(f);
        // Every bone is six vertices: head, tail, waist; its tail is the next node.
        for (v, b) in vertices.chunks_exact(6).zip(bound.chunks_exact(6)) {
            let node = usize::from(b[0][0]);
            let m = inverse_bind[node];
            let rest = DVec3::from_array(v[1].map(f64::from));
            let local = rest + DVec3::new(m[3][0].into(), m[3][1].into(), m[3][2].into());
            let tail = fk[node] + turn[node] * local;
            let nearest = fk
                .iter()
                .map(|p| (*p - tail).length())
                .fold(f64::INFINITY, f64::min);
            assert!(
                nearest < 1e-5,
                "frame {f}: a bone's tail is {nearest} m from any node"
            );
        }
        for (name, node, positions) in &joints {
            let p = &positions[f];
            if p.is_null() {
                continue;
            }
            let error = (fk[*node] * 1000.0 - axes(json_point(p))).length();
            assert!(error < 0.01, "{name} frame {f}: glTF FK off by {error} mm");
            checked += 1;
        }
    }
    checked
}

#[test]
fn glb_forward_kinematics_and_skinned_bones_reproduce_the_json() {
    let s = gappy_scene();
    let out = files(&s, &Params::default());
    let checked = check_glb(&out, |p| p);
    // As many as the BVH compares: every known joint position.
    assert_eq!(checked, check_round_trip(&out, |p| p));
    assert!(checked > 200, "only {checked} positions compared");
    let y_up = files(
        &s,
        &Params {
            y_up: true,
            ..Params::default()
        },
    );
    assert_eq!(check_glb(&y_up, |p| DVec3::new(p.x, p.z, -p.y)), checked);
    assert_ne!(
        y_up.files.get("skeleton.glb"),
        out.files.get("skeleton.glb")
    );
    let glb = gltf::Gltf::from_slice(out.files.get("skeleton.glb").map_or(&[][..], |v| v))
        .unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<&str> = glb.nodes().map(|n| n.name().unwrap_or_default()).collect();
    // The BVH's nodes, its End Sites named after their joints, then the skinned mesh.
    assert_eq!(
        names,
        ["root", "j1", "j3", "j2", "j3 end", "j2 end", "bones"]
    );
    // Quaternions stay on one side from frame to frame (Blender interpolates components).
    let blob = glb.blob.as_deref().unwrap_or_default();
    for channel in glb
        .animations()
        .flat_map(|a| a.channels().collect::<Vec<_>>())
    {
        if let Some(gltf::animation::util::ReadOutputs::Rotations(r)) =
            channel.reader(|_| Some(blob)).read_outputs()
        {
            let r: Vec<DQuat> = r
                .into_f32()
                .map(|q| DQuat::from_array(q.map(f64::from)))
                .collect();
            assert!(r.windows(2).all(|w| w[0].dot(w[1]) >= 0.0));
        }
    }
}

/// A ball joint that turns about one axis only (the scene's nodding head) warns that its
/// centre along that axis is uncertain, with its `centre_gain`; the hip, turning about two
/// axes, does not, and neither does the knee, a hinge, whose gain is as large as the head's.
#[test]
fn a_ball_joint_turning_about_one_axis_warns() {
    let s = scene(120, 60.0);
    let doc = json(&files(&s, &Params::default()));
    let joint = |child: u64| {
        doc["joints"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|j| j["child_segment"].as_u64() == Some(child))
            .unwrap_or_else(|| panic!("a joint into segment {child}: {doc}"))
    };
    let warned = |j: &Value| j["warnings"].to_string().contains("one axis");
    let gain = |j: &Value| j["centre_gain"].as_f64().expect("a centre gain");
    let (hip, head, knee) = (joint(1), joint(3), joint(2));
    assert!(warned(head) && gain(head) > 20.0, "{head}");
    assert!(!warned(hip) && gain(hip) < 10.0, "{hip}");
    assert!(!warned(knee) && gain(knee) > 20.0, "{knee}");
}

#[test]
fn joints_c3d_counts_from_one_and_is_left_out_past_the_formats_frames() {
    let track = |first: i64, frames: usize| {
        mocap_io::Trajectories::new(
            vec!["root".to_owned()],
            100.0,
            first,
            frames,
            vec![[1.0, 2.0, 3.0]; frames],
        )
        .unwrap_or_else(|e| panic!("{e}"))
    };
    let read = |bytes: Vec<u8>| {
        mocap_io::c3d::parse(&bytes, &mocap_io::ReadOptions::default())
            .unwrap_or_else(|e| panic!("{e}"))
            .trajectories
    };
    let kept = crate::trc::c3d(&track(7, 10), "joints.c3d").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(kept.map(read).map(|t| t.first_frame()), Some(7));
    // A capture numbered from 0 (CSV) or running past 65535 is numbered from 1.
    for (first, frames) in [(0, 10), (65_000, 1000)] {
        let bytes =
            crate::trc::c3d(&track(first, frames), "joints.c3d").unwrap_or_else(|e| panic!("{e}"));
        let t = bytes
            .map(read)
            .unwrap_or_else(|| panic!("no joints.c3d from {first}"));
        assert_eq!((t.first_frame(), t.frames()), (1, frames));
    }
    let long = crate::trc::c3d(&track(1, 65_536), "joints.c3d").unwrap_or_else(|e| panic!("{e}"));
    assert!(long.is_none(), "a C3D holds at most 65535 frames");
}
