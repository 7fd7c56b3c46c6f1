//! Agglomerative clustering on ρ: every marker starts alone; the two groups whose
//! cross-pair ρ (largest or mean, the linkage) is smallest merge, while it stays within
//! the tolerance. Complete linkage (largest ρ) merges two groups only when *every*
//! measurable pair between them keeps its distance, which is what rigidity means for
//! three or more non-collinear markers; a two-marker segment (thigh LTHI + LKNE) stays
//! whole because its one pair is its own nearest neighbour, whatever the rest look like.

use crate::pairstats::PairStats;
use crate::params::Linkage;

/// Each node's scale for [`scaled_distance`]: its ρ to its `k`-th nearest node, floored at
/// `floor_mm` (the capture's noise level), mm.
pub(crate) fn node_scales(
    stats: &PairStats,
    nodes: &[usize],
    k: usize,
    floor_mm: f64,
    min_overlap: usize,
) -> Vec<f64> {
    crate::affinity::local_scales(nodes, k, floor_mm.max(1e-9), |i, j| {
        stats.rho(i, j, min_overlap)
    })
}

/// Groups `nodes` (marker indices) by agglomeration while the linkage of
/// `dist(a, b)` (node positions, `None` = not measurable) stays within `tol`; groups come
/// back as marker indices. Two groups with no measurable cross pair never merge.
pub(crate) fn agglomerate(
    nodes: &[usize],
    dist: impl Fn(usize, usize) -> Option<f64>,
    tol: f64,
    linkage: Linkage,
) -> Vec<Vec<usize>> {
    let n = nodes.len();
    // Cross-group link statistics, row-major n × n over group slots: the largest ρ, the
    // sum of ρ and the count of measurable pairs (Lance–Williams updates are exact).
    let mut max = vec![f64::NAN; n * n];
    let mut sum = vec![0.0; n * n];
    let mut count = vec![0usize; n * n];
    for a in 0..n {
        for b in 0..n {
            if a == b {
                continue;
            }
            if let Some(r) = dist(a, b) {
                max[a * n + b] = r;
                sum[a * n + b] = r;
                count[a * n + b] = 1;
            }
        }
    }
    let mut groups: Vec<Option<Vec<usize>>> = nodes.iter().map(|&m| Some(vec![m])).collect();
    let link = |k: usize, max: &[f64], sum: &[f64], count: &[usize]| -> Option<f64> {
        (count[k] > 0).then(|| match linkage {
            Linkage::Complete => max[k],
            Linkage::Average => sum[k] / count[k] as f64,
        })
    };
    loop {
        // The lowest link within the tolerance; ties go to the lowest slot pair.
        let live: Vec<usize> = (0..n).filter(|&g| groups[g].is_some()).collect();
        let mut best: Option<(f64, usize, usize)> = None;
        for (p, &a) in live.iter().enumerate() {
            for &b in &live[p + 1..] {
                if let Some(l) = link(a * n + b, &max, &sum, &count)
                    && l <= tol
                    && best.is_none_or(|(bl, _, _)| l < bl)
                {
                    best = Some((l, a, b));
                }
            }
        }
        let Some((_, a, b)) = best else { break };
        let taken = groups[b].take().unwrap_or_default();
        if let Some(g) = groups[a].as_mut() {
            g.extend(taken);
        }
        for &c in &live {
            if c == a || c == b {
                continue;
            }
            let (ac, bc) = (a * n + c, b * n + c);
            let merged_max = match (count[ac] > 0, count[bc] > 0) {
                (true, true) => max[ac].max(max[bc]),
                (true, false) => max[ac],
                (false, true) => max[bc],
                (false, false) => f64::NAN,
            };
            let (s, k) = (sum[ac] + sum[bc], count[ac] + count[bc]);
            for (x, y) in [(a, c), (c, a)] {
                max[x * n + y] = merged_max;
                sum[x * n + y] = s;
                count[x * n + y] = k;
            }
        }
    }
    groups.into_iter().flatten().collect()
}
