//! The one in-memory representation of a capture's marker trajectories.

use serde::{Deserialize, Serialize};

use crate::bulk;
use crate::error::IoError;

/// Marker trajectories: labels, timing and positions in millimetres.
///
/// Representation (the only one in the project):
/// - `positions` holds `frames × markers` samples, frame-major: the sample of marker `m`
///   at 0-based frame index `f` is `positions[f * markers + m]`.
/// - Every coordinate is in millimetres, in the capture's own global frame (no axis swap).
/// - A missing sample is `[NaN, NaN, NaN]`; a present sample has three finite coordinates.
///   Readers turn every vendor's gap convention (negative residual, exact zeros, empty
///   TRC fields) into this before a `Trajectories` exists.
/// - `first_frame` is the file's own number for frame index 0 (C3D frames start at 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trajectories {
    labels: Vec<String>,
    frame_rate: f64,
    first_frame: i64,
    frames: usize,
    #[serde(with = "bulk::vec3s")]
    positions: Vec<[f64; 3]>,
}

/// The marker of this value stands for a missing sample.
pub const MISSING: [f64; 3] = [f64::NAN, f64::NAN, f64::NAN];

/// A coordinate this large (mm, i.e. 1000 km) is no measurement: vendors write such values
/// (SIMI's ±1e9) as gap fill, and squaring larger ones overflows the distance statistics.
/// Samples with a coordinate beyond it, or non-finite, are missing.
pub const ABSURD_MM: f64 = 1e9;

impl Trajectories {
    /// Builds trajectories, checking the invariants above; samples with a non-finite or
    /// absurd (beyond [`ABSURD_MM`]) coordinate become missing.
    pub fn new(
        labels: Vec<String>,
        frame_rate: f64,
        first_frame: i64,
        frames: usize,
        mut positions: Vec<[f64; 3]>,
    ) -> Result<Self, IoError> {
        let expected = frames.checked_mul(labels.len());
        if expected != Some(positions.len()) {
            return Err(IoError::Invalid(format!(
                "trajectories: {} samples for {} frames × {} markers",
                positions.len(),
                frames,
                labels.len()
            )));
        }
        if !(frame_rate.is_finite() && frame_rate >= 0.0) {
            return Err(IoError::Invalid(format!(
                "trajectories: frame rate {frame_rate} is not a finite non-negative number"
            )));
        }
        for p in &mut positions {
            if !p.iter().all(|c| c.abs() <= ABSURD_MM) {
                *p = MISSING;
            }
        }
        Ok(Self {
            labels,
            frame_rate,
            first_frame,
            frames,
            positions,
        })
    }

