//! What the tree probes share: the stages up to the tree on a synthetic trial, and the
//! found segments read against the generator's truth.

// Each example compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use jointfit::PairFits;
use segment::Segmentation;
use synth::{Preset, Subject, SynthConfig, Trial};
use topo::Topology;

/// The synthetic trial of one subject, preset, seed, length and markers per segment.
pub fn trial(
    subject: Subject,
    preset: Preset,
    seed: u64,
    frames: usize,
    markers_per_segment: (usize, usize),
) -> Result<Trial, synth::Error> {
    synth::generate(&SynthConfig {
        subject,
        preset,
        frames,
        seed,
        markers_per_segment,
        ..SynthConfig::default()
    })
}

/// Segmentation, pair fits and tree of a trial, every stage at its defaults.
pub fn up_to_tree(
    trial: &Trial,
) -> Result<(Segmentation, PairFits, Topology), Box<dyn std::error::Error>> {
    let traj = &trial.trajectories;
    let mut seg = segment::run(traj, &segment::Params::default())?;
    // Set and not empty: `TRUE_SEGMENTS= cmd` (as a shell leaves a cleared variable) is off.
    if std::env::var_os("TRUE_SEGMENTS").is_some_and(|v| !v.is_empty()) {
        seg.regroup(&trial.true_segment_markers(), "on no true segment");
    }
    // `JOINTFIT='{"tree_poses": false}'` sets jointfit parameters (JSON) for a diagnosis.
    let params: jointfit::Params = match std::env::var("JOINTFIT") {
        Ok(json) => serde_json::from_str(&json)?,
        Err(_) => jointfit::Params::default(),
    };
    let fits = jointfit::run(traj, &seg, &params)?;
    let topology = topo::run(&seg, &fits, &topo::Params::default())?;
    Ok((seg, fits, topology))
}

/// Each found segment's true segment: the one sharing most of its markers.
pub fn truth_of(trial: &Trial, seg: &Segmentation) -> Vec<Option<usize>> {
    let labels = trial.trajectories.labels();
    seg.segments
        .iter()
        .map(|s| {
            let mut best = (0usize, None);
            for (t, ts) in trial.truth.segments.iter().enumerate() {
                let shared = s
                    .markers
                    .iter()
                    .filter(|&&m| labels.get(m).is_some_and(|l| ts.markers.contains(l)))
                    .count();
                if shared > best.0 {
                    best = (shared, Some(t));
                }
            }
            best.1
        })
        .collect()
}

/// Whether found segments a and b hold the two sides of a true joint.
pub fn true_edge(trial: &Trial, truth_of: &[Option<usize>], a: usize, b: usize) -> bool {
    let (Some(ta), Some(tb)) = (truth_of[a], truth_of[b]) else {
        return false;
    };
    trial.truth.joints.iter().any(|j| {
        (j.parent_segment, j.child_segment) == (ta, tb)
            || (j.parent_segment, j.child_segment) == (tb, ta)
    })
}

/// Whether the tree joins segments a and b.
pub fn chosen(topology: &Topology, a: usize, b: usize) -> bool {
    topology.joints.iter().any(|j| {
        (j.parent_segment, j.child_segment) == (a, b)
            || (j.parent_segment, j.child_segment) == (b, a)
    })
}
