//! Unit tests on hand-made rigid bodies and articulated chains with known partitions.

use mocap_io::{MISSING, Trajectories};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::*;

type V3 = [f64; 3];

fn rotate(axis: V3, angle: f64, v: V3) -> V3 {
    // Rodrigues' formula; `axis` is a unit vector.
    let (s, c) = angle.sin_cos();
    let cross = [
        axis[1] * v[2] - axis[2] * v[1],
        axis[2] * v[0] - axis[0] * v[2],
        axis[0] * v[1] - axis[1] * v[0],
    ];
    let dot = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
    std::array::from_fn(|k| v[k] * c + cross[k] * s + axis[k] * dot * (1.0 - c))
}

fn unit(rng: &mut ChaCha8Rng) -> V3 {
    loop {
        let v: V3 = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 0.2 && n < 1.0 {
            return v.map(|x| x / n);
        }
    }
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller; enough for test noise.
    let u: f64 = rng.random_range(1e-12..1.0);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A test capture: `sizes[s]` markers per segment. `chain`: each segment hangs from the
/// previous one at a joint (articulated); otherwise each body moves on its own.
/// Returns trajectories and the true partition (marker indices per segment).
struct Scene {
    sizes: Vec<usize>,
    chain: bool,
    frames: usize,
    noise_mm: f64,
    gap_fraction: f64,
    seed: u64,
}

impl Scene {
    fn build(&self) -> (Trajectories, Vec<Vec<usize>>) {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let segs = self.sizes.len();
        // Each segment: local marker offsets from its joint, a rotation axis and frequencies.
        let mut truth = Vec::new();
        let mut offsets = Vec::new();
        let mut next = 0;
        for &k in &self.sizes {
            truth.push((next..next + k).collect::<Vec<_>>());
            next += k;
            let bone = rng.random_range(200.0..400.0);
            offsets.push(
                (0..k)
                    .map(|_| {
                        let along = rng.random_range(0.15..0.85) * bone;
                        let side: V3 = unit(&mut rng).map(|x| x * rng.random_range(30.0..70.0));
                        [side[0], side[1], side[2] - along]
                    })
                    .collect::<Vec<V3>>(),
            );
        }
        let motions: Vec<(V3, V3, f64, f64, f64)> = (0..segs)
            .map(|_| {
                (
                    unit(&mut rng),
                    unit(&mut rng),
                    rng.random_range(0.02..0.06),
                    rng.random_range(0.01..0.05),
                    rng.random_range(0.0..6.0),
                )
            })
            .collect();
        let bones: Vec<f64> = (0..segs).map(|_| rng.random_range(250.0..400.0)).collect();
        let labels: Vec<String> = (0..next).map(|m| format!("M{m:02}")).collect();
        let mut positions = Vec::with_capacity(self.frames * next);
        for f in 0..self.frames {
            let t = f as f64;
            // Per segment a global frame as (rotation applied as a list of axis-angles, origin).
            let mut origin: V3 = [0.0, 0.0, 1000.0];
            let mut chain_rot: Vec<(V3, f64)> = Vec::new();
            let mut frame_markers = Vec::new();
            for s in 0..segs {
                let (a1, a2, w1, w2, ph) = motions[s];
                let r1 = (a1, 0.9 * (w1 * t + ph).sin());
                let r2 = (a2, 0.7 * (w2 * t + 2.0 * ph).cos());
                if !self.chain {
                    chain_rot.clear();
                    origin = [
                        s as f64 * 500.0 + 100.0 * (0.01 * t).sin(),
                        50.0 * (0.013 * t + s as f64).cos(),
                        1000.0,
                    ];
                }
                chain_rot.push(r1);
                chain_rot.push(r2);
                let apply = |v: V3| {
                    chain_rot
                        .iter()
                        .rev()
                        .fold(v, |acc, &(ax, an)| rotate(ax, an, acc))
                };
                for o in &offsets[s] {
                    let p = apply(*o);
                    frame_markers.push([origin[0] + p[0], origin[1] + p[1], origin[2] + p[2]]);
                }
                if self.chain {
                    let tip = apply([0.0, 0.0, -bones[s]]);
                    origin = [origin[0] + tip[0], origin[1] + tip[1], origin[2] + tip[2]];
                }
            }
            for p in frame_markers {
                if rng.random::<f64>() < self.gap_fraction {
                    positions.push(MISSING);
                } else {
                    positions.push(p.map(|x| x + self.noise_mm * gauss(&mut rng)));
                }
            }
        }
        let traj = Trajectories::new(labels, 100.0, 1, self.frames, positions)
            .expect("valid test capture");
        (traj, truth)
    }
}

fn partition(seg: &Segmentation) -> Vec<Vec<usize>> {
    seg.segments.iter().map(|s| s.markers.clone()).collect()
}

fn four_bodies(seed: u64) -> Scene {
    Scene {
        sizes: vec![3, 5, 4, 3],
        chain: false,
        frames: 600,
        noise_mm: 0.3,
        gap_fraction: 0.05,
        seed,
    }
}

#[test]
fn independent_rigid_bodies_are_found_exactly() {
    for seed in [1, 2, 3] {
        let (traj, truth) = four_bodies(seed).build();
        let seg = run(&traj, &Params::default()).expect("segments");
        assert_eq!(partition(&seg), truth, "seed {seed}");
        assert_eq!(seg.eigengap_segments, 4, "seed {seed}: eigen-gap count");
        assert!(seg.unassigned.is_empty());
        // Spectrum: four eigenvalues near 1, then a clear drop.
        assert!(
            seg.eigenvalues[3] > 0.95 && seg.eigenvalues[4] < 0.0,
            "{:?}",
            seg.eigenvalues
        );
    }
}

#[test]
fn articulated_chain_is_found_exactly_by_every_variant() {
    let scene = Scene {
        sizes: vec![4, 3, 5, 3, 2],
        chain: true,
        frames: 800,
        noise_mm: 0.5,
        gap_fraction: 0.1,
        seed: 11,
    };
    let (traj, truth) = scene.build();
    let variants = [
        Params::default(),
        Params {
            rigidity_check: false,
            ..Params::default()
        },
        Params {
            affinity: Affinity::Absolute,
            ..Params::default()
        },
        Params {
            method: Method::Cliques,
            ..Params::default()
        },
    ];
    for params in variants {
        let seg = run(&traj, &params).expect("segments");
        assert_eq!(partition(&seg), truth, "{params:?}");
    }
}

#[test]
fn noiseless_rigid_data_does_not_collapse() {
    let scene = Scene {
        noise_mm: 0.0,
        gap_fraction: 0.0,
        ..four_bodies(5)
    };
    let (traj, truth) = scene.build();
    let seg = run(&traj, &Params::default()).expect("segments");
    assert_eq!(partition(&seg), truth);
    assert!(seg.noise_mm < 1e-6, "noise {}", seg.noise_mm);
    assert_eq!(seg.tolerance_mm, Params::default().tolerance_min_mm);
}

#[test]
fn rarely_seen_marker_is_unassigned_with_reason() {
    let (traj, truth) = four_bodies(7).build();
    let (n, frames) = (traj.markers(), traj.frames());
    let mut positions = traj.positions().to_vec();
    // Marker 4 (second body) is seen in only 8 frames.
    for f in 8..frames {
        positions[f * n + 4] = MISSING;
    }
    let traj =
        Trajectories::new(traj.labels().to_vec(), 100.0, 1, frames, positions).expect("valid");
    let seg = run(&traj, &Params::default()).expect("segments");
    assert_eq!(seg.unassigned.len(), 1);
    assert_eq!(seg.unassigned[0].marker, 4);
    assert!(
        seg.unassigned[0].reason.starts_with("visible in "),
        "{}",
        seg.unassigned[0].reason
    );
    assert_eq!(seg.markers[4].segment, None);
    let expected: Vec<Vec<usize>> = truth
        .into_iter()
        .map(|s| s.into_iter().filter(|&m| m != 4).collect())
        .collect();
    assert_eq!(partition(&seg), expected);
}

#[test]
fn same_seed_gives_identical_output() {
    let (traj, _) = Scene {
        sizes: vec![3, 4, 3, 5, 3, 4],
        chain: true,
        frames: 400,
        noise_mm: 1.0,
        gap_fraction: 0.2,
        seed: 9,
    }
    .build();
    let a = run(&traj, &Params::default()).expect("segments");
    let b = run(&traj, &Params::default()).expect("segments");
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
}

#[test]
fn rigidity_check_splits_a_forced_merge() {
    let (traj, truth) = four_bodies(4).build();
    let forced = Params {
        segments: 2,
        ..Params::default()
    };
    let seg = run(&traj, &forced).expect("segments");
    assert_eq!(seg.eigengap_segments, 2);
    assert_eq!(partition(&seg), truth);
    // The paper's method alone: no rigidity check, and no joint test, which cuts the two
    // independent 3-marker bodies forced together by where one goes in the other's frame.
    let paper_like = Params {
        segments: 2,
        rigidity_check: false,
        joint_split_z: 0.0,
        ..Params::default()
    };
    assert_eq!(run(&traj, &paper_like).expect("segments").segments.len(), 2);
}

#[test]
fn sliding_marker_is_flagged() {
    let (traj, truth) = four_bodies(8).build();
    let (n, frames) = (traj.markers(), traj.frames());
    let mut positions = traj.positions().to_vec();
    // Marker 5 (second body, 5 markers) slides back and forth by ±6 mm along x.
    for f in 0..frames {
        let p = &mut positions[f * n + 5];
        p[0] += 6.0 * (0.05 * f as f64).sin();
    }
    let traj =
        Trajectories::new(traj.labels().to_vec(), 100.0, 1, frames, positions).expect("valid");
    let seg = run(&traj, &Params::default()).expect("segments");
    assert_eq!(partition(&seg), truth);
    let sliding: Vec<usize> = (0..n).filter(|&m| seg.markers[m].slides).collect();
    assert_eq!(sliding, vec![5]);
    assert!(seg.markers[5].rigidity_residual_mm > 2.0);
    assert!(seg.markers[6].rigidity_residual_mm < 0.6 * seg.markers[5].rigidity_residual_mm);
    assert!(seg.markers[9].rigidity_residual_mm < 1.0);
}

#[test]
fn a_glitching_marker_stays_with_its_body_and_its_glitch_is_counted() {
    let (traj, truth) = four_bodies(8).build();
    let (n, frames) = (traj.markers(), traj.frames());
    let mut positions = traj.positions().to_vec();
    // Marker 9 (third body, 4 markers) is reconstructed 60 mm off for 40 of 600 frames.
    for f in 300..340 {
        let p = &mut positions[f * n + 9];
        if mocap_io::is_present(*p) {
            p[0] += 60.0;
        }
    }
    let glitched_frames = (300..340).filter(|&f| traj.get(f, 9).is_some()).count();
    let traj =
        Trajectories::new(traj.labels().to_vec(), 100.0, 1, frames, positions).expect("valid");
    let seg = run(&traj, &Params::default()).expect("segments");
    assert_eq!(partition(&seg), truth);
    // A frame where the jump happens to keep most of its distances is not a glitch.
    let counted = seg.markers[9].glitch_frames;
    assert!(
        (glitched_frames - 3..=glitched_frames).contains(&counted),
        "{counted}"
    );
    let others: usize = (0..n)
        .filter(|&m| m != 9)
        .map(|m| seg.markers[m].glitch_frames)
        .sum();
    assert_eq!(others, 0);
    // Later stages read the same samples as gaps: exactly the counted ones, all in the jump.
    assert!(seg.glitches.iter().all(|g| g.marker == 9));
    let repaired = seg.repaired(&traj);
    let blanked: Vec<usize> = (0..frames)
        .filter(|&f| traj.get(f, 9).is_some() && repaired.get(f, 9).is_none())
        .collect();
    assert_eq!(blanked.len(), counted);
    assert!(
        blanked.iter().all(|f| (300..340).contains(f)),
        "{blanked:?}"
    );
    assert!((0..n).filter(|&m| m != 9).all(|m| {
        (0..frames).all(|f| traj.get(f, m).is_some() == repaired.get(f, m).is_some())
    }));
    // Unchecked, its distances to its body spread so far that it is rigid with none of its
    // markers and leaves the body (`loose_marker_factor`); with that off it stays, to be
    // measured against the checked run.
    let unchecked = Params {
        glitch_factor: 0.0,
        ..Params::default()
    };
    let loose = run(&traj, &unchecked).expect("segments");
    assert!(
        loose
            .segments
            .iter()
            .all(|s| !s.markers.contains(&9) || s.markers.len() == 1)
    );
    let unchecked = Params {
        loose_marker_factor: 0.0,
        ..unchecked
    };
    let plain = run(&traj, &unchecked).expect("segments");
    assert_eq!(plain.markers[9].glitch_frames, 0);
    assert!(plain.glitches.is_empty());
    assert!(matches!(
        plain.repaired(&traj),
        std::borrow::Cow::Borrowed(_)
    ));
    // Its distances to its body steady again (10.7 mm unchecked, 1.2 mm checked).
    let (checked, unchecked) = (
        seg.markers[9].rigidity_residual_mm,
        plain.markers[9].rigidity_residual_mm,
    );
    assert!(checked < 0.2 * unchecked, "{checked} vs {unchecked}");
}

#[test]
fn pair_statistics_match_a_direct_computation() {
    let (traj, _) = four_bodies(3).build();
    let stats = crate::pairstats::pair_stats(&traj);
    for (i, j) in [(0, 1), (2, 9), (5, 14)] {
        let d: Vec<f64> = (0..traj.frames())
            .filter_map(|f| {
                let (a, b) = (traj.get(f, i)?, traj.get(f, j)?);
                Some(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
            })
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let std = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        let k = stats.at(i, j);
        assert_eq!(stats.overlap[k], d.len());
        assert!((stats.mean[k] - mean).abs() < 1e-9);
        assert!(
            (stats.std[k] - std).abs() < 1e-9,
            "{} vs {std}",
            stats.std[k]
        );
        assert_eq!(stats.std[k], stats.std[stats.at(j, i)]);
    }
}

#[test]
fn paper_affinity_works_on_short_clean_captures_and_degrades_gracefully_on_long_ones() {
    let short = Scene {
        frames: 60,
        noise_mm: 0.0,
        gap_fraction: 0.0,
        ..four_bodies(2)
    };
    let (traj, _) = short.build();
    let paper = Params {
        affinity: Affinity::Paper,
        rigidity_check: false,
        ..Params::default()
    };
    // 60 frames: σ = mean distance / 60 ≈ 8 mm, so 2σ² dwarfs every ρ and all is one body.
    let seg = run(&traj, &paper).expect("segments");
    assert_eq!(seg.segments.len(), 1);
    // 600 noiseless frames: σ < 1 mm, Eq. 1 separates the bodies.
    let long_clean = Scene {
        noise_mm: 0.0,
        gap_fraction: 0.0,
        ..four_bodies(2)
    };
    let (traj, truth) = long_clean.build();
    let seg = run(&traj, &paper).expect("segments");
    assert_eq!(partition(&seg), truth);
    // 600 noisy frames: Eq. 1 underflows; the stage still answers and says why.
    let (traj, _) = four_bodies(2).build();
    let seg = run(&traj, &paper).expect("segments");
    let covered =
        seg.segments.iter().map(|s| s.markers.len()).sum::<usize>() + seg.unassigned.len();
    assert_eq!(covered, traj.markers());
}

#[test]
fn bad_input_is_an_error() {
    let empty = Trajectories::new(vec!["A".into()], 100.0, 1, 0, vec![]).expect("valid");
    assert!(matches!(
        run(&empty, &Params::default()),
        Err(Error::EmptyCapture { .. })
    ));
    let (traj, _) = four_bodies(1).build();
    let bad = Params {
        restarts: 0,
        ..Params::default()
    };
    assert!(matches!(
        run(&traj, &bad),
        Err(Error::InvalidParam {
            name: "restarts",
            ..
        })
    ));
}

#[test]
fn param_docs_cover_every_field() {
    let value = serde_json::to_value(Params::default()).expect("serialises");
    let fields: Vec<&String> = value.as_object().expect("object").keys().collect();
    assert_eq!(fields.len(), PARAM_DOCS.len());
    for f in fields {
        assert!(PARAM_DOCS.iter().any(|(n, _)| n == f), "{f} undocumented");
    }
}

/// Adjusted Rand index of two labelings (Hubert & Arabie 1985); 1 = identical partitions.
fn ari(a: &[usize], b: &[usize]) -> f64 {
    use std::collections::BTreeMap;
    let c2 = |v: f64| v * (v - 1.0) / 2.0;
    let mut table: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    let (mut ra, mut rb) = (BTreeMap::new(), BTreeMap::new());
    for (&x, &y) in a.iter().zip(b) {
        *table.entry((x, y)).or_default() += 1.0;
        *ra.entry(x).or_insert(0.0) += 1.0;
        *rb.entry(y).or_insert(0.0) += 1.0;
    }
    let index: f64 = table.values().map(|&v| c2(v)).sum();
    let sa: f64 = ra.values().map(|&v| c2(v)).sum();
    let sb: f64 = rb.values().map(|&v| c2(v)).sum();
    let expected = sa * sb / c2(a.len() as f64);
    let max = 0.5 * (sa + sb);
    if (max - expected).abs() < 1e-12 {
        1.0
    } else {
        (index - expected) / (max - expected)
    }
}

/// A synthetic trial with the generator's defaults.
fn synth_trial(subject: synth::Subject, preset: synth::Preset, seed: u64) -> synth::Trial {
    trial_of(subject, preset, seed, synth::SynthConfig::default().frames)
}

/// A synthetic trial as `cargo xtask eval` makes it: the generator's defaults, 480 frames.
fn eval_trial(subject: synth::Subject, preset: synth::Preset, seed: u64) -> synth::Trial {
    trial_of(subject, preset, seed, 480)
}

/// A synthetic trial as `cargo xtask eval --markers 2:3` makes it: 480 frames, two or
/// three markers per segment.
fn sparse_eval_trial(subject: synth::Subject, preset: synth::Preset, seed: u64) -> synth::Trial {
    let config = synth::SynthConfig {
        subject,
        preset,
        seed,
        frames: 480,
        markers_per_segment: (2, 3),
        ..synth::SynthConfig::default()
    };
    synth::generate(&config).expect("synthetic trial")
}

/// A synthetic trial with the generator's defaults but its length.
fn trial_of(
    subject: synth::Subject,
    preset: synth::Preset,
    seed: u64,
    frames: usize,
) -> synth::Trial {
    let config = synth::SynthConfig {
        subject,
        preset,
        seed,
        frames,
        ..synth::SynthConfig::default()
    };
    synth::generate(&config).expect("synthetic trial")
}

/// How many found segments hold markers of `segment` (a true segment's name).
fn pieces_of(trial: &synth::Trial, seg: &Segmentation, segment: &str) -> usize {
    let truth = true_markers(trial, segment);
    seg.segments
        .iter()
        .filter(|s| s.markers.iter().any(|m| truth.binary_search(m).is_ok()))
        .count()
}

/// Skin without noise (eval's 480 frames): two of the right forearm's six markers, whose
/// skin moves alike, are cut from it by the rigidity check (its ρ reach 9.87 mm, beyond
/// even the merge's tolerance of 9.57), and the pair rejoin puts them back (the forearm's
/// own body holds them as well as it holds its markers). Without it the regroup does:
/// the pair, the rest of the forearm and the hand are two bodies that fit almost as well
/// as three. Without both the forearm stays in two.
#[test]
fn a_pair_skin_cut_from_its_segment_rejoins_it() {
    let trial = eval_trial(synth::Subject::Snowman, synth::Preset::Skin, 10019);
    let traj = &trial.trajectories;
    let seg = run(traj, &Params::default()).expect("segments");
    assert_eq!(
        pieces_of(&trial, &seg, "r_forearm"),
        1,
        "{:?}",
        partition(&seg)
    );
    assert_eq!(seg.segments.len(), trial.truth.segments.len());
    let no_rejoin = Params {
        pair_rejoin_ratio: 0.0,
        ..Params::default()
    };
    let regrouped = run(traj, &no_rejoin).expect("segments");
    assert_eq!(
        pieces_of(&trial, &regrouped, "r_forearm"),
        1,
        "{:?}",
        partition(&regrouped)
    );
    let off = Params {
        regroup_ratio: 0.0,
        ..no_rejoin
    };
    let cut = run(traj, &off).expect("segments");
    assert_eq!(
        pieces_of(&trial, &cut, "r_forearm"),
        2,
        "{:?}",
        partition(&cut)
    );
}

/// Skin without noise (eval's 480 frames): the smallest ρ says 1.30 mm, but the head's four
/// markers keep their distances only within 8.96 mm, the left forearm's and foot's beyond
/// 7 mm. A tolerance on the noise (5 × 1.30) leaves each cut in two, one piece of two
/// markers; on the spectral clusters' spread of ρ (11.4 mm) those pieces rejoin. (With the
/// noise's tolerance `join_small` puts the head back together too; it is off there
/// so that the tolerance alone is what is tested.)
#[test]
fn noiseless_skin_sets_the_merge_tolerance_not_the_noise() {
    let trial = eval_trial(synth::Subject::Human, synth::Preset::Skin, 6002);
    let traj = &trial.trajectories;
    let seg = run(traj, &Params::default()).expect("segments");
    assert!(
        seg.tolerance_mm > 8.0 * seg.noise_mm,
        "{} vs noise {}",
        seg.tolerance_mm,
        seg.noise_mm
    );
    let on_noise = Params {
        tolerance_mm: Params::default().tolerance_factor * seg.noise_mm,
        join_small: false,
        ..Params::default()
    };
    let cut = run(traj, &on_noise).expect("segments");
    for segment in ["head", "l_forearm", "l_foot"] {
        assert_eq!(
            pieces_of(&trial, &seg, segment),
            1,
            "{segment}: {:?}",
            partition(&seg)
        );
        assert_eq!(
            pieces_of(&trial, &cut, segment),
            2,
            "{segment}: {:?}",
            partition(&cut)
        );
    }
}

/// The scatter about rigidity runs white from frame to frame under noise alone, smoothly
/// under skin, and in between under both (eval's 480 frames).
#[test]
fn scatter_smoothness_tells_noise_from_skin() {
    let smoothness = |preset| {
        let trial = eval_trial(synth::Subject::Human, preset, 20003);
        run(&trial.trajectories, &Params::default())
            .expect("segments")
            .scatter_smoothness
            .expect("a smoothness")
    };
    let (noise, skin, hard) = (
        smoothness(synth::Preset::Noise),
        smoothness(synth::Preset::Skin),
        smoothness(synth::Preset::Hard),
    );
    assert!(noise.abs() < 0.05, "noise {noise}");
    assert!(skin > 0.9, "skin {skin}");
    assert!((0.2..0.8).contains(&hard), "hard {hard}");
}

/// A hexapod under 1 mm of white noise alone (eval's 480 frames): two of its coxae turn so
/// little that their ρ to the body's markers stays within 5 × the noise level; with the
/// white-noise multiple, 3 ×, every segment comes out exactly, and without it both coxae
/// merge into the body.
#[test]
fn white_noise_keeps_the_tolerance_tight() {
    let trial = eval_trial(synth::Subject::Hexapod, synth::Preset::Noise, 20010);
    // The affinity's own white-noise rule moves one marker here; this test is the tolerance's.
    let raw_rho = Params {
        white_noise_excess: false,
        ..Params::default()
    };
    let seg = run(&trial.trajectories, &raw_rho).expect("segments");
    assert!(is_true_partition(&trial, &seg), "{:?}", partition(&seg));
    let skin_multiple = Params {
        tolerance_factor_white: 0.0,
        ..raw_rho
    };
    let merged = run(&trial.trajectories, &skin_multiple).expect("segments");
    assert_eq!(
        merged.segments.len(),
        true_partition(&trial).len() - 2,
        "{:?}",
        partition(&merged)
    );
}

/// Hexapod-noise-s20039 (white noise, 480 frames): the body's three markers keep 1.43 mm of
/// ρ among themselves and 1.6–2.6 mm to two coxae that turn little; with the noise's share
/// taken out of ρ in quadrature the spectral clusters hold the body apart and every segment
/// comes out exactly, where on the raw ρ they hand the body's markers to those coxae.
#[test]
fn white_noise_is_taken_out_of_the_affinity() {
    let trial = eval_trial(synth::Subject::Hexapod, synth::Preset::Noise, 20039);
    let seg = run(&trial.trajectories, &Params::default()).expect("segments");
    assert!(is_true_partition(&trial, &seg), "{:?}", partition(&seg));
    let raw_rho = Params {
        white_noise_excess: false,
        ..Params::default()
    };
    let mixed = run(&trial.trajectories, &raw_rho).expect("segments");
    assert!(
        !is_true_partition(&trial, &mixed),
        "{:?}",
        partition(&mixed)
    );
}

/// With two or three markers to a segment a cluster's second-nearest ρ may cross a joint,
/// so the tolerance stays on the noise level (skin, 480 frames, markers 2:3).
#[test]
fn few_markers_per_segment_keep_the_tolerance_on_the_noise() {
    let trial = sparse_eval_trial(synth::Subject::Human, synth::Preset::Skin, 6002);
    let seg = run(&trial.trajectories, &Params::default()).expect("segments");
    let on_noise = Params::default().tolerance_factor * seg.noise_mm;
    assert!(
        (seg.tolerance_mm - on_noise).abs() < 1e-9,
        "{} vs {on_noise}",
        seg.tolerance_mm
    );
}

/// Skin under little noise (human-hard-s20005 at 0.3 mm, 480 frames): the spectral
/// clusters come out too fragmented to measure the rigid spread, and a tolerance on the
/// noise level cuts segments apart; the segments it gives measure the spread, and the
/// second pass with it finds the true segments.
#[test]
fn a_second_pass_takes_the_spread_from_the_segments_when_the_clusters_cannot() {
    let config = synth::SynthConfig {
        subject: synth::Subject::Human,
        preset: synth::Preset::Hard,
        seed: 20005,
        frames: 480,
        noise_mm: 0.3,
        ..synth::SynthConfig::default()
    };
    let trial = synth::generate(&config).expect("synthetic trial");
    let truth = true_partition(&trial);
    let one_pass = Params {
        spread_second_pass: false,
        ..Params::default()
    };
    let first = run(&trial.trajectories, &one_pass).expect("segments");
    assert!(
        (first.tolerance_mm - one_pass.tolerance_factor * first.noise_mm).abs() < 1e-9,
        "one pass: tolerance {} on noise {}",
        first.tolerance_mm,
        first.noise_mm
    );
    assert_ne!(partition(&first), truth);
    let second = run(&trial.trajectories, &Params::default()).expect("segments");
    assert!(
        second.tolerance_mm > 1.5 * first.tolerance_mm,
        "{} against {}",
        second.tolerance_mm,
        first.tolerance_mm
    );
    assert_eq!(partition(&second), truth);
}

/// A quadruped's carpus under skin, noise and gaps (eval's 480 frames): the lower foreleg
/// and the paw turn about the wrist by a joint-test score of 4.38, above the 4.0 threshold
/// and below the 4.5 it had, where the two stayed one segment (`truth_evidence quadruped
/// hard 4008`; seed 4002's carpus, 4.07 while every frame was weighed as if it saw all of
/// a part's markers, scores 3.99 weighed by the markers each frame saw).
#[test]
fn a_carpus_scoring_just_above_the_joint_threshold_is_cut() {
    let trial = eval_trial(synth::Subject::Quadruped, synth::Preset::Hard, 4008);
    let traj = &trial.trajectories;
    let together = |seg: &Segmentation| {
        let labels = traj.labels();
        let segment_of = |name: &str| {
            let truth = trial.truth.segments.iter().find(|s| s.name == name);
            let first = truth.and_then(|t| t.markers.first()).expect("true segment");
            seg.segments
                .iter()
                .position(|s| s.markers.iter().any(|&m| &labels[m] == first))
        };
        segment_of("r_fore_lower") == segment_of("r_fore_paw")
    };
    let seg = run(traj, &Params::default()).expect("segments");
    assert!(!together(&seg), "{:?}", partition(&seg));
    assert_eq!(pieces_of(&trial, &seg, "r_fore_paw"), 1);
    let strict = Params {
        joint_split_z: 4.5,
        joint_merge_z: 4.5,
        ..Params::default()
    };
    let merged = run(traj, &strict).expect("segments");
    assert!(together(&merged), "{:?}", partition(&merged));
}

/// The trial's true segments as marker indices, each ascending, in ascending order.
fn true_partition(trial: &synth::Trial) -> Vec<Vec<usize>> {
    let mut parts: Vec<Vec<usize>> = trial
        .truth
        .segments
        .iter()
        .map(|s| true_markers(trial, &s.name))
        .collect();
    parts.sort();
    parts
}

/// Whether the segmentation's segments are exactly the trial's true marker sets.
fn is_true_partition(trial: &synth::Trial, seg: &Segmentation) -> bool {
    let mut found = partition(seg);
    found.sort();
    found == true_partition(trial)
}

/// Hexapod coxae under noise alone (eval's 480 frames), whose hinge the three- or
/// four-marker coxa poses badly: in s10019 body + left front coxa turn by a rotation score of
/// 3.83 but the coxa's centroid swings by a travel score of 5.20 (`joint_travel_z`); in
/// s10003 the body, cut from a leg, takes back two markers from a coxa's cluster, and the
/// body + coxa cluster that leaves is cut only when the joint test runs again after the
/// settling. Both get their true segments; without the travel score s10019 does not, on
/// the tolerance skin needs (`tolerance_factor_white` 0): the white-noise tolerance keeps
/// that coxa apart before the joint test sees it.
#[test]
fn a_coxa_the_rotation_score_misses_is_cut_by_its_travel() {
    let skin_multiple = Params {
        tolerance_factor_white: 0.0,
        ..Params::default()
    };
    for seed in [10003, 10019] {
        let trial = eval_trial(synth::Subject::Hexapod, synth::Preset::Noise, seed);
        for params in [&Params::default(), &skin_multiple] {
            let seg = run(&trial.trajectories, params).expect("segments");
            assert!(
                is_true_partition(&trial, &seg),
                "s{seed}: {:?}",
                partition(&seg)
            );
        }
    }
    let trial = eval_trial(synth::Subject::Hexapod, synth::Preset::Noise, 10019);
    let rotation_only = Params {
        joint_travel_z: 0.0,
        ..skin_multiple
    };
    let seg = run(&trial.trajectories, &rotation_only).expect("segments");
    assert!(!is_true_partition(&trial, &seg));
}

/// Segmentation of a synthetic trial against its truth: (ARI, exact partition); no label
/// swap may be reported where the trial has none.
fn score_on_synth(subject: synth::Subject, preset: synth::Preset, seed: u64) -> (f64, bool) {
    let trial = synth_trial(subject, preset, seed);
    let traj = &trial.trajectories;
    let truth_parts = true_partition(&trial);
    let seg = run(traj, &Params::default()).expect("segments");
    if trial.truth.swaps.is_empty() {
        assert!(
            seg.swaps.is_empty(),
            "{}: swaps {:?}",
            trial.truth.name,
            seg.swaps
        );
    }
    let mut truth = vec![usize::MAX; traj.markers()];
    for (s, part) in truth_parts.iter().enumerate() {
        part.iter().for_each(|&m| truth[m] = s);
    }
    let mut found: Vec<usize> = (0..traj.markers()).map(|m| 1000 + m).collect();
    for s in &seg.segments {
        s.markers.iter().for_each(|&m| found[m] = s.id);
    }
    (ari(&truth, &found), partition(&seg) == truth_parts)
}

const SUBJECTS: [synth::Subject; 6] = [
    synth::Subject::Human,
    synth::Subject::Robotarm,
    synth::Subject::Quadruped,
    synth::Subject::Snowman,
    synth::Subject::Hexapod,
    synth::Subject::Random,
];

#[test]
fn clean_synthetic_subjects_are_segmented_exactly() {
    for subject in SUBJECTS {
        for seed in [31, 32] {
            let (score, exact) = score_on_synth(subject, synth::Preset::Clean, seed);
            assert!(exact, "{subject:?} seed {seed}: ARI {score:.3}");
        }
    }
}

#[test]
fn hard_synthetic_subjects_are_segmented_closely() {
    // Noise + skin artefact + gaps over 240 frames (2 s). Measured with seeds 41–42: mean
    // ARI 0.85; the hexapod scores 0.37–0.66 because in 2 s its short leg segments move
    // less relative to each other (cross ρ 3–7 mm) than skin moves markers on one segment
    // (within ρ up to 9 mm), which no ρ-based grouping can separate; at 600 frames ≈ 0.93.
    let mut scores = Vec::new();
    for subject in SUBJECTS {
        for seed in [41, 42] {
            let (score, _) = score_on_synth(subject, synth::Preset::Hard, seed);
            if subject != synth::Subject::Hexapod {
                assert!(score > 0.8, "{subject:?} seed {seed}: ARI {score:.3}");
            }
            scores.push(score);
        }
    }
    let mean = scores.iter().sum::<f64>() / scores.len() as f64;
    assert!(mean > 0.8, "mean ARI {mean:.3}: {scores:?}");
}

/// Subjects whose swapped markers can leave homes of two.
const SWAP_SUBJECTS: [synth::Subject; 4] = [
    synth::Subject::Human,
    synth::Subject::Quadruped,
    synth::Subject::Snowman,
    synth::Subject::Robotarm,
];

/// A synthetic trial with one label swap, segmented: its name, the swap's two marker
/// indices (ascending) and frames `[first, last]` from the truth, and what was found.
fn segment_swap_trial(
    subject: synth::Subject,
    preset: synth::Preset,
    seed: u64,
) -> (String, [usize; 2], [usize; 2], Vec<LabelSwap>) {
    let trial = synth_trial(subject, preset, seed);
    let traj = &trial.trajectories;
    let seg = run(traj, &Params::default()).expect("segments");
    let index = |label: &str| traj.labels().iter().position(|l| l == label).unwrap();
    let [truth] = &trial.truth.swaps[..] else {
        panic!("{}: one swap expected", trial.truth.name)
    };
    let mut pair = [index(&truth.labels[0]), index(&truth.labels[1])];
    pair.sort_unstable();
    let window = [truth.first_frame, truth.first_frame + truth.frames - 1];
    let mut found = seg.swaps;
    for swap in &mut found {
        swap.markers.sort_unstable();
    }
    (trial.truth.name, pair, window, found)
}

/// Every label swap of the `swap` preset is found with its exact frames and undone: the
/// segments are the truth's.
#[test]
fn label_swaps_are_found_with_their_frames() {
    for subject in SWAP_SUBJECTS {
        for seed in [51, 52] {
            let (name, markers, window, found) =
                segment_swap_trial(subject, synth::Preset::Swap, seed);
            let expected = vec![LabelSwap {
                markers,
                frames: vec![window],
            }];
            assert_eq!(found, expected, "{name}");
            let (score, exact) = score_on_synth(subject, synth::Preset::Swap, seed);
            assert!(exact, "{name}: ARI {score:.3}");
        }
    }
}

/// With skin, noise and gaps as well (`messy`), a swap reported is the truth's pair within
/// the truth's frames (never a wrong pair, never frames outside), and most are found.
#[test]
fn label_swaps_under_skin_noise_and_gaps_are_never_wrong() {
    let (mut trials, mut found_any) = (0, 0);
    for subject in SWAP_SUBJECTS {
        for seed in [51, 52] {
            let (name, pair, window, found) =
                segment_swap_trial(subject, synth::Preset::Messy, seed);
            trials += 1;
            for swap in &found {
                assert_eq!(swap.markers, pair, "{name}: {found:?}");
                for w in &swap.frames {
                    assert!(
                        w[0] >= window[0] && w[1] <= window[1],
                        "{name}: {w:?} outside {window:?}"
                    );
                }
                found_any += 1;
            }
        }
    }
    assert!(
        2 * found_any >= trials,
        "{found_any} of {trials} swaps found"
    );
}

/// An unlabeled capture (each marker cut at its gaps into tracks, shuffled as `cargo xtask
/// eval --unlabeled` does, the reader's stitch joining what it can) whose label exchange
/// begins or ends where a track ends or starts, or shows no jump: undone, the segments are
/// the truth's, one for each true segment (each named by the marker most of its tracks
/// were cut from). robotarm-messy-s20006: the exchange's entry where link 1's track ends,
/// its exit where the base marker's next track starts; snake-messy-s20009: an exchange to
/// the capture's end with a track that starts 30 frames before it; snowman-messy-s20015:
/// an exchange across two of M029's tracks, undone in two rounds; snowman-messy-s20020:
/// an exchange whose steps are fast but no jumps.
#[test]
fn label_exchanges_in_unlabeled_captures_are_undone() {
    for (subject, seed) in [
        (synth::Subject::Robotarm, 20006),
        (synth::Subject::Snake, 20009),
        (synth::Subject::Snowman, 20015),
        (synth::Subject::Snowman, 20020),
    ] {
        let trial = eval_trial(subject, synth::Preset::Messy, seed);
        let (cut, marker_of_piece) =
            synth::unlabeled(&trial.trajectories, seed, |i, _, _| i.to_string());
        let read = mocap_io::stitch(mocap_io::Capture {
            format: mocap_io::Format::C3d,
            trajectories: cut,
            info: mocap_io::CaptureInfo::default(),
        });
        let traj = &read.trajectories;
        let seg = run(traj, &Params::default()).expect("segments");
        assert!(!seg.swaps.is_empty(), "{}: no swap", trial.truth.name);
        // A track is its first piece's marker; a true segment, the index of its markers'.
        let true_segment = |track: usize| {
            let piece: usize = traj.labels()[track].parse().expect("a piece's index");
            let label = &trial.trajectories.labels()[marker_of_piece[piece]];
            trial
                .truth
                .segments
                .iter()
                .position(|s| s.markers.contains(label))
                .expect("every marker is on a true segment")
        };
        let mut named: Vec<usize> = seg
            .segments
            .iter()
            .map(|s| {
                let mut votes = vec![0usize; trial.truth.segments.len()];
                s.markers.iter().for_each(|&m| votes[true_segment(m)] += 1);
                (0..votes.len())
                    .max_by_key(|&t| (votes[t], usize::MAX - t))
                    .unwrap_or(0)
            })
            .collect();
        named.sort_unstable();
        let every: Vec<usize> = (0..trial.truth.segments.len()).collect();
        assert_eq!(named, every, "{}: {:?}", trial.truth.name, seg.swaps);
    }
}

/// An unlabeled capture at two or three markers per segment (snake-hard-s20011 as `cargo
/// xtask eval --unlabeled --markers 2:3` makes it, the reader's stitch joining what it
/// can): link3's marker M016 comes back for its last 83 frames as a track of its own, seen
/// while the chain from the base to link4 barely moved, so its distances to base marker
/// M017 and to link4 keep as steady as to link3's M007, and spectral clustering puts it
/// with M017 and a link4 marker. Taken out of that cluster before the rigidity check
/// (`brief_track_fraction`), it no longer keeps M017 from the base: the base's three
/// markers are one segment, and link3 is M007 with both of M016's tracks. Left in, M017
/// and the late track stay one cluster.
#[test]
fn a_brief_track_leaves_its_spectral_cluster_before_the_rigidity_check() {
    let trial = sparse_eval_trial(synth::Subject::Snake, synth::Preset::Hard, 20011);
    let (cut, marker_of_piece) =
        synth::unlabeled(&trial.trajectories, 20011, |i, _, _| i.to_string());
    let read = mocap_io::stitch(mocap_io::Capture {
        format: mocap_io::Format::C3d,
        trajectories: cut,
        info: mocap_io::CaptureInfo::default(),
    });
    let traj = &read.trajectories;
    let label_of = |track: usize| -> &str {
        let piece: usize = traj.labels()[track].parse().expect("a piece's index");
        &trial.trajectories.labels()[marker_of_piece[piece]]
    };
    // The labels of the tracks in each segment, sorted, a marker once per track.
    let groups = |seg: &Segmentation| -> Vec<Vec<&str>> {
        seg.segments
            .iter()
            .map(|s| {
                let mut g: Vec<&str> = s.markers.iter().map(|&m| label_of(m)).collect();
                g.sort_unstable();
                g
            })
            .collect()
    };
    let seg = run(traj, &Params::default()).expect("segments");
    let found = groups(&seg);
    let base = ["M001", "M010", "M017"];
    assert!(found.iter().any(|g| g == &base), "{found:?}");
    let link3 = ["M007", "M016", "M016"];
    assert!(found.iter().any(|g| g == &link3), "{found:?}");
    let left_in = Params {
        brief_track_fraction: 0.0,
        ..Params::default()
    };
    let bridged = groups(&run(traj, &left_in).expect("segments"));
    assert!(
        bridged
            .iter()
            .any(|g| g.contains(&"M017") && g.contains(&"M016")),
        "{bridged:?}"
    );
}

/// Brief tracks leave their clusters as lone markers with no spectral cluster, the rest
/// keep theirs, and a cluster left empty is gone; the median counts each track's frames.
#[test]
fn brief_tracks_leave_their_clusters_alone_against_the_median_track() {
    // Four markers over 6 frames, seen in 6, 5, 2 and 1 frames.
    let seen = [6, 5, 2, 1];
    let labels: Vec<String> = ["A", "B", "C", "D"].iter().map(|s| s.to_string()).collect();
    let positions: Vec<[f64; 3]> = (0..6)
        .flat_map(|f| {
            seen.iter()
                .enumerate()
                .map(move |(m, &n)| if f < n { [m as f64, 0.0, 0.0] } else { MISSING })
        })
        .collect();
    let traj = Trajectories::new(labels, 100.0, 1, 6, positions).unwrap();
    let stats = crate::pairstats::pair_stats(&traj);
    assert_eq!(crate::median_visible(&stats, &[0, 1, 2, 3]), 3.5);
    assert_eq!(crate::median_visible(&stats, &[0, 1, 2]), 5.0);
    assert_eq!(crate::median_visible(&stats, &[]), 0.0);
    let mut clusters = vec![vec![0, 2], vec![1], vec![3]];
    let mut spectral_of = vec![Some(0), Some(1), Some(0), Some(2)];
    crate::take_out_brief_tracks(&mut clusters, &mut spectral_of, |m| stats.visible[m] < 3);
    assert_eq!(clusters, vec![vec![0], vec![1], vec![2], vec![3]]);
    assert_eq!(spectral_of, vec![Some(0), Some(1), None, None]);
}

/// Undoing a swap exchanges the two trajectories back in its frames only.
#[test]
fn untangle_exchanges_the_swapped_frames_back() {
    let labels: Vec<String> = ["A", "B", "C"].iter().map(|s| s.to_string()).collect();
    let positions: Vec<[f64; 3]> = (0..4)
        .flat_map(|f| (0..3).map(move |m| [f as f64, m as f64, 0.0]))
        .collect();
    let traj = Trajectories::new(labels, 100.0, 1, 4, positions).unwrap();
    let swaps = [LabelSwap {
        markers: [0, 2],
        frames: vec![[1, 2]],
    }];
    let fixed = crate::untangle(&traj, &swaps);
    for f in 0..4 {
        let swapped = (1..=2).contains(&f);
        let (a, c) = if swapped { (2.0, 0.0) } else { (0.0, 2.0) };
        assert_eq!(fixed.get(f, 0), Some([f as f64, a, 0.0]));
        assert_eq!(fixed.get(f, 1), Some([f as f64, 1.0, 0.0]));
        assert_eq!(fixed.get(f, 2), Some([f as f64, c, 0.0]));
    }
    // Markers and frames the capture does not have are left alone, never a panic.
    let beyond = Segmentation {
        segments: Vec::new(),
        unassigned: Vec::new(),
        markers: Vec::new(),
        noise_mm: 0.0,
        tolerance_mm: 0.0,
        eigenvalues: Vec::new(),
        scatter_smoothness: None,
        eigengap_segments: 0,
        swaps: vec![LabelSwap {
            markers: [0, 7],
            frames: vec![[0, 3]],
        }],
        glitches: vec![
            crate::Glitch {
                marker: 1,
                frames: vec![[3, usize::MAX]],
            },
            crate::Glitch {
                marker: 9,
                frames: vec![[0, 3]],
            },
        ],
        near_joints: Vec::new(),
        labels: Vec::new(),
        named_segments: Vec::new(),
        pieces: Vec::new(),
        stationary_segment: None,
        bodies: Vec::new(),
    };
    let repaired = beyond.repaired(&traj);
    for f in 0..4 {
        assert_eq!(repaired.get(f, 0), traj.get(f, 0));
        assert_eq!(repaired.get(f, 1).is_none(), f == 3, "frame {f}");
    }
    let empty = Trajectories::new(traj.labels().to_vec(), 100.0, 1, 0, Vec::new()).unwrap();
    assert_eq!(beyond.repaired(&empty).frames(), 0);
}

/// A CMU capture segmented with the defaults; `None` (the test says it skipped) without
/// the shared data.
struct SegmentedCmu {
    traj: Trajectories,
    seg: Segmentation,
}

impl SegmentedCmu {
    fn load(test: &str) -> Option<Self> {
        Self::load_trial(test, "02_01")
    }

    fn load_trial(test: &str, trial: &str) -> Option<Self> {
        let dir = mocap_io::testdata::shared_data_dir(test)?;
        let path = dir.join(format!("c3d/cmu/{trial}.c3d"));
        let capture = mocap_io::read_capture(&path, &Default::default())
            .unwrap_or_else(|e| panic!("CMU {trial} reads: {e}"));
        let seg = run(&capture.trajectories, &Params::default()).expect("segments");
        Some(Self {
            traj: capture.trajectories,
            seg,
        })
    }

    /// The segment of the marker labelled `name` (labels carry the subject prefix,
    /// "TakeoMonday:LFHD").
    fn segment_of(&self, name: &str) -> Option<usize> {
        let m = self
            .traj
            .labels()
            .iter()
            .position(|l| l.rsplit(':').next() == Some(name))
            .unwrap_or_else(|| panic!("label {name} in the capture"));
        self.seg.markers[m].segment
    }

    /// Thighs are THI + KNE and shanks SHN + ANK, each its own two-marker segment, on both
    /// sides (the CMU marker set gives those segments two markers each). The malleolus
    /// (ANK) sits near the ankle axis, rigid with shank and foot alike; it goes to the
    /// shank, whose only other marker would be alone, while the foot keeps 3.
    fn assert_two_marker_thighs_and_shanks(&self) {
        let parts: [(&str, &str, &[&str]); 2] =
            [("THI", "KNE", &["SHN", "FWT"]), ("SHN", "ANK", &["HEE"])];
        for side in ["L", "R"] {
            for (first, mate, elsewhere) in parts {
                let segment = self.segment_of(&format!("{side}{first}"));
                assert!(segment.is_some(), "{side}{first} unassigned");
                assert_eq!(
                    segment,
                    self.segment_of(&format!("{side}{mate}")),
                    "{side}{first} apart from {side}{mate}"
                );
                for other in elsewhere {
                    assert_ne!(
                        segment,
                        self.segment_of(&format!("{side}{other}")),
                        "{side}{first} with {side}{other}"
                    );
                }
                let size = self.size_of(segment);
                assert_eq!(size, Some(2), "{side}{first} + {side}{mate} only");
            }
        }
    }

    /// How many markers segment `id` has.
    fn size_of(&self, id: Option<usize>) -> Option<usize> {
        self.seg
            .segments
            .iter()
            .find(|s| Some(s.id) == id)
            .map(|s| s.markers.len())
    }
}

#[test]
fn cmu_02_01_groups_the_body_parts_we_are_sure_of() {
    let Some(cmu) = SegmentedCmu::load("segment cmu_02_01") else {
        return;
    };
    let segment_of = |name: &str| cmu.segment_of(name);
    let same = |names: &[&str]| {
        let first = segment_of(names[0]);
        assert!(first.is_some(), "{} unassigned", names[0]);
        for n in names {
            assert_eq!(segment_of(n), first, "{n} apart from {}", names[0]);
        }
    };
    same(&["LFHD", "RFHD", "LBHD", "RBHD"]);
    same(&["LFWT", "RFWT", "LBWT", "RBWT"]);
    same(&["LHEE", "LTOE", "LMT5"]);
    same(&["RHEE", "RTOE", "RMT5"]);
    same(&["RFRM", "RWRA", "RWRB"]);
    same(&["LFRM", "LWRA", "LWRB"]);
    assert_ne!(segment_of("LHEE"), segment_of("LFHD"));
    assert_ne!(segment_of("LHEE"), segment_of("RHEE"));
    assert_ne!(segment_of("LFHD"), segment_of("LFWT"));
    assert_ne!(segment_of("LFRM"), segment_of("RFRM"));
}

#[test]
fn cmu_02_01_keeps_two_marker_thighs_shanks_and_upper_arm() {
    // Thigh (LTHI, LKNE) and upper arm (LUPA, LELB) carry two markers each; local scaling
    // with k = 2 looked past the one mate and merged them into shank or forearm. The
    // rigidity split by scaled complete linkage keeps them (measured: both thighs and the
    // left upper arm come out as their own two-marker segments).
    let Some(cmu) = SegmentedCmu::load("segment cmu_02_01 two-marker") else {
        return;
    };
    let segment_of = |name: &str| cmu.segment_of(name);
    cmu.assert_two_marker_thighs_and_shanks();
    assert!(
        cmu.seg.unassigned.is_empty(),
        "unassigned: {:?}",
        cmu.seg.unassigned
    );
    let upa = segment_of("LUPA");
    assert!(upa.is_some(), "LUPA unassigned");
    assert_eq!(upa, segment_of("LELB"));
    assert_ne!(upa, segment_of("LFHD"), "upper arm with head");
    assert_ne!(upa, segment_of("LFRM"), "upper arm with forearm");
    assert_ne!(upa, segment_of("LSHO"), "upper arm with torso");
}

/// CMU 49_04, the same marker set on another subject (its 289 bone-model points are not
/// read, see mocap-io): the shin marker keeps ρ 4.0 mm to the knee marker but 29.2 mm to
/// the thigh marker, and must not ride the knee marker into the thigh.
#[test]
fn cmu_49_04_keeps_the_shin_marker_out_of_the_thigh() {
    let Some(cmu) = SegmentedCmu::load_trial("segment cmu_49_04", "49_04") else {
        return;
    };
    assert_eq!(cmu.traj.markers(), 41);
    cmu.assert_two_marker_thighs_and_shanks();
    let segment_of = |name: &str| cmu.segment_of(name);
    for side in ["L", "R"] {
        let foot: Vec<_> = ["HEE", "MT5", "TOE"]
            .iter()
            .map(|m| segment_of(&format!("{side}{m}")))
            .collect();
        assert!(foot[0].is_some(), "{side}HEE unassigned");
        assert!(foot.iter().all(|s| *s == foot[0]), "{side} foot split");
    }
}

/// The capture's indices (ascending) of the markers of the true segment called `name`.
fn true_markers(trial: &synth::Trial, name: &str) -> Vec<usize> {
    let labels = trial.trajectories.labels();
    let segment = trial
        .truth
        .segments
        .iter()
        .find(|s| s.name == name)
        .expect("a true segment of that name");
    let mut markers: Vec<usize> = segment
        .markers
        .iter()
        .map(|l| {
            labels
                .iter()
                .position(|x| x == l)
                .expect("truth label in capture")
        })
        .collect();
    markers.sort_unstable();
    markers
}

/// A clean trial of `subject` with one to three markers a segment (a sparse marker set),
/// 480 frames.
fn sparse_trial(subject: synth::Subject, seed: u64) -> synth::Trial {
    let config = synth::SynthConfig {
        subject,
        preset: synth::Preset::Clean,
        seed,
        frames: 480,
        markers_per_segment: (1, 3),
        ..synth::SynthConfig::default()
    };
    synth::generate(&config).expect("synthetic trial")
}

/// A sparse marker set (one to three markers a segment, clean): how many found pairs mix
/// two true segments, and of the true one-marker segments hanging from a true neighbour
/// found whole with ≥ 3 markers, how many are found as one-marker segments.
fn sparse_set_outcome(seed: u64, params: &Params) -> (usize, usize, usize) {
    let trial = sparse_trial(synth::Subject::Human, seed);
    let seg = run(&trial.trajectories, params).expect("segments");
    // Each true segment's sorted marker indices, in the truth's order.
    let labels = trial.trajectories.labels();
    let truth: Vec<Vec<usize>> = trial
        .truth
        .segments
        .iter()
        .map(|s| {
            let mut v: Vec<usize> = s
                .markers
                .iter()
                .filter_map(|l| labels.iter().position(|x| x == l))
                .collect();
            v.sort_unstable();
            v
        })
        .collect();
    let segment_of = |m: usize| truth.iter().position(|s| s.contains(&m));
    let found = partition(&seg);
    let mixed_pairs = found
        .iter()
        .filter(|c| c.len() == 2 && segment_of(c[0]) != segment_of(c[1]))
        .count();
    let (mut hanging, mut kept) = (0, 0);
    for j in &trial.truth.joints {
        for (lone, body) in [
            (j.child_segment, j.parent_segment),
            (j.parent_segment, j.child_segment),
        ] {
            if truth[lone].len() == 1 && truth[body].len() >= 3 && found.contains(&truth[body]) {
                hanging += 1;
                kept += usize::from(found.contains(&truth[lone]));
            }
        }
    }
    (mixed_pairs, hanging, kept)
}

/// One marker on the shank and one on the foot are each other's nearest, and scaled
/// linkage pairs them however much their distance changes; a marker stays in a group only if
/// it is rigid with some marker of it (`loose_marker_factor`), and a marker alone on its segment is one when it swings
/// about a point of its neighbour (`singleton_swing_factor`). Human, clean, one to three
/// markers a segment, seeds 4001–4004: found pairs that mix two true segments 12 → 2 (both
/// with ρ within 2 tolerances: markers near a joint); lone markers hanging from a
/// neighbour found whole (12 without these checks, 14 with: loose markers no longer spoil
/// the neighbour) kept as one-marker segments 0 → 12.
#[test]
fn a_sparse_marker_set_keeps_no_loose_pair_and_its_hanging_markers() {
    let off = Params {
        loose_marker_factor: 0.0,
        singleton_swing_factor: 0.0,
        ..Params::default()
    };
    let total = |params: &Params| {
        (4001..=4004)
            .map(|seed| sparse_set_outcome(seed, params))
            .fold((0, 0, 0), |t, o| (t.0 + o.0, t.1 + o.1, t.2 + o.2))
    };
    let (on, off) = (total(&Params::default()), total(&off));
    assert!(on.0 <= 2 && off.0 >= 10, "mixed pairs: {on:?} vs {off:?}");
    assert!(
        on.1 >= off.1 && on.1 >= 10,
        "hanging markers: {on:?} vs {off:?}"
    );
    assert!(
        on.2 >= on.1 * 3 / 4 && off.2 == 0,
        "kept: {on:?} vs {off:?}"
    );
}

/// A sparse robot arm (clean, one to three markers a segment, seed 4001) whose first link's
/// three markers came out as a pair and a lone marker that kept every distance to the pair:
/// the lone marker joins it (`loose_marker_factor`'s last step), and the link is whole.
#[test]
fn a_lone_marker_rigid_with_a_pair_joins_it() {
    let trial = sparse_trial(synth::Subject::Robotarm, 4001);
    let link1 = true_markers(&trial, "link1");
    assert_eq!(link1.len(), 3);
    let whole = |params: &Params| {
        let seg = run(&trial.trajectories, params).expect("segments");
        partition(&seg).contains(&link1)
    };
    let off = Params {
        loose_marker_factor: 0.0,
        ..Params::default()
    };
    assert!(whole(&Params::default()));
    assert!(!whole(&off));
}

/// A sparse snowman (clean, one to three markers a segment, seed 4001): the right forearm's
/// one marker hangs from a two-marker upper arm, which has no pose to test a swing in; it
/// moves against every group, and is a one-marker segment (`singleton_next_to_small`).
#[test]
fn a_lone_marker_next_to_a_pair_is_a_segment() {
    let trial = sparse_trial(synth::Subject::Snowman, 4001);
    let forearm = true_markers(&trial, "r_forearm");
    assert_eq!(forearm.len(), 1);
    let alone = |params: &Params| {
        let seg = run(&trial.trajectories, params).expect("segments");
        partition(&seg).contains(&forearm)
    };
    let off = Params {
        singleton_next_to_small: false,
        ..Params::default()
    };
    assert!(alone(&Params::default()));
    assert!(!alone(&off));
}

/// A sparse human (clean, one to three markers a segment, seed 6002) whose spectral
/// clusters mix segments: their second-nearest ρ made a 21.5 mm tolerance on noiseless
/// data and merged thigh with pelvis; bounded by the noise level (`spread_max_noise_factor`)
/// the tolerance stays at its floor.
#[test]
fn mixed_clusters_do_not_inflate_the_tolerance() {
    let trial = sparse_trial(synth::Subject::Human, 6002);
    let seg = run(&trial.trajectories, &Params::default()).expect("segments");
    assert!(
        seg.tolerance_mm <= Params::default().tolerance_min_mm + 1e-9,
        "{}",
        seg.tolerance_mm
    );
    let unbounded = Params {
        spread_max_noise_factor: 0.0,
        ..Params::default()
    };
    let seg = run(&trial.trajectories, &unbounded).expect("segments");
    assert!(seg.tolerance_mm > 10.0, "{}", seg.tolerance_mm);
}

/// ρ among eight markers of CMU 49_04 (mm, numpy over the frames each pair is seen): 0 =
/// LUPA, which the rigidity check's split left alone; 1–4 = LELB, LFRM, LWRA, LWRB (its
/// forearm group); 5–7 = CLAV, C7, LSHO.
fn orphaned_upper_arm() -> pairstats::PairStats {
    let rho = [
        [0.0, 4.6, 18.5, 55.0, 34.5, 17.6, 24.9, 15.0],
        [4.6, 0.0, 2.5, 4.2, 3.5, 27.5, 29.5, 17.6],
        [18.5, 2.5, 0.0, 3.5, 2.7, 54.7, 26.8, 29.3],
        [55.0, 4.2, 3.5, 0.0, 1.4, 133.1, 86.3, 84.8],
        [34.5, 3.5, 2.7, 1.4, 0.0, 92.7, 51.6, 55.8],
        [17.6, 27.5, 54.7, 133.1, 92.7, 0.0, 4.5, 11.3],
        [24.9, 29.5, 26.8, 86.3, 51.6, 4.5, 0.0, 17.3],
        [15.0, 17.6, 29.3, 84.8, 55.8, 11.3, 17.3, 0.0],
    ];
    let pairs: Vec<(usize, usize, f64)> = (0..8)
        .flat_map(|i| (i + 1..8).map(move |j| (i, j, rho[i][j])))
        .collect();
    rigidity::tests::stats(8, &pairs)
}

#[test]
fn a_marker_orphaned_at_a_joint_waits_instead_of_joining_a_loose_group() {
    let stats = orphaned_upper_arm();
    let nodes: Vec<usize> = (0..8).collect();
    let params = Params::default();
    let split = || vec![vec![1, 2, 3, 4], vec![0], vec![5, 6, 7]];
    // 49_04's noise 3.31 mm, spread 4.4 mm, tolerance 22 mm: LUPA's RMS ρ to the upper
    // thorax (19.6 mm) passes the tolerance, but LELB holds it three times steadier.
    let mut groups = split();
    rejoin_orphans(&mut groups, &stats, &nodes, 3.31, 4.4, 22.0, &params);
    assert!(groups.contains(&vec![0]), "{groups:?}");
    // Were skin to leave 8 mm of ρ on rigid bodies, 15 mm would be within twice that: it
    // joins, as a sliding marker does.
    let mut groups = split();
    rejoin_orphans(&mut groups, &stats, &nodes, 3.31, 8.0, 22.0, &params);
    assert!(
        groups.iter().any(|g| g.contains(&0) && g.contains(&7)),
        "{groups:?}"
    );
}

/// The pair route runs on a marker set whose clusters are often pairs, not on one where a
/// lone pair is a piece: 3 of 12 clusters of two is sparse at the default share, 1 of 12
/// is not, and shares of 0 and above 1 mean always and never.
#[test]
fn the_pair_route_runs_on_sparse_marker_sets() {
    let clusters = |pairs: usize| -> Vec<Vec<usize>> {
        let mut c: Vec<Vec<usize>> = (0..12)
            .map(|k| {
                let size = if k < pairs { 2 } else { 4 };
                (0..size).map(|m| 10 * k + m).collect()
            })
            .collect();
        c.push(vec![200]);
        c
    };
    let share = Params::default().joint_pair_share;
    assert!(sparse_marker_set(&clusters(3), share));
    assert!(!sparse_marker_set(&clusters(1), share));
    assert!(sparse_marker_set(&clusters(0), 0.0));
    assert!(!sparse_marker_set(&clusters(12), 1.5));
}

/// A snake with two or three markers per link (eval's 480 frames, `--markers 2:3`): one
/// of its two-marker links ends merged with a neighbour of three, which the joint test's
/// parts of ≥ 3 cannot cut; the pair route cuts it at the joint and every link is found,
/// where without the route the snake has a link too few.
#[test]
fn a_two_marker_link_merged_with_its_neighbour_is_cut_by_the_pair_route() {
    let trial = sparse_eval_trial(synth::Subject::Snake, synth::Preset::Hard, 30048);
    let traj = &trial.trajectories;
    let mut truth = trial.true_segment_markers();
    truth.iter_mut().for_each(|s| s.sort_unstable());
    truth.sort();
    let seg = run(traj, &Params::default()).expect("segments");
    assert_eq!(partition(&seg), truth);
    let never = Params {
        joint_pair_share: 2.0,
        ..Params::default()
    };
    let merged = run(traj, &never).expect("segments");
    assert_eq!(
        merged.segments.len() + 1,
        truth.len(),
        "{:?}",
        partition(&merged)
    );
}

/// Hexapod coxae skin hides (hard preset, eval's 480 frames: the grouping merges every
/// coxa into the body or a femur), named by the person who put the markers on
/// (`Params::groups`): each named coxa is a segment, and the body and femurs they were
/// cut from stand as their true segments; naming nothing changes nothing.
#[test]
fn named_coxae_are_segments_and_the_rest_is_grouped_as_found() {
    let trial = eval_trial(synth::Subject::Hexapod, synth::Preset::Hard, 20001);
    let traj = &trial.trajectories;
    let automatic = run(traj, &Params::default()).expect("segments");
    assert!(
        !is_true_partition(&trial, &automatic),
        "{:?}",
        partition(&automatic)
    );
    let coxae: Vec<Vec<String>> = trial
        .truth
        .segments
        .iter()
        .filter(|s| s.name.ends_with("_coxa"))
        .map(|s| s.markers.clone())
        .collect();
    assert_eq!(coxae.len(), 6);
    let named = Params {
        groups: coxae,
        ..Params::default()
    };
    let seg = run(traj, &named).expect("segments");
    // One marker of a femur the grouping leaves out either way (it slides); every segment
    // holds one true segment's markers, and there are as many as true segments.
    let truth = true_partition(&trial);
    let found = partition(&seg);
    assert_eq!(found.len(), truth.len(), "{found:?}");
    for part in &found {
        assert!(
            truth.iter().any(|t| part.iter().all(|m| t.contains(m))),
            "{part:?} mixes true segments: {found:?}"
        );
    }
    for coxa in named.groups.iter().map(|g| {
        let mut markers: Vec<usize> = g
            .iter()
            .map(|l| traj.labels().iter().position(|x| x == l).expect("label"))
            .collect();
        markers.sort_unstable();
        markers
    }) {
        assert!(
            found.contains(&coxa),
            "{coxa:?} is not a segment: {found:?}"
        );
    }
    let none = Params {
        groups: Vec::new(),
        ..Params::default()
    };
    assert_eq!(run(traj, &none).expect("segments"), automatic);
}

/// A group naming a label the capture lacks stops the stage with the group and the label.
#[test]
fn a_group_naming_no_marker_is_an_error() {
    let trial = synth_trial(synth::Subject::Snowman, synth::Preset::Clean, 1);
    let params = Params {
        groups: vec![vec!["M000".into(), "LKNE".into()]],
        ..Params::default()
    };
    let error = run(&trial.trajectories, &params).unwrap_err().to_string();
    assert!(
        error.contains("segment.groups, group 1") && error.contains("\"LKNE\""),
        "{error}"
    );
}

/// Two pieces of one marker at a joint (an unlabeled capture's, each never seen with its
/// other piece, whose three-marker segment cannot be posed in their frames) go to the
/// bodies they keep their distances to, alone or paired up; a pair of whole markers stays
/// as it was, though one of them keeps its distances to a body (that is for the holds and
/// the rigidity check to say, not this rule).
#[test]
fn pieces_of_markers_go_to_the_bodies_they_are_rigid_with() {
    use crate::testscene::{CHILD, PARENT, cut_at_gap, hinged_capture};
    let whole = hinged_capture(&PARENT[..3], &CHILD, 200, 20.0, 0.2);
    // Parent marker 2's later piece is 7, child marker 6's is 8.
    let cut = cut_at_gap(&cut_at_gap(&whole, 2, 90..100), 6, 110..120);
    let stats = pairstats::pair_stats(&cut);
    let tidy = |clusters: &mut Vec<Vec<usize>>| {
        clusters.retain(|c| !c.is_empty());
        clusters.iter_mut().for_each(|c| c.sort_unstable());
    };
    let mut lone = vec![vec![0, 1, 2], vec![3, 4, 5, 6], vec![7]];
    join_rigid_lone_markers(&mut lone, &stats, 2.0, 10);
    tidy(&mut lone);
    assert_eq!(lone, vec![vec![0, 1, 2, 7], vec![3, 4, 5, 6]]);
    let mut paired = vec![vec![0, 1, 2], vec![3, 4, 5, 6], vec![7, 8]];
    join_rigid_lone_markers(&mut paired, &stats, 2.0, 10);
    tidy(&mut paired);
    assert_eq!(paired, vec![vec![0, 1, 2, 7], vec![3, 4, 5, 6, 8]]);
    let whole = hinged_capture(&PARENT, &CHILD, 200, 20.0, 0.2);
    let stats = pairstats::pair_stats(&whole);
    let pairs = vec![vec![0, 1, 2], vec![4, 5, 6], vec![3, 7]];
    let mut markers = pairs.clone();
    join_rigid_lone_markers(&mut markers, &stats, 2.0, 10);
    assert_eq!(markers, pairs);
}

/// An unlabeled capture's pieces of one marker, cut past the reader's stitch (1.8 and
/// 1.3 s), are one marker to segmentation: each piece goes to its marker's segment, is
/// listed in `pieces`, keeps its own diagnostics and reaches later stages joined to its
/// marker's first track; with `join_pieces` off none is listed.
#[test]
fn pieces_of_a_marker_are_segmented_as_one() {
    use crate::testscene::{CHILD, PARENT, cut_at_gap, skin_hinged_capture};
    for seed in 1..=3 {
        let whole = skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, seed);
        let cut = cut_at_gap(&cut_at_gap(&whole, 1, 120..300), 6, 200..330);
        let seg = run(&cut, &Params::default()).expect("segments");
        let groups: Vec<Vec<usize>> = seg.segments.iter().map(|s| s.markers.clone()).collect();
        assert_eq!(
            groups,
            vec![vec![0, 1, 2, 3, 8], vec![4, 5, 6, 7, 9]],
            "seed {seed}"
        );
        assert_eq!(seg.pieces, vec![vec![1, 8], vec![6, 9]], "seed {seed}");
        assert!(
            seg.unassigned.is_empty(),
            "seed {seed}: {:?}",
            seg.unassigned
        );
        let seen = |m: usize| seg.markers[m].visible_frames;
        assert_eq!(
            [seen(1), seen(8), seen(6), seen(9)],
            [120, 100, 200, 70],
            "seed {seed}"
        );
        assert_eq!(seg.markers[8].segment, Some(0), "seed {seed}");
        assert!(
            seg.markers[8].rigidity_residual_mm.is_finite(),
            "seed {seed}"
        );
        // Later stages read each marker's pieces as its first track.
        let read = seg.repaired(&cut);
        for f in 0..cut.frames() {
            assert_eq!(read.get(f, 1), cut.get(f, 1).or(cut.get(f, 8)), "frame {f}");
            assert_eq!(read.get(f, 8), None, "frame {f}");
        }
        let off = Params {
            join_pieces: false,
            ..Params::default()
        };
        assert!(
            run(&cut, &off).expect("segments").pieces.is_empty(),
            "seed {seed}"
        );
    }
}

/// Three props that move on their own (`synth::with_props`) beside hard synthetic
/// subjects: each prop is a body and a segment of its own, and the subject's segments are
/// those it has alone. Before bodies were segmented apart (`body_gap_ratio` 0) the props
/// regrouped these subjects: hexapod 5 of seeds 20001–20006, quadruped 20001 and 20005
/// (`cargo run --release -p segment --example props_segment all hard 20001..20020`: 24 of
/// 140 subjects, none with bodies apart).
#[test]
fn props_that_move_on_their_own_leave_the_subject_s_segments_as_they_are() {
    use synth::Subject::{Hexapod, Quadruped};
    for (subject, seed) in [(Hexapod, 20001), (Quadruped, 20005)] {
        let alone = eval_trial(subject, synth::Preset::Hard, seed).trajectories;
        let n = alone.markers();
        let with = synth::with_props(&alone, 3, seed).expect("props");
        let props: Vec<Vec<usize>> = (0..3)
            .map(|p| (0..4).map(|k| n + 4 * p + k).collect())
            .collect();
        let mut bodies = independent_bodies(&with, &Params::default()).expect("bodies");
        bodies.sort();
        let mut expected = props.clone();
        expected.insert(0, (0..n).collect());
        assert_eq!(bodies, expected, "{subject} {seed}");
        let subject_groups = |seg: &Segmentation| -> Vec<Vec<usize>> {
            partition(seg).into_iter().filter(|g| g[0] < n).collect()
        };
        let seg_alone = run(&alone, &Params::default()).expect("segments");
        let seg_with = run(&with, &Params::default()).expect("segments");
        assert_eq!(
            subject_groups(&seg_with),
            subject_groups(&seg_alone),
            "{subject} {seed}"
        );
        for prop in &props {
            assert!(
                partition(&seg_with).contains(prop),
                "{subject} {seed}: {prop:?}"
            );
        }
        // Every marker's diagnostics are its own body's part's.
        for m in 0..n {
            assert_eq!(
                seg_with.markers[m].visible_frames,
                seg_alone.markers[m].visible_frames
            );
        }
        let one_body = Params {
            body_gap_ratio: 0.0,
            ..Params::default()
        };
        let before = run(&with, &one_body).expect("segments");
        assert_ne!(
            subject_groups(&before),
            subject_groups(&seg_alone),
            "{subject} {seed}"
        );
    }
}

/// No hard, messy or clean synthetic subject alone is taken for two bodies
/// (`props_segment`'s "subject alone split": 0 of 700 each over seeds 20001–20100; with two
/// or three markers per segment 2 of 700, a wide joint link standing 3.4 times above
/// the next).
#[test]
fn a_subject_alone_is_one_body() {
    for subject in synth::Subject::ALL {
        for preset in [
            synth::Preset::Clean,
            synth::Preset::Hard,
            synth::Preset::Messy,
        ] {
            let trial = eval_trial(subject, preset, 20001);
            let bodies =
                independent_bodies(&trial.trajectories, &Params::default()).expect("bodies");
            assert_eq!(bodies.len(), 1, "{}", trial.name);
        }
    }
}

/// A group the user names across two bodies says they are one: nothing is segmented
/// apart, and the group is a segment; so does a cluster count the user forces.
#[test]
fn a_group_named_across_bodies_makes_them_one() {
    let alone = eval_trial(synth::Subject::Snowman, synth::Preset::Hard, 20001).trajectories;
    let with = synth::with_props(&alone, 1, 20001).expect("props");
    let apart = independent_bodies(&with, &Params::default()).expect("bodies");
    assert_eq!(apart.len(), 2);
    let first = with.labels()[0].clone();
    let params = Params {
        groups: vec![vec![first, "PROP0_*".to_string()]],
        ..Params::default()
    };
    assert_eq!(independent_bodies(&with, &params).expect("bodies").len(), 1);
    // So does a cluster count the user forces: it is the whole capture's.
    let forced = Params {
        segments: 6,
        ..Params::default()
    };
    assert_eq!(independent_bodies(&with, &forced).expect("bodies").len(), 1);
    let seg = run(&with, &params).expect("segments");
    let n = alone.markers();
    let named: Vec<usize> = [0].into_iter().chain(n..n + 4).collect();
    assert!(partition(&seg).contains(&named), "{:?}", partition(&seg));
}
