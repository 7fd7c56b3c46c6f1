//! Kruskal's minimum spanning tree over the pair costs, the root choice and the
//! breadth-first joint order.

use std::collections::VecDeque;

use jointfit::{JointKind, PairFits};
use mocap_io::DisjointSets;
use segment::Segmentation;

use crate::independence::HubCorrelations;
use crate::{Error, Params, RunnerUp, SegmentRef, Topology, TreeJoint};

/// Builds the segment tree: Kruskal on the pair costs, a root, joints in BFS order.
///
/// See the crate docs for how rigid pairs, unusable costs, ties and the root are handled.
pub fn run(seg: &Segmentation, fits: &PairFits, params: &Params) -> Result<Topology, Error> {
    let n = seg.segments.len();
    if n == 0 {
        let first_reason = seg
            .unassigned
            .first()
            .map(|u| format!(", e.g. marker {}: {}", u.marker, u.reason))
            .unwrap_or_default();
        return Err(Error::NoSegments {
            unassigned: seg.unassigned.len(),
            first_reason,
        });
    }
    if fits.poses.len() != n {
        return Err(Error::SegmentCountMismatch {
            segments: n,
            poses: fits.poses.len(),
        });
    }
    let marker_count: Vec<usize> = seg.segments.iter().map(|s| s.markers.len()).collect();
    let mut notes = Vec::new();
    if n == 1 {
        notes.push(one_body_note(seg));
    }

    let named = named_pairs(seg, fits, &params.joints)?;
    // Pairs that are no joint leave every rule below as pairs without a usable fit do.
    let (refused, bodies) = refused_pairs(fits, &named, seg, &marker_count, params);
    let masked;
    let fits = if refused.is_empty() {
        fits
    } else {
        masked = without_pairs(fits, &refused);
        let sizes: Vec<usize> = bodies.iter().map(Vec::len).collect();
        let apart = if seg.bodies.len() > 1 && params.stationary_residual_ratio > 0.0 {
            format!(
                "; between the {} bodies the segment stage saw move independently, \
                 topo.stationary_residual_ratio {} times, or a misfit at most \
                 topo.stationary_misfit {}",
                seg.bodies.len(),
                params.stationary_residual_ratio,
                params.stationary_misfit
            )
        } else {
            String::new()
        };
        notes.push(format!(
            "{} bodies, of {sizes:?} segments (two subjects, a subject and a prop, or the \
             markers that never move): the pairs that fit a joint (a residual at most \
             topo.max_residual_ratio {} times the typical joint's{apart}) join the segments \
             so, and the {} pair(s) from one body to another disagree about a common centre \
             by more: no joint",
            bodies.len(),
            params.max_residual_ratio,
            refused.len()
        ));
        &masked
    };
    let body_segment = params
        .body
        .as_ref()
        .map(|r| {
            segment_of(seg, r).map_err(|reason| Error::BadBody {
                body: r.to_string(),
                reason,
            })
        })
        .transpose()?;
    let forced_root = params
        .root
        .as_ref()
        .map(|r| {
            segment_of(seg, r).map_err(|reason| Error::BadRoot {
                root: r.to_string(),
                reason,
                tree: (0..n).collect(),
            })
        })
        .transpose()?;
    // Candidate edges: (rank, cost, a, b, pair index), taken by rank, then cost.
    let mut edges: Vec<(u8, f64, usize, usize, usize)> = Vec::with_capacity(fits.pairs.len());
    for (i, p) in fits.pairs.iter().enumerate() {
        if p.a >= p.b || p.b >= n {
            return Err(Error::BadPair {
                pair: i,
                a: p.a,
                b: p.b,
                segments: n,
            });
        }
        if !p.cost.is_finite() {
            continue;
        }
        let rank = if named.contains(&i) {
            NAMED
        } else if params.rigid_first && p.tree_kind() == JointKind::Rigid {
            RIGID
        } else {
            ORDINARY
        };
        edges.push((rank, p.cost, p.a, p.b, i));
    }
    if params.composite_rotation_ratio > 0.0
        || params.composite_hinge_cost_ratio > 0.0
        || params.composite_independence_margin > 0.0
    {
        take_composites_after_their_joints(&mut edges, fits, n, params);
    }
    edges.sort_by(|x, y| {
        x.0.cmp(&y.0)
            .then(x.1.total_cmp(&y.1))
            .then(x.2.cmp(&y.2))
            .then(x.3.cmp(&y.3))
    });
    break_near_ties(&mut edges, fits, params);

    let mut sets = DisjointSets::new(n);
    let mut accepted = Vec::new();
    for &(rank, _, a, b, pair) in &edges {
        let cost = fits.pairs[pair].cost;
        if sets.union(a, b) {
            if rank == NAMED {
                notes.push(format!(
                    "segments {a} and {b} joined as topo.joints names them"
                ));
            } else if rank == RIGID {
                notes.push(format!(
                    "segments {a} and {b} do not move relative to each other (pair kind rigid \
                     on their own poses); joined first: they are probably one body split in two"
                ));
            }
            accepted.push((a, b, pair, cost));
        } else if rank == NAMED {
            return Err(Error::BadJoint {
                a: a.to_string(),
                b: b.to_string(),
                reason: "with the other pairs topo.joints names it closes a loop; a tree has \
                         none"
                    .into(),
            });
        }
    }
    // The rules below move edges the data hardly decide; never the user's.
    let fixed: Vec<bool> = accepted.iter().map(|e| named.contains(&e.2)).collect();
    notes.extend(crate::twins::hang_twins_on_one_parent(
        &mut accepted,
        &fixed,
        fits,
        n,
        params,
    ));
    notes.extend(crate::twins::hang_shared_leaves_on_the_twins_parent(
        &mut accepted,
        &fixed,
        fits,
        n,
        params,
    ));

    // Components; the tree is the forced root's, else the biggest (segments, markers, id).
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n];
    for s in 0..n {
        let r = sets.find(s);
        members[r].push(s);
    }
    let components: Vec<&Vec<usize>> = members.iter().filter(|m| !m.is_empty()).collect();
    let tree_set: Vec<usize> = match (forced_root, body_segment) {
        (Some(root), Some(b)) if sets.find(root) != sets.find(b) => {
            return Err(Error::BadRoot {
                root: root.to_string(),
                reason: format!("it lies in another body than topo.body's segment {b}"),
                tree: members[sets.find(b)].clone(),
            });
        }
        (Some(root), _) => {
            notes.push(format!("root forced to segment {root} (topo.root)"));
            members[sets.find(root)].clone()
        }
        (None, Some(b)) => {
            notes.push(format!("the tree of segment {b}'s body (topo.body)"));
            members[sets.find(b)].clone()
        }
        (None, None) => components
            .iter()
            .min_by(|x, y| bigger_first(x, y, &marker_count, seg.stationary_segment))
            .map(|c| (*c).clone())
            .unwrap_or_default(),
    };
    let body = bodies
        .iter()
        .position(|b| tree_set.first().is_some_and(|s| b.contains(s)));
    let mut in_tree = vec![false; n];
    for &s in &tree_set {
        in_tree[s] = true;
    }
    let mut has_edge = vec![false; n];
    for p in &fits.pairs {
        if p.cost.is_finite() {
            has_edge[p.a] = true;
            has_edge[p.b] = true;
        }
    }
    let detached_segments: Vec<usize> = (0..n).filter(|&s| !in_tree[s]).collect();
    for &s in &detached_segments {
        // Another body's segments are that body's (`bodies`, which the note on bodies
        // counts), not detached one by one.
        if bodies.iter().any(|b| b.contains(&s)) {
            continue;
        }
        if has_edge[s] {
            let comp = &members[sets.find(s)];
            notes.push(format!(
                "segment {s} is detached: its component {comp:?} has no finite-cost pair with the tree"
            ));
        } else {
            notes.push(format!(
                "segment {s} is detached: no pair fit with a finite cost involves it"
            ));
        }
    }

    // Tree adjacency, neighbours ascending for a deterministic BFS.
    let mut adjacency: Vec<Vec<(usize, usize, f64)>> = vec![Vec::new(); n];
    for &(a, b, pair, cost) in &accepted {
        if in_tree[a] {
            adjacency[a].push((b, pair, cost));
            adjacency[b].push((a, pair, cost));
        }
    }
    for adj in &mut adjacency {
        adj.sort_by_key(|e| e.0);
    }

    // A tree that holds the markers that never move is a fixed mechanism's: its ground
    // link, the base, is the root, as the frame every other segment's motion is read in.
    let fixed_base = seg
        .stationary_segment
        .filter(|room| tree_set.contains(room) && tree_set.len() > 1);
    let root_segment = match (forced_root, fixed_base) {
        (Some(root), _) => root,
        (None, Some(base)) => {
            notes.push(format!(
                "root: segment {base}, the markers that never move (a fixed base; topo.root \
                 picks another)"
            ));
            base
        }
        (None, None) => centre(&tree_set, &adjacency, &marker_count, |s| {
            spatial_spread(fits, &tree_set, s)
        }),
    };

    // Breadth-first from the root: every parent joint before its children.
    let mut joints: Vec<TreeJoint> = Vec::with_capacity(tree_set.len().saturating_sub(1));
    let mut joint_of_segment: Vec<Option<usize>> = vec![None; n];
    let mut visited = vec![false; n];
    let mut queue = VecDeque::from([root_segment]);
    visited[root_segment] = true;
    while let Some(parent) = queue.pop_front() {
        for &(child, pair, cost) in &adjacency[parent] {
            if visited[child] {
                continue;
            }
            visited[child] = true;
            joint_of_segment[child] = Some(joints.len());
            joints.push(TreeJoint {
                name: format!("j{child}"),
                parent_segment: parent,
                child_segment: child,
                pair,
                parent_joint: joint_of_segment[parent],
                cost,
                runner_up: None,
                named: named.contains(&pair),
            });
            queue.push_back(child);
        }
    }
    let runner_ups = runner_ups(&joints, &in_tree, fits);
    for (joint, runner_up) in joints.iter_mut().zip(runner_ups) {
        joint.runner_up = runner_up;
    }

    Ok(Topology {
        root_segment,
        joints,
        detached_segments,
        notes,
        bodies,
        body,
    })
}

