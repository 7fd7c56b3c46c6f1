//! Rigidity by whole-body fit: a group's markers are fitted as one rigid body in every frame
//! (Horn's quaternion method against a reference shape from the mean pair distances), and a
//! cluster splits in two when two bodies explain its motion clearly better than one.
//!
//! Why not ρ alone: the distance between a thigh and a shank marker changes only to second
//! order in the knee angle near a straight limb (d ∝ sin of the included angle), so a joint
//! with little motion in a short trial moves ρ by a few mm, no more than 5–15 mm of skin
//! artefact moves a same-segment pair. A rigid fit sees the rotation to first order: the
//! child's markers leave the parent's fitted body by lever arm × angle.

use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::eigen::symmetric_eigen;
use crate::eigen4::{horn_matrix, largest_eigenvalue4_below};
use crate::pairstats::PairStats;
use crate::reassign::{Pose, horn, locals_in};
use crate::rigidity::{merge_best_pairs, rms_rho};

/// Largest cluster whose bipartitions are all tried (2^(n−1) candidates).
const MAX_ENUMERATED: usize = 10;

/// A group's rigid-fit residual: sum of squares (mm²) and degrees of freedom.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FitResidual {
    /// Sum over frames and visible markers of the squared fit residual, mm².
    pub sum_sq: f64,
    /// Residual degrees of freedom: per frame 3k − 6 for k ≥ 3 visible markers, 1 for k = 2.
    pub dof: f64,
}

impl FitResidual {
    fn add(self, other: Self) -> Self {
        Self {
            sum_sq: self.sum_sq + other.sum_sq,
            dof: self.dof + other.dof,
        }
    }
}

/// Median distance of every pair of `cluster` over the frames where both are seen, mm,
/// row-major `n × n` (NaN when never seen together). The median, not the mean, so a label
/// swap for a minority of the frames does not bend the reference shape.
pub(crate) fn median_distances(traj: &Trajectories, cluster: &[usize]) -> Vec<f64> {
    let n = cluster.len();
    let markers = traj.markers().max(1);
    let mut out = vec![0.0; n * n];
    let mut d = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            d.clear();
            for frame in traj.positions().chunks_exact(markers) {
                if let (Some(&p), Some(&q)) = (frame.get(cluster[a]), frame.get(cluster[b]))
                    && mocap_io::is_present(p)
                    && mocap_io::is_present(q)
                {
                    d.push(
                        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
                            .sqrt(),
                    );
                }
            }
            let m = median(&mut d);
            out[a * n + b] = m;
            out[b * n + a] = m;
        }
    }
    out
}

/// Median of `v` (reordered), NaN when empty.
pub(crate) fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    let odd = v.len() % 2 == 1;
    let (lower, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    let m = *m;
    if odd {
        m
    } else {
        0.5 * (m + lower.iter().copied().fold(f64::NEG_INFINITY, f64::max))
    }
}

/// Reference shape (segment-local, mm) of the markers at positions `group` of a cluster with
/// pair distances `dist` (row-major `n × n`) by classical multidimensional scaling; a pair
/// never seen together takes the distance the rest of the shape implies (see
/// [`complete_distances`]); `None` when the rest does not imply one.
pub(crate) fn reference_shape(dist: &[f64], n: usize, group: &[usize]) -> Option<Vec<[f64; 3]>> {
    let k = group.len();
    let mut d2 = vec![0.0; k * k];
    let mut missing = Vec::new();
    for (a, &i) in group.iter().enumerate() {
        for (b, &j) in group.iter().enumerate() {
            if a != b {
                let m = dist[i * n + j];
                if m.is_finite() {
                    d2[a * k + b] = m * m;
                } else if a < b {
                    missing.push((a, b));
                }
            }
        }
    }
    if !missing.is_empty() {
        complete_distances(&mut d2, k, &missing)?;
    }
    classical_mds(&d2, k)
}

/// Fewest markers seen with both of a pair never seen together that place the pair's
/// distance: three partners fix each marker's place up to a mirror image.
const COMPLETION_PARTNERS: usize = 3;

/// Most rounds of [`complete_distances`]; each costs one `k × k` eigendecomposition.
const COMPLETION_ROUNDS: usize = 100;

/// [`complete_distances`] stops once no filled distance moves by more than this, mm.
const COMPLETION_STEP_MM: f64 = 1e-3;

