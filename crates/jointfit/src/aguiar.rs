//! The paper's joint centre (Aguiar et al. 2006, Sect. 4, Eq. 2–4), normalised per marker.
//!
//! Everything happens in a's local frame (the paper aligns to segment A's markers at a
//! reference frame; our local frame is that alignment). a's own markers sit at their
//! reference positions; every sample of b's markers is mapped there by a's pose of its
//! frame. For a candidate centre `c`, each marker k has distances `r_kf = |c − q_kf|` over
//! its samples, mean `d̄_k` (Eq. 4) and variance `σ_k` (Eq. 3, a variance in mm²: the
//! printed formula has no square root); a's markers have one fixed sample, so `σ = 0`.
//!
//! Cost (ours): `(1 / K) Σ_k (σ_k + α d̄_k)` over the K markers with samples. The paper's
//! Eq. 2 is `½ Σ_k (σ_k + α d̄_k)`: it grows with the marker count, so pairs of segments
//! with few markers would look more joint-like (DESIGN numerical note 3). σ and d̄ are
//! already means over frames (the paper's 1/N), so the cost is per marker and per frame.
//!
//! Minimised by argmin's L-BFGS (More–Thuente line search) with the analytic gradient,
//! started from a closed-form sphere fit of b's marker trajectories in a's frame.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use std::cell::Cell;

use argmin::core::{CostFunction, Executor, Gradient, State};
use argmin::solver::linesearch::MoreThuenteLineSearch;
use argmin::solver::quasinewton::LBFGS;
use glam::DVec3;

use crate::small::sym_eigen;

/// One of b's markers: its samples in a's local frame (mm).
pub(crate) struct Cloud {
    /// Samples, a-local (mm).
    pub points: Vec<DVec3>,
    /// Their mean (mm).
    pub mean: DVec3,
}

impl Cloud {
    /// A cloud from samples; `None` when there are none.
    pub fn new(points: Vec<DVec3>) -> Option<Self> {
        if points.is_empty() {
            return None;
        }
        let mean = points.iter().sum::<DVec3>() / points.len() as f64;
        Some(Self { points, mean })
    }
}

/// Eq. 2 for one pair, per marker.
#[derive(Clone, Copy)]
pub(crate) struct EqTwo<'a> {
    /// a's markers in a's local frame (mm), finite only.
    pub fixed: &'a [DVec3],
    /// b's markers' samples in a's local frame.
    pub clouds: &'a [Cloud],
    /// Weight of the mean distance.
    pub alpha: f64,
}

impl EqTwo<'_> {
    /// Cost and gradient at `c` (a-local, mm).
    pub fn eval(&self, c: DVec3) -> (f64, DVec3) {
        let markers = (self.fixed.len() + self.clouds.len()).max(1) as f64;
        let mut total = 0.0;
        let mut grad = DVec3::ZERO;
        for r in self.fixed {
            let v = c - *r;
            let d = v.length();
            total += self.alpha * d;
            if d > 0.0 {
                grad += self.alpha * v / d;
            }
        }
        for cloud in self.clouds {
            // Welford's running mean and squared deviation: E[r²] − E[r]² would cancel
            // catastrophically near a good centre (r ≈ 300 mm, σ ≈ 0.01 mm²), and a noisy
            // cost stalls the line search.
            let (mut mean, mut m2, mut sum_u, mut k) = (0.0, 0.0, DVec3::ZERO, 0.0);
            for q in &cloud.points {
                let v = c - *q;
                let r = v.length();
                k += 1.0;
                let delta = r - mean;
                mean += delta / k;
                m2 += delta * (r - mean);
                if r > 0.0 {
                    sum_u += v / r;
                }
            }
            let var = m2 / k;
            let grad_dbar = sum_u / k;
            // ∇σ = 2 mean((r − d̄) u) = 2 (c − mean q) − 2 d̄ ∇d̄.
            let grad_var = 2.0 * (c - cloud.mean) - 2.0 * mean * grad_dbar;
            total += var + self.alpha * mean;
            grad += grad_var + self.alpha * grad_dbar;
        }
        (total / markers, grad / markers)
    }
}

/// [`EqTwo`] as argmin sees it: counts evaluations, remembers the best point, and stops
/// the solver (with an error) on a non-finite step or when the evaluation budget is
/// spent, because argmin's More–Thuente search has no iteration limit of its own and can
/// loop forever once L-BFGS produces a degenerate direction at an exact minimum.
pub(crate) struct Guarded<'a> {
    problem: EqTwo<'a>,
    budget: usize,
    evals: Cell<usize>,
    best: Cell<(f64, DVec3)>,
}

impl<'a> Guarded<'a> {
    fn check(&self, p: &[f64]) -> Result<(f64, DVec3), argmin::core::Error> {
        let c = to_vec3(p);
        let n = self.evals.get() + 1;
        self.evals.set(n);
        if n > self.budget {
            return Err(argmin::core::Error::msg("evaluation budget spent"));
        }
        if !c.is_finite() {
            return Err(argmin::core::Error::msg("non-finite step"));
        }
        let (cost, grad) = self.problem.eval(c);
        if cost < self.best.get().0 {
            self.best.set((cost, c));
        }
        Ok((cost, grad))
    }
}

impl CostFunction for &Guarded<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, p: &Self::Param) -> Result<f64, argmin::core::Error> {
        Ok(self.check(p)?.0)
    }
}

impl Gradient for &Guarded<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    fn gradient(&self, p: &Self::Param) -> Result<Vec<f64>, argmin::core::Error> {
        Ok(self.check(p)?.1.to_array().to_vec())
    }
}

