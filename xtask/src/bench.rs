//! `cargo xtask bench`: reading a C3D, each stage and the whole run, timed on a synthetic human.

use std::time::Instant;

use anyhow::{Context as _, Result};
use mocap_io::ReadOptions;
use synth::{Preset, Subject, SynthConfig};

use crate::cache::Cache;
use crate::pipeline::{self, Params};
use crate::progress::Progress;
use crate::tempdir::TempDir;

/// Arguments of `bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Frames of the synthetic capture.
    #[arg(long, default_value_t = 6000)]
    pub frames: usize,
    /// Subject of the synthetic capture.
    #[arg(long, default_value = "human")]
    pub subject: String,
    /// Degradation preset of the synthetic capture.
    #[arg(long, default_value = "clean")]
    pub preset: String,
    /// Generator seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Times the C3D is read (the best time is reported).
    #[arg(long, default_value_t = 5)]
    pub reads: usize,
    /// Times the warm-cache run is repeated (the best time is reported: a single one,
    /// right after the cold run in the same process, varied 0.040-0.088 s on the default
    /// capture).
    #[arg(long, default_value_t = 5)]
    pub warm_runs: usize,
    /// Set a stage parameter (STAGE.PARAM=VALUE). Repeatable.
    #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
    pub set: Vec<String>,
}

/// Runs `bench`.
pub fn main(args: &Args) -> Result<()> {
    let params = Params::from_assignments(&args.set)?;
    let config = SynthConfig {
        subject: args.subject.parse::<Subject>()?,
        preset: args.preset.parse::<Preset>()?,
        frames: args.frames,
        seed: args.seed,
        ..SynthConfig::default()
    };
    config.validate()?;
    let start = Instant::now();
    let trial = synth::generate(&config)?;
    let generate_s = start.elapsed().as_secs_f64();
    let dir = TempDir::new("bench")?;
    let c3d = dir.path().join(format!("{}.c3d", trial.name));
    mocap_io::write_c3d(&c3d, &trial.trajectories)?;
    let bytes = std::fs::metadata(&c3d)
        .with_context(|| format!("{}: cannot stat", c3d.display()))?
        .len();
    let t = &trial.trajectories;
    println!(
        "bench: {} — {} markers × {} frames at {} Hz, C3D {:.1} MB (generated in {generate_s:.2} s)",
        trial.name,
        t.markers(),
        t.frames(),
        t.frame_rate(),
        bytes as f64 / 1e6
    );

    let mut best_read = f64::INFINITY;
    let mut capture = None;
    for _ in 0..args.reads.max(1) {
        let start = Instant::now();
        let c = mocap_io::read_capture(&c3d, &ReadOptions::default())?;
        best_read = best_read.min(start.elapsed().as_secs_f64());
        capture = Some(c);
    }
    let capture = capture.context("no read happened")?;

    let start = Instant::now();
    let (products, runs) = pipeline::run_in_memory(capture, &params)?;
    let stages_s = start.elapsed().as_secs_f64();

    // The runner's own path: cold cache (compute + encode + store, files written), then
    // warm (all hits: entries checked by header and hash, export's files streamed out and
    // left where the folder holds them already).
    let cache_dir = TempDir::new("bench-cache")?;
    let cache = Cache::open(cache_dir.path())?;
    let out = dir.path().join("out");
    let start = Instant::now();
    pipeline::run_cached(&c3d, &params, &cache, None, &Progress::hidden(), &out)?;
    let cold_s = start.elapsed().as_secs_f64();
    let mut warm_s = f64::INFINITY;
    let mut all_cached = true;
    for _ in 0..args.warm_runs.max(1) {
        let start = Instant::now();
        let (_, runs, _) =
            pipeline::run_cached(&c3d, &params, &cache, None, &Progress::hidden(), &out)?;
        warm_s = warm_s.min(start.elapsed().as_secs_f64());
        all_cached &= runs.iter().all(|r| r.cached);
    }

    println!();
    println!("| step | seconds | notes |");
    println!("| --- | ---: | --- |");
    println!(
        "| read C3D (mocap-io) | {best_read:.4} | best of {}, {:.0} MB/s |",
        args.reads.max(1),
        bytes as f64 / 1e6 / best_read.max(1e-9)
    );
    for r in &runs {
        println!("| {} | {:.4} | |", r.name, r.seconds);
    }
    println!(
        "| all stages, in memory | {:.4} | read + segment … export |",
        best_read + stages_s
    );
    println!(
        "| `run`, cold cache | {cold_s:.4} | read, compute, encode and store every artifact, \
         write the files |"
    );
    println!(
        "| `run`, warm cache | {warm_s:.4} | best of {}; {} |",
        args.warm_runs.max(1),
        if all_cached {
            "every stage a cache hit (header and hash checked; export's files streamed out, \
             those the folder holds already left as they are)"
        } else {
            "NOT all cached"
        }
    );
    if let (Some(seg), Some(topo)) = (&products.segmentation, &products.topology) {
        println!();
        println!(
            "{} segments (truth {}), {} joints (truth {})",
            seg.segments.len(),
            trial.truth.segments.len(),
            topo.joints.len(),
            trial.truth.joints.len()
        );
    }
    Ok(())
}
