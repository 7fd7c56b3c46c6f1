//! Markers that never move (floor and reference markers, stray reflections, a fixed base)
//! and markers that fall off, through the whole pipeline: the room is no body's part, a
//! fixed base is its arm's root, and a fallen marker is a gap from where it lies.

use glam::DVec3;
use mocap_io::Trajectories;

use crate::support::{Scratch, cmu_02_01, groups_without, read_json, xtask_ok};

/// A synthetic trial as `cargo xtask eval` makes it (480 frames).
fn trial(subject: synth::Subject, preset: synth::Preset, seed: u64) -> synth::Trial {
    let config = synth::SynthConfig {
        subject,
        preset,
        seed,
        frames: 480,
        ..synth::SynthConfig::default()
    };
    synth::generate(&config).expect("synthetic trial")
}

/// `traj` with `count` floor markers (`FLOOR0`..) appended, spread over 4 m, each
/// jittering by up to ±0.5 mm per axis (seeded), as cameras see a marker lying still.
fn with_floor(traj: &Trajectories, count: usize) -> Trajectories {
    let mut state: u64 = 7;
    let mut jitter = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let mut labels = traj.labels().to_vec();
    labels.extend((0..count).map(|k| format!("FLOOR{k}")));
    let mut positions = Vec::with_capacity(traj.frames() * labels.len());
    for f in 0..traj.frames() {
        positions.extend_from_slice(traj.frame(f));
        for k in 0..count {
            let (x, y) = (-2000.0 + 800.0 * k as f64, 1500.0 - 600.0 * k as f64);
            positions.push([x + jitter(), y + jitter(), 5.0 + jitter()]);
        }
    }
    Trajectories::new(
        labels,
        traj.frame_rate(),
        traj.first_frame(),
        traj.frames(),
        positions,
    )
    .unwrap()
}

/// The ids of skeleton.json's segments that say `"stationary": true`.
fn stationary_segments(skeleton: &serde_json::Value) -> Vec<u64> {
    skeleton["segments"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["stationary"] == true)
        .map(|s| s["id"].as_u64().unwrap())
        .collect()
}

/// A hard synthetic human walking its circle beside six floor markers: `inspect` names
/// them; the floor is a segment of its own that no joint joins, listed once as markers
/// that never move, with no skeleton folder of its own; the human's tree has as many
/// joints as it has alone.
#[test]
fn floor_markers_are_the_room_and_join_no_skeleton() {
    let walk = trial(synth::Subject::Human, synth::Preset::Hard, 20001);
    let tmp = Scratch::new("stationary-floor");
    let alone = tmp.path("alone.c3d");
    mocap_io::write_c3d(&alone, &walk.trajectories).unwrap();
    let input = tmp.path("floor.c3d");
    mocap_io::write_c3d(&input, &with_floor(&walk.trajectories, 6)).unwrap();
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let run = |input: &std::path::Path, out: &str| {
        let args = [
            "run".to_string(),
            path(input),
            "--out".into(),
            path(&tmp.path(out)),
            "--cache".into(),
            path(&tmp.path("cache")),
            "--json".into(),
        ];
        let stdout = xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        (read_json(&tmp.path(out).join("skeleton.json")), report)
    };
    let inspected: serde_json::Value =
        serde_json::from_str(&xtask_ok(&["inspect", &path(&input), "--json"])).unwrap();
    assert_eq!(
        inspected["stationary_markers"],
        serde_json::json!(["FLOOR0", "FLOOR1", "FLOOR2", "FLOOR3", "FLOOR4", "FLOOR5"])
    );
    let (plain, _) = run(&alone, "alone");
    let (skeleton, report) = run(&input, "floor");
    let room = stationary_segments(&skeleton);
    assert_eq!(room.len(), 1, "{}", skeleton["segments"]);
    let floor: Vec<&str> = skeleton["segments"][room[0] as usize]["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    assert_eq!(
        floor,
        ["FLOOR0", "FLOOR1", "FLOOR2", "FLOOR3", "FLOOR4", "FLOOR5"]
    );
    let joints = skeleton["joints"].as_array().unwrap();
    assert_eq!(joints.len(), plain["joints"].as_array().unwrap().len());
    for j in joints {
        for side in ["parent_segment", "child_segment"] {
            assert_ne!(j[side].as_u64(), Some(room[0]), "{j}");
        }
    }
    assert_eq!(skeleton["bodies"].as_array().map(Vec::len), Some(2));
    assert!(!tmp.path("floor").join("body2").exists());
    let findings = report["findings"].to_string();
    assert!(
        findings.contains("markers that never move") && !findings.contains("another body"),
        "{findings}"
    );
    assert_eq!(report["other_bodies"].as_array().map(Vec::len), Some(0));
    let page = std::fs::read_to_string(tmp.path("floor").join("report.html")).unwrap();
    assert!(page.contains("Markers that never move"), "report.html");
    assert!(
        !page.contains("bodies, no joint between them"),
        "report.html"
    );
}