/// Fills the squared distances (`d2`, row-major `k × k`) of the `missing` pairs (a < b) with
/// the ones the rest of the shape implies: each starts at its tightest triangle bound from
/// below (max over partners c of |d_ac − d_bc|: zero for two pieces of one marker an
/// unlabeled capture cut at a gap), then the shape is embedded in 3-D and the pair's distance
/// read off the embedding, until it settles (a rank-3 completion of the Gram matrix). `None`
/// when some pair has fewer than [`COMPLETION_PARTNERS`] markers seen with both of its own.
fn complete_distances(d2: &mut [f64], k: usize, missing: &[(usize, usize)]) -> Option<()> {
    let known = |a: usize, b: usize| a == b || !missing.contains(&(a.min(b), a.max(b)));
    let mut lower = Vec::with_capacity(missing.len());
    for &(a, b) in missing {
        let bounds = (0..k)
            .filter(|&c| c != a && c != b && known(a, c) && known(b, c))
            .map(|c| (d2[a * k + c].sqrt() - d2[b * k + c].sqrt()).abs());
        let (count, bound) = bounds.fold((0, 0.0f64), |(n, m), v| (n + 1, m.max(v)));
        if count < COMPLETION_PARTNERS {
            return None;
        }
        lower.push(bound);
    }
    for (&(a, b), &d) in missing.iter().zip(&lower) {
        d2[a * k + b] = d * d;
        d2[b * k + a] = d * d;
    }
    for _ in 0..COMPLETION_ROUNDS {
        let shape = classical_mds(d2, k)?;
        let mut step = 0.0f64;
        for &(a, b) in missing {
            let implied = (0..3)
                .map(|i| (shape[a][i] - shape[b][i]).powi(2))
                .sum::<f64>();
            step = step.max((implied.sqrt() - d2[a * k + b].sqrt()).abs());
            d2[a * k + b] = implied;
            d2[b * k + a] = implied;
        }
        if step < COMPLETION_STEP_MM {
            break;
        }
    }
    Some(())
}

/// Classical multidimensional scaling of the squared distances `d2` (row-major `k × k`)
/// into 3-D; `None` when the eigendecomposition fails.
fn classical_mds(d2: &[f64], n: usize) -> Option<Vec<[f64; 3]>> {
    // B = −½ J D² J (double centring).
    let row: Vec<f64> = (0..n)
        .map(|a| d2[a * n..(a + 1) * n].iter().sum::<f64>() / n as f64)
        .collect();
    let all = row.iter().sum::<f64>() / n as f64;
    let mut b = vec![0.0; n * n];
    for a in 0..n {
        for c in 0..n {
            b[a * n + c] = -0.5 * (d2[a * n + c] - row[a] - row[c] + all);
        }
    }
    let spectrum = symmetric_eigen(&b, n).ok()?;
    let mut shape = vec![[0.0; 3]; n];
    for (axis, value) in spectrum.values.iter().take(3).enumerate() {
        let scale = value.max(0.0).sqrt();
        for (a, p) in shape.iter_mut().enumerate() {
            p[axis] = spectrum.vectors[a * n + axis] * scale;
        }
    }
    Some(shape)
}

