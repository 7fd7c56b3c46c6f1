//! Rigidity of marker groups under a tolerance on ρ: the noise level, and the repair of
//! clusters that are not rigid (split), misplaced markers (move) and rigid neighbours (merge).

use rayon::prelude::*;

use mocap_io::Trajectories;

use crate::pairstats::PairStats;

/// A marker split off alone rejoins the group it is most rigid with when its RMS ρ to it is
/// within this multiple of the tolerance: skin sliding of a few mm must not cost a segment
/// its marker, while a lone marker on a body of its own (ρ of tens of mm) stays out.
const REJOIN_FACTOR: f64 = 4.0;

/// Most repair sweeps (move then merge); each sweep only ever improves rigidity, so a few do.
const MAX_SWEEPS: usize = 10;

/// Each of `nodes` with its steadiest partner among them (the smallest ρ, the first of
/// equals) and that ρ, mm: `(marker, partner, ρ)`; markers seen with no other for
/// `min_overlap` frames are left out.
pub(crate) fn steadiest_partners(
    stats: &PairStats,
    nodes: &[usize],
    min_overlap: usize,
) -> Vec<(usize, usize, f64)> {
    nodes
        .iter()
        .filter_map(|&i| {
            nodes
                .iter()
                .filter_map(|&j| stats.rho(i, j, min_overlap).map(|r| (i, j, r)))
                .min_by(|x, y| x.2.total_cmp(&y.2))
        })
        .collect()
}

/// The noise level in mm: the median over the markers of their smallest ρ to another
/// (`partners`, [`steadiest_partners`]).
///
/// On a rigid body with noise the smallest ρ is a same-segment pair, so this measures the
/// measurement noise (in ρ units), robustly to skin motion on a minority of markers.
pub(crate) fn noise_level(partners: &[(usize, usize, f64)]) -> f64 {
    let mut nearest: Vec<f64> = partners.iter().map(|&(_, _, r)| r).collect();
    if nearest.is_empty() {
        return 0.0;
    }
    nearest.sort_by(f64::total_cmp);
    median_of_sorted(&nearest)
}

/// How smooth over time the capture's scatter about rigidity is: the median over the
/// markers of the lag-one autocorrelation of each one's distance to its steadiest partner
/// (`partners`, [`steadiest_partners`]) about that distance's median, over consecutive
/// frames where both are seen. About 0 where that scatter is white measurement noise
/// (rigid marker plates, a robot's links), near 1 where it is skin, which moves markers
/// with the joint angles from frame to frame smoothly. `None` without a marker seen with
/// its partner over ≥ `min_overlap` consecutive pairs of frames.
pub(crate) fn scatter_smoothness(
    traj: &Trajectories,
    partners: &[(usize, usize, f64)],
    min_overlap: usize,
) -> Option<f64> {
    let mut smoothness: Vec<f64> = Vec::with_capacity(partners.len());
    let mut distances: Vec<Option<f64>> = Vec::with_capacity(traj.frames());
    let mut seen: Vec<f64> = Vec::with_capacity(traj.frames());
    for &(i, j, _) in partners {
        distances.clear();
        distances.extend((0..traj.frames()).map(|f| crate::swaps::distance(traj, f, i, j)));
        seen.clear();
        seen.extend(distances.iter().flatten());
        if seen.is_empty() {
            continue;
        }
        seen.sort_by(f64::total_cmp);
        let middle = median_of_sorted(&seen);
        let (mut lagged, mut a2, mut b2, mut pairs) = (0.0, 0.0, 0.0, 0usize);
        for w in distances.windows(2) {
            if let [Some(a), Some(b)] = w {
                let (a, b) = (a - middle, b - middle);
                lagged += a * b;
                a2 += a * a;
                b2 += b * b;
                pairs += 1;
            }
        }
        let norm = (a2 * b2).sqrt();
        if pairs >= min_overlap && norm > 0.0 {
            smoothness.push(lagged / norm);
        }
    }
    if smoothness.is_empty() {
        return None;
    }
    smoothness.sort_by(f64::total_cmp);
    Some(median_of_sorted(&smoothness))
}

