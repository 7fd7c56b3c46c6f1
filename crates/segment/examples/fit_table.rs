//! Rigid-fit σ of every true segment and of every jointed pair of true segments (their
//! union) in one synthetic trial, with the best bipartition's pooled σ: how well the fit
//! split separates joints from skin artefact.
//!
//! `cargo run --release -p segment --example fit_table SUBJECT PRESET SEED [frames]`
#![allow(clippy::print_stdout)]

use synth::{Preset, Subject, SynthConfig};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let subject: Subject = args
        .first()
        .and_then(|s| s.parse().ok())
        .unwrap_or(Subject::Human);
    let preset: Preset = args
        .get(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(Preset::Hard);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(480);
    let config = SynthConfig {
        subject,
        preset,
        frames,
        seed,
        ..SynthConfig::default()
    };
    let trial = synth::generate(&config).expect("trial");
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
    let overrides: serde_json::Map<String, serde_json::Value> = args
        .iter()
        .skip(4)
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| {
            (
                k.to_string(),
                serde_json::from_str(v).unwrap_or(serde_json::Value::String(v.to_string())),
            )
        })
        .collect();
    let params: segment::Params =
        serde_json::from_value(serde_json::Value::Object(overrides)).expect("params");
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