fn to_vec3(p: &[f64]) -> DVec3 {
    match p {
        [x, y, z, ..] => DVec3::new(*x, *y, *z),
        _ => DVec3::NAN,
    }
}

/// Closed-form sphere centre of b's marker trajectories (a-local, mm): one common centre,
/// one radius per marker. `|p|² = 2 c·p + k_j`; centring each marker's samples removes
/// `k_j`, leaving 3×3 normal equations. Directions the data do not determine (a hinge's
/// axis, no motion at all) are filled from `fallback`.
pub(crate) fn sphere_centre(clouds: &[Cloud], fallback: DVec3) -> DVec3 {
    let mut m = [[0.0f64; 3]; 3];
    let mut rhs = DVec3::ZERO;
    for cloud in clouds {
        let n = cloud.points.len() as f64;
        let mean_sq = cloud
            .points
            .iter()
            .map(|q| (*q - cloud.mean).length_squared())
            .sum::<f64>()
            / n;
        for q in &cloud.points {
            // Shifting by the marker's mean keeps |p|² small (better conditioned); the
            // centre is then relative to that mean.
            let d = *q - cloud.mean;
            let y = d.length_squared() - mean_sq;
            let da = d.to_array();
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += da[i] * da[j];
                }
            }
            rhs += d * (0.5 * y);
        }
    }
    // With per-marker shifts the unknown is c − mean_j, different per marker: rewrite
    // 2 (c − mean_j)·d = y as 2 c·d = y + 2 mean_j·d, so accumulate the shift's share.
    let mut shift = DVec3::ZERO;
    for cloud in clouds {
        for q in &cloud.points {
            let d = *q - cloud.mean;
            shift += d * d.dot(cloud.mean);
        }
    }
    let rhs = rhs + shift;
    let (values, vectors) = sym_eigen(m);
    let lmax = values[0];
    let mut c = DVec3::ZERO;
    let mut undetermined = Vec::new();
    for k in 0..3 {
        let v = DVec3::from_array(vectors[k]);
        if lmax > 0.0 && values[k] > 1e-6 * lmax {
            c += v * (v.dot(rhs) / values[k]);
        } else {
            undetermined.push(v);
        }
    }
    for v in undetermined {
        c += v * v.dot(fallback - c);
    }
    c
}

/// Result of the L-BFGS minimisation.
pub(crate) struct Minimum {
    /// Centre, a-local (mm).
    pub centre: DVec3,
    /// Normalised Eq. 2 at the centre.
    pub cost: f64,
    /// What happened, for the evidence string.
    pub note: String,
}

/// Minimises Eq. 2 from `start`; the best point evaluated wins, whatever stopped the solver.
pub(crate) fn minimise(problem: &EqTwo<'_>, start: DVec3, max_iters: u64) -> Minimum {
    let start_cost = problem.eval(start).0;
    let guarded = Guarded {
        problem: *problem,
        // L-BFGS spends one cost and one gradient per line-search step, a few steps per
        // iteration.
        budget: 40 * max_iters as usize,
        evals: Cell::new(0),
        best: Cell::new((start_cost, start)),
    };
    let run = || -> Result<u64, argmin::core::Error> {
        let linesearch = MoreThuenteLineSearch::new();
        let solver = LBFGS::new(linesearch, 7)
            .with_tolerance_grad(1e-8)?
            .with_tolerance_cost(1e-12)?;
        let result = Executor::new(&guarded, solver)
            .configure(|state| state.param(start.to_array().to_vec()).max_iters(max_iters))
            .run()?;
        Ok(result.state().get_iter())
    };
    let outcome = run();
    let (cost, centre) = guarded.best.get();
    let evals = guarded.evals.get();
    let how = match outcome {
        Ok(iters) => format!("{iters} iterations"),
        Err(e) => format!("stopped after {evals} evaluations: {e}"),
    };
    Minimum {
        centre,
        cost,
        note: format!("L-BFGS {how}; sphere-fit start cost {start_cost:.3} → {cost:.3}"),
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::horn::tests::TestRng;

    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = TestRng(5);
        let fixed = [rng.vec3(100.0), rng.vec3(100.0), rng.vec3(100.0)];
        let clouds: Vec<Cloud> = (0..3)
            .map(|_| Cloud::new((0..50).map(|_| rng.vec3(300.0)).collect()).unwrap())
            .collect();
        let p = EqTwo {
            fixed: &fixed,
            clouds: &clouds,
            alpha: 0.2,
        };
        let c = DVec3::new(10.0, -20.0, 30.0);
        let (_, g) = p.eval(c);
        let h = 1e-4;
        for (i, e) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
            let fd = (p.eval(c + e * h).0 - p.eval(c - e * h).0) / (2.0 * h);
            assert!(
                (fd - g[i]).abs() < 1e-5 * (1.0 + fd.abs()),
                "{i}: {fd} vs {}",
                g[i]
            );
        }
    }

    #[test]
    fn sphere_fit_recovers_centre() {
        let mut rng = TestRng(9);
        let centre = DVec3::new(40.0, -70.0, 120.0);
        let clouds: Vec<Cloud> = [80.0, 150.0, 220.0]
            .iter()
            .map(|&radius| {
                let pts = (0..200)
                    .map(|_| {
                        let d = rng.vec3(1.0).try_normalize().unwrap_or(DVec3::X);
                        centre + d * radius
                    })
                    .collect();
                Cloud::new(pts).unwrap()
            })
            .collect();
        let c = sphere_centre(&clouds, DVec3::ZERO);
        assert!((c - centre).length() < 1e-6, "{c}");
    }
}
