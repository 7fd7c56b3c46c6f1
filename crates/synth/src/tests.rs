//! Self-checks of the generator on its own ground truth.

use std::collections::BTreeMap;

use glam::DVec3;

use crate::score::{Estimate, score};
use crate::{Preset, Subject, SynthConfig, Trial, generate, write_trial};

/// Short trials keep the whole suite fast in the dev profile.
fn config(subject: Subject, preset: Preset, seed: u64) -> SynthConfig {
    SynthConfig {
        subject,
        preset,
        frames: 120,
        seed,
        ..SynthConfig::default()
    }
}

fn trial(subject: Subject, preset: Preset, seed: u64) -> Trial {
    generate(&config(subject, preset, seed)).unwrap()
}

/// Marker index by label.
fn index(trial: &Trial) -> BTreeMap<String, usize> {
    trial
        .trajectories
        .labels()
        .iter()
        .enumerate()
        .map(|(i, l)| (l.clone(), i))
        .collect()
}

fn at(trial: &Trial, frame: usize, marker: usize) -> DVec3 {
    DVec3::from(trial.trajectories.frame(frame)[marker])
}

/// max − min of a quantity over frames.
fn spread(values: impl Iterator<Item = f64>) -> f64 {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    hi - lo
}

#[test]
fn clean_markers_are_rigid_and_joint_centres_fixed_in_both_segments() {
    for subject in Subject::ALL {
        let t = trial(subject, Preset::Clean, 1);
        let idx = index(&t);
        let frames = t.trajectories.frames();
        assert_eq!(t.trajectories.missing_samples(), 0);
        for seg in &t.truth.segments {
            for (i, a) in seg.markers.iter().enumerate() {
                for b in &seg.markers[i + 1..] {
                    let s =
                        spread((0..frames).map(|f| at(&t, f, idx[a]).distance(at(&t, f, idx[b]))));
                    assert!(s < 1e-6, "{}: {a}-{b} distance varies by {s} mm", t.name);
                }
            }
        }
        for joint in &t.truth.joints {
            let centre = |f: usize| DVec3::from(joint.positions[f]);
            for s in [joint.parent_segment, joint.child_segment] {
                for m in &t.truth.segments[s].markers {
                    // The truth is rounded to 1e-4 mm per coordinate.
                    let d = spread((0..frames).map(|f| centre(f).distance(at(&t, f, idx[m]))));
                    assert!(
                        d < 2e-4,
                        "{}: {} to {m} varies by {d} mm",
                        t.name,
                        joint.name
                    );
                }
            }
            // And it is not fixed relative to the child's children: the joints really move.
            for grandchild in t
                .truth
                .joints
                .iter()
                .filter(|j| j.parent_segment == joint.child_segment)
            {
                for m in &t.truth.segments[grandchild.child_segment].markers {
                    let d = spread((0..frames).map(|f| centre(f).distance(at(&t, f, idx[m]))));
                    let dist = centre(0).distance(at(&t, 0, idx[m]));
                    if dist > 30.0 {
                        assert!(
                            d > 1.0,
                            "{}: {} to {m} only varies by {d} mm",
                            t.name,
                            joint.name
                        );
                    }
                }
            }
            if let Some(p) = joint.parent_joint {
                let parent = &t.truth.joints[p];
                let bone = spread(
                    (0..frames).map(|f| centre(f).distance(DVec3::from(parent.positions[f]))),
                );
                // Both ends are rounded to 1e-4 mm per coordinate.
                assert!(
                    bone < 4e-4,
                    "{}: bone {} varies by {bone}",
                    t.name,
                    joint.name
                );
                let length = centre(0).distance(DVec3::from(parent.positions[0]));
                assert!((length - joint.bone_length_mm.unwrap_or(0.0)).abs() < 2e-4);
            }
        }
    }
}

/// Asserts that a joint's degree of freedom swept between `least` and `most` degrees.
fn assert_swept_within(t: &Trial, joint: &str, swept: f64, least: f64, most: f64) {
    assert!(
        (least..=most).contains(&swept),
        "{}: {joint} sweeps {swept}°, outside [{least}°, {most}°]",
        t.name
    );
}

