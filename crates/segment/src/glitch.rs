//! Glitches: samples where a marker leaves the distances it keeps to its steadiest partners.
//!
//! A marker reconstructed wrongly for a few frames (c3d.org Eb015: RSK1 leaves its shank
//! plate by up to 50 mm in frames 136–166 of 450) changes its distance to its plate-mates
//! all at once, and a standard deviation over all frames then calls the plate jointed
//! (ρ 8.6 mm against the plate's 0.5–1 mm). A joint moves a marker against the other
//! segment's markers, never against its own, and skin or noise moves it by about its usual
//! scatter. So a sample is a glitch when, in that frame, the marker is off its median
//! distance to most of its [`PARTNERS`] steadiest partners seen there (smallest robust
//! scatter: the 90th percentile of the distance's deviation from its median, in σ of
//! Gaussian scatter) by more than `factor` × that pair's scatter and at least `floor_mm`.
//! These statistics hold while a glitch lasts under a tenth of the frames. Segmentation
//! reads glitch samples as gaps, and so do the later stages (`Segmentation::glitches`,
//! applied by `Segmentation::repaired`).

use std::borrow::Cow;

use mocap_io::{MISSING, Trajectories};
use rayon::prelude::*;

use crate::segmentation::with_positions;

/// Steadiest partners each marker is checked against in a frame: the first this many of
/// its [`CANDIDATES`] steadiest that are seen in it.
pub(crate) const PARTNERS: usize = 3;

/// Steadiest partners a marker's judges are drawn from, so that gaps leave enough of them.
const CANDIDATES: usize = 6;

/// Most frames, evenly strided, whose distances give a pair's median and scatter.
const MAX_FRAMES: usize = 1024;

/// Share of a pair's frames its scatter covers: a pair's glitches may last this long, and a
/// joint that turns in more of the frames cannot make markers across it look steady
/// partners. A median absolute deviation lets a joint still in half the frames do that:
/// with it, AlbertoINT had 6068 samples of 19 markers masked (an epicondyle in 1027 of
/// 4921 frames) and its arm segments changed; with this, 25 samples of one marker.
const SCATTER_QUANTILE: f64 = 0.9;

/// The [`SCATTER_QUANTILE`] quantile of |Z| for a standard normal Z: scatter in units of σ.
const QUANTILE_TO_SIGMA: f64 = 1.0 / 1.644_853_626_951_472_2;

/// Median distance and robust scatter (mm, [`SCATTER_QUANTILE`]) of every marker pair over
/// the co-visible frames of a stride; `None` for pairs seen together in fewer than
/// `min_overlap` of those frames. Row-major `n × n`.
type PairMedians = Vec<Option<(f64, f64)>>;

/// `traj` with every glitch sample missing (borrowed unchanged when there is none), and
/// each marker's glitch frames, ascending. `factor` 0 turns the check off.
pub(crate) fn mask_glitches(
    traj: &Trajectories,
    min_overlap: usize,
    factor: f64,
    floor_mm: f64,
) -> (Cow<'_, Trajectories>, Vec<Vec<usize>>) {
    let (n, frames) = (traj.markers(), traj.frames());
    if factor <= 0.0 || n < 3 || frames == 0 {
        return (Cow::Borrowed(traj), vec![Vec::new(); n]);
    }
    let medians = pair_medians(traj, min_overlap);
    // The distance in frame f, where both are seen.
    let distance_in =
        |f: usize, i: usize, j: usize| Some(distance(traj.get(f, i)?, traj.get(f, j)?));
    let glitches: Vec<Vec<usize>> = (0..n)
        .into_par_iter()
        .map(|m| {
            let mut partners: Vec<(f64, usize, f64)> = (0..n)
                .filter(|&j| j != m)
                .filter_map(|j| medians[m * n + j].map(|(median, scatter)| (scatter, j, median)))
                .collect();
            partners.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            partners.truncate(CANDIDATES);
            if partners.len() < 2 {
                return Vec::new();
            }
            (0..frames)
                .filter(|&f| {
                    let (mut seen, mut off) = (0, 0);
                    for &(scatter, j, median) in &partners {
                        if let Some(d) = distance_in(f, m, j) {
                            seen += 1;
                            if (d - median).abs() > (factor * scatter).max(floor_mm) {
                                off += 1;
                            }
                            if seen == PARTNERS {
                                break;
                            }
                        }
                    }
                    // Two judges at least, and most of them off: one partner's own glitch
                    // never masks a marker.
                    seen >= 2 && 2 * off > seen
                })
                .collect()
        })
        .collect();
    if glitches.iter().all(Vec::is_empty) {
        return (Cow::Borrowed(traj), glitches);
    }
    let mut positions = traj.positions().to_vec();
    for (m, frames_off) in glitches.iter().enumerate() {
        for &f in frames_off {
            positions[f * n + m] = MISSING;
        }
    }
    (Cow::Owned(with_positions(traj, positions)), glitches)
}

/// Ascending frame indices as inclusive runs `[first, last]`.
pub(crate) fn runs(frames: &[usize]) -> Vec<[usize; 2]> {
    let mut out: Vec<[usize; 2]> = Vec::new();
    for &f in frames {
        match out.last_mut() {
            Some(run) if run[1] + 1 == f => run[1] = f,
            _ => out.push([f, f]),
        }
    }
    out
}

