//! jointfit: per-frame segment poses and a joint fit for every segment pair.
//!
//! Takes the capture's [`mocap_io::Trajectories`] and the segment stage's
//! [`segment::Segmentation`] (only each segment's marker indices are read) and gives
//! [`PairFits`]: every segment's rigid pose per frame (Horn's quaternion method on the
//! visible markers, ≥ 3, against a mean reference shape), and for every pair `a < b` a
//! joint centre fixed in both segments' local frames (its position per frame follows from
//! them and the poses, [`PairFits::joint_positions`]), a cost for the topology stage, the
//! joint kind (ball / hinge / universal / rigid) with its evidence, and the hinge axis or
//! a universal joint's two axes. Methods
//! (`Params::method`): `score` (symmetrical centre of rotation with SARA hinge axes, closed
//! form, its centres weighted frame by frame by each pose's precision at the centre,
//! `Params::weighted_centres`, and held between the two segments where the motion barely
//! fixes them, `Params::centre_prior`; default), `aguiar` (the paper's Eq. 2 by L-BFGS) and
//! `local` (per-marker density-weighted sphere/circle fits by Levenberg–Marquardt in the
//! other segment's frame, averaged with weight attachment / radius; see `local.rs`).
//!
//! The kind comes from how the relative rotation's directions wobble: a hinge's axis
//! barely moves (`Params::hinge_ratio` against the next direction), or moves no more than
//! the two segments' pose noise tilts it (`Params::hinge_noise_factor`, from each fit's
//! scatter and its markers' inertia: skin on a compact marker set wobbles a hinge's axis as
//! much as a ball joint's least-used direction; a two-marker segment posed through a joint
//! turns about that joint's centre, so its markers' moments about the centre and their
//! radial scatter give its noise); and a pair the ratio calls a hinge is none when its
//! least wobble exceeds that noise several times over (`Params::hinge_max_noise_factor`:
//! two rotations moving together look like one axis to the ratio). After both passes, a
//! ball pair a tree could use is universal when two axes, one fixed in each segment, keep
//! their angle (`Params::universal_ratio`, see `universal.rs`); its centre stays the ball
//! joint's.
//!
//! Segments carried by 1 or 2 markers (or collinear ones) are posed through the joint with
//! a posed neighbour (greedy anchoring, `Params::anchor`, see `anchor.rs`): 2 markers plus
//! the joint centre the neighbour carries; a 1-marker segment gets a swing-only pose (its
//! twist about the centre→marker line is unobservable and set to the neighbour's). Frames
//! where only 2 markers of a larger segment are visible are filled the same way, and so
//! are frames whose visible markers nearly line up when the whole set does not (their spin
//! beyond `Params::max_spin_deg`: a marker hidden from a well-spread set). Where no
//! segment has ≥ 3 non-collinear markers to start from (two markers on every segment),
//! two two-marker segments' common centre starts it (`Params::anchor_seed`, see
//! `seed.rs`): their four markers keep constant distances from it, four spheres meeting
//! in one point per frame, and one of them is posed from its markers plus that point. A
//! segment posed through a joint has a twist about its marker line that is derived, not
//! seen, so its joints are centred by its markers' distances
//! (`Params::anchor_centres_by_distance`) wherever those fix the centre (a hinge's only
//! across its axis, `Params::anchor_hinge_slides`).
//!
//! Greedy anchoring does not know the tree, and a segment whose own markers nearly line
//! up even when all are seen is posed with a spin error that throws its joints' images
//! far. So a second pass (`Params::tree_poses`) runs along the minimum spanning tree of the
//! first pass's costs: such segments are posed through a tree neighbour's joint (or one off
//! the tree whose centre fits clearly better, since their own tree edges came from
//! spin-blind poses; `Params::loose_off_tree_ratio`), anchors are sought among tree
//! neighbours first, and a two-marker segment is posed from both its joints' centres
//! (`Params::anchor_two_centres`). Where that pass posed a segment through a tree
//! neighbour's joint although another neighbour's centre holds its markers clearly better
//! (`Params::anchor_swap_ratio`), a third pass runs along the tree with that neighbour's
//! edge instead: the tentative tree came from greedy anchors, cheap by construction. Topo
//! reads the last pass's pairs' costs, relative rotations and kinds
//! (`Params::tree_from_second_pass`; off, the pairs keep the first pass's for it,
//! `PairFit::first_pass_kind`, and the tree is the one the segments' own poses support).
//! Where a pass would leave a pair the first pass fitted without a centre, the pass before
//! it stands.
//!
//! It does not choose which pairs are joints (topo does, from the costs); hinge centres
//! are placed on their axes from the tree by [`place_hinges_across_bones`] (or the older
//! [`place_hinge_centres`]), which the caller (bonefit) runs once the tree is known,
//! with its edges turned from the segment that turns least in the world where that is
//! clearly not the tree's root ([`steadiest_orientation`]). Once the tree is known, the
//! caller can also refit the tree's centres and read its joints' positions from all the
//! tree's joints at once ([`tree_centres`], [`tree_positions`]: a segment's pose error
//! shows at each joint it carries, so two joints' gaps on one segment err together).

