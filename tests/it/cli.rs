//! The runner as a user drives it: default run, caching, reruns, bad input, inspect,
//! batches.

use crate::support::{Scratch, read_json, root, xtask, xtask_ok};

fn stages(json: &serde_json::Value) -> Vec<(String, bool)> {
    json["stages"]
        .as_array()
        .expect("stages array")
        .iter()
        .map(|s| {
            (
                s["name"].as_str().unwrap().to_owned(),
                s["cached"].as_bool().unwrap(),
            )
        })
        .collect()
}

#[test]
fn default_run_writes_the_contract_and_caches_every_stage() {
    let tmp = Scratch::new("default-run");
    let (out, cache) = (tmp.path("out"), tmp.path("cache"));
    let (out, cache) = (out.to_str().unwrap(), cache.to_str().unwrap());
    let args = ["run", "--out", out, "--cache", cache, "--json"];

    let first: serde_json::Value = serde_json::from_str(&xtask_ok(&args)).unwrap();
    let names: Vec<_> = stages(&first).into_iter().map(|(n, _)| n).collect();
    assert_eq!(
        names,
        [
            "mocap-io", "segment", "jointfit", "topo", "bonefit", "export"
        ]
    );
    assert!(stages(&first).iter().all(|(_, cached)| !cached), "{first}");

    let skeleton = read_json(&tmp.path("out/skeleton.json"));
    assert_eq!(skeleton["units"], "mm");
    let frames = skeleton["frame_count"].as_u64().unwrap() as usize;
    assert!(skeleton["frame_rate"].as_f64().unwrap() > 0.0);
    assert!(
        skeleton["segments"].as_array().unwrap().len() >= 15,
        "human has ≥ 15 segments"
    );
    assert!(skeleton["unassigned_markers"].is_array());
    let root = skeleton["root_segment"].as_u64().unwrap();
    let joints = skeleton["joints"].as_array().unwrap();
    assert_eq!(
        joints.len() + 1,
        skeleton["segments"].as_array().unwrap().len()
    );
    let bvh = std::fs::read_to_string(tmp.path("out/skeleton.bvh")).unwrap();
    assert!(bvh.starts_with("HIERARCHY"));
    assert!(bvh.contains(&format!("Frames: {frames}")));
    for j in joints {
        assert_eq!(j["positions"].as_array().unwrap().len(), frames);
        let name = j["name"].as_str().unwrap();
        assert!(
            bvh.contains(&format!("JOINT {name}\n")),
            "BVH lacks joint {name}"
        );
        assert!(["ball", "hinge", "universal", "rigid"].contains(&j["kind"].as_str().unwrap()));
        assert_ne!(j["child_segment"].as_u64().unwrap(), root);
        // Clean data decide the tree: every other pair across a joint costs far more.
        let runner_up = &j["runner_up"];
        assert!(runner_up["parent_side_segment"].is_u64(), "{j}");
        assert!(runner_up["child_side_segment"].is_u64(), "{j}");
        assert!(runner_up["cost_ratio"].as_f64().unwrap() > 1.2, "{j}");
        assert!(!j["warnings"].to_string().contains("could join"), "{j}");
    }
    let csv = std::fs::read_to_string(tmp.path("out/joints.csv")).unwrap();
    assert!(csv.starts_with("frame,joint,x,y,z"));
    // The joint centres as markers: the root, then every joint, as many frames.
    let trc = mocap_io::read_capture(
        &tmp.path("out/joints.trc"),
        &mocap_io::ReadOptions::default(),
    )
    .unwrap();
    let names: Vec<&str> = std::iter::once("root")
        .chain(joints.iter().map(|j| j["name"].as_str().unwrap()))
        .collect();
    assert_eq!(trc.trajectories.labels(), names.as_slice());
    assert_eq!(trc.trajectories.frames(), frames);
    // The glTF: a binary glTF 2.0 container whose nodes include every joint.
    let glb = std::fs::read(tmp.path("out/skeleton.glb")).unwrap();
    assert_eq!(&glb[..4], b"glTF");
    assert_eq!(
        u32::from_le_bytes([glb[8], glb[9], glb[10], glb[11]]) as usize,
        glb.len()
    );
    for name in &names {
        assert!(
            glb.windows(name.len() + 2)
                .any(|w| w == format!("\"{name}\"").as_bytes()),
            "glTF lacks node {name}"
        );
    }
    let report = std::fs::read_to_string(tmp.path("out/report.html")).unwrap();
    assert!(report.starts_with("<!doctype html>") && report.contains("<h2>Joints</h2>"));

    // Nothing changed: nothing recomputed, and the outputs are byte-identical.
    let json_bytes = std::fs::read(tmp.path("out/skeleton.json")).unwrap();
    let again: serde_json::Value = serde_json::from_str(&xtask_ok(&args)).unwrap();
    assert!(stages(&again).iter().all(|(_, cached)| *cached), "{again}");
    assert_eq!(
        std::fs::read(tmp.path("out/skeleton.json")).unwrap(),
        json_bytes
    );

    // A jointfit parameter reruns jointfit and everything downstream, nothing upstream.
    let mut set = args.to_vec();
    set.extend(["--set", "jointfit.alpha=0.25"]);
    let rerun: serde_json::Value = serde_json::from_str(&xtask_ok(&set)).unwrap();
    let cached: Vec<_> = stages(&rerun).into_iter().map(|(_, c)| c).collect();
    assert_eq!(cached, [true, true, false, false, false, false], "{rerun}");
}

