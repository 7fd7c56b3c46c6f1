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
//! frames. Only where the capture moves ([`MOTION_RATIO`]): a static trial is left whole.
//!
//! A marker that stops moving for good while its steadiest partner goes on (it fell off,
//! or the tracker kept a reflection where it lost it: [`fallen_markers`]) is read as a
//! gap from there on, a glitch that lasts, before anything else too: CMU 02_01's RFIN left
//! on the floor from frame 200 of 343 regrouped five of its segments.

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
struct Wander {
    /// RMS distance of its positions from their mean.
    spread_mm: f64,
    /// RMS length of its steps between consecutive frames both seen.
    step_mm: f64,
}

/// How far marker `m` wanders, over the frames it is seen in; `None` with fewer than
/// `needed` frames seen or [`MIN_STEPS`] steps.
fn wander(traj: &Trajectories, m: usize, needed: usize) -> Option<Wander> {
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
    let needed = crate::visible_frames_needed(params, traj.frames());
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

/// Markers that stop moving for good while their steadiest partner goes on: one fell off
/// and lies where it fell, or the tracker kept a reflection where it lost it. For each,
/// the first frame of its last still stretch (see [`still_since`]), where its steadiest
/// partner before that frame wanders [`MOTION_RATIO`] times as far as it does over the
/// stretch's frames where both are seen (at least as many as a marker needs); a marker
/// still with its partner (a foot planted to the end, a subject who stops) is none.
/// Ascending by marker; none of `named`.
pub(crate) fn fallen_markers(
    traj: &Trajectories,
    params: &Params,
    named: &[Vec<usize>],
) -> Vec<(usize, usize)> {
    if params.stationary_jitter_factor <= 0.0 {
        return Vec::new();
    }
    let needed = crate::visible_frames_needed(params, traj.frames()).max(MIN_STEPS + 1);
    let mut out = Vec::new();
    for m in (0..traj.markers()).filter(|m| !named.iter().flatten().any(|n| n == m)) {
        let Some(from) = still_since(traj, m, needed, params.stationary_jitter_factor) else {
            continue;
        };
        let Some(partner) = steadiest_before(traj, m, from, needed, params.min_overlap_frames)
        else {
            continue;
        };
        // Over the frames both are seen: a marker seen briefly after a long gap is no
        // measure of how far its partner went meanwhile.
        let both: Vec<usize> = (from..traj.frames())
            .filter(|&f| is_present(traj.frame(f)[m]) && is_present(traj.frame(f)[partner]))
            .collect();
        if both.len() < needed {
            continue;
        }
        let (own, other) = (spread(traj, m, &both), spread(traj, partner, &both));
        if other > MOTION_RATIO * own.max(EXACT_MM) {
            out.push((m, from));
        }
    }
    out
}

/// The first frame of marker `m`'s last still stretch: from there to its last frame seen
/// (at least `needed` frames seen), its positions' RMS distance from their mean is within
/// `factor` times the median length of its last `needed` steps between frames (the
/// median: the one step where it fell is no jitter). Only where it was seen in at least
/// `needed` frames before; `None` without such a stretch or where it is still throughout.
fn still_since(traj: &Trajectories, m: usize, needed: usize, factor: f64) -> Option<usize> {
    let seen: Vec<(usize, [f64; 3])> = (0..traj.frames())
        .filter_map(|f| {
            let p = traj.frame(f)[m];
            is_present(p).then_some((f, p))
        })
        .collect();
    let tail = &seen[seen.len().saturating_sub(needed)..];
    let mut steps: Vec<f64> = tail
        .windows(2)
        .filter(|w| w[1].0 == w[0].0 + 1)
        .map(|w| {
            (0..3)
                .map(|k| (w[1].1[k] - w[0].1[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    if seen.len() < 2 * needed || steps.len() < MIN_STEPS {
        return None;
    }
    steps.sort_by(f64::total_cmp);
    let jitter = steps[steps.len() / 2];
    let (mut count, mut sum, mut sum_sq) = (0usize, [0.0f64; 3], 0.0f64);
    let mut start = None;
    for i in (0..seen.len()).rev() {
        count += 1;
        for (s, x) in sum.iter_mut().zip(seen[i].1) {
            *s += x;
            sum_sq += x * x;
        }
        if count < needed {
            continue;
        }
        let mean_sq: f64 = sum.iter().map(|s| (s / count as f64).powi(2)).sum();
        let spread = (sum_sq / count as f64 - mean_sq).max(0.0).sqrt();
        if spread <= factor * jitter + EXACT_MM {
            start = Some(i);
        } else {
            break;
        }
    }
    let i = start?;
    (i >= needed).then(|| seen[i].0)
}

/// The marker whose distance to `m` varies least (standard deviation) over the frames
/// before `until` where both are seen, at least `min_overlap` and `needed` of them.
fn steadiest_before(
    traj: &Trajectories,
    m: usize,
    until: usize,
    needed: usize,
    min_overlap: usize,
) -> Option<usize> {
    let mut best: Option<(f64, usize)> = None;
    for k in (0..traj.markers()).filter(|&k| k != m) {
        let (mut n, mut sum, mut sum_sq) = (0usize, 0.0f64, 0.0f64);
        for f in 0..until {
            let (p, q) = (traj.frame(f)[m], traj.frame(f)[k]);
            if is_present(p) && is_present(q) {
                let d = (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt();
                (n, sum, sum_sq) = (n + 1, sum + d, sum_sq + d * d);
            }
        }
        if n < min_overlap.max(needed) {
            continue;
        }
        let mean = sum / n as f64;
        let sd = (sum_sq / n as f64 - mean * mean).max(0.0).sqrt();
        if best.is_none_or(|(b, _)| sd < b) {
            best = Some((sd, k));
        }
    }
    best.map(|(_, k)| k)
}

/// The RMS distance (mm) of marker `m`'s positions in `frames` (each seen) from their mean.
fn spread(traj: &Trajectories, m: usize, frames: &[usize]) -> f64 {
    let points: Vec<[f64; 3]> = frames.iter().map(|&f| traj.frame(f)[m]).collect();
    let n = points.len().max(1) as f64;
    let mean = [0, 1, 2].map(|k| points.iter().map(|p| p[k]).sum::<f64>() / n);
    let sum: f64 = points
        .iter()
        .map(|p| (0..3).map(|k| (p[k] - mean[k]).powi(2)).sum::<f64>())
        .sum();
    (sum / n).sqrt()
}

/// The capture moves where the median marker that is not stationary wanders more than
/// this many times as far as the stationary one that wanders most: on c3d.org's static
/// trial (sample 33) the markers beyond their jitter wander less than that one (RMS 0.28
/// mm, median, against 1.1), on OpenSim's treadmill walk (subject01_walk1) 100 times as
/// far as a floor marker's 0.9, on CMU 02_01's walk 1000 times (a one-off script).
const MOTION_RATIO: f64 = 20.0;

/// Records the `fallen` markers' still stretches (marker, first frame), which `seg` was
/// found without, as glitches: samples read as gaps, here and by the later stages
/// ([`Segmentation::repaired`]), and counted among the marker's visible frames.
pub(crate) fn put_back_fallen(
    seg: &mut Segmentation,
    traj: &Trajectories,
    fallen: &[(usize, usize)],
) {
    for &(m, from) in fallen {
        let frames: Vec<usize> = (from..traj.frames())
            .filter(|&f| is_present(traj.frame(f)[m]))
            .collect();
        if let Some(d) = seg.markers.get_mut(m) {
            d.visible_frames += frames.len();
            d.glitch_frames += frames.len();
        }
        match seg.glitches.iter_mut().find(|g| g.marker == m) {
            Some(g) => g.frames.extend(crate::glitch::runs(&frames)),
            None => seg.glitches.push(crate::Glitch {
                marker: m,
                frames: crate::glitch::runs(&frames),
            }),
        }
    }
    seg.glitches.sort_by_key(|g| g.marker);
}

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
    for s in seg.bodies.iter_mut().flatten() {
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

    /// A hard synthetic human as `cargo xtask eval` makes it (seed 20001, 480 frames).
    fn hard_human() -> synth::Trial {
        let config = synth::SynthConfig {
            subject: synth::Subject::Human,
            preset: synth::Preset::Hard,
            seed: 20001,
            frames: 480,
            ..synth::SynthConfig::default()
        };
        synth::generate(&config).expect("synthetic trial")
    }

    /// A hard synthetic human beside one marker lying still, then six: the moving markers
    /// group exactly as without them; the six are one segment, `stationary_segment`, the
    /// one alone is unassigned as stationary. Without the setting aside, the one regroups
    /// the human's markers.
    #[test]
    fn markers_that_never_move_are_grouped_apart_from_the_rest() {
        let trial = hard_human();
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

    /// `traj` with marker `m` lying still from frame `from` on where it was then, but on
    /// the floor (z 8 mm), jittering by up to ±0.3 mm per axis (seeded): it fell off.
    fn fallen_at(traj: &Trajectories, m: usize, from: usize) -> Trajectories {
        let mut state: u64 = 11;
        let mut jitter = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            0.6 * (((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5)
        };
        let n = traj.markers();
        let at = traj.frame(from)[m];
        let mut positions = traj.positions().to_vec();
        for f in from..traj.frames() {
            positions[f * n + m] = [at[0] + jitter(), at[1] + jitter(), 8.0 + jitter()];
        }
        traj.with_positions(positions)
            .expect("as many samples as before")
    }

    /// A hard synthetic human whose marker 0 falls off at frame 300 of 480: its samples
    /// from there on are glitches, and the markers group as without the fall (marker 0 in
    /// its segment); the whole subject holding still from frame 300 makes no marker fallen.
    #[test]
    fn a_marker_that_falls_off_is_a_gap_from_there_on() {
        let trial = hard_human();
        let traj = &trial.trajectories;
        let params = Params::default();
        let alone = crate::run(traj, &params).unwrap();
        let fell = fallen_at(traj, 0, 300);
        assert_eq!(super::fallen_markers(&fell, &params, &[]), vec![(0, 300)]);
        let seg = crate::run(&fell, &params).unwrap();
        assert_eq!(seg.segments, alone.segments);
        let glitch = seg
            .glitches
            .iter()
            .find(|g| g.marker == 0)
            .expect("a glitch");
        assert_eq!(glitch.frames.last(), Some(&[300, 479]));

        // Everyone holding still from frame 300 on: each marker's partner holds still too.
        let n = traj.markers();
        let mut positions = traj.positions().to_vec();
        for f in 300..traj.frames() {
            for m in 0..n {
                positions[f * n + m] = positions[299 * n + m];
            }
        }
        let frozen = traj.with_positions(positions).unwrap();
        assert!(super::fallen_markers(&frozen, &params, &[]).is_empty());
    }
}
