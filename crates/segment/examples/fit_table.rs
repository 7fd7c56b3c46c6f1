//! Rigid-fit σ of every true segment and of every jointed pair of true segments (their
//! union) in one synthetic trial, with the best bipartition's pooled σ: how well the fit
//! split separates joints from skin artefact.
//!
//! `cargo run --release -p segment --example fit_table SUBJECT PRESET SEED [frames]`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let trial = common::trial_from_args(&args, 480);
    let traj = &trial.trajectories;
    let members = trial.true_segment_markers();
    println!("{}", trial.name);
    for (s, seg) in trial.truth.segments.iter().enumerate() {
        if let Some((w, b)) = segment::fit_split_sigmas(traj, &members[s]) {
            println!(
                "  segment {:14} n={:2} σ {:6.2} split {:6.2} ratio {:5.2}",
                seg.name,
                members[s].len(),
                w,
                b,
                w / b
            );
        }
    }
    for j in &trial.truth.joints {
        let mut union = members[j.parent_segment].clone();
        union.extend(&members[j.child_segment]);
        if let Some((w, b)) = segment::fit_split_sigmas(traj, &union) {
            println!(
                "  joint   {:14} n={:2} σ {:6.2} split {:6.2} ratio {:5.2} ({})",
                j.name,
                union.len(),
                w,
                b,
                w / b,
                j.kind
            );
        }
    }
    let params = common::params_from_overrides(args.iter().skip(4));
    let seg = segment::run(traj, &params).expect("segmentation");
    let truth_of = |m: usize| {
        members
            .iter()
            .position(|g| g.contains(&m))
            .unwrap_or(usize::MAX)
    };
    for s in &seg.segments {
        let truths: Vec<usize> = s.markers.iter().map(|&m| truth_of(m)).collect();
        if let Some((w, b)) = segment::fit_split_sigmas(traj, &s.markers) {
            println!(
                "  found {:2} truth {:?} σ {:6.2} split {:6.2} ratio {:5.2}",
                s.id,
                truths,
                w,
                b,
                w / b
            );
        }
    }
}
