//! Motion: smooth joint angles sweeping most of each range, and the root's travel.
//!
//! Every degree of freedom follows a sum of three sinusoids (random frequencies in a
//! low band, random phases and amplitudes), affinely rescaled so that over the trial it
//! spans exactly a random share of the joint's range (by default 70–95 %, see
//! [`crate::SynthConfig::sweep`]), placed at random inside it. The
//! band is 0.25–0.8 Hz, raised for short trials so each track completes at least one
//! cycle. The root walks a circle of 0.5–4 m circumference while its heading makes one
//! full turn, bobs or jumps, and tilts a few degrees.

use std::f64::consts::{PI, TAU};

use glam::{DQuat, DVec3, EulerRot};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::body::Body;

/// Every segment's pose at every frame, and the joint angles behind them.
#[derive(Clone, Debug)]
pub(crate) struct Motion {
    /// Number of frames.
    pub frames: usize,
    /// Number of segments.
    pub segments: usize,
    /// Local → global rotation of segment `s` at frame `f`: `rot[f * segments + s]`.
    pub rot: Vec<DQuat>,
    /// Local origin of segment `s` at frame `f` in global mm: `origin[f * segments + s]`.
    pub origin: Vec<DVec3>,
    /// Joint `j`'s first angle track rescaled to [−1, 1] per frame (drives skin artefact).
    pub drive: Vec<Vec<f64>>,
}

impl Motion {
    /// Rotation of a segment at a frame.
    pub(crate) fn rot(&self, frame: usize, segment: usize) -> DQuat {
        self.rot[frame * self.segments + segment]
    }
    /// Origin of a segment at a frame, global mm.
    pub(crate) fn origin(&self, frame: usize, segment: usize) -> DVec3 {
        self.origin[frame * self.segments + segment]
    }
}

/// Frequency band (Hz) of the angle tracks for a trial of `duration` seconds.
fn band(duration: f64) -> [f64; 2] {
    [0.25f64.max(1.0 / duration), 0.8f64.max(1.5 / duration)]
}

/// A smooth track over `frames` frames, rescaled to span exactly [0, 1].
fn smooth_track(frames: usize, rate: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let [lo, hi] = band(frames as f64 / rate);
    let waves: Vec<[f64; 3]> = (0..3)
        .map(|_| {
            [
                rng.random_range(0.5..1.0),
                rng.random_range(lo..=hi),
                rng.random_range(0.0..TAU),
            ]
        })
        .collect();
    let raw: Vec<f64> = (0..frames)
        .map(|f| {
            let t = f as f64 / rate;
            waves
                .iter()
                .map(|[a, fr, ph]| a * (TAU * fr * t + ph).sin())
                .sum()
        })
        .collect();
    let min = raw.iter().copied().fold(f64::INFINITY, f64::min);
    let max = raw.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = max - min;
    raw.iter()
        .map(|r| if span > 1e-12 { (r - min) / span } else { 0.5 })
        .collect()
}

/// Animates a body over `frames` frames at `rate` Hz from the motion random stream, each
/// degree of freedom sweeping a share of its range drawn uniformly in `sweep`.
pub(crate) fn animate(
    body: &Body,
    frames: usize,
    rate: f64,
    sweep: (f64, f64),
    rng: &mut ChaCha8Rng,
) -> Motion {
    // angles[j][f * dofs + d] in degrees.
    let mut angles: Vec<Vec<f64>> = Vec::with_capacity(body.joints.len());
    let mut drive = Vec::with_capacity(body.joints.len());
    for joint in &body.joints {
        let limits = joint.kind.limits();
        let dofs = limits.len();
        let mut track = vec![0.0; frames * dofs];
        for (d, [lo, hi]) in limits.iter().copied().enumerate() {
            // One draw either way, so a fixed share leaves the rest of the stream alone.
            let draw: f64 = rng.random_range(0.0..1.0);
            let fraction = sweep.0 + (sweep.1 - sweep.0) * draw;
            let width = fraction * (hi - lo);
            let start = lo + rng.random_range(0.0..1.0) * (hi - lo - width);
            let unit = smooth_track(frames, rate, rng);
            for (f, u) in unit.iter().enumerate() {
                track[f * dofs + d] = start + width * u;
            }
            if d == 0 {
                drive.push(unit.iter().map(|u| 2.0 * u - 1.0).collect());
            }
        }
        angles.push(track);
    }

    let duration = frames as f64 / rate;
    let style = &body.root;
    let path = (style.speed_mm_s * duration).clamp(500.0, 4000.0);
    let heading0 = rng.random_range(0.0..TAU);
    let centre = DVec3::new(
        rng.random_range(-500.0..500.0),
        rng.random_range(-500.0..500.0),
        0.0,
    );
    let [lo, hi] = band(duration);
    let mut tilt = || (rng.random_range(lo..=hi), rng.random_range(0.0..TAU));
    let (pitch_hz, pitch_phase) = tilt();
    let (roll_hz, roll_phase) = tilt();
    let bob_phase = rng.random_range(0.0..TAU);
    // Heading turns at a constant rate, one full turn per trial; walking along the
    // heading at constant speed traces a circle of radius path / 2π.
    let omega = TAU / duration;
    let radius = path / TAU;

    let segments = body.segments.len();
    let mut motion = Motion {
        frames,
        segments,
        rot: Vec::with_capacity(frames * segments),
        origin: Vec::with_capacity(frames * segments),
        drive,
    };
    let mut frame_angles: Vec<Vec<f64>> = body
        .joints
        .iter()
        .map(|j| vec![0.0; j.kind.limits().len()])
        .collect();
    for f in 0..frames {
        let t = f as f64 / rate;
        let heading = heading0 + omega * t;
        let pitch = style.tilt_deg.to_radians() * (TAU * pitch_hz * t + pitch_phase).sin();
        let roll = style.tilt_deg.to_radians() * (TAU * roll_hz * t + roll_phase).sin();
        let root_rot = DQuat::from_euler(EulerRot::ZYX, heading, pitch, roll);
        let z = style.height_mm
            + style.bob_mm * (TAU * style.bob_hz * t + bob_phase).sin()
            + style.jump_mm * (PI * style.bob_hz * t).sin().powi(2);
        let root_pos = centre
            + DVec3::new(
                radius * (heading.sin() - heading0.sin()),
                radius * (heading0.cos() - heading.cos()),
                z,
            );
        for (j, a) in frame_angles.iter_mut().enumerate() {
            let dofs = a.len();
            a.copy_from_slice(&angles[j][f * dofs..(f + 1) * dofs]);
        }
        let pose = body.pose(root_rot, root_pos, &frame_angles);
        motion.rot.extend_from_slice(&pose.rot);
        motion.origin.extend_from_slice(&pose.origin);
    }
    motion
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn tracks_are_smooth_and_span_the_unit_interval() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let t = smooth_track(240, 120.0, &mut rng);
        let min = t.iter().copied().fold(f64::INFINITY, f64::min);
        let max = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(min.abs() < 1e-12 && (max - 1.0).abs() < 1e-12);
        // Smooth: no frame-to-frame step above what 3 waves of ≤ 1.2 Hz allow at 120 Hz.
        let step = t
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        assert!(step < 0.1, "{step}");
    }
}
