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

    /// Marker labels, in file order.
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
}

/// True when a sample holds a position (not the missing marker).
#[inline]
pub fn is_present(p: [f64; 3]) -> bool {
    p[0].is_finite() && p[1].is_finite() && p[2].is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

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