/// Least-squares rigid-fit residual of `group` in every frame (zero dof where fewer than two
/// markers are seen), against its reference shape or its mirror image, whichever fits
/// better (MDS cannot tell handedness); with tracks never seen together, against
/// [`core_shape`] where there is one. The MDS shape is kept on purpose, not refined to
/// the least-squares one: median distances across a moving joint fit no one shape, and
/// that inflation is much of what tells a cluster spanning a joint (refining cut a
/// two-plus-three cluster's σ from 8.9 to 5.1 mm against its parts' 3.7; with 2–3 markers
/// per segment, seeds 20001..20050 and 30001..30050, hard, exact trees went 207 → 199).
fn fit_residual(
    traj: &Trajectories,
    cluster: &[usize],
    dist: &[f64],
    positions: &[usize],
) -> Option<Vec<FitResidual>> {
    let group: Vec<usize> = positions.iter().map(|&p| cluster[p]).collect();
    if group.len() > MAX_GROUP {
        return None;
    }
    if let Some(shape) = core_shape(traj, cluster, dist, positions) {
        return Some(residuals(traj, &group, &shape));
    }
    let shape = reference_shape(dist, cluster.len(), positions)?;
    let n_markers = traj.markers();
    let mut frames: [Vec<FitResidual>; 2] = [Vec::new(), Vec::new()];
    let mut p = [[0.0; 3]; MAX_GROUP];
    let mut q = [[0.0; 3]; MAX_GROUP];
    for frame in traj.positions().chunks_exact(n_markers.max(1)) {
        let mut k = 0;
        for (a, &m) in group.iter().enumerate() {
            if let Some(&x) = frame.get(m)
                && mocap_io::is_present(x)
            {
                p[k] = shape[a];
                q[k] = x;
                k += 1;
            }
        }
        if k < 2 {
            frames
                .iter_mut()
                .for_each(|f| f.push(FitResidual::default()));
            continue;
        }
        let centre = |v: &mut [[f64; 3]]| {
            let mut c = [0.0; 3];
            for x in v.iter() {
                (0..3).for_each(|i| c[i] += x[i]);
            }
            c.iter_mut().for_each(|x| *x /= v.len() as f64);
            for x in v.iter_mut() {
                (0..3).for_each(|i| x[i] -= c[i]);
            }
        };
        centre(&mut p[..k]);
        centre(&mut q[..k]);
        let norms: f64 = (0..k)
            .map(|i| {
                (0..3)
                    .map(|c| p[i][c] * p[i][c] + q[i][c] * q[i][c])
                    .sum::<f64>()
            })
            .sum();
        let dof = if k >= 3 { (3 * k - 6) as f64 } else { 1.0 };
        for (mirror, fit) in frames.iter_mut().enumerate() {
            let sign = if mirror == 1 { -1.0 } else { 1.0 };
            let mut s = [[0.0; 3]; 3];
            for i in 0..k {
                let pi = [sign * p[i][0], p[i][1], p[i][2]];
                for (r, row) in s.iter_mut().enumerate() {
                    for (c, v) in row.iter_mut().enumerate() {
                        *v += pi[r] * q[i][c];
                    }
                }
            }
            let n = horn_matrix(s);
            let ss = (norms - 2.0 * largest_eigenvalue4_below(n, norms / 2.0)).max(0.0);
            fit.push(FitResidual { sum_sq: ss, dof });
        }
    }
    let [a, b] = frames;
    let total = |v: &[FitResidual]| v.iter().map(|f| f.sum_sq).sum::<f64>();
    Some(if total(&a) <= total(&b) { a } else { b })
}

/// Largest group [`fit_residual`] fits.
const MAX_GROUP: usize = 64;

/// Per-frame rigid-fit residual of `group` (marker indices) against `shape` as it is, its
/// handedness already chosen (zero dof where fewer than two markers are seen).
fn residuals(traj: &Trajectories, group: &[usize], shape: &[[f64; 3]]) -> Vec<FitResidual> {
    let mut p = [[0.0; 3]; MAX_GROUP];
    let mut q = [[0.0; 3]; MAX_GROUP];
    traj.positions()
        .chunks_exact(traj.markers().max(1))
        .map(|frame| {
            let k = seen_in(frame, group, shape, &mut p, &mut q);
            if k < 2 {
                return FitResidual::default();
            }
            let dof = if k >= 3 { (3 * k - 6) as f64 } else { 1.0 };
            FitResidual {
                sum_sq: horn(&p[..k], &q[..k]).1,
                dof,
            }
        })
        .collect()
}

/// Fills `p` with the shape points and `q` with the positions of the markers of `group`
/// seen in `frame`; returns how many.
fn seen_in(
    frame: &[[f64; 3]],
    group: &[usize],
    shape: &[[f64; 3]],
    p: &mut [[f64; 3]; MAX_GROUP],
    q: &mut [[f64; 3]; MAX_GROUP],
) -> usize {
    let mut k = 0;
    for (&m, &point) in group.iter().zip(shape).take(MAX_GROUP) {
        if let Some(&x) = frame.get(m)
            && mocap_io::is_present(x)
        {
            p[k] = point;
            q[k] = x;
            k += 1;
        }
    }
    k
}

