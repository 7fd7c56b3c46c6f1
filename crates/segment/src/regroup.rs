//! Three clusters that are two segments: a small cluster between two neighbours, shared
//! out between them.
//!
//! Skin that moves the markers near a joint with the joint's angle can leave a cluster of
//! three or four markers there, some from each side (human-hard-s20020's piece holds
//! markers of the abdomen and the thorax), or cut one segment in two whose halves never
//! merge back (robot-arm-hard-s30016's first link, 3 + 2 markers); either way the capture
//! gets one segment too many. The joint test cannot mend it, since no cluster holds both
//! true segments whole, and the rigid merge cannot, since no two of the three clusters are
//! one body. Their union can: the middle cluster's markers shared out between the two
//! neighbours make the two true segments, and those two bodies explain the markers almost
//! as well as the three clusters did, where three true segments in two bodies fit clearly
//! worse (one body then spans a joint). Regrouped where the share-out (each middle marker to
//! the side it keeps its distances to best) fits within `regroup_ratio` × the three
//! clusters' pooled σ and its two bodies pass the joint test.

use mocap_io::Trajectories;

use crate::fitsplit::union_sigma;
use crate::jointsplit::{JointTest, MIN_PART, evidence_of};
use crate::pairstats::PairStats;

/// Largest middle cluster tried: the pieces a joint leaves are small.
const MAX_MIDDLE: usize = 4;

/// Largest union of three clusters tried.
const MAX_UNION: usize = 12;

/// Neighbours of a middle cluster tried: its nearest by closest mean marker distance.
const NEIGHBOURS: usize = 3;

/// Regroups, repeatedly, the three clusters (a small middle one and two of its nearest)
/// whose share-out (see [`best_regroup`]) fits within `ratio` × their pooled σ as two
/// bodies that pass `test`, the lowest ratio first; returns how many were regrouped. A
/// `ratio` of 0 does nothing.
pub(crate) fn regroup_over_splits(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    clusters: &mut Vec<Vec<usize>>,
    test: JointTest,
    ratio: f64,
) -> usize {
    if ratio <= 0.0 || test.min_z <= 0.0 {
        return 0;
    }
    let mut regrouped = 0;
    // Each regroup leaves one cluster fewer, so this ends.
    while let Some((three, parts)) = best_regroup(traj, stats, min_overlap, clusters, test, ratio) {
        let mut kept: Vec<Vec<usize>> = clusters
            .iter()
            .enumerate()
            .filter(|(i, _)| !three.contains(i))
            .map(|(_, c)| c.clone())
            .collect();
        kept.extend(parts);
        *clusters = kept;
        crate::rigidity::normalise(clusters);
        regrouped += 1;
    }
    regrouped
}

/// The best regroup of `clusters`: the three clusters' indices and the two parts.
///
/// The two parts keep the two neighbours apart and share the middle cluster's markers out
/// between them, each to the side whose markers it keeps its distances to best (smallest
/// mean ρ): its markers are what skin put on the wrong side of a joint, or a piece of one
/// neighbour's segment. Each fit σ is read once per cluster; the joint test only where the
/// share-out fits well enough.
fn best_regroup(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    clusters: &[Vec<usize>],
    test: JointTest,
    ratio: f64,
) -> Option<([usize; 3], [Vec<usize>; 2])> {
    // Closest mean distance between two clusters' markers (mm).
    let gap = |x: &[usize], y: &[usize]| {
        x.iter()
            .flat_map(|&i| y.iter().map(move |&j| stats.mean[stats.at(i, j)]))
            .filter(|d| d.is_finite())
            .fold(f64::INFINITY, f64::min)
    };
    // Mean ρ of marker `m` to the markers of `side` it was seen with (mm).
    let steadiness = |m: usize, side: &[usize]| {
        let (sum, count) = side
            .iter()
            .filter_map(|&k| stats.rho(m, k, min_overlap))
            .fold((0.0, 0usize), |(s, n), r| (s + r, n + 1));
        if count == 0 {
            f64::INFINITY
        } else {
            sum / count as f64
        }
    };
    let sigma = |c: &[usize]| union_sigma(traj, c, &[]).filter(|s| s.is_finite());
    let own_sigma: Vec<Option<f64>> = clusters.iter().map(|c| sigma(c)).collect();
    // Pooled σ, markers weighting each body's variance; NaN when none fits.
    let pooled = |groups: &[(usize, Option<f64>)]| {
        let (mut sum, mut count) = (0.0, 0.0);
        for &(n, s) in groups {
            if let Some(s) = s {
                sum += n as f64 * s * s;
                count += n as f64;
            }
        }
        (sum / count).sqrt()
    };
    let mut best: Option<(f64, [usize; 3], [Vec<usize>; 2])> = None;
    for (x, middle) in clusters.iter().enumerate() {
        if middle.len() > MAX_MIDDLE {
            continue;
        }
        let mut near: Vec<(f64, usize)> = (0..clusters.len())
            .filter(|&c| c != x)
            .map(|c| (gap(middle, &clusters[c]), c))
            .filter(|(d, _)| d.is_finite())
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        near.truncate(NEIGHBOURS);
        for (i, &(_, z)) in near.iter().enumerate() {
            for &(_, y) in &near[i + 1..] {
                let (side_z, side_y) = (&clusters[z], &clusters[y]);
                if side_z.len() + middle.len() + side_y.len() > MAX_UNION {
                    continue;
                }
                let mut a = side_z.clone();
                let mut b = side_y.clone();
                for &m in middle {
                    if steadiness(m, side_z) <= steadiness(m, side_y) {
                        a.push(m);
                    } else {
                        b.push(m);
                    }
                }
                if a.len() < MIN_PART || b.len() < MIN_PART {
                    continue;
                }
                let three_sigma = pooled(&[
                    (side_z.len(), own_sigma[z]),
                    (middle.len(), own_sigma[x]),
                    (side_y.len(), own_sigma[y]),
                ]);
                let two_sigma = pooled(&[(a.len(), sigma(&a)), (b.len(), sigma(&b))]);
                let r = two_sigma / three_sigma;
                if !(r.is_finite() && r <= ratio && best.as_ref().is_none_or(|(br, _, _)| r < *br))
                {
                    continue;
                }
                let passes = evidence_of(traj, &a, &b, test.typical_sigma_mm)
                    .is_some_and(|e| test.passes(&e));
                if passes {
                    let mut three = [z, x, y];
                    three.sort_unstable();
                    best = Some((r, three, [a, b]));
                }
            }
        }
    }
    best.map(|(_, three, parts)| (three, parts))
}

