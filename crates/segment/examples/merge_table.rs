//! The joint test's evidence between every two final segments of ≥ 3 markers of synthetic
//! trials, labelled by the truth: `split` (both mostly the same true segment: a rigid body
//! cut in two) or `joint` (mostly two segments a true joint joins); other pairs are left
//! out. What a rule merging segments back (`segment.joint_merge_z`) would weigh, with the
//! smallest ρ between their markers over the tolerance (`rhotol`), and the joint test's own
//! best cut of their union (`uz`, `utz`; `same` when it is their partition).
//!
//! `cargo run --release -p segment --example merge_table SUBJECTS PRESET FRAMES SEEDS...`
#![allow(clippy::print_stdout)]

mod common;

use rayon::prelude::*;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let set = common::trial_set_from_args(&args);
    let params = segment::Params::default();
    let jobs: Vec<(synth::Subject, u64)> = set
        .subjects
        .iter()
        .flat_map(|&s| set.seeds.iter().map(move |&seed| (s, seed)))
        .collect();
    let lines: Vec<Vec<String>> = jobs
        .par_iter()
        .map(|&(subject, seed)| {
            let trial = common::generate(subject, set.preset, set.frames, seed);
            let traj = &trial.trajectories;
            let truth = common::true_segment_of(&trial);
            let seg = segment::run(traj, &params).expect("segmentation");
            let clusters: Vec<Vec<usize>> =
                seg.segments.iter().map(|s| s.markers.clone()).collect();
            let sigma = segment::typical_fit_sigma(traj, &clusters);
            let majority = |c: &[usize]| {
                let mut counts = std::collections::BTreeMap::new();
                for &m in c {
                    *counts.entry(truth[m]).or_insert(0usize) += 1;
                }
                counts
                    .into_iter()
                    .max_by_key(|&(s, n)| (n, std::cmp::Reverse(s)))
                    .map(|(s, _)| s)
            };
            let joined = |a: usize, b: usize| {
                trial.truth.joints.iter().any(|j| {
                    (j.parent_segment == a && j.child_segment == b)
                        || (j.parent_segment == b && j.child_segment == a)
                })
            };
            let rho_min = |a: &[usize], b: &[usize]| {
                a.iter()
                    .flat_map(|&x| b.iter().map(move |&y| common::rho_mm(traj, x, y)))
                    .filter(|r| r.is_finite())
                    .fold(f64::INFINITY, f64::min)
            };
            let mut out = Vec::new();
            for (i, a) in clusters.iter().enumerate() {
                for (j, b) in clusters.iter().enumerate().skip(i + 1) {
                    if a.len() < 3 || b.len() < 3 {
                        continue;
                    }
                    let (Some(ma), Some(mb)) = (majority(a), majority(b)) else {
                        continue;
                    };
                    let label = if ma == mb {
                        "split"
                    } else if joined(ma, mb) {
                        "joint"
                    } else {
                        "apart"
                    };
                    if label == "apart" {
                        continue;
                    }
                    if let Some(e) = segment::joint_evidence(traj, a, b, sigma) {
                        // What the joint test itself weighs on the union: its own cut.
                        let union = [a.as_slice(), b.as_slice()].concat();
                        let cut = segment::joint_split_candidate(traj, &union, sigma, &params)
                            .map_or("uz - utz - same -".to_owned(), |(ca, _, u)| {
                                let mut x = ca.clone();
                                x.sort_unstable();
                                let (mut y, mut z) = (a.clone(), b.clone());
                                y.sort_unstable();
                                z.sort_unstable();
                                format!(
                                    "uz {:.2} utz {:.2} same {}",
                                    u.rotation_z,
                                    u.translation_z,
                                    x == y || x == z
                                )
                            });
                        out.push(format!(
                            "{label:5} {:24} {i}+{j} na {} nb {} rhotol {:.2} {} {cut}",
                            trial.name,
                            a.len(),
                            b.len(),
                            rho_min(a, b) / seg.tolerance_mm,
                            common::evidence_line(&e, sigma)
                        ));
                    }
                }
            }
            out
        })
        .collect();
    for l in lines.into_iter().flatten() {
        println!("{l}");
    }
}