/// `sweep` bounds what every degree of freedom of every subject moves through, and a
/// share outside (0, 1] is refused.
#[test]
fn a_narrow_sweep_moves_every_joint_through_that_share_of_its_range() {
    for subject in Subject::ALL {
        let t = generate(&SynthConfig {
            sweep: (0.2, 0.3),
            ..config(subject, Preset::Clean, 5)
        })
        .unwrap();
        for j in &t.truth.joints {
            for ([lo, hi], swept) in j.rom_deg.iter().zip(&j.swept_deg) {
                let width = hi - lo;
                assert_swept_within(&t, &j.name, *swept, 0.2 * width - 1e-3, 0.3 * width + 1e-3);
            }
        }
    }
    for sweep in [(0.0, 0.5), (0.6, 0.5), (0.5, 1.01), (f64::NAN, 0.5)] {
        let bad = SynthConfig {
            sweep,
            ..SynthConfig::default()
        };
        assert!(bad.validate().is_err(), "{sweep:?}");
    }
}

#[test]
fn every_joint_sweeps_most_of_its_range_in_enough_axes() {
    for subject in Subject::ALL {
        for seed in [1, 2] {
            let t = trial(subject, Preset::Clean, seed);
            for j in &t.truth.joints {
                let mut big = 0;
                for ([lo, hi], swept) in j.rom_deg.iter().zip(&j.swept_deg) {
                    let width = hi - lo;
                    assert_swept_within(&t, &j.name, *swept, 0.6 * width, width + 1e-3);
                    big += usize::from(*swept >= 30.0);
                }
                let needed = if j.kind == "ball" { 2 } else { 1 };
                assert!(
                    big >= needed,
                    "{}: {} moves ≥ 30° in only {big} axes",
                    t.name,
                    j.name
                );
                if j.kind == "hinge" {
                    let axis = j.axis.map(DVec3::from).unwrap_or_default();
                    assert!((axis.length() - 1.0).abs() < 1e-6);
                } else {
                    assert!(j.axis.is_none());
                }
            }
        }
    }
}

#[test]
fn root_travels_and_turns_once() {
    let t = generate(&SynthConfig::default()).unwrap();
    let root = &t.truth.segments[t.truth.root_segment];
    assert!(root.parent_joint.is_none());
    // Heading of the pelvis–hip line: the root's markers' mean moves a few metres around a circle.
    let idx = index(&t);
    let f_last = t.trajectories.frames() - 1;
    let mean = |f: usize| {
        root.markers
            .iter()
            .map(|m| at(&t, f, idx[m]))
            .sum::<DVec3>()
            / root.markers.len() as f64
    };
    let mut path = 0.0;
    for f in 1..=f_last {
        path += mean(f).truncate().distance(mean(f - 1).truncate());
    }
    assert!((1500.0..5000.0).contains(&path), "path {path} mm");
    // After a full turn the body faces the way it started: last and first frames nearly agree.
    let start_to_end = mean(0).truncate().distance(mean(f_last).truncate());
    assert!(start_to_end < 0.2 * path, "{start_to_end}");
    let half = mean(0).truncate().distance(mean(f_last / 2).truncate());
    assert!(half > 0.2 * path, "{half}");
}

#[test]
fn same_seed_gives_identical_output_and_different_seeds_differ() {
    for subject in [Subject::Human, Subject::Random] {
        let a = trial(subject, Preset::Hard, 5);
        let b = trial(subject, Preset::Hard, 5);
        assert_eq!(a.truth.to_json().unwrap(), b.truth.to_json().unwrap());
        let bits = |t: &Trial| -> Vec<u64> {
            t.trajectories
                .positions()
                .iter()
                .flatten()
                .map(|c| c.to_bits())
                .collect()
        };
        assert_eq!(bits(&a), bits(&b));
        assert_eq!(a.trajectories.labels(), b.trajectories.labels());
        let c = trial(subject, Preset::Hard, 6);
        assert_ne!(a.truth.to_json().unwrap(), c.truth.to_json().unwrap());
    }
    // The preset does not change the body or motion.
    let clean = trial(Subject::Human, Preset::Clean, 5);
    let hard = trial(Subject::Human, Preset::Hard, 5);
    assert_eq!(clean.truth.joints, hard.truth.joints);
    assert_eq!(clean.truth.segments, hard.truth.segments);
}

