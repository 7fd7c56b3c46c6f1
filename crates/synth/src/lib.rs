//! synth: synthetic motion-capture trials with known answers, and the scorer.
//!
//! Takes a [`SynthConfig`] (subject, degradation preset, frames, rate, seed) and gives a
//! [`Trial`]: marker [`Trajectories`] (global frame, Z up, mm,
//! NaN triples where missing) with labels `M000`, `M001`, … that reveal nothing, and its
//! [`Truth`]: which markers ride on which segment, every joint's kind, range of motion
//! and centre per frame, the tree, the subject's size. [`write_trial`] writes
//! `<name>.c3d`, `<name>.truth.json` (and a TRC on request); [`score::score`] compares a
//! pipeline's skeleton.json with a truth.
//!
//! Subjects are articulated trees (human, quadruped, robot arm, the paper's jumping
//! snowman, hexapod, random trees, a snake robot of universal joints) moving smoothly,
//! every joint sweeping 70–95 % of its range (or the share [`SynthConfig::sweep`] asks for)
//! while the whole body walks a circle and turns once about the vertical.
//!
//! It does not estimate anything (that is the pipeline) and writes files only through
//! [`write_trial`]. Same config → byte-identical output.

mod body;
mod config;
mod degrade;
mod error;
mod markers;
mod motion;
mod props;
pub mod score;
mod subjects;
mod truth;
mod unlabeled;

use mocap_io::Trajectories;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use config::{CONFIG_DOCS, Preset, Subject, SynthConfig};
pub use error::Error;
pub use props::{PROP_MARKERS, with_props};
pub use truth::{
    POSITION_STEP_MM, TRUTH_SCHEMA_VERSION, Truth, TruthGap, TruthJoint, TruthSegment, TruthSwap,
    read_truth, write_trial,
};
pub use unlabeled::unlabeled;

/// Stage-like name of this crate, for logs and artifact headers.
pub const STAGE: &str = "synth";

/// A generated trial: its name, marker trajectories and ground truth.
#[derive(Clone, Debug)]
pub struct Trial {
    /// `<subject>-<preset>-s<seed>`, e.g. `human-clean-s1`; the stem of the files written.
    pub name: String,
    /// Marker trajectories, global frame, mm; first frame numbered 1.
    pub trajectories: Trajectories,
    /// What the trajectories really show.
    pub truth: Truth,
    /// Each segment's local → global rotation per frame as a quaternion `[x, y, z, w]`,
    /// `[frame * segments + segment]` (segment frames have the global axes at the rest
    /// pose); in memory only, for scoring errors in a segment's own frame.
    pub segment_rotations: Vec<[f64; 4]>,
}

impl Trial {
    /// The true segments as marker indices into `trajectories.labels()`, in truth order:
    /// the segmentation a perfect segment stage would return.
    pub fn true_segment_markers(&self) -> Vec<Vec<usize>> {
        let labels = self.trajectories.labels();
        self.truth
            .segments
            .iter()
            .map(|s| {
                s.markers
                    .iter()
                    .filter_map(|l| labels.iter().position(|x| x == l))
                    .collect()
            })
            .collect()
    }
}

/// Independent random streams, so that changing the preset leaves body, markers and
/// motion unchanged.
#[derive(Clone, Copy)]
enum Stream {
    Body = 1,
    Markers = 2,
    Motion = 3,
    Skin = 4,
    Noise = 5,
    Gaps = 6,
}

fn rng(seed: u64, stream: Stream) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream as u64);
    r
}

/// Generates a trial: body, markers, motion, then the preset's degradations (skin
/// artefact, then label swap, then noise, then gaps).
pub fn generate(config: &SynthConfig) -> Result<Trial, Error> {
    config.validate()?;
    let body = subjects::build(config.subject, &mut rng(config.seed, Stream::Body));
    let markers = markers::place(
        &body,
        config.markers_per_segment,
        config.marker_arc_deg,
        &mut rng(config.seed, Stream::Markers),
    );
    let motion = motion::animate(
        &body,
        config.frames,
        config.rate,
        config.sweep,
        &mut rng(config.seed, Stream::Motion),
    );
    let preset = config.preset;
    let skin = preset.has_skin().then(|| {
        degrade::skin(
            &body,
            &motion,
            &markers,
            config.skin_mm,
            &mut rng(config.seed, Stream::Skin),
        )
    });
    let mut positions = markers::positions(&motion, &markers, skin.as_deref());
    let swaps = if preset.has_swap() {
        degrade::swap(&mut positions, &markers, config.frames)
            .into_iter()
            .collect()
    } else {
        Vec::new()
    };
    if preset.has_noise() {
        degrade::noise(
            &mut positions,
            config.noise_mm,
            &mut rng(config.seed, Stream::Noise),
        );
    }
    let gaps = if preset.has_gaps() {
        degrade::gaps(
            &mut positions,
            &markers,
            config.frames,
            &mut rng(config.seed, Stream::Gaps),
        )
    } else {
        Vec::new()
    };
    let truth = truth::build(config, &body, &markers, &motion, gaps, swaps);
    let trajectories = Trajectories::new(
        markers.labels.clone(),
        config.rate,
        1,
        config.frames,
        positions,
    )?;
    Ok(Trial {
        name: truth.name.clone(),
        trajectories,
        truth,
        segment_rotations: motion.rot.iter().map(|q| q.to_array()).collect(),
    })
}

#[cfg(test)]
mod tests;
