//! The bonefit stage: constant offsets, then forward kinematics over every frame.

use glam::{DQuat, DVec3};
use jointfit::{PairFit, PairFits};
use mocap_io::Trajectories;
use segment::Segmentation;
use topo::Topology;

use crate::horn::{RotationFit, spans_plane};
use crate::poses::{FilledPoses, fill, fill_rotations};
use crate::{BoneMethod, Error, HingePlacement, Params, RotationMethod, Skeleton, SkeletonJoint};

/// Name of the root node in animation files.
const ROOT_NAME: &str = "root";

/// One topology joint resolved against the pair fits.
struct JointSpec<'a> {
    name: &'a str,
    parent: Option<usize>,
    parent_segment: usize,
    child_segment: usize,
    pair_index: usize,
    pair: &'a PairFit,
    /// Joint centre in the parent segment's local frame (mm).
    centre_in_parent: DVec3,
}

/// The tree's joints as `(pair, parent segment, child segment)`, as jointfit's tree
/// functions take them.
fn tree_edges(topo: &Topology) -> Vec<(usize, usize, usize)> {
    topo.joints
        .iter()
        .map(|j| (j.pair, j.parent_segment, j.child_segment))
        .collect()
}

/// Fits constant offsets and computes the motion (see the crate docs).
pub fn run(
    traj: &Trajectories,
    seg: &Segmentation,
    fits: &PairFits,
    topo: &Topology,
    params: &Params,
) -> Result<Skeleton, Error> {
    // The markers as segmentation read them: swaps undone, glitch samples missing.
    let repaired = seg.repaired(traj);
    let traj = repaired.as_ref();
    let frames = traj.frames();
    let segments = fits.poses.len();
    if seg.segments.len() != segments {
        return Err(Error::SegmentCountMismatch {
            segments: seg.segments.len(),
            poses: segments,
        });
    }
    // Every segment is the root, one joint's child or detached, exactly once.
    let placed_segments = 1 + topo.joints.len() + topo.detached_segments.len();
    if placed_segments != segments {
        return Err(Error::TopologyMismatch {
            segments,
            topology: placed_segments,
        });
    }
    for (s, p) in fits.poses.iter().enumerate() {
        for (what, found) in [
            ("rotations", p.rotations.len()),
            ("translations", p.translations.len()),
        ] {
            if found != frames {
                return Err(Error::FrameCountMismatch {
                    what: format!("segment {s} pose {what}"),
                    expected: frames,
                    found,
                });
            }
        }
    }
    let root = topo.root_segment;
    if root >= segments {
        return Err(Error::BadRoot { root, segments });
    }
    // The tree steps change the pair fits on one working copy, which holds the tree
    // pairs' positions (jointfit's artifact leaves them to be derived); the poses are never
    // changed, only the tree pairs' centres and positions.
    let mut work = fits.clone();
    work.fill_positions(topo.joints.iter().map(|j| j.pair));
    // Both tree readings read the segments' precision and poses; built once.
    let tree_poses =
        (params.tree_centres || params.tree_positions).then(|| jointfit::TreePoses::of(fits));
    if params.tree_centres
        && let Some(poses) = &tree_poses
    {
        jointfit::tree_centres(&mut work, &tree_edges(topo), poses);
    }
    // Hinge centres placed on their axes from the tree.
    let mut hinge_shifts = vec![0.0; topo.joints.len()];
    // Per tree joint: its slide ends at a point two segments' fit measured.
    let mut measured_point = vec![false; topo.joints.len()];
    if params.place_hinges {
        let copy = &mut work;
        let edges = tree_edges(topo);
        // What the placement reads as it was before: the tree pairs and their bones.
        let before: Vec<Option<PairFit>> = edges
            .iter()
            .map(|&(pair, _, _)| copy.pairs.get(pair).cloned())
            .collect();
        let bones: Vec<f64> = (0..edges.len())
            .map(|e| bone_length_before(copy, topo, e))
            .collect();
        let shifts = match params.hinge_placement {
            HingePlacement::Tree => jointfit::place_hinge_centres(copy, &edges),
            HingePlacement::Bone => {
                let (directed, direction) =
                    jointfit::placement_direction(copy, &edges, params.hinge_sides_from_steadiest);
                let placed = jointfit::place_hinges_across_bones(
                    copy,
                    &directed,
                    direction,
                    params.hinge_lines,
                );
                measured_point = placed.at_composite_point;
                placed.shifts
            }
            mode => {
                // The joint solve, capped, for hinges with no ball joint below them.
                let mut tree = copy.clone();
                let mut tree_shifts = jointfit::place_hinge_centres(&mut tree, &edges);
                for (s, &bone) in tree_shifts.iter_mut().zip(&bones) {
                    let short = bone.is_nan()
                        || bone <= 0.0
                        || s.abs() <= params.hinge_max_shift_ratio * bone;
                    if !short {
                        *s = 0.0;
                    }
                }
                let chain = mode == HingePlacement::Chain;
                place_hinges_on_child(copy, topo, &tree_shifts, chain)
            }
        };
        let capped = params.hinge_placement == HingePlacement::Tree;
        for (e, ((h, s), &(pair, _, _))) in
            hinge_shifts.iter_mut().zip(shifts).zip(&edges).enumerate()
        {
            if s == 0.0 {
                continue;
            }
            // A true hinge's centre slides along its axis at no cost to the fit; where the
            // slide makes the two segments disagree about the centre noticeably more, the
            // axis is not a line of equally good centres (a ball read as a hinge, a noisy
            // axis): keep the pair fit's centre. Unless the slide ends at a point other
            // segments' fit measured: then the pair's own wobble along a skin-tilted axis
            // is what grows, not doubt about where the centre is.
            let (Some(before), Some(after)) = (&before[e], copy.pairs.get(pair)) else {
                continue;
            };
            let (r0, r1) = (pair_residual(copy, before), pair_residual(copy, after));
            // A slide that is a large part of the bone comes from an ill-conditioned
            // system (nearly parallel neighbouring axes, a noisy axis), not from anatomy.
            let bone = bones[e];
            let short = !capped
                || bone.is_nan()
                || bone <= 0.0
                || s.abs() <= params.hinge_max_shift_ratio * bone;
            let steady = r1 <= r0 * (1.0 + params.hinge_residual_increase.max(0.0)) + 0.1;
            // The residual grows along any axis by its wobble times the slide; where the
            // rotation barely fixes the centre along it, that growth says little, unless
            // it is several-fold (CMU 02_01's elbows, 1.0 -> 5.8 mm for a 121 mm slide).
            // (Its gain, a pass over the frames, only for a slide the residual refused;
            // it reads the poses alone, which the placement leaves as they were.)
            // Below that gain the slide is kept in part: the pair fit places the centre
            // along the axis to about the gain times its poses' error, the placement to
            // about hinge_free_gain times it, so each counts by the other's variance.
            let residual_bound_holds =
                r1 <= r0 * (1.0 + params.hinge_free_residual_increase.max(0.0)) + 0.1;
            let gain = || {
                (params.hinge_free_gain > 0.0 && residual_bound_holds)
                    .then(|| jointfit::centre_gain(copy, pair))
                    .flatten()
            };
            if short && (steady || measured_point[e]) {
                *h = s;
            } else if let Some(g) = short.then(gain).flatten() {
                let share = if g >= params.hinge_free_gain {
                    1.0
                } else {
                    g * g / (g * g + params.hinge_free_gain * params.hinge_free_gain)
                };
                if share < 1.0 {
                    let mut part = slid_part(before, after, share);
                    part.residual_rms_mm = pair_residual(copy, &part);
                    copy.pairs[pair] = part;
                }
                *h = share * s;
            } else {
                copy.pairs[pair] = before.clone();
            }
        }
    }
    // Then every tree joint's positions read from all the tree's views at once.
    if params.tree_positions
        && let Some(poses) = &tree_poses
    {
        jointfit::tree_positions(&mut work, &tree_edges(topo), poses);
    }
    let fits = &work;
    let specs = resolve_joints(fits, topo, frames)?;

    let rate = traj.frame_rate();
    let max_gap = if rate > 0.0 && params.max_gap_s.is_finite() && params.max_gap_s > 0.0 {
        (params.max_gap_s * rate).floor() as usize
    } else {
        0
    };
    // Poses of the tree's segments only: detached segments play no part.
    let mut tracks: Vec<Option<FilledPoses>> = (0..segments).map(|_| None).collect();
    tracks[root] = Some(fill(&fits.poses[root], max_gap));
    for s in &specs {
        tracks[s.child_segment] = Some(fill(&fits.poses[s.child_segment], max_gap));
    }
    let track = |s: usize| tracks[s].as_ref();

    // The root point: mean of the root's child-joint centres in its frame (its marker
    // centroid, the frame's origin, when it has no children).
    let root_children: Vec<DVec3> = specs
        .iter()
        .filter(|s| s.parent.is_none())
        .map(|s| s.centre_in_parent)
        .collect();
    let root_point = if root_children.is_empty() {
        DVec3::ZERO
    } else {
        root_children.iter().fold(DVec3::ZERO, |a, &c| a + c) / root_children.len() as f64
    };

    // Rigid offsets: the joint centre minus the parent point, both in the parent's frame.
    let mut offsets: Vec<DVec3> = specs
        .iter()
        .map(|s| {
            let from = match s.parent {
                Some(k) => centre_in(specs[k].pair, s.parent_segment),
                None => root_point,
            };
            s.centre_in_parent - from
        })
        .collect();
    if params.method == BoneMethod::Paper {
        let root_track = track(root);
        let root_positions: Vec<DVec3> = (0..frames)
            .map(|f| match root_track {
                Some(t) if t.measured[f] => t.rotations[f] * root_point + t.translations[f],
                _ => DVec3::NAN,
            })
            .collect();
        paper_offsets(&specs, &tracks, &root_positions, &mut offsets);
    }

    // Forward kinematics, frame by frame, exactly as the Skeleton docs define it; each
    // segment's orientation is chosen (fitted or from its pose) once its parent joint is
    // placed, so the fit can anchor on it.
    let models = segment_models(traj, seg, fits, &specs, &offsets, root, root_point);
    let fitted = params.rotations == RotationMethod::Fitted;
    let mut frame_fit = FrameFit {
        traj,
        root,
        specs: &specs,
        models: &models,
        marker_weight: params.marker_weight.max(0.0),
        scratch_local: Vec::new(),
        scratch_observed: Vec::new(),
        scratch_weights: Vec::new(),
    };
    let n = specs.len();
    let mut local_rotations = vec![vec![[0.0; 4]; frames]; n];
    let mut positions = vec![vec![[f64::NAN; 3]; frames]; n];
    let mut root_positions = vec![[f64::NAN; 3]; frames];
    let mut root_rotations = vec![[0.0, 0.0, 0.0, 1.0]; frames];
    let mut root_translations = vec![[f64::NAN; 3]; frames];
    let mut local_now = vec![DQuat::IDENTITY; n];
    let mut on_way = vec![false; n];
    let mut fitted_centre: Vec<Option<DVec3>> = vec![None; n];
    let subtree_joints = subtree_sizes(&specs);
    let mut frames_known = vec![0usize; n];
    let mut frames_interpolated = vec![0usize; n];
    let mut fit_sq = vec![0.0f64; n];
    let mut fit_count = vec![0usize; n];
    let mut global = vec![DQuat::IDENTITY; n];
    let mut point = vec![DVec3::ZERO; n];
    let mut known = vec![false; n];
    let mut measured = vec![false; n];
    // Per segment at the current frame: the target orientation, and whether it is fixed
    // by observations (measured) or by those or a filled pose gap (known).
    let mut seg_rotation = vec![DQuat::IDENTITY; segments];
    let mut seg_known = vec![false; segments];
    let mut seg_measured = vec![false; segments];
    let offset_arrays: Vec<[f64; 3]> = offsets.iter().map(|o| o.to_array()).collect();
    // The root's orientation where neither its pose nor the observations fix it (a point,
    // a line or nothing seen): the nearest fixed one, slerped between and held at the ends,
    // so the root does not snap to identity where its pose track was never measured.
    let root_hold = {
        let root_track = track(root);
        let determined: Vec<Option<DQuat>> = (0..frames)
            .map(|f| {
                let pose = root_track.filter(|t| t.measured[f]).map(|t| t.rotations[f]);
                if !fitted || pose.is_some() {
                    return pose;
                }
                let prior = Prior {
                    rotation: root_track.map_or(DQuat::IDENTITY, |t| t.rotations[f]),
                    known: false,
                    measured: false,
                };
                frame_fit
                    .root(f, prior)
                    .filter(|e| e.measured)
                    .map(|e| e.rotation)
            })
            .collect();
        fill_rotations(&determined)
    };
    // Each joint's last local rotation (child relative to parent). Where a child segment's
    // own pose was not measured, its orientation carries on from there rather than from
    // its pose track's fill: the observations then leave the spin about a line (or every
    // angle) to that prior, and a track whose own poses turn far from the fitted ones (three
    // markers nearly in line) made the skeleton snap for the frames of a gap (by 115° in
    // quadruped-hard-s20045's BVH).
    let mut last_local: Vec<Option<DQuat>> = vec![None; n];
    // With it, each segment's pull towards that rotation (see `rotation_prior_deg_s`):
    // the weight a turn of that speed over one frame has against its markers' scatter.
    let turn_prior_weight: Vec<Option<f64>> = fits
        .poses
        .iter()
        .map(|p| {
            let turn = (params.rotation_prior_deg_s / rate).to_radians();
            if !(fitted && turn > 0.0 && turn.is_finite()) {
                return None;
            }
            let scatter = p.median_rms_mm()?;
            let weight = params.marker_weight.max(0.0) * scatter * scatter / (turn * turn);
            // Exact data (no scatter) keep the weak prior of their own poses.
            (weight > 0.0).then_some(weight)
        })
        .collect();
    for f in 0..frames {
        let prior = |s: usize| match track(s) {
            Some(t) => Prior {
                rotation: t.rotations[f],
                known: t.known[f],
                measured: t.measured[f],
            },
            None => Prior {
                rotation: DQuat::IDENTITY,
                known: false,
                measured: false,
            },
        };
        let mut root_prior = prior(root);
        if !root_prior.measured {
            root_prior.rotation = root_hold[f];
        }
        let root_pose_point = match track(root) {
            Some(t) => t.rotations[f] * root_point + t.translations[f],
            None => DVec3::NAN,
        };
        let estimate = if fitted {
            frame_fit.root(f, root_prior)
        } else {
            None
        };
        let (root_rotation, root_position, root_known, root_measured) = match estimate {
            Some(e) => (e.rotation, e.anchor, e.known, e.measured),
            None => (
                root_prior.rotation,
                root_pose_point,
                root_prior.known,
                root_prior.measured,
            ),
        };
        root_rotations[f] = root_rotation.normalize().to_array();
        let root_rotation = DQuat::from_array(root_rotations[f]);
        let root_known = root_known && root_position.is_finite();
        if root_known {
            root_positions[f] = root_position.to_array();
        }
        seg_rotation[root] = root_rotation;
        seg_known[root] = root_known;
        seg_measured[root] = root_measured;
        // Where the root is not known, the chains start from the observed parent joint of
        // a segment posed on its own (`anchor_joint`): the root point is put where the
        // rotations along the way up reach that joint, so forward kinematics from it gives
        // the joint and everything below it; only the way up and what hangs off it stay
        // unknown.
        let anchor = if fitted && !root_known {
            anchor_joint(&specs, &subtree_joints, f, |s| {
                track(s).is_some_and(|t| t.measured[f])
            })
        } else {
            None
        };
        let mut base = if anchor.is_some() {
            DVec3::ZERO
        } else {
            root_position
        };
        // The segments on the way up are not posed on their own (one would carry more
        // joints and be the anchor), and a fit about their parent joint would hang on where
        // the root point goes: they keep their prior orientations, so the way's reach does
        // not move with the root point and a second pass lands on the anchor exactly.
        on_way.fill(false);
        if let Some((a, _)) = anchor {
            let mut k = specs[a].parent;
            while let Some(j) = k {
                on_way[j] = true;
                k = specs[j].parent;
            }
        }
        let passes = if anchor.is_some() { 2 } else { 1 };
        for pass in 0..passes {
            for (j, s) in specs.iter().enumerate() {
                let (g_parent, p_parent, k_parent, m_parent) = match s.parent {
                    Some(k) => (global[k], point[k], known[k], measured[k]),
                    None => (root_rotation, base, root_known, root_measured),
                };
                let offset = DVec3::from_array(offset_arrays[j]);
                point[j] = p_parent + g_parent * offset;
                fitted_centre[j] = s
                    .pair
                    .positions
                    .get(f)
                    .map(|&p| DVec3::from_array(p))
                    .filter(|c| c.is_finite());
                // With fitted rotations the bone towards an observed centre is aimed at it,
                // whatever the parent segment's spin.
                let aimed = fitted && fitted_centre[j].is_some();
                let p = s.parent_segment;
                known[j] = k_parent && (seg_known[p] || aimed);
                measured[j] = m_parent && (seg_measured[p] || aimed);
                if let Some((a, target)) = anchor
                    && a == j
                    && point[j].distance(target) <= ANCHOR_TOLERANCE_MM
                {
                    // The child's own pose fixes this joint, wherever the way up is unknown.
                    known[j] = true;
                    measured[j] = true;
                }

                // The child segment's orientation, anchored at this joint.
                let c = s.child_segment;
                let mut child_prior = prior(c);
                let mut turn_weight = 0.0;
                if fitted && let Some(q) = last_local[j] {
                    if let Some(w) = turn_prior_weight[c] {
                        child_prior.rotation = g_parent * q;
                        turn_weight = w;
                    } else if !child_prior.measured {
                        child_prior.rotation = g_parent * q;
                    }
                }
                let estimate = if fitted && point[j].is_finite() && !on_way[j] {
                    frame_fit.about_joint(f, c, point[j], child_prior, turn_weight)
                } else {
                    None
                };
                (seg_rotation[c], seg_known[c], seg_measured[c]) = match estimate {
                    Some(e) => (e.rotation, e.known, e.measured),
                    None => (
                        child_prior.rotation,
                        child_prior.known,
                        child_prior.measured,
                    ),
                };
                local_now[j] = (g_parent.inverse() * seg_rotation[c]).normalize();
                global[j] = g_parent * local_now[j];
            }
            if let Some((a, target)) = anchor
                && pass + 1 < passes
            {
                base += target - point[a];
            }
        }
        root_translations[f] = base.to_array();
        for j in 0..n {
            local_rotations[j][f] = local_now[j].to_array();
            last_local[j] = Some(local_now[j]);
            if known[j] {
                positions[j][f] = point[j].to_array();
                frames_known[j] += 1;
                if !measured[j] {
                    frames_interpolated[j] += 1;
                }
                if let Some(c) = fitted_centre[j] {
                    fit_sq[j] += (point[j] - c).length_squared();
                    fit_count[j] += 1;
                }
            }
        }
    }

    let joints = specs
        .iter()
        .enumerate()
        .map(|(j, s)| {
            let relative: Vec<DQuat> = match (track(s.parent_segment), track(s.child_segment)) {
                (Some(p), Some(c)) => (0..frames)
                    .filter(|&f| p.measured[f] && c.measured[f])
                    .map(|f| p.rotations[f].inverse() * c.rotations[f])
                    .collect(),
                _ => Vec::new(),
            };
            SkeletonJoint {
                name: s.name.to_owned(),
                parent: s.parent,
                parent_segment: s.parent_segment,
                child_segment: s.child_segment,
                pair: s.pair_index,
                offset: offset_arrays[j],
                bone_length: offsets[j].length(),
                local_rotations: std::mem::take(&mut local_rotations[j]),
                positions: std::mem::take(&mut positions[j]),
                frames_known: frames_known[j],
                frames_interpolated: frames_interpolated[j],
                fit_rms_mm: if fit_count[j] > 0 {
                    (fit_sq[j] / fit_count[j] as f64).sqrt()
                } else {
                    f64::NAN
                },
                range_of_motion_deg: range_of_motion_deg(&relative),
                hinge_shift_mm: hinge_shifts.get(j).copied().unwrap_or(0.0),
            }
        })
        .collect();

    Ok(Skeleton {
        frame_rate: rate,
        frame_count: frames,
        root_segment: root,
        root_name: ROOT_NAME.to_owned(),
        method: params.method.name().to_owned(),
        rotation_method: params.rotations.name().to_owned(),
        root_point_in_segment: root_point.to_array(),
        root_positions,
        root_translations,
        root_rotations,
        joints,
    })
}

