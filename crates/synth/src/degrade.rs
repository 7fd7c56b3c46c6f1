//! Degradations: soft-tissue artefact, label swaps, noise and gaps.

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::body::Body;
use crate::markers::MarkerSet;
use crate::motion::Motion;
use crate::truth::{TruthGap, TruthSwap};

/// Share of the trial a label swap lasts.
pub(crate) const SWAP_FRACTION: f64 = 0.15;
/// Short holes: probability that a marker gets any.
pub(crate) const SHORT_GAP_PROBABILITY: f64 = 0.5;
/// Short holes per affected marker, inclusive range.
pub(crate) const SHORT_GAPS_PER_MARKER: [usize; 2] = [1, 3];
/// Short hole length, frames, inclusive range.
pub(crate) const SHORT_GAP_FRAMES: [usize; 2] = [2, 20];
/// Long hole length as a share of the trial.
pub(crate) const LONG_GAP_FRACTION: [f64; 2] = [0.1, 0.3];
/// One long hole per this many markers (at least one).
pub(crate) const MARKERS_PER_LONG_GAP: usize = 15;

/// Soft-tissue displacement of every marker at every frame, in its segment's local frame
/// (`[f * markers + m]`, mm).
///
/// Each joint touching the marker's segment drives the displacement with its first angle
/// (rescaled to [−1, 1]); the direction is half a segment-wide vector shared by the
/// segment's markers and half the marker's own, weighted by closeness to the joint;
/// the result is scaled so its largest length over the trial is drawn in `amplitude_mm`
/// (the config's `skin_mm`, 5–15 mm by default).
pub(crate) fn skin(
    body: &Body,
    motion: &Motion,
    markers: &MarkerSet,
    amplitude_mm: (f64, f64),
    rng: &mut ChaCha8Rng,
) -> Vec<DVec3> {
    let n = markers.labels.len();
    let frames = motion.frames;
    // Per joint, one direction shared by its child's markers and one by its parent's.
    let shared: Vec<[DVec3; 2]> = body
        .joints
        .iter()
        .map(|_| [random_unit(rng), random_unit(rng)])
        .collect();
    let mut out = vec![DVec3::ZERO; frames * n];
    for m in 0..n {
        let s = markers.segment[m];
        let p = markers.local[m];
        // (joint, direction) pairs driving this marker.
        let mut drivers = Vec::new();
        for (j, joint) in body.joints.iter().enumerate() {
            let (side, at) = if joint.child == s {
                (0, DVec3::ZERO)
            } else if joint.parent == s {
                (1, joint.offset)
            } else {
                continue;
            };
            let weight = 1.0 / (1.0 + p.distance(at) / 150.0);
            let dir = 0.5 * shared[j][side] + 0.5 * random_unit(rng);
            drivers.push((j, dir * weight));
        }
        let amplitude = rng.random_range(amplitude_mm.0..=amplitude_mm.1);
        let mut largest: f64 = 0.0;
        for f in 0..frames {
            let d: DVec3 = drivers
                .iter()
                .map(|(j, dir)| *dir * motion.drive[*j][f])
                .fold(DVec3::ZERO, |a, b| a + b);
            largest = largest.max(d.length());
            out[f * n + m] = d;
        }
        if largest > 1e-12 {
            let scale = amplitude / largest;
            for f in 0..frames {
                out[f * n + m] *= scale;
            }
        }
    }
    out
}

/// A uniformly random unit vector.
fn random_unit(rng: &mut ChaCha8Rng) -> DVec3 {
    loop {
        let p = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = p.length();
        if (0.1..=1.0).contains(&l) {
            return p / l;
        }
    }
}