mod aguiar;
mod anchor;
mod error;
mod fit;
mod hinge;
mod horn;
mod local;
mod motion;
mod pairfits;
mod params;
mod poses;
mod score;
mod seed;
mod small;
mod treefit;
mod universal;

pub use error::Error;
pub use hinge::{
    EdgeDirection, HingePlacements, axis_tilt_bound, centre_gain, place_hinge_centres,
    place_hinges_across_bones, placement_direction, slide_hinge_centre, steadiest_orientation,
};
pub use horn::{RigidFit, absolute_orientation, chordal_mean, rotation_from_cross_covariance};
pub use pairfits::*;
pub use params::{Method, PARAM_DOCS, Params};
pub use treefit::{TreePoses, tree_centres, tree_positions};

use glam::DVec3;
use mocap_io::Trajectories;
use rayon::prelude::*;

/// Stage name, as the runner and cache know it.
pub const STAGE: &str = "jointfit";

/// Runs the stage: poses of every segment, then every pair's joint fit (in parallel;
/// each pair is computed serially, so the output does not depend on the thread count),
/// on the trajectories with the segmentation's label swaps undone.
pub fn run(
    traj: &Trajectories,
    seg: &segment::Segmentation,
    params: &Params,
) -> Result<PairFits, Error> {
    let mut segments = Vec::with_capacity(seg.segments.len());
    for (position, s) in seg.segments.iter().enumerate() {
        if s.id != position {
            return Err(Error::SegmentId { position, id: s.id });
        }
        segments.push(s.markers.clone());
    }
    run_on_segments(&seg.repaired(traj), &segments, params)
}

/// A segment's rotation uncertainty about its markers' line with all its markers seen
/// (degrees, the linearised standard error: its median fit scatter over the lever of its
/// reference shape), at most [`SPIN_UNFIXED_DEG`]; `None` for fewer than 3 markers, no
/// fitted frame or markers on a line.
pub fn segment_spin_deg(poses: &SegmentPoses) -> Option<f64> {
    poses::spin_error_deg(poses)
        .filter(|d| d.is_finite())
        .map(|d| d.min(SPIN_UNFIXED_DEG))
}

/// The largest spin error [`segment_spin_deg`] gives (degrees): a turn's error beyond half
/// a revolution means the markers do not fix that turn at all (the linearised figure grows
/// without bound as they line up: 1.7e8 degrees for Sample_Jump2's right forearm).
pub const SPIN_UNFIXED_DEG: f64 = 180.0;

/// [`run`] on bare marker lists: `segments[id]` = marker indices of segment `id` (for
/// evaluations that start from a known segmentation rather than the segment stage's).
pub fn run_on_segments(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    params: &Params,
) -> Result<PairFits, Error> {
    let mut fits = fit_passes(traj, segments, params)?;
    universal::read_universal_joints(&mut fits, params);
    Ok(fits)
}

