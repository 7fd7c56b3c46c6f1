//! k-means with seeded k-means++ initialisation and restarts.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Largest number of Lloyd iterations per restart; the spectral embeddings converge in a few.
const MAX_ITERATIONS: usize = 100;

/// Clusters `points` (row-major `n × dim`) into `k` groups; returns a label per point.
///
/// `restarts` independent k-means++ starts from one ChaCha8 stream seeded with `seed`; the
/// lowest inertia wins (the first one on ties), so the result depends only on the inputs.
pub(crate) fn kmeans(
    points: &[f64],
    dim: usize,
    k: usize,
    restarts: usize,
    seed: u64,
) -> Vec<usize> {
    let n = points.len().checked_div(dim).unwrap_or(0);
    if n == 0 || k <= 1 {
        return vec![0; n];
    }
    let k = k.min(n);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut best: Option<(f64, Vec<usize>)> = None;
    for _ in 0..restarts.max(1) {
        let (inertia, labels) = lloyd(points, dim, n, k, &mut rng);
        if best.as_ref().is_none_or(|(b, _)| inertia < *b) {
            best = Some((inertia, labels));
        }
    }
    best.map(|(_, l)| l).unwrap_or_else(|| vec![0; n])
}

fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// One k-means++ start followed by Lloyd iterations; returns (inertia, labels).
fn lloyd(
    points: &[f64],
    dim: usize,
    n: usize,
    k: usize,
    rng: &mut ChaCha8Rng,
) -> (f64, Vec<usize>) {
    let point = |i: usize| &points[i * dim..(i + 1) * dim];
    // k-means++: each next centre drawn with probability ∝ squared distance to the nearest one.
    let mut centres = Vec::with_capacity(k * dim);
    centres.extend_from_slice(point(rng.random_range(0..n)));
    let mut nearest: Vec<f64> = (0..n).map(|i| sq_dist(point(i), &centres[..dim])).collect();
    while centres.len() < k * dim {
        let total: f64 = nearest.iter().sum();
        let pick = if total > 0.0 {
            let mut target = rng.random::<f64>() * total;
            let mut chosen = n - 1;
            for (i, d) in nearest.iter().enumerate() {
                if target < *d {
                    chosen = i;
                    break;
                }
                target -= d;
            }
            chosen
        } else {
            rng.random_range(0..n)
        };
        let start = centres.len();
        centres.extend_from_slice(point(pick));
        for (i, d) in nearest.iter_mut().enumerate() {
            *d = d.min(sq_dist(point(i), &centres[start..start + dim]));
        }
    }

    let mut labels = vec![usize::MAX; n];
    let mut counts = vec![0usize; k];
    for _ in 0..MAX_ITERATIONS {
        let mut changed = false;
        for (i, label) in labels.iter_mut().enumerate() {
            let p = point(i);
            let mut best = (f64::INFINITY, 0);
            for c in 0..k {
                let d = sq_dist(p, &centres[c * dim..(c + 1) * dim]);
                if d < best.0 {
                    best = (d, c);
                }
            }
            if *label != best.1 {
                *label = best.1;
                changed = true;
            }
        }
        // An emptied cluster takes the point farthest from its centre, so k stays k.
        counts.iter_mut().for_each(|c| *c = 0);
        labels.iter().for_each(|&l| counts[l] += 1);
        for c in 0..k {
            if counts[c] == 0 {
                let far = (0..n)
                    .filter(|&i| counts[labels[i]] > 1)
                    .map(|i| {
                        let l = labels[i];
                        (sq_dist(point(i), &centres[l * dim..(l + 1) * dim]), i)
                    })
                    .fold((-1.0, usize::MAX), |a, b| if b.0 > a.0 { b } else { a });
                if far.1 != usize::MAX {
                    counts[labels[far.1]] -= 1;
                    labels[far.1] = c;
                    counts[c] = 1;
                    changed = true;
                }
            }
        }
        centres.iter_mut().for_each(|x| *x = 0.0);
        for (i, &l) in labels.iter().enumerate() {
            for (c, x) in centres[l * dim..(l + 1) * dim].iter_mut().zip(point(i)) {
                *c += x;
            }
        }
        for (c, &count) in counts.iter().enumerate() {
            if count > 0 {
                centres[c * dim..(c + 1) * dim]
                    .iter_mut()
                    .for_each(|x| *x /= count as f64);
            }
        }
        if !changed {
            break;
        }
    }
    let inertia = (0..n)
        .map(|i| sq_dist(point(i), &centres[labels[i] * dim..(labels[i] + 1) * dim]))
        .sum();
    (inertia, labels)
}
