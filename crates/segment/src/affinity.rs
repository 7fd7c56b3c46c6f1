//! Affinity between markers from the standard deviation ρ of their distance.

use crate::pairstats::PairStats;
use crate::params::{Affinity, Params};

/// The affinity matrix of `nodes` (marker indices), row-major `nodes.len()²`, zero diagonal
/// (Ng–Jordan–Weiss). Pairs seen together in fewer than `min_overlap_frames` frames get 0.
/// `noise_rho_mm`: the share of every pair's ρ that white measurement noise gives it (0
/// where the capture's scatter is not white), taken out in quadrature first.
pub(crate) fn affinity_matrix(
    stats: &PairStats,
    nodes: &[usize],
    params: &Params,
    noise_rho_mm: f64,
) -> Vec<f64> {
    let n = nodes.len();
    let min_overlap = params.min_overlap_frames;
    let rho_of = |i: usize, j: usize| {
        stats
            .rho(i, j, min_overlap)
            .map(|rho| (rho * rho - noise_rho_mm * noise_rho_mm).max(0.0).sqrt())
    };
    let mut a = vec![0.0; n * n];
    let scales = match params.affinity {
        Affinity::Local => local_scales(nodes, params.local_k, params.min_scale_mm, rho_of),
        Affinity::Paper | Affinity::Absolute => Vec::new(),
    };
    for (r, &i) in nodes.iter().enumerate() {
        for (c, &j) in nodes.iter().enumerate().skip(r + 1) {
            let Some(rho) = rho_of(i, j) else {
                continue;
            };
            let value = match params.affinity {
                Affinity::Paper => {
                    // Eq. 1 as printed: σ = (1/N²)·Σ_f dist = mean distance / N, with N the
                    // frames both markers are seen in; ρ enters unsquared.
                    let k = stats.at(i, j);
                    let sigma = stats.mean[k] / stats.overlap[k] as f64;
                    (-rho / (2.0 * sigma * sigma)).exp()
                }
                Affinity::Local => (-(rho * rho) / (scales[r] * scales[c])).exp(),
                Affinity::Absolute => {
                    (-(rho * rho) / (2.0 * params.scale_mm * params.scale_mm)).exp()
                }
            };
            let value = if value.is_finite() { value } else { 0.0 };
            a[r * n + c] = value;
            a[c * n + r] = value;
        }
    }
    a
}

/// Self-tuning scales (Zelnik-Manor & Perona 2004): each marker's ρ (as `rho_of` gives it)
/// to its k-th nearest marker in ρ (fewer neighbours: the farthest one), never below
/// `floor_mm`, mm.
pub(crate) fn local_scales(
    nodes: &[usize],
    k: usize,
    floor_mm: f64,
    rho_of: impl Fn(usize, usize) -> Option<f64>,
) -> Vec<f64> {
    let mut rhos = Vec::with_capacity(nodes.len());
    nodes
        .iter()
        .map(|&i| {
            rhos.clear();
            rhos.extend(nodes.iter().filter_map(|&j| rho_of(i, j)));
            rhos.sort_by(f64::total_cmp);
            let kth = rhos.get(k.min(rhos.len()).wrapping_sub(1)).copied();
            kth.unwrap_or(floor_mm).max(floor_mm)
        })
        .collect()
}
