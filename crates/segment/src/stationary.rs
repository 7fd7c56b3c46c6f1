//! Markers that never move: floor and reference markers, a calibration frame left in the
//! volume, stray reflections the tracker kept. They are rigid with one another and with
//! nothing that moves, carry nothing about how a body is built, and yet they move the
//! capture-wide quantities the grouping reads (the noise level off the steadiest pairs,
//! the marker spacing, the eigen-gap count): one static point beside CMU 02_01 regrouped
//! three of its markers, and on OpenSim's subject01_walk1 one joined the pelvis. So they
//! are set aside before anything else and come back at the end as one segment of their
//! own (the room, or a fixed robot's base, which a joint may still join) or, one alone,
//! unassigned with the reason.
//!
//! A marker is stationary when its positions' RMS spread about their mean is within
//! `Params::stationary_jitter_factor` times the RMS of its frame-to-frame steps: white
//! measurement noise alone gives a ratio of about 0.7 (spread √3 σ, steps √6 σ), while
//! anything a body carries moves smoothly, far more over the capture than between two
//! frames. Only where the capture moves ([`MOTION_RATIO`]): a static trial is left as it is.

use mocap_io::{Trajectories, is_present};

use crate::pairstats::pair_stats;
use crate::rigidity::rms_rho;
use crate::{MarkerDiagnostics, Params, Segment, Segmentation, UnassignedMarker};

/// Steps between consecutive frames needed before a marker's jitter is believed.
const MIN_STEPS: usize = 10;

/// A spread (mm) at or below this is no motion whatever the jitter (noiseless data).
const EXACT_MM: f64 = 1e-6;

/// How far a marker wanders over the capture and between frames, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Wander {
    /// RMS distance of its positions from their mean.
    pub spread_mm: f64,
    /// RMS length of its steps between consecutive frames both seen.
    pub step_mm: f64,
}