/// The pairs (indices into `fits.pairs`) between bodies, and the bodies (segments
/// ascending, [`bigger_first`]; empty for one body). Where the pairs the user named, and
/// those whose residual is at most `max_residual_ratio` times the typical joint's
/// ([`typical_joint_residual`], at least the capture's measurement noise `noise_mm`) or
/// at most the capture's longest segment that moves ([`longest_segment_mm`]), join the
/// segments into more than one body: the finite-cost pairs from one body to another.
/// Within one body nothing is refused, so a capture of one subject keeps every pair.
fn refused_pairs(
    fits: &PairFits,
    named: &[usize],
    seg: &Segmentation,
    marker_count: &[usize],
    params: &Params,
) -> (Vec<usize>, Vec<Vec<usize>>) {
    if params.max_residual_ratio <= 0.0 {
        return (Vec::new(), Vec::new());
    }
    let Some(typical) = typical_joint_residual(fits) else {
        return (Vec::new(), Vec::new());
    };
    // A segment of one or two markers poses poorly, and its joints' residuals run far past
    // the typical one (up to 121 mm against a typical 0 on clean trials with 1-3 markers
    // per segment): a pair is between bodies only where its centres also disagree by more
    // than the capture's longest segment that moves (the markers that never move span the
    // room, not a body).
    let limit = (params.max_residual_ratio * typical.max(seg.noise_mm).max(RESIDUAL_FLOOR_MM))
        .max(longest_segment_mm(fits, seg.stationary_segment));
    // The room joins a body only by a joint as tight as a typical one: a fixed base's. So
    // do bodies the segment stage saw move independently (a prop the subject lets go of
    // is no joint, a limb only sparse markers hold across its joint is).
    let room_limit = (params.stationary_residual_ratio > 0.0).then(|| {
        params.stationary_residual_ratio * typical.max(seg.noise_mm).max(RESIDUAL_FLOOR_MM)
    });
    let n = fits.poses.len();
    let mut moving_body: Vec<Option<usize>> = vec![None; n];
    for (k, body) in seg.bodies.iter().enumerate() {
        for &s in body.iter().filter(|&&s| s < n) {
            moving_body[s] = Some(k);
        }
    }
    let apart = |a: usize, b: usize| {
        seg.stationary_segment
            .is_some_and(|room| room == a || room == b)
            || matches!((moving_body[a], moving_body[b]), (Some(x), Some(y)) if x != y)
    };
    let usable = |i: usize| {
        let p = &fits.pairs[i];
        p.cost.is_finite() && p.a < p.b && p.b < n
    };
    let mut bodies = DisjointSets::new(n);
    let mut paired = vec![false; n];
    for i in (0..fits.pairs.len()).filter(|&i| usable(i)) {
        let p = &fits.pairs[i];
        (paired[p.a], paired[p.b]) = (true, true);
        let fits_joint = match room_limit {
            Some(room_limit) if apart(p.a, p.b) => {
                p.residual_rms_mm <= room_limit || p.misfit_over_noise <= params.stationary_misfit
            }
            _ => p.residual_rms_mm <= limit,
        };
        if fits_joint || named.contains(&i) {
            bodies.union(p.a, p.b);
        }
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n];
    for s in (0..n).filter(|&s| paired[s]) {
        members[bodies.find(s)].push(s);
    }
    let mut members: Vec<Vec<usize>> = members.into_iter().filter(|m| !m.is_empty()).collect();
    if members.len() < 2 {
        return (Vec::new(), Vec::new());
    }
    members.sort_by(|x, y| bigger_first(x, y, marker_count, seg.stationary_segment));
    let refused = (0..fits.pairs.len())
        .filter(|&i| usable(i) && bodies.find(fits.pairs[i].a) != bodies.find(fits.pairs[i].b))
        .collect();
    (refused, members)
}

/// Orders sets of segments biggest first: the room alone (the segment `room` of the markers
/// that never move) last, then more segments, then more markers, then the lower smallest
/// id (the tree's body, where nothing else chooses it).
fn bigger_first(
    x: &[usize],
    y: &[usize],
    marker_count: &[usize],
    room: Option<usize>,
) -> std::cmp::Ordering {
    let markers = |set: &[usize]| set.iter().map(|&s| marker_count[s]).sum::<usize>();
    let room_alone = |set: &[usize]| room.is_some_and(|r| set == [r]);
    room_alone(x)
        .cmp(&room_alone(y))
        .then(y.len().cmp(&x.len()))
        .then(markers(y).cmp(&markers(x)))
        .then(x.first().cmp(&y.first()))
}

/// Residuals below this (mm) are rounding: noiseless data fit every joint to within it.
const RESIDUAL_FLOOR_MM: f64 = 1e-3;

/// The largest distance between two markers of one segment other than `skip` (mm,
/// reference shapes); 0 without a segment of two markers.
fn longest_segment_mm(fits: &PairFits, skip: Option<usize>) -> f64 {
    let mut longest: f64 = 0.0;
    for poses in fits.poses.iter().filter(|p| Some(p.segment) != skip) {
        let markers: Vec<glam::DVec3> = poses
            .reference
            .iter()
            .map(|&m| glam::DVec3::from_array(m))
            .filter(|m| m.is_finite())
            .collect();
        for (i, a) in markers.iter().enumerate() {
            for b in &markers[i + 1..] {
                longest = longest.max(a.distance(*b));
            }
        }
    }
    longest
}

/// The typical joint's residual (mm): the lower median of `residual_rms_mm` over the edges
/// of the plain minimum spanning tree of the finite costs (Kruskal, no rule of the tree's);
/// `None` without such an edge. Two bodies in one capture add one edge between them to that
/// tree for every body after the first, so the median stays a joint's.
pub fn typical_joint_residual(fits: &PairFits) -> Option<f64> {
    let mut order: Vec<usize> = (0..fits.pairs.len())
        .filter(|&i| {
            let p = &fits.pairs[i];
            p.cost.is_finite() && p.a < p.b && p.b < fits.poses.len()
        })
        .collect();
    order.sort_by(|&x, &y| {
        fits.pairs[x]
            .cost
            .total_cmp(&fits.pairs[y].cost)
            .then(x.cmp(&y))
    });
    let mut sets = DisjointSets::new(fits.poses.len());
    let mut residuals: Vec<f64> = order
        .into_iter()
        .filter(|&i| sets.union(fits.pairs[i].a, fits.pairs[i].b))
        .map(|i| fits.pairs[i].residual_rms_mm)
        .filter(|r| r.is_finite())
        .collect();
    residuals.sort_by(f64::total_cmp);
    residuals.get(residuals.len().checked_sub(1)? / 2).copied()
}

/// A copy of `fits` in which the `refused` pairs have no usable fit (cost NaN).
fn without_pairs(fits: &PairFits, refused: &[usize]) -> PairFits {
    let mut masked = fits.clone();
    for &i in refused {
        masked.pairs[i].cost = f64::NAN;
    }
    masked
}

/// Per tree joint (in `joints`' order, parents first), the cheapest finite-cost pair
/// other than its own that crosses the cut the joint makes: one segment in the child's
/// subtree, the other in the tree outside it.
fn runner_ups(joints: &[TreeJoint], in_tree: &[bool], fits: &PairFits) -> Vec<Option<RunnerUp>> {
    let n = in_tree.len();
    // Children of each segment, for the subtree walk.
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    for j in joints {
        children[j.parent_segment].push(j.child_segment);
    }
    let mut below = vec![false; n];
    let mut stack = Vec::new();
    joints
        .iter()
        .map(|j| {
            below.fill(false);
            stack.clear();
            stack.push(j.child_segment);
            while let Some(s) = stack.pop() {
                below[s] = true;
                stack.extend(&children[s]);
            }
            fits.pairs
                .iter()
                .enumerate()
                .filter(|&(i, p)| {
                    i != j.pair
                        && p.cost.is_finite()
                        && in_tree[p.a]
                        && in_tree[p.b]
                        && below[p.a] != below[p.b]
                })
                .min_by(|x, y| x.1.cost.total_cmp(&y.1.cost).then(x.0.cmp(&y.0)))
                .map(|(i, p)| {
                    let (child_side, parent_side) =
                        if below[p.a] { (p.a, p.b) } else { (p.b, p.a) };
                    RunnerUp {
                        parent_side,
                        child_side,
                        pair: i,
                        cost: p.cost,
                    }
                })
        })
        .collect()
}

/// Why a capture gave one segment and no joint: every marker kept its distance to every
/// other (a static trial, or a rigid object), in the segmentation's own numbers.
fn one_body_note(seg: &Segmentation) -> String {
    let largest = seg
        .markers
        .iter()
        .filter(|m| m.segment.is_some())
        .map(|m| m.rigidity_residual_mm)
        .filter(|r| r.is_finite())
        .fold(f64::NAN, f64::max);
    let residual = if largest.is_finite() {
        format!("largest marker rigidity residual {largest:.2} mm, ")
    } else {
        String::new()
    };
    format!(
        "one segment, no joint: all {} assigned markers move as one rigid body ({residual}\
         rigidity tolerance {:.2} mm); a static trial or a rigid object has no joint to find: \
         capture the joints moving",
        seg.segments[0].markers.len(),
        seg.tolerance_mm
    )
}

