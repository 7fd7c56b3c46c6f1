//! What the segment probes share: a synthetic trial, a real capture and parameter overrides
//! from argv, and the joint test's evidence as one line.

// Each example compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use synth::{Preset, Subject, SynthConfig, Trial};

/// The trial named by `SUBJECT PRESET SEED [FRAMES]` (defaults: human, hard, 1, `frames`).
pub fn trial_from_args(args: &[String], frames: usize) -> Trial {
    let (subject, preset) = subject_and_preset(args);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(frames);
    generate(subject, preset, frames, seed)
}

/// The subject and preset `SUBJECT PRESET ...` names (defaults: human, hard).
pub fn subject_and_preset(args: &[String]) -> (Subject, Preset) {
    let subject: Subject = args
        .first()
        .and_then(|s| s.parse().ok())
        .unwrap_or(Subject::Human);
    let preset: Preset = args
        .get(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(Preset::Hard);
    (subject, preset)
}

/// Seeds from one argument: a seed or an inclusive range `FIRST..LAST`; `None` when it is
/// neither.
pub fn seeds(arg: &str) -> Option<Vec<u64>> {
    match arg.split_once("..") {
        Some((first, last)) => Some((first.parse().ok()?..=last.parse().ok()?).collect()),
        None => Some(vec![arg.parse().ok()?]),
    }
}

/// The synthetic trial of one subject, preset, length and seed.
pub fn generate(subject: Subject, preset: Preset, frames: usize, seed: u64) -> Trial {
    let defaults = SynthConfig::default();
    // `MARKERS=MIN:MAX` in the environment sets the markers per segment.
    let markers_per_segment = env_range("MARKERS").unwrap_or(defaults.markers_per_segment);
    // `NOISE=MM` sets the noise σ of the noise, hard and messy presets.
    let noise_mm = std::env::var("NOISE")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(defaults.noise_mm);
    // `SWEEP=MIN:MAX` sets the share of each joint's range the trial sweeps.
    let sweep = env_range("SWEEP").unwrap_or(defaults.sweep);
    // `SKIN=MIN:MAX` sets each marker's soft-tissue amplitude, mm (skin, hard, messy).
    let skin_mm = env_range("SKIN").unwrap_or(defaults.skin_mm);
    synth::generate(&SynthConfig {
        subject,
        preset,
        frames,
        seed,
        markers_per_segment,
        noise_mm,
        sweep,
        skin_mm,
        ..defaults
    })
    .expect("synthetic trial")
}

/// The environment variable `name` read as `MIN:MAX`; `None` when unset or malformed.
fn env_range<T: std::str::FromStr>(name: &str) -> Option<(T, T)> {
    let value = std::env::var(name).ok()?;
    let (a, b) = value.split_once(':')?;
    Some((a.parse().ok()?, b.parse().ok()?))
}

/// Each marker's true segment (`usize::MAX` for a marker on none).
pub fn true_segment_of(trial: &Trial) -> Vec<usize> {
    let mut truth = vec![usize::MAX; trial.trajectories.markers()];
    for (s, markers) in trial.true_segment_markers().iter().enumerate() {
        for &m in markers {
            truth[m] = s;
        }
    }
    truth
}

/// `segment::Params` from `key=value` words (values parsed as JSON, else strings).
pub fn params_from_overrides<'a>(words: impl IntoIterator<Item = &'a String>) -> segment::Params {
    let overrides: serde_json::Map<String, serde_json::Value> = words
        .into_iter()
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| {
            (
                k.to_string(),
                serde_json::from_str(v).unwrap_or(serde_json::Value::String(v.to_string())),
            )
        })
        .collect();
    serde_json::from_value(serde_json::Value::Object(overrides)).expect("segment params")
}

/// Trials named by `SUBJECTS PRESET FRAMES SEEDS...` (subjects comma-separated; defaults:
/// none, hard, 480, none).
pub struct TrialSet {
    pub subjects: Vec<Subject>,
    pub preset: Preset,
    pub frames: usize,
    pub seeds: Vec<u64>,
}

impl TrialSet {
    /// Every trial of the set, each subject's seeds in turn.
    pub fn trials(&self) -> impl Iterator<Item = Trial> + '_ {
        self.subjects.iter().flat_map(move |&subject| {
            self.seeds
                .iter()
                .map(move |&seed| generate(subject, self.preset, self.frames, seed))
        })
    }
}

/// Parses [`TrialSet`] from argv (after the program name).
pub fn trial_set_from_args(args: &[String]) -> TrialSet {
    TrialSet {
        subjects: args
            .first()
            .map(|s| s.split(',').filter_map(|x| x.parse().ok()).collect())
            .unwrap_or_default(),
        preset: args
            .get(1)
            .and_then(|s| s.parse().ok())
            .unwrap_or(Preset::Hard),
        frames: args.get(2).and_then(|s| s.parse().ok()).unwrap_or(480),
        seeds: args.iter().skip(3).filter_map(|s| s.parse().ok()).collect(),
    }
}

/// The capture whose path is `args[0]` (path, trajectories); prints `usage` and gives `None`
/// when no path was given.
pub fn capture_from_args(args: &[String], usage: &str) -> Option<(String, mocap_io::Trajectories)> {
    let Some(path) = args.first() else {
        println!("usage: {usage}");
        return None;
    };
    let capture = mocap_io::read_capture(std::path::Path::new(path), &Default::default())
        .expect("readable capture");
    Some((path.clone(), capture.trajectories))
}

/// The joint test's evidence on one line, with the typical segment σ it was weighed by.
pub fn evidence_line(e: &segment::JointEvidence, typical_sigma_mm: f64) -> String {
    format!(
        "z {:.2} tz {:.2} rot {:.2} noise {:.2} centre {:.2} transl {:.2} part {:.2} typ {typical_sigma_mm:.2}",
        e.rotation_z,
        e.translation_z,
        e.rotation_deg,
        e.noise_deg,
        e.centre_mm,
        e.translation_mm,
        e.part_sigma_mm
    )
}

/// Rigid-fit σ of `a` ∪ `b` as one body over the capture's typical σ: how well two parts fit
/// as one (the fit split rejoins pieces up to its floor, 2).
pub fn union_ratio(
    traj: &mocap_io::Trajectories,
    a: &[usize],
    b: &[usize],
    typical_sigma_mm: f64,
) -> f64 {
    segment::fit_split_sigmas(traj, &[a, b].concat())
        .map_or(f64::NAN, |(sigma, _)| sigma / typical_sigma_mm)
}

/// ρ of markers `i` and `j` by brute force: the standard deviation of their distance over
/// the frames both are seen in (mm; NaN when they never are). A diagnostic, not the stage's.
pub fn rho_mm(traj: &mocap_io::Trajectories, i: usize, j: usize) -> f64 {
    let d: Vec<f64> = (0..traj.frames())
        .filter_map(|f| {
            let (a, b) = (traj.get(f, i)?, traj.get(f, j)?);
            Some(((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
        })
        .collect();
    let m = d.iter().sum::<f64>() / d.len() as f64;
    (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
}