/// Every pair's median distance and robust scatter ([`PairMedians`]), rows in parallel.
fn pair_medians(traj: &Trajectories, min_overlap: usize) -> PairMedians {
    let (n, frames) = (traj.markers(), traj.frames());
    let stride = frames.div_ceil(MAX_FRAMES).max(1);
    let strided: Vec<usize> = (0..frames).step_by(stride).collect();
    // Marker-major copy of the strided samples: a pair's loop streams two short arrays.
    let samples: Vec<[f64; 3]> = (0..n)
        .flat_map(|m| strided.iter().map(move |&f| traj.frame(f)[m]))
        .collect();
    let track = |m: usize| &samples[m * strided.len()..(m + 1) * strided.len()];
    let rows: Vec<Vec<Option<(f64, f64)>>> = (0..n)
        .into_par_iter()
        .map(|i| {
            // One scratch buffer per row: the pair loop itself does not allocate.
            let mut scratch: Vec<f64> = Vec::with_capacity(strided.len());
            (i + 1..n)
                .map(|j| {
                    scratch.clear();
                    scratch.extend(track(i).iter().zip(track(j)).filter_map(|(a, b)| {
                        let d = distance(*a, *b);
                        // A missing sample is NaN, so its distance is NaN.
                        (!d.is_nan()).then_some(d)
                    }));
                    if scratch.len() < min_overlap.max(2) {
                        return None;
                    }
                    let median = median_in_place(&mut scratch);
                    for d in scratch.iter_mut() {
                        *d = (*d - median).abs();
                    }
                    let k = ((SCATTER_QUANTILE * scratch.len() as f64).ceil() as usize)
                        .clamp(1, scratch.len());
                    let q = *scratch.select_nth_unstable_by(k - 1, f64::total_cmp).1;
                    Some((median, QUANTILE_TO_SIGMA * q))
                })
                .collect()
        })
        .collect();
    let mut out = vec![None; n * n];
    for (i, row) in rows.into_iter().enumerate() {
        for (off, v) in row.into_iter().enumerate() {
            let j = i + 1 + off;
            out[i * n + j] = v;
            out[j * n + i] = v;
        }
    }
    out
}

/// Distance between two samples, mm (NaN when either is missing).
pub(crate) fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The upper median of `values` (reorders them).
fn median_in_place(values: &mut [f64]) -> f64 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four markers of one rigid plate translating, with marker 0 thrown `jump_mm` off for
    /// frames 40..60 of 200 (along the line from marker 1, so every distance changes).
    fn plate(jump_mm: f64) -> Trajectories {
        let shape = [
            [0.0, 0.0, 0.0],
            [100.0, 0.0, 0.0],
            [0.0, 80.0, 0.0],
            [60.0, 60.0, 30.0],
        ];
        let frames = 200;
        let mut positions = Vec::new();
        for f in 0..frames {
            let t = f as f64 * 0.05;
            for (m, p) in shape.iter().enumerate() {
                let wobble = 0.3 * ((m as f64 + 1.0) * 1.7 * t).sin();
                let mut q = [
                    p[0] + 40.0 * t.sin() + wobble,
                    p[1] + 10.0 * t,
                    p[2] - wobble,
                ];
                if m == 0 && (40..60).contains(&f) {
                    q[0] -= jump_mm;
                }
                positions.push(q);
            }
        }
        let labels = (0..4).map(|m| format!("P{m}")).collect();
        Trajectories::new(labels, 100.0, 1, frames, positions).expect("capture")
    }

    #[test]
    fn a_marker_thrown_off_its_plate_is_masked_in_those_frames_only() {
        let capture = plate(40.0);
        let (masked, frames) = mask_glitches(&capture, 10, 8.0, 2.0);
        assert!(matches!(masked, Cow::Owned(_)));
        assert_eq!(frames[0], (40..60).collect::<Vec<_>>());
        assert!(frames[1..].iter().all(Vec::is_empty));
        assert_eq!(runs(&frames[0]), vec![[40, 59]]);
        for f in 0..200 {
            assert_eq!(
                masked.get(f, 0).is_none(),
                (40..60).contains(&f),
                "frame {f}"
            );
        }
    }

    #[test]
    fn scatter_within_the_bounds_is_no_glitch_and_zero_factor_is_off() {
        // 1 mm is within the 2 mm floor, whatever the scatter.
        let capture = plate(1.0);
        let (unchanged, frames) = mask_glitches(&capture, 10, 8.0, 2.0);
        assert!(frames.iter().all(Vec::is_empty));
        // Nothing masked, nothing copied.
        assert!(matches!(unchanged, Cow::Borrowed(_)));
        let off = mask_glitches(&plate(40.0), 10, 0.0, 2.0).1;
        assert!(off.iter().all(Vec::is_empty));
    }

    #[test]
    fn frames_become_inclusive_runs() {
        assert_eq!(runs(&[]), Vec::<[usize; 2]>::new());
        assert_eq!(runs(&[3, 4, 5, 9, 11, 12]), vec![[3, 5], [9, 9], [11, 12]]);
    }
}