#[test]
fn recomputing_without_the_cache_gives_byte_identical_files() {
    let tmp = Scratch::new("determinism");
    let run = |name: &str| {
        let out = tmp.path(name);
        let cache = tmp.path(&format!("cache-{name}"));
        xtask_ok(&[
            "run",
            "--out",
            out.to_str().unwrap(),
            "--cache",
            cache.to_str().unwrap(),
        ]);
        [
            "skeleton.json",
            "skeleton.bvh",
            "skeleton.glb",
            "joints.csv",
            "joints.trc",
            "joints.c3d",
            "markers.trc",
            "markers.c3d",
            "skeleton.osim",
            "skeleton.mot",
            "report.html",
        ]
        .map(|f| std::fs::read(out.join(f)).unwrap())
    };
    assert!(run("a") == run("b"), "two fresh runs differ");
}

#[test]
fn a_bad_capture_fails_clearly_and_writes_nothing() {
    let tmp = Scratch::new("bad-input");
    let bad = tmp.path("broken.c3d");
    let mut bytes = vec![0u8; 1024];
    bytes[0] = 2;
    bytes[1] = 0x50;
    bytes[2..4].copy_from_slice(&u16::MAX.to_le_bytes());
    std::fs::write(&bad, &bytes).unwrap();
    let out = tmp.path("out");
    let args = tmp.run_args(&bad);
    let result = xtask(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!result.status.success());
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(
        stderr.contains("broken.c3d"),
        "error does not name the file: {stderr}"
    );
    assert!(!out.join("skeleton.json").exists() && !out.join("skeleton.bvh").exists());
}

#[test]
fn inspect_json_summarises_a_capture() {
    let fixture = crate::support::root().join("fixtures");
    let c3d = std::fs::read_dir(&fixture)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "c3d"))
        .expect("a committed C3D fixture");
    let json: serde_json::Value =
        serde_json::from_str(&xtask_ok(&["inspect", c3d.to_str().unwrap(), "--json"])).unwrap();
    assert_eq!(json["format"], "c3d");
    assert_eq!(json["units"], "mm");
    let markers = json["markers"].as_u64().unwrap() as usize;
    assert_eq!(json["labels"].as_array().unwrap().len(), markers);
    assert_eq!(json["middle_frame"].as_array().unwrap().len(), markers);
    assert!(json["frames"].as_u64().unwrap() > 0);
    assert!(json["warnings"].is_array());
}