/// Reference shape of a group holding tracks never seen together (the pieces an unlabeled
/// capture cuts a marker into at its gaps), at positions `group` of `cluster` with pair
/// distances `dist`: MDS of a core of ≥ 3 tracks all seen together (without the least seen
/// of a pair never together, one at a time), its handedness the one that fits, and every
/// other track at its mean place in the core's frame over the frames the core is posed in.
/// `None` when every pair was seen together, the core is under 3, or a track is never seen
/// while the core is posed: the completed distances serve there. Why not complete them: a
/// piece's median distances cover only its own stretch of the trial, so under skin they fit
/// no one shape with the rest, and the MDS of the completed matrix bends every marker's
/// place (snowman-hard-s30002 unlabeled, its bottom with a marker in three pieces: fit σ
/// 8.8 mm on the completed shape, 5.2 on this one, 4.3 for the marker whole, labelled),
/// which the fit split reads as a joint.
pub(crate) fn core_shape(
    traj: &Trajectories,
    cluster: &[usize],
    dist: &[f64],
    group: &[usize],
) -> Option<Vec<[f64; 3]>> {
    let n = cluster.len();
    let apart = |a: usize, b: usize| a != b && !dist[group[a] * n + group[b]].is_finite();
    let k = group.len();
    if k > MAX_GROUP || !(0..k).any(|a| (0..k).any(|b| apart(a, b))) {
        return None;
    }
    let markers: Vec<usize> = group.iter().map(|&p| cluster[p]).collect();
    let frames = || traj.positions().chunks_exact(traj.markers().max(1));
    let visible: Vec<usize> = markers
        .iter()
        .map(|&m| {
            frames()
                .filter(|f| f.get(m).is_some_and(|&x| mocap_io::is_present(x)))
                .count()
        })
        .collect();
    let mut core: Vec<usize> = (0..k).collect();
    while let Some(drop) = core
        .iter()
        .copied()
        .filter(|&a| core.iter().any(|&b| apart(a, b)))
        .min_by_key(|&a| (visible[a], a))
    {
        core.retain(|&a| a != drop);
    }
    if core.len() < 3 {
        return None;
    }
    let placed: Vec<usize> = (0..k).filter(|a| !core.contains(a)).collect();
    let core_markers: Vec<usize> = core.iter().map(|&a| markers[a]).collect();
    let core_at: Vec<usize> = core.iter().map(|&a| group[a]).collect();
    let mds = reference_shape(dist, n, &core_at)?;
    let mirrored: Vec<[f64; 3]> = mds.iter().map(|p| [-p[0], p[1], p[2]]).collect();
    let total = |shape: &[[f64; 3]]| {
        residuals(traj, &core_markers, shape)
            .iter()
            .map(|f| f.sum_sq)
            .sum::<f64>()
    };
    let core_shape = if total(&mds) <= total(&mirrored) {
        mds
    } else {
        mirrored
    };
    let (mut p, mut q) = ([[0.0; 3]; MAX_GROUP], [[0.0; 3]; MAX_GROUP]);
    let poses: Vec<Option<Pose>> = frames()
        .map(|frame| {
            let seen = seen_in(frame, &core_markers, &core_shape, &mut p, &mut q);
            (seen >= 3).then(|| horn(&p[..seen], &q[..seen]).0)
        })
        .collect();
    let mut shape = vec![[0.0; 3]; k];
    for (&a, &point) in core.iter().zip(&core_shape) {
        shape[a] = point;
    }
    for &a in &placed {
        let locals = locals_in(traj, &poses, markers[a], 1);
        if locals.is_empty() {
            return None;
        }
        let mut sum = [0.0; 3];
        for local in &locals {
            (0..3).for_each(|c| sum[c] += local[c]);
        }
        shape[a] = sum.map(|v| v / locals.len() as f64);
    }
    Some(shape)
}

/// Robust residual σ of per-frame fits, mm: the square root of the [`QUANTILE`] over frames
/// of each frame's sum of squares over its degrees of freedom. A quantile ignores a label
/// swap or a glitch lasting a minority of the frames, while a joint moves the fit in most
/// frames (the reference is the mean shape).
fn robust_sigma(frames: impl Iterator<Item = FitResidual>) -> f64 {
    let mut v: Vec<f64> = frames
        .filter(|f| f.dof > 0.0)
        .map(|f| f.sum_sq / f.dof)
        .collect();
    quantile(&mut v, QUANTILE).sqrt()
}

/// Quantile of the per-frame residual variances that stands for a fit's σ.
pub(crate) const QUANTILE: f64 = 0.75;

/// The `q` quantile (nearest rank) of `v` (reordered), NaN when empty.
pub(crate) fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let rank = ((q * v.len() as f64) as usize).min(v.len() - 1);
    *v.select_nth_unstable_by(rank, f64::total_cmp).1
}