#[test]
fn all_subjects_generate_under_every_preset_with_any_marker_count() {
    for subject in Subject::ALL {
        for (seed, preset) in Preset::ALL.into_iter().enumerate() {
            let cfg = SynthConfig {
                frames: 40,
                markers_per_segment: if seed % 2 == 0 { (1, 2) } else { (3, 6) },
                ..config(subject, preset, seed as u64 + 10)
            };
            let t = generate(&cfg).unwrap();
            let (lo, hi) = cfg.markers_per_segment;
            assert!(t.truth.segments.len() >= 5, "{}", t.name);
            assert_eq!(t.truth.joints.len(), t.truth.segments.len() - 1);
            let mut seen = 0;
            for s in &t.truth.segments {
                assert!((lo..=hi).contains(&s.markers.len()), "{}", t.name);
                seen += s.markers.len();
            }
            assert_eq!(seen, t.trajectories.markers());
            assert!(t.truth.height_mm > 100.0);
            assert_eq!(t.truth.frame_count, 40);
            assert!(t.truth.joints.iter().all(|j| j.positions.len() == 40));
            // Labels reveal nothing: sequential numbers, not grouped by segment.
            assert_eq!(t.trajectories.labels()[0], "M000");
        }
    }
}

#[test]
fn labels_are_shuffled_across_segments() {
    let t = trial(Subject::Human, Preset::Clean, 1);
    // Consecutive labels on the same segment would betray the grouping; a shuffle leaves few.
    let seg_of: BTreeMap<&str, usize> = t
        .truth
        .segments
        .iter()
        .enumerate()
        .flat_map(|(s, seg)| seg.markers.iter().map(move |m| (m.as_str(), s)))
        .collect();
    let labels = t.trajectories.labels();
    let same = labels
        .windows(2)
        .filter(|w| seg_of[w[0].as_str()] == seg_of[w[1].as_str()])
        .count();
    assert!(
        same < labels.len() / 4,
        "{same} of {} neighbours share a segment",
        labels.len()
    );
}

#[test]
fn gaps_have_the_documented_structure() {
    let t = trial(Subject::Human, Preset::Gaps, 3);
    let n = t.trajectories.markers();
    let frames = t.trajectories.frames();
    let idx = index(&t);
    // The listed holes are exactly the missing samples.
    let mut listed = vec![false; n * frames];
    for g in &t.truth.gaps {
        for f in g.first_frame..g.first_frame + g.frames {
            listed[f * n + idx[&g.label]] = true;
        }
    }
    for f in 0..frames {
        for m in 0..n {
            assert_eq!(
                listed[f * n + m],
                t.trajectories.get(f, m).is_none(),
                "frame {f} marker {m}"
            );
        }
    }
    let kinds = |k: &str| {
        t.truth
            .gaps
            .iter()
            .filter(|g| g.kind == k)
            .collect::<Vec<_>>()
    };
    let lost = kinds("lost");
    assert_eq!(lost.len(), 1);
    let m = idx[&lost[0].label];
    assert!((0..frames / 2).all(|f| t.trajectories.get(f, m).is_some()));
    assert!((frames / 2..frames).all(|f| t.trajectories.get(f, m).is_none()));
    let long = kinds("long");
    assert!(!long.is_empty() && long.len() <= n / 10 + 1);
    for g in &long {
        assert!(
            (12..=36).contains(&g.frames),
            "long gap of {} frames",
            g.frames
        );
    }
    let short = kinds("short");
    for g in &short {
        assert!((2..=20).contains(&g.frames));
    }
    let with_short: std::collections::BTreeSet<&str> =
        short.iter().map(|g| g.label.as_str()).collect();
    assert!(
        with_short.len() >= n / 4,
        "{} of {n} markers have short holes",
        with_short.len()
    );
}