#[cfg(test)]
mod tests {
    use mocap_io::Trajectories;

    use super::regroup_over_splits;
    use crate::fitsplit::typical_sigma;
    use crate::jointsplit::JointTest;
    use crate::pairstats::pair_stats;
    use crate::testscene::{CHILD, PARENT, hinge_x, hinged_capture, moving_capture};

    /// The default joint test for a capture whose true bodies are `bodies`.
    fn test_for(traj: &Trajectories, bodies: &[Vec<usize>]) -> JointTest {
        let p = crate::Params::default();
        let typical = typical_sigma(traj, bodies);
        JointTest {
            min_z: p.joint_split_z,
            min_travel_z: p.joint_travel_z,
            rotation_travel_z: p.joint_rotation_travel_z,
            rotation_alone_z: p.joint_rotation_alone_z,
            centre_fraction: p.joint_centre_fraction,
            pair: crate::pairsplit::PairTest::default(),
            typical_sigma_mm: typical,
            max_part_sigma_mm: p.segment_sigma_mm(typical),
        }
    }

    /// A parent and a hinged child of four markers each, clustered 3 | 1 + 2 | 2 (a piece
    /// mixing both sides at the joint): the three regroup as the two bodies; off at ratio 0.
    #[test]
    fn a_piece_mixing_two_bodies_regroups_into_them() {
        let traj = hinged_capture(&PARENT, &CHILD, 300, 40.0, 0.5);
        let stats = pair_stats(&traj);
        let bodies = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
        let test = test_for(&traj, &bodies);
        let pieces = vec![vec![0, 1, 2], vec![3, 4, 5], vec![6, 7]];
        let mut off = pieces.clone();
        assert_eq!(
            regroup_over_splits(&traj, &stats, 10, &mut off, test, 0.0),
            0
        );
        assert_eq!(off, pieces);
        let mut clusters = pieces;
        assert_eq!(
            regroup_over_splits(&traj, &stats, 10, &mut clusters, test, 1.15),
            1
        );
        assert_eq!(clusters, bodies);
    }

    /// Three bodies in a chain, each hinged on the one before with its own phase: no two of
    /// them are one body, so the three stay three, by the joint test's part bound and by
    /// the ratio each on its own.
    #[test]
    fn three_bodies_stay_three() {
        let grandchild: Vec<[f64; 3]> = CHILD.iter().map(|p| [p[0], p[1], p[2] - 350.0]).collect();
        let traj = moving_capture(12, 300, 0.5, |t, k| {
            let knee = (0.7 * t).sin() * 40f64.to_radians();
            let ankle = (1.3 * t + 0.5).sin() * 35f64.to_radians();
            match k {
                0..4 => PARENT[k],
                4..8 => hinge_x(knee, CHILD[k - 4], 0.0),
                _ => {
                    // Turned about the lower hinge (z = -350) with the child, then the child's.
                    let about_ankle = hinge_x(ankle, grandchild[k - 8], -350.0);
                    hinge_x(knee, about_ankle, 0.0)
                }
            }
        });
        let stats = pair_stats(&traj);
        let bodies = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7], vec![8, 9, 10, 11]];
        let test = test_for(&traj, &bodies);
        let mut clusters = bodies.clone();
        assert_eq!(
            regroup_over_splits(&traj, &stats, 10, &mut clusters, test, 1.15),
            0
        );
        assert_eq!(clusters, bodies);
        // The joint test's part bound stops it first (a part spanning a joint fits like no
        // segment); without that bound the ratio alone keeps the three, as only a ratio far
        // beyond any two-body fit lets two true segments become one body.
        let lax = JointTest {
            max_part_sigma_mm: f64::INFINITY,
            ..test
        };
        let mut clusters = bodies.clone();
        assert_eq!(
            regroup_over_splits(&traj, &stats, 10, &mut clusters, lax, 1.15),
            0
        );
        assert_eq!(
            regroup_over_splits(&traj, &stats, 10, &mut clusters, lax, 100.0),
            1
        );
        assert_eq!(clusters, [vec![0, 1, 2, 3, 4, 5, 6, 7], vec![8, 9, 10, 11]]);
    }
}