/// How far marker `m` wanders, over the frames it is seen in; `None` with fewer than
/// `needed` frames seen or [`MIN_STEPS`] steps.
pub(crate) fn wander(traj: &Trajectories, m: usize, needed: usize) -> Option<Wander> {
    let (mut seen, mut sum, mut steps, mut step_sq) = (0usize, [0.0f64; 3], 0usize, 0.0f64);
    let mut last: Option<[f64; 3]> = None;
    for f in 0..traj.frames() {
        let p = traj.frame(f)[m];
        if !is_present(p) {
            last = None;
            continue;
        }
        seen += 1;
        for k in 0..3 {
            sum[k] += p[k];
        }
        if let Some(q) = last {
            step_sq += (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>();
            steps += 1;
        }
        last = Some(p);
    }
    if seen < needed.max(1) || steps < MIN_STEPS {
        return None;
    }
    let mean = sum.map(|s| s / seen as f64);
    let spread_sq: f64 = (0..traj.frames())
        .map(|f| traj.frame(f)[m])
        .filter(|&p| is_present(p))
        .map(|p| (0..3).map(|k| (p[k] - mean[k]).powi(2)).sum::<f64>())
        .sum();
    Some(Wander {
        spread_mm: (spread_sq / seen as f64).sqrt(),
        step_mm: (step_sq / steps as f64).sqrt(),
    })
}

/// The stationary markers (ascending; see the module docs), none of them in `named` (the
/// user's groups stand over the data); empty where no marker moves.
pub(crate) fn stationary_markers(
    traj: &Trajectories,
    params: &Params,
    named: &[Vec<usize>],
) -> Vec<usize> {
    if params.stationary_jitter_factor <= 0.0 {
        return Vec::new();
    }
    let needed = params
        .min_visible_frames
        .max((params.min_visible_fraction * traj.frames() as f64).ceil() as usize);
    let mut still = Vec::new();
    let mut still_spread: f64 = 0.0;
    let mut moving_spreads = Vec::new();
    for m in 0..traj.markers() {
        let Some(w) = wander(traj, m, needed) else {
            continue;
        };
        if w.spread_mm <= params.stationary_jitter_factor * w.step_mm + EXACT_MM {
            if !named.iter().flatten().any(|&n| n == m) {
                still.push(m);
                still_spread = still_spread.max(w.spread_mm);
            }
        } else {
            moving_spreads.push(w.spread_mm);
        }
    }
    // A static trial sways: its markers wander a little more than they jitter, and those
    // that jitter more than they wander are no room apart from them.
    moving_spreads.sort_by(f64::total_cmp);
    let moves = moving_spreads
        .get(moving_spreads.len() / 2)
        .is_some_and(|&median| median > MOTION_RATIO * still_spread);
    if moves { still } else { Vec::new() }
}

/// The capture moves where the median marker that is not stationary wanders more than
/// this many times as far as the stationary one that wanders most: on c3d.org's static
/// trial (sample 33) the markers beyond their jitter wander less than that one (RMS 0.28
/// mm, median, against 1.1), on OpenSim's treadmill walk (subject01_walk1) 100 times as
/// far as a floor marker's 0.9, on CMU 02_01's walk 1000 times (a one-off script).
const MOTION_RATIO: f64 = 20.0;

/// Puts the `still` markers, which `seg` was found without, back: one segment of their
/// own where there are at least `min_segment_markers` (inserted in id order, the later
/// ids shifted), else each unassigned with the reason; their diagnostics from `traj`.
pub(crate) fn put_back(
    seg: &mut Segmentation,
    traj: &Trajectories,
    still: &[usize],
    params: &Params,
) {
    if still.is_empty() {
        return;
    }
    seg.unassigned.retain(|u| !still.contains(&u.marker));
    let alone = traj.select(0..traj.frames(), still);
    let stats = pair_stats(&alone);
    for (k, &m) in still.iter().enumerate() {
        if let Some(d) = seg.markers.get_mut(m) {
            let mates: Vec<usize> = (0..still.len()).filter(|&j| j != k).collect();
            *d = MarkerDiagnostics {
                segment: None,
                visible_frames: stats.visible[k],
                glitch_frames: 0,
                rigidity_residual_mm: rms_rho(&stats, k, &mates, params.min_overlap_frames)
                    .unwrap_or(f64::NAN),
                slides: false,
            };
        }
    }
    if still.len() < params.min_segment_markers.max(2) {
        for &m in still {
            let w = wander(traj, m, 0);
            seg.unassigned.push(UnassignedMarker {
                marker: m,
                reason: w.map_or_else(
                    || "stationary: it does not move while the capture's markers do".to_string(),
                    |w| {
                        format!(
                            "stationary: it stays within {:.2} mm RMS of one place (its steps \
                             between frames {:.2} mm RMS) while the capture's markers move",
                            w.spread_mm, w.step_mm
                        )
                    },
                ),
            });
        }
        seg.unassigned.sort_by_key(|u| u.marker);
        return;
    }
    let first = still[0];
    let id = seg
        .segments
        .iter()
        .position(|s| s.markers.first().is_some_and(|&m| m > first))
        .unwrap_or(seg.segments.len());
    seg.segments.insert(
        id,
        Segment {
            id,
            markers: still.to_vec(),
        },
    );
    let shift = |s: usize| if s >= id { s + 1 } else { s };
    for (k, s) in seg.segments.iter_mut().enumerate() {
        s.id = k;
    }
    for d in &mut seg.markers {
        d.segment = d.segment.map(shift);
    }
    for &m in still {
        if let Some(d) = seg.markers.get_mut(m) {
            d.segment = Some(id);
        }
    }
    for n in &mut seg.near_joints {
        n.segment = shift(n.segment);
    }
    for s in &mut seg.named_segments {
        *s = shift(*s);
    }
    seg.stationary_segment = Some(id);
}

#[cfg(test)]
mod tests {
    use mocap_io::Trajectories;

    use crate::Params;

    /// `traj` with `count` markers that never move appended (`FLOOR0`, ...): spread over
    /// 3.5 m of the room, each jittering by up to ±0.5 mm per axis (seeded), as a camera
    /// system sees a marker lying still.
    fn with_floor_markers(traj: &Trajectories, count: usize) -> Trajectories {
        let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut jitter = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let places: Vec<[f64; 3]> = (0..count)
            .map(|k| {
                [
                    1000.0 - 700.0 * k as f64,
                    -1000.0 + 500.0 * k as f64,
                    800.0 - 150.0 * k as f64,
                ]
            })
            .collect();
        let mut labels = traj.labels().to_vec();
        labels.extend((0..count).map(|k| format!("FLOOR{k}")));
        let mut positions = Vec::with_capacity(traj.frames() * labels.len());
        for f in 0..traj.frames() {
            positions.extend_from_slice(traj.frame(f));
            for p in &places {
                positions.push([p[0] + jitter(), p[1] + jitter(), p[2] + jitter()]);
            }
        }
        Trajectories::new(
            labels,
            traj.frame_rate(),
            traj.first_frame(),
            traj.frames(),
            positions,
        )
        .expect("as many samples as labels × frames")
    }

    /// A hard synthetic human beside one marker lying still, then six: the moving markers
    /// group exactly as without them; the six are one segment, `stationary_segment`, the
    /// one alone is unassigned as stationary. Without the setting aside, the one regroups
    /// the human's markers.
    #[test]
    fn markers_that_never_move_are_grouped_apart_from_the_rest() {
        let config = synth::SynthConfig {
            subject: synth::Subject::Human,
            preset: synth::Preset::Hard,
            seed: 20001,
            frames: 480,
            ..synth::SynthConfig::default()
        };
        let trial = synth::generate(&config).expect("synthetic trial");
        let traj = &trial.trajectories;
        let params = Params::default();
        let alone = crate::run(traj, &params).unwrap();
        assert_eq!(alone.stationary_segment, None);
        let n = traj.markers();

        let one = crate::run(&with_floor_markers(traj, 1), &params).unwrap();
        assert_eq!(one.segments, alone.segments);
        assert_eq!(one.stationary_segment, None);
        let reason = one
            .unassigned
            .iter()
            .find(|u| u.marker == n)
            .map(|u| &u.reason);
        assert!(
            reason.is_some_and(|r| r.starts_with("stationary")),
            "{reason:?}"
        );

        let six = crate::run(&with_floor_markers(traj, 6), &params).unwrap();
        let room = six.stationary_segment.expect("a segment of the six");
        assert_eq!(six.segments[room].markers, (n..n + 6).collect::<Vec<_>>());
        let moving: Vec<_> = six.segments.iter().filter(|s| s.id != room).collect();
        assert_eq!(moving.len(), alone.segments.len());
        for (a, b) in moving.iter().zip(&alone.segments) {
            assert_eq!(a.markers, b.markers);
        }
        assert!(six.markers[n..].iter().all(|d| d.segment == Some(room)));
        assert!(
            six.markers[n].rigidity_residual_mm < 2.0,
            "{}",
            six.markers[n].rigidity_residual_mm
        );

        // Set off, the one marker lying still regroups the moving ones.
        let off = Params {
            stationary_jitter_factor: 0.0,
            ..Params::default()
        };
        let mixed = crate::run(&with_floor_markers(traj, 1), &off).unwrap();
        assert_ne!(mixed.segments, alone.segments);
    }
}
