//! Tracks seen only while their cluster held still against another: which segment they are
//! on, the data cannot say.
//!
//! A marker keeps its distances to its own segment's markers and, across a joint, changes
//! them as the joint turns. A track seen only briefly (an unlabeled capture's short piece,
//! or a marker hidden most of the time) may have been seen only while a neighbouring
//! segment held still against its own (moved against it, by the distances across them,
//! less than [`WITNESSED_SHARE`] of what it does over the capture): it then keeps its
//! distances to both alike, and whichever cluster the clustering gave it, it may pose the
//! wrong segment while it is seen (a 35-frame piece of a snake's link4 marker posed link5
//! for those frames and re-hung link4 in the tree). Such a track is left out, with the
//! reason. A track rigid with two clusters that did turn against each other while it was
//! seen sits at their joint, and stays where it is.

use crate::glitch::distance;
use crate::pairstats::PairStats;
use crate::pieces::span;
use crate::segmentation::UnassignedMarker;
use mocap_io::Trajectories;

/// A track decides between two clusters when, while it was seen, they moved against each
/// other by at least this share of their motion over the whole capture (ρ's ratio). Leaving
/// a marker out loses its data, so only a joint seen to move far less than it does leaves
/// it undecided: before the no-worse condition, 1/3 and 1/2 gave 249 and 248 exact trees
/// on the hard suite's unlabeled trials at 2–3 markers per segment, and 1/2 took out two
/// labelled markers seen in half the frames or more (shares 0.45 and 0.50).
const WITNESSED_SHARE: f64 = 1.0 / 3.0;

/// Distance standard deviation of markers `a` and `b` over the frames in which `t`, `a` and
/// `b` are all seen (`t` is seen only within `span`), and the number of those frames.
fn rho_while_seen(
    traj: &Trajectories,
    (t, span): (usize, std::ops::RangeInclusive<usize>),
    a: usize,
    b: usize,
) -> (f64, usize) {
    // Welford's running mean and sum of squared deviations: stable without a buffer.
    let (mut count, mut mean, mut m2) = (0usize, 0.0f64, 0.0f64);
    for f in span {
        let (Some(_), Some(x), Some(y)) = (traj.get(f, t), traj.get(f, a), traj.get(f, b)) else {
            continue;
        };
        let d = distance(x, y);
        count += 1;
        let delta = d - mean;
        mean += delta / count as f64;
        m2 += delta * (d - mean);
    }
    let rho = if count > 0 {
        (m2 / count as f64).sqrt()
    } else {
        0.0
    };
    (rho, count)
}

/// Track `t`'s largest ρ to the markers of `group` it was seen with for ≥ `min_overlap`
/// frames; `None` when it was seen so with none.
fn loosest_rho(stats: &PairStats, t: usize, group: &[usize], min_overlap: usize) -> Option<f64> {
    group
        .iter()
        .filter(|&&m| m != t)
        .filter_map(|&m| stats.rho(t, m, min_overlap))
        .max_by(f64::total_cmp)
}

/// The cluster (index) that `t`, a member of cluster `own` and rigid with it (ρ ≤ `tol_mm`),
/// keeps its distances to no worse than to its own (largest ρ against largest ρ), where
/// over the frames `t` was seen the two clusters moved against each other by less than
/// [`WITNESSED_SHARE`] of what they do over the capture (the root mean square ratio of each
/// cross pair's ρ then to its ρ over all its frames); `None` when the data place it.
fn undecided_against(
    traj: &Trajectories,
    stats: &PairStats,
    clusters: &[Vec<usize>],
    own: usize,
    t: usize,
    tol_mm: f64,
    min_overlap: usize,
) -> Option<usize> {
    let own_group = &clusters[own];
    let own_rho = loosest_rho(stats, t, own_group, min_overlap).filter(|&r| r <= tol_mm)?;
    // Only the frames from its first sighting to its last can see it.
    let (first, last) = span(traj, t)?;
    let seen = first..=last;
    (0..clusters.len()).filter(|&r| r != own).find(|&r| {
        let other = &clusters[r];
        // Kept its distances to the other no worse than to its own: the clustering's choice
        // had nothing to go on.
        if loosest_rho(stats, t, other, min_overlap).is_none_or(|rho| rho > own_rho) {
            return false;
        }
        let (mut witnessed, mut overall) = (0.0, 0.0);
        for &a in own_group.iter().filter(|&&a| a != t) {
            for &b in other {
                let (rho, frames) = rho_while_seen(traj, (t, seen.clone()), a, b);
                let Some(all) = stats.rho(a, b, min_overlap) else {
                    continue;
                };
                if frames < min_overlap {
                    continue;
                }
                witnessed += rho * rho;
                overall += all * all;
            }
        }
        overall > 0.0 && witnessed < WITNESSED_SHARE * WITNESSED_SHARE * overall
    })
}

