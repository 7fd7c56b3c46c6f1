//! An unlabeled capture: every marker's trajectory cut at each of its gaps into tracks of
//! their own, shuffled and named as a reconstruction names them (`*12`), as Motive's
//! `Unlabeled N` or an unlabeled Vicon trial comes. The reader joins the pieces
//! (`mocap-io.stitch`), and the skeleton is the labelled capture's.

use std::collections::{BTreeMap, BTreeSet};

use crate::support::{Scratch, xtask_ok};

/// The trial's trajectories cut at every gap into pieces, shuffled by a fixed permutation;
/// each piece's label and the label of the marker it was cut from.
fn cut_at_gaps(t: &mocap_io::Trajectories) -> (mocap_io::Trajectories, Vec<String>) {
    let mut pieces: Vec<(usize, std::ops::Range<usize>)> = Vec::new();
    for m in 0..t.markers() {
        let mut f = 0;
        while f < t.frames() {
            if t.get(f, m).is_none() {
                f += 1;
                continue;
            }
            let start = f;
            while f < t.frames() && t.get(f, m).is_some() {
                f += 1;
            }
            pieces.push((m, start..f));
        }
    }
    // A fixed shuffle (multiplicative hash order), so piece order says nothing.
    pieces.sort_by_key(|(m, r)| ((m * 7919 + r.start * 104_729) % 1_000_003, *m, r.start));
    let n = pieces.len();
    let mut positions = vec![mocap_io::MISSING; t.frames() * n];
    for (k, (m, frames)) in pieces.iter().enumerate() {
        for f in frames.clone() {
            positions[f * n + k] = t.frame(f)[*m];
        }
    }
    let labels: Vec<String> = (0..n).map(|k| format!("*{k}")).collect();
    let cut = mocap_io::Trajectories::new(
        labels,
        t.frame_rate(),
        t.first_frame(),
        t.frames(),
        positions,
    )
    .unwrap();
    let origin = pieces.iter().map(|(m, _)| t.labels()[*m].clone()).collect();
    (cut, origin)
}

/// The skeleton's joints as pairs of true segment names (each found segment named by the
/// true segment most of its markers are on), and its segment count.
fn tree(
    skeleton: &serde_json::Value,
    owner: &BTreeMap<String, String>,
    origin: &BTreeMap<String, String>,
) -> (usize, BTreeSet<(String, String)>) {
    let segments = skeleton["segments"].as_array().unwrap();
    let name: Vec<String> = segments
        .iter()
        .map(|s| {
            let mut votes: BTreeMap<&str, usize> = BTreeMap::new();
            for m in s["markers"].as_array().unwrap() {
                let label = m.as_str().unwrap();
                let marker = origin.get(label).map_or(label, String::as_str);
                *votes.entry(owner[marker].as_str()).or_default() += 1;
            }
            let best = votes
                .iter()
                .max_by_key(|(n, v)| (**v, std::cmp::Reverse(**n)));
            best.map(|(n, _)| n.to_string()).unwrap()
        })
        .collect();
    let edges = skeleton["joints"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| {
            let a = name[j["parent_segment"].as_u64().unwrap() as usize].clone();
            let b = name[j["child_segment"].as_u64().unwrap() as usize].clone();
            (a.clone().min(b.clone()), a.max(b))
        })
        .collect();
    (segments.len(), edges)
}

#[test]
fn an_unlabeled_capture_cut_at_every_gap_gives_the_labelled_skeleton() {
    let trial = synth::generate(&synth::SynthConfig {
        subject: synth::Subject::Human,
        preset: synth::Preset::Hard,
        frames: 480,
        seed: 20001,
        ..synth::SynthConfig::default()
    })
    .unwrap();
    let owner: BTreeMap<String, String> = trial
        .truth
        .segments
        .iter()
        .flat_map(|s| s.markers.iter().map(|m| (m.clone(), s.name.clone())))
        .collect();
    let truth: BTreeSet<(String, String)> = trial
        .truth
        .joints
        .iter()
        .map(|j| {
            let a = trial.truth.segments[j.parent_segment].name.clone();
            let b = trial.truth.segments[j.child_segment].name.clone();
            (a.clone().min(b.clone()), a.max(b))
        })
        .collect();
    let (cut, origin) = cut_at_gaps(&trial.trajectories);
    assert!(
        cut.markers() > trial.trajectories.markers() + 40,
        "{} pieces",
        cut.markers()
    );
    let tmp = Scratch::new("unlabeled");
    let input = tmp.path("unlabeled.c3d");
    mocap_io::write_c3d(&input, &cut).unwrap();

    // Every join is right: a joined track's pieces were cut from one marker.
    let read = mocap_io::read_capture(&input, &mocap_io::ReadOptions::default()).unwrap();
    let piece = |label: &str| origin[label[1..].parse::<usize>().unwrap()].clone();
    for joined in &read.info.stitched {
        let from: BTreeSet<String> = joined.iter().map(|l| piece(l)).collect();
        assert_eq!(from.len(), 1, "{joined:?} joins {from:?}");
    }
    let joined: usize = read.info.stitched.iter().map(Vec::len).sum();
    assert!(
        joined >= 80,
        "only {joined} of {} pieces joined",
        cut.markers()
    );

    // The skeleton: the true tree, as the labelled capture gives it.
    let origin: BTreeMap<String, String> = (0..cut.markers())
        .map(|k| (format!("*{k}"), origin[k].clone()))
        .collect();
    let out = tmp.run(&input);
    let skeleton: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("skeleton.json")).unwrap()).unwrap();
    assert_eq!(
        tree(&skeleton, &owner, &origin),
        (truth.len() + 1, truth.clone())
    );

    // Without the joining the pieces make a different, wrong skeleton.
    let apart = tmp.path("apart");
    xtask_ok(&[
        "run",
        input.to_str().unwrap(),
        "--out",
        apart.to_str().unwrap(),
        "--cache",
        tmp.path("cache-apart").to_str().unwrap(),
        "--set",
        "mocap-io.stitch=false",
    ]);
    let skeleton: serde_json::Value =
        serde_json::from_slice(&std::fs::read(apart.join("skeleton.json")).unwrap()).unwrap();
    assert_ne!(tree(&skeleton, &owner, &origin).1, truth);
}