/// Both passes of [`run_on_segments`], every kind but universal.
fn fit_passes(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    params: &Params,
) -> Result<PairFits, Error> {
    params.validate()?;
    let params = &params.with_floors_scaled(traj.floor_scale());
    for (segment, markers) in segments.iter().enumerate() {
        if let Some(&marker) = markers.iter().find(|&&m| m >= traj.markers()) {
            return Err(Error::MarkerOutOfRange {
                segment,
                marker,
                markers: traj.markers(),
            });
        }
    }
    // Every segment's poses from its own markers: both passes start from them.
    let own_poses = poses::all_segment_poses(traj, segments, poses::FitRules::of(params));
    let mut own = fit_all(traj, segments, params, own_poses.clone(), None);
    fit::weigh_costs_by_noise(&mut own.fits.pairs, params);
    if !params.tree_poses {
        return Ok(own.fits);
    }
    // Segments whose own markers fix their spin too loosely even when all are seen.
    let loose: Vec<bool> = own_poses
        .iter()
        .map(|p| {
            params.max_spin_deg > 0.0
                && poses::spin_error_deg(p).is_some_and(|d| d > params.max_spin_deg)
        })
        .collect();
    // Second pass along the tree the costs make: poses through the joints the topology
    // will most likely keep. Topo then reads this pass's costs, relative rotations and
    // kinds (`tree_from_second_pass`), or the first pass's for all three. The second
    // pass's kinds fit its centres and are the ones written: the first pass's kinds on
    // these fits measured worse (cargo xtask eval --presets hard: 8101-8124 1.95 → 1.98 %,
    // --markers 2:3 3.08 → 3.15 %).
    let tree = cheapest_tree(segments.len(), &own.fits);
    let off_tree = |(s, nb): (usize, &Option<usize>)| nb.is_some_and(|nb| !tree[s][nb]);
    // A two-marker segment with two tree neighbours to take centres from
    // (`Params::anchor_two_centres`).
    let two_joints = (0..segments.len()).any(|s| {
        params.anchor_two_centres
            && segments[s].len() == 2
            && tree[s].iter().filter(|&&t| t).count() >= 2
    });
    if !loose.contains(&true) && !own.anchored_to.iter().enumerate().any(off_tree) && !two_joints {
        // Every anchor is a tree neighbour already: a second pass would repeat the first.
        return Ok(own.fits);
    }
    // A segment posed through a joint is posed only where its neighbour is: a pair the
    // first pass could fit may have too few frames left. Topo would take its first-pass
    // cost and bonefit find no centre, so a later pass is all or nothing.
    let fitted = |p: &PairFit| {
        p.centre_in_a
            .iter()
            .chain(&p.centre_in_b)
            .all(|x| x.is_finite())
    };
    let keeps_every_fit = |fits: &PairFits| {
        fits.pairs
            .iter()
            .zip(&own.fits.pairs)
            .all(|(x, first)| !fitted(first) || fitted(x))
    };
    let mut along = fit_all(
        traj,
        segments,
        params,
        own_poses.clone(),
        Some((&tree, &loose)),
    )
    .fits;
    if !keeps_every_fit(&along) {
        return Ok(own.fits);
    }
    // A third pass where the second posed a segment through a tree neighbour whose joint
    // holds its markers clearly worse than another neighbour's (`Params::anchor_swap_ratio`).
    if let Some(swapped) = tree_with_better_anchors(&tree, &along.pairs, params.anchor_swap_ratio) {
        let third = fit_all(traj, segments, params, own_poses, Some((&swapped, &loose))).fits;
        if keeps_every_fit(&third) {
            along = third;
        }
    }
    if params.tree_from_second_pass {
        // The tree from the better poses: a loose segment posed through its tentative
        // neighbour's joint no longer makes all its pairs dear.
        fit::weigh_costs_by_noise(&mut along.pairs, params);
        return Ok(along);
    }
    for (fit, first) in along.pairs.iter_mut().zip(&own.fits.pairs) {
        if fit.kind != first.kind {
            fit.first_pass_kind = Some(first.kind);
        }
        fit.misfit_over_noise = first.misfit_over_noise;
        let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
        if !same(fit.cost, first.cost) || !same(fit.rotation_rms_deg, first.rotation_rms_deg) {
            fit.cost = first.cost;
            fit.rotation_rms_deg = first.rotation_rms_deg;
            fit.evidence.push_str(&format!(
                "; cost and RMS relative rotation ({:.1}°) from the first pass (the segments' \
                 own poses)",
                first.rotation_rms_deg
            ));
        }
    }
    Ok(along)
}