/// Reorders runs of near-equal costs by the pair's relative rotation, smallest first.
///
/// Segments meeting at one point (siblings on a common parent, e.g. two limbs on one
/// hub) give three pairs with the same fixed point and costs equal up to noise; any two
/// of them form a tree but the sibling pair is false. The sibling pair's relative motion
/// is the composition of both true joints' motions, so it turns the most: among tied
/// costs, the pair with the smaller RMS relative rotation is taken first. A run starts at
/// its cheapest edge `c` and holds every edge of the same rank costing at most
/// `c + tie_absolute + tie_relative · c` (anchored, not chained, so a long run of
/// slowly rising costs is not one tie). NaN rotations go last; then cost, then ids.
fn break_near_ties(edges: &mut [(u8, f64, usize, usize, usize)], fits: &PairFits, params: &Params) {
    let rotation = |e: &(u8, f64, usize, usize, usize)| {
        let r = fits.pairs[e.4].rotation_rms_deg;
        if r.is_finite() { r } else { f64::INFINITY }
    };
    let mut start = 0;
    while start < edges.len() {
        let (rank, first) = (edges[start].0, edges[start].1);
        let limit =
            first + params.tie_absolute.max(0.0) + params.tie_relative.max(0.0) * first.abs();
        let mut end = start + 1;
        while end < edges.len() && edges[end].0 == rank && edges[end].1 <= limit {
            end += 1;
        }
        edges[start..end].sort_by(|x, y| {
            rotation(x)
                .total_cmp(&rotation(y))
                .then(x.1.total_cmp(&y.1))
                .then(x.2.cmp(&y.2))
                .then(x.3.cmp(&y.3))
        });
        start = end;
    }
}

/// Raises each composite pair's cost (see [`composite_of`]) to when its two joints are
/// taken. A joint of a composite may itself be raised as another pair's composite (two
/// siblings' pairs across a hub and a third sibling), so the raise is repeated on the
/// raised costs until none moves.
fn take_composites_after_their_joints(
    edges: &mut [(u8, f64, usize, usize, usize)],
    fits: &PairFits,
    n: usize,
    params: &Params,
) {
    let mut taken_at = vec![vec![f64::NAN; n]; n];
    let mut hub_correlations = HubCorrelations::new(fits);
    for e in edges.iter() {
        taken_at[e.2][e.3] = e.1;
        taken_at[e.3][e.2] = e.1;
    }
    // Every raise lifts a cost to a higher one of the pairs' own costs (raised costs are
    // such costs too), a finite set, so the rounds end.
    loop {
        let mut raised = false;
        for e in edges.iter_mut().filter(|e| e.0 == ORDINARY) {
            let Some(after) =
                composite_of(fits, n, e.2, e.3, params, &taken_at, &mut hub_correlations)
            else {
                continue;
            };
            if after > e.1 {
                e.1 = after;
                taken_at[e.2][e.3] = after;
                taken_at[e.3][e.2] = after;
                raised = true;
            }
        }
        if !raised {
            break;
        }
    }
}

/// When pair (b, c) looks like the composite of two joints through a third segment a,
/// the cost it should be taken after: the cheapest such a's dearer edge, as `taken_at`
/// (symmetric, per pair) has those edges taken. A pair across
/// two joints composes both joints' motions, so it turns more than either; where the
/// joints are close (two clavicles on the sternum, two legs on one tip) it can still fit
/// a centre as well as they do. It is a composite when
/// - a–b and a–c both cost at most `composite_cost_ratio` × its cost, it turns at least
///   `composite_rotation_ratio` × as much as either, and the quieter of the two turns at
///   least `composite_turn_share` of the other, or
/// - it is not a hinge, a–b and a–c are both hinges costing at most
///   `composite_hinge_cost_ratio` × its cost, and it turns at least as much as either:
///   two hinges compose to more than one axis, while in a chain through a hinge the
///   pair across it composes that hinge with the other joint and is no hinge itself, or
/// - a–b and a–c both cost at most `composite_independence_cost_ratio` × its cost, the
///   quieter turns at least `composite_turn_share` of the other, and a's two pairs'
///   rotations correlate at least `composite_independence_margin` (in units of chance
///   correlation, [`HubCorrelations`]) less than b's two pairs' and c's.
fn composite_of(
    fits: &PairFits,
    n: usize,
    b: usize,
    c: usize,
    params: &Params,
    taken_at: &[Vec<f64>],
    hub_correlations: &mut HubCorrelations,
) -> Option<f64> {
    let pair = |x: usize, y: usize| {
        fits.pair(x, y)
            .filter(|p| p.cost.is_finite() && p.rotation_rms_deg.is_finite())
    };
    let own = pair(b, c)?;
    let own_not_hinge = matches!(own.tree_kind(), JointKind::Ball | JointKind::Universal);
    let is_hub = |a: usize, hub_correlations: &mut HubCorrelations| {
        let (Some(ab), Some(ac)) = (pair(a, b), pair(a, c)) else {
            return false;
        };
        let dearer = ab.cost.max(ac.cost);
        let turns = ab.rotation_rms_deg.max(ac.rotation_rms_deg);
        // Where one of the two barely turns, the pair across it turns about as much as
        // the other joint whichever is the composite: the rotations cannot tell.
        let quieter = ab.rotation_rms_deg.min(ac.rotation_rms_deg);
        let by_motion = params.composite_rotation_ratio > 0.0
            && dearer <= params.composite_cost_ratio * own.cost
            && own.rotation_rms_deg >= params.composite_rotation_ratio * turns
            && quieter >= params.composite_turn_share * turns;
        let by_kinds = own_not_hinge
            && ab.tree_kind() == JointKind::Hinge
            && ac.tree_kind() == JointKind::Hinge
            && dearer <= params.composite_hinge_cost_ratio * own.cost
            && own.rotation_rms_deg >= turns;
        // Seen from the hub, its two joints turn independently; seen from either other
        // segment, its two pairs share that segment's joint. Each reading is a pass over
        // the capture, so it comes last and stops at the first miss.
        by_motion
            || by_kinds
            || (params.composite_independence_margin > 0.0
                && dearer <= params.composite_independence_cost_ratio * own.cost
                && quieter >= params.composite_turn_share * turns
                && hub_correlations.clearly_the_hub(a, b, c, params.composite_independence_margin))
    };
    // The cheapest hub decides, so hubs are tried cheapest first and the first one found
    // ends the search (the costly readings are left for where they can matter).
    let mut hubs: Vec<(f64, usize)> = (0..n)
        .filter(|&a| a != b && a != c)
        .map(|a| (taken_at[a][b].max(taken_at[a][c]), a))
        .collect();
    hubs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    hubs.into_iter()
        .find(|&(_, a)| is_hub(a, hub_correlations))
        .map(|(after, _)| after)
}

/// The tree's centre: minimum eccentricity in hops, ties by the smaller sum of hops to
/// every segment (the centre with more of the tree on its side), then by most markers,
/// then by the smaller mean distance to the tree's other segments over the capture
/// (`spread`), then lowest id. Nothing before the last key depends on how the segments
/// happen to be numbered (the capture's marker order).
fn centre(
    tree: &[usize],
    adjacency: &[Vec<(usize, usize, f64)>],
    marker_count: &[usize],
    spread: impl Fn(usize) -> f64,
) -> usize {
    let n = adjacency.len();
    // Per segment of the tree: (eccentricity, sum of hops, markers reversed so that more
    // sorts first), and its id.
    let mut keys = Vec::with_capacity(tree.len());
    let mut hops = vec![usize::MAX; n];
    let mut queue = VecDeque::new();
    for &s in tree {
        hops.fill(usize::MAX);
        hops[s] = 0;
        queue.clear();
        queue.push_back(s);
        let (mut eccentricity, mut total) = (0, 0);
        while let Some(u) = queue.pop_front() {
            eccentricity = eccentricity.max(hops[u]);
            total += hops[u];
            for &(v, _, _) in &adjacency[u] {
                if hops[v] == usize::MAX {
                    hops[v] = hops[u] + 1;
                    queue.push_back(v);
                }
            }
        }
        keys.push(((eccentricity, total, std::cmp::Reverse(marker_count[s])), s));
    }
    let Some(best) = keys.iter().map(|k| k.0).min() else {
        return 0;
    };
    // `tree` is ascending, so the lowest id comes first among exact ties.
    let tied: Vec<usize> = keys.iter().filter(|k| k.0 == best).map(|k| k.1).collect();
    if tied.len() == 1 {
        return tied[0];
    }
    let spreads: Vec<f64> = tied.iter().map(|&s| spread(s)).collect();
    let mut pick = 0;
    for (i, &d) in spreads.iter().enumerate() {
        if d < spreads[pick] {
            pick = i;
        }
    }
    tied[pick]
}

