//! Horn's closed-form absolute orientation with unit quaternions (J. Opt. Soc. Am. A 4(4), 1987).
//!
//! The rotation best mapping centred reference points onto centred observed points is the
//! eigenvector of the largest eigenvalue of a symmetric 4×4 matrix built from their
//! cross-covariance. Allocation-free: this runs once per segment and frame.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::{DQuat, DVec3, DVec4};

/// A rigid motion `observed ≈ rotation * reference + translation`, with its fit quality.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidFit {
    /// Unit quaternion, reference (local) frame → observed (global) frame.
    pub rotation: DQuat,
    /// Translation (mm), in the observed frame.
    pub translation: DVec3,
    /// RMS distance between observed points and the moved reference points (mm).
    pub rms_mm: f64,
}

/// Chordal mean of unit quaternions (each sign aligned with the first's, summed,
/// normalized): the mean rotation of rotations within a half turn of each other. `None`
/// when empty.
pub fn chordal_mean(rotations: &[DQuat]) -> Option<DQuat> {
    let first = DVec4::from(*rotations.first()?);
    let mut sum = DVec4::ZERO;
    for &q in rotations {
        let v = DVec4::from(q);
        sum += if v.dot(first) < 0.0 { -v } else { v };
    }
    // Every term is within a right angle of the first, so the sum is never zero.
    Some(DQuat::from_vec4(sum).normalize())
}

/// Least-squares rigid motion mapping `pairs[i].0` (reference) onto `pairs[i].1` (observed).
///
/// `None` with fewer than 3 pairs or non-finite input. Collinear points give *a* rotation
/// (the spin about their line is arbitrary); callers that care check the spread first.
pub fn absolute_orientation(pairs: &[(DVec3, DVec3)]) -> Option<RigidFit> {
    if pairs.len() < 3 {
        return None;
    }
    let n = pairs.len() as f64;
    let (sum_r, sum_o) = pairs
        .iter()
        .fold((DVec3::ZERO, DVec3::ZERO), |(a, b), (r, o)| {
            (a + *r, b + *o)
        });
    let (cr, co) = (sum_r / n, sum_o / n);
    if !(cr.is_finite() && co.is_finite()) {
        return None;
    }
    // Cross-covariance s[a][b] = Σ r'_a o'_b.
    let mut s = [[0.0f64; 3]; 3];
    for (r, o) in pairs {
        let r = (*r - cr).to_array();
        let o = (*o - co).to_array();
        for a in 0..3 {
            for b in 0..3 {
                s[a][b] += r[a] * o[b];
            }
        }
    }
    let mut rotation = rotation_from_cross_covariance(s)?;
    // One sign per rotation keeps stored quaternions comparable across frames.
    if rotation.w < 0.0 {
        rotation = -rotation;
    }
    let translation = co - rotation * cr;
    let sq: f64 = pairs
        .iter()
        .map(|(r, o)| (rotation * *r + translation - *o).length_squared())
        .sum();
    Some(RigidFit {
        rotation,
        translation,
        rms_mm: (sq / n).sqrt(),
    })
}