/// The median of a sorted, non-empty slice.
fn median_of_sorted(sorted: &[f64]) -> f64 {
    let mid = sorted.len() / 2;
    if sorted.len() % 2 == 1 {
        sorted[mid]
    } else {
        0.5 * (sorted[mid - 1] + sorted[mid])
    }
}

/// Fewest markers a cluster needs to vote in [`rigid_spread`]: in a cluster of three a
/// marker's second-nearest mate is its farthest, not a typical one.
const SPREAD_CLUSTER_MARKERS: usize = 4;

/// How much ρ a rigid body shows, mm: the median, over the markers of `clusters` of ≥ 4
/// markers, of each marker's second-smallest ρ to its cluster-mates; `None` when such
/// clusters hold fewer than half of all the clusters' markers.
///
/// Skin moves a marker's nearest mate much as it moves the marker, so the smallest ρ
/// ([`noise_level`]) sees the noise and little of the skin, and a tolerance on it cuts
/// segments whose skin the noise does not happen to cover (noiseless skin on synthetic
/// subjects: smallest 1.0-1.4 mm, second 2.1-2.8 mm; noise alone: both ≈ √2 σ). With
/// markers spread two or three to a segment the clusters do not say which ρ is within a
/// segment, and the noise level stands.
pub(crate) fn rigid_spread(
    stats: &PairStats,
    clusters: &[Vec<usize>],
    min_overlap: usize,
) -> Option<f64> {
    let clustered: usize = clusters.iter().map(Vec::len).sum();
    let mut second = Vec::new();
    let mut rhos = Vec::new();
    for cluster in clusters
        .iter()
        .filter(|c| c.len() >= SPREAD_CLUSTER_MARKERS)
    {
        for &i in cluster {
            rhos.clear();
            rhos.extend(cluster.iter().filter_map(|&j| stats.rho(i, j, min_overlap)));
            if rhos.len() >= 2 {
                rhos.select_nth_unstable_by(1, f64::total_cmp);
                second.push(rhos[1]);
            }
        }
    }
    if second.is_empty() || 2 * second.len() < clustered {
        return None;
    }
    second.sort_by(f64::total_cmp);
    Some(median_of_sorted(&second))
}

/// RMS of ρ from marker `i` to the markers of `group` other than itself, mm; `None` when
/// no pair was seen together long enough.
pub(crate) fn rms_rho(
    stats: &PairStats,
    i: usize,
    group: &[usize],
    min_overlap: usize,
) -> Option<f64> {
    let (mut sum, mut count) = (0.0, 0usize);
    for &j in group {
        if let Some(r) = stats.rho(i, j, min_overlap) {
            sum += r * r;
            count += 1;
        }
    }
    (count > 0).then(|| (sum / count as f64).sqrt())
}

/// Makes every cluster rigid, deterministically: splits within `spread_tol` (mm), then
/// [`repair`]s, as the linkage split and repair of the default path do.
pub(crate) fn refine(
    clusters: Vec<Vec<usize>>,
    stats: &PairStats,
    noise_tol: f64,
    spread_tol: f64,
    min_overlap: usize,
    min_group: usize,
) -> Vec<Vec<usize>> {
    let clusters: Vec<Vec<usize>> = clusters
        .iter()
        .flat_map(|c| split(c, stats, spread_tol, min_overlap, min_group))
        .collect();
    repair(clusters, stats, noise_tol, spread_tol, min_overlap)
}

/// Moves misplaced markers (within `noise_tol`, mm) and merges rigid neighbours (within
/// `noise_tol`, or `spread_tol` where one has fewer than [`POSED_MARKERS`]) until nothing
/// changes (at most [`MAX_SWEEPS`] sweeps), then normalises.
pub(crate) fn repair(
    mut clusters: Vec<Vec<usize>>,
    stats: &PairStats,
    noise_tol: f64,
    spread_tol: f64,
    min_overlap: usize,
) -> Vec<Vec<usize>> {
    for _ in 0..MAX_SWEEPS {
        let moved = move_markers(&mut clusters, stats, noise_tol, min_overlap);
        let merged = merge_rigid(&mut clusters, stats, noise_tol, spread_tol, min_overlap);
        if !moved && !merged {
            break;
        }
    }
    normalise(&mut clusters);
    clusters
}