/// Mean over the tree's other segments of the mean distance (mm) between their pose
/// origins (marker centroids) and segment `s`'s, over the frames where both are posed:
/// small for the segment in the middle of the body. Infinite when nothing is posed.
fn spatial_spread(fits: &PairFits, tree: &[usize], s: usize) -> f64 {
    let Some(own) = fits.poses.get(s) else {
        return f64::INFINITY;
    };
    let mut sum = 0.0;
    let mut count = 0usize;
    for &u in tree.iter().filter(|&&u| u != s) {
        let Some(other) = fits.poses.get(u) else {
            continue;
        };
        let (mut total, mut frames) = (0.0, 0usize);
        for (a, b) in own.translations.iter().zip(&other.translations) {
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            if d.is_finite() {
                total += d;
                frames += 1;
            }
        }
        if frames > 0 {
            sum += total / frames as f64;
            count += 1;
        }
    }
    if count == 0 {
        f64::INFINITY
    } else {
        sum / count as f64
    }
}

/// Edge ranks, taken in this order: pairs `topo.joints` names, rigid pairs
/// (`rigid_first`), the rest by cost.
const NAMED: u8 = 0;
/// See [`NAMED`].
const RIGID: u8 = 1;
/// See [`NAMED`].
const ORDINARY: u8 = 2;

/// The segment `r` names: an id the segmentation has, or the one segment holding the
/// markers a label (or `*` pattern) names; else why not.
fn segment_of(seg: &Segmentation, r: &SegmentRef) -> Result<usize, String> {
    let n = seg.segments.len();
    match r {
        SegmentRef::Id(id) if *id < n => Ok(*id),
        SegmentRef::Id(_) => Err(format!(
            "the segmentation has segments 0 to {} (skeleton.json's segment ids)",
            n.saturating_sub(1)
        )),
        SegmentRef::Marker(label) => {
            if seg.labels.is_empty() {
                return Err(
                    "the segmentation names no markers (an artifact written before \
                            labels were kept: run the segment stage again)"
                        .into(),
                );
            }
            let markers = mocap_io::markers_named(&seg.labels, label);
            if markers.is_empty() {
                return Err(mocap_io::no_marker_named(&seg.labels, label));
            }
            let segment_of = |m: usize| seg.segments.iter().position(|s| s.markers.contains(&m));
            let mut held: Vec<usize> = Vec::new();
            for &m in &markers {
                let Some(s) = segment_of(m) else {
                    return Err(format!("marker {:?} is in no segment", seg.labels[m]));
                };
                if !held.contains(&s) {
                    held.push(s);
                }
            }
            match held[..] {
                [s] => Ok(s),
                _ => Err(format!(
                    "{label:?} names markers of segments {held:?}, not of one segment"
                )),
            }
        }
    }
}