#[test]
fn a_batch_runs_every_capture_and_names_the_ones_that_failed() {
    let tmp = Scratch::new("batch");
    let captures = tmp.path("captures");
    std::fs::create_dir_all(&captures).unwrap();
    for name in ["robotarm-clean.c3d", "human-clean.c3d"] {
        std::fs::copy(root().join("fixtures").join(name), captures.join(name)).unwrap();
    }
    std::fs::write(captures.join("broken.trc"), "PathFileType\t4\n").unwrap();
    // Not a capture's name: left out of the folder's batch.
    std::fs::write(captures.join("notes.txt"), "session notes").unwrap();
    let (out, cache) = (tmp.path("out"), tmp.path("cache"));
    let args = [
        "run",
        captures.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--cache",
        cache.to_str().unwrap(),
        "--json",
    ];
    let result = xtask(&args);
    assert!(!result.status.success(), "a failed capture fails the batch");
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(
        stderr.contains("1 of 3 captures failed") && stderr.contains("broken.trc"),
        "{stderr}"
    );
    // Every good capture was written in its own folder, the broken one nowhere.
    for stem in ["robotarm-clean", "human-clean"] {
        let skeleton = read_json(&out.join(stem).join("skeleton.json"));
        assert!(!skeleton["joints"].as_array().unwrap().is_empty(), "{stem}");
    }
    assert!(!out.join("broken").exists() && !out.join("notes").exists());
    // One JSON entry per capture, in name order: a report or the error.
    let reports: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
    let entries = reports.as_array().unwrap();
    let inputs: Vec<&str> = entries
        .iter()
        .map(|e| e["input"].as_str().unwrap())
        .collect();
    assert!(inputs[0].ends_with("broken.trc") && inputs[1].ends_with("human-clean.c3d"));
    assert!(inputs[2].ends_with("robotarm-clean.c3d"));
    assert!(entries[0]["error"].as_str().unwrap().contains("broken.trc"));
    assert_eq!(entries[1]["report"]["joints"], 17);
    assert!(entries[2]["report"]["files"].as_array().unwrap().len() >= 6);
}