    /// Marker labels, in file order; the readers name a repeated label's later markers
    /// `LABEL#2`, `LABEL#3`… so each is unique.
    pub fn labels(&self) -> &[String] {
        &self.labels
    }
    /// Number of markers.
    pub fn markers(&self) -> usize {
        self.labels.len()
    }
    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.frames
    }
    /// Frames per second.
    pub fn frame_rate(&self) -> f64 {
        self.frame_rate
    }
    /// The file's number for frame index 0.
    pub fn first_frame(&self) -> i64 {
        self.first_frame
    }
    /// All samples, frame-major (see the type's docs); millimetres, NaN where missing.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.positions
    }
    /// The samples of one frame, one per marker.
    pub fn frame(&self, frame: usize) -> &[[f64; 3]] {
        let m = self.labels.len();
        &self.positions[frame * m..(frame + 1) * m]
    }
    /// These trajectories (labels, rate, first frame, frame count) with `positions`
    /// (frame-major) as their samples: an error when the count does not fit.
    pub fn with_positions(&self, positions: Vec<[f64; 3]>) -> Result<Self, IoError> {
        Self::new(
            self.labels.clone(),
            self.frame_rate,
            self.first_frame,
            self.frames,
            positions,
        )
    }
    /// One sample in millimetres, or `None` where it is missing.
    pub fn get(&self, frame: usize, marker: usize) -> Option<[f64; 3]> {
        let p = self.positions[frame * self.labels.len() + marker];
        is_present(p).then_some(p)
    }
    /// Number of missing samples over all frames and markers.
    pub fn missing_samples(&self) -> usize {
        self.positions.iter().filter(|p| !is_present(**p)).count()
    }
    /// Duration of the capture in seconds (0 when the rate is unknown).
    pub fn duration_seconds(&self) -> f64 {
        if self.frame_rate > 0.0 {
            self.frames as f64 / self.frame_rate
        } else {
            0.0
        }
    }

    /// How far apart the markers sit (mm): the median over markers of the median over up
    /// to [`SPACING_FRAMES`] evenly spread frames of the distance to the nearest other
    /// visible marker (coincident ones skipped); `None` when no frame shows two apart.
    pub fn marker_spacing_mm(&self) -> Option<f64> {
        let m = self.labels.len();
        if self.frames == 0 || m < 2 {
            return None;
        }
        let step = self.frames.div_ceil(SPACING_FRAMES).max(1);
        let mut nearest: Vec<Vec<f64>> = vec![Vec::new(); m];
        for f in (0..self.frames).step_by(step) {
            let row = self.frame(f);
            for (i, p) in row.iter().enumerate() {
                if !is_present(*p) {
                    continue;
                }
                let d = row
                    .iter()
                    .enumerate()
                    .filter(|&(j, q)| j != i && is_present(*q))
                    .map(|(_, q)| distance(*p, *q))
                    .filter(|&d| d > 0.0)
                    .fold(f64::INFINITY, f64::min);
                if d.is_finite() {
                    nearest[i].push(d);
                }
            }
        }
        let mut per_marker: Vec<f64> = nearest
            .iter_mut()
            .filter(|d| !d.is_empty())
            .map(|d| median(d))
            .collect();
        (!per_marker.is_empty()).then(|| median(&mut per_marker))
    }

    /// These trajectories over the frame indices `frames` only, with the markers `keep`
    /// (indices, in the order given); the first frame kept keeps its number.
    ///
    /// Panics when `frames` reaches past the last frame or a marker index is out of range
    /// (callers check both against what the file holds: [`crate::read_capture`]).
    pub fn select(&self, frames: std::ops::Range<usize>, keep: &[usize]) -> Trajectories {
        let m = self.labels.len();
        let mut positions = Vec::with_capacity(frames.len() * keep.len());
        for f in frames.clone() {
            let row = &self.positions[f * m..(f + 1) * m];
            positions.extend(keep.iter().map(|&k| row[k]));
        }
        Trajectories {
            labels: keep.iter().map(|&k| self.labels[k].clone()).collect(),
            frame_rate: self.frame_rate,
            first_frame: self.first_frame.saturating_add(frames.start as i64),
            frames: frames.len(),
            positions,
        }
    }

    /// These trajectories with the samples of each marker of `hidden` (index, first frame
    /// hidden) missing from that frame on, the labels and frames as they are: later steps
    /// see those markers as not seen there (from frame 0: never seen).
    ///
    /// Panics when a marker index is out of range (callers take them from these labels).
    pub fn hiding(&self, hidden: &[(usize, usize)]) -> Trajectories {
        let m = self.labels.len();
        let mut positions = self.positions.clone();
        for (f, row) in positions.chunks_mut(m.max(1)).enumerate() {
            for &(k, from) in hidden {
                if f >= from {
                    row[k] = MISSING;
                }
            }
        }
        Trajectories {
            labels: self.labels.clone(),
            frame_rate: self.frame_rate,
            first_frame: self.first_frame,
            frames: self.frames,
            positions,
        }
    }

    /// The factor (≤ 1) by which the stages shrink their millimetre floors and bounds for
    /// this capture: [`marker_spacing_mm`](Self::marker_spacing_mm) over
    /// [`FLOOR_SPACING_MM`], capped at 1 (and at least 1e-3): the floors were set for
    /// markers a few centimetres apart, and a mouse or a hand moves within them.
    pub fn floor_scale(&self) -> f64 {
        floor_scale_of(self.marker_spacing_mm())
    }
}

/// [`Trajectories::floor_scale`] from a spacing already measured (mm; `None`: 1).
pub fn floor_scale_of(spacing_mm: Option<f64>) -> f64 {
    spacing_mm.map_or(1.0, |s| (s / FLOOR_SPACING_MM).clamp(1e-3, 1.0))
}