#[test]
fn noise_skin_and_swap_do_what_they_say() {
    let clean = trial(Subject::Human, Preset::Clean, 4);
    let diff = |t: &Trial| -> Vec<DVec3> {
        t.trajectories
            .positions()
            .iter()
            .zip(clean.trajectories.positions())
            .map(|(a, b)| DVec3::from(*a) - DVec3::from(*b))
            .collect()
    };
    let noisy = diff(&trial(Subject::Human, Preset::Noise, 4));
    let var = noisy.iter().map(|d| d.length_squared()).sum::<f64>() / (3 * noisy.len()) as f64;
    assert!(
        (var.sqrt() - 1.0).abs() < 0.05,
        "noise sigma {}",
        var.sqrt()
    );

    let skin = trial(Subject::Human, Preset::Skin, 4);
    let d = diff(&skin);
    let n = clean.trajectories.markers();
    for m in 0..n {
        let largest = (0..clean.trajectories.frames())
            .map(|f| d[f * n + m].length())
            .fold(0.0, f64::max);
        assert!(
            (5.0 - 1e-6..=15.0 + 1e-6).contains(&largest),
            "marker {m}: {largest} mm"
        );
    }

    let swapped = trial(Subject::Human, Preset::Swap, 4);
    assert_eq!(swapped.truth.swaps.len(), 1);
    let s = &swapped.truth.swaps[0];
    let idx = index(&clean);
    let (a, b) = (idx[&s.labels[0]], idx[&s.labels[1]]);
    let seg_of = |l: &str| {
        clean
            .truth
            .segments
            .iter()
            .position(|seg| seg.markers.iter().any(|m| m == l))
    };
    assert_ne!(seg_of(&s.labels[0]), seg_of(&s.labels[1]));
    assert_eq!(s.frames, 18);
    for f in 0..clean.trajectories.frames() {
        let inside = (s.first_frame..s.first_frame + s.frames).contains(&f);
        let (pa, pb) = (
            at(&swapped, f, a),
            at(&clean, f, if inside { b } else { a }),
        );
        assert_eq!(pa, pb, "frame {f}");
    }
}

#[test]
fn truth_scores_perfectly_against_itself() {
    for subject in Subject::ALL {
        let t = trial(subject, Preset::Clean, 2);
        let est = Estimate::from_truth(&t.truth);
        let s = score(&t.truth, &est);
        assert_eq!(s.ari, 1.0, "{s}");
        assert!(s.topology_exact && s.root_correct, "{s}");
        assert_eq!(s.joint_error_mean_mm, Some(0.0));
        assert_eq!(s.joint_error_worst_mm, Some(0.0));
        assert_eq!(s.known_fraction, 1.0);
        assert_eq!(s.kind_accuracy, Some(1.0));
        assert!(s.bone_length_std_mm.unwrap_or(0.0) < 1e-4, "{s}");
        // Through skeleton.json text, as the pipeline writes it.
        let text = serde_json::to_string(&est).unwrap();
        let back: Estimate = serde_json::from_str(&text).unwrap();
        assert_eq!(score(&t.truth, &back), s);
    }
}

#[test]
fn score_detects_a_wrong_estimate() {
    let t = trial(Subject::Human, Preset::Clean, 2);
    let mut est = Estimate::from_truth(&t.truth);
    // Merge the left hand into the left forearm, dropping the wrist.
    let wrist = t
        .truth
        .joints
        .iter()
        .position(|j| j.name == "l_wrist")
        .unwrap();
    let (fore, hand) = (
        t.truth.joints[wrist].parent_segment,
        t.truth.joints[wrist].child_segment,
    );
    let hand_markers = std::mem::take(&mut est.segments[hand].markers);
    est.segments[fore].markers.extend(hand_markers);
    est.joints.remove(wrist);
    // Shift every other centre by 10 mm, hide the knee in half the frames, call it a ball.
    for j in &mut est.joints {
        for p in j.positions.iter_mut().flatten() {
            p[0] += 10.0;
        }
        if j.name == "l_knee" {
            j.kind = "ball".into();
            for p in j.positions.iter_mut().step_by(2) {
                *p = None;
            }
        }
    }
    // An edge that does not exist: head to left foot.
    let head = t
        .truth
        .segments
        .iter()
        .position(|s| s.name == "head")
        .unwrap();
    let foot = t
        .truth
        .segments
        .iter()
        .position(|s| s.name == "l_foot")
        .unwrap();
    est.joints.push(crate::score::EstimatedJoint {
        name: "bogus".into(),
        parent_segment: head,
        child_segment: foot,
        kind: "ball".into(),
        positions: vec![None; t.truth.frame_count],
    });
    let s = score(&t.truth, &est);
    assert!(s.ari < 0.99 && s.ari > 0.8, "{s}");
    assert!(!s.topology_exact);
    assert_eq!(s.matched_joints, t.truth.joints.len() - 1);
    assert!((s.topology_recall - 16.0 / 17.0).abs() < 1e-12);
    assert!((s.topology_precision - 16.0 / 17.0).abs() < 1e-12);
    let mean = s.joint_error_mean_mm.unwrap();
    assert!((mean - 10.0).abs() < 1e-3, "{s}");
    assert!(s.known_fraction < 1.0 && s.known_fraction > 0.95);
    assert!((s.kind_accuracy.unwrap() - 15.0 / 16.0).abs() < 1e-12);
    assert!(s.to_string().starts_with("ARI "));
    assert!(!s.to_string().contains('\n'));
}

