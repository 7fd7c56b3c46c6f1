//! How two segments rotate relative to each other: range of motion and joint kind.
//!
//! With `S` = the mean over frames of the relative rotation `R_aᵀ R_b` (b-local → a-local),
//! the SCoRE normal matrix is `[[I, −S], [−Sᵀ, I]]` and its eigenvalues are `1 ± σᵢ(S)`.
//! A direction whose singular value is 1 never moves between the two frames: that is a
//! hinge axis (SARA, Ehrig et al. 2007), and three of them mean no relative motion. We
//! report each singular direction's wobble `sqrt(2 (1 − σᵢ))` in degrees, which is
//! approximately the RMS angle by which that direction tilts over the capture.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::{DMat3, DVec3};

use crate::pairfits::JointKind;
use crate::params::Params;
use crate::poses::Pose;
use crate::small::sym_eigen;

/// Relative rotation statistics of a pair over the frames where both have a pose.
#[derive(Clone, Debug)]
pub(crate) struct RelativeMotion {
    /// Wobble of the three singular directions (degrees), ascending.
    pub wobble_deg: [f64; 3],
    /// The least-wobbling direction in a's frame (unit; the hinge axis for hinges).
    pub axis_in_a: DVec3,
    /// The same direction in b's frame (unit).
    pub axis_in_b: DVec3,
    /// RMS angle of the relative rotation from its mean (degrees).
    pub rms_deg: f64,
    /// Largest angle of the relative rotation from its mean (degrees).
    pub max_deg: f64,
}

/// Statistics over `frames` (indices where both poses exist; must be non-empty).
pub(crate) fn relative_motion(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
) -> RelativeMotion {
    let mut s = DMat3::ZERO;
    for &f in frames {
        if let (Some(a), Some(b)) = (&pa[f], &pb[f]) {
            s += a.rot.transpose() * b.rot;
        }
    }
    let s = s * (1.0 / frames.len().max(1) as f64);
    let sts = s.transpose() * s;
    let m = [
        sts.x_axis.to_array(),
        sts.y_axis.to_array(),
        sts.z_axis.to_array(),
    ];
    let (_, vecs) = sym_eigen(m);
    let v0 = DVec3::from_array(vecs[0]).normalize();
    let v1 = DVec3::from_array(vecs[1]).normalize();
    let v2 = v0.cross(v1);
    let u0 = (s * v0).try_normalize().unwrap_or(DVec3::X);
    let u1 = (s * v1 - (s * v1).dot(u0) * u0)
        .try_normalize()
        .unwrap_or(u0.any_orthonormal_vector());
    let u2 = u0.cross(u1);
    // Signed singular values: proper rotations U and V put any reflection into σ₂'s sign.
    let sigma = [u0.dot(s * v0), u1.dot(s * v1), u2.dot(s * v2)];
    let wobble = sigma.map(|sg| (2.0 * (1.0 - sg).max(0.0)).sqrt().to_degrees());
    let mean_rotation = DMat3::from_cols(u0, u1, u2) * DMat3::from_cols(v0, v1, v2).transpose();
    let (mut sq, mut max) = (0.0f64, 0.0f64);
    for &f in frames {
        if let (Some(a), Some(b)) = (&pa[f], &pb[f]) {
            let d = mean_rotation.transpose() * a.rot.transpose() * b.rot;
            let cos = ((d.x_axis.x + d.y_axis.y + d.z_axis.z - 1.0) / 2.0).clamp(-1.0, 1.0);
            let angle = cos.acos().to_degrees();
            sq += angle * angle;
            max = max.max(angle);
        }
    }
    RelativeMotion {
        wobble_deg: wobble,
        axis_in_a: u0,
        axis_in_b: v0,
        rms_deg: (sq / frames.len().max(1) as f64).sqrt(),
        max_deg: max,
    }
}

impl RelativeMotion {
    /// Joint kind from the motion, and the evidence in words.
    pub fn classify(&self, params: &Params, frames: usize) -> (JointKind, String) {
        let [w0, w1, w2] = self.wobble_deg;
        let ratio = if w1 > 0.0 { w0 / w1 } else { 1.0 };
        let kind = if self.rms_deg < params.rigid_deg {
            JointKind::Rigid
        } else if ratio < params.hinge_ratio {
            JointKind::Hinge
        } else {
            JointKind::Ball
        };
        let why = match kind {
            JointKind::Rigid => format!("RMS relative rotation < rigid_deg {}°", params.rigid_deg),
            JointKind::Hinge => format!("wobble ratio < hinge_ratio {}", params.hinge_ratio),
            _ => format!("wobble ratio ≥ hinge_ratio {}", params.hinge_ratio),
        };
        let evidence = format!(
            "{why}; relative rotation {:.1}° RMS, {:.1}° max over {frames} frames; \
             direction wobble {w0:.2}°/{w1:.2}°/{w2:.2}° (ratio {ratio:.3})",
            self.rms_deg, self.max_deg
        );
        (kind, evidence)
    }
}
