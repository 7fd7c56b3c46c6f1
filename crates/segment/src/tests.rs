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
    let paper_like = Params {
        segments: 2,
        rigidity_check: false,
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

#[test]
fn explore_scales() {
    if std::env::var_os("SEG_EXPLORE").is_none() {
        return;
    }
    for (name, scene) in [
        ("4bodies", four_bodies(1)),
        (
            "chain",
            Scene {
                sizes: vec![4, 3, 5, 3, 2],
                chain: true,
                frames: 800,
                noise_mm: 0.5,
                gap_fraction: 0.1,
                seed: 11,
            },
        ),
        (
            "chain2",
            Scene {
                sizes: vec![3, 3, 2, 3, 2, 4, 3],
                chain: true,
                frames: 800,
                noise_mm: 1.0,
                gap_fraction: 0.1,
                seed: 12,
            },
        ),
    ] {
        let (traj, truth) = scene.build();
        for k in [1, 2, 3, 5] {
            for floor in [0.5, 1.0, 3.0] {
                let p = Params {
                    local_k: k,
                    min_scale_mm: floor,
                    rigidity_check: false,
                    ..Params::default()
                };
                let seg = run(&traj, &p).expect("segments");
                let ok = partition(&seg) == truth;
                let ev: Vec<String> = seg
                    .eigenvalues
                    .iter()
                    .take(truth.len() + 2)
                    .map(|v| format!("{v:.3}"))
                    .collect();
                eprintln!(
                    "{name} k={k} floor={floor} ok={ok} chosen={} ev={}",
                    seg.eigengap_segments,
                    ev.join(" ")
                );
            }
        }
    }
}