/// Shortest observed vector (mm) that counts towards fixing a rotation by itself.
const MIN_LEVER_MM: f64 = 10.0;
/// Two observed vectors fix a rotation when at least this far apart (sine, ≈ 6°).
const MIN_SPREAD_SIN: f64 = 0.1;

/// How near forward kinematics must bring an anchor joint to its observed position for the
/// joint to count as known there (mm).
const ANCHOR_TOLERANCE_MM: f64 = 0.01;

/// Per joint, how many joints its child segment carries below it, itself included.
fn subtree_sizes(specs: &[JointSpec]) -> Vec<usize> {
    let mut sizes = vec![1; specs.len()];
    // Parents come before their children, so children are summed first from the end.
    for j in (0..specs.len()).rev() {
        if let Some(k) = specs[j].parent {
            sizes[k] += sizes[j];
        }
    }
    sizes
}

/// The joint the chains of frame `f` start from where the root is not known: of the joints
/// whose child segment is posed on its own there (`posed`) and whose position the pair fit
/// observed, the one carrying the most joints (the first in tree order on a tie), with that
/// observed position; `None` when there is none.
fn anchor_joint(
    specs: &[JointSpec],
    subtree_joints: &[usize],
    f: usize,
    posed: impl Fn(usize) -> bool,
) -> Option<(usize, DVec3)> {
    let mut best: Option<(usize, DVec3)> = None;
    for (j, s) in specs.iter().enumerate() {
        let Some(target) = s
            .pair
            .positions
            .get(f)
            .map(|&p| DVec3::from_array(p))
            .filter(|p| p.is_finite())
        else {
            continue;
        };
        if posed(s.child_segment) && best.is_none_or(|(b, _)| subtree_joints[j] > subtree_joints[b])
        {
            best = Some((j, target));
        }
    }
    best
}