#[test]
fn estimate_reads_the_output_contract_and_ignores_unknown_fields() {
    let text = r#"{"units": "mm", "frame_rate": 120.0, "frame_count": 2, "extra": {"x": 1},
        "segments": [{"id": 7, "markers": ["M000", "M001"], "name": "s7"}],
        "unassigned_markers": ["M002"], "root_segment": 7,
        "joints": [{"name": "j3", "parent_segment": 7, "child_segment": 3, "kind": "ball",
                    "positions": [[1.0, 2.0, 3.0], null], "offset": [0, 0, 0]}]}"#;
    let e: Estimate = serde_json::from_str(text).unwrap();
    assert_eq!(e.segments[0].id, 7);
    assert_eq!(e.joints[0].positions, vec![Some([1.0, 2.0, 3.0]), None]);
    assert_eq!(e.unassigned_markers, vec!["M002".to_string()]);
}

/// A scratch directory under the system temp dir, removed on drop.
struct Scratch(std::path::PathBuf);
impl Scratch {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("synth-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        Self(dir)
    }
}
impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn written_trial_reads_back_unchanged_and_byte_identical() {
    let t = trial(Subject::Human, Preset::Hard, 1);
    let dir = Scratch::new("roundtrip");
    let paths = write_trial(&dir.0, &t, false).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(paths.len(), 2);
    let capture = mocap_io::read_capture(&paths[0], &mocap_io::ReadOptions::default()).unwrap();
    let back = &capture.trajectories;
    assert_eq!(back.labels(), t.trajectories.labels());
    assert_eq!(back.frames(), t.trajectories.frames());
    assert!((back.frame_rate() - t.trajectories.frame_rate()).abs() < 1e-6);
    for (a, b) in back.positions().iter().zip(t.trajectories.positions()) {
        assert_eq!(mocap_io::is_present(*a), mocap_io::is_present(*b));
        if mocap_io::is_present(*b) {
            for k in 0..3 {
                // f32 keeps 24 bits: relative error ≤ 6e-8.
                assert!(
                    (a[k] - b[k]).abs() <= 1e-7 * b[k].abs().max(1.0),
                    "{a:?} vs {b:?}"
                );
            }
        }
    }
    let truth = crate::read_truth(&paths[1]).unwrap();
    assert_eq!(truth, t.truth);
    // Written twice: byte-identical files.
    let first: Vec<Vec<u8>> = paths.iter().map(|p| std::fs::read(p).unwrap()).collect();
    let again = write_trial(&dir.0, &t, false).unwrap();
    let second: Vec<Vec<u8>> = again.iter().map(|p| std::fs::read(p).unwrap()).collect();
    assert!(first == second, "rewritten files differ");

    // With a TRC too: same labels, frames and gaps, positions to the TRC's decimals.
    let with_trc = write_trial(&dir.0, &t, true).unwrap();
    assert_eq!(with_trc.len(), 3);
    let trc = mocap_io::read_capture(&with_trc[2], &mocap_io::ReadOptions::default()).unwrap();
    assert_eq!(trc.trajectories.labels(), t.trajectories.labels());
    for (a, b) in trc
        .trajectories
        .positions()
        .iter()
        .zip(t.trajectories.positions())
    {
        assert_eq!(mocap_io::is_present(*a), mocap_io::is_present(*b));
        if mocap_io::is_present(*b) {
            assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-3), "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn truth_json_is_compact_and_round_trips() {
    let t = trial(Subject::Robotarm, Preset::Gaps, 1);
    let json = t.truth.to_json().unwrap();
    let back = crate::Truth::from_json(&json).unwrap();
    assert_eq!(back, t.truth);
    // One line per joint-centre frame, not five.
    assert!(json.lines().count() < t.truth.joints.len() * (t.truth.frame_count + 30) + 200);
}

#[test]
fn committed_fixtures_are_reproducible() {
    // The fixtures come from examples/make_fixtures.rs in the release profile; the same
    // bytes from this (dev) build show the output does not depend on the profile.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    for (subject, preset, markers_per_segment) in [
        (Subject::Human, Preset::Clean, (3, 4)),
        (Subject::Human, Preset::Hard, (3, 4)),
        (Subject::Robotarm, Preset::Clean, (3, 6)),
    ] {
        let stem = format!("{}-{}", subject.name(), preset.name());
        let committed = std::fs::read_to_string(dir.join(format!("{stem}.truth.json")))
            .unwrap_or_else(|e| panic!("fixtures/{stem}.truth.json is committed: {e}"));
        let mut t = generate(&SynthConfig {
            subject,
            preset,
            markers_per_segment,
            ..SynthConfig::default()
        })
        .unwrap();
        t.truth.name = stem.clone();
        assert!(
            t.truth.to_json().unwrap() == committed,
            "{stem}.truth.json differs"
        );
        let c3d = std::fs::read(dir.join(format!("{stem}.c3d"))).unwrap();
        assert!(
            mocap_io::c3d::write(&t.trajectories).unwrap() == c3d,
            "{stem}.c3d differs"
        );
    }
}

