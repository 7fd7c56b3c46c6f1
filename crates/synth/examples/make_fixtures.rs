//! Writes the committed fixtures: `fixtures/{human-clean,human-hard,robotarm-clean}`
//! `.c3d` + `.truth.json`, 240 frames at 120 Hz, seed 1.
//!
//! Run: `cargo run --release -p synth --example make_fixtures [OUT_DIR]`
//! (default OUT_DIR: the workspace's `fixtures/`). File stems drop the `-s1` seed suffix
//! of trial names so the README's default input, `fixtures/human-clean.c3d`, stays put;
//! the truth files still record the seed.

use std::path::PathBuf;

use synth::{Preset, Subject, SynthConfig, generate, write_trial};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures"));
    let fixtures = [
        // 3–4 markers per segment keeps an 18-segment human's C3D under 300 KB.
        (Subject::Human, Preset::Clean, (3, 4)),
        (Subject::Human, Preset::Hard, (3, 4)),
        (Subject::Robotarm, Preset::Clean, (3, 6)),
    ];
    for (subject, preset, markers_per_segment) in fixtures {
        let config = SynthConfig {
            subject,
            preset,
            frames: 240,
            rate: 120.0,
            seed: 1,
            markers_per_segment,
            ..SynthConfig::default()
        };
        let mut trial = generate(&config)?;
        trial.name = format!("{}-{}", subject.name(), preset.name());
        trial.truth.name = trial.name.clone();
        for path in write_trial(&out, &trial, false)? {
            let bytes = std::fs::metadata(&path)?.len();
            eprintln!("{:>8} bytes  {}", bytes, path.display());
        }
    }
    Ok(())
}