/// What a segment's orientation is fitted to, in its local frame, relative to its anchor
/// (the parent joint's centre; the root point for the root).
#[derive(Default)]
struct SegmentModel {
    /// (joint index, constant bone vector from the anchor to that child joint), mm.
    children: Vec<(usize, DVec3)>,
    /// (marker index in the trajectories, reference position relative to the anchor), mm.
    markers: Vec<(usize, DVec3)>,
}

/// A segment's pose track at one frame: the fit's weak prior and fallback.
#[derive(Clone, Copy)]
struct Prior {
    /// Measured or interpolated orientation (never NaN).
    rotation: DQuat,
    /// Measured or inside a filled short gap.
    known: bool,
    /// Measured by jointfit.
    measured: bool,
}

/// One segment's fitted orientation at one frame.
struct Estimate {
    /// Orientation, local frame → global frame.
    rotation: DQuat,
    /// The anchor's global position (mm): the given parent joint, or the fitted root point.
    anchor: DVec3,
    /// Fixed by observations or by a measured or filled pose.
    known: bool,
    /// Fixed by observations or by a measured pose (not only a filled gap).
    measured: bool,
}

/// The prior turned by the least rotation that points its view of the observations' line
/// (the weighted mean of the local vectors from the joint, each taken on the first one's
/// side) along the observed one (the same of the observed points less the joint at
/// `anchor`): the two angles such points fix, the spin about them kept. The prior itself
/// where either mean vanishes.
fn swing_from_prior(
    local: &[DVec3],
    observed: &[DVec3],
    weights: &[f64],
    anchor: DVec3,
    prior: DQuat,
) -> DQuat {
    let Some(&first) = local.iter().find(|a| a.length_squared() > 0.0) else {
        return prior;
    };
    let (mut along_local, mut along_observed) = (DVec3::ZERO, DVec3::ZERO);
    for ((&a, &b), &w) in local.iter().zip(observed).zip(weights) {
        let side = if a.dot(first) < 0.0 { -w } else { w };
        along_local += side * a;
        along_observed += side * (b - anchor);
    }
    match (
        (prior * along_local).try_normalize(),
        along_observed.try_normalize(),
    ) {
        (Some(from), Some(to)) => (DQuat::from_rotation_arc(from, to) * prior).normalize(),
        _ => prior,
    }
}

/// Builds every tree segment's model: its child joints' bone vectors and its markers.
fn segment_models(
    traj: &Trajectories,
    seg: &Segmentation,
    fits: &PairFits,
    specs: &[JointSpec<'_>],
    offsets: &[DVec3],
    root: usize,
    root_point: DVec3,
) -> Vec<SegmentModel> {
    let segments = fits.poses.len();
    let mut anchors: Vec<Option<DVec3>> = vec![None; segments];
    anchors[root] = Some(root_point);
    for s in specs {
        anchors[s.child_segment] = Some(centre_in(s.pair, s.child_segment));
    }
    let mut models: Vec<SegmentModel> = (0..segments).map(|_| SegmentModel::default()).collect();
    for (k, s) in specs.iter().enumerate() {
        models[s.parent_segment].children.push((k, offsets[k]));
    }
    for (s, model) in models.iter_mut().enumerate() {
        let (Some(anchor), Some(segment)) = (anchors[s], seg.segments.get(s)) else {
            continue;
        };
        for (&m, &r) in segment.markers.iter().zip(&fits.poses[s].reference) {
            let r = DVec3::from_array(r);
            if m < traj.markers() && r.is_finite() {
                model.markers.push((m, r - anchor));
            }
        }
    }
    models
}

/// The per-frame orientation fit (see [`crate::RotationMethod::Fitted`]), with scratch
/// buffers reused across frames.
struct FrameFit<'a> {
    traj: &'a Trajectories,
    root: usize,
    specs: &'a [JointSpec<'a>],
    models: &'a [SegmentModel],
    marker_weight: f64,
    scratch_local: Vec<DVec3>,
    scratch_observed: Vec<DVec3>,
    scratch_weights: Vec<f64>,
}