/// `tree` with each anchor the second pass took clearly worse than the next best
/// (`PairFit::next_best_anchor` below `ratio`) swapped for that neighbour's edge, the most
/// decisive first, where the swap keeps a tree; `None` when nothing is swapped.
fn tree_with_better_anchors(
    tree: &[Vec<bool>],
    pairs: &[PairFit],
    ratio: f64,
) -> Option<Vec<Vec<bool>>> {
    let mut swaps: Vec<(f64, usize, usize, usize)> = pairs
        .iter()
        .filter_map(|p| {
            let s = p.posed_through?;
            let (better, r) = p.next_best_anchor?;
            let anchor = if p.a == s { p.b } else { p.a };
            (r < ratio).then_some((r, s, anchor, better))
        })
        .collect();
    swaps.sort_by(|x, y| {
        x.0.total_cmp(&y.0)
            .then((x.1, x.2, x.3).cmp(&(y.1, y.2, y.3)))
    });
    let mut tree = tree.to_vec();
    let mut swapped = false;
    for (_, s, anchor, better) in swaps {
        if !tree[s][anchor] || tree[s][better] {
            continue;
        }
        tree[s][anchor] = false;
        tree[anchor][s] = false;
        // Without the anchor's edge, `better` must lie across the cut it made.
        if reachable(&tree, s)[better] {
            tree[s][anchor] = true;
            tree[anchor][s] = true;
            continue;
        }
        tree[s][better] = true;
        tree[better][s] = true;
        swapped = true;
    }
    swapped.then_some(tree)
}

/// Which segments `tree` (symmetric adjacency) connects to `from`.
fn reachable(tree: &[Vec<bool>], from: usize) -> Vec<bool> {
    let mut seen = vec![false; tree.len()];
    seen[from] = true;
    let mut stack = vec![from];
    while let Some(u) = stack.pop() {
        for (v, &edge) in tree[u].iter().enumerate() {
            if edge && !seen[v] {
                seen[v] = true;
                stack.push(v);
            }
        }
    }
    seen
}

/// Pair fits, and the anchors that decide whether a second pass along the tree changes
/// any pose.
struct FitPass {
    fits: PairFits,
    /// Per segment, the neighbour it is posed through (anchored segments only).
    anchored_to: Vec<Option<usize>>,
}

/// The minimum spanning tree of the pair costs (Kruskal; finite costs only, ties in pair
/// order, rigid pairs first as topo's defaults take them), as a symmetric adjacency matrix.
fn cheapest_tree(n: usize, fits: &PairFits) -> Vec<Vec<bool>> {
    let mut order: Vec<&PairFit> = fits.pairs.iter().filter(|p| p.cost.is_finite()).collect();
    order.sort_by(|x, y| {
        let rigid = |p: &PairFit| u8::from(p.kind != JointKind::Rigid);
        rigid(x).cmp(&rigid(y)).then(x.cost.total_cmp(&y.cost))
    });
    let mut root: Vec<usize> = (0..n).collect();
    fn find(root: &mut [usize], mut x: usize) -> usize {
        while root[x] != x {
            root[x] = root[root[x]];
            x = root[x];
        }
        x
    }
    let mut tree = vec![vec![false; n]; n];
    for p in order {
        let (ra, rb) = (find(&mut root, p.a), find(&mut root, p.b));
        if ra != rb {
            root[ra] = rb;
            tree[p.a][p.b] = true;
            tree[p.b][p.a] = true;
        }
    }
    tree
}

