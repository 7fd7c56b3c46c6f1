//! Per synthetic trial, which found segments mix true segments and which true segments are
//! spread over several found ones (by name and marker count): what a segmentation got wrong.
//!
//! `cargo run --release -p segment --example mix_segment SUBJECTS PRESET FRAMES SEEDS... [key=value ...]`
//! (SUBJECTS comma-separated, e.g. `hexapod,human`).
#![allow(clippy::print_stdout)]

use std::collections::BTreeMap;

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let set = common::trial_set_from_args(&args);
    let overrides: Vec<&String> = args.iter().skip(3).filter(|a| a.contains('=')).collect();
    let params = common::params_from_overrides(overrides);
    let (mut exact, mut total) = (0, 0);
    for trial in set.trials() {
        let traj = &trial.trajectories;
        let truth_sets = trial.true_segment_markers();
        let truth = common::true_segment_of(&trial);
        let seg = segment::run(traj, &params).expect("segmentation");
        let name = |s: usize| trial.truth.segments[s].name.clone();
        let mut wrong = Vec::new();
        for s in &seg.segments {
            let mut parts: BTreeMap<usize, usize> = BTreeMap::new();
            for &m in &s.markers {
                *parts.entry(truth[m]).or_default() += 1;
            }
            let whole = parts.iter().all(|(&t, &c)| truth_sets[t].len() == c);
            if parts.len() > 1 || !whole {
                let desc: Vec<String> = parts
                    .iter()
                    .map(|(&t, &c)| format!("{}{}/{}", name(t), c, truth_sets[t].len()))
                    .collect();
                wrong.push(format!("[{}]", desc.join(" ")));
            }
        }
        for u in &seg.unassigned {
            wrong.push(format!("unassigned {}", name(truth[u.marker])));
        }
        total += 1;
        if wrong.is_empty() {
            exact += 1;
        } else {
            println!("{}: {}", trial.name, wrong.join(" "));
        }
    }
    println!("exact {exact}/{total}");
}