#[test]
fn true_segment_markers_cover_every_marker_once() {
    let t = trial(Subject::Quadruped, Preset::Gaps, 4);
    let segments = t.true_segment_markers();
    assert_eq!(segments.len(), t.truth.segments.len());
    let mut seen: Vec<usize> = segments.iter().flatten().copied().collect();
    seen.sort_unstable();
    assert_eq!(seen, (0..t.trajectories.markers()).collect::<Vec<_>>());
    for (markers, truth) in segments.iter().zip(&t.truth.segments) {
        let labels: Vec<&str> = markers
            .iter()
            .map(|&m| t.trajectories.labels()[m].as_str())
            .collect();
        assert_eq!(
            labels,
            truth.markers.iter().map(String::as_str).collect::<Vec<_>>()
        );
    }
}

/// Two children on one parent's tip: hanging the second on the first instead is the same
/// skeleton in motion, and scores as exact (centre scored, kind not); hanging it on a
/// segment elsewhere does not.
#[test]
fn coincident_joints_make_equivalent_trees_exact() {
    let found = (1..40u64).find_map(|seed| {
        let t = trial(Subject::Random, Preset::Clean, seed);
        let joints = &t.truth.joints;
        let pair = (0..joints.len()).find_map(|j| {
            ((j + 1)..joints.len())
                .find(|&k| {
                    joints[j].parent_segment == joints[k].parent_segment
                        && joints[j].positions == joints[k].positions
                })
                .map(|k| (j, k))
        })?;
        Some((t, pair))
    });
    let (t, (j, k)) = found.expect("a random tree with two children on one tip in seeds 1..40");
    let mut est = Estimate::from_truth(&t.truth);
    est.joints[k].parent_segment = t.truth.joints[j].child_segment;
    let s = score(&t.truth, &est);
    assert!(s.topology_exact, "{s}");
    assert_eq!(s.equivalent_joints, 1, "{s}");
    assert_eq!(s.joint_error_mean_mm, Some(0.0), "{s}");
    assert_eq!(s.kind_accuracy, Some(1.0), "{s}");
    assert_eq!(s.joints.iter().filter(|js| js.equivalent).count(), 1);
    // A segment that touches none of the coincident joints.
    let elsewhere = (0..t.truth.segments.len()).find(|&seg| {
        seg != t.truth.joints[k].child_segment
            && t.truth
                .joints
                .iter()
                .filter(|jt| jt.positions == t.truth.joints[k].positions)
                .all(|jt| jt.parent_segment != seg && jt.child_segment != seg)
    });
    // Splitting the second child in two, both halves on the parent: the duplicate is an
    // extra joint, not a re-hung one (it must not take the first child's place).
    let mut split = Estimate::from_truth(&t.truth);
    let c2 = t.truth.joints[k].child_segment;
    let half = split.segments[c2].markers.split_off(1);
    let new_id = split.segments.len();
    split.segments.push(crate::score::EstimatedSegment {
        id: new_id,
        markers: half,
    });
    split.joints.remove(j);
    let mut extra = split.joints[k - 1].clone();
    extra.child_segment = new_id;
    split.joints.push(extra);
    let s = score(&t.truth, &split);
    assert!(!s.topology_exact && s.equivalent_joints == 0, "{s}");
    let seg = elsewhere.expect("random trees have at least 5 segments");
    let mut wrong = Estimate::from_truth(&t.truth);
    wrong.joints[k].parent_segment = seg;
    let s = score(&t.truth, &wrong);
    assert!(!s.topology_exact && s.equivalent_joints == 0, "{s}");
}