/// A bipartition and its pooled robust fit σ: (σ mm, part A, part B), marker indices.
type Bipartition = (f64, Vec<usize>, Vec<usize>);

/// The cluster's robust fit σ and, for 4–[`MAX_ENUMERATED`] markers, the bipartition into
/// parts of ≥ 2 markers with the smallest pooled robust σ: (whole σ, pooled σ, A, B), mm.
/// The search is skipped (no bipartition) when the whole σ is within `skip_below_mm`.
fn best_bipartition(
    traj: &Trajectories,
    cluster: &[usize],
    skip_below_mm: f64,
) -> Option<(f64, Option<Bipartition>)> {
    let n = cluster.len();
    let dist = median_distances(traj, cluster);
    let all: Vec<usize> = (0..n).collect();
    let whole = robust_sigma(fit_residual(traj, cluster, &dist, &all)?.into_iter());
    if !(4..=MAX_ENUMERATED).contains(&n) || whole.is_nan() || whole <= skip_below_mm {
        return Some((whole, None));
    }
    // Masks keep the first marker in part A, so each bipartition is seen once (parts as
    // positions in the cluster). Each is a pass over the capture (up to 2^9 of them), so
    // they are fitted in parallel; the pick runs in mask order.
    let parts = |mask: u32| -> (Vec<usize>, Vec<usize>) {
        (0..n).partition(|&i| i == 0 || (mask >> (i - 1)) & 1 == 0)
    };
    let pooled: Vec<Option<f64>> = (0u32..(1u32 << (n - 1)))
        .into_par_iter()
        .map(|mask| {
            let (a, b) = parts(mask);
            if a.len() < 2 || b.len() < 2 {
                return None;
            }
            let fa = fit_residual(traj, cluster, &dist, &a)?;
            let fb = fit_residual(traj, cluster, &dist, &b)?;
            Some(robust_sigma(fa.into_iter().zip(fb).map(|(x, y)| x.add(y))))
        })
        .collect();
    let mut least: Option<(f64, u32)> = None;
    for (mask, sigma) in (0u32..).zip(pooled) {
        if let Some(sigma) = sigma
            && least.is_none_or(|(s, _)| sigma < s)
        {
            least = Some((sigma, mask));
        }
    }
    let best = least.map(|(sigma, mask)| {
        let (a, b) = parts(mask);
        let markers = |part: &[usize]| part.iter().map(|&i| cluster[i]).collect();
        (sigma, markers(&a), markers(&b))
    });
    Some((whole, best))
}

/// Splits `cluster` (marker indices) in two when its robust rigid-fit σ exceeds `ratio` ×
/// the pooled σ of the best bipartition into parts of ≥ 2 markers, and `floor_mm`;
/// recursively. Clusters outside 4–[`MAX_ENUMERATED`] markers or without a reference shape
/// stay whole.
pub(crate) fn split_by_fit(
    traj: &Trajectories,
    cluster: &[usize],
    ratio: f64,
    floor_mm: f64,
) -> Vec<Vec<usize>> {
    if !(4..=MAX_ENUMERATED).contains(&cluster.len()) {
        return vec![cluster.to_vec()];
    }
    // Below the floor no bipartition can make it split: skip the 2^(n−1) fits.
    match best_bipartition(traj, cluster, floor_mm) {
        Some((sigma, Some((pooled, a, b)))) if sigma > floor_mm && sigma > ratio * pooled => {
            let mut out = split_by_fit(traj, &a, ratio, floor_mm);
            out.extend(split_by_fit(traj, &b, ratio, floor_mm));
            out
        }
        _ => vec![cluster.to_vec()],
    }
}

/// Diagnostic: (robust σ of the whole group, best pooled σ of a bipartition or NaN) in mm.
pub(crate) fn split_sigmas(traj: &Trajectories, cluster: &[usize]) -> Option<(f64, f64)> {
    let (whole, best) = best_bipartition(traj, cluster, f64::NEG_INFINITY)?;
    Some((whole, best.map_or(f64::NAN, |b| b.0)))
}

/// Robust fit σ of `a` ∪ `b` as one body, mm.
pub(crate) fn union_sigma(traj: &Trajectories, a: &[usize], b: &[usize]) -> Option<f64> {
    let mut union = a.to_vec();
    union.extend(b);
    let dist = median_distances(traj, &union);
    let all: Vec<usize> = (0..union.len()).collect();
    Some(robust_sigma(
        fit_residual(traj, &union, &dist, &all)?.into_iter(),
    ))
}

