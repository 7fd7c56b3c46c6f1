//! Weighted rotation about a fixed point (Horn's quaternion method without the
//! translation), with a prior rotation: weak, settling only what the observations leave
//! free, or of a given weight.
//!
//! Allocation-free: this runs once per segment and frame.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::{DMat3, DQuat, DVec3};

/// Weighted pairs (local vector, observed vector) for one rotation, accumulated in place.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RotationFit {
    /// Cross-covariance `s[a][b] = Σ w · local_a · observed_b`.
    s: [[f64; 3]; 3],
    /// Σ w |local| |observed|: the scale the prior's weight is measured against.
    scale: f64,
}

/// Relative weight of the prior rotation: small enough that it never moves what the
/// observations determine (~1e-8 of their weight), large enough that the 4×4 eigenproblem
/// still resolves the spin they leave free (Jacobi reaches ~1e-16 relative).
const PRIOR_WEIGHT: f64 = 1e-8;

impl RotationFit {
    /// No pairs yet.
    pub(crate) fn new() -> Self {
        Self {
            s: [[0.0; 3]; 3],
            scale: 0.0,
        }
    }

    /// Adds `observed ≈ R · local` with weight `w` (both vectors from the fixed point, mm).
    pub(crate) fn add(&mut self, local: DVec3, observed: DVec3, w: f64) {
        let (l, o) = (local.to_array(), observed.to_array());
        for a in 0..3 {
            for b in 0..3 {
                self.s[a][b] += w * l[a] * o[b];
            }
        }
        self.scale += w * local.length() * observed.length();
    }

    /// The rotation maximising Σ w · observed·(R local), plus a weak pull towards `prior`.
    pub(crate) fn solve(&self, prior: DQuat) -> DQuat {
        self.solve_with(prior, 0.0)
    }

    /// [`Self::solve`] with the prior as three unit pairs of weight `weight` (the units of
    /// the observations' w · |local| · |observed|, mm²), or the weak pull where that is less.
    pub(crate) fn solve_with(&self, prior: DQuat, weight: f64) -> DQuat {
        let eps = (PRIOR_WEIGHT * self.scale.max(1.0)).max(weight);
        // The prior as pairs (e_a, R_p e_a): s[a][b] += eps · (R_p)_{b a}.
        let r = DMat3::from_quat(prior);
        let mut s = self.s;
        for a in 0..3 {
            let column = r.col(a).to_array();
            for b in 0..3 {
                s[a][b] += eps * column[b];
            }
        }
        let Some(q) = jointfit::rotation_from_cross_covariance(s) else {
            return prior;
        };
        // The sign nearest the prior keeps successive frames continuous.
        if q.dot(prior) < 0.0 { -q } else { q }
    }
}

/// Whether the vectors span a plane: two of them (each longer than `min_mm`) at least
/// `min_sin` apart in direction. Decides whether a rotation is fixed by observations alone.
pub(crate) fn spans_plane(vectors: &[DVec3], min_mm: f64, min_sin: f64) -> bool {
    for (i, &u) in vectors.iter().enumerate() {
        let lu = u.length();
        if lu < min_mm {
            continue;
        }
        for &w in &vectors[i + 1..] {
            let lw = w.length();
            if lw >= min_mm && u.cross(w).length() >= min_sin * lu * lw {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_rotation_and_uses_the_prior_only_for_the_free_spin() {
        let q = DQuat::from_euler(glam::EulerRot::ZXY, 1.0, -0.4, 2.5);
        let local = [
            DVec3::new(0.0, 0.0, -300.0),
            DVec3::new(40.0, 20.0, -50.0),
            DVec3::new(-30.0, 10.0, -120.0),
        ];
        let mut fit = RotationFit::new();
        for (i, l) in local.iter().enumerate() {
            fit.add(*l, q * *l, if i == 0 { 1.0 } else { 0.1 });
        }
        let got = fit.solve(DQuat::IDENTITY);
        assert!(got.angle_between(q) < 1e-6, "{}", got.angle_between(q));

        // One vector: its direction is matched; the spin about it comes from the prior.
        let prior = q * DQuat::from_rotation_z(0.3);
        let mut one = RotationFit::new();
        one.add(local[0], q * local[0], 1.0);
        let got = one.solve(prior);
        assert!((got * local[0] - q * local[0]).length() < 1e-6);
        assert!(got.angle_between(prior) < 1e-6);
        // Nothing at all: the prior.
        assert!(RotationFit::new().solve(prior).angle_between(prior) < 1e-7);

        assert!(spans_plane(&local, 10.0, 0.1));
        assert!(!spans_plane(&local[..1], 10.0, 0.1));
        assert!(!spans_plane(&[local[0], local[0] * 0.5], 10.0, 0.1));
    }
}
