//! markers.trc: the capture's markers gap-filled from their segments' poses. Stretches of
//! markers the capture has are hidden, the pipeline runs on the rest, and the fill is
//! held against the hidden samples and against what a straight line across each gap
//! (the capture software's plainest fill) would have put there.

use std::path::Path;

use mocap_io::Trajectories;

use crate::support::Scratch;

/// Every `every`-th marker hidden for `length` frames where the capture has it, the k-th
/// of them from frame `first + k × stride` (occlusions come one marker at a time more
/// often than all at once): the capture with those samples missing, and the hidden
/// samples as (frame, marker, position).
fn hide(
    traj: &Trajectories,
    every: usize,
    (first, length, stride): (usize, usize, usize),
) -> (Trajectories, Vec<(usize, usize, [f64; 3])>) {
    let markers = traj.markers();
    let mut positions = traj.positions().to_vec();
    let mut hidden = Vec::new();
    for (k, m) in (0..markers).step_by(every).enumerate() {
        let start = first + k * stride;
        for f in start..(start + length).min(traj.frames()) {
            if let Some(p) = traj.get(f, m) {
                hidden.push((f, m, p));
                positions[f * markers + m] = mocap_io::MISSING;
            }
        }
    }
    (traj.with_positions(positions).unwrap(), hidden)
}

/// The straight line across the gap holding `frame` in `marker`'s track of `cut`, from
/// the last sample before to the first after; `None` at an open end.
fn linear(cut: &Trajectories, marker: usize, frame: usize) -> Option<[f64; 3]> {
    let before = (0..frame)
        .rev()
        .find_map(|f| cut.get(f, marker).map(|p| (f, p)))?;
    let after = (frame + 1..cut.frames()).find_map(|f| cut.get(f, marker).map(|p| (f, p)))?;
    let w = (frame - before.0) as f64 / (after.0 - before.0) as f64;
    Some(std::array::from_fn(|i| {
        before.1[i] + w * (after.1[i] - before.1[i])
    }))
}

/// How the fill did: samples hidden, samples filled (where a straight line can be drawn
/// too), and the RMS errors (mm) of the fill and of the straight line over those samples.
struct FillScore {
    hidden: usize,
    filled: usize,
    rms_mm: f64,
    linear_rms_mm: f64,
}

impl FillScore {
    /// Prints the score for `what` and asserts that ≥ 90 % of the hidden samples were
    /// filled, within `max_rms_mm` RMS and `times` closer than the straight line.
    fn check(&self, what: &str, max_rms_mm: f64, times: f64) {
        eprintln!(
            "{what} fill: {} of {} hidden samples filled, RMS {:.2} mm; straight line {:.2} mm",
            self.filled, self.hidden, self.rms_mm, self.linear_rms_mm
        );
        assert!(
            self.filled * 10 >= self.hidden * 9,
            "{} of {}",
            self.filled,
            self.hidden
        );
        assert!(self.rms_mm < max_rms_mm, "fill RMS {:.2} mm", self.rms_mm);
        assert!(
            self.rms_mm * times < self.linear_rms_mm,
            "{:.2} against {:.2}",
            self.rms_mm,
            self.linear_rms_mm
        );
    }
}

/// Runs the pipeline on `cut` (written as C3D into `tmp`) and scores markers.trc's fill
/// of `hidden`; markers.trc must keep every sample `cut` has, as it has it (neither
/// capture here has a glitch, whose samples the pipeline reads as gaps).
fn score_fill(tmp: &Scratch, cut: &Trajectories, hidden: &[(usize, usize, [f64; 3])]) -> FillScore {
    let input = tmp.path("hidden.c3d");
    mocap_io::write_c3d(&input, cut).unwrap();
    let out = tmp.run(&input);
    let filled = read(&out.join("markers.trc"));
    assert_eq!(filled.labels(), cut.labels());
    assert_eq!(filled.frames(), cut.frames());
    for f in 0..cut.frames() {
        for m in 0..cut.markers() {
            if let Some(p) = cut.get(f, m) {
                let q = filled.get(f, m).unwrap();
                let d = (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt();
                // TRC holds 0.001 mm; the C3D input held floats.
                assert!(d < 2e-3, "frame {f} marker {m} moved {d} mm");
            }
        }
    }
    let (mut count, mut sum, mut sum_linear) = (0, 0.0, 0.0);
    for &(f, m, truth) in hidden {
        let (Some(q), Some(l)) = (filled.get(f, m), linear(cut, m, f)) else {
            continue;
        };
        count += 1;
        sum += (0..3).map(|i| (q[i] - truth[i]).powi(2)).sum::<f64>();
        sum_linear += (0..3).map(|i| (l[i] - truth[i]).powi(2)).sum::<f64>();
    }
    let rms = |s: f64| (s / count.max(1) as f64).sqrt();
    FillScore {
        hidden: hidden.len(),
        filled: count,
        rms_mm: rms(sum),
        linear_rms_mm: rms(sum_linear),
    }
}

fn read(path: &Path) -> Trajectories {
    mocap_io::read_capture(path, &mocap_io::ReadOptions::default())
        .unwrap()
        .trajectories
}

/// A synthetic human under skin and noise, every fifth marker hidden for half a second
/// (staggered): the fill lands within a few millimetres of the hidden samples (the skin the
/// rigid pose cannot see), many times closer than a straight line across the gap. Measured:
/// 996 of 1009 filled, RMS 5.27 mm against the straight line's 105.55 mm.
#[test]
fn a_synthetic_capture_s_hidden_stretches_are_filled_near_the_truth() {
    let trial = synth::generate(&synth::SynthConfig {
        subject: synth::Subject::Human,
        preset: synth::Preset::Hard,
        frames: 480,
        seed: 20002,
        ..synth::SynthConfig::default()
    })
    .unwrap();
    let (cut, hidden) = hide(&trial.trajectories, 5, (40, 60, 20));
    let tmp = Scratch::new("fill-synthetic");
    score_fill(&tmp, &cut, &hidden).check("synthetic", 10.0, 5.0);
}

/// CMU 02_01 (a walk): every fifth marker hidden for half a second (staggered), the fill
/// held to the samples the walk has there. A real body is less rigid than the generator's
/// (the forearm twists the wrist markers about the elbow's), and with those gaps RSHN
/// segments with the right thigh: measured 540 of 540 filled, RMS 18.34 mm against the
/// straight line's 128.79 mm.
#[test]
fn a_real_walk_s_hidden_stretches_are_filled_near_the_samples() {
    let Some(data) = mocap_io::testdata::shared_data_dir("fill_cmu_02_01") else {
        return;
    };
    let walk = read(&data.join("c3d/cmu/02_01.c3d"));
    let (cut, hidden) = hide(&walk, 5, (40, 60, 20));
    let tmp = Scratch::new("fill-real");
    score_fill(&tmp, &cut, &hidden).check("CMU 02_01", 25.0, 3.0);
}