impl FrameFit<'_> {
    /// Collects segment `s`'s observations at frame `f` (local vector, observed global
    /// point, weight) into the scratch buffers.
    fn observe(&mut self, s: usize, f: usize) {
        self.scratch_local.clear();
        self.scratch_observed.clear();
        self.scratch_weights.clear();
        let model = &self.models[s];
        for &(k, a) in &model.children {
            let y = self.specs[k]
                .pair
                .positions
                .get(f)
                .map_or(DVec3::NAN, |&p| DVec3::from_array(p));
            if y.is_finite() {
                self.scratch_local.push(a);
                self.scratch_observed.push(y);
                self.scratch_weights.push(1.0);
            }
        }
        if self.marker_weight > 0.0 {
            let markers = self.traj.markers();
            let positions = self.traj.positions();
            for &(m, a) in &model.markers {
                let z = positions
                    .get(f * markers + m)
                    .map_or(DVec3::NAN, |&p| DVec3::from_array(p));
                if z.is_finite() {
                    self.scratch_local.push(a);
                    self.scratch_observed.push(z);
                    self.scratch_weights.push(self.marker_weight);
                }
            }
        }
    }

    /// Orientation of segment `s` about its parent joint at `anchor` (global, mm); `None`
    /// when nothing of the segment is observed at frame `f`.
    fn about_joint(
        &mut self,
        f: usize,
        s: usize,
        anchor: DVec3,
        prior: Prior,
        prior_weight: f64,
    ) -> Option<Estimate> {
        self.observe(s, f);
        if self.scratch_local.is_empty() {
            return None;
        }
        let mut fit = RotationFit::new();
        for ((&a, &b), &w) in self
            .scratch_local
            .iter()
            .zip(&self.scratch_observed)
            .zip(&self.scratch_weights)
        {
            fit.add(a, b - anchor, w);
        }
        let spans = spans_plane(&self.scratch_local, MIN_LEVER_MM, MIN_SPREAD_SIN);
        // Points on one line through the joint fix only that line's direction; the spin
        // about it is the prior's, not what noise across the line makes of it.
        let rotation = if spans {
            fit.solve_with(prior.rotation, prior_weight)
        } else {
            swing_from_prior(
                &self.scratch_local,
                &self.scratch_observed,
                &self.scratch_weights,
                anchor,
                prior.rotation,
            )
        };
        Some(Estimate {
            rotation,
            anchor,
            known: spans || prior.known,
            measured: spans || prior.measured,
        })
    }

    /// The root segment's orientation and root point (a rigid fit with translation);
    /// `None` when nothing of the root is observed at frame `f`.
    fn root(&mut self, f: usize, prior: Prior) -> Option<Estimate> {
        self.observe(self.root, f);
        let total: f64 = self.scratch_weights.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return None;
        }
        let (mut local_mean, mut observed_mean) = (DVec3::ZERO, DVec3::ZERO);
        for ((&a, &b), &w) in self
            .scratch_local
            .iter()
            .zip(&self.scratch_observed)
            .zip(&self.scratch_weights)
        {
            local_mean += w * a;
            observed_mean += w * b;
        }
        local_mean /= total;
        observed_mean /= total;
        let mut fit = RotationFit::new();
        for ((&a, &b), &w) in self
            .scratch_local
            .iter()
            .zip(&self.scratch_observed)
            .zip(&self.scratch_weights)
        {
            fit.add(a - local_mean, b - observed_mean, w);
        }
        // Three points not on one line fix a rigid pose.
        let first = self.scratch_local[0];
        for a in self.scratch_local.iter_mut() {
            *a -= first;
        }
        let spans = spans_plane(&self.scratch_local, MIN_LEVER_MM, MIN_SPREAD_SIN);
        let rotation = fit.solve(prior.rotation);
        Some(Estimate {
            rotation,
            anchor: observed_mean - rotation * local_mean,
            known: spans || prior.known,
            measured: spans || prior.measured,
        })
    }
}

/// Slides each hinge centre of the tree along its axis, by itself, to the point nearest
/// the far end of its child bone, seen in the child segment's frame: the mean of the
/// child segment's ball (non-hinge) child joints; with `chain`, else of its hinge child
/// joints as already placed (leaves first). A hinge axis runs across the bone it moves
/// (a knee's across the shank, an elbow's across the forearm) and a ball child is a
/// well-determined point, so this is the centre; unlike the joint solve over all hinges,
/// no hinge is pulled by a parent bone its axis need not cross, and nearly parallel
/// neighbouring axes cannot couple into a long common slide, so no length cap is needed.
/// Hinges with no such target take `tree_shifts[e]` (the capped joint solve). Recomputes
/// the moved pairs' centres and positions in `fits`; returns each topology joint's shift
/// along its axis (mm, 0 where nothing moved).
fn place_hinges_on_child(
    fits: &mut PairFits,
    topo: &Topology,
    tree_shifts: &[f64],
    chain: bool,
) -> Vec<f64> {
    let joints = &topo.joints;
    let mut shifts = vec![0.0; joints.len()];
    // Depth of each joint below the root, so children are placed before their parents.
    let depth = |mut e: usize| {
        let mut d = 0usize;
        while let Some(up) = joints
            .iter()
            .position(|j| j.child_segment == joints[e].parent_segment)
        {
            d += 1;
            e = up;
            if d > joints.len() {
                break;
            }
        }
        d
    };
    let mut order: Vec<usize> = (0..joints.len()).collect();
    order.sort_by_key(|&e| std::cmp::Reverse(depth(e)));
    for e in order {
        let joint = &joints[e];
        let x = joint.child_segment;
        let Some(fit) = fits.pairs.get(joint.pair) else {
            continue;
        };
        // A centre the markers' distances fixed (jointfit) is not free along its axis.
        let free = fit.free_hinge();
        if !free || !(fit.a == x || fit.b == x) {
            continue;
        }
        let (Some(ua), Some(ub)) = (fit.axis_in_a, fit.axis_in_b) else {
            continue;
        };
        let u = DVec3::from_array(if fit.a == x { ua } else { ub });
        let c = centre_in(fit, x);
        if !c.is_finite() || !u.is_finite() || u.length_squared() < 1e-12 {
            continue;
        }
        let (mut balls, mut hinges) = (Vec::new(), Vec::new());
        for child in joints.iter().filter(|j| j.parent_segment == x) {
            let Some(f) = fits.pairs.get(child.pair) else {
                continue;
            };
            let t = centre_in(f, x);
            if !t.is_finite() {
                continue;
            }
            if f.kind == jointfit::JointKind::Hinge {
                hinges.push(t);
            } else {
                balls.push(t);
            }
        }
        let targets = if balls.is_empty() && chain {
            hinges
        } else {
            balls
        };
        let shift = if targets.is_empty() {
            tree_shifts.get(e).copied().unwrap_or(0.0)
        } else {
            let target = targets.iter().fold(DVec3::ZERO, |a, &t| a + t) / targets.len() as f64;
            u.dot(target - c) / u.length_squared()
        };
        if !shift.is_finite() || shift == 0.0 {
            continue;
        }
        shifts[e] = shift;
        jointfit::slide_hinge_centre(fits, joint.pair, shift, "toward its child bone's far end");
    }
    shifts
}

/// Length (mm) of topology joint `e`'s bone from its parent segment's anchor (the parent
/// joint's centre, or for the root the mean of its child joints' centres), in the parent
/// segment's frame, with the pair fits' centres; NaN when not computable.
fn bone_length_before(fits: &PairFits, topo: &Topology, e: usize) -> f64 {
    let Some(joint) = topo.joints.get(e) else {
        return f64::NAN;
    };
    let p = joint.parent_segment;
    let centre = |pair: usize| fits.pairs.get(pair).map_or(DVec3::NAN, |f| centre_in(f, p));
    let anchor = match topo.joints.iter().find(|j| j.child_segment == p) {
        Some(into) => centre(into.pair),
        None => {
            let children: Vec<DVec3> = topo
                .joints
                .iter()
                .filter(|j| j.parent_segment == p)
                .map(|j| centre(j.pair))
                .collect();
            children.iter().fold(DVec3::ZERO, |a, &c| a + c) / children.len().max(1) as f64
        }
    };
    (centre(joint.pair) - anchor).length()
}

/// `before` with its centre moved `share` of the way to `after`'s along the slide between
/// them, positions alike (each frame's position is linear in the two centres, so the
/// positions between are the positions of the centres between).
fn slid_part(before: &PairFit, after: &PairFit, share: f64) -> PairFit {
    let between = |x: [f64; 3], y: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|i| x[i] + share * (y[i] - x[i]))
    };
    let mut part = after.clone();
    part.centre_in_a = between(before.centre_in_a, after.centre_in_a);
    part.centre_in_b = between(before.centre_in_b, after.centre_in_b);
    part.positions = before
        .positions
        .iter()
        .zip(&after.positions)
        .map(|(x, y)| between(*x, *y))
        .collect();
    part
}

/// RMS over the frames where both segments are posed of the distance between the pair's
/// centre as each segment carries it (mm); NaN when never both posed.
fn pair_residual(fits: &PairFits, pair: &PairFit) -> f64 {
    let (Some(pa), Some(pb)) = (fits.poses.get(pair.a), fits.poses.get(pair.b)) else {
        return f64::NAN;
    };
    let (ca, cb) = (
        DVec3::from_array(pair.centre_in_a),
        DVec3::from_array(pair.centre_in_b),
    );
    let (mut sum, mut count) = (0.0, 0usize);
    for f in 0..pa.rotations.len().min(pb.rotations.len()) {
        let pose = |p: &jointfit::SegmentPoses, c: DVec3| {
            let q = DQuat::from_array(p.rotations[f]);
            let t = p
                .translations
                .get(f)
                .map_or(DVec3::NAN, |&t| DVec3::from_array(t));
            q.normalize() * c + t
        };
        let d = (pose(pa, ca) - pose(pb, cb)).length_squared();
        if d.is_finite() {
            sum += d;
            count += 1;
        }
    }
    if count == 0 {
        f64::NAN
    } else {
        (sum / count as f64).sqrt()
    }
}

