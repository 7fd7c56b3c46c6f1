//! Props that move on their own beside a subject (a ball, a box pushed about, a second
//! tracked object), through the whole pipeline: each is a body of its own, and the
//! subject's skeleton is the one it has alone.

use mocap_io::Trajectories;

use crate::support::{Scratch, cmu_02_01, groups_without, read_json, xtask_ok};

/// Props beside each capture.
const PROPS: usize = 3;

/// skeleton.json of `walk` alone, of `walk` beside [`PROPS`] props (`synth::with_props`,
/// seed 1), and of that with no bodies segmented apart (`segment.body_gap_ratio=0`), each
/// run in a scratch folder `name`; then `inspect --json` of the capture with the props.
fn alone_and_beside_props(name: &str, walk: &Trajectories) -> [serde_json::Value; 4] {
    let tmp = Scratch::new(name);
    let with = synth::with_props(walk, PROPS, 1).unwrap();
    let [alone, props, one_body] = [
        ("alone", walk, None),
        ("props", &with, None),
        ("one-body", &with, Some("segment.body_gap_ratio=0")),
    ]
    .map(|(what, traj, set)| {
        let input = tmp.path(&format!("{what}.c3d"));
        mocap_io::write_c3d(&input, traj).unwrap();
        let mut args = tmp.run_args(&input);
        args.extend(
            set.into_iter()
                .flat_map(|s| ["--set".to_string(), s.to_string()]),
        );
        xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let out = tmp.path("out");
        let skeleton = read_json(&out.join("skeleton.json"));
        std::fs::remove_dir_all(out).unwrap();
        skeleton
    });
    let input = tmp.path("props.c3d");
    let inspected = xtask_ok(&["inspect", input.to_str().unwrap(), "--json"]);
    [
        alone,
        props,
        one_body,
        serde_json::from_str(&inspected).unwrap(),
    ]
}

/// Each joint of `skeleton` by the sorted labels of its parent's and child's markers.
fn joints_by_markers(
    skeleton: &serde_json::Value,
) -> std::collections::BTreeMap<(Vec<String>, Vec<String>), serde_json::Value> {
    let markers_of = |id: &serde_json::Value| -> Vec<String> {
        let segment = skeleton["segments"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| &s["id"] == id)
            .unwrap();
        let mut labels: Vec<String> = segment["markers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_str().unwrap().to_string())
            .collect();
        labels.sort();
        labels
    };
    skeleton["joints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| {
            let key = (
                markers_of(&j["parent_segment"]),
                markers_of(&j["child_segment"]),
            );
            (key, j.clone())
        })
        .collect()
}

/// The subject beside props has the segments it has alone, and every joint as it has it
/// alone, its centre frame by frame and its bone; each prop is a body of one segment, and
/// `inspect` (`inspected`) lists the bodies, the subject's first.
fn assert_props_leave_the_subject_as_it_is(
    alone: &serde_json::Value,
    props: &serde_json::Value,
    inspected: &serde_json::Value,
) {
    let listed = inspected["independent_bodies"].as_array().unwrap();
    assert_eq!(listed.len(), 1 + PROPS, "{listed:?}");
    for (p, body) in listed[1..].iter().enumerate() {
        assert_eq!(
            body[0].as_str(),
            Some(format!("PROP{p}_0").as_str()),
            "{body}"
        );
    }
    assert_eq!(groups_without(props, "PROP"), groups_without(alone, "PROP"));
    let (before, after) = (joints_by_markers(alone), joints_by_markers(props));
    assert_eq!(
        after.keys().collect::<Vec<_>>(),
        before.keys().collect::<Vec<_>>()
    );
    for (key, joint) in &before {
        for field in ["positions", "bone_length_mm", "kind", "residual_rms_mm"] {
            assert_eq!(after[key][field], joint[field], "{} {field}", joint["name"]);
        }
    }
    let bodies = props["bodies"].as_array().unwrap();
    assert_eq!(bodies.len(), 1 + PROPS, "{bodies:?}");
    let prop_bodies = bodies
        .iter()
        .filter(|b| b["segments"].as_array().unwrap().len() == 1 && b["marker_count"] == 4)
        .count();
    assert_eq!(prop_bodies, PROPS, "{bodies:?}");
    let every_group = groups_without(props, "");
    for p in 0..PROPS {
        let prop: Vec<String> = (0..4).map(|k| format!("PROP{p}_{k}")).collect();
        assert!(every_group.contains(&prop), "{prop:?}");
    }
}

/// A hard synthetic hexapod beside three props; with no bodies segmented apart the props
/// regroup its markers (as they did 5 of seeds 20001–20006: `cargo run --release -p segment
/// --example props_segment hexapod hard 20001..20006`).
#[test]
fn props_beside_a_synthetic_subject_leave_its_skeleton_as_it_is() {
    let config = synth::SynthConfig {
        subject: synth::Subject::Hexapod,
        preset: synth::Preset::Hard,
        seed: 20001,
        frames: 480,
        ..synth::SynthConfig::default()
    };
    let walk = synth::generate(&config).unwrap().trajectories;
    let [alone, props, one_body, inspected] = alone_and_beside_props("props-hexapod", &walk);
    assert_props_leave_the_subject_as_it_is(&alone, &props, &inspected);
    assert_ne!(
        groups_without(&one_body, "PROP"),
        groups_without(&alone, "PROP")
    );
}

/// CMU 02_01 beside three props; with no bodies segmented apart the props regroup its
/// markers (T10 into the pelvis, RSHO into the thorax, LELB into the forearm, and the
/// left and right upper-arm markers LUPA and RUPA into one segment).
#[test]
fn props_beside_a_real_walk_leave_its_skeleton_as_it_is() {
    let Some(walk) = cmu_02_01("props_beside_cmu") else {
        return;
    };
    let [alone, props, one_body, inspected] = alone_and_beside_props("props-cmu", &walk);
    assert_props_leave_the_subject_as_it_is(&alone, &props, &inspected);
    assert_ne!(
        groups_without(&one_body, "PROP"),
        groups_without(&alone, "PROP")
    );
}
