//! Accuracy of the whole pipeline on the committed synthetic fixtures, scored against
//! their ground truth with `synth::score` (the same scorer `cargo xtask eval` uses).

use crate::support::{Scratch, root};

/// Runs the pipeline on a fixture and scores its skeleton.json against the truth.
fn score_fixture(name: &str) -> synth::score::Score {
    let tmp = Scratch::new(&format!("accuracy-{name}"));
    let out = tmp.run(&root().join(format!("fixtures/{name}.c3d")));
    let truth = synth::read_truth(&root().join(format!("fixtures/{name}.truth.json"))).unwrap();
    let estimate = synth::score::read_estimate(&out.join("skeleton.json")).unwrap();
    synth::score::score(&truth, &estimate)
}

#[test]
fn clean_human_is_segmented_and_jointed_exactly() {
    let s = score_fixture("human-clean");
    assert!(
        (s.ari - 1.0).abs() < 1e-12,
        "segmentation differs from the truth: {s}"
    );
    assert!(s.topology_exact, "{s}");
    // Issue 5: ≤ 0.5 % of the subject's height on clean data (the paper reports ~3 %).
    assert!(s.joint_error_mean_pct.is_some_and(|e| e <= 0.5), "{s}");
    assert!(s.known_fraction >= 0.999, "{s}");
}

#[test]
fn clean_robot_arm_topology_is_exact() {
    let s = score_fixture("robotarm-clean");
    assert!((s.ari - 1.0).abs() < 1e-12, "{s}");
    assert!(s.topology_exact, "{s}");
    assert!(s.joint_error_mean_pct.is_some_and(|e| e <= 3.0), "{s}");
}

#[test]
fn hard_human_stays_within_the_papers_clean_figure() {
    let s = score_fixture("human-hard");
    // Issue 4's bar for noise + skin artefact + gaps.
    assert!(s.joint_error_mean_pct.is_some_and(|e| e <= 4.0), "{s}");
    assert!(s.known_fraction >= 0.90, "{s}");
    assert!(s.topology_recall >= 0.8, "{s}");
}

/// Writes a 480-frame synthetic trial (`cargo xtask synth`) into `tmp`'s `trial` folder,
/// which it gives back.
fn synthesize(tmp: &Scratch, subject: &str, preset: &str, seed: u64) -> std::path::PathBuf {
    synthesize_with(tmp, subject, preset, seed, &[])
}

/// [`synthesize`] with more `cargo xtask synth` arguments (`--markers 2:3`, say).
fn synthesize_with(
    tmp: &Scratch,
    subject: &str,
    preset: &str,
    seed: u64,
    more: &[&str],
) -> std::path::PathBuf {
    let dir = tmp.path("trial");
    let seed = seed.to_string();
    let mut args = vec![
        "synth",
        "--subject",
        subject,
        "--preset",
        preset,
        "--seed",
        &seed,
        "--frames",
        "480",
        "--out",
        dir.to_str().expect("UTF-8 path"),
    ];
    args.extend_from_slice(more);
    crate::support::xtask_ok(&args);
    dir
}

/// Runs the pipeline on the trial `synthesize` wrote as `stem` with `sets` (`STAGE.PARAM=V`)
/// and scores its skeleton.json against the trial's truth.
fn run_and_score(
    tmp: &Scratch,
    dir: &std::path::Path,
    stem: &str,
    sets: &[String],
) -> synth::score::Score {
    let mut args = tmp.run_args(&dir.join(format!("{stem}.c3d")));
    for set in sets {
        args.extend(["--set".into(), set.clone()]);
    }
    crate::support::xtask_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let truth = synth::read_truth(&dir.join(format!("{stem}.truth.json"))).unwrap();
    let estimate = synth::score::read_estimate(&tmp.path("out").join("skeleton.json")).unwrap();
    synth::score::score(&truth, &estimate)
}

/// The mean error (mm) of the true joint `name` in `score`; panics, with the score, when
/// no estimated joint matched it or it was never known.
fn mean_error_mm(score: &synth::score::Score, name: &str) -> f64 {
    score
        .joints
        .iter()
        .find(|j| j.truth == name)
        .unwrap_or_else(|| panic!("{name} matched\n{score}"))
        .mean_mm
        .unwrap_or_else(|| panic!("{name} known in some frame\n{score}"))
}