/// The pair fits `joints` (`topo.joints`) names, by index into `fits.pairs`: an error names
/// a pair whose segments the segmentation has not, or that has no usable fit to place it.
fn named_pairs(
    seg: &Segmentation,
    fits: &PairFits,
    joints: &[[SegmentRef; 2]],
) -> Result<Vec<usize>, Error> {
    joints
        .iter()
        .map(|[ra, rb]| {
            let bad = |reason: String| Error::BadJoint {
                a: ra.to_string(),
                b: rb.to_string(),
                reason,
            };
            let (a, b) = (
                segment_of(seg, ra).map_err(bad)?,
                segment_of(seg, rb).map_err(bad)?,
            );
            if a == b {
                return Err(bad(format!(
                    "both name segment {a}; a segment cannot be joined to itself"
                )));
            }
            match fits.pair_index(a, b) {
                Some(i) if fits.pairs[i].cost.is_finite() => Ok(i),
                _ => Err(bad(format!(
                    "segments {a} and {b} have no usable joint fit (fewer than \
                     jointfit.min_frames frames with both posed, or no centre fits them)"
                ))),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use jointfit::{PairFit, SegmentPoses};
    use segment::Segment;

    /// A segmentation with the given marker count per segment (markers numbered in order).
    fn segmentation(markers: &[usize]) -> Segmentation {
        let mut next = 0;
        let segments = markers
            .iter()
            .enumerate()
            .map(|(id, &m)| {
                let s = Segment {
                    id,
                    markers: (next..next + m).collect(),
                };
                next += m;
                s
            })
            .collect();
        Segmentation {
            segments,
            unassigned: Vec::new(),
            markers: Vec::new(),
            noise_mm: 0.0,
            tolerance_mm: 1.0,
            eigenvalues: Vec::new(),
            scatter_smoothness: None,
            eigengap_segments: 0,
            swaps: Vec::new(),
            glitches: Vec::new(),
            near_joints: Vec::new(),
            labels: (0..next).map(|m| format!("M{m}")).collect(),
            named_segments: Vec::new(),
            pieces: Vec::new(),
            stationary_segment: None,
            bodies: Vec::new(),
        }
    }

    /// The test fit of segments a < b.
    fn fit_mut(f: &mut PairFits, a: usize, b: usize) -> &mut PairFit {
        f.pairs
            .iter_mut()
            .find(|p| (p.a, p.b) == (a, b))
            .expect("every pair has a fit")
    }

    /// Sets every pair's RMS relative rotation (degrees).
    fn turning(f: &mut PairFits, degrees: impl Fn(usize, usize) -> f64) {
        for p in &mut f.pairs {
            p.rotation_rms_deg = degrees(p.a, p.b);
        }
    }

    /// Pair fits over `n` segments with `cost(a, b)` for every pair (a < b).
    fn fits(n: usize, cost: impl Fn(usize, usize) -> (f64, JointKind)) -> PairFits {
        let poses = (0..n)
            .map(|segment| SegmentPoses {
                segment,
                reference: Vec::new(),
                rotations: Vec::new(),
                translations: Vec::new(),
                rms_mm: Vec::new(),
            })
            .collect();
        let mut pairs = Vec::new();
        for a in 0..n {
            for b in a + 1..n {
                let (cost, kind) = cost(a, b);
                pairs.push(PairFit {
                    a,
                    b,
                    method: "test".into(),
                    cost,
                    centre_in_a: [0.0; 3],
                    centre_in_b: [0.0; 3],
                    positions: Vec::new(),
                    kind,
                    axis_in_a: None,
                    axis_in_b: None,
                    universal_axes: None,
                    residual_rms_mm: 0.0,
                    frames_used: 0,
                    rotation_rms_deg: 30.0,
                    rotation_max_deg: 60.0,
                    wobble_deg: [10.0; 3],
                    evidence: String::new(),
                    centre_from_distances: false,
                    seeded: false,
                    posed_through: None,
                    next_best_anchor: None,
                    first_pass_kind: None,
                    misfit_over_noise: f64::NAN,
                });
            }
        }
        PairFits {
            frames: 0,
            poses,
            pairs,
        }
    }

    /// Costs that make `edges` (unordered) the cheapest, everything else expensive.
    fn tree_costs(edges: &[(usize, usize)]) -> impl Fn(usize, usize) -> (f64, JointKind) + '_ {
        move |a, b| {
            let on_tree = edges
                .iter()
                .position(|&(x, y)| (x.min(y), x.max(y)) == (a, b));
            match on_tree {
                Some(i) => (1.0 + 0.1 * i as f64, JointKind::Ball),
                None => (10.0 + a as f64 + 0.01 * b as f64, JointKind::Ball),
            }
        }
    }

    fn edge_set(t: &Topology) -> Vec<(usize, usize)> {
        let mut e: Vec<_> = t
            .joints
            .iter()
            .map(|j| {
                (
                    j.parent_segment.min(j.child_segment),
                    j.parent_segment.max(j.child_segment),
                )
            })
            .collect();
        e.sort();
        e
    }

    #[test]
    fn human_like_tree_root_bfs_order_and_parent_joints() {
        // Torso 2 with head 4, arms 0 and 5 (5 has a forearm 1), leg 3.
        let edges = [(2, 4), (2, 0), (2, 5), (5, 1), (2, 3)];
        let seg = segmentation(&[3, 3, 6, 3, 3, 3]);
        let f = fits(6, tree_costs(&edges));
        let t = run(&seg, &f, &Params::default()).unwrap();
        let mut want: Vec<_> = edges.iter().map(|&(a, b)| (a.min(b), a.max(b))).collect();
        want.sort();
        assert_eq!(edge_set(&t), want);
        assert_eq!(t.root_segment, 2);
        let names: Vec<&str> = t.joints.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["j0", "j3", "j4", "j5", "j1"]);
        assert_eq!(t.joints[4].parent_segment, 5);
        assert_eq!(t.joints[4].parent_joint, Some(3));
        assert!(t.joints[..4].iter().all(|j| j.parent_joint.is_none()));
        assert!(t.detached_segments.is_empty());
        // The pair index points at the pair of the joint's two segments.
        for j in &t.joints {
            let p = &f.pairs[j.pair];
            assert_eq!(
                (p.a, p.b),
                (
                    j.parent_segment.min(j.child_segment),
                    j.parent_segment.max(j.child_segment)
                )
            );
            assert_eq!(j.cost, p.cost);
        }
    }

    #[test]
    fn one_segment_is_a_tree_of_its_own_and_says_why() {
        let mut seg = segmentation(&[4]);
        seg.markers = [0.12, 0.31, f64::NAN, 0.2]
            .into_iter()
            .map(|r| segment::MarkerDiagnostics {
                segment: Some(0),
                visible_frames: 100,
                glitch_frames: 0,
                rigidity_residual_mm: r,
                slides: false,
            })
            .collect();
        let t = run(&seg, &fits(1, tree_costs(&[])), &Params::default()).unwrap();
        assert!(t.joints.is_empty());
        assert_eq!(t.root_segment, 0);
        let [note] = &t.notes[..] else {
            panic!("{:?}", t.notes)
        };
        assert!(
            note.contains("all 4 assigned markers move as one rigid body"),
            "{note}"
        );
        assert!(
            note.contains("largest marker rigidity residual 0.31 mm"),
            "{note}"
        );
        // Two segments: no such note.
        let t = run(
            &segmentation(&[3, 3]),
            &fits(2, tree_costs(&[(0, 1)])),
            &Params::default(),
        )
        .unwrap();
        assert!(t.notes.is_empty(), "{:?}", t.notes);
    }

    #[test]
    fn centre_ties_go_to_most_markers_then_lowest_id_where_nothing_else_differs() {
        // Chain 0-1-2-3: centres 1 and 2 (eccentricity 2).
        let edges = [(0, 1), (1, 2), (2, 3)];
        let f = fits(4, tree_costs(&edges));
        let t = run(&segmentation(&[3, 3, 5, 3]), &f, &Params::default()).unwrap();
        assert_eq!(t.root_segment, 2);
        let t = run(&segmentation(&[3, 3, 3, 3]), &f, &Params::default()).unwrap();
        assert_eq!(t.root_segment, 1);
        assert_eq!(t.joints[0].name, "j0");
        assert_eq!(t.joints[1].name, "j2");
        assert_eq!(t.joints[2].name, "j3");
        assert_eq!(t.joints[2].parent_joint, Some(1));
    }

    #[test]
    fn centre_ties_go_by_the_trees_shape_then_by_where_segments_are_not_by_id() {
        // Centres 3 and 1 (eccentricity 2); 3 carries two leaves (0, 4), 1 one (2): 3 is
        // nearer the rest in hops (5 against 6), though its id is higher.
        let edges = [(3, 1), (3, 0), (3, 4), (1, 2)];
        let t = run(
            &segmentation(&[3; 5]),
            &fits(5, tree_costs(&edges)),
            &Params::default(),
        )
        .unwrap();
        assert_eq!(t.root_segment, 3);
        // Chain 0-1-2-3, a tie in hops and markers: segment 2 sits nearer the others
        // (mean distance 90.5 mm against 110).
        let mut f = fits(4, tree_costs(&[(0, 1), (1, 2), (2, 3)]));
        let at = [
            [0.0, 0.0, 0.0],
            [100.0, 0.0, 0.0],
            [100.0, 100.0, 0.0],
            [100.0, 130.0, 0.0],
        ];
        for (pose, p) in f.poses.iter_mut().zip(at) {
            pose.translations = vec![p, p];
        }
        let t = run(&segmentation(&[3; 4]), &f, &Params::default()).unwrap();
        assert_eq!(t.root_segment, 2);
    }

    #[test]
    fn unusable_costs_detach_segments_and_equal_costs_break_by_id() {
        // Segment 3 has no finite cost; 0, 1, 2 all cost 1: edges (0,1) and (0,2) win.
        let f = fits(4, |a, b| {
            if b == 3 {
                (
                    if a == 0 { f64::NAN } else { f64::INFINITY },
                    JointKind::Ball,
                )
            } else {
                (1.0, JointKind::Ball)
            }
        });
        let t = run(&segmentation(&[3, 3, 3, 3]), &f, &Params::default()).unwrap();
        assert_eq!(t.detached_segments, vec![3]);
        assert_eq!(edge_set(&t), vec![(0, 1), (0, 2)]);
        assert_eq!(t.root_segment, 0);
        assert!(t.notes.iter().any(|n| n.contains("segment 3 is detached")));
        // Deterministic: the same input gives the same tree.
        assert_eq!(
            t,
            run(&segmentation(&[3, 3, 3, 3]), &f, &Params::default()).unwrap()
        );
    }

    #[test]
    fn smaller_component_is_detached() {
        // {0, 1, 2} and {3, 4} are linked only inside themselves.
        let f = fits(5, |a, b| {
            let same = (a < 3) == (b < 3);
            (if same { 1.0 } else { f64::INFINITY }, JointKind::Ball)
        });
        let t = run(&segmentation(&[3; 5]), &f, &Params::default()).unwrap();
        assert_eq!(t.detached_segments, vec![3, 4]);
        assert_eq!(t.joints.len(), 2);
        // Forcing a root in the other component makes that one the tree.
        let p = Params {
            root: Some(SegmentRef::Id(4)),
            ..Params::default()
        };
        let t = run(&segmentation(&[3; 5]), &f, &p).unwrap();
        assert_eq!(t.root_segment, 4);
        assert_eq!(t.detached_segments, vec![0, 1, 2]);
        assert_eq!(t.joints.len(), 1);
        assert_eq!(t.joints[0].name, "j3");
    }

    #[test]
    fn near_tied_siblings_are_not_joined_to_each_other() {
        // Segment 2 is a hub; 0 and 1 hang on it at one point, so all three pairs fit that
        // point (cost ~0). The sibling pair (0, 1) turns the most and must not be an edge,
        // even though it is the cheapest by a hair and has the lowest ids.
        let seg = segmentation(&[3, 3, 4, 3]);
        let mut f = fits(4, |a, b| match (a, b) {
            (0, 1) => (1e-9, JointKind::Ball),
            (0, 2) | (1, 2) => (2e-9, JointKind::Ball),
            (2, 3) => (3.0, JointKind::Ball),
            _ => (40.0, JointKind::Ball),
        });
        turning(&mut f, |a, b| if (a, b) == (0, 1) { 50.0 } else { 30.0 });
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 2), (1, 2), (2, 3)]);
        // Costs clearly apart are not ties: the cheaper pair wins whatever it turns.
        fit_mut(&mut f, 0, 1).cost = -5.0;
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
        // With no tolerance the cheapest pair wins again.
        fit_mut(&mut f, 0, 1).cost = 1e-9;
        let exact = Params {
            tie_absolute: 0.0,
            tie_relative: 0.0,
            ..Params::default()
        };
        let t = run(&seg, &f, &exact).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
    }

    /// Thorax 2 carrying clavicles 0 and 1 at nearby points, and segment 3 (then 4, with
    /// `forearm`: its pair with 3 costs 4, with the thorax 9). With skin the clavicle pair
    /// fits a centre a little better than either clavicle fits the thorax, but it turns
    /// the most: its motion composes both sternoclavicular joints'.
    fn clavicles(forearm: bool) -> (Segmentation, PairFits) {
        let n = if forearm { 5 } else { 4 };
        let seg = segmentation(&[3, 3, 6, 3, 3][..n]);
        let mut f = fits(n, |a, b| match (a, b) {
            (0, 1) => (7.6, JointKind::Ball),
            (0, 2) => (8.4, JointKind::Ball),
            (1, 2) => (8.0, JointKind::Ball),
            (2, 3) => (5.0, JointKind::Ball),
            (3, 4) => (4.0, JointKind::Ball),
            (2, 4) => (9.0, JointKind::Ball),
            _ => (40.0, JointKind::Ball),
        });
        turning(&mut f, |a, b| match (a, b) {
            (0, 1) => 31.0,
            (0, 2) => 21.0,
            (1, 2) => 23.0,
            _ => 30.0,
        });
        (seg, f)
    }

    #[test]
    fn composite_pairs_are_taken_after_their_joints() {
        let (seg, mut f) = clavicles(false);
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 2), (1, 2), (2, 3)]);
        // Off, or with the two only a little apart in rotation, the cheapest pair wins.
        let off = Params {
            composite_rotation_ratio: 0.0,
            ..Params::default()
        };
        let t = run(&seg, &f, &off).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
        fit_mut(&mut f, 0, 1).rotation_rms_deg = 25.0;
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
        // Nor where one clavicle barely turns on the thorax: the pair across it then turns
        // as much as the other joint, whichever is the composite.
        let (seg, mut f) = clavicles(false);
        fit_mut(&mut f, 0, 2).rotation_rms_deg = 8.0;
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)), "{:?}", edge_set(&t));
        fit_mut(&mut f, 0, 2).rotation_rms_deg = 10.0;
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 2), (1, 2), (2, 3)]);
    }

    /// A hub 0 with three children 1, 2, 3 (random-hard-s20033's shape): every pair of
    /// siblings is a composite through the hub. The pair (1, 3) also looks like the
    /// composite of (1, 2) and (2, 3), which are cheaper than the joint (0, 3); but those
    /// are composites too and are taken only after the hub's joints, so (1, 3) waits for
    /// (0, 3) as well, and the tie goes to the joint, which turns less.
    #[test]
    fn a_composite_of_composites_waits_for_the_joints_they_wait_for() {
        let seg = segmentation(&[3, 3, 3, 3]);
        // (cost, RMS relative rotation in degrees) per pair; (1, 3) is the last.
        let pair = |a, b| match (a, b) {
            (0, 1) => (6.4, 36.0),
            (0, 2) => (5.0, 30.0),
            (0, 3) => (9.7, 47.0),
            (1, 2) => (5.3, 60.0),
            (2, 3) => (8.3, 65.0),
            _ => (9.5, 75.0),
        };
        let mut f = fits(4, |a, b| (pair(a, b).0, JointKind::Ball));
        turning(&mut f, |a, b| pair(a, b).1);
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 1), (0, 2), (0, 3)]);
        // Where (1, 2) and (2, 3) are joints (no hub turns less under them), (1, 3) is
        // their composite and 3 hangs from 2.
        fit_mut(&mut f, 0, 2).rotation_rms_deg = 70.0;
        fit_mut(&mut f, 0, 3).rotation_rms_deg = 80.0;
        fit_mut(&mut f, 0, 2).cost = 20.0;
        fit_mut(&mut f, 0, 3).cost = 20.0;
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 1), (1, 2), (2, 3)]);
    }

    /// Thorax 0, clavicles 1 and 2 on it, and below each an upper arm (3, 4) carrying
    /// `below` segments each: none, a forearm (5, 6), or a forearm and a second segment (7,
    /// 8: a branching, not a limb); the clavicles' pair costs least, so the spanning tree
    /// hangs clavicle 2 on clavicle 1. Bones (joint to joint): clavicles 150 and 140 mm,
    /// upper arms 280 and `upper_arm_2` mm (to every child).
    fn twin_arms(below: usize, upper_arm_2: f64) -> (Segmentation, PairFits) {
        let n = 5 + 2 * below;
        let seg = segmentation(&[6, 3, 3, 3, 3, 3, 3, 3, 3][..n]);
        let mut f = fits(n, |a, b| match (a, b) {
            (1, 2) => (3.0, JointKind::Ball),
            (0, 1) | (1, 3) | (2, 4) | (3, 5) | (4, 6) | (3, 7) | (4, 8) => (4.0, JointKind::Ball),
            (0, 2) => (5.0, JointKind::Ball),
            _ => (40.0, JointKind::Ball),
        });
        // (pair, its centre in a's frame, in b's): each bone runs from its segment's origin,
        // where its parent joint is, along x.
        let x = |mm: f64| [mm, 0.0, 0.0];
        for ((a, b), in_a, in_b) in [
            ((1, 3), x(150.0), x(0.0)),
            ((2, 4), x(140.0), x(0.0)),
            ((3, 5), x(280.0), x(0.0)),
            ((4, 6), x(upper_arm_2), x(0.0)),
            ((3, 7), x(280.0), x(0.0)),
            ((4, 8), x(upper_arm_2), x(0.0)),
        ] {
            if b < n {
                fit_mut(&mut f, a, b).centre_in_a = in_a;
                fit_mut(&mut f, a, b).centre_in_b = in_b;
            }
        }
        (seg, f)
    }

    #[test]
    fn a_limb_hung_on_its_twin_moves_to_the_twins_parent() {
        let (seg, f) = twin_arms(1, 300.0);
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            edge_set(&t),
            [(0, 1), (0, 2), (1, 3), (2, 4), (3, 5), (4, 6)]
        );
        assert!(
            t.notes
                .iter()
                .any(|n| n.contains("segment 2 hung on segment 0, not on 1")),
            "{:?}",
            t.notes
        );
        // Not where the rule is off, the bones differ, the pair with the parent costs too
        // much more, the twins are one bone deep (a like length is a coin toss there), or
        // they branch (rather a body cut in pieces than two limbs).
        let stays = |seg: &Segmentation, f: &PairFits, params: &Params| {
            let t = run(seg, f, params).unwrap_or_else(|e| panic!("{e}"));
            edge_set(&t).contains(&(1, 2))
        };
        let off = Params {
            twin_cost_ratio: 0.0,
            ..Params::default()
        };
        assert!(stays(&seg, &f, &off));
        let (seg, f) = twin_arms(1, 520.0);
        assert!(stays(&seg, &f, &Params::default()));
        let (seg, mut f) = twin_arms(1, 300.0);
        fit_mut(&mut f, 0, 2).cost = 6.5;
        assert!(stays(&seg, &f, &Params::default()));
        let (seg, f) = twin_arms(0, 300.0);
        assert!(stays(&seg, &f, &Params::default()));
        let (seg, f) = twin_arms(2, 300.0);
        assert!(stays(&seg, &f, &Params::default()));
    }

    #[test]
    fn pairs_the_user_names_are_joined_first_and_no_rule_moves_them() {
        // The twins rule would move clavicle 2 from clavicle 1 to the thorax (above); named,
        // the edge stays. A dear pair named is taken over the cheap one across its cut.
        let (seg, f) = twin_arms(1, 300.0);
        let named = |joints: Vec<[usize; 2]>| Params {
            joints: joints
                .into_iter()
                .map(|[a, b]| [SegmentRef::Id(a), SegmentRef::Id(b)])
                .collect(),
            ..Params::default()
        };
        let t = run(&seg, &f, &named(vec![[2, 1]])).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(1, 2)), "{:?}", edge_set(&t));
        let named_joints: Vec<(usize, usize)> = t
            .joints
            .iter()
            .filter(|j| j.named)
            .map(|j| (j.parent_segment, j.child_segment))
            .collect();
        assert_eq!(named_joints, [(1, 2)]);
        assert!(
            t.notes
                .iter()
                .any(|n| n == "segments 1 and 2 joined as topo.joints names them"),
            "{:?}",
            t.notes
        );
        let t = run(&seg, &f, &named(vec![[0, 3]])).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 3)), "{:?}", edge_set(&t));
        assert!(!edge_set(&t).contains(&(1, 3)), "{:?}", edge_set(&t));
        // Pairs the tree cannot take are errors naming the pair and why.
        let refused = |joints: Vec<[usize; 2]>, f: &PairFits| {
            run(&seg, f, &named(joints))
                .map(|_| ())
                .unwrap_err()
                .to_string()
        };
        assert!(refused(vec![[1, 1]], &f).contains("[1, 1]: both name segment 1"));
        assert!(refused(vec![[0, 9]], &f).contains("segments 0 to 6"));
        assert!(refused(vec![[0, 1], [1, 2], [2, 0]], &f).contains("[0, 2]: with the other pairs"));
        let mut unfit = f.clone();
        fit_mut(&mut unfit, 0, 4).cost = f64::INFINITY;
        assert!(refused(vec![[4, 0]], &unfit).contains("no usable joint fit"));

        // By a marker's label: the same segment in every trial of a marker set (the test
        // segments hold markers M0–M5, M6–M8, M9–M11, ...).
        let by_label = |pairs: &[[&str; 2]], root: Option<&str>| Params {
            joints: pairs
                .iter()
                .map(|p| p.map(|l| SegmentRef::Marker(l.into())))
                .collect(),
            root: root.map(|l| SegmentRef::Marker(l.into())),
            ..Params::default()
        };
        let t =
            run(&seg, &f, &by_label(&[["M9", "M7"]], Some("M6"))).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(1, 2)), "{:?}", edge_set(&t));
        assert_eq!(t.root_segment, 1);
        let refused = |p: Params| run(&seg, &f, &p).map(|_| ()).unwrap_err().to_string();
        let e = refused(by_label(&[["LKNE", "M0"]], None));
        assert!(
            e.contains("[\"LKNE\", \"M0\"]: the capture has no marker labelled \"LKNE\""),
            "{e}"
        );
        let e = refused(by_label(&[["M1*", "M0"]], None));
        assert!(
            e.contains("\"M1*\" names markers of segments [0, 2, 3, 4, 5]"),
            "{e}"
        );
        let e = refused(by_label(&[], Some("M99")));
        assert!(e.contains("topo.root = \"M99\""), "{e}");
    }

    #[test]
    fn a_twin_posed_through_its_twin_is_weighed_against_the_twins_own_joint() {
        // Clavicle 2 hung on clavicle 1 at 3 mm, its pair with the thorax 7 mm: 2.33 × the
        // edge, too dear for the rule. But where one clavicle is posed through the other
        // (two markers, no pose of its own), that edge is cheap by construction, and the
        // thorax's pair with clavicle 2 is weighed against clavicle 1's own, 4 mm.
        let moved = |posed_through: Option<usize>| {
            let (seg, mut f) = twin_arms(1, 300.0);
            fit_mut(&mut f, 0, 2).cost = 7.0;
            fit_mut(&mut f, 1, 2).posed_through = posed_through;
            let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
            let note = t.notes.iter().any(|n| {
                n.contains("segment 2 hung on segment 0, not on 1")
                    && n.contains("1.75 × the larger of its pair with 1")
            });
            (edge_set(&t).contains(&(0, 2)), note)
        };
        assert_eq!(moved(None), (false, false));
        assert_eq!(moved(Some(2)), (true, true));
        assert_eq!(moved(Some(1)), (true, true));
    }

    /// Twin arms (see `twin_arms`) with a head 7 that fits a centre with clavicle 1 best
    /// (4 mm), with the thorax (5) and the other clavicle (`head_on_2` mm) a little worse:
    /// the spanning tree hangs clavicle 2 and the head on clavicle 1.
    fn twin_arms_and_head(head_on_2: f64) -> (Segmentation, PairFits) {
        let (_, arms) = twin_arms(1, 300.0);
        let seg = segmentation(&[6, 3, 3, 3, 3, 3, 3, 4]);
        let mut f = fits(8, |a, b| match (a, b) {
            (1, 7) => (4.0, JointKind::Ball),
            (0, 7) => (5.0, JointKind::Ball),
            (2, 7) => (head_on_2, JointKind::Ball),
            (_, 7) => (40.0, JointKind::Ball),
            _ => (0.0, JointKind::Ball),
        });
        for p in &arms.pairs {
            *fit_mut(&mut f, p.a, p.b) = p.clone();
        }
        (seg, f)
    }

    #[test]
    fn a_leaf_that_fits_both_twins_moves_to_their_parent() {
        let (seg, f) = twin_arms_and_head(5.5);
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            edge_set(&t),
            [(0, 1), (0, 2), (0, 7), (1, 3), (2, 4), (3, 5), (4, 6)]
        );
        assert!(
            t.notes
                .iter()
                .any(|n| n.contains("segment 7 hung on segment 0, not on 1")),
            "{:?}",
            t.notes
        );
        // Without the leaf rule the head blinds the twins rule too (clavicle 1 carries more
        // than clavicle 2); and a head that fits the other clavicle much worse (13 mm, 3.25
        // × its 4) sits on clavicle 1's far side, not between the twins: it stays, and so
        // do the clavicles.
        let off = Params {
            twin_leaf_cost_ratio: 0.0,
            ..Params::default()
        };
        let stays = |seg: &Segmentation, f: &PairFits, params: &Params| {
            let e = edge_set(&run(seg, f, params).unwrap_or_else(|e| panic!("{e}")));
            e.contains(&(1, 2)) && e.contains(&(1, 7))
        };
        assert!(stays(&seg, &f, &off));
        let (seg, f) = twin_arms_and_head(13.0);
        assert!(stays(&seg, &f, &Params::default()));
    }

    /// A head posed through its joint with clavicle 1 (two markers): that edge costs 4 by
    /// construction, its pairs with the thorax (14) and clavicle 2 (30) far more, beyond
    /// `twin_leaf_cost_ratio`. But the thorax's centre held its markers next best, 1.2
    /// times the joint's radial residual: it moves to the thorax, and the clavicles'
    /// twinship shows. Not at 1.6 times, nor where the next best is another segment, nor
    /// with the rule off.
    #[test]
    fn a_leaf_posed_through_a_twin_that_its_parent_holds_nearly_as_well_moves_to_it() {
        let placed = |next_best: Option<(usize, f64)>, params: &Params| {
            let (seg, mut f) = twin_arms_and_head(30.0);
            fit_mut(&mut f, 0, 7).cost = 14.0;
            fit_mut(&mut f, 1, 7).posed_through = Some(7);
            fit_mut(&mut f, 1, 7).next_best_anchor = next_best;
            let t = run(&seg, &f, params).unwrap_or_else(|e| panic!("{e}"));
            let note = t.notes.iter().any(|n| {
                n.contains("segment 7 hung on segment 0, not on 1")
                    && n.contains("1.20 × that joint's radial residual")
            });
            let e = edge_set(&t);
            (e.contains(&(0, 7)) && e.contains(&(0, 2)), note)
        };
        let defaults = Params::default();
        assert_eq!(placed(Some((0, 1.2)), &defaults), (true, true));
        assert!(!placed(Some((0, 1.6)), &defaults).0);
        assert!(!placed(Some((2, 1.2)), &defaults).0);
        assert!(!placed(None, &defaults).0);
        let off = Params {
            twin_leaf_anchor_ratio: 0.0,
            ..Params::default()
        };
        assert!(!placed(Some((0, 1.2)), &off).0);
    }

    /// Each joint's runner-up is the cheapest other pair joining the two sides of its cut:
    /// for a clavicle, the sibling pair, cheaper than the joint itself (the composite rule
    /// took the joints against the costs); for the upper arm, whose subtree holds the
    /// forearm, the forearm's pair with the thorax. Two segments have none.
    #[test]
    fn runner_ups_are_the_cheapest_other_pair_across_each_cut() {
        let (seg, f) = clavicles(true);
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 2), (1, 2), (2, 3), (3, 4)]);
        let runner_up = |child: usize| {
            let j = t.joints.iter().find(|j| j.child_segment == child);
            let r = j.and_then(|j| j.runner_up.clone());
            r.map(|r| (r.parent_side, r.child_side, r.cost, f.pairs[r.pair].cost))
        };
        assert_eq!(runner_up(0), Some((1, 0, 7.6, 7.6)));
        assert_eq!(runner_up(1), Some((0, 1, 7.6, 7.6)));
        assert_eq!(runner_up(3), Some((2, 4, 9.0, 9.0)));
        assert_eq!(runner_up(4), Some((2, 4, 9.0, 9.0)));
        let two = run(
            &segmentation(&[3, 3]),
            &fits(2, |_, _| (1.0, JointKind::Ball)),
            &Params::default(),
        );
        let two = two.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(two.joints.len(), 1);
        assert_eq!(two.joints[0].runner_up, None);
    }

    #[test]
    fn two_hinges_on_a_hub_outrank_the_cheaper_ball_they_compose() {
        // Hub 2 (poorly posed) carries 0 and 1 on hinges about different axes; the pair
        // (0, 1) fits a centre at half their cost, reads as a ball and turns more than
        // either: the hinges' composite, not a joint.
        let seg = segmentation(&[4, 4, 3, 3]);
        let mut f = fits(4, |a, b| match (a, b) {
            (0, 1) => (5.0, JointKind::Ball),
            (0, 2) => (9.0, JointKind::Hinge),
            (1, 2) => (12.0, JointKind::Hinge),
            (2, 3) => (4.0, JointKind::Ball),
            _ => (60.0, JointKind::Ball),
        });
        turning(&mut f, |a, b| match (a, b) {
            (0, 1) => 41.0,
            (0, 2) => 38.0,
            _ => 30.0,
        });
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 2), (1, 2), (2, 3)]);
        let off = Params {
            composite_hinge_cost_ratio: 0.0,
            ..Params::default()
        };
        let t = run(&seg, &f, &off).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
        // Beyond the ratio (12 > 2 x 5), the cheaper pair stands.
        let tight = Params {
            composite_hinge_cost_ratio: 2.0,
            ..Params::default()
        };
        let t = run(&seg, &f, &tight).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
        // A hinge, or a ball turning less than a hinge through the hub, is no composite.
        for (kind, turns) in [(JointKind::Hinge, 41.0), (JointKind::Ball, 35.0)] {
            let pair = fit_mut(&mut f, 0, 1);
            pair.kind = kind;
            pair.rotation_rms_deg = turns;
            let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
            assert!(edge_set(&t).contains(&(0, 1)), "{kind:?} {turns}");
        }
        // The kinds read are the first pass's, like the costs: a hinge the second pass
        // calls a ball still makes (0, 1) its composite, and a ball it calls a hinge not.
        let pair = fit_mut(&mut f, 0, 1);
        (pair.kind, pair.rotation_rms_deg) = (JointKind::Ball, 41.0);
        let hub = fit_mut(&mut f, 1, 2);
        (hub.kind, hub.first_pass_kind) = (JointKind::Ball, Some(JointKind::Hinge));
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 2), (1, 2), (2, 3)]);
        let hub = fit_mut(&mut f, 1, 2);
        (hub.kind, hub.first_pass_kind) = (JointKind::Hinge, Some(JointKind::Ball));
        let t = run(&seg, &f, &Params::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(0, 1)));
    }

    #[test]
    fn rigid_pairs_are_taken_first_and_noted() {
        // Chain 0-1-2 by cost; pair (0, 2) is rigid with a high cost.
        let f = fits(3, |a, b| match (a, b) {
            (0, 2) => (50.0, JointKind::Rigid),
            (0, 1) => (1.0, JointKind::Ball),
            _ => (2.0, JointKind::Ball),
        });
        let seg = segmentation(&[3, 3, 3]);
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (0, 2)]);
        assert!(t.notes.iter().any(|n| n.contains("rigid")));
        let p = Params {
            rigid_first: false,
            ..Params::default()
        };
        let t = run(&seg, &f, &p).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2)]);
        // The kind read is the first pass's: rigid there, a ball in the second pass, still
        // first; and the reverse is not.
        let mut f = f;
        let pair = fit_mut(&mut f, 0, 2);
        (pair.kind, pair.first_pass_kind) = (JointKind::Ball, Some(JointKind::Rigid));
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (0, 2)]);
        let pair = fit_mut(&mut f, 0, 2);
        (pair.kind, pair.first_pass_kind) = (JointKind::Rigid, Some(JointKind::Ball));
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2)]);
    }

    /// Segments 0-1-2 and 3-4, each a chain of joints fitting within 5 mm, and every pair
    /// across them `across_mm` off; the cheapest pair of all (2, 3) is across.
    fn two_bodies(across_mm: f64) -> (Segmentation, PairFits) {
        let body = |s: usize| usize::from(s >= 3);
        let mut f = fits(5, tree_costs(&[(0, 1), (1, 2), (3, 4)]));
        for p in &mut f.pairs {
            p.residual_rms_mm = if body(p.a) == body(p.b) {
                5.0
            } else {
                across_mm
            };
        }
        fit_mut(&mut f, 0, 2).residual_rms_mm = 30.0;
        fit_mut(&mut f, 2, 3).cost = 0.5;
        (segmentation(&[4, 3, 3, 5, 4]), f)
    }

    #[test]
    fn two_bodies_make_two_trees_and_no_pair_joins_them() {
        let (seg, f) = two_bodies(1000.0);
        assert_eq!(typical_joint_residual(&f), Some(5.0));
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2)]);
        assert_eq!(t.detached_segments, vec![3, 4]);
        assert_eq!(t.bodies, vec![vec![0, 1, 2], vec![3, 4]]);
        assert_eq!(t.body, Some(0));
        assert!(
            t.notes
                .iter()
                .any(|n| n.starts_with("2 bodies, of [3, 2] segments"))
        );
        assert!(!t.notes.iter().any(|n| n.contains("detached")));
        // No pair from the other body stands in for one of the tree's joints.
        let runner_ups: Vec<_> = t
            .joints
            .iter()
            .filter_map(|j| j.runner_up.as_ref())
            .collect();
        assert!(
            runner_ups
                .iter()
                .all(|r| r.parent_side < 3 && r.child_side < 3)
        );

        let other = Params {
            body: Some(SegmentRef::Marker("M14".into())),
            ..Params::default()
        };
        let t = run(&seg, &f, &other).unwrap();
        assert_eq!(edge_set(&t), vec![(3, 4)]);
        assert_eq!(
            (t.detached_segments.clone(), t.body),
            (vec![0, 1, 2], Some(1))
        );

        let apart = Params {
            root: Some(SegmentRef::Id(0)),
            ..other.clone()
        };
        let e = run(&seg, &f, &apart).unwrap_err().to_string();
        assert!(e.contains("another body than topo.body's segment 3"), "{e}");
        let missing = Params {
            body: Some(SegmentRef::Id(7)),
            ..Params::default()
        };
        let e = run(&seg, &f, &missing).unwrap_err().to_string();
        assert!(e.starts_with("topo: topo.body = 7 is not usable"), "{e}");

        // Off, or pairs across that fit a joint well enough: one body, as before.
        let off = Params {
            max_residual_ratio: 0.0,
            ..Params::default()
        };
        for (across, params, longest) in [
            (1000.0, &off, 0.0),
            (150.0, &Params::default(), 0.0),
            // A segment longer than the pairs across disagree: they may be its joints.
            (1000.0, &Params::default(), 1200.0),
        ] {
            let (seg, mut f) = two_bodies(across);
            f.poses[0].reference = vec![[0.0; 3], [longest, 0.0, 0.0]];
            let t = run(&seg, &f, params).unwrap();
            assert_eq!(edge_set(&t), vec![(0, 1), (1, 2), (2, 3), (3, 4)]);
            assert!(t.bodies.is_empty() && t.body.is_none());
        }
    }

    /// Segments 0-1-2, a chain of joints fitting within 5 mm (misfit 1), and segment 3,
    /// the markers that never move (the room), whose pairs fit `room_mm` off at a misfit
    /// of `room_misfit`; the room's pair with 2 is the cheapest of all.
    fn a_body_and_the_room(room_mm: f64, room_misfit: f64) -> (Segmentation, PairFits) {
        let mut f = fits(4, tree_costs(&[(0, 1), (1, 2), (2, 3)]));
        for p in &mut f.pairs {
            (p.residual_rms_mm, p.misfit_over_noise) = if p.b == 3 {
                (room_mm, room_misfit)
            } else {
                (5.0, 1.0)
            };
        }
        fit_mut(&mut f, 2, 3).cost = 0.5;
        let mut seg = segmentation(&[4, 3, 3, 6]);
        seg.stationary_segment = Some(3);
        (seg, f)
    }

    #[test]
    fn the_room_joins_a_body_only_as_tightly_as_a_joint_and_is_then_its_root() {
        // A sway 3 times the typical joint's, misfit 4: a body of its own, the last.
        let (seg, f) = a_body_and_the_room(15.0, 4.0);
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2)]);
        assert_eq!(t.bodies, vec![vec![0, 1, 2], vec![3]]);
        assert_eq!(t.body, Some(0));
        // As any other pair, 15 mm is well within 40 times 5.
        let off = Params {
            stationary_residual_ratio: 0.0,
            ..Params::default()
        };
        let t = run(&seg, &f, &off).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2), (2, 3)]);
        // A fixed base: within twice the typical residual, or a misfit the poses' noise
        // explains; the tree's root.
        for (room_mm, misfit) in [(8.0, 4.0), (15.0, 1.2)] {
            let (seg, f) = a_body_and_the_room(room_mm, misfit);
            let t = run(&seg, &f, &Params::default()).unwrap();
            assert_eq!(edge_set(&t), vec![(0, 1), (1, 2), (2, 3)]);
            assert!(t.bodies.is_empty());
            assert_eq!(t.root_segment, 3);
        }
        // The room alone is the last body even where it holds more markers.
        use std::cmp::Ordering::{Greater, Less};
        assert_eq!(bigger_first(&[1], &[0], &[3, 6], None), Less);
        assert_eq!(bigger_first(&[1], &[0], &[3, 6], Some(1)), Greater);
    }

    /// Segments 0-1-2 a chain as in [`a_body_and_the_room`], and segment 3 a prop the
    /// segment stage saw move on its own (`Segmentation::bodies`) whose pairs fit `prop_mm`
    /// off at a misfit of `misfit`: a pair 3 times the typical joint's is no joint there,
    /// as with the room, where it would be one within a body.
    #[test]
    fn bodies_the_segment_stage_told_apart_join_only_as_tightly_as_a_joint() {
        let apart = |prop_mm: f64, misfit: f64| {
            let (mut seg, f) = a_body_and_the_room(prop_mm, misfit);
            seg.stationary_segment = None;
            seg.bodies = vec![vec![0, 1, 2], vec![3]];
            (seg, f)
        };
        let (seg, f) = apart(15.0, 4.0);
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2)]);
        assert_eq!(t.bodies, vec![vec![0, 1, 2], vec![3]]);
        assert!(t.notes.iter().any(|n| n.contains(
            "between the 2 bodies the segment stage saw move independently, \
             topo.stationary_residual_ratio 2 times"
        )));
        // Told apart by nothing, 15 mm is within 40 times 5.
        let (mut seg, f) = apart(15.0, 4.0);
        seg.bodies.clear();
        let t = run(&seg, &f, &Params::default()).unwrap();
        assert_eq!(edge_set(&t), vec![(0, 1), (1, 2), (2, 3)]);
        // A joint as tight as a typical one joins them (a limb cut off by sparse markers).
        for (prop_mm, misfit) in [(8.0, 4.0), (15.0, 1.2)] {
            let (seg, f) = apart(prop_mm, misfit);
            let t = run(&seg, &f, &Params::default()).unwrap();
            assert_eq!(edge_set(&t), vec![(0, 1), (1, 2), (2, 3)]);
            assert!(t.bodies.is_empty());
        }
    }

    #[test]
    fn forced_root_and_errors() {
        let edges = [(0, 1), (1, 2)];
        let f = fits(3, tree_costs(&edges));
        let seg = segmentation(&[3, 3, 3]);
        let p = Params {
            root: Some(SegmentRef::Id(0)),
            ..Params::default()
        };
        let t = run(&seg, &f, &p).unwrap();
        assert_eq!(t.root_segment, 0);
        assert_eq!(t.joints[1].parent_joint, Some(0));
        let bad = Params {
            root: Some(SegmentRef::Id(7)),
            ..Params::default()
        };
        assert!(matches!(
            run(&seg, &f, &bad),
            Err(Error::BadRoot { root, .. }) if root == "7"
        ));
        assert!(matches!(
            run(&segmentation(&[3, 3]), &f, &Params::default()),
            Err(Error::SegmentCountMismatch { .. })
        ));
        assert!(matches!(
            run(
                &segmentation(&[]),
                &fits(0, tree_costs(&[])),
                &Params::default()
            ),
            Err(Error::NoSegments { unassigned: 0, .. })
        ));
        // A single segment is a tree with no joints.
        let t = run(
            &segmentation(&[4]),
            &fits(1, tree_costs(&[])),
            &Params::default(),
        )
        .unwrap();
        assert_eq!((t.root_segment, t.joints.len()), (0, 0));
    }

    #[test]
    fn params_round_trip_and_docs_cover_every_field() {
        let p: Params = serde_json::from_str(r#"{"root": 3}"#).unwrap();
        assert_eq!(p.root, Some(SegmentRef::Id(3)));
        let p: Params =
            serde_json::from_str(r#"{"root": "LASI", "joints": [[2, "RKNE"]]}"#).unwrap();
        assert_eq!(p.root, Some(SegmentRef::Marker("LASI".into())));
        for wrong in [
            r#"{"root": -1}"#,
            r#"{"root": 1.5}"#,
            r#"{"joints": [[true, 2]]}"#,
        ] {
            let e = serde_json::from_str::<Params>(wrong)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("a segment id (0, 1, …) or the label of a marker"),
                "{e}"
            );
        }
        assert_eq!(
            p.joints,
            [[SegmentRef::Id(2), SegmentRef::Marker("RKNE".into())]]
        );
        assert!(p.rigid_first);
        assert!(serde_json::from_str::<Params>(r#"{"rooot": 3}"#).is_err());
        let v = serde_json::to_value(Params::default()).unwrap();
        let fields: Vec<&String> = v.as_object().unwrap().keys().collect();
        for f in fields {
            assert!(
                crate::PARAM_DOCS.iter().any(|(n, _)| n == f),
                "{f} undocumented"
            );
        }
    }

    /// Siblings 1 and 2 on hub 0 (each turning on it with three independent angles): the
    /// sibling pair is the cheapest and turns hardly more than either joint, so neither
    /// the costs nor the rotations' sizes say it is their composite; seen from the hub the
    /// two joints turn independently, seen from either sibling they do not.
    #[test]
    fn siblings_that_turn_independently_of_each_other_hang_on_their_hub() {
        let seg = segmentation(&[4, 4, 4]);
        let mut f = fits(3, |a, b| match (a, b) {
            (1, 2) => (1.0, JointKind::Ball),
            (0, 1) => (1.3, JointKind::Ball),
            _ => (1.4, JointKind::Ball),
        });
        turning(&mut f, |a, _| if a == 0 { 30.0 } else { 32.0 });
        f.frames = 480;
        f.poses = crate::independence::hub_and_two_children(480);
        let on = Params {
            composite_independence_margin: 2.0,
            ..Params::default()
        };
        let t = run(&seg, &f, &on).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(edge_set(&t), [(0, 1), (0, 2)]);
        let off = Params {
            composite_independence_margin: 0.0,
            ..on.clone()
        };
        let t = run(&seg, &f, &off).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(1, 2)));
        // Beyond the cost ratio (1.4 > 1.2 x 1.0) the sibling pair stands.
        let tight = Params {
            composite_independence_cost_ratio: 1.2,
            ..on
        };
        let t = run(&seg, &f, &tight).unwrap_or_else(|e| panic!("{e}"));
        assert!(edge_set(&t).contains(&(1, 2)));
    }
}