#[test]
fn a_batch_refuses_two_captures_that_would_write_one_folder() {
    let tmp = Scratch::new("batch-stems");
    for dir in ["a", "b"] {
        std::fs::create_dir_all(tmp.path(dir)).unwrap();
        std::fs::copy(
            root().join("fixtures/robotarm-clean.c3d"),
            tmp.path(&format!("{dir}/trial.c3d")),
        )
        .unwrap();
    }
    let out = tmp.path("out");
    let (a, b) = (tmp.path("a/trial.c3d"), tmp.path("b/trial.c3d"));
    let result = xtask(&[
        "run",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!result.status.success());
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(stderr.contains("would both write"), "{stderr}");
    assert!(
        !out.exists(),
        "nothing runs before the batch is known to be sound"
    );
    let empty = tmp.path("a-folder-without-captures");
    std::fs::create_dir_all(&empty).unwrap();
    let result = xtask(&["run", empty.to_str().unwrap()]);
    assert!(!result.status.success());
    assert!(String::from_utf8_lossy(&result.stderr).contains("no C3D, TRC, CSV or TSV file"));
}

/// `mocap-io.frames` and `mocap-io.exclude_markers` from the command line: the skeleton
/// covers the chosen frames under their own numbers and names no left-out marker; a range
/// the capture does not hold fails, naming the capture and the option, and writes nothing.
#[test]
fn a_frame_range_and_left_out_markers_reach_the_skeleton() {
    let tmp = Scratch::new("select");
    let capture = root().join("fixtures/robotarm-clean.c3d");
    let mut args = tmp.run_args(&capture);
    let first_label = {
        let json: serde_json::Value =
            serde_json::from_str(&xtask_ok(&["inspect", capture.to_str().unwrap(), "--json"]))
                .unwrap();
        json["labels"][0].as_str().unwrap().to_string()
    };
    args.extend([
        "--set".into(),
        "mocap-io.frames=[41,240]".into(),
        "--set".into(),
        format!("mocap-io.exclude_markers=[\"{first_label}\"]"),
    ]);
    xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let mut skeleton = read_json(&tmp.path("out/skeleton.json"));
    assert_eq!(skeleton["first_frame"], 41);
    assert_eq!(skeleton["frame_count"], 200);
    // The settings say what was left out (and the reader's note); no segment, joint or
    // marker entry names it.
    let settings = skeleton["settings"].take();
    assert_eq!(
        settings,
        serde_json::json!({
            "mocap-io.frames": [41, 240],
            "mocap-io.exclude_markers": [first_label],
        })
    );
    assert!(
        skeleton["reader_warnings"]
            .as_array()
            .is_some_and(|w| w.iter().any(|w| w.as_str().is_some_and(|w| w
                .starts_with("left out 1 of")
                && w.ends_with(&format!(": {first_label}"))))),
        "{}",
        skeleton["reader_warnings"]
    );
    skeleton["reader_warnings"].take();
    let text = skeleton.to_string();
    assert!(
        !text.contains(&format!("\"{first_label}\"")),
        "{first_label} still named"
    );

    // `inspect` reads the capture as `run` would with the same options, and no others.
    let inspected: serde_json::Value = serde_json::from_str(&xtask_ok(&[
        "inspect",
        capture.to_str().unwrap(),
        "--json",
        "--set",
        "mocap-io.frames=[41,240]",
    ]))
    .unwrap();
    assert_eq!(inspected["frames"], 200);
    let refused = xtask(&[
        "inspect",
        capture.to_str().unwrap(),
        "--set",
        "jointfit.alpha=1",
    ]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("only mocap-io"));

    Scratch::new("select-bad").run_refused(
        &capture,
        "mocap-io.frames=[0,100000]",
        &["robotarm-clean.c3d", "mocap-io.frames"],
    );
}

/// `segment.groups` from the command line: two segments named as one group are one
/// segment of exactly those markers in skeleton.json, the others as found; a label the
/// capture lacks fails, naming the capture, the option and the label, and writes nothing.
#[test]
fn named_groups_reach_the_skeleton() {
    let capture = root().join("fixtures/robotarm-clean.c3d");
    let found = Scratch::new("groups-found");
    found.run(&capture);
    let labels_of = |segment: &serde_json::Value| {
        let mut labels: Vec<String> = segment["markers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap().to_string())
            .collect();
        labels.sort();
        labels
    };
    let automatic: Vec<Vec<String>> = read_json(&found.path("out/skeleton.json"))["segments"]
        .as_array()
        .unwrap()
        .iter()
        .map(labels_of)
        .collect();
    assert!(automatic.len() >= 3, "{automatic:?}");
    let mut group = automatic[0].clone();
    group.extend(automatic[1].iter().cloned());
    group.sort();

    let named = Scratch::new("groups-named");
    let mut args = named.run_args(&capture);
    args.extend([
        "--set".into(),
        format!("segment.groups=[{}]", serde_json::json!(group)),
    ]);
    xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let skeleton = read_json(&named.path("out/skeleton.json"));
    // The file says how it was made.
    assert_eq!(
        skeleton["settings"],
        serde_json::json!({ "segment.groups": [group.clone()] })
    );
    let mut segments: Vec<Vec<String>> = skeleton["segments"]
        .as_array()
        .unwrap()
        .iter()
        .map(labels_of)
        .collect();
    segments.sort();
    let mut expected = automatic[2..].to_vec();
    expected.push(group);
    expected.sort();
    assert_eq!(segments, expected);

    Scratch::new("groups-bad").run_refused(
        &capture,
        &format!("segment.groups=[[\"{}\", \"NOSUCH\"]]", automatic[0][0]),
        &[
            "robotarm-clean.c3d",
            "segment.groups, group 1",
            "\"NOSUCH\"",
        ],
    );
}

/// `topo.joints` from the command line: a pair named by ids or by marker labels is a joint
/// of the tree, said in the notes; an id the segmentation has not fails, naming the option and the pair, and
/// writes nothing.
#[test]
fn named_joints_reach_the_skeleton() {
    let capture = root().join("fixtures/robotarm-clean.c3d");
    let tmp = Scratch::new("joints-named");
    let edges = |skeleton: &serde_json::Value| {
        let mut edges: Vec<(u64, u64)> = skeleton["joints"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| {
                let (p, c) = (
                    j["parent_segment"].as_u64().unwrap(),
                    j["child_segment"].as_u64().unwrap(),
                );
                (p.min(c), p.max(c))
            })
            .collect();
        edges.sort();
        edges
    };
    let automatic = read_json(&tmp.run(&capture).join("skeleton.json"));
    let found = edges(&automatic);
    let (a, b) = found[0];
    let label_on = |s: u64| automatic["segments"][s as usize]["markers"][0].clone();
    // By id, and by the label of a marker on each segment: the same joint, said in the notes.
    for set in [
        format!("topo.joints=[[{b}, {a}]]"),
        format!("topo.joints=[[{}, {}]]", label_on(b), label_on(a)),
    ] {
        let mut args = tmp.run_args(&capture);
        args.extend(["--set".into(), set.clone()]);
        xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        let skeleton = read_json(&tmp.path("out/skeleton.json"));
        assert_eq!(edges(&skeleton), found, "{set}");
        let note = format!("segments {a} and {b} joined as topo.joints names them");
        assert!(
            skeleton["notes"]
                .as_array()
                .unwrap()
                .iter()
                .any(|n| n == note.as_str()),
            "{set}: {}",
            skeleton["notes"]
        );
    }

    Scratch::new("joints-bad").run_refused(
        &capture,
        "topo.joints=[[0, 99]]",
        &["robotarm-clean.c3d", "topo.joints pair [0, 99]"],
    );
}