/// The typical rigid-fit σ of a segment in this capture, mm: the median robust σ of the
/// clusters of two or more markers (most clusters are whole segments). Pairs count: a
/// two-marker fit's σ per degree of freedom measures the same as a body's, and where
/// clusters of ≥ 3 are often two segments merged across a joint (two markers on most
/// segments, or a walk's small joint motion merging pelvis and trunk, shank and foot: BTK
/// Gait.trc), their σ includes the joint's motion and a yardstick set by them keeps them
/// merged. Skin artefact sets it, not the measurement noise, so it is the scale a joint's
/// motion must clearly exceed.
pub(crate) fn typical_sigma(traj: &Trajectories, clusters: &[Vec<usize>]) -> f64 {
    let mut v: Vec<f64> = clusters
        .iter()
        .filter(|c| c.len() >= 2 && c.len() <= MAX_GROUP)
        .filter_map(|c| {
            let dist = median_distances(traj, c);
            let all: Vec<usize> = (0..c.len()).collect();
            fit_residual(traj, c, &dist, &all).map(|f| robust_sigma(f.into_iter()))
        })
        .filter(|s| s.is_finite())
        .collect();
    median(&mut v)
}

/// Splits every cluster with [`split_by_fit`] (σ above `floor_mm` and `ratio` × the best
/// bipartition's); then each piece a split produced joins the cluster, among the
/// `REJOIN_CANDIDATES` it keeps its distances to best (RMS ρ), whose union with it fits within
/// the floor (like one ordinary segment), smallest union σ first: markers ρ had put on the
/// wrong side of a joint go back to their own segment rather than stand alone. The union's
/// σ is not also held to `ratio` × the two bodies' pooled σ: a piece of two or three
/// markers absorbs skin as a body of its own, so that test keeps true pieces apart (S16
/// seeds, measured at 06c9387: hard trees 75 → 74 of 96, skin 53 → 52, messy 72 → 71 with it).
pub(crate) fn split_and_rejoin(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    clusters: Vec<Vec<usize>>,
    ratio: f64,
    floor_mm: f64,
) -> Vec<Vec<usize>> {
    // Each cluster's split search is independent (and integer-valued): run them in
    // parallel, then assemble in cluster order so the result does not depend on threads.
    let split: Vec<Vec<Vec<usize>>> = clusters
        .par_iter()
        .map(|c| split_by_fit(traj, c, ratio, floor_mm))
        .collect();
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut pieces: Vec<usize> = Vec::new();
    for parts in split {
        if parts.len() > 1 {
            pieces.extend(out.len()..out.len() + parts.len());
        }
        out.extend(parts);
    }
    for &p in &pieces {
        if out[p].is_empty() {
            continue;
        }
        let mut near: Vec<(f64, usize)> = (0..out.len())
            .filter(|&q| q != p && out[q].len() >= 2)
            .filter_map(|q| {
                let (mut sum, mut count) = (0.0, 0usize);
                for &i in &out[p] {
                    if let Some(r) = rms_rho(stats, i, &out[q], min_overlap) {
                        sum += r * r;
                        count += 1;
                    }
                }
                (count > 0).then(|| ((sum / count as f64).sqrt(), q))
            })
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let best = near
            .iter()
            .take(REJOIN_CANDIDATES)
            .filter_map(|&(_, q)| {
                let whole = union_sigma(traj, &out[p], &out[q])?;
                (whole <= floor_mm).then_some((whole, q))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        if let Some((_, q)) = best {
            let taken = std::mem::take(&mut out[p]);
            out[q].extend(taken);
        }
    }
    out.retain(|c| !c.is_empty());
    out
}

/// Clusters a split piece may rejoin: the few it keeps its distances to best.
const REJOIN_CANDIDATES: usize = 3;

/// Joins clusters of one or two markers to each other where spectral clustering had them
/// in one cluster (`spectral_of`, per marker) and their union (≥ 3 markers) fits as one
/// rigid body within `floor_mm`, like an ordinary segment; the smallest union σ first,
/// repeatedly. Skin cuts a segment into pairs whose own distances stay steady and that no
/// body of ≥ 3 is left to hold. The spectral condition keeps two true two-marker segments
/// apart across a joint that turns too little to lift their union's σ (a pair's motion
/// alone cannot show a joint). Returns how many joins were made.
pub(crate) fn join_small_clusters(
    traj: &Trajectories,
    clusters: &mut Vec<Vec<usize>>,
    floor_mm: f64,
    spectral_of: &[Option<usize>],
) -> usize {
    let origin = |c: &[usize]| {
        let first = spectral_of.get(*c.first()?).copied().flatten()?;
        c.iter()
            .all(|&m| spectral_of.get(m).copied().flatten() == Some(first))
            .then_some(first)
    };
    merge_best_pairs(
        clusters,
        |a, b| {
            a.len() <= 2
                && b.len() <= 2
                && a.len() + b.len() >= 3
                && origin(a).is_some_and(|o| origin(b) == Some(o))
        },
        |a, b| union_sigma(traj, a, b).filter(|&whole| whole <= floor_mm),
    )
}

#[cfg(test)]
mod tests {
    use super::{join_small_clusters, reference_shape, split_by_fit, typical_sigma};
    use crate::testscene::{CHILD, PARENT, hinged_capture};

    fn distance(p: [f64; 3], q: [f64; 3]) -> f64 {
        (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt()
    }

    /// Pair distances of `points`, row-major, with the pairs in `unseen` never seen together.
    fn distances(points: &[[f64; 3]], unseen: &[(usize, usize)]) -> Vec<f64> {
        let n = points.len();
        let mut dist = vec![0.0; n * n];
        for a in 0..n {
            for b in 0..n {
                let never = unseen.contains(&(a.min(b), a.max(b)));
                dist[a * n + b] = if never {
                    f64::NAN
                } else {
                    distance(points[a], points[b])
                };
            }
        }
        dist
    }

    /// A pair never seen together takes the distance the rest of the shape implies: zero for
    /// two pieces of one marker (an unlabeled capture cut at a gap), the true one for two
    /// markers; with fewer than three partners seen with both there is no shape.
    #[test]
    fn reference_shape_fills_pairs_never_seen_together() {
        let body = [
            [0.0, 0.0, 0.0],
            [80.0, 0.0, 0.0],
            [0.0, 60.0, 0.0],
            [0.0, 0.0, 50.0],
            [40.0, 30.0, 20.0],
        ];
        for sixth in [body[0], [30.0, -20.0, 45.0]] {
            let mut points = body.to_vec();
            points.push(sixth);
            let dist = distances(&points, &[(0, 5)]);
            let all: Vec<usize> = (0..6).collect();
            let shape = reference_shape(&dist, 6, &all).expect("five partners place the pair");
            for a in 0..6 {
                for b in 0..6 {
                    let (got, truth) =
                        (distance(shape[a], shape[b]), distance(points[a], points[b]));
                    assert!(
                        (got - truth).abs() < 0.05,
                        "{a}–{b}: {got} mm, truly {truth}"
                    );
                }
            }
        }
        let few = [body[0], body[1], body[2], body[0]];
        let dist = distances(&few, &[(0, 3)]);
        assert!(reference_shape(&dist, 4, &[0, 1, 2, 3]).is_none());
    }

    /// The typical σ counts two-marker clusters: a three-marker cluster across a hinge
    /// swinging ±15° is not what a segment looks like where two pairs are rigid.
    #[test]
    fn typical_sigma_counts_pairs() {
        let traj = hinged_capture(&PARENT, &CHILD, 200, 15.0, 0.2);
        let across = vec![0, 4, 5];
        let merged = typical_sigma(&traj, std::slice::from_ref(&across));
        let with_pairs = typical_sigma(&traj, &[across, vec![1, 2], vec![6, 7]]);
        assert!(
            with_pairs < 0.25 * merged,
            "{with_pairs} mm against {merged} mm"
        );
    }

    /// Two pairs of one rigid body, one cluster to spectral clustering, join; the same pairs
    /// seen apart by spectral clustering, or hinged ±15° (their union's σ above the floor),
    /// stay apart, as does a pair with a body of three.
    #[test]
    fn small_clusters_join_where_they_fit_as_one_body() {
        let (parent, child) = (&PARENT[..2], &CHILD[..2]);
        let rigid = hinged_capture(parent, child, 200, 0.0, 0.2);
        let pairs = || vec![vec![0, 1], vec![2, 3]];
        let together = [Some(0); 4];
        let mut clusters = pairs();
        assert_eq!(
            join_small_clusters(&rigid, &mut clusters, 1.0, &together),
            1
        );
        clusters[0].sort_unstable();
        assert_eq!(clusters, vec![vec![0, 1, 2, 3]]);
        let apart = [Some(0), Some(0), Some(1), Some(1)];
        let mut clusters = pairs();
        assert_eq!(join_small_clusters(&rigid, &mut clusters, 1.0, &apart), 0);
        assert_eq!(clusters, pairs());
        let hinged = hinged_capture(parent, child, 200, 15.0, 0.2);
        let mut clusters = pairs();
        assert_eq!(
            join_small_clusters(&hinged, &mut clusters, 1.0, &together),
            0
        );
        let body = hinged_capture(&PARENT[..3], child, 200, 0.0, 0.2);
        let mut clusters = vec![vec![0, 1, 2], vec![3, 4]];
        assert_eq!(
            join_small_clusters(&body, &mut clusters, 1.0, &[Some(0); 5]),
            0
        );
    }

    /// Two 3-marker bodies joined by a hinge near a straight limb, the child swinging ±12°
    /// about it while both translate: the cluster of all six splits into the two bodies,
    /// and a six-marker rigid body stays whole.
    #[test]
    fn hinge_splits_rigid_body_stays_whole() {
        let (parent, child) = (&PARENT[..3], &CHILD[..3]);
        let all: Vec<usize> = (0..6).collect();
        let traj = hinged_capture(parent, child, 200, 12.0, 0.2);
        let mut parts = split_by_fit(&traj, &all, 2.0, 1.0);
        parts.iter_mut().for_each(|p| p.sort_unstable());
        parts.sort();
        assert_eq!(parts, vec![vec![0, 1, 2], vec![3, 4, 5]]);
        let traj = hinged_capture(parent, child, 200, 0.0, 0.2);
        assert_eq!(split_by_fit(&traj, &all, 2.0, 1.0), vec![all]);
    }

    /// A body with skin whose marker an unlabeled capture cut into three pieces fits as one
    /// body about as well as with the marker whole (σ 2.5–2.9 mm against 2.7–3.0): on the
    /// completed distances' MDS shape (9.7–13.5 mm), a marker in the plane of a ring of
    /// markers has its place across the ring's plane fixed by distances only to second
    /// order, and a piece's own stretch of skin puts it tens of mm from its other pieces.
    #[test]
    fn pieces_of_a_marker_fit_on_the_shape_around_the_core() {
        // A ring of markers round a thick body's bone, as the generator places them.
        const RING: [[f64; 3]; 5] = [
            [150.0, 0.0, 100.0],
            [46.0, 143.0, 112.0],
            [-121.0, 88.0, 96.0],
            [-121.0, -88.0, 108.0],
            [46.0, -143.0, 104.0],
        ];
        use super::{core_shape, median_distances, residuals, robust_sigma, split_sigmas};
        use crate::testscene::{cut_at_gap, skin_hinged_capture};
        for seed in 1..=3 {
            let whole = skin_hinged_capture(&RING, &CHILD, 30.0, 10.0, seed);
            let cut = cut_at_gap(&cut_at_gap(&whole, 0, 100..110), 9, 250..260);
            let pieces = [0, 1, 2, 3, 4, 9, 10];
            let sigma = |traj, group: &[usize]| split_sigmas(traj, group).map(|s| s.0);
            let (Some(one), Some(cut_sigma)) =
                (sigma(&whole, &[0, 1, 2, 3, 4]), sigma(&cut, &pieces))
            else {
                panic!("seed {seed}: no fit");
            };
            let dist = median_distances(&cut, &pieces);
            let all: Vec<usize> = (0..pieces.len()).collect();
            assert!(
                core_shape(&cut, &pieces, &dist, &all).is_some(),
                "seed {seed}"
            );
            let completed = reference_shape(&dist, pieces.len(), &all).expect("completed");
            let mirrored: Vec<[f64; 3]> = completed.iter().map(|p| [-p[0], p[1], p[2]]).collect();
            let completed_sigma = [completed, mirrored]
                .iter()
                .map(|shape| robust_sigma(residuals(&cut, &pieces, shape).into_iter()))
                .fold(f64::INFINITY, f64::min);
            assert!(cut_sigma < 1.2 * one, "seed {seed}: {cut_sigma} vs {one}");
            assert!(
                completed_sigma > 1.5 * cut_sigma,
                "seed {seed}: {completed_sigma} vs {cut_sigma}"
            );
        }
    }
}