/// Widest angle (degrees) between two markers' directions from the bone, over the
/// segments of `subject` (seed 3) with markers placed within `arc_deg`.
fn widest_marker_angle(subject: Subject, arc_deg: f64) -> f64 {
    let body = crate::subjects::build(subject, &mut crate::rng(3, crate::Stream::Body));
    let set = crate::markers::place(
        &body,
        (3, 6),
        arc_deg,
        &mut crate::rng(3, crate::Stream::Markers),
    );
    let mut widest: f64 = 0.0;
    for (s, seg) in body.segments.iter().enumerate() {
        let [start, end] = seg.bone;
        let Some(axis) = (end - start).try_normalize() else {
            continue;
        };
        let directions: Vec<DVec3> = set
            .local
            .iter()
            .zip(&set.segment)
            .filter(|&(_, &g)| g == s)
            .filter_map(|(p, _)| (*p - start).reject_from_normalized(axis).try_normalize())
            .collect();
        for a in &directions {
            for b in &directions {
                widest = widest.max(a.angle_between(*b).to_degrees());
            }
        }
    }
    widest
}

/// `marker_arc_deg` keeps each segment's markers on one side of its bone (real limb sets
/// sit laterally), all round by default; an arc outside (0, 360] is refused.
#[test]
fn a_marker_arc_puts_each_segments_markers_on_one_side_of_its_bone() {
    for subject in Subject::ALL {
        let widest = widest_marker_angle(subject, 90.0);
        assert!(
            widest <= 90.0 + 1e-6,
            "{subject:?}: markers {widest:.1}° apart around a bone"
        );
        assert!(
            widest_marker_angle(subject, 360.0) > 120.0,
            "{subject:?}: all round, some segment's markers should be far apart"
        );
    }
    for arc in [0.0, -10.0, 361.0, f64::NAN] {
        let bad = SynthConfig {
            marker_arc_deg: arc,
            ..SynthConfig::default()
        };
        assert!(bad.validate().is_err(), "{arc}");
    }
}

/// `skin_mm` sets each marker's largest soft-tissue displacement: against the clean twin
/// (the same body, markers and motion), every marker of a `skin` trial at 2–2 mm moves by
/// at most 2 mm and reaches it; a range below 0 or upside down is refused.
#[test]
fn skin_amplitude_follows_the_configured_range() {
    let of = |preset, skin_mm| {
        generate(&SynthConfig {
            preset,
            frames: 120,
            seed: 3,
            skin_mm,
            ..SynthConfig::default()
        })
        .expect("trial")
    };
    let clean = of(Preset::Clean, (2.0, 2.0));
    let skin = of(Preset::Skin, (2.0, 2.0));
    let (c, s) = (&clean.trajectories, &skin.trajectories);
    let n = c.markers();
    for m in 0..n {
        let largest = (0..c.frames())
            .map(|f| {
                let (a, b) = (c.positions()[f * n + m], s.positions()[f * n + m]);
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        assert!((largest - 2.0).abs() < 0.01, "marker {m}: {largest} mm");
    }
    for skin_mm in [(-1.0, 2.0), (3.0, 2.0), (0.0, f64::NAN)] {
        let bad = SynthConfig {
            skin_mm,
            ..SynthConfig::default()
        };
        assert!(bad.validate().is_err(), "{skin_mm:?}");
    }
}
