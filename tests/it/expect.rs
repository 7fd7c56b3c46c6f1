//! Readable snapshots of what the pipeline makes of the committed fixtures: segments,
//! the tree, joint kinds and bone lengths rounded to 0.1 mm. A change in behaviour shows
//! as a diff of `tests/it/expect/*.txt`; after checking it, accept it with
//! `UPDATE_EXPECT=1 cargo test -p xtask --test it expect`.

use std::fmt::Write as _;

use crate::support::{Scratch, read_json, root};

/// The summary text of one fixture's skeleton.json.
fn summary(fixture: &str) -> String {
    let tmp = Scratch::new(&format!("expect-{fixture}"));
    let out = tmp.run(&root().join(format!("fixtures/{fixture}.c3d")));
    let s = read_json(&out.join("skeleton.json"));
    let mut text = String::new();
    let _ = writeln!(
        text,
        "frames {} at {} Hz",
        s["frame_count"], s["frame_rate"]
    );
    for seg in s["segments"].as_array().unwrap() {
        let markers: Vec<&str> = seg["markers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_str().unwrap())
            .collect();
        let _ = writeln!(text, "segment {:>2}: {}", seg["id"], markers.join(" "));
    }
    let _ = writeln!(text, "unassigned: {}", s["unassigned_markers"]);
    let _ = writeln!(text, "root segment {}", s["root_segment"]);
    for j in s["joints"].as_array().unwrap() {
        let _ = writeln!(
            text,
            "{:<4} {:>2} -> {:>2}  {:<6} bone {:.1} mm",
            j["name"].as_str().unwrap(),
            j["parent_segment"],
            j["child_segment"],
            j["kind"].as_str().unwrap(),
            j["bone_length_mm"].as_f64().unwrap()
        );
    }
    text
}

fn check(fixture: &str) {
    let path = root().join(format!("tests/it/expect/{fixture}.txt"));
    let actual = summary(fixture);
    if std::env::var_os("UPDATE_EXPECT").is_some() {
        std::fs::write(&path, &actual).unwrap();
        return;
    }
    let expected = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        expected == actual,
        "{} differs from what the pipeline makes now; if the change is intended, run \
         UPDATE_EXPECT=1 cargo test -p xtask --test it expect\n--- expected\n{expected}--- actual\n{actual}",
        path.display()
    );
}

#[test]
fn human_clean_summary() {
    check("human-clean");
}

#[test]
fn robotarm_clean_summary() {
    check("robotarm-clean");
}