/// Swaps the labels of the two markers of different segments that come closest to
/// each other, for 15 % of the trial around that moment. Returns what was swapped.
pub(crate) fn swap(
    positions: &mut [[f64; 3]],
    markers: &MarkerSet,
    frames: usize,
) -> Option<TruthSwap> {
    let n = markers.labels.len();
    let mut best: Option<(f64, usize, usize, usize)> = None;
    for f in 0..frames {
        let row = &positions[f * n..(f + 1) * n];
        for a in 0..n {
            for b in a + 1..n {
                if markers.segment[a] == markers.segment[b] {
                    continue;
                }
                let d = DVec3::from(row[a]).distance_squared(DVec3::from(row[b]));
                if best.is_none_or(|(bd, ..)| d < bd) {
                    best = Some((d, a, b, f));
                }
            }
        }
    }
    let (_, a, b, at) = best?;
    let length = ((frames as f64 * SWAP_FRACTION).round() as usize).clamp(1, frames);
    let first = at.saturating_sub(length / 2).min(frames - length);
    for f in first..first + length {
        positions.swap(f * n + a, f * n + b);
    }
    Some(TruthSwap {
        labels: [markers.labels[a].clone(), markers.labels[b].clone()],
        first_frame: first,
        frames: length,
    })
}

/// Adds independent Gaussian noise of `sigma_mm` to every coordinate of present samples.
pub(crate) fn noise(positions: &mut [[f64; 3]], sigma_mm: f64, rng: &mut ChaCha8Rng) {
    let Ok(normal) = Normal::new(0.0, sigma_mm) else {
        return;
    };
    if sigma_mm == 0.0 {
        return;
    }
    for p in positions.iter_mut() {
        for c in p.iter_mut() {
            *c += normal.sample(rng);
        }
    }
}

/// Punches holes (NaN samples): short ones in about half the markers, a long one in a
/// few, and one marker lost from the middle frame to the end. Returns every hole.
pub(crate) fn gaps(
    positions: &mut [[f64; 3]],
    markers: &MarkerSet,
    frames: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<TruthGap> {
    let n = markers.labels.len();
    let mut holes = Vec::new();
    if n == 0 {
        return holes;
    }
    let lost = rng.random_range(0..n);
    holes.push(TruthGap {
        label: markers.labels[lost].clone(),
        first_frame: frames / 2,
        frames: frames - frames / 2,
        kind: "lost".into(),
    });
    // Long holes go to distinct markers other than the lost one.
    let mut others: Vec<usize> = (0..n).filter(|&m| m != lost).collect();
    let long_count = (n / MARKERS_PER_LONG_GAP).max(1).min(others.len());
    for _ in 0..long_count {
        let m = others.swap_remove(rng.random_range(0..others.len()));
        let share = rng.random_range(LONG_GAP_FRACTION[0]..=LONG_GAP_FRACTION[1]);
        let length = ((share * frames as f64).round() as usize).clamp(1, frames);
        let first = rng.random_range(0..=frames - length);
        holes.push(TruthGap {
            label: markers.labels[m].clone(),
            first_frame: first,
            frames: length,
            kind: "long".into(),
        });
    }
    for m in (0..n).filter(|&m| m != lost) {
        if !rng.random_bool(SHORT_GAP_PROBABILITY) {
            continue;
        }
        let count = rng.random_range(SHORT_GAPS_PER_MARKER[0]..=SHORT_GAPS_PER_MARKER[1]);
        for _ in 0..count {
            let length = rng
                .random_range(SHORT_GAP_FRAMES[0]..=SHORT_GAP_FRAMES[1])
                .min(frames);
            let first = rng.random_range(0..=frames - length);
            holes.push(TruthGap {
                label: markers.labels[m].clone(),
                first_frame: first,
                frames: length,
                kind: "short".into(),
            });
        }
    }
    for hole in &holes {
        if let Some(m) = markers.labels.iter().position(|l| *l == hole.label) {
            for f in hole.first_frame..hole.first_frame + hole.frames {
                positions[f * n + m] = mocap_io::MISSING;
            }
        }
    }
    // Stable order: by label, then start, then length.
    holes.sort_by(|a, b| {
        (a.label.as_str(), a.first_frame, a.frames).cmp(&(
            b.label.as_str(),
            b.first_frame,
            b.frames,
        ))
    });
    holes
}