/// Merges, repeatedly, the pair of clusters (`i < j`) that `eligible` admits and `score`
/// rates lowest (`None`: not to be merged), `j` into `i`, ties to the lower ids; scores in
/// parallel. Returns how many merges were made.
pub(crate) fn merge_best_pairs(
    clusters: &mut Vec<Vec<usize>>,
    eligible: impl Fn(&[usize], &[usize]) -> bool,
    score: impl Fn(&[usize], &[usize]) -> Option<f64> + Sync,
) -> usize {
    let mut merged = 0;
    loop {
        let candidates: Vec<(usize, usize)> = (0..clusters.len())
            .flat_map(|i| ((i + 1)..clusters.len()).map(move |j| (i, j)))
            .filter(|&(i, j)| eligible(&clusters[i], &clusters[j]))
            .collect();
        let best = candidates
            .par_iter()
            .filter_map(|&(i, j)| Some((score(&clusters[i], &clusters[j])?, i, j)))
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        let Some((_, i, j)) = best else { break };
        let moved = std::mem::take(&mut clusters[j]);
        clusters[i].extend(moved);
        clusters.remove(j);
        merged += 1;
    }
    merged
}

/// Sorts markers inside clusters and clusters by their smallest marker; drops empty ones.
pub(crate) fn normalise(clusters: &mut Vec<Vec<usize>>) {
    clusters.retain(|c| !c.is_empty());
    clusters.iter_mut().for_each(|c| c.sort_unstable());
    clusters.sort_by_key(|c| c[0]);
}

/// Average-linkage agglomeration inside one cluster, stopping before any merge whose mean ρ
/// between the two groups exceeds `tol`. A rigid cluster comes back whole; thigh + shank
/// comes back as two. Mean (not max) linkage keeps a segment whole when only one noisy
/// pair exceeds the tolerance. Groups smaller than `min_group` (a sliding marker) rejoin
/// the group they are most rigid with if within [`REJOIN_FACTOR`] × `tol`; the move step
/// handles markers that belong to another cluster.
pub(crate) fn split(
    cluster: &[usize],
    stats: &PairStats,
    tol: f64,
    min_overlap: usize,
    min_group: usize,
) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = cluster.iter().map(|&m| vec![m]).collect();
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for a in 0..groups.len() {
            for b in a + 1..groups.len() {
                let Some(link) = mean_link(&groups[a], &groups[b], stats, min_overlap) else {
                    continue;
                };
                if link <= tol && best.is_none_or(|(l, _, _)| link < l) {
                    best = Some((link, a, b));
                }
            }
        }
        let Some((_, a, b)) = best else { break };
        let taken = groups.remove(b);
        groups[a].extend(taken);
    }
    rejoin_small(
        &mut groups,
        stats,
        |_| REJOIN_FACTOR * tol,
        |_, _| true,
        min_overlap,
        min_group,
    );
    groups
}

