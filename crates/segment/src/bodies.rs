//! Bodies that move independently of each other (a subject and the props it does not
//! hold, two subjects): each is segmented on its own, so that no body's markers shift the
//! noise level, tolerance, typical fit σ or k-means of another's.
//!
//! Within a body every segment is joined to a neighbour, and the markers nearest a joint
//! keep their distance across it within tens of mm (ρ); a body's single-linkage tree on ρ
//! has no link much wider than the rest. Between two bodies that move apart, the
//! steadiest cross pair still varies by hundreds of mm: the tree's links there stand far
//! above every link within either body.

use std::collections::BTreeMap;

use mocap_io::DisjointSets;

use crate::pairstats::PairStats;
use crate::{
    Glitch, LabelSwap, MarkerDiagnostics, NearJoint, Segment, Segmentation, UnassignedMarker,
};

/// The fewest markers a body is given for: fewer cannot be posed, and a marker or two
/// that keep their distance to nothing (a loose or glitching marker) stay where the
/// segmentation of the biggest body judges them, as without bodies.
const MIN_BODY_MARKERS: usize = 3;

/// The capture's markers as bodies, the biggest first (ties: the lowest marker first),
/// each ascending: the components of the single-linkage tree on ρ over `nodes` (markers
/// seen enough to judge) with every link cut that is at least `gap_ratio` times the widest
/// link left and at least `spacing_mm` (the markers' typical spacing: a pair that wanders
/// apart by more than markers sit apart), where that leaves two or more of at least
/// [`MIN_BODY_MARKERS`] markers; smaller components and every marker not in `nodes` join
/// the biggest body. Of the cuts that qualify, the one that keeps the most links (the
/// finest separation whose every cut link stands `gap_ratio` above all kept). `together`:
/// groups of markers that must share a body (the user's named segments). One body of all
/// markers where nothing qualifies, `gap_ratio` is 0 or the spacing is unknown.
pub(crate) fn independent_bodies(
    stats: &PairStats,
    nodes: &[usize],
    min_overlap: usize,
    gap_ratio: f64,
    spacing_mm: Option<f64>,
    together: &[Vec<usize>],
) -> Vec<Vec<usize>> {
    let everyone = || vec![(0..stats.n).collect::<Vec<usize>>()];
    let Some(spacing_mm) = spacing_mm else {
        return everyone();
    };
    if gap_ratio <= 0.0 || nodes.len() < 2 * MIN_BODY_MARKERS {
        return everyone();
    }
    let links = single_linkage_tree(stats, nodes, min_overlap);
    let mut widths: Vec<f64> = links.iter().map(|l| l.2).collect();
    widths.sort_by(|a, b| b.total_cmp(a));
    // The finest qualifying cut: the smallest width w with a gap below it.
    let cut = widths
        .windows(2)
        .rev()
        .filter(|w| w[0].is_finite() && w[0] >= spacing_mm && w[0] >= gap_ratio * w[1])
        .find_map(|w| {
            let mut parts = components(stats.n, nodes, &links, w[0], together);
            parts.retain(|p| p.len() >= MIN_BODY_MARKERS);
            (parts.len() >= 2).then_some(parts)
        });
    let Some(mut bodies) = cut else {
        return everyone();
    };
    bodies.sort_by(|a, b| b.len().cmp(&a.len()).then(a[0].cmp(&b[0])));
    // Small parts and markers too little seen go with the biggest body, as they would
    // with no bodies told apart.
    let mut in_body = vec![false; stats.n];
    for &m in bodies.iter().flatten() {
        in_body[m] = true;
    }
    bodies[0].extend((0..stats.n).filter(|&m| !in_body[m]));
    bodies[0].sort_unstable();
    bodies
}

/// `part`, the segmentation of `body`'s markers alone (a capture of those markers only, in
/// that order), in the indices of the whole capture, whose markers are `labels`; the other
/// markers' diagnostics are empty, for their own bodies' parts to fill.
pub(crate) fn in_capture(part: Segmentation, body: &[usize], labels: &[String]) -> Segmentation {
    let global = |m: usize| body[m];
    let mut markers = vec![
        MarkerDiagnostics {
            segment: None,
            visible_frames: 0,
            glitch_frames: 0,
            rigidity_residual_mm: f64::NAN,
            slides: false,
        };
        labels.len()
    ];
    for (m, d) in part.markers.into_iter().enumerate() {
        markers[global(m)] = d;
    }
    let to_global = |ms: Vec<usize>| -> Vec<usize> { ms.into_iter().map(global).collect() };
    Segmentation {
        segments: part
            .segments
            .into_iter()
            .map(|s| Segment {
                id: s.id,
                markers: to_global(s.markers),
            })
            .collect(),
        unassigned: part
            .unassigned
            .into_iter()
            .map(|u| UnassignedMarker {
                marker: global(u.marker),
                ..u
            })
            .collect(),
        markers,
        swaps: part
            .swaps
            .into_iter()
            .map(|s| LabelSwap {
                markers: s.markers.map(global),
                ..s
            })
            .collect(),
        glitches: part
            .glitches
            .into_iter()
            .map(|g| Glitch {
                marker: global(g.marker),
                ..g
            })
            .collect(),
        near_joints: part
            .near_joints
            .into_iter()
            .map(|n| NearJoint {
                parts: n.parts.map(to_global),
                ..n
            })
            .collect(),
        labels: labels.to_vec(),
        pieces: part.pieces.into_iter().map(to_global).collect(),
        ..part
    }
}