/// The unit of a stage parameter that [`Trajectories::floor_scale`] scales, as the
/// stages' parameter docs print it (one text, so the docs agree with [`FLOOR_SPACING_MM`]).
#[macro_export]
macro_rules! floor_scaled_mm {
    () => {
        "mm × the capture's floor scale (median nearest-marker distance / 30 mm, at most 1)"
    };
}

/// Frames [`Trajectories::marker_spacing_mm`] looks at, at most.
pub const SPACING_FRAMES: usize = 64;

/// The marker spacing (mm) at and above which the stages' millimetre floors apply as
/// set; below it they shrink in proportion (see [`Trajectories::floor_scale`]). The
/// synthetic generator's subjects sit at 28-94 mm (48 seeds of each: only two hexapods
/// under it, at 28.4 and 29.7 mm, and their eval trials score as before), the shared real
/// captures at 36-321 mm but c3d.org's arthuman-sample (20 mm, labelled noise-free bodies).
pub const FLOOR_SPACING_MM: f64 = 30.0;

/// Euclidean distance between two points, mm.
pub(crate) fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Median of a non-empty slice (sorts it).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// True when a sample holds a position (not the missing marker).
#[inline]
pub fn is_present(p: [f64; 3]) -> bool {
    p[0].is_finite() && p[1].is_finite() && p[2].is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Markers on a line at 0, 10 and 40 mm, the middle one hidden in the second frame, a
    /// fourth on top of the last: nearest distances 10/40, 10, 30/40 (the coincident
    /// marker skipped), so the spacing is the median of 25, 10, 35 and 35 (the fourth's).
    #[test]
    fn marker_spacing_is_the_median_nearest_distance_over_frames() {
        let labels: Vec<String> = ["A", "B", "C", "D"].map(String::from).to_vec();
        let frame = |b: [f64; 3]| [[0.0, 0.0, 0.0], b, [40.0, 0.0, 0.0], [40.0, 0.0, 0.0]];
        let positions: Vec<[f64; 3]> = frame([10.0, 0.0, 0.0])
            .into_iter()
            .chain(frame(MISSING))
            .collect();
        let traj = Trajectories::new(labels, 100.0, 1, 2, positions).unwrap();
        assert_eq!(traj.marker_spacing_mm(), Some(30.0));
        assert_eq!(traj.floor_scale(), 1.0);
        // Ten times smaller: the floors shrink to a tenth.
        let small = Trajectories::new(
            traj.labels().to_vec(),
            100.0,
            1,
            2,
            traj.positions()
                .iter()
                .map(|p| p.map(|c| 0.1 * c))
                .collect(),
        )
        .unwrap();
        assert!((small.floor_scale() - 0.1).abs() < 1e-12);
        // One marker: no spacing, floors as set.
        let one = Trajectories::new(vec!["A".into()], 100.0, 1, 1, vec![[1.0, 2.0, 3.0]]).unwrap();
        assert_eq!(one.marker_spacing_mm(), None);
        assert_eq!(one.floor_scale(), 1.0);
    }

    /// The parameter docs' unit names the spacing the floors are set for.
    #[test]
    fn the_floor_scale_unit_names_the_floor_spacing() {
        assert!(floor_scaled_mm!().contains(&format!("/ {FLOOR_SPACING_MM} mm")));
    }

    #[test]
    fn absurd_and_partial_samples_are_missing() {
        let t = Trajectories::new(
            vec!["A".into()],
            100.0,
            1,
            4,
            vec![
                [1.0, 2.0, 3.0],
                [1e308, 0.0, 0.0],
                [-2e9, 0.0, 0.0],
                [f64::NAN, 1.0, 1.0],
            ],
        )
        .unwrap();
        assert_eq!(t.get(0, 0), Some([1.0, 2.0, 3.0]));
        assert_eq!(t.missing_samples(), 3);
    }

    #[test]
    fn inconsistent_shapes_are_errors() {
        assert!(Trajectories::new(vec!["A".into()], 100.0, 1, 2, vec![[0.0; 3]]).is_err());
        assert!(Trajectories::new(vec![], f64::NAN, 1, 0, vec![]).is_err());
    }
}