/// Groups smaller than `min_group` (a sliding or orphaned marker), smallest marker first,
/// join, of the big groups `admit(small, big)` allows, the one they are most rigid with
/// (RMS ρ over their markers) when that RMS is within `bound(small group)` (mm) and so are
/// most of their cross pairs; the others stay as they are. The RMS alone lets a marker near a joint bridge two bodies: CMU 49_04's
/// shin marker kept ρ 4.0 mm to the knee marker and 29.2 mm to the thigh marker (the knee
/// flexes 7-109°), RMS 20.8 mm under a 22 mm bound, and went into the thigh.
pub(crate) fn rejoin_small(
    groups: &mut Vec<Vec<usize>>,
    stats: &PairStats,
    bound: impl Fn(&[usize]) -> f64,
    admit: impl Fn(&[usize], &[usize]) -> bool,
    min_overlap: usize,
    min_group: usize,
) {
    groups.sort_by_key(|g| g.iter().min().copied());
    let mut g = 0;
    while g < groups.len() {
        if groups[g].len() >= min_group {
            g += 1;
            continue;
        }
        let small = &groups[g];
        let limit = bound(small);
        // RMS over the small group's markers of each one's RMS ρ to the other group, among
        // the groups most of whose cross pairs are within the limit.
        let best = groups
            .iter()
            .enumerate()
            .filter(|(h, other)| *h != g && other.len() >= min_group && admit(small, other))
            .filter_map(|(h, other)| {
                let (mut sum, mut count) = (0.0, 0usize);
                let (mut pairs, mut within) = (0usize, 0usize);
                for &i in small {
                    let (mut squares, mut n) = (0.0, 0usize);
                    for r in other.iter().filter_map(|&j| stats.rho(i, j, min_overlap)) {
                        squares += r * r;
                        n += 1;
                        within += usize::from(r <= limit);
                    }
                    if n > 0 {
                        sum += squares / n as f64;
                        count += 1;
                        pairs += n;
                    }
                }
                (count > 0 && 2 * within > pairs).then(|| ((sum / count as f64).sqrt(), h))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        match best {
            Some((r, h)) if r <= limit => {
                let taken = groups.remove(g);
                let h = if h > g { h - 1 } else { h };
                groups[h].extend(taken);
                g = 0;
            }
            _ => g += 1,
        }
    }
}

/// Mean ρ over the measurable pairs between two groups, mm.
fn mean_link(a: &[usize], b: &[usize], stats: &PairStats, min_overlap: usize) -> Option<f64> {
    let (mut sum, mut count) = (0.0, 0usize);
    for &i in a {
        for &j in b {
            if let Some(r) = stats.rho(i, j, min_overlap) {
                sum += r;
                count += 1;
            }
        }
    }
    (count > 0).then(|| sum / count as f64)
}

/// Moves each marker whose RMS ρ to its own cluster exceeds `tol` (or who is alone) into the
/// cluster it is most rigid with, when that one is within `tol`. Returns whether any moved.
pub(crate) fn move_markers(
    clusters: &mut [Vec<usize>],
    stats: &PairStats,
    tol: f64,
    min_overlap: usize,
) -> bool {
    let mut markers: Vec<usize> = clusters.iter().flatten().copied().collect();
    markers.sort_unstable();
    let mut any = false;
    for m in markers {
        let Some(own) = clusters.iter().position(|c| c.contains(&m)) else {
            continue;
        };
        let own_rms = rms_rho(stats, m, &clusters[own], min_overlap).unwrap_or(f64::INFINITY);
        if own_rms <= tol {
            continue;
        }
        let best = clusters
            .iter()
            .enumerate()
            .filter(|(c, _)| *c != own)
            .filter_map(|(c, g)| rms_rho(stats, m, g, min_overlap).map(|r| (r, c)))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        if let Some((r, target)) = best
            && r <= tol
            && r < own_rms
        {
            clusters[own].retain(|&x| x != m);
            clusters[target].push(m);
            any = true;
        }
    }
    any
}

/// Fewest markers that give a cluster a pose of its own.
const POSED_MARKERS: usize = 3;

/// Merges pairs of clusters whose every measurable cross pair has ρ ≤ `noise_tol`, or
/// `spread_tol` where one of them has fewer than [`POSED_MARKERS`] (they move as one body
/// within the tolerance), most rigid pair first. Returns whether any merged.
fn merge_rigid(
    clusters: &mut Vec<Vec<usize>>,
    stats: &PairStats,
    noise_tol: f64,
    spread_tol: f64,
    min_overlap: usize,
) -> bool {
    // The move step may have emptied a cluster; merges never empty one.
    clusters.retain(|c| !c.is_empty());
    let worst_cross_rho = |a: &[usize], b: &[usize]| {
        let posed = a.len().min(b.len()) >= POSED_MARKERS;
        let tol = if posed { noise_tol } else { spread_tol };
        a.iter()
            .flat_map(|&i| b.iter().filter_map(move |&j| stats.rho(i, j, min_overlap)))
            .reduce(f64::max)
            .filter(|&w| w <= tol)
    };
    merge_best_pairs(clusters, |_, _| true, worst_cross_rho) > 0
}

/// Fewest markers a donor keeps when it gives a marker to an orphan: three non-collinear
/// markers still give it a full pose of its own.
pub(crate) const DONOR_KEEPS: usize = 3;

/// Gives each lone marker (a group of one) a partner taken from a group of four or more.
///
/// A marker near a joint axis (the lateral malleolus, LANK) keeps its distance to both
/// sides of the joint, so the evidence cannot say which side it belongs to; agglomeration
/// hands it to one side and may leave the other side's only marker (LSHN) alone. When the
/// lone marker `m` and a marker `x` of a group keep their distance within `tol` (ρ, mm:
/// rigid by the same standard the merges use), at least as well as `x` keeps it to its
/// group (RMS ρ: the evidence does not favour the group), and that group keeps
/// [`DONOR_KEEPS`] markers without `x`, `x` moves to `m`: both segments are then poseable (jointfit
/// anchors a two-marker segment to its neighbour's joint), and no pair whose ρ exceeds the
/// tolerance is ever put together. Steadiest pair first; each lone marker takes one, and
/// a marker moves once.
pub(crate) fn pair_orphans(
    clusters: &mut [Vec<usize>],
    stats: &PairStats,
    tol: f64,
    min_overlap: usize,
) {
    let mut offers: Vec<(f64, usize, usize)> = Vec::new();
    for (o, orphan) in clusters.iter().enumerate() {
        let [m] = orphan[..] else { continue };
        for donor in clusters.iter().filter(|d| d.len() > DONOR_KEEPS) {
            for &x in donor {
                // Ambiguous only when x keeps its distance to m at least as well as to its
                // own group: a marker sliding on the donor's skin is steadier with none.
                let mates: Vec<usize> = donor.iter().copied().filter(|&y| y != x).collect();
                let to_donor = rms_rho(stats, x, &mates, min_overlap).unwrap_or(f64::INFINITY);
                if let Some(r) = stats.rho(m, x, min_overlap)
                    && r <= tol
                    && r <= to_donor
                {
                    offers.push((r, o, x));
                }
            }
        }
    }
    offers.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut moved: Vec<usize> = Vec::new();
    for (_, o, x) in offers {
        if clusters[o].len() != 1 || moved.contains(&x) {
            continue;
        }
        let Some(d) = clusters.iter().position(|c| c.contains(&x)) else {
            continue;
        };
        if clusters[d].len() <= DONOR_KEEPS {
            continue;
        }
        clusters[d].retain(|&y| y != x);
        clusters[o].push(x);
        moved.push(x);
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// ρ between markers given as (i, j, ρ), every pair seen together in 100 frames.
    pub(crate) fn stats(n: usize, pairs: &[(usize, usize, f64)]) -> PairStats {
        let mut std = vec![0.0; n * n];
        for &(i, j, r) in pairs {
            std[i * n + j] = r;
            std[j * n + i] = r;
        }
        PairStats {
            n,
            visible: vec![100; n],
            overlap: vec![100; n * n],
            mean: vec![500.0; n * n],
            std,
        }
    }

    #[test]
    fn a_marker_rejoins_only_where_most_of_its_pairs_are_within_the_bound() {
        // Thigh marker 0 and knee marker 1 (ρ 2.1); shin marker 2 keeps ρ 4.0 to the knee
        // and 29.2 to the thigh: RMS 20.8 within a 22 mm bound, one pair of two within it.
        let bridge = stats(3, &[(0, 1, 2.1), (1, 2, 4.0), (0, 2, 29.2)]);
        let mut groups = vec![vec![0, 1], vec![2]];
        rejoin_small(&mut groups, &bridge, |_| 22.0, |_, _| true, 10, 2);
        assert_eq!(groups, vec![vec![0, 1], vec![2]]);
        // Both of its pairs within the bound: it joins.
        let rigid = stats(3, &[(0, 1, 2.1), (1, 2, 4.0), (0, 2, 12.0)]);
        let mut groups = vec![vec![0, 1], vec![2]];
        rejoin_small(&mut groups, &rigid, |_| 22.0, |_, _| true, 10, 2);
        assert_eq!(groups, vec![vec![0, 1, 2]]);
    }
}
