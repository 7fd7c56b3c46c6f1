//! The joint test's evidence in synthetic trials: for every true segment of ≥ 6 markers the
//! bipartition the test weighs (a false split if it passes), and for every true joint the
//! union of its two segments, cut where the test would cut it and where the truth does.
//!
//! `cargo run --release -p segment --example joint_table SUBJECTS PRESET FRAMES SEEDS...`
//! One line per case: kind, trial, name, n, rotation/noise (deg), ratio, centre/translation
//! (mm), fraction, pooled σ, and whether the weighed cut is the true one.
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let set = common::trial_set_from_args(&args);
    let params = segment::Params::default();
    let line = |kind: &str,
                trial: &str,
                name: &str,
                n: usize,
                e: &segment::JointEvidence,
                sigma: f64,
                tag: &str| {
        println!(
            "{kind:5} {trial:22} {name:28} n={n:2} rot {:6.2} noise {:5.2} ratio {:6.2} centre {:6.2} transl {:6.2} frac {:5.2} pooled {:5.2} gain {:6.4} z {:6.2} tz {:6.2} part {:5.2} typ {sigma:5.2} {tag}",
            e.rotation_deg,
            e.noise_deg,
            e.rotation_deg / e.noise_deg,
            e.centre_mm,
            e.translation_mm,
            e.centre_mm / e.translation_mm,
            e.pooled_sigma_mm,
            e.gain_deg_per_mm,
            e.rotation_z,
            e.translation_z,
            e.part_sigma_mm
        );
    };
    for trial in set.trials() {
        let traj = &trial.trajectories;
        let members = trial.true_segment_markers();
        let sigma = segment::typical_fit_sigma(traj, &members);
        for (s, seg) in trial.truth.segments.iter().enumerate() {
            if let Some((_, _, e)) =
                segment::joint_split_candidate(traj, &members[s], sigma, &params)
            {
                line(
                    "seg",
                    &trial.name,
                    &seg.name,
                    members[s].len(),
                    &e,
                    sigma,
                    "",
                );
            }
        }
        for j in &trial.truth.joints {
            let (a, b) = (&members[j.parent_segment], &members[j.child_segment]);
            let mut union = a.clone();
            union.extend(b);
            let name = format!(
                "{}+{}",
                trial.truth.segments[j.parent_segment].name,
                trial.truth.segments[j.child_segment].name
            );
            if let Some((ca, _, e)) = segment::joint_split_candidate(traj, &union, sigma, &params) {
                let right = {
                    let mut x = ca.clone();
                    x.sort_unstable();
                    let mut y = a.clone();
                    y.sort_unstable();
                    let mut z = b.clone();
                    z.sort_unstable();
                    x == y || x == z
                };
                line(
                    "joint",
                    &trial.name,
                    &name,
                    union.len(),
                    &e,
                    sigma,
                    if right { "cut=truth" } else { "cut!=truth" },
                );
            }
            if a.len() >= 3
                && b.len() >= 3
                && let Some(e) = segment::joint_evidence(traj, a, b, sigma)
            {
                line("true", &trial.name, &name, union.len(), &e, sigma, "");
            }
        }
    }
}