/// Anchors and every pair's fit, from the segments' `own` poses. With `along` (a second
/// pass: the tree and which segments are loose), loose segments are posed through a
/// neighbour instead (their own poses kept where none qualifies), and anchors are sought
/// among tree neighbours first.
fn fit_all(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    params: &Params,
    own: Vec<SegmentPoses>,
    along: Option<(&[Vec<bool>], &[bool])>,
) -> FitPass {
    let mut poses = own;
    let tree = along.map(|(tree, _)| tree);
    let loose = along.map(|(_, loose)| loose);
    // A loose segment's own poses, kept aside in case no neighbour can pose it.
    let mut set_aside: Vec<Option<SegmentPoses>> = vec![None; poses.len()];
    for (s, p) in poses.iter_mut().enumerate() {
        if loose.is_some_and(|l| l[s]) {
            set_aside[s] = Some(p.clone());
            p.forget();
        }
    }
    // First pass only: the lines of segments whose own markers fix their spin too loosely
    // (the second pass poses them through a joint instead).
    let correct_spin = along.is_none() && params.spin_corrected_cost && params.max_spin_deg > 0.0;
    let lines: Vec<Option<score::MarkerLine>> = poses
        .iter()
        .map(|p| {
            if !correct_spin {
                return None;
            }
            let spin = poses::spin_error_deg(p)?.min(SPIN_UNFIXED_DEG);
            (spin > params.max_spin_deg)
                .then(|| poses::marker_line(p, spin.to_radians()))
                .flatten()
        })
        .collect();
    let anchors = anchor::anchor_segments(traj, segments, &mut poses, params, tree, loose);
    for (s, own) in set_aside.into_iter().enumerate() {
        if let Some(own) = own
            && anchors[s].as_ref().is_none_or(|a| !a.posed_by_anchor)
        {
            poses[s] = own;
        }
    }
    let anchored_to = anchors
        .iter()
        .map(|a| {
            a.as_ref()
                .filter(|a| a.posed_by_anchor)
                .map(|a| a.neighbour)
        })
        .collect();
    let tracks: Vec<Vec<Option<poses::Pose>>> = poses.par_iter().map(poses::pose_track).collect();
    let scatters: Vec<poses::PoseScatter> = poses.par_iter().map(poses::PoseScatter::of).collect();
    let views: Vec<fit::SegmentView<'_>> = segments
        .iter()
        .zip(&poses)
        .zip(&tracks)
        .zip(&scatters)
        .zip(&anchors)
        .zip(&lines)
        .map(
            |(((((markers, poses), track), scatter), anchor), line)| fit::SegmentView {
                markers,
                line: *line,
                poses,
                track,
                scatter,
                pivot: anchor
                    .as_ref()
                    .filter(|a| a.posed_by_anchor && markers.len() >= 2)
                    .and_then(|a| {
                        let n_track = &tracks[a.neighbour];
                        anchor::centre_in_segment(track, n_track, a.fit.centre, params.min_frames)
                            .map(|c| (c, a.fit.rms_mm))
                    }),
                filled_through: anchor.as_ref().and_then(|a| {
                    if a.posed_by_anchor {
                        a.secondary.as_ref().map(|(nb, f)| (*nb, f.as_slice()))
                    } else {
                        Some((a.neighbour, a.filled.as_slice()))
                    }
                }),
            },
        )
        .collect();
    let pairs: Vec<(usize, usize)> = (0..views.len())
        .flat_map(|a| ((a + 1)..views.len()).map(move |b| (a, b)))
        .collect();
    let mut fits: Vec<PairFit> = pairs
        .par_iter()
        .map(|&(a, b)| fit::fit_pair(traj, a, b, &views[a], &views[b], params))
        .collect();
    // A segment posed through a joint has no twist of its own about its marker line: its
    // joints (the anchor's and any other) are centred by its markers' distances alone.
    if params.anchor_centres_by_distance {
        fits.par_iter_mut().for_each(|fit| {
            centre_by_distances(traj, fit, segments, &anchors, (&scatters, &tracks), params);
        });
    }
    // Say which joints carry a segment's poses: their costs are low partly by construction.
    for (s, anchor) in anchors.iter().enumerate() {
        let Some(anchor) = anchor else { continue };
        let (a, b) = (s.min(anchor.neighbour), s.max(anchor.neighbour));
        if let Some(fit) = fits.iter_mut().find(|p| p.a == a && p.b == b) {
            let how = if anchor.seed {
                "posed first, from the two segments' markers' common centre (no segment had a \
                 pose of its own),"
            } else if anchor.along_line {
                "posed along its two markers' line, which runs through this joint's centre \
                 (its twist about that line is the other segment's),"
            } else if anchor.posed_by_anchor {
                "posed through this joint"
            } else {
                "2-marker frames filled through this joint"
            };
            fit.seeded |= anchor.seed;
            if anchor.posed_by_anchor {
                fit.posed_through = Some(s);
            }
            let next_best = match anchor.next_best {
                Some((x, rms)) if anchor.posed_by_anchor && !anchor.seed => {
                    let ratio = rms / anchor.fit.rms_mm;
                    fit.next_best_anchor = Some((x, ratio));
                    format!(
                        "; next best, segment {x}'s: radial residual {rms:.2} mm, {ratio:.2} \
                         times this"
                    )
                }
                _ => String::new(),
            };
            fit.evidence.push_str(&format!(
                "; segment {s} {how} in {} frames (common centre in segment {}: {}{next_best})",
                anchor.frames_posed,
                anchor.neighbour,
                anchor.fit.describe()
            ));
        }
        if let Some((nb, second)) = &anchor.second_centre {
            let (a, b) = (s.min(*nb), s.max(*nb));
            if let Some(fit) = fits.iter_mut().find(|p| p.a == a && p.b == b) {
                fit.posed_through = Some(s);
                fit.evidence.push_str(&format!(
                    "; segment {s} posed through this joint too, with its anchor {}'s \
                     (common centre in segment {nb}: {})",
                    anchor.neighbour,
                    second.describe()
                ));
            }
        }
        if let Some((nb, filled)) = &anchor.secondary {
            let (a, b) = (s.min(*nb), s.max(*nb));
            let frames = filled.iter().filter(|&&x| x).count();
            if let Some(fit) = fits.iter_mut().find(|p| p.a == a && p.b == b) {
                fit.evidence.push_str(&format!(
                    "; segment {s}'s frames without its anchor {} filled through this joint \
                     in {frames} frames",
                    anchor.neighbour
                ));
            }
        }
    }
    FitPass {
        fits: PairFits {
            frames: traj.frames(),
            poses,
            pairs: fits,
        },
        anchored_to,
    }
}