/// The pair's joint centre in segment `s`'s local frame (mm).
fn centre_in(pair: &PairFit, s: usize) -> DVec3 {
    DVec3::from_array(pair.centre_in(s))
}

/// Checks every topology joint against the pair fits and resolves its parent joint.
fn resolve_joints<'a>(
    fits: &'a PairFits,
    topo: &'a Topology,
    frames: usize,
) -> Result<Vec<JointSpec<'a>>, Error> {
    let segments = fits.poses.len();
    let mut joint_of_child: Vec<Option<usize>> = vec![None; segments];
    let mut specs = Vec::with_capacity(topo.joints.len());
    for (j, tj) in topo.joints.iter().enumerate() {
        let bad = |reason: String| Error::BadJoint {
            joint: tj.name.clone(),
            reason,
        };
        let (p, c) = (tj.parent_segment, tj.child_segment);
        if p >= segments || c >= segments || p == c {
            return Err(bad(format!(
                "segments {p} → {c} are not two of the {segments} segments with poses"
            )));
        }
        let pair = fits
            .pairs
            .get(tj.pair)
            .ok_or_else(|| bad(format!("pair {} does not exist", tj.pair)))?;
        if (pair.a, pair.b) != (p.min(c), p.max(c)) {
            return Err(bad(format!(
                "pair {} joins segments {} and {}, not {p} and {c}",
                tj.pair, pair.a, pair.b
            )));
        }
        if pair.positions.len() != frames && !pair.positions.is_empty() {
            return Err(Error::FrameCountMismatch {
                what: format!("pair {} positions", tj.pair),
                expected: frames,
                found: pair.positions.len(),
            });
        }
        for s in [p, c] {
            if !centre_in(pair, s).is_finite() {
                return Err(Error::UnfittedJoint {
                    joint: tj.name.clone(),
                    pair: tj.pair,
                    segment: s,
                });
            }
        }
        if joint_of_child[c].is_some() || c == topo.root_segment {
            return Err(bad(format!(
                "segment {c} is the child of more than one joint"
            )));
        }
        let parent = if p == topo.root_segment {
            None
        } else {
            Some(joint_of_child[p].ok_or_else(|| {
                bad(format!(
                    "parent segment {p} is neither the root nor the child of an earlier joint"
                ))
            })?)
        };
        joint_of_child[c] = Some(j);
        specs.push(JointSpec {
            name: &tj.name,
            parent,
            parent_segment: p,
            child_segment: c,
            pair_index: tj.pair,
            pair,
            centre_in_parent: centre_in(pair, p),
        });
    }
    Ok(specs)
}