/// Leaves out of `clusters` each track the data cannot place (see the module docs), into
/// `unassigned` with the reason; a cluster keeps at least two markers, and tracks `fixed`
/// marks (the user's groups) stay.
pub(crate) fn leave_out_undecided(
    traj: &Trajectories,
    stats: &PairStats,
    clusters: &mut [Vec<usize>],
    unassigned: &mut Vec<UnassignedMarker>,
    fixed: &[bool],
    tol_mm: f64,
    min_overlap: usize,
) {
    let labels = traj.labels();
    let label = |m: usize| labels.get(m).map_or("?", String::as_str);
    // Decided on the clusters as they stand, then taken out, so the order does not matter.
    let mut out: Vec<(usize, usize, usize)> = Vec::new();
    for (own, group) in clusters.iter().enumerate() {
        for &t in group {
            if fixed.get(t).copied().unwrap_or(false) {
                continue;
            }
            if let Some(other) =
                undecided_against(traj, stats, clusters, own, t, tol_mm, min_overlap)
            {
                out.push((own, t, other));
            }
        }
    }
    for (own, t, other) in out {
        if clusters[own].len() <= 2 {
            continue;
        }
        let name_of = |c: usize| {
            clusters[c]
                .iter()
                .filter(|&&m| m != t)
                .map(|&m| label(m))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let reason = format!(
            "seen in {} frames, over which the markers {} and {} moved against each other \
             less than a third as much as over the capture, and it kept its distances to \
             both: which segment it is on cannot be told",
            stats.visible[t],
            name_of(own),
            name_of(other)
        );
        clusters[own].retain(|&m| m != t);
        unassigned.push(UnassignedMarker { marker: t, reason });
    }
    unassigned.sort_by_key(|u| u.marker);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pairstats::pair_stats;
    use crate::testscene::{CHILD, PARENT, hinge_x, moving_capture};
    use mocap_io::MISSING;

    /// Parent markers 0–3, child markers 4–7 hinged about the x axis, still for the first 2 s
    /// (40 frames) and swinging after; marker 8 on the child seen only while it was still,
    /// marker 9 on the hinge axis seen throughout.
    fn still_then_swinging() -> Trajectories {
        let on_child = [25.0, 20.0, -120.0];
        let on_axis = [40.0, 0.0, 0.0];
        let whole = moving_capture(10, 200, 0.2, |t, k| {
            let angle = if t < 2.0 {
                0.0
            } else {
                40f64.to_radians() * (0.7 * (t - 2.0)).sin()
            };
            match k {
                0..4 => PARENT[k],
                4..8 => hinge_x(angle, CHILD[k - 4], 0.0),
                8 => hinge_x(angle, on_child, 0.0),
                _ => on_axis,
            }
        });
        let mut positions = whole.positions().to_vec();
        for f in 40..200 {
            positions[f * 10 + 8] = MISSING;
        }
        match Trajectories::new(whole.labels().to_vec(), 100.0, 1, 200, positions) {
            Ok(traj) => traj,
            Err(e) => panic!("scene: {e}"),
        }
    }

    #[test]
    fn a_track_seen_only_while_the_joint_held_still_is_left_out() {
        let traj = still_then_swinging();
        let stats = pair_stats(&traj);
        // The clustering gave the child's brief marker to the parent, as it gave the hinge's.
        let mut clusters = vec![vec![0, 1, 2, 3, 8, 9], vec![4, 5, 6, 7]];
        let mut unassigned = Vec::new();
        leave_out_undecided(
            &traj,
            &stats,
            &mut clusters,
            &mut unassigned,
            &[false; 10],
            2.0,
            10,
        );
        assert_eq!(clusters, vec![vec![0, 1, 2, 3, 9], vec![4, 5, 6, 7]]);
        assert_eq!(unassigned.len(), 1);
        assert_eq!(unassigned[0].marker, 8);
        assert!(
            unassigned[0].reason.contains("M4"),
            "{}",
            unassigned[0].reason
        );
        // A track the user named stays.
        let mut clusters = vec![vec![0, 1, 2, 3, 8, 9], vec![4, 5, 6, 7]];
        let mut fixed = [false; 10];
        fixed[8] = true;
        leave_out_undecided(
            &traj,
            &stats,
            &mut clusters,
            &mut Vec::new(),
            &fixed,
            2.0,
            10,
        );
        assert_eq!(clusters[0], vec![0, 1, 2, 3, 8, 9]);
    }
}