/// A centre no farther than this (mm, mean nearest-marker distance) beyond the pose fit's
/// counts as just as near: the test separates slides along a free axis (tens of mm), not
/// ties.
const NEARER_TOLERANCE_MM: f64 = 1.0;

/// Re-centres `fit` by the marker distances of a segment of the pair posed through an
/// anchor (see [`distance_centre`]); where both are, the side whose markers keep their
/// distances best decides (a knee between a 2-marker thigh and shank).
///
/// Where that centre and the pose fit's disagree, the data leave a direction nearly free
/// (a hinge-like axis) and each fit settled it on its own bias. Joints lie inside the limbs
/// the markers sit on, so a centre that ends farther from every marker of the pair (mean
/// over frames of the nearest-marker distance) is sliding along that direction, not
/// finding the joint, and is refused.
fn centre_by_distances(
    traj: &Trajectories,
    fit: &mut PairFit,
    segments: &[Vec<usize>],
    anchors: &[Option<anchor::Anchor>],
    (scatters, tracks): (&[poses::PoseScatter], &[Vec<Option<poses::Pose>>]),
    params: &Params,
) {
    // An unidentifiable pair (no common frames) has no centre to move.
    if !fit.cost.is_finite() {
        return;
    }
    let best = [fit.a, fit.b]
        .into_iter()
        .filter_map(|s| {
            let anchor = anchors[s].as_ref().filter(|a| a.posed_by_anchor)?;
            let other = if fit.a == s { fit.b } else { fit.a };
            // The other segment posed through s: its frame carries s's centre by
            // construction, so s's markers keep their distances there trivially.
            let circular = anchors[other]
                .as_ref()
                .is_some_and(|o| o.posed_by_anchor && o.neighbour == s);
            if circular {
                return None;
            }
            distance_centre(traj, fit, s, &segments[s], anchor, tracks, params)
        })
        .min_by(|x, y| x.rms_mm.total_cmp(&y.rms_mm));
    let Some(c) = best else { return };
    let (ta, tb) = (&tracks[fit.a], &tracks[fit.b]);
    let posed = |s: usize| fit::PosedSegment::of(scatters, tracks, s);
    let Some(moved) = fit::recentre(fit, c.frame, c.centre, posed(fit.a), posed(fit.b)) else {
        return;
    };
    // Both measured on the positions they give, over the frames both are known.
    let before = fit::joint_positions(
        DVec3::from_array(fit.centre_in_a),
        DVec3::from_array(fit.centre_in_b),
        posed(fit.a),
        posed(fit.b),
    );
    let markers = || segments[fit.a].iter().chain(&segments[fit.b]).copied();
    let known = |p: &[f64; 3]| {
        let p = DVec3::from_array(*p);
        p.is_finite().then_some(p)
    };
    let both = |f: usize| known(&before[f]).zip(known(&moved.positions[f]));
    let now = nearest_marker_mm(traj, markers(), |f| both(f).map(|(old, _)| old));
    let then = nearest_marker_mm(traj, markers(), |f| both(f).map(|(_, new)| new));
    if then <= now + NEARER_TOLERANCE_MM {
        fit::apply_recentred(fit, moved, ta, tb, &c.note);
        if params.anchor_hinge_slides && fit.kind == JointKind::Hinge {
            // Every point of a hinge's axis keeps its distance to every marker turning
            // about it: the distances place the centre across the axis, not along it.
            fit.centre_from_distances = false;
            fit.evidence
                .push_str(", free to slide along the hinge axis");
        }
    } else {
        fit.evidence.push_str(&format!(
            "; {} not used: its centre is {then:.1} mm from the nearest marker on average, \
             the pose fit's {now:.1} mm",
            c.note
        ));
    }
}