/// Three joints on one tip of the root segment (random-clean-s30044) are one point, and one
/// point fits any plane: they must not read as a parent side crossing a leaf hinge's axis
/// squarely. Seen across that axis from where the sibling hinges are placed (not from their
/// unplaced centres, which scatter 35-162 mm across it), the leaf's sides stay as the tree
/// has them and its centre stays where its own markers put it (before: 170 mm along the
/// axis, 2.3 % of height).
#[test]
fn siblings_sharing_one_tip_do_not_turn_a_hinge() {
    random_clean_within(30044, 1.0, 8.0);
}

/// Synthesizes the clean random tree of `seed`, runs it with the defaults, and checks its
/// tree is exact and its mean and worst joint errors are at most `mean_pct` and `worst_pct`
/// of its height.
fn random_clean_within(seed: u64, mean_pct: f64, worst_pct: f64) {
    let tmp = Scratch::new(&format!("accuracy-random-clean-{seed}"));
    let dir = synthesize(&tmp, "random", "clean", seed);
    let score = run_and_score(&tmp, &dir, &format!("random-clean-s{seed}"), &[]);
    assert!(score.topology_exact, "{score}");
    assert!(
        score.joint_error_mean_pct.is_some_and(|e| e <= mean_pct),
        "{score}"
    );
    assert!(
        score.joint_error_worst_pct.is_some_and(|e| e <= worst_pct),
        "{score}"
    );
}