/// Aguiar et al. Eq. 5–6, root to leaves: bone length = mean distance from the adjusted
/// parent point to the fitted joint; adjusted joint = parent + length × unit direction.
/// The offset's direction is the mean of that unit direction in the parent's frame.
/// Joints with no usable frame keep their rigid offset.
fn paper_offsets(
    specs: &[JointSpec<'_>],
    tracks: &[Option<FilledPoses>],
    root_positions: &[DVec3],
    offsets: &mut [DVec3],
) {
    let mut adjusted: Vec<Vec<DVec3>> = Vec::with_capacity(specs.len());
    for (j, s) in specs.iter().enumerate() {
        let from: &[DVec3] = match s.parent {
            Some(k) => &adjusted[k],
            None => root_positions,
        };
        let mut directions = vec![DVec3::NAN; from.len()];
        let (mut sum, mut count) = (0.0, 0usize);
        for (f, d) in directions.iter_mut().enumerate() {
            let c = s
                .pair
                .positions
                .get(f)
                .map_or(DVec3::NAN, |&p| DVec3::from_array(p));
            let v = c - from[f];
            let len = v.length();
            if len.is_finite() && len > 0.0 {
                *d = v / len;
                sum += len;
                count += 1;
            }
        }
        if count == 0 {
            adjusted.push(vec![DVec3::NAN; from.len()]);
            continue;
        }
        let length = sum / count as f64;
        let parent_track = tracks[s.parent_segment].as_ref();
        let mut mean_direction = DVec3::ZERO;
        for (f, d) in directions.iter().enumerate() {
            if let Some(t) = parent_track.filter(|t| t.measured[f] && d.is_finite()) {
                mean_direction += t.rotations[f].inverse() * *d;
            }
        }
        offsets[j] = match mean_direction.try_normalize() {
            Some(u) => u * length,
            None => offsets[j].normalize_or_zero() * length,
        };
        adjusted.push(
            from.iter()
                .zip(&directions)
                .map(|(&p, &d)| p + d * length)
                .collect(),
        );
    }
}

/// Largest angle between two of the relative orientations (degrees), by two sweeps: the
/// orientation farthest from the mean, then the one farthest from that. NaN when empty.
fn range_of_motion_deg(relative: &[DQuat]) -> f64 {
    let Some(mean) = jointfit::chordal_mean(relative) else {
        return f64::NAN;
    };
    let angle = |a: DQuat, b: DQuat| 2.0 * a.dot(b).abs().min(1.0).acos();
    let farthest = |from: DQuat| {
        relative
            .iter()
            .copied()
            .max_by(|&x, &y| angle(from, x).total_cmp(&angle(from, y)))
            .unwrap_or(from)
    };
    let extreme = farthest(mean);
    angle(extreme, farthest(extreme)).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RotationMethod;
    use crate::testkit::{Scene, scene};

    /// The stage on the scene's capture and segmentation with `fits` and `topo`, defaults.
    fn run_on(s: &Scene, fits: &PairFits, topo: &Topology) -> Result<Skeleton, Error> {
        run(
            &s.trajectories,
            &s.segmentation,
            fits,
            topo,
            &Params::default(),
        )
    }

    fn fit(s: &Scene, params: &Params) -> Skeleton {
        match run(
            &s.trajectories,
            &s.segmentation,
            &s.fits,
            &s.topology,
            params,
        ) {
            Ok(k) => k,
            Err(e) => panic!("bonefit failed: {e}"),
        }
    }

    /// Forward kinematics from the skeleton's own numbers, written independently of `run`.
    fn forward_kinematics(k: &Skeleton, f: usize) -> Vec<DVec3> {
        let root_q = DQuat::from_array(k.root_rotations[f]);
        let root_p = DVec3::from_array(k.root_translations[f]);
        let mut global: Vec<DQuat> = Vec::new();
        let mut position: Vec<DVec3> = Vec::new();
        for j in &k.joints {
            let (gq, gp) = match j.parent {
                Some(p) => (global[p], position[p]),
                None => (root_q, root_p),
            };
            position.push(gp + gq * DVec3::from_array(j.offset));
            global.push(gq * DQuat::from_array(j.local_rotations[f]));
        }
        position
    }

    fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
        (DVec3::from_array(a) - DVec3::from_array(b)).length()
    }

    #[test]
    fn rigid_bones_are_exact_and_fk_reproduces_truth() {
        let s = scene(200, 100.0);
        let k = fit(&s, &Params::default());
        assert_eq!(k.method, "rigid");
        assert_eq!(k.frame_count, 200);
        let names: Vec<&str> = k.joints.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["j1", "j3", "j2"]);
        assert_eq!(k.joints[2].parent, Some(0));
        // Root point: mean of the torso's child-joint centres (0,0,-200) and (0,0,180).
        assert_eq!(k.root_point_in_segment, [0.0, 0.0, -10.0]);
        for (j, want) in k.joints.iter().zip([190.0, 190.0, 300.0]) {
            assert!(
                (j.bone_length - want).abs() < 1e-9,
                "{}: {}",
                j.name,
                j.bone_length
            );
            assert_eq!(j.frames_known, 200);
            assert_eq!(j.frames_interpolated, 0);
            assert!(j.fit_rms_mm < 1e-9, "{}: {}", j.name, j.fit_rms_mm);
        }
        for f in 0..200 {
            let fk = forward_kinematics(&k, f);
            for (j, joint) in k.joints.iter().enumerate() {
                assert!(distance(fk[j].to_array(), joint.positions[f]) < 1e-9);
                assert!(distance(joint.positions[f], s.truth[j][f]) < 1e-9);
                let q = DQuat::from_array(joint.local_rotations[f]);
                assert!((q.length() - 1.0).abs() < 1e-12);
            }
        }
        // Range of motion: the knee flexes 0..1 rad (57.3°).
        assert!((k.joints[2].range_of_motion_deg - 1.0f64.to_degrees()).abs() < 0.5);
    }

    #[test]
    fn paper_method_gives_the_same_bones_on_exact_data() {
        let s = scene(150, 100.0);
        let p = Params {
            method: BoneMethod::Paper,
            ..Params::default()
        };
        let k = fit(&s, &p);
        assert_eq!(k.method, "paper");
        for (j, want) in k.joints.iter().zip([190.0, 190.0, 300.0]) {
            assert!(
                (j.bone_length - want).abs() < 1e-6,
                "{}: {}",
                j.name,
                j.bone_length
            );
            assert!(j.fit_rms_mm < 1e-6);
        }
    }

    #[test]
    fn paper_method_bone_length_is_the_mean_distance_under_noise() {
        // Perturb the fitted knee centre: ±5 mm along the shank on alternate frames.
        let mut s = scene(100, 100.0);
        let knee = s.topology.joints[2].pair;
        let hip = s.topology.joints[0].pair;
        for f in 0..100 {
            let hip_p = DVec3::from_array(s.fits.pairs[hip].positions[f]);
            let knee_p = DVec3::from_array(s.fits.pairs[knee].positions[f]);
            let along = (knee_p - hip_p).normalize() * if f % 2 == 0 { 5.0 } else { -5.0 };
            s.fits.pairs[knee].positions[f] = (knee_p + along).to_array();
        }
        let p = Params {
            method: BoneMethod::Paper,
            ..as_given()
        };
        let k = fit(&s, &p);
        assert!((k.joints[2].bone_length - 300.0).abs() < 1e-6);
        // FK still reproduces the truth: the noise averaged out of the constant bone.
        assert!(k.joints[2].fit_rms_mm > 4.9 && k.joints[2].fit_rms_mm < 5.1);
    }

    /// The marker-pose rotations (the method before `fitted`).
    fn poses() -> Params {
        Params {
            rotations: RotationMethod::Poses,
            ..Params::default()
        }
    }

    /// The pair fits' centres and positions as given (tests that edit them).
    fn as_given() -> Params {
        Params {
            place_hinges: false,
            ..Params::default()
        }
    }

    /// Segment `segment` without a pose (rotation and translation) at `range`.
    fn unpose(s: &mut Scene, segment: usize, range: std::ops::Range<usize>) {
        let poses = &mut s.fits.poses[segment];
        for f in range {
            poses.rotations[f] = [f64::NAN; 4];
            poses.translations[f] = [f64::NAN; 3];
        }
    }

    /// Hides marker `m` of the trajectories at the frames `range`.
    fn hide_marker(s: &mut Scene, m: usize, range: std::ops::Range<usize>) {
        let markers = s.trajectories.markers();
        let mut positions = s.trajectories.positions().to_vec();
        for f in range {
            positions[f * markers + m] = [f64::NAN; 3];
        }
        set_positions(s, positions);
    }

    /// The scene's capture with these marker positions (frame-major, as the capture's).
    fn set_positions(s: &mut Scene, positions: Vec<[f64; 3]>) {
        let t = &s.trajectories;
        s.trajectories = Trajectories::new(
            t.labels().to_vec(),
            t.frame_rate(),
            t.first_frame(),
            t.frames(),
            positions,
        )
        .unwrap_or_else(|e| panic!("{e}"));
    }

    #[test]
    fn fitted_rotations_follow_the_centres_not_the_poses() {
        // Every segment's pose is tilted by a few degrees; markers and centres are exact.
        let mut s = scene(120, 100.0);
        for (i, p) in s.fits.poses.iter_mut().enumerate() {
            for (f, q) in p.rotations.iter_mut().enumerate() {
                let tilt = DQuat::from_rotation_y(0.05 * (1.0 + i as f64) * (0.1 * f as f64).sin());
                *q = (DQuat::from_array(*q) * tilt).to_array();
            }
        }
        let fitted = fit(&s, &as_given());
        assert_eq!(fitted.rotation_method, "fitted");
        let chained = fit(&s, &poses());
        let mut worst_chained = 0.0f64;
        for f in 0..120 {
            for j in 0..3 {
                let e = distance(fitted.joints[j].positions[f], s.truth[j][f]);
                assert!(e < 1e-6, "frame {f} joint {j}: {e} mm");
                worst_chained =
                    worst_chained.max(distance(chained.joints[j].positions[f], s.truth[j][f]));
            }
            // The fitted orientations are the true ones: markers and centres agree on them.
            let fk = forward_kinematics(&fitted, f);
            for (j, joint) in fitted.joints.iter().enumerate() {
                assert!(distance(fk[j].to_array(), joint.positions[f]) < 1e-9);
            }
        }
        assert!(worst_chained > 5.0, "{worst_chained}");
    }

    #[test]
    fn fitted_rotations_use_the_child_side_and_two_markers_in_pose_gaps() {
        let mut s = scene(100, 100.0);
        // The thigh (markers 3, 4, 5) loses its pose and every marker at 40..70; the knee's
        // fitted centre is still known there (carried by the shank).
        unpose(&mut s, 1, 40..70);
        for m in 3..6 {
            hide_marker(&mut s, m, 40..70);
        }
        // The torso (markers 0, 1, 2) keeps two markers at 20..30 and loses its pose.
        unpose(&mut s, 0, 20..30);
        hide_marker(&mut s, 2, 20..30);
        let k = fit(&s, &as_given());
        for (j, joint) in k.joints.iter().enumerate() {
            assert_eq!(joint.frames_known, 100, "{}", joint.name);
            assert_eq!(joint.frames_interpolated, 0, "{}", joint.name);
            for f in 0..100 {
                let e = distance(joint.positions[f], s.truth[j][f]);
                assert!(e < 1e-6, "frame {f} {}: {e} mm", joint.name);
            }
        }
        // Without the knee's centre in the gap nothing orients the thigh: the knee is
        // unknown there (a 30-frame gap is longer than max_gap_s), known elsewhere.
        let knee = s.topology.joints[2].pair;
        for f in 40..70 {
            s.fits.pairs[knee].positions[f] = [f64::NAN; 3];
        }
        let k = fit(&s, &as_given());
        assert_eq!(k.joints[2].frames_known, 70);
        assert!(k.joints[2].positions[55][0].is_nan());
        assert_eq!(k.joints[0].frames_known, 100);
    }

    #[test]
    fn hinge_centres_slide_back_onto_the_bone() {
        // The knee (hinge about local x) fitted off along its axis: any point of the axis
        // fits the motion equally, the bone from the hip is shortest at the truth.
        let knee_off = |off: f64| {
            let mut s = scene(100, 100.0);
            let knee = s.topology.joints[2].pair;
            let pair = &mut s.fits.pairs[knee];
            pair.centre_in_a[0] += off;
            pair.centre_in_b[0] += off;
            for (f, p) in pair.positions.iter_mut().enumerate() {
                let q = DQuat::from_array(s.fits.poses[1].rotations[f]);
                *p = (DVec3::from_array(*p) + q * DVec3::new(off, 0.0, 0.0)).to_array();
            }
            s
        };
        let s = knee_off(25.0);
        let off = fit(&s, &as_given());
        assert!((off.joints[2].bone_length - 300.0f64.hypot(25.0)).abs() < 1e-6);
        assert_eq!(off.joints[2].hinge_shift_mm, 0.0);
        let child = Params {
            hinge_placement: HingePlacement::Child,
            ..Params::default()
        };
        for params in [&child, &Params::default()] {
            let k = fit(&s, params);
            assert!((k.joints[2].hinge_shift_mm + 25.0).abs() < 1e-6);
            assert!((k.joints[2].bone_length - 300.0).abs() < 1e-6);
            for f in 0..100 {
                assert!(distance(k.joints[2].positions[f], s.truth[2][f]) < 1e-6);
            }
            assert_eq!(k.joints[0].hinge_shift_mm, 0.0);
        }
        // `child` refuses the tree solve's slide of a fifth of the bone (ill-conditioned
        // systems give those) unless the limit allows it; `bone` (default) has no cap:
        // the thigh's hip, the shank's markers (centred on the bone) all agree.
        let s = knee_off(60.0);
        assert_eq!(fit(&s, &child).joints[2].hinge_shift_mm, 0.0);
        let p = Params {
            hinge_max_shift_ratio: 0.5,
            ..child
        };
        assert!((fit(&s, &p).joints[2].hinge_shift_mm + 60.0).abs() < 1e-6);
        let k = fit(&s, &Params::default());
        assert!((k.joints[2].hinge_shift_mm + 60.0).abs() < 1e-6);
        assert!((k.joints[2].bone_length - 300.0).abs() < 1e-6);
    }

    #[test]
    fn hinge_with_a_ball_child_slides_uncapped_to_the_point_nearest_it() {
        // The scene's head becomes a foot hanging from the shank by a ball ankle, so the
        // knee hinge (axis local x) has a ball joint on its child segment. The knee is
        // fitted 80 mm off along its axis; the ankle sits at x = 20 mm in the shank, so
        // the point of the knee axis nearest it is 60 mm from the fitted centre, a fifth
        // of the 310 mm thigh bone: `child` goes there, `tree` is refused by the 10 % cap.
        let (frames, rate) = (100, 100.0);
        let mut s = scene(frames, rate);
        let (ankle_in_shank, ankle_in_foot) =
            (DVec3::new(20.0, 0.0, -100.0), DVec3::new(0.0, 0.0, 40.0));
        let mut positions = s.trajectories.positions().to_vec();
        let markers = s.trajectories.markers();
        let mut ankle = Vec::with_capacity(frames);
        for f in 0..frames {
            let t = f as f64 / rate;
            let shank = &s.fits.poses[2];
            let (q2, t2) = (
                DQuat::from_array(shank.rotations[f]),
                DVec3::from_array(shank.translations[f]),
            );
            let centre = q2 * ankle_in_shank + t2;
            let q = q2
                * DQuat::from_rotation_y(0.5 * (2.0 * t).sin())
                * DQuat::from_rotation_z(0.4 * (1.7 * t).cos());
            let origin = centre - q * ankle_in_foot;
            let foot = &mut s.fits.poses[3];
            foot.rotations[f] = q.to_array();
            foot.translations[f] = origin.to_array();
            for (m, r) in foot.reference.iter().enumerate() {
                positions[f * markers + 9 + m] = (q * DVec3::from_array(*r) + origin).to_array();
            }
            ankle.push(centre.to_array());
        }
        s.trajectories = match Trajectories::new(
            s.trajectories.labels().to_vec(),
            rate,
            s.trajectories.first_frame(),
            frames,
            positions,
        ) {
            Ok(t) => t,
            Err(e) => panic!("trajectories: {e}"),
        };
        let shank_foot = s.fits.pairs.iter().position(|p| (p.a, p.b) == (2, 3));
        let Some(shank_foot) = shank_foot else {
            panic!("no shank-foot pair");
        };
        let pair = &mut s.fits.pairs[shank_foot];
        pair.centre_in_a = ankle_in_shank.to_array();
        pair.centre_in_b = ankle_in_foot.to_array();
        pair.positions = ankle;
        pair.cost = 3.0;
        // Tree 0→1→2→3: hip (ball), knee (hinge), ankle (ball).
        s.topology.joints[1].parent_segment = 2;
        s.topology.joints[1].pair = shank_foot;
        s.topology.joints[1].parent_joint = Some(2);
        s.topology.joints.swap(1, 2);
        s.topology.joints[2].parent_joint = Some(1);

        let off = 80.0;
        let knee = s.topology.joints[1].pair;
        let pair = &mut s.fits.pairs[knee];
        pair.centre_in_a[0] += off;
        pair.centre_in_b[0] += off;
        for (f, p) in pair.positions.iter_mut().enumerate() {
            let q = DQuat::from_array(s.fits.poses[1].rotations[f]);
            *p = (DVec3::from_array(*p) + q * DVec3::new(off, 0.0, 0.0)).to_array();
        }
        // The point of the knee axis nearest the ankle, globally per frame.
        let nearest: Vec<[f64; 3]> = (0..frames)
            .map(|f| {
                let shank = &s.fits.poses[2];
                let q = DQuat::from_array(shank.rotations[f]);
                (q * DVec3::new(ankle_in_shank.x, 0.0, 120.0)
                    + DVec3::from_array(shank.translations[f]))
                .to_array()
            })
            .collect();
        let knee_joint = |k: &Skeleton| match k.joints.iter().find(|j| j.name == "j2") {
            Some(j) => j.clone(),
            None => panic!("no knee joint"),
        };

        let child = Params {
            hinge_placement: HingePlacement::Child,
            ..Params::default()
        };
        let k = knee_joint(&fit(&s, &child));
        assert!(
            (k.hinge_shift_mm + 60.0).abs() < 0.1,
            "shift {}",
            k.hinge_shift_mm
        );
        assert_eq!(k.positions.len(), frames);
        for (f, (&p, &n)) in k.positions.iter().zip(&nearest).enumerate() {
            let d = distance(p, n);
            assert!(
                d < 0.1,
                "child: frame {f} knee {d} mm from the nearest point"
            );
        }
        // `bone` (default) too: the ankle is on the shank's bone; the hip, 20 mm off the
        // ankle's plane, disagrees and is left out; the shank's markers, centred 20 mm off
        // too, pull by their small weight (σ 14 mm against the ankle's 1 mm).
        let k = knee_joint(&fit(&s, &Params::default()));
        assert!(
            (k.hinge_shift_mm + 60.0).abs() < 0.5,
            "bone: shift {}",
            k.hinge_shift_mm
        );

        let tree = Params {
            hinge_placement: HingePlacement::Tree,
            ..Params::default()
        };
        let k = knee_joint(&fit(&s, &tree));
        assert_eq!(k.hinge_shift_mm, 0.0);
        assert_eq!(k.positions.len(), frames);
        for (f, (&p, &n)) in k.positions.iter().zip(&nearest).enumerate() {
            let d = distance(p, n);
            assert!(
                d > 10.0,
                "tree: frame {f} knee {d} mm from the nearest point"
            );
        }
    }

    #[test]
    fn pose_gaps_short_filled_long_unknown_rotations_never_nan() {
        let mut s = scene(100, 100.0);
        let thigh = &mut s.fits.poses[1];
        for f in (10..14).chain(40..70) {
            thigh.rotations[f] = [f64::NAN; 4];
            thigh.translations[f] = [f64::NAN; 3];
        }
        // The head is never seen.
        s.fits.poses[3].rotations.fill([f64::NAN; 4]);
        let k = fit(&s, &poses()); // 0.1 s = 10 frames at 100 Hz
        let (hip, head, knee) = (&k.joints[0], &k.joints[1], &k.joints[2]);
        // The hip hangs on the torso only: known everywhere.
        assert_eq!(hip.frames_known, 100);
        // The knee hangs on the thigh: the 4-frame gap is filled, the 30-frame gap unknown.
        assert_eq!(knee.frames_known, 70);
        assert_eq!(knee.frames_interpolated, 4);
        assert!(knee.positions[50][0].is_nan());
        assert!(!knee.positions[12][0].is_nan());
        // An interpolated frame of a rigid chain stays close to the truth (slow motion).
        assert!(distance(knee.positions[12], s.truth[2][12]) < 30.0);
        assert!(head.range_of_motion_deg.is_nan());
        for j in &k.joints {
            for f in 0..100 {
                assert!(j.local_rotations[f].iter().all(|c| c.is_finite()));
            }
        }
        assert!(k.root_rotations.iter().flatten().all(|c| c.is_finite()));
        // FK of the stored numbers is the stored positions wherever known.
        for f in 0..100 {
            let fk = forward_kinematics(&k, f);
            for (j, joint) in k.joints.iter().enumerate() {
                if !joint.positions[f][0].is_nan() {
                    assert!(distance(fk[j].to_array(), joint.positions[f]) < 1e-9);
                }
            }
        }
        // With gap filling off, the short gap is unknown too.
        let p = Params {
            max_gap_s: 0.0,
            ..poses()
        };
        assert_eq!(fit(&s, &p).joints[2].frames_known, 66);
    }

    #[test]
    fn unknown_root_pose_leaves_root_and_joints_unknown() {
        let mut s = scene(50, 100.0);
        for f in 20..45 {
            s.fits.poses[0].rotations[f] = [f64::NAN; 4];
        }
        let k = fit(&s, &poses());
        assert!(k.root_positions[30][0].is_nan());
        assert!(!k.root_positions[10][0].is_nan());
        assert!(k.joints.iter().all(|j| j.frames_known == 25));
    }

    /// Fitted rotations: the torso's markers gone too, its two child centres lie on one line
    /// through the root point, so its spin is unknown there and the root point with it. The
    /// thigh is posed on its own, so the hip it observes starts the chains there: the hip
    /// and the knee below it stay known and exact, forward kinematics from the skeleton's
    /// root translation reaches them, and the head (on the unknown torso) is unknown.
    #[test]
    fn an_unknown_root_leaves_the_chains_below_a_posed_segment_known() {
        let mut s = scene(50, 100.0);
        unpose(&mut s, 0, 20..45);
        for m in 0..3 {
            hide_marker(&mut s, m, 20..45);
        }
        let k = fit(&s, &Params::default());
        let known: Vec<usize> = k.joints.iter().map(|j| j.frames_known).collect();
        // j1 (hip), j3 (neck), j2 (knee).
        assert_eq!(known, [50, 25, 50]);
        for f in 0..50 {
            let fk = forward_kinematics(&k, f);
            assert!(
                k.root_translations[f].iter().all(|c| c.is_finite()),
                "frame {f}"
            );
            if (20..45).contains(&f) {
                assert!(k.root_positions[f][0].is_nan(), "frame {f}");
                assert!(k.joints[1].positions[f][0].is_nan(), "frame {f}");
            }
            for j in [0, 2] {
                let at = k.joints[j].positions[f];
                assert!(distance(at, s.truth[j][f]) < 1e-6, "joint {j} frame {f}");
                assert!(distance(fk[j].to_array(), at) < 1e-9, "joint {j} frame {f}");
            }
        }
        // Without the thigh's pose there, the head and the shank are the segments posed on
        // their own, each carrying one joint: the first in tree order (the neck) starts
        // the chains, and the knee, on another way up, stays unknown with the hip.
        unpose(&mut s, 1, 20..45);
        for f in 20..45 {
            s.fits.pairs[s.topology.joints[0].pair].positions[f] = [f64::NAN; 3];
        }
        let k = fit(&s, &Params::default());
        let known: Vec<usize> = k.joints.iter().map(|j| j.frames_known).collect();
        assert_eq!(known, [25, 50, 25]);
        for f in 20..45 {
            let at = k.joints[1].positions[f];
            assert!(distance(at, s.truth[1][f]) < 1e-6, "frame {f}");
            assert!(distance(forward_kinematics(&k, f)[1].to_array(), at) < 1e-9);
        }
    }

    #[test]
    fn inconsistent_inputs_are_errors() {
        let s = scene(20, 100.0);
        let mut topo = s.topology.clone();
        topo.joints[2].pair = 0;
        let r = run_on(&s, &s.fits, &topo);
        assert!(matches!(r, Err(Error::BadJoint { .. })));
        let mut fits = s.fits.clone();
        fits.poses[2].rotations.pop();
        let r = run_on(&s, &fits, &s.topology);
        assert!(matches!(r, Err(Error::FrameCountMismatch { .. })));
        let mut fits = s.fits.clone();
        fits.pairs[0].centre_in_b = [f64::NAN; 3];
        let r = run_on(&s, &fits, &s.topology);
        assert!(matches!(r, Err(Error::UnfittedJoint { segment: 1, .. })));
        let mut topo = s.topology.clone();
        topo.joints.swap(0, 2);
        let r = run_on(&s, &s.fits, &topo);
        assert!(matches!(r, Err(Error::BadJoint { .. })));
    }

    #[test]
    fn topology_and_fits_must_match_the_segmentation() {
        let s = scene(10, 100.0);
        // A 2-segment tree (torso → thigh) against the 4-segment segmentation.
        let mut topo = s.topology.clone();
        topo.joints.truncate(1);
        let r = run_on(&s, &s.fits, &topo);
        match r {
            Err(e @ Error::TopologyMismatch { .. }) => {
                let text = e.to_string();
                assert!(
                    text.contains("covers 2 segments") && text.contains("has 4"),
                    "{text}"
                );
            }
            other => panic!("{:?}", other.map(|_| ())),
        }
        let mut fits = s.fits.clone();
        fits.poses.pop();
        let r = run_on(&s, &fits, &s.topology);
        match r {
            Err(e @ Error::SegmentCountMismatch { .. }) => {
                let text = e.to_string();
                assert!(
                    text.contains("3 segments") && text.contains("has 4"),
                    "{text}"
                );
            }
            other => panic!("{:?}", other.map(|_| ())),
        }
        // With the rest of the tree detached it runs.
        topo.detached_segments = vec![2, 3];
        assert!(run_on(&s, &s.fits, &topo).is_ok());
    }

    #[test]
    fn leading_root_gap_holds_the_first_known_rotation() {
        // The root (torso) is unseen at frames 0..10: no pose, no markers, no centres
        // through it. Its rotation there is held at frame 10's, not identity.
        // Also with one of its markers still seen (a point: the rotation it leaves free
        // comes from the held one).
        for (rotations, hidden) in [
            (RotationMethod::Fitted, 3),
            (RotationMethod::Fitted, 2),
            (RotationMethod::Poses, 3),
        ] {
            let mut s = scene(40, 100.0);
            // Fitted: the root's pose track is never measured, only its markers orient it.
            let unposed = if rotations == RotationMethod::Fitted {
                40
            } else {
                10
            };
            unpose(&mut s, 0, 0..unposed);
            for f in 0..10 {
                for e in &s.topology.joints {
                    if e.parent_segment == 0 {
                        s.fits.pairs[e.pair].positions[f] = [f64::NAN; 3];
                    }
                }
            }
            for m in 0..hidden {
                hide_marker(&mut s, m, 0..10);
            }
            let p = Params {
                rotations,
                ..Params::default()
            };
            let k = fit(&s, &p);
            let at10 = DQuat::from_array(k.root_rotations[10]);
            assert!(at10.angle_between(DQuat::IDENTITY) > 0.05);
            for f in 0..10 {
                let q = DQuat::from_array(k.root_rotations[f]);
                // (1e-6 rad: the weak prior moves frame 10's fit by ~1e-7.)
                assert!(
                    q.angle_between(at10) < 1e-6,
                    "{rotations:?} {hidden} hidden, frame {f}: {:?} vs {:?}",
                    q,
                    at10
                );
                assert!(k.root_positions[f][0].is_nan());
            }
        }
    }

    /// The scene's exact rotations of `segment`, one per frame.
    fn true_rotations(s: &Scene, segment: usize) -> Vec<DQuat> {
        s.fits.poses[segment]
            .rotations
            .iter()
            .map(|&q| DQuat::from_array(q))
            .collect()
    }

    /// How far (degrees) a segment hung on the root turns from `truth` at frame `f` in the
    /// skeleton: the root's rotation chained with its joint's local rotation.
    fn off_truth_deg(k: &Skeleton, segment: usize, truth: &[DQuat], f: usize) -> f64 {
        let joint = k
            .joints
            .iter()
            .find(|j| j.child_segment == segment && j.parent_segment == k.root_segment)
            .unwrap_or_else(|| panic!("no joint from the root to segment {segment}"));
        let global =
            DQuat::from_array(k.root_rotations[f]) * DQuat::from_array(joint.local_rotations[f]);
        global.angle_between(truth[f]).to_degrees()
    }

    /// Where a segment's visible markers lie on one line through its joint, they fix that
    /// line's direction and not the spin about it: the spin carries on from the frames
    /// before (the local rotation held), not from the pose track's fill across the gap,
    /// here turned 90° from the truth as the own poses of three markers nearly in line are.
    #[test]
    fn markers_in_line_with_the_joint_keep_the_spin_they_had() {
        let mut s = scene(40, 100.0);
        let head = 3;
        let truth = true_rotations(&s, head);
        let turned = DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2);
        for (f, q) in s.fits.poses[head].rotations.iter_mut().enumerate() {
            *q = (truth[f] * turned).to_array();
        }
        // One head marker seen at frames 15..25, and no pose there.
        let gap = 15..25;
        unpose(&mut s, head, gap.clone());
        for m in [3 * head + 1, 3 * head + 2] {
            hide_marker(&mut s, m, gap.clone());
        }
        let k = fit(&s, &Params::default());
        for f in gap {
            let off = off_truth_deg(&k, head, &truth, f);
            // The nod turns at most 0.4 × 2.5 rad/s, 5.7° over the 0.1 s gap; the fill is
            // 90° off.
            assert!(off < 8.0, "frame {f}: {off:.1}° from the truth");
        }
    }

    /// A segment whose markers scatter (skin) turns from frame to frame as far as its
    /// observations outweigh a turn at `rotation_prior_deg_s`: a marker jumping 15 mm
    /// to and fro across the head every other frame shakes it by 8° RMS without that prior
    /// and 1.9° with it (8 mm of marker scatter, 100 Hz); exact data (no scatter) are not
    /// held at all (the other tests' exactness).
    #[test]
    fn the_frame_before_steadies_a_scattering_segment() {
        let mut s = scene(60, 100.0);
        let head = 3;
        let truth = true_rotations(&s, head);
        s.fits.poses[head].rms_mm = vec![8.0; 60];
        let markers = s.trajectories.markers();
        let mut positions = s.trajectories.positions().to_vec();
        for (f, q) in truth.iter().enumerate() {
            let across = *q * DVec3::Y * if f % 2 == 0 { 15.0 } else { -15.0 };
            let p = &mut positions[f * markers + 3 * head];
            *p = (DVec3::from_array(*p) + across).to_array();
        }
        set_positions(&mut s, positions);
        let error_deg = |rotation_prior_deg_s: f64| {
            let k = fit(
                &s,
                &Params {
                    rotation_prior_deg_s,
                    ..Params::default()
                },
            );
            let sq: f64 = (10..60)
                .map(|f| off_truth_deg(&k, head, &truth, f).powi(2))
                .sum();
            (sq / 50.0).sqrt()
        };
        let (held, free) = (error_deg(600.0), error_deg(0.0));
        assert!(free > 2.0, "the jitter shakes the free head by {free:.2}°");
        assert!(held < 0.7 * free, "{held:.2}° held against {free:.2}° free");
    }

    #[test]
    fn single_segment_skeleton_has_a_root_only() {
        let s = scene(10, 100.0);
        let topo = Topology {
            root_segment: 2,
            joints: Vec::new(),
            detached_segments: vec![0, 1, 3],
            notes: Vec::new(),
            bodies: Vec::new(),
            body: None,
        };
        let k = run_on(&s, &s.fits, &topo).unwrap_or_else(|e| panic!("{e}"));
        assert!(k.joints.is_empty());
        assert_eq!(k.root_point_in_segment, [0.0; 3]);
        let p = DVec3::from_array(k.root_positions[3]);
        assert!((p - DVec3::from_array(s.fits.poses[2].translations[3])).length() < 1e-9);
    }

    #[test]
    fn params_docs_cover_every_field() {
        let v = serde_json::to_value(Params::default()).unwrap_or_default();
        let fields = v.as_object().map(|o| o.keys().cloned().collect::<Vec<_>>());
        for f in fields.unwrap_or_default() {
            assert!(
                crate::PARAM_DOCS.iter().any(|(n, _)| *n == f),
                "{f} undocumented"
            );
        }
        let p: Params = serde_json::from_str(r#"{"method": "paper"}"#).unwrap_or_default();
        assert_eq!(p.method, BoneMethod::Paper);
    }
}