/// A synthetic robot arm whose base is bolted down (every frame moved so the base's
/// markers stay where they were in the first): the base never moves, and its joint with
/// the first link fits like any other, so the arm's tree holds it, as its root.
#[test]
fn a_fixed_base_never_moves_and_is_its_arm_s_root() {
    let arm = trial(synth::Subject::Robotarm, synth::Preset::Noise, 7);
    let traj = &arm.trajectories;
    let labels = traj.labels();
    let base: Vec<usize> = arm.truth.segments[0]
        .markers
        .iter()
        .map(|m| labels.iter().position(|l| l == m).unwrap())
        .collect();
    let at = |f: usize, m: usize| DVec3::from_array(traj.frame(f)[m]);
    let mut positions = Vec::with_capacity(traj.positions().len());
    for f in 0..traj.frames() {
        let pairs: Vec<(DVec3, DVec3)> = base.iter().map(|&m| (at(f, m), at(0, m))).collect();
        let fit = jointfit::absolute_orientation(&pairs).unwrap();
        positions.extend(
            (0..traj.markers()).map(|m| (fit.rotation * at(f, m) + fit.translation).to_array()),
        );
    }
    let fixed = traj.with_positions(positions).unwrap();
    let tmp = Scratch::new("stationary-base");
    let input = tmp.path("fixed.c3d");
    mocap_io::write_c3d(&input, &fixed).unwrap();
    let skeleton = read_json(&tmp.run(&input).join("skeleton.json"));
    let room = stationary_segments(&skeleton);
    assert_eq!(room.len(), 1, "{}", skeleton["segments"]);
    let mut markers: Vec<&str> = skeleton["segments"][room[0] as usize]["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    markers.sort_unstable();
    let mut truth: Vec<&str> = arm.truth.segments[0]
        .markers
        .iter()
        .map(String::as_str)
        .collect();
    truth.sort_unstable();
    assert_eq!(markers, truth);
    let joints = skeleton["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 6);
    assert!(
        joints
            .iter()
            .any(|j| j["parent_segment"].as_u64() == Some(room[0])
                || j["child_segment"].as_u64() == Some(room[0])),
        "no joint holds the base"
    );
    assert_eq!(skeleton["bodies"].as_array().map(Vec::len), Some(0));
    assert_eq!(skeleton["root_segment"].as_u64(), Some(room[0]));
}

/// CMU 02_01 beside one marker lying still, then six: its segments are those it has
/// alone (one point beside it regrouped three of its markers, and six put both upper arms
/// in one segment, before they were set aside), and its tree has as many joints.
#[test]
fn markers_that_never_move_leave_a_real_walk_as_it_is() {
    let Some(walk) = cmu_02_01("stationary_beside_cmu") else {
        return;
    };
    let tmp = Scratch::new("stationary-cmu");
    let mut runs = Vec::new();
    for count in [0, 1, 6] {
        let input = tmp.path(&format!("floor{count}.c3d"));
        mocap_io::write_c3d(&input, &with_floor(&walk, count)).unwrap();
        let out = tmp.run(&input);
        runs.push(read_json(&out.join("skeleton.json")));
        std::fs::remove_dir_all(out).unwrap();
    }
    let joints = |s: &serde_json::Value| s["joints"].as_array().map(Vec::len);
    for (count, run) in [(1, &runs[1]), (6, &runs[2])] {
        assert_eq!(
            groups_without(run, "FLOOR"),
            groups_without(&runs[0], "FLOOR"),
            "{count}"
        );
        assert_eq!(joints(run), joints(&runs[0]), "{count}");
    }
    assert!(stationary_segments(&runs[1]).is_empty());
    assert_eq!(stationary_segments(&runs[2]).len(), 1);
}

/// CMU 02_01 whose RFIN falls off at frame 200 of 343 and lies on the floor: its samples
/// from there on are read as gaps and reported, and the walk's segments are those it has
/// intact (before, the fall regrouped five of them and left RFIN in none).
#[test]
fn a_marker_that_falls_off_a_real_walk_leaves_its_segments_as_they_are() {
    let Some(walk) = cmu_02_01("fallen_marker_cmu") else {
        return;
    };
    let n = walk.markers();
    let rfin = walk
        .labels()
        .iter()
        .position(|l| l.ends_with("RFIN"))
        .unwrap();
    let at = walk.get(200, rfin).expect("RFIN seen at frame 200");
    let mut positions = walk.positions().to_vec();
    let mut state: u64 = 3;
    let mut lying = 0;
    for f in 200..walk.frames() {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        let jitter = 0.6 * (((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5);
        if walk.get(f, rfin).is_some() {
            positions[f * n + rfin] = [at[0] + jitter, at[1] - jitter, 8.0 + jitter];
            lying += 1;
        }
    }
    let fell = walk.with_positions(positions).unwrap();
    let tmp = Scratch::new("fallen-cmu");
    let mut runs = Vec::new();
    for (name, traj) in [("intact", &walk), ("fell", &fell)] {
        let input = tmp.path(&format!("{name}.c3d"));
        mocap_io::write_c3d(&input, traj).unwrap();
        let out = tmp.run(&input);
        runs.push(read_json(&out.join("skeleton.json")));
        std::fs::remove_dir_all(out).unwrap();
    }
    assert_eq!(
        groups_without(&runs[1], "FLOOR"),
        groups_without(&runs[0], "FLOOR")
    );
    let marker = runs[1]["markers"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["label"].as_str().is_some_and(|l| l.ends_with("RFIN")))
        .unwrap()
        .clone();
    assert_eq!(marker["glitch_frames"].as_u64(), Some(lying), "{marker}");
    assert!(marker["segment"].is_u64(), "{marker}");
}
