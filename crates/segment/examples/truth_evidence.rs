//! The joint test's evidence across each true joint of synthetic trials, between the
//! true marker sets of its two segments: what the test would see with the cut in the
//! right place (a true joint scoring below `joint_split_z` cannot be found by it).
//!
//! `cargo run --release -p segment --example truth_evidence SUBJECT PRESET SEEDS [frames]`
//!
//! SEEDS is one seed or a range `FIRST..LAST`. Each line says whether the default
//! parameters' joint test would cut there (`cut`) or not (`below`); over several seeds a
//! summary follows: the trials in which every true joint would be cut (a ceiling on the
//! exact trees any segmentation gets from this test) and the joints that would not be,
//! by name. The typical fit σ is the true segments', not the pipeline's clusters'.
//! `MARKERS`, `NOISE`, `SWEEP` and `SKIN` (`MIN:MAX`) set the generator, as in the other
//! examples.
#![allow(clippy::print_stdout)]

mod common;

use std::collections::BTreeMap;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (subject, preset) = common::subject_and_preset(&args);
    let seeds = match args.get(2) {
        None => vec![1],
        Some(arg) => common::seeds(arg).unwrap_or_else(|| {
            eprintln!("SEEDS: a seed or a range FIRST..LAST, not {arg:?}");
            std::process::exit(2)
        }),
    };
    let frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(480);
    let params = segment::Params::default();
    let mut every_joint_cut = 0;
    let mut missed_by_joint: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for &seed in &seeds {
        let trial = common::generate(subject, preset, frames, seed);
        let traj = &trial.trajectories;
        let sets = trial.true_segment_markers();
        let posable: Vec<Vec<usize>> = sets.iter().filter(|s| s.len() >= 3).cloned().collect();
        let sigma = segment::typical_fit_sigma(traj, &posable);
        // Each part must fit like an ordinary segment, as in `segment::run`.
        let part_sigma = params.segment_sigma_mm(sigma);
        println!("{}: typical fit σ {sigma:.2} mm", trial.name);
        let mut all_cut = true;
        for j in &trial.truth.joints {
            let (a, b) = (&sets[j.parent_segment], &sets[j.child_segment]);
            let swept: Vec<String> = j.swept_deg.iter().map(|d| format!("{d:.0}")).collect();
            let head = format!(
                "{:<18} {:<6} {}+{} markers, swept {}°",
                j.name,
                j.kind,
                a.len(),
                b.len(),
                swept.join("/")
            );
            let evidence = (a.len() >= 3 && b.len() >= 3)
                .then(|| segment::joint_evidence(traj, a, b, sigma))
                .flatten();
            let cut = evidence.is_some_and(|e| {
                e.is_joint(
                    params.joint_split_z,
                    params.joint_travel_z,
                    (
                        params.joint_rotation_travel_z,
                        params.joint_rotation_alone_z,
                    ),
                    params.joint_centre_fraction,
                    part_sigma,
                )
            });
            all_cut &= cut;
            let tally = missed_by_joint.entry(j.name.clone()).or_default();
            tally.0 += usize::from(!cut);
            tally.1 += 1;
            let verdict = if cut { "cut" } else { "below" };
            match evidence {
                Some(e) => println!(
                    "{head}: {verdict:<5} {} union σ/typ {:.2}",
                    common::evidence_line(&e, sigma),
                    common::union_ratio(traj, a, b, sigma)
                ),
                None => println!(
                    "{head}: {verdict:<5} not testable (a side with < 3 markers or < 3 posed frames)"
                ),
            }
        }
        every_joint_cut += usize::from(all_cut);
    }
    if seeds.len() > 1 {
        println!(
            "\n{subject} {preset}, {} seeds: every true joint cut in {every_joint_cut} trials",
            seeds.len()
        );
        for (name, (missed, of)) in missed_by_joint
            .iter()
            .filter(|(_, (missed, _))| *missed > 0)
        {
            println!("  {name:<18} below the test in {missed} of {of}");
        }
    }
}
