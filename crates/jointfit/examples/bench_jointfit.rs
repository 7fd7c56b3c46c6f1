//! Times the jointfit stage on a generated human: poses, then all pair fits per method.
//!
//! `cargo run --release -p jointfit --example bench_jointfit -- [FRAMES] [SUBJECT]`
//! (default 6000 frames, human, hard preset).
#![allow(clippy::print_stdout)]

use std::time::Instant;

use jointfit::{Method, Params, run_on_segments};
use synth::{Preset, Subject, SynthConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let frames: usize = args.get(1).map_or(Ok(6000), |s| s.parse())?;
    let subject: Subject = args.get(2).map_or(Ok(Subject::Human), |s| s.parse())?;
    let trial = synth::generate(&SynthConfig {
        subject,
        preset: Preset::Hard,
        frames,
        seed: 7,
        ..SynthConfig::default()
    })?;
    let traj = &trial.trajectories;
    let segments: Vec<Vec<usize>> = trial.true_segment_markers();
    let n = segments.len();
    println!(
        "{}: {frames} frames, {} markers, {n} segments, {} pairs, {} threads",
        trial.name,
        traj.markers(),
        n * (n - 1) / 2,
        rayon::current_num_threads()
    );
    // Poses alone: one-segment runs have no pairs.
    let start = Instant::now();
    for s in &segments {
        run_on_segments(traj, std::slice::from_ref(s), &Params::default())?;
    }
    println!(
        "poses (serial over segments): {:.3} s",
        start.elapsed().as_secs_f64()
    );
    for method in [Method::Score, Method::Aguiar] {
        let params = Params {
            method,
            ..Params::default()
        };
        let start = Instant::now();
        let fits = run_on_segments(traj, &segments, &params)?;
        println!(
            "{:<7} poses + all pairs: {:.3} s ({} pairs)",
            method.name(),
            start.elapsed().as_secs_f64(),
            fits.pairs.len()
        );
    }
    Ok(())
}
