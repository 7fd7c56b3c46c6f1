//! The joint test's evidence across each true joint of one synthetic trial, between the
//! true marker sets of its two segments: what the test would see with the cut in the
//! right place (a true joint scoring below `joint_split_z` cannot be found by it).
//!
//! `cargo run --release -p segment --example truth_evidence SUBJECT PRESET SEED [frames]`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let trial = common::trial_from_args(&args, 480);
    let traj = &trial.trajectories;
    let sets = trial.true_segment_markers();
    let posable: Vec<Vec<usize>> = sets.iter().filter(|s| s.len() >= 3).cloned().collect();
    let sigma = segment::typical_fit_sigma(traj, &posable);
    println!("{}: typical fit σ {sigma:.2} mm", trial.name);
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
        match evidence {
            Some(e) => println!(
                "{head}: {} union σ/typ {:.2}",
                common::evidence_line(&e, sigma),
                common::union_ratio(traj, a, b, sigma)
            ),
            None => println!("{head}: not testable (a side with < 3 markers or < 3 posed frames)"),
        }
    }
}
