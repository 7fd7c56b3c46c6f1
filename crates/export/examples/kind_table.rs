//! Per true joint of synthetic trials, with the later stages given the true segments: its
//! true kind and swept angles, the kind jointfit gave the pair and why, as one JSON line
//! each, so kind rules can be weighed against the truth.
//!
//! `cargo run --release -p export --example kind_table -- SUBJECT PRESET SEED...`
//! (`JOINTFIT=JSON` sets jointfit parameters).
#![allow(clippy::print_stdout)]

mod common;

use synth::{Preset, Subject, SynthConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        println!("usage: kind_table SUBJECT PRESET SEED...");
        return Ok(());
    }
    let subject: Subject = args[1].parse()?;
    let preset: Preset = args[2].parse()?;
    let markers = SynthConfig::default().markers_per_segment;
    for seed in args[3..].iter().filter_map(|a| a.parse::<u64>().ok()) {
        let trial = common::trial(subject, preset, seed, 480, markers)?;
        let traj = &trial.trajectories;
        let mut seg = segment::run(traj, &segment::Params::default())?;
        seg.regroup(&trial.true_segment_markers(), "on no true segment");
        let params: jointfit::Params = match std::env::var("JOINTFIT") {
            Ok(json) => serde_json::from_str(&json)?,
            Err(_) => jointfit::Params::default(),
        };
        let fits = jointfit::run(traj, &seg, &params)?;
        let truth_of = common::truth_of(&trial, &seg);
        for j in &trial.truth.joints {
            let found = |t: usize| truth_of.iter().position(|&x| x == Some(t));
            let (Some(a), Some(b)) = (found(j.parent_segment), found(j.child_segment)) else {
                continue;
            };
            let Some(pair) = fits
                .pairs
                .iter()
                .find(|p| (p.a, p.b) == (a.min(b), a.max(b)))
            else {
                continue;
            };
            println!(
                "{}",
                serde_json::json!({
                    "trial": trial.name,
                    "joint": j.name,
                    "kind": j.kind,
                    "swept_deg": j.swept_deg,
                    "estimated": pair.kind,
                    "rotation_rms_deg": pair.rotation_rms_deg,
                    "wobble_deg": pair.wobble_deg,
                    "evidence": pair.evidence,
                })
            );
        }
    }
    Ok(())
}