/// The rotation `R` maximising `Σ observed · (R reference)` given the cross-covariance
/// `s[a][b] = Σ reference_a · observed_b` of centred (or fixed-point) vector pairs: the
/// eigenvector of the largest eigenvalue of Horn's symmetric 4×4 matrix.
///
/// `None` when the matrix is not finite. The sign of the quaternion is arbitrary.
pub fn rotation_from_cross_covariance(s: [[f64; 3]; 3]) -> Option<DQuat> {
    let m = segment::eigen4::horn_matrix(s);
    if !m.iter().flatten().all(|x| x.is_finite()) {
        return None;
    }
    let (_, [w, x, y, z]) = segment::eigen4::largest_eigenpair4(m);
    let q = DQuat::from_xyzw(x, y, z, w);
    let len = q.length();
    (len.is_finite() && len > 1e-12).then(|| q / len)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// SplitMix64: a tiny seeded generator so the tests need no RNG dependency.
    pub(crate) struct TestRng(pub u64);
    impl TestRng {
        pub(crate) fn next_f64(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }
        /// Uniform in [-1, 1).
        pub(crate) fn sym(&mut self) -> f64 {
            2.0 * self.next_f64() - 1.0
        }
        /// Standard normal (Box–Muller).
        pub(crate) fn gauss(&mut self) -> f64 {
            let u = self.next_f64().max(1e-300);
            let v = self.next_f64();
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
        pub(crate) fn vec3(&mut self, scale: f64) -> DVec3 {
            DVec3::new(self.sym(), self.sym(), self.sym()) * scale
        }
        /// A uniformly random rotation (normalised Gaussian quaternion).
        pub(crate) fn rotation(&mut self) -> DQuat {
            DQuat::from_xyzw(self.gauss(), self.gauss(), self.gauss(), self.gauss()).normalize()
        }
    }

    #[test]
    fn recovers_random_rotations_exactly() {
        let mut rng = TestRng(7);
        for trial in 0..500 {
            let n = 3 + trial % 6;
            let q = rng.rotation();
            let t = rng.vec3(1000.0);
            let mut pairs = Vec::new();
            for _ in 0..n {
                let r = rng.vec3(150.0);
                pairs.push((r, q * r + t));
            }
            let fit = absolute_orientation(&pairs).unwrap();
            let q = if q.w < 0.0 { -q } else { q };
            let dq = (fit.rotation - q).length();
            assert!(dq < 1e-9, "trial {trial}: quaternion off by {dq}");
            assert!((fit.translation - t).length() < 1e-9);
            assert!(fit.rms_mm < 1e-9);
        }
    }

    #[test]
    fn rotation_by_pi_and_identity() {
        let pts = [
            DVec3::new(100.0, 0.0, 0.0),
            DVec3::new(0.0, 50.0, 0.0),
            DVec3::new(0.0, 0.0, 70.0),
            DVec3::new(20.0, -30.0, 10.0),
        ];
        for q in [
            DQuat::IDENTITY,
            DQuat::from_axis_angle(DVec3::X, std::f64::consts::PI),
            DQuat::from_axis_angle(DVec3::new(1.0, 1.0, 0.0).normalize(), std::f64::consts::PI),
        ] {
            let pairs: Vec<_> = pts.iter().map(|p| (*p, q * *p)).collect();
            let fit = absolute_orientation(&pairs).unwrap();
            let angle = (fit.rotation.inverse() * q)
                .normalize()
                .angle_between(DQuat::IDENTITY);
            assert!(angle.abs() < 1e-9 || (angle - std::f64::consts::TAU).abs() < 1e-9);
            assert!(fit.rms_mm < 1e-9);
        }
    }

    #[test]
    fn noisy_fit_reports_rms_and_rejects_too_few() {
        let mut rng = TestRng(3);
        let q = rng.rotation();
        let pairs: Vec<_> = (0..6)
            .map(|_| {
                let r = rng.vec3(100.0);
                (r, q * r + rng.vec3(1.0))
            })
            .collect();
        let fit = absolute_orientation(&pairs).unwrap();
        assert!(fit.rms_mm > 0.1 && fit.rms_mm < 1.0, "{}", fit.rms_mm);
        assert!(absolute_orientation(&pairs[..2]).is_none());
    }

    /// Rotations spread symmetrically about one, some written with the opposite sign
    /// (the same rotation), average to it; an empty list has no mean.
    #[test]
    fn chordal_mean_ignores_quaternion_signs() {
        let centre = DQuat::from_scaled_axis(DVec3::new(0.3, -0.2, 0.5));
        let spread =
            [0.2, -0.2, 0.1, -0.1].map(|t| DQuat::from_scaled_axis(DVec3::new(t, 0.0, 0.0)));
        let rotations: Vec<DQuat> = spread
            .iter()
            .enumerate()
            .map(|(i, &d)| {
                if i % 2 == 0 {
                    centre * d
                } else {
                    -(centre * d)
                }
            })
            .collect();
        let mean = chordal_mean(&rotations).expect("non-empty");
        assert!(mean.dot(centre).abs() > 1.0 - 1e-12, "{mean:?}");
        assert!(chordal_mean(&[]).is_none());
    }
}