/// One segmentation of the whole capture from each body's own (`parts[k]` of `bodies[k]`,
/// in the capture's indices, see [`in_capture`]): the segments of all, in order of their
/// smallest marker; each marker's diagnostics from its own body's part; the eigenvalues
/// all bodies' together (the largest first) and the spectral cluster count their sum; the
/// noise level, tolerance and scatter smoothness the biggest body's; each body's segments
/// in `bodies` (a body none of whose markers is a segment left out).
pub(crate) fn merged(parts: Vec<Segmentation>, bodies: &[Vec<usize>]) -> Segmentation {
    // (body, id there, markers), in order of the smallest marker.
    let mut segments: Vec<(usize, usize, Vec<usize>)> = parts
        .iter()
        .enumerate()
        .flat_map(|(k, p)| p.segments.iter().map(move |s| (k, s.id, s.markers.clone())))
        .collect();
    segments.sort_by_key(|s| s.2.first().copied());
    let mut new_id: Vec<Vec<usize>> = parts.iter().map(|p| vec![0; p.segments.len()]).collect();
    for (id, (k, old, _)) in segments.iter().enumerate() {
        new_id[*k][*old] = id;
    }
    let mut whole = parts[0].clone();
    whole.segments = segments
        .into_iter()
        .enumerate()
        .map(|(id, (_, _, markers))| Segment { id, markers })
        .collect();
    // A part holds its own body's markers only: its lists are theirs as they stand.
    whole.unassigned = parts.iter().flat_map(|p| p.unassigned.clone()).collect();
    whole.swaps = parts.iter().flat_map(|p| p.swaps.clone()).collect();
    whole.glitches = parts.iter().flat_map(|p| p.glitches.clone()).collect();
    whole.pieces = parts.iter().flat_map(|p| p.pieces.clone()).collect();
    whole.near_joints.clear();
    whole.named_segments.clear();
    for (k, p) in parts.iter().enumerate() {
        whole
            .near_joints
            .extend(p.near_joints.iter().map(|n| NearJoint {
                segment: new_id[k][n.segment],
                ..n.clone()
            }));
        whole
            .named_segments
            .extend(p.named_segments.iter().map(|&s| new_id[k][s]));
        for &m in &bodies[k] {
            whole.markers[m] = MarkerDiagnostics {
                segment: p.markers[m].segment.map(|s| new_id[k][s]),
                ..p.markers[m].clone()
            };
        }
    }
    // Far apart in ρ, bodies have no affinity between them: the capture's spectrum is
    // theirs together, and its cluster count their sum.
    let kept = parts.iter().map(|p| p.eigenvalues.len()).max().unwrap_or(0);
    whole.eigenvalues = parts
        .iter()
        .flat_map(|p| p.eigenvalues.iter().copied())
        .collect();
    whole.eigenvalues.sort_by(|a, b| b.total_cmp(a));
    whole.eigenvalues.truncate(kept);
    whole.eigengap_segments = parts.iter().map(|p| p.eigengap_segments).sum();
    whole.bodies = new_id
        .iter()
        .map(|ids| {
            let mut ids = ids.clone();
            ids.sort_unstable();
            ids
        })
        .filter(|ids| !ids.is_empty())
        .collect();
    whole.unassigned.sort_by_key(|u| u.marker);
    whole.glitches.sort_by_key(|g| g.marker);
    whole.near_joints.sort_by_key(|n| n.segment);
    whole.named_segments.sort_unstable();
    whole.pieces.sort();
    whole
}

/// Prim's minimum spanning forest over `nodes` on ρ (pairs seen together in fewer than
/// `min_overlap` frames have no link; a node with none to the tree so far starts anew,
/// joined by an infinite link so that it is cut): `(marker, marker, ρ)` per link.
fn single_linkage_tree(
    stats: &PairStats,
    nodes: &[usize],
    min_overlap: usize,
) -> Vec<(usize, usize, f64)> {
    let n = nodes.len();
    let mut in_tree = vec![false; n];
    // Each outside node's narrowest link into the tree: (width, tree node).
    let mut best: Vec<(f64, usize)> = vec![(f64::INFINITY, 0); n];
    let mut links = Vec::with_capacity(n.saturating_sub(1));
    let mut next = 0;
    for step in 0..n {
        in_tree[next] = true;
        if step > 0 {
            links.push((nodes[best[next].1], nodes[next], best[next].0));
        }
        for k in 0..n {
            if in_tree[k] {
                continue;
            }
            if let Some(r) = stats.rho(nodes[next], nodes[k], min_overlap)
                && r < best[k].0
            {
                best[k] = (r, next);
            }
        }
        // The narrowest link next, the lowest index of equals; none: a fresh start.
        if let Some(k) = (0..n)
            .filter(|&k| !in_tree[k])
            .min_by(|&a, &b| best[a].0.total_cmp(&best[b].0).then(a.cmp(&b)))
        {
            next = k;
        }
    }
    links
}

/// The components of `nodes` under the links narrower than `width`, with each group of
/// `together` in one; each ascending, in order of their lowest marker.
fn components(
    markers: usize,
    nodes: &[usize],
    links: &[(usize, usize, f64)],
    width: f64,
    together: &[Vec<usize>],
) -> Vec<Vec<usize>> {
    let mut sets = DisjointSets::new(markers);
    for &(a, b, _) in links.iter().filter(|l| l.2 < width) {
        sets.union(a, b);
    }
    for pair in together.iter().flat_map(|g| g.windows(2)) {
        sets.union(pair[0], pair[1]);
    }
    let mut by_root: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &m in nodes {
        by_root.entry(sets.find(m)).or_default().push(m);
    }
    let mut parts: Vec<Vec<usize>> = by_root.into_values().collect();
    for p in &mut parts {
        p.sort_unstable();
    }
    parts.sort_by_key(|p| p[0]);
    parts
}
