//! Normalised spectral clustering (Ng, Jordan & Weiss 2001) with the eigen-gap segment count.

use crate::Error;
use crate::eigen::symmetric_eigen;
use crate::kmeans::kmeans;
use crate::params::Params;

/// What spectral clustering found for a set of nodes.
pub(crate) struct SpectralClusters {
    /// Groups of node positions (indices into the affinity's rows).
    pub clusters: Vec<Vec<usize>>,
    /// Top eigenvalues of D^-1/2 A D^-1/2 over the connected nodes, descending.
    pub eigenvalues: Vec<f64>,
    /// Clusters chosen (eigen-gap or forced), not counting isolated nodes.
    pub chosen: usize,
}

/// Clusters the nodes of the row-major `n × n` affinity `a`.
///
/// Nodes with zero affinity to everyone (degree 0) cannot be normalised; each becomes a
/// cluster of its own. The rest: L = D^-1/2 A D^-1/2, k from the largest gap between
/// consecutive top eigenvalues (k ≤ `max_segments`) unless `segments` forces it, rows of
/// the top-k eigenvectors normalised to unit length, then k-means.
pub(crate) fn spectral_clusters(
    a: &[f64],
    n: usize,
    params: &Params,
) -> Result<SpectralClusters, Error> {
    let degree: Vec<f64> = (0..n).map(|r| a[r * n..(r + 1) * n].iter().sum()).collect();
    let connected: Vec<usize> = (0..n)
        .filter(|&r| degree[r] > 0.0 && degree[r].is_finite())
        .collect();
    let mut clusters: Vec<Vec<usize>> = (0..n)
        .filter(|r| !connected.contains(r))
        .map(|r| vec![r])
        .collect();
    let m = connected.len();
    if m == 0 {
        return Ok(SpectralClusters {
            clusters,
            eigenvalues: Vec::new(),
            chosen: 0,
        });
    }
    let inv_sqrt: Vec<f64> = connected.iter().map(|&r| 1.0 / degree[r].sqrt()).collect();
    let mut l = vec![0.0; m * m];
    for (p, &r) in connected.iter().enumerate() {
        for (q, &c) in connected.iter().enumerate() {
            l[p * m + q] = a[r * n + c] * inv_sqrt[p] * inv_sqrt[q];
        }
    }
    let spectrum = symmetric_eigen(&l, m).map_err(|detail| Error::Eigen { markers: m, detail })?;
    let top = (params.max_segments + 1).min(m);
    let eigenvalues = spectrum.values[..top].to_vec();
    let k = if params.segments > 0 {
        params.segments.min(m)
    } else {
        eigengap_count(&spectrum.values, params.max_segments)
    };
    // Rows of the top-k eigenvectors, each scaled to unit length (NJW step 4).
    let mut embedding = vec![0.0; m * k];
    for p in 0..m {
        let row = &mut embedding[p * k..(p + 1) * k];
        row.copy_from_slice(&spectrum.vectors[p * m..p * m + k]);
        let norm = row.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > 0.0 {
            row.iter_mut().for_each(|x| *x /= norm);
        }
    }
    let labels = kmeans(&embedding, k, k, params.restarts, params.seed);
    let mut groups = vec![Vec::new(); k];
    for (p, &label) in labels.iter().enumerate() {
        groups[label].push(connected[p]);
    }
    clusters.extend(groups.into_iter().filter(|g| !g.is_empty()));
    Ok(SpectralClusters {
        clusters,
        eigenvalues,
        chosen: k,
    })
}

/// The k in 1..=min(max_k, n − 1) with the largest gap λ_k − λ_{k+1} (descending values);
/// ties go to the smaller k. A single node is one cluster.
pub(crate) fn eigengap_count(values: &[f64], max_k: usize) -> usize {
    let n = values.len();
    if n <= 1 {
        return n;
    }
    let mut best = (f64::NEG_INFINITY, 1);
    for k in 1..=max_k.min(n - 1) {
        let gap = values[k - 1] - values[k];
        if gap > best.0 {
            best = (gap, k);
        }
    }
    best.1
}
