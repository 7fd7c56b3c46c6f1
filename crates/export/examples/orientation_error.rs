//! How far the skeleton's segment orientations are from the truth: for every tree segment
//! of synthetic trials, its global orientation (root rotation chained with the joints'
//! local rotations) against its true segment's, after the one constant rotation that best
//! aligns the two frames (a segment's frame is its reference pose, the truth's its rest
//! pose); RMS over segments and frames, leaf segments apart, and how many frames a segment
//! turns by over 30° from the frame before.
//!
//! `cargo run --release -p export --example orientation_error -- SUBJECTS SEEDS [PRESET]`
//! (subjects comma-separated, seeds `A..B` or comma-separated, preset default `hard`;
//! `BONEFIT='{"rotation_prior_deg_s": 0}'` sets bonefit parameters as JSON).
#![allow(clippy::print_stdout)]

mod common;

use glam::{DQuat, DVec4};
use synth::{Preset, Subject, SynthConfig};

/// Seeds from `A..B` (inclusive) or `A,B,C`.
fn seeds(arg: &str) -> Result<Vec<u64>, std::num::ParseIntError> {
    let mut out = Vec::new();
    for part in arg.split(',') {
        match part.split_once("..") {
            Some((a, b)) => out.extend(a.parse::<u64>()?..=b.parse::<u64>()?),
            None => out.push(part.parse()?),
        }
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let subjects = args
        .get(1)
        .map_or("human", |s| s.as_str())
        .split(',')
        .map(str::parse)
        .collect::<Result<Vec<Subject>, _>>()?;
    let seeds = seeds(args.get(2).map_or("20001..20010", |s| s.as_str()))?;
    let preset: Preset = args.get(3).map_or("hard", |s| s.as_str()).parse()?;
    let params: bonefit::Params = match std::env::var("BONEFIT") {
        Ok(json) => serde_json::from_str(&json)?,
        Err(_) => bonefit::Params::default(),
    };
    let (mut all, mut leaves) = ((0.0f64, 0usize), (0.0f64, 0usize));
    let mut turns = 0usize;
    for &subject in &subjects {
        for &seed in &seeds {
            let markers = SynthConfig::default().markers_per_segment;
            let trial = common::trial(subject, preset, seed, 480, markers)?;
            let (seg, fits, topology) = common::up_to_tree(&trial)?;
            let truth_of = common::truth_of(&trial, &seg);
            let skeleton = bonefit::run(&trial.trajectories, &seg, &fits, &topology, &params)?;
            let frames = skeleton.frame_count;
            let true_segments = trial.truth.segments.len();
            let mut global: Vec<Vec<DQuat>> = vec![Vec::new(); seg.segments.len()];
            global[skeleton.root_segment] = skeleton
                .root_rotations
                .iter()
                .map(|&q| DQuat::from_array(q))
                .collect();
            // Joints come parent before child.
            for j in &skeleton.joints {
                let parent = global[j.parent_segment].clone();
                global[j.child_segment] = parent
                    .iter()
                    .zip(&j.local_rotations)
                    .map(|(p, &q)| *p * DQuat::from_array(q))
                    .collect();
            }
            for (s, estimated) in global.iter().enumerate() {
                let Some(t) = truth_of[s].filter(|_| estimated.len() == frames) else {
                    continue;
                };
                let truth: Vec<DQuat> = (0..frames)
                    .map(|f| DQuat::from_array(trial.segment_rotations[f * true_segments + t]))
                    .collect();
                let first = DVec4::from(truth[0].inverse() * estimated[0]);
                let mut sum = DVec4::ZERO;
                for (t, e) in truth.iter().zip(estimated) {
                    let v = DVec4::from(t.inverse() * *e);
                    sum += if v.dot(first) < 0.0 { -v } else { v };
                }
                let align = DQuat::from_vec4(sum).normalize();
                let leaf = !skeleton.joints.iter().any(|j| j.parent_segment == s);
                for f in 0..frames {
                    let error = (truth[f] * align).angle_between(estimated[f]).to_degrees();
                    all = (all.0 + error * error, all.1 + 1);
                    if leaf {
                        leaves = (leaves.0 + error * error, leaves.1 + 1);
                    }
                    if f > 0 && estimated[f - 1].angle_between(estimated[f]).to_degrees() > 30.0 {
                        turns += 1;
                    }
                }
            }
        }
    }
    let rms = |(sq, n): (f64, usize)| (sq / n.max(1) as f64).sqrt();
    println!(
        "orientation RMS error {:.3}° over {} (segment, frame); leaf segments {:.3}° over {}; \
         frames turning over 30° from the one before: {turns}",
        rms(all),
        all.1,
        rms(leaves),
        leaves.1
    );
    Ok(())
}