/// Mean over frames of the distance (mm) from `centre(f)` to the nearest visible marker of
/// `markers`; +∞ when no frame has both.
fn nearest_marker_mm(
    traj: &Trajectories,
    markers: impl Iterator<Item = usize> + Clone,
    centre: impl Fn(usize) -> Option<DVec3>,
) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for f in 0..traj.frames() {
        let Some(c) = centre(f) else { continue };
        let nearest = markers
            .clone()
            .filter_map(|m| traj.get(f, m))
            .map(|p| DVec3::from_array(p).distance(c))
            .fold(f64::INFINITY, f64::min);
        if nearest.is_finite() {
            sum += nearest;
            count += 1;
        }
    }
    if count == 0 {
        f64::INFINITY
    } else {
        sum / count as f64
    }
}

/// A joint centre from a segment's markers' distances, in segment `frame`'s local frame.
struct DistanceCentre {
    frame: usize,
    centre: DVec3,
    /// RMS radial residual of the fit (mm).
    rms_mm: f64,
    /// Where the centre came from, for the evidence.
    note: String,
}

/// The centre of `fit`, a pair of segment `s` (posed through `anchor`), by `s`'s markers'
/// distances: for the anchor's own joint the anchor's common centre, for any other the
/// common centre of `s`'s markers in the other segment's frame. `None` where the distances
/// leave a direction free (a hinge axis), do not pin the centre (an anchor taken for its
/// steadier distances, `Params::anchor_steadier_ratio`) or the pair does not move: the
/// pose fit stays.
fn distance_centre(
    traj: &Trajectories,
    fit: &PairFit,
    s: usize,
    markers: &[usize],
    anchor: &anchor::Anchor,
    tracks: &[Vec<Option<poses::Pose>>],
    params: &Params,
) -> Option<DistanceCentre> {
    let other = if fit.a == s { fit.b } else { fit.a };
    if other == anchor.neighbour {
        return (!anchor.fit.hinge() && anchor.fit.identified).then(|| DistanceCentre {
            frame: other,
            centre: anchor.fit.centre,
            rms_mm: anchor.fit.rms_mm,
            note: "the anchor's common centre".to_string(),
        });
    }
    if fit.kind == JointKind::Rigid {
        return None;
    }
    // The topology decides whether this pair is a joint, so the bar is lower than for
    // choosing an anchor: only a swing too small to curve the markers' paths is refused.
    let cf = anchor::centre_fit(
        traj,
        markers,
        &tracks[other],
        params,
        params.anchor_refit_min_excursion_deg,
    )
    .filter(|f| f.identified)?;
    (!cf.hinge()).then(|| DistanceCentre {
        frame: other,
        centre: cf.centre,
        rms_mm: cf.rms_mm,
        note: format!(
            "segment {s}'s markers' common centre in segment {other} ({})",
            cf.describe()
        ),
    })
}

#[cfg(test)]
mod testkit;
#[cfg(test)]
mod tests;