/// Checks that skeleton.json (in `tmp`'s out folder) lists exactly the truth's one label
/// swap: its two markers and its frames.
fn assert_truths_swap_found(tmp: &Scratch, truth: &synth::Truth) {
    let [swap] = &truth.swaps[..] else {
        panic!("one swapped pair: {:?}", truth.swaps)
    };
    let doc = crate::support::read_json(&tmp.path("out").join("skeleton.json"));
    let found = doc["label_swaps"].as_array().expect("label_swaps");
    assert_eq!(found.len(), 1, "{found:?}");
    let mut labels: Vec<&str> = found[0]["markers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    labels.sort_unstable();
    let mut expected: Vec<&str> = swap.labels.iter().map(String::as_str).collect();
    expected.sort_unstable();
    assert_eq!(labels, expected);
    let window = [swap.first_frame, swap.first_frame + swap.frames - 1];
    assert_eq!(found[0]["frames"], serde_json::json!([window]));
}

/// A label swap whose partner never leaves its own distances (snowman-messy-s6005: M008 and
/// M024 were close when exchanged, and M024's two-marker home is unseen during the swap):
/// found from M008 alone, proven on the distances that are seen and by the jumps at the
/// window's ends, and undone over exactly the truth's frames. The same search finds no swap
/// in a trial that has none (hexapod-hard-s10009, where skin alone looked exchanged).
#[test]
fn a_swap_whose_partner_stays_put_is_found_by_its_jumps() {
    let tmp = Scratch::new("accuracy-lone-swap");
    let dir = synthesize(&tmp, "snowman", "messy", 6005);
    let score = run_and_score(&tmp, &dir, "snowman-messy-s6005", &[]);
    let truth = synth::read_truth(&dir.join("snowman-messy-s6005.truth.json")).unwrap();
    assert_truths_swap_found(&tmp, &truth);
    assert!(score.topology_exact, "{score}");
    assert!(
        score.joint_error_mean_pct.is_some_and(|e| e <= 1.5),
        "{score}"
    );

    let tmp = Scratch::new("accuracy-no-swap");
    let dir = synthesize(&tmp, "hexapod", "hard", 10009);
    run_and_score(&tmp, &dir, "hexapod-hard-s10009", &[]);
    let doc = crate::support::read_json(&tmp.path("out").join("skeleton.json"));
    assert_eq!(doc["label_swaps"], serde_json::json!([]));
}

/// A leaf hinge (random-clean-s30060, true joint03) whose parent segment carries a sibling
/// hinge pinned by its own child side: the row "the leaf's centre lies square to the
/// sibling's axis" is believed at a few percent, and must move the leaf no further than
/// that. Counted at the sibling's precision alone it pinned the leaf 66 mm from where its
/// markers put it (1.6 % of height; now 0.2 %).
#[test]
fn a_row_through_a_sibling_hinge_moves_it_only_as_far_as_believed() {
    random_clean_within(30060, 0.5, 4.0);
}

/// Two leaf hinges hung on one tip of a poorly posed hub, under skin (random-hard-s30015):
/// the tree takes the hub's two hinges, not the cheaper ball-like pair their children
/// compose (`topo.composite_hinge_cost_ratio`), and each hinge goes to the point those
/// children turn about, which their own pair fit measures where skin tilts the axes apart.
/// Before, the hinges stayed 64 and 136 mm along their axes (bonefit's residual guard
/// refused the slide): 4.6 % of height, worst 16.9 %; now 1.3 % and 3.7 %.
#[test]
fn hinges_on_one_tip_go_where_their_children_turn_about() {
    let tmp = Scratch::new("accuracy-composite-point");
    let dir = synthesize(&tmp, "random", "hard", 30015);
    let score = run_and_score(&tmp, &dir, "random-hard-s30015", &[]);
    assert!(score.topology_exact, "{score}");
    assert_eq!(score.equivalent_joints, 0, "{score}");
    assert!(
        score.joint_error_mean_pct.is_some_and(|e| e <= 2.0),
        "{score}"
    );
    assert!(
        score.joint_error_worst_pct.is_some_and(|e| e <= 6.0),
        "{score}"
    );
    // Without the tree rule the siblings' false edge holds the point (exact only up to
    // the coincident joints).
    let off = run_and_score(
        &tmp,
        &dir,
        "random-hard-s30015",
        &["topo.composite_hinge_cost_ratio=0".into()],
    );
    assert!(off.equivalent_joints > 0, "{off}");
}

/// A label swap whose markers leave homes of two (robot arm, seed 21): found with its exact
/// frames, undone, and the segmentation is the truth's; `run` says so.
#[test]
fn label_swap_is_found_undone_and_reported() {
    let tmp = Scratch::new("accuracy-swap");
    let dir = synthesize(&tmp, "robotarm", "swap", 21);
    let input = dir.join("robotarm-swap-s21.c3d");
    let args = tmp.run_args(&input);
    let out = crate::support::xtask(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success());
    let truth = synth::read_truth(&dir.join("robotarm-swap-s21.truth.json")).unwrap();
    assert_truths_swap_found(&tmp, &truth);
    let estimate = synth::score::read_estimate(&tmp.path("out").join("skeleton.json")).unwrap();
    let score = synth::score::score(&truth, &estimate);
    assert!(
        (score.ari - 1.0).abs() < 1e-12 && score.topology_exact,
        "{score}"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("label swaps found and undone"), "{stderr}");
}

/// The segments (as sorted marker-label lists) and tree edges (as pairs of those, sorted)
/// the segment, jointfit and topo stages find in `traj`.
fn segments_and_tree(traj: &mocap_io::Trajectories) -> (Vec<Vec<String>>, Vec<[Vec<String>; 2]>) {
    let seg = segment::run(traj, &segment::Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let fits =
        jointfit::run(traj, &seg, &jointfit::Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let tree = topo::run(&seg, &fits, &topo::Params::default()).unwrap_or_else(|e| panic!("{e}"));
    let labels = |s: usize| {
        let mut l: Vec<String> = seg.segments[s]
            .markers
            .iter()
            .map(|&m| traj.labels()[m].clone())
            .collect();
        l.sort();
        l
    };
    let mut segments: Vec<Vec<String>> = (0..seg.segments.len()).map(labels).collect();
    segments.sort();
    let mut edges: Vec<[Vec<String>; 2]> = tree
        .joints
        .iter()
        .map(|j| {
            let mut e = [labels(j.parent_segment), labels(j.child_segment)];
            e.sort();
            e
        })
        .collect();
    edges.sort();
    (segments, edges)
}

/// A subject twenty times smaller (an 85 mm human; noise and skin shrink alike) moves the
/// same way, so it gets the full-size segments and tree: the stages' millimetre floors
/// (rigidity tolerance, affinity scale, least marker spread, anchor bounds) shrink with
/// the capture's marker spacing. With the floors as set, the small human came out with
/// 17 segments and 7 wrong joints of 17, the small quadruped with 12 segments.
#[test]
fn a_subject_a_twentieth_the_size_gets_the_full_size_tree() {
    for (subject, preset) in [
        (synth::Subject::Human, synth::Preset::Clean),
        (synth::Subject::Quadruped, synth::Preset::Hard),
    ] {
        let trial = synth::generate(&synth::SynthConfig {
            subject,
            preset,
            seed: 21,
            frames: 480,
            ..synth::SynthConfig::default()
        })
        .unwrap_or_else(|e| panic!("{e}"));
        let full = &trial.trajectories;
        let small = mocap_io::Trajectories::new(
            full.labels().to_vec(),
            full.frame_rate(),
            full.first_frame(),
            full.frames(),
            full.positions()
                .iter()
                .map(|p| p.map(|c| 0.05 * c))
                .collect(),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let (full_segments, full_tree) = segments_and_tree(full);
        let (small_segments, small_tree) = segments_and_tree(&small);
        assert_eq!(small_segments, full_segments, "{}: segments", trial.name);
        assert_eq!(small_tree, full_tree, "{}: tree", trial.name);
        assert_eq!(
            full_tree.len() + 1,
            full_segments.len(),
            "{}: one tree",
            trial.name
        );
    }
}

/// A random tree (seed 30055) rooted by topo at its centre, not at the subject's root: the
/// tree's child of its first hinge is the subject's parent, whose bone meets the axis at a
/// slant. Judged from the segment that turns least in the world (the subject's root),
/// the hinge goes where its true child's bone crosses the axis; judged from the tree's
/// root it lands tens of millimetres along the axis (2.5 % of height on the eval).
#[test]
fn hinge_sides_are_judged_from_the_segment_that_turns_least() {
    let tmp = Scratch::new("accuracy-steadiest");
    let dir = synthesize(&tmp, "random", "clean", 30055);
    let score_with = |steadiest: bool| {
        let set = format!("bonefit.hinge_sides_from_steadiest={steadiest}");
        run_and_score(&tmp, &dir, "random-clean-s30055", &[set])
    };
    let steadiest = score_with(true);
    let tree_root = score_with(false);
    assert!(
        steadiest.topology_exact && tree_root.topology_exact,
        "{steadiest} / {tree_root}"
    );
    assert!(
        steadiest.joint_error_mean_pct.is_some_and(|e| e <= 0.1),
        "from the steadiest segment: {steadiest}"
    );
    assert!(
        tree_root.joint_error_mean_pct.is_some_and(|e| e >= 1.0),
        "from the tree's root: {tree_root}"
    );
}

/// A random tree (seed 30051) whose hinges hang along bones that carry other joints: each
/// such bone's joints draw its line, and a hinge goes where its axis meets it
/// (`bonefit.hinge_lines`); without that line its markers alone place joint07 12.4 mm
/// along its axis (0.4 mm with it).
#[test]
fn a_hinge_along_a_bone_goes_where_its_axis_meets_the_bones_line() {
    let tmp = Scratch::new("accuracy-hinge-lines");
    let dir = synthesize(&tmp, "random", "clean", 30051);
    let score_with = |lines: bool| {
        let set = format!("bonefit.hinge_lines={lines}");
        run_and_score(&tmp, &dir, "random-clean-s30051", &[set])
    };
    let (lines, markers) = (score_with(true), score_with(false));
    assert!(
        lines.topology_exact && markers.topology_exact,
        "{lines} / {markers}"
    );
    assert!(
        lines.joint_error_mean_pct.is_some_and(|e| e <= 0.03),
        "with the lines: {lines}"
    );
    assert!(
        markers.joint_error_mean_pct.is_some_and(|e| e >= 0.1),
        "without: {markers}"
    );
}

/// A clean synthetic snake (`cargo xtask synth --subject snake`) through the whole CLI: the
/// tree is exact and every joint is written `universal` with its two unit axes (the one
/// fixed in the parent's frame, then the child's) and no hinge axis.
#[test]
fn a_snake_robots_joints_are_written_universal_with_their_axes() {
    let tmp = Scratch::new("accuracy-snake-clean");
    let dir = synthesize(&tmp, "snake", "clean", 4);
    let score = run_and_score(&tmp, &dir, "snake-clean-s4", &[]);
    assert!(score.topology_exact, "{score}");
    assert!(
        score.joint_error_mean_pct.is_some_and(|e| e <= 0.1),
        "{score}"
    );
    let skeleton = crate::support::read_json(&tmp.path("out").join("skeleton.json"));
    let joints = skeleton["joints"].as_array().expect("joints");
    assert!(joints.len() >= 5, "{} joints", joints.len());
    for joint in joints {
        assert_eq!(joint["kind"], "universal", "{}", joint["kind_evidence"]);
        let axes: Vec<[f64; 3]> = joint["universal_axes"]
            .as_array()
            .expect("universal_axes")
            .iter()
            .map(|a| {
                let v: Vec<f64> = a
                    .as_array()
                    .expect("axis")
                    .iter()
                    .map(|c| c.as_f64().expect("number"))
                    .collect();
                [v[0], v[1], v[2]]
            })
            .collect();
        assert_eq!(axes.len(), 2);
        for a in &axes {
            let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            assert!((norm - 1.0).abs() < 1e-5, "{a:?}");
        }
        assert!(joint["hinge_axis_in_parent"].is_null());
    }
}

/// With 1 mm of noise and no skin, a knee's hip 420 mm away still places it along its axis:
/// the axis is fitted over every frame, so the noise that wobbles it ~1° per frame tilts
/// it by that over √frames (human-noise-s20001: the left knee 7.9 mm off when the
/// per-frame wobble counted as the tilt; 3.4 and 1.5 mm for the left and right now).
#[test]
fn a_noisy_knee_is_placed_by_its_hip() {
    joints_within("human", "noise", 20001, &["l_knee", "r_knee"], 5.0);
}

/// Synthesizes `subject`'s `preset` trial of `seed`, runs it with the defaults, checks that
/// each of `joints` is within `max_mm` of the truth on average, and gives the score.
fn joints_within(
    subject: &str,
    preset: &str,
    seed: u64,
    joints: &[&str],
    max_mm: f64,
) -> synth::score::Score {
    let tmp = Scratch::new(&format!("accuracy-{subject}-{preset}-{seed}"));
    let dir = synthesize(&tmp, subject, preset, seed);
    let score = run_and_score(&tmp, &dir, &format!("{subject}-{preset}-s{seed}"), &[]);
    for joint in joints {
        let error = mean_error_mm(&score, joint);
        assert!(error < max_mm, "{joint}: {error:.1} mm\n{score}");
    }
    score
}

/// A gap filled from two markers and a joint centre in line with them leaves the pose's
/// spin about that line to noise: snowman-hard-s30038's middle sphere lost a marker for
/// half the trial, and its two others lie in line with its right shoulder (9 mm off the
/// 370 mm line through them). Filled so, the sphere turned about that line, and its waist
/// and neck, 200 mm away, were put 134 and 152 mm off; now those frames are not filled
/// (30 and 12 mm).
#[test]
fn a_fill_in_line_with_its_joint_does_not_turn_the_body() {
    let score = joints_within("snowman", "hard", 30038, &["waist", "neck"], 60.0);
    assert!(score.known_fraction >= 0.95, "{score}");
}

/// A hinge whose rotation leaves its axis a free line slides along it even though the
/// pair's residual grows: the axis wobbles with skin and noise, so any slide grows the
/// residual by that wobble. random-hard-s30034's joint06 (a gain of 43) sat 117 mm along
/// its axis when its 116 mm slide was refused for 10.0 → 11.2 mm of residual; 6 mm off
/// with it.
#[test]
fn a_free_hinge_axis_slides_despite_its_wobble() {
    joints_within("random", "hard", 30034, &["joint06"], 20.0);
}

/// A hinge whose axis is less free keeps part of its slide: random-hard-s30021's joint02,
/// a hinge carrying two child joints that place it, has a centre gain of 16.9 (under
/// `hinge_free_gain`'s 20), and its slide, refused whole for the residual it adds, had
/// left it 139 mm off, nearly all along its axis; g² / (g² + 20²) of it puts it 79 mm off.
#[test]
fn a_less_free_hinge_axis_keeps_part_of_its_slide() {
    joints_within("random", "hard", 30021, &["joint02"], 100.0);
}

/// A segment whose own markers nearly line up is posed through a neighbour's joint along
/// the first pass's tree, but that tree came from its own spin-blind poses: a neighbour off
/// it whose centre fits clearly better is taken (`jointfit.loose_off_tree_ratio`).
/// hexapod-hard-s20023's body was posed through the r2 femur (radial residual 4.62 mm), and
/// the other legs' pairs with it fitted so badly (r3 femur 35 mm) that three hips were
/// never found and the l3 hip sat 110 mm off; through the r3 femur (3.81 mm) every hip is
/// within 33 mm.
#[test]
fn a_body_whose_markers_line_up_takes_the_neighbour_that_fits_best() {
    let hips = ["l1_hip", "r1_hip", "l2_hip", "r2_hip", "l3_hip", "r3_hip"];
    joints_within("hexapod", "hard", 20023, &hips, 40.0);
}

/// A segment's own hinge and the hinge it carries are the two ends of its bone, not one
/// tip: their axes crossing by chance is no point for either. random-hard-s20032's seg04
/// hangs on joint04 and carries the leaf hinge joint07 145 mm away; their axes pass within
/// what the fits leave, and taking the crossing put joint07 102 mm off (80 mm along its
/// axis); 22 mm without it.
#[test]
fn a_segments_own_hinge_and_the_hinge_it_carries_do_not_meet() {
    let tmp = Scratch::new("accuracy-random-hard-chain-axes");
    let dir = synthesize(&tmp, "random", "hard", 20032);
    let score = run_and_score(&tmp, &dir, "random-hard-s20032", &[]);
    let error = mean_error_mm(&score, "joint07");
    assert!(error < 40.0, "joint07: {error:.1} mm\n{score}");
}

/// Asserts that the `hard` trial of `subject` and `seed` gets the exact tree with the
/// defaults and not with `off` (`STAGE.PARAM=V`, the rule under test switched off).
fn exact_only_with_the_rule(scratch: &str, subject: &str, seed: u64, off: &str) {
    exact_only_with_the_rule_given(scratch, subject, seed, &[], off);
}

/// [`exact_only_with_the_rule`] on a trial synthesized with `more` arguments.
fn exact_only_with_the_rule_given(
    scratch: &str,
    subject: &str,
    seed: u64,
    more: &[&str],
    off: &str,
) {
    let tmp = Scratch::new(scratch);
    let dir = synthesize_with(&tmp, subject, "hard", seed, more);
    let stem = format!("{subject}-hard-s{seed}");
    let score = run_and_score(&tmp, &dir, &stem, &[]);
    assert!(score.topology_exact, "{score}");
    let without = run_and_score(&tmp, &dir, &stem, &[off.into()]);
    assert!(!without.topology_exact, "with {off}: {without}");
}

/// random-hard-s20007 with 2–3 markers per segment: the second pass posed seg04 along the
/// tentative tree through seg03's joint (radial residual 5.28 mm), though its true parent
/// seg02's centre holds its markers at 2.90 mm (0.55 times), and topo kept that cheap pair;
/// the third pass poses it through seg02 and the tree is exact (with
/// `jointfit.anchor_swap_ratio=0` it is not).
#[test]
fn a_segment_posed_through_a_worse_anchor_is_posed_again_through_the_better() {
    exact_only_with_the_rule_given(
        "accuracy-random-hard-anchor-swap",
        "random",
        20007,
        &["--markers", "2:3"],
        "jointfit.anchor_swap_ratio=0",
    );
}

/// human-hard-s20037's spanning tree hangs one clavicle on the other (a centre with its
/// twin fits a little better than with the thorax); but what hangs below it (upper arm,
/// forearm, hand) is built like what else hangs below the other, so it is that one's twin
/// and goes to the thorax: the tree is exact (with `topo.twin_cost_ratio=0` it is not).
/// The trial was human-hard-s20022 until d5df52b weighed the joint test's frames by the
/// markers each saw, which merged that trial's thorax with a clavicle.
#[test]
fn a_clavicle_hung_on_its_twin_goes_to_the_thorax() {
    exact_only_with_the_rule(
        "accuracy-human-hard-twins",
        "human",
        20037,
        "topo.twin_cost_ratio=0",
    );
}

/// human-hard-s20046's tree hung the left clavicle (11.30 against the thorax's 15.45) and
/// the head (18.29) on the right clavicle. The head blinds the twins rule (the right
/// clavicle carries one branch more than the left), but it fits a centre with the left
/// clavicle (20.41) and the thorax (16.03) about as well: it sits where the twins meet the
/// thorax, not on one clavicle's far side. Both go to the thorax and the tree is exact
/// (with `topo.twin_leaf_cost_ratio=0` it is not).
#[test]
fn a_head_between_the_clavicles_goes_to_the_thorax() {
    exact_only_with_the_rule(
        "accuracy-human-hard-twin-leaf",
        "human",
        20046,
        "topo.twin_leaf_cost_ratio=0",
    );
}

/// human-hard-s20038's abdomen and thorax (three markers each) ended as one segment: a
/// step after the joint test's rounds assembled that cluster, and nothing tested it,
/// although its best cut, the true one, scores z 5.05 against the test's 4. The last joint
/// test (`segment.joint_retest`) cuts it and the tree is exact (without it, it is not).
#[test]
fn a_cluster_the_last_steps_assemble_is_put_to_the_joint_test() {
    exact_only_with_the_rule(
        "accuracy-human-hard-retest",
        "human",
        20038,
        "segment.joint_retest=false",
    );
}

/// snake-hard-s20030's second link (six markers) was cut 3 + 3: the halves turned 100°
/// RMS relative to each other (rotation z 5.05 against the test's 4), but the turn was the
/// worse posed half spinning about its own centroid, which travelled 8.7 mm in the other
/// half's frame (travel z 2.04, about what one body gives). A rotation counts only with a
/// travel (`segment.joint_rotation_travel_z`), so the link stays whole and the tree is exact
/// (with the rule off it is not).
#[test]
fn a_turn_that_carries_no_centroid_does_not_cut_a_segment() {
    exact_only_with_the_rule(
        "accuracy-snake-hard-spin",
        "snake",
        20030,
        "segment.joint_rotation_travel_z=0",
    );
}

/// random-hard-s30029 hangs seg00 and seg02 on seg01 (their joints cost 17.05 and 7.67,
/// turning 27.9° and 37.7° RMS with the true segments); the sibling pair seg00-seg02 costs
/// 15.50 and turns only 29.4°, so neither costs nor rotations' sizes call it a composite.
/// Seen from seg01 the two joints turn independently, seen from either child they do not
/// (`topo.composite_independence_margin`): the tree is exact, and with the rule off it is
/// not.
#[test]
fn siblings_that_turn_independently_hang_on_their_hub() {
    exact_only_with_the_rule(
        "accuracy-random-hard-independence",
        "random",
        30029,
        "topo.composite_independence_margin=0",
    );
}

/// robot-arm-hard-s50085's root (a 3-marker segment at the tree's centre) cannot be placed
/// in 23 of its 480 frames, while three links below it (3 to 6 markers) are posed by their
/// own markers in every frame: the chains start there from the joint the nearest posed link
/// observes, so those joints stay known (95.2 % of joint-frames when one hidden root hid the
/// whole skeleton). The BVH, animated from the root translation that reaches them, still
/// gives the JSON's positions (the export tests check that); here the known share, the
/// error, and the root point itself left unknown where it is hidden.
#[test]
fn a_hidden_root_leaves_the_posed_links_below_it_known() {
    let tmp = Scratch::new("accuracy-robotarm-hard-50085");
    let dir = synthesize(&tmp, "robotarm", "hard", 50085);
    let score = run_and_score(&tmp, &dir, "robotarm-hard-s50085", &[]);
    assert!(score.known_fraction >= 0.97, "{score}");
    // Its mean was 1.57 % of height when measured, the newly known frames included.
    assert!(
        score.joint_error_mean_pct.is_some_and(|e| e <= 2.0),
        "{score}"
    );
    let doc = crate::support::read_json(&tmp.path("out").join("skeleton.json"));
    let joints = doc["joints"].as_array().cloned().unwrap_or_default();
    let hidden: Vec<usize> = (0..480)
        .filter(|&f| doc["root"]["positions"][f].is_null())
        .collect();
    assert!(hidden.len() >= 20, "root hidden in {} frames", hidden.len());
    for f in hidden {
        let known = joints
            .iter()
            .filter(|j| !j["positions"][f].is_null())
            .count();
        assert!(known >= 3, "frame {f}: {known} joints known");
    }
}

/// human-hard-s20020 ends with a cluster of three markers where the abdomen meets the
/// thorax, holding markers of both (skin moves them with the joint): one segment too many,
/// which no cut and no merge mends. It and its two nearest clusters regroup as
/// the two true bodies (`segment.regroup_ratio`), and the tree is exact; without the
/// regroup it is not.
#[test]
fn a_piece_of_two_segments_at_a_joint_regroups_into_them() {
    exact_only_with_the_rule(
        "accuracy-human-hard-regroup",
        "human",
        20020,
        "segment.regroup_ratio=0",
    );
}
