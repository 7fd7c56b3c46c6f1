//! Runs synthetic trials through every stage and prints, per trial, how far the
//! skeleton's forward kinematics (constant bones) is from jointfit's fitted joint centres,
//! and the scorer's joint error against the truth, for each bone/rotation method.
//!
//! `cargo run --release -p export --example pipeline_fk [-- frames seed [methods]]`
//! where methods is a comma list of `rigid+fitted`, `rigid+poses`, `paper+fitted`,
//! `paper+poses` (default `rigid+fitted,rigid+poses`), and an optional marker weight
//! for the fitted rotations (default bonefit's). With `SHOW_SHIFTS=1` in the environment,
//! every slid hinge centre is listed (shift, bone).
#![allow(clippy::print_stdout)]

mod common;

use synth::{Preset, Subject, SynthConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(600);
    let seed = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(11);
    let methods: Vec<(bonefit::BoneMethod, bonefit::RotationMethod)> = args
        .get(3)
        .map_or("rigid+fitted,rigid+poses", |s| s.as_str())
        .split(',')
        .filter_map(|m| {
            let (b, r) = m.split_once('+')?;
            let b = serde_json::from_value(serde_json::Value::String(b.to_owned())).ok()?;
            let r = serde_json::from_value(serde_json::Value::String(r.to_owned())).ok()?;
            Some((b, r))
        })
        .collect();
    let marker_weight = args
        .get(4)
        .and_then(|a| a.parse().ok())
        .unwrap_or(bonefit::Params::default().marker_weight);
    println!(
        "{:<22} {:>12} {:>5} {:>5} {:>9} {:>9} {:>9} {:>7} {:>9} {:>9} {:>9}",
        "trial",
        "method",
        "segs",
        "topo",
        "fk-rms",
        "fk-worst",
        "err-mm",
        "err-%",
        "known",
        "fit-err",
        "fit-known"
    );
    for subject in [
        Subject::Human,
        Subject::Quadruped,
        Subject::Robotarm,
        Subject::Snowman,
        Subject::Hexapod,
        Subject::Random,
    ] {
        for preset in [Preset::Clean, Preset::Hard] {
            let trial = synth::generate(&SynthConfig {
                subject,
                preset,
                frames,
                seed,
                ..SynthConfig::default()
            })?;
            let traj = &trial.trajectories;
            let (seg, fits, topology) = common::up_to_tree(&trial)?;
            for &(method, rotations) in &methods {
                let params = bonefit::Params {
                    method,
                    rotations,
                    marker_weight,
                    ..bonefit::Params::default()
                };
                let skeleton = bonefit::run(traj, &seg, &fits, &topology, &params)?;
                let outputs = export::run(
                    &export::Inputs {
                        trajectories: traj,
                        segmentation: &seg,
                        fits: &fits,
                        topology: &topology,
                        skeleton: &skeleton,
                        settings: &Default::default(),
                        reader_warnings: &[],
                    },
                    &export::Params::default(),
                )?;
                let json = outputs
                    .files
                    .get("skeleton.json")
                    .cloned()
                    .unwrap_or_default();
                let estimate: synth::score::Estimate = serde_json::from_slice(&json)?;
                let score = synth::score::score(&trial.truth, &estimate);
                // The same estimate with jointfit's per-frame centres instead of FK.
                let mut fitted = estimate.clone();
                for (e, j) in fitted.joints.iter_mut().zip(&skeleton.joints) {
                    let pair = &fits.pairs[j.pair];
                    e.positions = pair
                        .positions
                        .iter()
                        .map(|p| p.iter().all(|c| c.is_finite()).then_some(*p))
                        .collect();
                }
                let fitted_score = synth::score::score(&trial.truth, &fitted);
                if std::env::var_os("SHOW_SHIFTS").is_some() {
                    for j in &skeleton.joints {
                        if j.hinge_shift_mm != 0.0 {
                            println!(
                                "  {} shift {:.1} mm, bone {:.0} mm",
                                j.name, j.hinge_shift_mm, j.bone_length
                            );
                        }
                    }
                }
                // RMS over all joints' frames of FK − fitted (each joint weighted by frames).
                let (mut sum, mut count, mut worst) = (0.0, 0.0, 0.0f64);
                for j in &skeleton.joints {
                    if j.fit_rms_mm.is_finite() {
                        sum += j.fit_rms_mm.powi(2) * j.frames_known as f64;
                        count += j.frames_known as f64;
                        worst = worst.max(j.fit_rms_mm);
                    }
                }
                let opt = |v: Option<f64>| v.map_or("-".to_owned(), |x| format!("{x:.1}"));
                println!(
                    "{:<22} {:>12} {:>5} {:>5} {:>9.2} {:>9.2} {:>9} {:>7} {:>9.3} {:>9} {:>9.3}",
                    trial.name,
                    format!("{}+{}", method.name(), rotations.name()),
                    seg.segments.len(),
                    score.topology_exact,
                    (sum / count.max(1.0)).sqrt(),
                    worst,
                    opt(score.joint_error_mean_mm),
                    opt(score.joint_error_mean_pct),
                    score.known_fraction,
                    opt(fitted_score.joint_error_mean_mm),
                    fitted_score.known_fraction,
                );
            }
        }
    }
    Ok(())
}
