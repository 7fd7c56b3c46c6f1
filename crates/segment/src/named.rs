//! Segments the user names (`segment.groups`): where the data cannot decide (a joint that
//! turns no more than skin moves its markers), the person who put the markers on can.
//! Each named group becomes a segment of exactly its markers, taken out of the segments the
//! grouping found; everything else stays as found.

use std::collections::BTreeSet;

use crate::{Error, UnassignedMarker};

/// Resolves `groups` (labels or `*` patterns) to marker indices, ascending per group:
/// an error names the group and the label that matches nothing, or a marker two groups name.
pub(crate) fn resolve(labels: &[String], groups: &[Vec<String>]) -> Result<Vec<Vec<usize>>, Error> {
    let mut named_by: Vec<Option<usize>> = vec![None; labels.len()];
    let mut out = Vec::with_capacity(groups.len());
    for (g, group) in groups.iter().enumerate() {
        let error = |detail: String| Error::Group {
            group: g + 1,
            labels: group.clone(),
            detail,
        };
        let mut markers = BTreeSet::new();
        for pattern in group {
            let found = mocap_io::markers_named(labels, pattern);
            if found.is_empty() {
                return Err(error(mocap_io::no_marker_named(labels, pattern)));
            }
            markers.extend(found);
        }
        for &m in &markers {
            if let Some(other) = named_by[m] {
                return Err(error(format!(
                    "marker {:?} is in group {} too; a marker is in one segment",
                    labels[m],
                    other + 1
                )));
            }
            named_by[m] = Some(g);
        }
        out.push(markers.into_iter().collect());
    }
    Ok(out)
}

/// Makes each of `named` (marker indices) a cluster of its own: its markers leave the
/// clusters they were in and `unassigned`; a cluster that loses some and keeps fewer than
/// `min_markers` is unassigned, with the reason. Clusters come back normalised.
pub(crate) fn apply(
    clusters: &mut Vec<Vec<usize>>,
    unassigned: &mut Vec<UnassignedMarker>,
    named: &[Vec<usize>],
    min_markers: usize,
    labels: &[String],
) {
    if named.is_empty() {
        return;
    }
    let is_named: BTreeSet<usize> = named.iter().flatten().copied().collect();
    unassigned.retain(|u| !is_named.contains(&u.marker));
    for cluster in clusters.iter_mut() {
        let before = cluster.len();
        cluster.retain(|m| !is_named.contains(m));
        if cluster.len() < before && !cluster.is_empty() && cluster.len() < min_markers {
            let taken: Vec<&str> = cluster.iter().map(|&m| labels[m].as_str()).collect();
            for &m in cluster.iter() {
                unassigned.push(UnassignedMarker {
                    marker: m,
                    reason: format!(
                        "its segment's other markers went to groups segment.groups names, \
                         leaving {} ({}), fewer than min_segment_markers {min_markers}",
                        taken.len(),
                        taken.join(", ")
                    ),
                });
            }
            cluster.clear();
        }
    }
    clusters.extend(named.iter().cloned());
    crate::rigidity::normalise(clusters);
    unassigned.sort_by_key(|u| u.marker);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("M{i}")).collect()
    }

    fn group(labels: &[&str]) -> Vec<String> {
        labels.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn labels_and_patterns_resolve_to_markers() {
        let l = labels(12);
        let g = resolve(&l, &[group(&["M3", "M1"]), group(&["M1?", "M1*"])]);
        // "M1?" has no `?` wildcard: it names nothing.
        assert!(matches!(g, Err(Error::Group { group: 2, .. })), "{g:?}");
        let g = resolve(&l, &[group(&["M3", "M2"]), group(&["M1*"])]).unwrap();
        assert_eq!(g, vec![vec![2, 3], vec![1, 10, 11]]);
    }

    #[test]
    fn a_marker_in_two_groups_or_an_unknown_label_is_an_error_naming_it() {
        let l = labels(6);
        let e = resolve(&l, &[group(&["M1", "M2"]), group(&["M2", "M3"])]).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("group 2") && text.contains("\"M2\"") && text.contains("group 1"),
            "{text}"
        );
        let e = resolve(&l, &[group(&["m4"])]).unwrap_err().to_string();
        assert!(
            e.contains("no marker labelled \"m4\"") && e.contains("did you mean \"M4\""),
            "{e}"
        );
    }

    #[test]
    fn a_named_group_is_cut_out_of_its_segments_and_small_rests_are_unassigned() {
        let l = labels(10);
        // Found: a body of 0..=4 holding a coxa 3, 4; a pair 5, 6; 7, 8, 9 unassigned.
        let mut clusters = vec![vec![0, 1, 2, 3, 4], vec![5, 6]];
        let mut unassigned: Vec<UnassignedMarker> = (7..10)
            .map(|marker| UnassignedMarker {
                marker,
                reason: "as found".into(),
            })
            .collect();
        // Name the coxa with one marker of the pair and one unassigned marker.
        apply(&mut clusters, &mut unassigned, &[vec![3, 4, 6, 9]], 2, &l);
        assert_eq!(clusters, vec![vec![0, 1, 2], vec![3, 4, 6, 9]]);
        let left: Vec<(usize, bool)> = unassigned
            .iter()
            .map(|u| (u.marker, u.reason.contains("segment.groups")))
            .collect();
        assert_eq!(left, vec![(5, true), (7, false), (8, false)]);
    }
}
