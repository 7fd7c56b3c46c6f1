//! Poses for segments carried by fewer than three markers, through a joint with a posed
//! neighbour (the second paper's handling of two-marker segments, made greedy).
//!
//! A segment S without its own poses (1 or 2 markers, or collinear markers) is anchored to
//! the posed segment N whose frame sees S's markers move most like points at constant
//! distances from one common centre: in N's local frame every marker m of S satisfies
//! `|q − c|² = r_m²`, i.e. `|q|² = 2 c·q + k_m` with one `k_m` per marker, linear in `c`;
//! that algebraic fit starts a geometric one (Gauss–Newton on `|q − c| − r_m`), because the
//! algebraic fit shortens radii on short arcs. A hinge leaves the component of `c` along
//! its axis undetermined. The axis is the markers' least-spread direction — but not the
//! radial one: a ball joint swinging a limb through a modest arc (a hip in a walk) moves
//! the markers least along the limb, and sliding the centre there changes the bone length
//! (CMU 02_01 femurs were 24–28 % short that way). When sliding along the axis does not
//! raise the radial residual, `c` is put on the axis nearest the midpoint of N's origin and
//! S's markers (any point on a true axis is fixed in both segments, so the resulting pose
//! does not depend on where). The cost is the RMS of the radial residual (mm); pairs with
//! too few samples, too little angular excursion about `c` for their residual (no
//! identifiable joint) or too large a residual are not candidates, except that a neighbour
//! S keeps clearly steadier distances to than to every one that qualifies (with none yet,
//! than the anchor taken next anywhere) is one however little S turns about it
//! (`Params::anchor_steadier_ratio`). For a ball joint
//! (`Params::anchor_line_prior`) a two-marker S's line adds a first-order cue for the
//! centre's coordinate along the limb. Greedily, the cheapest (S, N) over all unposed S
//! and posed N is taken, S becomes posed, and the search repeats until no candidate is
//! left.
//!
//! S's pose at a frame: with ≥ 2 markers, Horn's method on S's visible markers plus the
//! centre as N carries it, against a reference shape {markers, centre} in S's local frame
//! (origin at S's markers' centroid; ≥ 3 non-collinear points needed, otherwise no pose).
//! With one marker no full pose exists: the twist about the centre→marker line cannot be
//! seen. We give it N's rotation composed with the minimal rotation (swing) carrying the
//! marker's mean direction from the centre (in N's frame) to its current direction, so the
//! twist relative to N is zero by convention; the local origin is the marker, the centre
//! sits at distance r along the reference direction, and the translation puts the centre
//! exactly where N carries it.
//!
//! When no posed neighbour is left for any unposed segment and two two-marker segments
//! are among them, the pair whose markers' common centre fits best starts again
//! (`seed.rs`): one of the two is posed from its markers plus that centre's track, and the
//! greedy search goes on from it. A marker set with two markers on every segment starts
//! this way; so does a group of such segments no posed segment reaches.
//!
//! A two-marker S posed from its markers and one centre turns about the line through its
//! markers as freely as the centre is near that line (a knee marker beside the knee). Along
//! the tree (second pass), its other joint's centre, its markers' common centre in that
//! neighbour's frame, is a fourth point of its pose when the two centres fit alike
//! (`Params::anchor_two_centres`); a two-marker S no single centre can pose (each in line
//! with its markers) is posed from the two best centres at once. Exactly in line, the
//! centre adds no spin to any frame; where a hinge square to the line swings it in one
//! plane, S's twist about the line is N's, so S takes swing-only poses along it through
//! N, as one marker does, when N holds its markers clearly steadier than any other posed
//! neighbour would (a robot link's two markers along its bone, which would otherwise be
//! posed through the next link's joint).
//!
//! Segments with their own poses (≥ 3 markers) get the same anchor search, and frames
//! where only 2 of their markers are visible are filled from those 2 plus the anchor's
//! centre (issue 5, item 4).

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::{DMat3, DQuat, DVec3};
use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::pairfits::SegmentPoses;
use crate::params::Params;
use crate::poses::{FitRules, Pose, Spread, fit_pairs, fit_shape, pose_track};
use crate::seed;
use crate::small::sym_eigen;

/// How a segment was tied to a neighbour.
#[derive(Clone, Debug)]
pub(crate) struct Anchor {
    /// The posed neighbour N.
    pub neighbour: usize,
    /// Whether S's poses come from this anchor (true) or only its gaps were filled (false).
    pub posed_by_anchor: bool,
    /// The common centre fit.
    pub fit: CentreFit,
    /// Frames filled or posed through the anchor.
    pub frames_posed: usize,
    /// Gap filling only (`posed_by_anchor` false): per frame, whether S's pose there was
    /// filled through N's centre (empty otherwise).
    pub filled: Vec<bool>,
    /// Posed by this anchor but missing where N has no pose: a second neighbour through
    /// whose joint those frames were filled, and per frame whether they were.
    pub secondary: Option<(usize, Vec<bool>)>,
    /// Posed first of all, from S's and N's markers' common centre (`seed.rs`), before N
    /// had a pose.
    pub seed: bool,
    /// A two-marker S posed from its markers and both its joints' centres: the second
    /// neighbour and the centre of S's markers in its frame.
    pub second_centre: Option<(usize, CentreFit)>,
    /// S's two markers lie in line with the centre: posed along that line, its twist about
    /// the line taken from N (see [`line_poses`]).
    pub along_line: bool,
    /// When the greedy search chose N: the other posed neighbour whose identified centre
    /// held S's markers best, and its radial residual (mm). How decisive the choice was:
    /// the chosen joint's pair is cheap by construction, the runner-up's is not.
    pub next_best: Option<(usize, f64)>,
}

impl Anchor {
    /// S posed through neighbour `neighbour`'s centre `fit` in `frames_posed` frames.
    fn posing(neighbour: usize, fit: CentreFit, frames_posed: usize) -> Self {
        Self {
            neighbour,
            posed_by_anchor: true,
            fit,
            frames_posed,
            filled: Vec::new(),
            secondary: None,
            seed: false,
            second_centre: None,
            along_line: false,
            next_best: None,
        }
    }
}

/// A common centre of S's markers in N's local frame.
#[derive(Clone, Debug)]
pub(crate) struct CentreFit {
    /// Centre in N's local frame (mm).
    pub centre: DVec3,
    /// RMS radial residual (mm) of the distances-only centre (before the line prior).
    pub rms_mm: f64,
    /// Largest over S's markers of the RMS angle of the centre→marker direction from its
    /// mean (degrees).
    pub excursion_deg: f64,
    /// Samples (marker × frame) used.
    pub samples: usize,
    /// The direction the distances left undetermined (a hinge axis, N-local unit vector),
    /// along which the centre was set by placement; `None` when they fixed every direction.
    pub axis: Option<DVec3>,
    /// Per marker of S (in S's marker order): mean radius (mm) and mean unit direction
    /// from the centre (N-local); NaN when the marker had too few samples.
    pub radii: Vec<(f64, DVec3)>,
    /// Whether S's markers turn enough about the centre to fix it: at least the
    /// excursion asked of [`centre_fit`], or less with a residual that pins it
    /// (`Params::anchor_exact_centre_mm`).
    pub identified: bool,
}

impl CentreFit {
    /// Whether one direction of the centre was undetermined (a hinge axis) and set by
    /// placement.
    pub fn hinge(&self) -> bool {
        self.axis.is_some()
    }

    /// One line for `PairFit::evidence`.
    pub fn describe(&self) -> String {
        format!(
            "radial residual {:.2} mm over {} samples, excursion {:.1}°{}",
            self.rms_mm,
            self.samples,
            self.excursion_deg,
            if self.hinge() {
                ", centre placed on the hinge axis"
            } else {
                ""
            }
        )
    }
}

/// Anchors every segment it can; replaces the poses of segments without their own and
/// fills 2-marker frames of the others. With `tree` (symmetric adjacency), a segment is
/// anchored to a tree neighbour while any qualifies, a `loose` one also to a neighbour off
/// the tree whose centre fits clearly better. Returns the anchor of every segment.
pub(crate) fn anchor_segments(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    poses: &mut [SegmentPoses],
    params: &Params,
    tree: Option<&[Vec<bool>]>,
    loose: Option<&[bool]>,
) -> Vec<Option<Anchor>> {
    let n = segments.len();
    let mut anchors: Vec<Option<Anchor>> = vec![None; n];
    if !params.anchor {
        return anchors;
    }
    let mut tracks: Vec<Vec<Option<Pose>>> = poses.iter().map(pose_track).collect();
    let posed_count = |t: &[Option<Pose>]| t.iter().filter(|p| p.is_some()).count();
    let own: Vec<bool> = tracks
        .iter()
        .map(|t| posed_count(t) >= params.min_frames)
        .collect();
    let mut posed = own.clone();
    // Fits are computed once per (S, N): N's poses never change after it is posed.
    let mut memo: Vec<Vec<Option<Option<CentreFit>>>> = vec![vec![None; n]; n];
    let mut failed = vec![vec![false; n]; n];
    // Off-tree neighbours are tried only once no tree neighbour is left to try.
    let on_tree = |s: usize, nb: usize| tree.is_none_or(|t| t[s][nb]);
    let mut tree_only = tree.is_some();
    // Pairs of two-marker segments a seed was tried on, and the seeds posed (segment, partner).
    let mut seed_refused = vec![vec![false; n]; n];
    let mut seeded: Vec<(usize, usize)> = Vec::new();
    let mut seed_memo = seed::SeedMemo::default();
    // Centre fits at the refit bar, for two-centre poses (`joint_centres`).
    let mut refit_memo: Vec<Vec<Option<Option<CentreFit>>>> = vec![vec![None; n]; n];
    loop {
        // A loose segment's tree edges came from poses whose spin its markers did not fix,
        // so its neighbours off the tree are weighed too (`Params::loose_off_tree_ratio`).
        let reopened = |s: usize| {
            tree_only && params.loose_off_tree_ratio > 0.0 && loose.is_some_and(|l| l[s])
        };
        let open =
            |s: usize, nb: usize| !failed[s][nb] && (!tree_only || on_tree(s, nb) || reopened(s));
        let wanted: Vec<(usize, usize)> = (0..n)
            .filter(|&s| !posed[s] && !segments[s].is_empty())
            .flat_map(|s| (0..n).map(move |nb| (s, nb)))
            .filter(|&(s, nb)| nb != s && posed[nb] && open(s, nb))
            .collect();
        fit_candidates(traj, segments, &tracks, params, &mut memo, &wanted);
        let mut best: Option<(f64, usize, usize)> = None;
        // The residual of the anchor the search would take next anywhere.
        let next_identified = (0..n)
            .filter(|&s| !posed[s] && !segments[s].is_empty())
            .flat_map(|s| (0..n).map(move |nb| (s, nb)))
            .filter(|&(s, nb)| nb != s && posed[nb] && open(s, nb))
            .filter_map(|(s, nb)| memo[s][nb].as_ref()?.as_ref())
            .filter(|f| f.identified)
            .map(|f| f.rms_mm)
            .fold(f64::INFINITY, f64::min);
        for s in 0..n {
            if posed[s] || segments[s].is_empty() {
                continue;
            }
            let fits = || {
                (0..n)
                    .filter(|&nb| nb != s && posed[nb] && open(s, nb))
                    .filter_map(|nb| Some((nb, memo[s][nb].as_ref()?.as_ref()?)))
            };
            // A neighbour S keeps clearly steadier distances to than to any whose centre
            // is identified is S's neighbour, however little S turns about it (a foot whose
            // markers sit near the ankle barely swing about it, and swing about the knee
            // with the whole leg); `Params::anchor_steadier_ratio`. With no such neighbour
            // yet, clearly steadier than the anchor taken next anywhere: a forearm turning
            // little about the elbow is posed before its hand can hang from the upper arm.
            let identified = fits()
                .filter(|(_, f)| f.identified)
                .map(|(_, f)| f.rms_mm)
                .fold(f64::INFINITY, f64::min);
            let identified = if identified.is_finite() {
                identified
            } else {
                next_identified
            };
            let qualifies = |fit: &CentreFit| {
                fit.identified
                    || (identified.is_finite()
                        && fit.rms_mm < params.anchor_steadier_ratio * identified)
            };
            // Off the tree only clearly better than every tree neighbour that qualifies.
            let on_tree_best = fits()
                .filter(|&(nb, f)| on_tree(s, nb) && qualifies(f))
                .map(|(_, f)| f.rms_mm)
                .fold(f64::INFINITY, f64::min);
            for (nb, fit) in fits() {
                let allowed = !tree_only
                    || on_tree(s, nb)
                    || fit.rms_mm < params.loose_off_tree_ratio * on_tree_best;
                if qualifies(fit) && allowed && best.is_none_or(|(c, _, _)| fit.rms_mm < c) {
                    best = Some((fit.rms_mm, s, nb));
                }
            }
        }
        let Some((_, s, nb)) = best else {
            if tree_only {
                tree_only = false;
                continue;
            }
            // A two-marker segment no single joint could pose (its markers nearly in line
            // with each centre) may be posed from two neighbours' centres at once: tree
            // neighbours along a tree, else the two whose centres fit best, as anchoring
            // chooses one.
            if params.anchor_two_centres {
                let both = (0..n)
                    .filter(|&s| !posed[s] && segments[s].len() == 2)
                    .find_map(|s| {
                        let near = (0..n)
                            .filter(|&nb| nb != s && posed[nb] && on_tree(s, nb))
                            .filter(|&nb| !posed_through(&anchors, s, nb))
                            .collect();
                        let row = &mut refit_memo[s];
                        let mut found =
                            joint_centres(traj, &segments[s], near, &tracks, params, row);
                        let second = found.get(1)?.clone();
                        let first = found.swap_remove(0);
                        let new = two_centre_poses(
                            traj,
                            s,
                            &segments[s],
                            &first,
                            &second,
                            &tracks,
                            params,
                        );
                        let count = posed_count(&pose_track(&new));
                        (count >= params.min_frames).then_some((s, first, second, new, count))
                    });
                if let Some((s, (nb, fit), second, new, count)) = both {
                    tracks[s] = pose_track(&new);
                    poses[s] = new;
                    posed[s] = true;
                    anchors[s] = Some(Anchor {
                        second_centre: Some(second),
                        ..Anchor::posing(nb, fit, count)
                    });
                    continue;
                }
            }
            // Nothing posed is left to anchor to: start from two two-marker segments'
            // common centre, if any pair has one (`seed.rs`).
            let Some((s, partner, common)) = params
                .anchor_seed
                .then(|| {
                    seed::best_seed(
                        traj,
                        segments,
                        &posed,
                        &seed_refused,
                        params,
                        &mut seed_memo,
                    )
                })
                .flatten()
            else {
                break;
            };
            seed_refused[s][partner] = true;
            seed_refused[partner][s] = true;
            // The centre's track as a neighbour's pose that carries the point 0.
            let centre_track: Vec<Option<Pose>> = common
                .centre
                .iter()
                .map(|c| {
                    c.map(|trans| Pose {
                        rot: DMat3::IDENTITY,
                        trans,
                    })
                })
                .collect();
            let fit = CentreFit {
                centre: DVec3::ZERO,
                rms_mm: common.rms_mm,
                excursion_deg: common.excursion_deg,
                samples: 4 * common.centre.iter().flatten().count(),
                axis: None,
                radii: Vec::new(),
                identified: true,
            };
            let new = anchored_poses(
                traj,
                s,
                &segments[s],
                &poses[partner],
                &centre_track,
                &fit,
                params,
            );
            let track = pose_track(&new);
            if posed_count(&track) < params.min_frames {
                continue;
            }
            poses[s] = new;
            tracks[s] = track;
            posed[s] = true;
            seeded.push((s, partner));
            // Anchoring goes on from the seed, along the tree first again.
            tree_only = tree.is_some();
            continue;
        };
        let Some(Some(fit)) = memo[s][nb].clone() else {
            break;
        };
        let mut new = anchored_poses(traj, s, &segments[s], &poses[nb], &tracks[nb], &fit, params);
        let mut track = pose_track(&new);
        let mut count = posed_count(&track);
        let mut along_line = false;
        // Two markers in line with N's centre leave no frame a spin, so the fit refuses
        // them all. Where the joint swings their line in one plane (a hinge square to it:
        // `swing_plane_ratio` under `Params::hinge_ratio`) the line's twist is N's, and
        // where N also holds them clearly steadier than any other posed neighbour
        // (`Params::anchor_steadier_ratio`) they are posed along the line as one marker
        // is, not through a worse neighbour's joint (a robot link's markers along its bone).
        // Only about a centre they visibly swing about: one taken for steadier distances
        // alone can lie far out along the line (hexapod-hard-s30028 at 2:3, 2.8°).
        if count < params.min_frames
            && segments[s].len() == 2
            && fit.excursion_deg >= params.anchor_min_excursion_deg
        {
            let other = (0..n)
                .filter(|&x| x != s && x != nb && posed[x] && open(s, x))
                .filter_map(|x| memo[s][x].as_ref()?.as_ref())
                .filter(|f| f.identified)
                .map(|f| f.rms_mm)
                .fold(f64::INFINITY, f64::min);
            if fit.rms_mm < params.anchor_steadier_ratio * other {
                let line = line_poses(traj, s, &segments[s], &poses[nb], &tracks[nb], &fit);
                let line_track = pose_track(&line);
                let line_count = posed_count(&line_track);
                if line_count >= params.min_frames
                    && swing_plane_ratio(&line, &poses[nb]) < params.hinge_ratio
                {
                    (new, track, count, along_line) = (line, line_track, line_count, true);
                }
            }
        }
        if count < params.min_frames {
            // Too few frames with both markers and the neighbour: try the next candidate.
            failed[s][nb] = true;
            continue;
        }
        // Weighed against every posed neighbour, on the tree or off it, as the first pass
        // weighs them (the tree pass fits only tree neighbours until none is left to try).
        // Fits not in the memo are not stored: the second-neighbour gap filling below reads
        // the memo after the first gap fills have refreshed the neighbours' tracks, and
        // must fit its candidates on those (storing them here changed 447 of 700 trials).
        let others: Vec<usize> = (0..n).filter(|&x| x != s && x != nb && posed[x]).collect();
        let next_best = others
            .par_iter()
            .filter_map(|&x| {
                let identified = |f: &CentreFit| f.identified.then_some((x, f.rms_mm));
                match &memo[s][x] {
                    Some(fit) => fit.as_ref().and_then(identified),
                    None => centre_fit(
                        traj,
                        &segments[s],
                        &tracks[x],
                        params,
                        params.anchor_min_excursion_deg,
                    )
                    .as_ref()
                    .and_then(identified),
                }
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        poses[s] = new;
        tracks[s] = track;
        posed[s] = true;
        let mut anchor = Anchor {
            along_line,
            next_best,
            ..Anchor::posing(nb, fit, count)
        };
        // Along the tree, a two-marker segment's other joint gives its pose a fourth point.
        let along = || {
            (0..n)
                .filter(|&x| x != s && x != nb && posed[x] && on_tree(s, x))
                .filter(|&x| !posed_through(&anchors, s, x))
                .collect()
        };
        if tree.is_some()
            && params.anchor_two_centres
            && segments[s].len() == 2
            && let Some(second) = joint_centres(
                traj,
                &segments[s],
                along(),
                &tracks,
                params,
                &mut refit_memo[s],
            )
            .into_iter()
            .next()
            && agree(&anchor.fit, &second.1, params)
        {
            let first = (nb, anchor.fit.clone());
            let new = two_centre_poses(traj, s, &segments[s], &first, &second, &tracks, params);
            let track = pose_track(&new);
            if posed_count(&track) >= count {
                anchor.frames_posed = posed_count(&track);
                anchor.second_centre = Some(second);
                // Two centres fix the twist the line left to N.
                anchor.along_line = false;
                poses[s] = new;
                tracks[s] = track;
            }
        }
        anchors[s] = Some(anchor);
    }
    // A seed is posed through its partner's joint: once the partner is posed, that joint's
    // common centre in the partner's frame is its anchor, as for any anchored segment.
    for (s, partner) in seeded {
        if !posed[partner] {
            continue;
        }
        let wanted = [(s, partner)];
        fit_candidates(traj, segments, &tracks, params, &mut memo, &wanted);
        if let Some(Some(fit)) = memo[s][partner]
            .clone()
            .filter(|f| f.as_ref().is_some_and(|f| f.identified))
        {
            anchors[s] = Some(Anchor {
                seed: true,
                ..Anchor::posing(partner, fit, posed_count(&tracks[s]))
            });
        }
    }
    // Fills S's frames without a pose where 2 of its markers are visible through the
    // posed neighbour (not `skip`, not anchored through S) whose centre fits best; returns
    // that neighbour, its fit and the frames filled, and refreshes S's track.
    let fill = |s: usize,
                skip: Option<usize>,
                poses: &mut [SegmentPoses],
                tracks: &mut [Vec<Option<Pose>>],
                anchors: &[Option<Anchor>],
                memo: &mut [Vec<Option<Option<CentreFit>>>]| {
        let gappy = (0..traj.frames()).any(|f| {
            tracks[s][f].is_none()
                && segments[s]
                    .iter()
                    .filter(|&&m| traj.get(f, m).is_some())
                    .count()
                    >= 2
        });
        if !gappy {
            return None;
        }
        let candidates: Vec<usize> = (0..n)
            .filter(|&nb| {
                let loops_back = anchors[nb].as_ref().is_some_and(|a| a.neighbour == s);
                nb != s && Some(nb) != skip && posed[nb] && !loops_back
            })
            .collect();
        // Along a tree (second pass), through a tree neighbour's joint while one fits:
        // the joint the gap frames will be read through, and a few fits instead of one
        // per posed segment.
        let mut best = None;
        for tree_round in [true, false] {
            let round: Vec<usize> = candidates
                .iter()
                .copied()
                .filter(|&nb| !tree_round || on_tree(s, nb))
                .collect();
            let wanted: Vec<(usize, usize)> = round.iter().map(|&nb| (s, nb)).collect();
            fit_candidates(traj, segments, tracks, params, memo, &wanted);
            best = round
                .into_iter()
                .filter_map(|nb| {
                    let f = memo[s][nb].as_ref()?.as_ref()?;
                    f.identified.then_some((f.rms_mm, nb))
                })
                .min_by(|x, y| x.0.total_cmp(&y.0));
            if best.is_some() {
                break;
            }
        }
        let (_, nb) = best?;
        let fit = memo[s][nb].take().flatten()?;
        let filled = fill_gaps(
            traj,
            &segments[s],
            &mut poses[s],
            &tracks[s],
            &tracks[nb],
            &fit,
            params,
        );
        if !filled.iter().any(|&x| x) {
            return None;
        }
        tracks[s] = pose_track(&poses[s]);
        Some((nb, fit, filled))
    };
    // Gap filling for segments posed by their own markers.
    for s in 0..n {
        if !own[s] || segments[s].len() < 3 {
            continue;
        }
        if let Some((nb, fit, filled)) = fill(s, None, poses, &mut tracks, &anchors, &mut memo) {
            anchors[s] = Some(Anchor {
                posed_by_anchor: false,
                frames_posed: filled.iter().filter(|&&x| x).count(),
                filled,
                ..Anchor::posing(nb, fit, 0)
            });
        }
    }
    // Segments posed through a neighbour lack poses wherever that neighbour has none;
    // where both markers are visible, a second neighbour's joint fills them (its centre
    // placed in S's frame from the frames both are posed, as for the gaps above).
    for s in 0..n {
        let Some(first) = anchors[s]
            .as_ref()
            .filter(|a| a.posed_by_anchor)
            .map(|a| a.neighbour)
        else {
            continue;
        };
        if segments[s].len() != 2 {
            continue;
        }
        if let Some((nb, _, filled)) = fill(s, Some(first), poses, &mut tracks, &anchors, &mut memo)
            && let Some(a) = anchors[s].as_mut()
        {
            a.secondary = Some((nb, filled));
        }
    }
    anchors
}

/// The centres of two-marker segment S's `markers` in the frames of the posed
/// `neighbours`, best first (RMS radial residual), each qualifying at
/// `Params::anchor_refit_min_excursion_deg`: a second centre only adds a point to a pose,
/// so the bar is the refit's, not anchoring's. `memo` is S's row of fits already made at
/// that bar (a posed neighbour's poses never change).
///
/// Why: a two-marker segment posed from its markers and one centre turns about the line
/// through them as freely as that centre is near it, and a knee marker 14 mm from the knee
/// centre leaves the shank free to spin (BTK Gait.trc: 178° of relative rotation at the
/// knee, the ankle thrown 190 mm off the malleoli). Its other joint's centre, here the
/// ankle's in the foot's frame, needs no shank pose at all.
fn joint_centres(
    traj: &Trajectories,
    markers: &[usize],
    neighbours: Vec<usize>,
    tracks: &[Vec<Option<Pose>>],
    params: &Params,
    memo: &mut [Option<Option<CentreFit>>],
) -> Vec<(usize, CentreFit)> {
    let missing: Vec<usize> = neighbours
        .iter()
        .copied()
        .filter(|&nb| memo[nb].is_none())
        .collect();
    let fitted: Vec<Option<CentreFit>> = missing
        .par_iter()
        .map(|&nb| {
            let bar = params.anchor_refit_min_excursion_deg;
            let mut fit =
                centre_fit(traj, markers, &tracks[nb], params, bar).filter(|f| f.identified)?;
            // On a hinge axis the centre's place is a convention; as a point of S's pose
            // it is taken where the axis passes nearest S's markers (a limb's bone is
            // across its hinge's axis), which is where a ball joint turning mostly about
            // one axis has its centre.
            if let Some(axis) = fit.axis {
                let ends: Vec<DVec3> = fit
                    .radii
                    .iter()
                    .filter(|(r, u)| r.is_finite() && u.is_finite())
                    .map(|(r, u)| fit.centre + *r * *u)
                    .collect();
                if !ends.is_empty() {
                    let mean = ends.iter().sum::<DVec3>() / ends.len() as f64;
                    fit.centre += axis * axis.dot(mean - fit.centre);
                }
            }
            Some(fit)
        })
        .collect();
    for (nb, fit) in missing.into_iter().zip(fitted) {
        memo[nb] = Some(fit);
    }
    let mut found: Vec<(usize, CentreFit)> = neighbours
        .into_iter()
        .filter_map(|nb| memo[nb].clone().flatten().map(|fit| (nb, fit)))
        .collect();
    found.sort_by(|x, y| x.1.rms_mm.total_cmp(&y.1.rms_mm).then(x.0.cmp(&y.0)));
    found
}

/// Whether `nb`'s poses come, through a chain of anchors, from `s`'s.
fn posed_through(anchors: &[Option<Anchor>], s: usize, nb: usize) -> bool {
    let mut at = nb;
    for _ in 0..anchors.len() {
        match anchors[at].as_ref().filter(|a| a.posed_by_anchor) {
            Some(a) if a.neighbour == s => return true,
            Some(a) => at = a.neighbour,
            None => return false,
        }
    }
    true
}

/// Whether a second centre may join an anchor's in a pose: the anchor's centre keeps S's
/// markers' distances no more than [`TWO_CENTRE_AGREEMENT`] times as loosely as the
/// second's (plus `Params::min_spread_mm`, the noise floor). An anchor taken because a
/// better neighbour's centre lay in line with S's markers (random-clean-s5001 at two
/// markers per segment: 15.3 mm against 0.0 mm) would drag the second centre's pose with it.
fn agree(anchor: &CentreFit, second: &CentreFit, params: &Params) -> bool {
    anchor.rms_mm <= TWO_CENTRE_AGREEMENT * second.rms_mm + params.min_spread_mm
}

/// See [`agree`]: the real captures' pairs of centres are within 2.1 × of each other.
const TWO_CENTRE_AGREEMENT: f64 = 3.0;

/// Poses of two-marker segment `id` from its markers and two neighbours' centres (each
/// neighbour and the centre in its frame), carried by the neighbours' poses.
fn two_centre_poses(
    traj: &Trajectories,
    id: usize,
    markers: &[usize],
    first: &(usize, CentreFit),
    second: &(usize, CentreFit),
    tracks: &[Vec<Option<Pose>>],
    params: &Params,
) -> SegmentPoses {
    let (t1, c1) = (&tracks[first.0], first.1.centre);
    let (t2, c2) = (&tracks[second.0], second.1.centre);
    let shape = fit_shape(
        traj.frames(),
        markers.len() + 2,
        markers.len(),
        |f, k| match markers.get(k) {
            Some(&m) => traj.get(f, m).map(DVec3::from_array),
            None if k == markers.len() => t1[f].as_ref().map(|p| p.apply(c1)),
            None => t2[f].as_ref().map(|p| p.apply(c2)),
        },
        FitRules {
            // The centres are no markers (see `anchored_poses`).
            max_spin_deg: 0.0,
            ..FitRules::of(params)
        },
    );
    shape.into_poses(id, markers.len())
}

/// Fits, in parallel (each is independent), the centre of every `(S, N)` in `wanted` not
/// yet in `memo`, and keeps them there: N's poses never change once it is posed.
fn fit_candidates(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    tracks: &[Vec<Option<Pose>>],
    params: &Params,
    memo: &mut [Vec<Option<Option<CentreFit>>>],
    wanted: &[(usize, usize)],
) {
    let missing: Vec<(usize, usize)> = wanted
        .iter()
        .copied()
        .filter(|&(s, nb)| memo[s][nb].is_none())
        .collect();
    let fitted: Vec<Option<CentreFit>> = missing
        .par_iter()
        .map(|&(s, nb)| {
            centre_fit(
                traj,
                &segments[s],
                &tracks[nb],
                params,
                params.anchor_min_excursion_deg,
            )
        })
        .collect();
    for ((s, nb), fit) in missing.into_iter().zip(fitted) {
        memo[s][nb] = Some(fit);
    }
}

/// Common centre of `markers` (S's) in the frame of a neighbour with poses `track`;
/// `None` when the residual exceeds `Params::anchor_max_rms_mm`; `identified` when the
/// markers turn at least `min_excursion_deg` RMS about it, or less but with a residual
/// that pins the centre within `Params::anchor_exact_centre_mm`.
pub(crate) fn centre_fit(
    traj: &Trajectories,
    markers: &[usize],
    track: &[Option<Pose>],
    params: &Params,
    min_excursion_deg: f64,
) -> Option<CentreFit> {
    // Samples of each marker in N's frame.
    let clouds: Vec<Vec<DVec3>> = markers
        .iter()
        .map(|&m| {
            track
                .iter()
                .enumerate()
                .filter_map(|(f, pose)| {
                    let p = traj.get(f, m)?;
                    Some(pose.as_ref()?.inverse_apply(DVec3::from_array(p)))
                })
                .collect()
        })
        .collect();
    let used: Vec<bool> = clouds
        .iter()
        .map(|c| c.len() >= params.min_frames)
        .collect();
    let samples: usize = clouds
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(c, _)| c.len())
        .sum();
    if samples == 0 {
        return None;
    }
    // Work relative to the samples' mean so |q|² does not cancel catastrophically.
    let origin = clouds
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .flat_map(|(c, _)| c.iter())
        .sum::<DVec3>()
        / samples as f64;
    let mut a = [[0.0f64; 3]; 3];
    let mut b = DVec3::ZERO;
    let mut means = vec![DVec3::ZERO; clouds.len()];
    for (k, cloud) in clouds.iter().enumerate() {
        if !used[k] {
            continue;
        }
        let len = cloud.len() as f64;
        let mean = cloud.iter().map(|q| *q - origin).sum::<DVec3>() / len;
        let sq_mean = cloud
            .iter()
            .map(|q| (*q - origin).length_squared())
            .sum::<f64>()
            / len;
        means[k] = mean + origin;
        for q in cloud {
            let d = *q - origin - mean;
            let y = (*q - origin).length_squared() - sq_mean;
            let d3 = d.to_array();
            for i in 0..3 {
                for j in 0..3 {
                    a[i][j] += d3[i] * d3[j];
                }
            }
            b += d * (0.5 * y);
        }
    }
    let (values, vectors) = sym_eigen(a);
    if values[0].is_nan() || values[0] <= 0.0 {
        return None;
    }
    // Placement target for an undetermined direction: midway between N's origin and S's
    // markers' mean position in N's frame.
    let markers_mean = means
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(m, _)| *m)
        .sum::<DVec3>()
        / used.iter().filter(|u| **u).count() as f64;
    let target = 0.5 * markers_mean;
    let mut full = origin;
    for k in 0..3 {
        let v = DVec3::from_array(vectors[k]);
        if values[k] > 1e-12 * values[0] {
            full += v * (v.dot(b) / values[k]);
        } else {
            full += v * v.dot(target - origin);
        }
    }
    // The algebraic fit shortens radii on short arcs; the geometric one is the estimate.
    let sphere = geometric_centre(&clouds, &used, full, &[], None);
    let (rms_sphere, _) = radial(&clouds, &used, sphere);
    // Along the limb (centre → markers) distances fix the centre only to second order in
    // the swing angle (an arc's curvature): with noise that coordinate drifts (on a real
    // walk, hips 60 mm too far from the knee). With two markers, the point nearest all
    // their lines fixes it to first order (and ignores markers sliding along the limb); it
    // is combined with the distances as a prior whose variance is its own noise plus a
    // bound on its bias when the centre is off the line.
    let line = params
        .anchor_line_prior
        .then(|| MarkerLine::new(traj, markers, track))
        .flatten();
    let noise = rms_sphere.max(1e-3);
    // Skin artefact is smooth, so neighbouring frames' residuals are not independent
    // evidence: the distances' weight is their effective sample count.
    let effective = effective_fraction(&clouds, &used, sphere);
    // `across`: a candidate hinge axis. Along it a near-hinge leaves the centre free, and
    // the lines' meeting point there (the waist of the surface they sweep) can lie far
    // from the joint, so the prior only pins the coordinate across it.
    let prior = |across: Option<DVec3>| {
        let line = line.as_ref()?;
        let mut dir = line.dir;
        if let Some(axis) = across {
            dir = (dir - axis * axis.dot(dir)).try_normalize()?;
        }
        let bias = line.bias_bound();
        let variance = bias * bias
            + line
                .foot_var
                .max(noise * noise / (line.turn_var * line.count() * effective));
        Some(Prior {
            dir,
            value: dir.dot(line.foot),
            weight: noise * noise / (variance * effective),
        })
    };
    // On (nearly) noise-free data a hinge leaves the distances exactly flat along its axis,
    // and the sphere fit settles anywhere on it, by rounding: far along it, the direction
    // to the markers is the axis itself and would be refused as radial below. The fit's
    // own curvature names that axis whatever the centre's place on it.
    let radial_dir = (markers_mean - sphere).try_normalize();
    let axis = flat_direction(&clouds, &used, sphere)
        .or_else(|| hinge_axis(&clouds, &used, &means, radial_dir));
    let planar = axis.map(|axis| {
        let on_axis = sphere + axis * axis.dot(target - sphere);
        geometric_centre(&clouds, &used, on_axis, &[axis], None)
    });
    // Sliding along the axis bought nothing: it is a hinge axis (or near it).
    let (base, hinge) = match planar {
        Some(p) if radial(&clouds, &used, p).0 <= 1.05 * rms_sphere + 1e-3 => (p, true),
        _ => (sphere, false),
    };
    // Whether this neighbour qualifies, and how it ranks, is the distances' verdict alone:
    // the prior below only moves the centre (pulling it where the distances disagree must
    // not hand the segment to a worse neighbour). On a true axis the prior would only
    // slide the centre along it, so it applies to ball joints.
    let (rms_mm, base_radii) = radial(&clouds, &used, base);
    // About a hinge, the turn is measured in the plane across its axis: the centre's place
    // along the axis is a convention, and from one far along it every direction to the
    // markers looks nearly the same.
    let across = |v: DVec3| match axis {
        Some(a) if hinge => v - a * a.dot(v),
        _ => v,
    };
    let excursion_deg = clouds
        .iter()
        .zip(&base_radii)
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|((cloud, (_, dir)), _)| {
            let mean = across(*dir).normalize_or_zero();
            let sq = cloud
                .iter()
                .filter_map(|q| across(*q - base).try_normalize())
                .map(|u| u.dot(mean).clamp(-1.0, 1.0).acos().powi(2))
                .sum::<f64>();
            (sq / cloud.len() as f64).sqrt().to_degrees()
        })
        .fold(0.0f64, f64::max);
    let centre = match prior(axis) {
        Some(prior) if !hinge => geometric_centre(&clouds, &used, sphere, &[], Some(prior)),
        _ => base,
    };
    let (_, radii) = radial(&clouds, &used, centre);
    // A short turn identifies the centre as well as the residual allows: the distances
    // let it stray about residual / excursion (radians) across the markers' paths.
    let exact = params.anchor_exact_centre_mm > 0.0
        && rms_mm / excursion_deg.to_radians() <= params.anchor_exact_centre_mm;
    let ok = rms_mm.is_finite() && rms_mm <= params.anchor_max_rms_mm;
    ok.then_some(CentreFit {
        centre,
        rms_mm,
        excursion_deg,
        samples,
        axis: axis.filter(|_| hinge),
        radii,
        identified: excursion_deg >= min_excursion_deg || exact,
    })
}

/// Curvature of the radial objective below which a direction counts as flat, relative to
/// its largest: rounding only (a swing's sagitta or noise off a hinge's planes stays
/// orders of magnitude above it).
const FLAT_CURVATURE: f64 = 1e-6;

/// The direction along which the radial residual about `c` does not change at all (a
/// hinge axis on noise-free data): the Gauss–Newton matrix's least eigenvector when its
/// eigenvalue is below [`FLAT_CURVATURE`] of the largest; `None` otherwise.
fn flat_direction(clouds: &[Vec<DVec3>], used: &[bool], c: DVec3) -> Option<DVec3> {
    let jtj: DMat3 = clouds
        .iter()
        .zip(used)
        .filter(|(cloud, u)| **u && !cloud.is_empty())
        .map(|(cloud, _)| CloudSums::new(cloud, c, true).normal_matrix())
        .sum();
    let (values, vectors) = sym_eigen(jtj.to_cols_array_2d());
    (values[0] > 0.0 && values[2] <= FLAT_CURVATURE * values[0])
        .then(|| DVec3::from_array(vectors[2]).try_normalize())
        .flatten()
}

/// The direction a hinge would turn S's markers about, in N's frame, or `None` when no
/// direction qualifies. A hinge keeps each marker in a plane ⟂ its axis, so the axis is
/// the least-spread direction of the markers' displacements about their own means —
/// unless that direction is the radial one (from the centre to the markers): a ball joint
/// swinging a limb through a modest arc moves it least along the limb (the arc's sagitta),
/// and sliding the centre along the limb is a change of bone length, not a free choice.
/// Then the axis is the least-spread direction across the limb (the swing's minor axis).
fn hinge_axis(
    clouds: &[Vec<DVec3>],
    used: &[bool],
    means: &[DVec3],
    radial_dir: Option<DVec3>,
) -> Option<DVec3> {
    let scatter = scatter(
        clouds
            .iter()
            .zip(used)
            .zip(means)
            .filter(|((_, u), _)| **u)
            .flat_map(|((cloud, _), mean)| cloud.iter().map(move |q| *q - *mean)),
    );
    let (_, vectors) = sym_eigen(scatter);
    let normal = DVec3::from_array(vectors[2]).try_normalize()?;
    let Some(radial_dir) = radial_dir else {
        return Some(normal);
    };
    // 60° from the radial direction: beyond that the plane normal is not a swing axis.
    if normal.dot(radial_dir).abs() < 0.5 {
        return Some(normal);
    }
    let e1 = radial_dir.any_orthonormal_vector();
    let e2 = radial_dir.cross(e1);
    let m = DMat3::from_cols_array_2d(&scatter);
    let across = [
        [e1.dot(m * e1), e1.dot(m * e2)],
        [e2.dot(m * e1), e2.dot(m * e2)],
    ];
    let (_, v2) = sym_eigen(across);
    (e1 * v2[1][0] + e2 * v2[1][1]).try_normalize()
}

/// A two-marker S's line seen from N: per frame the markers' midpoint and unit direction.
struct MarkerLine {
    samples: Vec<(DVec3, DVec3)>,
    dir_mean: DVec3,
    /// Unit mean direction.
    dir: DVec3,
    /// The point nearest every frame's line, least squares (N-local, mm).
    foot: DVec3,
    /// Variance (mm²) of `foot` along the line from the lines' own scatter.
    foot_var: f64,
    /// Mean squared change of the direction, `Σ|d − d̄|² / n` (radians², small angles).
    turn_var: f64,
}

impl MarkerLine {
    /// `None` unless S has exactly two markers and the line turns (≳ 1° RMS) in N's frame.
    /// A centre fixed in both segments on (or near) S's line is where (or near where) all
    /// the frames' lines meet; that point is found to first order in the swing, where the
    /// markers' distances find the centre's coordinate along the limb only to second.
    fn new(traj: &Trajectories, markers: &[usize], track: &[Option<Pose>]) -> Option<Self> {
        let &[m1, m2] = markers else { return None };
        let samples: Vec<(DVec3, DVec3)> = track
            .iter()
            .enumerate()
            .filter_map(|(f, pose)| {
                let pose = pose.as_ref()?;
                let p1 = pose.inverse_apply(DVec3::from_array(traj.get(f, m1)?));
                let p2 = pose.inverse_apply(DVec3::from_array(traj.get(f, m2)?));
                Some((0.5 * (p1 + p2), (p2 - p1).try_normalize()?))
            })
            .collect();
        if samples.len() < 3 {
            return None;
        }
        let n = samples.len() as f64;
        let dir_mean = samples.iter().map(|(_, d)| *d).sum::<DVec3>() / n;
        let (mut normal, mut rhs, mut var) = (DMat3::ZERO, DVec3::ZERO, 0.0);
        for (a, d) in &samples {
            // Projector across the line: the point nearest every line does not care where
            // along its line a marker sits (skin slides markers along a limb).
            let across = DMat3::IDENTITY - DMat3::from_cols(*d * d.x, *d * d.y, *d * d.z);
            normal += across;
            rhs += across * *a;
            var += (*d - dir_mean).length_squared();
        }
        if var / n < 3e-4 || normal.determinant().abs() < 1e-12 {
            return None;
        }
        let foot = normal.inverse() * rhs;
        // How well the lines agree on that point: each line's distance from it should be
        // constant (the centre's offset from the line); its scatter is the line noise as
        // seen at the foot — skin artefact across the line, amplified by the lever from
        // the markers — and, being smooth, it counts as its effective sample number.
        let distances: Vec<f64> = samples
            .iter()
            .map(|(a, d)| {
                let v = foot - *a;
                (v - *d * d.dot(v)).length()
            })
            .collect();
        let mean = distances.iter().sum::<f64>() / n;
        let spread: Vec<f64> = distances.iter().map(|x| x - mean).collect();
        let sq = spread.iter().map(|x| x * x).sum::<f64>();
        let lag = spread.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
        let rho = if sq > 0.0 {
            (lag / sq).clamp(0.0, 0.999)
        } else {
            0.0
        };
        let effective = ((1.0 - rho) / (1.0 + rho)).clamp(1e-3, 1.0);
        let foot_var = (sq / n) / (n * effective * (var / n));
        Some(Self {
            dir_mean,
            dir: dir_mean.try_normalize()?,
            foot,
            foot_var,
            turn_var: var / n,
            samples,
        })
    }

    /// Samples (frames) on the line.
    fn count(&self) -> f64 {
        self.samples.len() as f64
    }

    /// A bound (mm) on how far `foot` sits along the line from the projection of the
    /// centre. Lines through the centre meet there exactly; lines at distance `h` from it
    /// meet off it along the line by `h Cov(d, n) / Var(d)` (`d` the line's direction, `n`
    /// the unit direction from the line to the centre), which vanishes for a swing in one
    /// plane and, by Cauchy–Schwarz with `n` turning as much as the minor swing, is at
    /// most `h √(minor / major)` of the direction's swing variances. `h` is the RMS
    /// distance of `foot` from the lines, which does not depend on any sphere fit.
    fn bias_bound(&self) -> f64 {
        let n = self.count();
        let h = (self
            .samples
            .iter()
            .map(|(a, d)| {
                let v = self.foot - *a;
                (v - *d * d.dot(v)).length_squared()
            })
            .sum::<f64>()
            / n)
            .sqrt();
        let (values, _) = sym_eigen(scatter(
            self.samples.iter().map(|(_, d)| *d - self.dir_mean),
        ));
        if values[0] <= 0.0 {
            return h;
        }
        h * (values[1].max(0.0) / values[0]).sqrt()
    }
}

/// `Σ v vᵀ` over `vectors`.
fn scatter(vectors: impl Iterator<Item = DVec3>) -> [[f64; 3]; 3] {
    let mut sum = [[0.0f64; 3]; 3];
    for v in vectors {
        let v = v.to_array();
        for i in 0..3 {
            for j in 0..3 {
                sum[i][j] += v[i] * v[j];
            }
        }
    }
    sum
}

/// `n_eff / n` of the radial residuals about `c`, from their lag-1 autocorrelation ρ:
/// `(1 − ρ) / (1 + ρ)`, clamped to [1e-3, 1].
fn effective_fraction(clouds: &[Vec<DVec3>], used: &[bool], c: DVec3) -> f64 {
    let (mut lag, mut sq) = (0.0, 0.0);
    for (cloud, &u) in clouds.iter().zip(used) {
        if !u || cloud.is_empty() {
            continue;
        }
        let r = cloud.iter().map(|q| (*q - c).length()).sum::<f64>() / cloud.len() as f64;
        let e: Vec<f64> = cloud.iter().map(|q| (*q - c).length() - r).collect();
        sq += e.iter().map(|x| x * x).sum::<f64>();
        lag += e.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
    }
    if sq <= 0.0 {
        return 1.0;
    }
    let rho = (lag / sq).clamp(0.0, 0.999);
    ((1.0 - rho) / (1.0 + rho)).clamp(1e-3, 1.0)
}

/// A soft constraint `weight · (dir · c − value)²` added to the squared radial residuals.
#[derive(Clone, Copy)]
struct Prior {
    dir: DVec3,
    value: f64,
    weight: f64,
}

/// One pass over a marker's samples about a centre `c`: the sums the radial residual and
/// its Gauss–Newton system need, so each iteration reads every sample once, with one
/// square root.
struct CloudSums {
    /// Number of samples.
    n: f64,
    /// Distance of the first sample: the shift that keeps the sums of squares from
    /// cancelling (distances of hundreds of mm, residuals of a few).
    shift: f64,
    /// Σ (|q − c| − shift).
    sum_e: f64,
    /// Σ (|q − c| − shift)².
    sum_e2: f64,
    /// Σ of the unit directions (q − c)/|q − c|.
    sum_u: DVec3,
    /// Σ u uᵀ (upper triangle: xx, xy, xz, yy, yz, zz); zero unless asked for.
    outer: [f64; 6],
}

impl CloudSums {
    fn new(cloud: &[DVec3], c: DVec3, with_outer: bool) -> Self {
        let shift = cloud.first().map_or(0.0, |q| (*q - c).length());
        let mut sums = Self {
            n: cloud.len() as f64,
            shift,
            sum_e: 0.0,
            sum_e2: 0.0,
            sum_u: DVec3::ZERO,
            outer: [0.0; 6],
        };
        for q in cloud {
            let v = *q - c;
            let d = v.length();
            let u = if d > 0.0 { v / d } else { DVec3::ZERO };
            let e = d - shift;
            sums.sum_e += e;
            sums.sum_e2 += e * e;
            sums.sum_u += u;
            if with_outer {
                let o = &mut sums.outer;
                o[0] += u.x * u.x;
                o[1] += u.x * u.y;
                o[2] += u.x * u.z;
                o[3] += u.y * u.y;
                o[4] += u.y * u.z;
                o[5] += u.z * u.z;
            }
        }
        sums
    }

    /// This marker's Gauss–Newton matrix JᵀJ = Σ u uᵀ − n m mᵀ (m the mean direction; the
    /// Jacobian row of a sample is m − u, see [`geometric_centre`]).
    fn normal_matrix(&self) -> DMat3 {
        let o = self.outer;
        let uu = DMat3::from_cols_array(&[o[0], o[1], o[2], o[1], o[3], o[4], o[2], o[4], o[5]]);
        let m = self.sum_u;
        uu - DMat3::from_cols(m * m.x, m * m.y, m * m.z) * (1.0 / self.n)
    }

    /// The mean distance: the marker's radius about `c`.
    fn radius(&self) -> f64 {
        self.shift + self.sum_e / self.n
    }

    /// Σ (|q − c| − radius)².
    fn squared_residual(&self) -> f64 {
        (self.sum_e2 - self.sum_e * self.sum_e / self.n).max(0.0)
    }
}

/// Gauss–Newton on the geometric radial residual `|q − c| − r_m` (each `r_m` at its
/// optimum, the mean distance, eliminated), from `start`; `c` does not move along the
/// orthonormal directions `fixed`; `prior` adds a soft constraint on one coordinate.
/// Keeps `start` if no step lowers the objective.
///
/// With u_q the unit direction from c to sample q and m the mean of a marker's u_q, the
/// Jacobian row of a sample is m − u_q (variable projection of r_m), so JᵀJ = Σ u uᵀ − n m mᵀ
/// and Jᵀe = r n m − Σ (q − c): one pass per iteration ([`CloudSums`]), which also gives
/// the objective at the point it was taken at.
fn geometric_centre(
    clouds: &[Vec<DVec3>],
    used: &[bool],
    start: DVec3,
    fixed: &[DVec3],
    prior: Option<Prior>,
) -> DVec3 {
    let sample_sums: Vec<DVec3> = clouds.iter().map(|c| c.iter().copied().sum()).collect();
    // The projection that removes the `fixed` directions from a Jacobian row, as a matrix.
    let project = |mut j: DVec3| {
        for axis in fixed {
            j -= *axis * axis.dot(j);
        }
        j
    };
    let p = DMat3::from_cols(project(DVec3::X), project(DVec3::Y), project(DVec3::Z));
    let outer = |j: DVec3| DMat3::from_cols(j * j.x, j * j.y, j * j.z);
    // Objective, JᵀJ and Jᵀe at `c`.
    let system = |c: DVec3| {
        let (mut value, mut jtj, mut jte) = (0.0, DMat3::ZERO, DVec3::ZERO);
        for ((cloud, &u), &sum_q) in clouds.iter().zip(used).zip(&sample_sums) {
            if !u || cloud.is_empty() {
                continue;
            }
            let s = CloudSums::new(cloud, c, true);
            value += s.squared_residual();
            jtj += s.normal_matrix();
            jte += s.sum_u * s.radius() - (sum_q - c * s.n);
        }
        let mut jtj = p * jtj * p.transpose();
        let mut jte = p * jte;
        if let Some(prior) = prior {
            let gap = prior.dir.dot(c) - prior.value;
            value += prior.weight * gap * gap;
            let j = project(prior.dir);
            jtj += outer(j) * prior.weight;
            jte += j * (prior.weight * gap);
        }
        for axis in fixed {
            // A fixed direction has no data; keep the system solvable without moving along it.
            jtj += outer(*axis);
        }
        (value, jtj, jte)
    };
    let mut c = start;
    let (mut best, mut jtj, mut jte) = system(c);
    for _ in 0..20 {
        if jtj.determinant().abs() < 1e-300 {
            break;
        }
        let step = -(jtj.inverse() * jte);
        if !step.is_finite() {
            break;
        }
        let next = c + step;
        let (next_value, next_jtj, next_jte) = system(next);
        if next_value.partial_cmp(&best) != Some(std::cmp::Ordering::Less) {
            break;
        }
        let small = step.length() < 1e-6;
        c = next;
        (best, jtj, jte) = (next_value, next_jtj, next_jte);
        if small {
            break;
        }
    }
    c
}

/// RMS radial residual about `c` and every marker's (mean radius, mean unit direction).
fn radial(clouds: &[Vec<DVec3>], used: &[bool], c: DVec3) -> (f64, Vec<(f64, DVec3)>) {
    let (mut sq, mut count) = (0.0, 0usize);
    let mut radii = Vec::with_capacity(clouds.len());
    for (cloud, &u) in clouds.iter().zip(used) {
        if !u {
            radii.push((f64::NAN, DVec3::NAN));
            continue;
        }
        let s = CloudSums::new(cloud, c, false);
        sq += s.squared_residual();
        count += cloud.len();
        radii.push((s.radius(), s.sum_u.try_normalize().unwrap_or(DVec3::NAN)));
    }
    ((sq / count.max(1) as f64).sqrt(), radii)
}

/// Poses of segment `id` (markers `markers`) through the centre `fit` found in N's frame.
fn anchored_poses(
    traj: &Trajectories,
    id: usize,
    markers: &[usize],
    n_poses: &SegmentPoses,
    n_track: &[Option<Pose>],
    fit: &CentreFit,
    params: &Params,
) -> SegmentPoses {
    let c = fit.centre;
    if markers.len() >= 2 {
        let count = markers.len() + 1;
        let shape = fit_shape(
            traj.frames(),
            count,
            markers.len(),
            |f, k| match markers.get(k) {
                Some(&m) => traj.get(f, m).map(DVec3::from_array),
                None => n_track[f].as_ref().map(|p| p.apply(c)),
            },
            FitRules {
                // The centre is no marker: its scatter is the neighbour's pose error, so
                // the markers' scatter says nothing about the spin this shape leaves.
                max_spin_deg: 0.0,
                ..FitRules::of(params)
            },
        );
        return shape.into_poses(id, markers.len());
    }
    // One marker: swing-only pose relative to N (see the module docs).
    line_poses(traj, id, markers, n_poses, n_track, fit)
}

/// Swing-only poses of a segment of one marker, or of markers in line with the centre N
/// carries (see the module docs): per frame N's rotation composed with the smallest
/// rotation carrying the centre→markers direction from its mean to the frame's (the twist
/// about that line is N's, by convention), placed so the centre is where N carries it.
/// Local frame: N's axes, origin at the markers' mean place; `rms_mm` the markers' RMS
/// distance from their posed places (for one marker, its distance's from the radius).
fn line_poses(
    traj: &Trajectories,
    id: usize,
    markers: &[usize],
    n_poses: &SegmentPoses,
    n_track: &[Option<Pose>],
    fit: &CentreFit,
) -> SegmentPoses {
    let c = fit.centre;
    let frames = traj.frames();
    let nan3 = [f64::NAN; 3];
    let mut out = SegmentPoses {
        segment: id,
        reference: vec![nan3; markers.len()],
        rotations: vec![[f64::NAN; 4]; frames],
        translations: vec![nan3; frames],
        rms_mm: vec![f64::NAN; frames],
    };
    // Each marker's mean place in N's frame, from the centre fit.
    let places: Vec<DVec3> = fit.radii.iter().map(|&(r, u)| c + r * u).collect();
    if places.len() != markers.len() || places.iter().any(|p| !p.is_finite()) {
        return out;
    }
    let origin = places.iter().sum::<DVec3>() / places.len() as f64;
    let Some(dir0) = (origin - c).try_normalize() else {
        return out;
    };
    for (r, p) in out.reference.iter_mut().zip(&places) {
        *r = (*p - origin).to_array();
    }
    let centre_local = c - origin;
    for f in 0..frames {
        let Some(pose) = &n_track[f] else { continue };
        let seen = || {
            markers
                .iter()
                .zip(&places)
                .filter_map(|(&m, &place)| Some((place, DVec3::from_array(traj.get(f, m)?))))
        };
        // The seen markers' mean place now, against the same markers' reference mean.
        let (mut now, mut then, mut count) = (DVec3::ZERO, DVec3::ZERO, 0usize);
        for (place, x) in seen() {
            now += pose.inverse_apply(x);
            then += place;
            count += 1;
        }
        let (Some(u), Some(u0)) = (
            (now / count as f64 - c).try_normalize(),
            (then / count as f64 - c).try_normalize(),
        ) else {
            continue;
        };
        let swing = DQuat::from_rotation_arc(u0, u) * DQuat::from_rotation_arc(dir0, u0);
        let mut rot = (DQuat::from_array(n_poses.rotations[f]) * swing).normalize();
        if rot.w < 0.0 {
            rot = -rot;
        }
        let trans = pose.apply(c) - rot * centre_local;
        let sq: f64 = seen()
            .map(|(place, x)| (rot * (place - origin) + trans).distance_squared(x))
            .sum();
        out.rotations[f] = rot.to_array();
        out.translations[f] = trans.to_array();
        out.rms_mm[f] = (sq / count as f64).sqrt();
    }
    out
}

/// How far the line of a segment posed by [`line_poses`] leaves one plane through the
/// centre as it swings, in N's frame: √(λ₃ / λ₂) of the second moments of its direction
/// about the centre (λ₁ ≥ λ₂ ≥ λ₃), out-of-plane spread over in-plane swing. A hinge
/// whose axis is square to the line swings it in a plane and turns it about nothing else,
/// so the line's poses are the joint's (ratio near 0); about a ball joint the line covers
/// a patch and its own twist, which no pose of two markers in line can see, is unknown.
fn swing_plane_ratio(line: &SegmentPoses, n_poses: &SegmentPoses) -> f64 {
    let direction = line_direction(line);
    let mut m = [[0.0f64; 3]; 3];
    for (q, qn) in line.rotations.iter().zip(&n_poses.rotations) {
        if !q[3].is_finite() || !qn[3].is_finite() {
            continue;
        }
        // The line's direction in N's frame.
        let rel = DQuat::from_array(*qn).inverse() * DQuat::from_array(*q);
        let d = (rel * direction).to_array();
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += d[i] * d[j];
            }
        }
    }
    let (values, _) = sym_eigen(m);
    if values[1].is_nan() || values[1] <= 0.0 {
        return f64::INFINITY;
    }
    (values[2].max(0.0) / values[1]).sqrt()
}

/// The direction of a two-marker segment's marker line in its local frame.
fn line_direction(poses: &SegmentPoses) -> DVec3 {
    match poses.reference.as_slice() {
        [a, b] => (DVec3::from_array(*b) - DVec3::from_array(*a)).normalize_or_zero(),
        _ => DVec3::ZERO,
    }
}

/// A centre N carries (`centre`, N-local) as S sees it: the mean over the frames where
/// both are posed of its place in S's local frame; `None` with fewer than `min_frames`
/// (at least 1) such frames.
pub(crate) fn centre_in_segment(
    s_track: &[Option<Pose>],
    n_track: &[Option<Pose>],
    centre: DVec3,
    min_frames: usize,
) -> Option<DVec3> {
    let (mut sum, mut count) = (DVec3::ZERO, 0usize);
    for (s, nb) in s_track.iter().zip(n_track) {
        if let (Some(s), Some(nb)) = (s, nb) {
            sum += s.inverse_apply(nb.apply(centre));
            count += 1;
        }
    }
    (count >= min_frames.max(1)).then(|| sum / count as f64)
}

/// How well spread the points of a gap fill (S's visible markers and the anchor's centre)
/// must be: as for a pose from S's own markers (`Params::max_spin_deg`), the spin their
/// scatter leaves is bounded, that scatter being S's fit scatter, or the centre's radial
/// residual where larger, over their lever; and as there, only a lever clearly worse than
/// S's whole marker set's is refused (a set poorly spread even when all are seen keeps
/// its fills). Two markers in line with the centre (a sphere's marker beside the shoulder
/// it hangs from) leave the spin about that line to noise: snowman-hard-s30038's middle
/// sphere, filled so in half its frames, put its waist and neck 130-150 mm off.
fn fill_spread(poses: &SegmentPoses, fit: &CentreFit, params: &Params) -> Spread {
    let mut spread = Spread::fixed(params.min_spread_mm);
    if params.max_spin_deg > 0.0
        && let Some((sigma, reference)) = crate::poses::fit_scatter(poses)
    {
        let sigma = sigma.max(fit.rms_mm);
        let full_lever = crate::poses::lever_mm(reference.into_iter());
        if sigma.is_finite() {
            spread.min_lever_mm = (sigma / params.max_spin_deg.to_radians()).min(0.5 * full_lever);
        }
    }
    spread
}

/// Fills frames where `poses` (S's own, ≥ 3 markers) is missing from S's visible markers
/// plus the anchor's centre; returns which frames were filled.
fn fill_gaps(
    traj: &Trajectories,
    markers: &[usize],
    poses: &mut SegmentPoses,
    s_track: &[Option<Pose>],
    n_track: &[Option<Pose>],
    fit: &CentreFit,
    params: &Params,
) -> Vec<bool> {
    let mut filled = vec![false; traj.frames()];
    let Some(centre_in_s) = centre_in_segment(s_track, n_track, fit.centre, params.min_frames)
    else {
        return filled;
    };
    let reference: Vec<DVec3> = poses
        .reference
        .iter()
        .map(|r| DVec3::from_array(*r))
        .collect();
    let spread = fill_spread(poses, fit, params);
    let mut buf = Vec::with_capacity(markers.len() + 1);
    for f in 0..traj.frames() {
        let (None, Some(nb)) = (&s_track[f], &n_track[f]) else {
            continue;
        };
        buf.clear();
        for (&m, r) in markers.iter().zip(&reference) {
            if let Some(p) = traj.get(f, m)
                && r.is_finite()
            {
                buf.push((*r, DVec3::from_array(p)));
            }
        }
        if buf.len() < 2 {
            continue;
        }
        buf.push((centre_in_s, nb.apply(fit.centre)));
        if let Some(rf) = fit_pairs(&buf, spread) {
            poses.rotations[f] = rf.rotation.to_array();
            poses.translations[f] = rf.translation.to_array();
            poses.rms_mm[f] = rf.rms_mm;
            filled[f] = true;
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A segment of three markers 200-370 mm apart, fitted with 2 mm of misfit, and an
    /// anchor centre fitted to 1 mm.
    fn sphere_and_centre() -> (SegmentPoses, CentreFit) {
        let poses = SegmentPoses {
            segment: 0,
            reference: vec![
                [-76.0, 140.5, -24.1],
                [-112.8, -26.9, 68.0],
                [188.8, -113.7, -43.9],
            ],
            rotations: vec![[0.0, 0.0, 0.0, 1.0]; 10],
            translations: vec![[0.0; 3]; 10],
            rms_mm: vec![2.0; 10],
        };
        let fit = CentreFit {
            centre: DVec3::ZERO,
            rms_mm: 1.0,
            excursion_deg: 30.0,
            samples: 100,
            axis: None,
            radii: Vec::new(),
            identified: true,
        };
        (poses, fit)
    }

    /// Fit of the first and third reference markers plus the centre at `centre` (S-local),
    /// all seen where they are (identity pose).
    fn fill_with(poses: &SegmentPoses, spread: Spread, centre: DVec3) -> Option<()> {
        let r = |k: usize| DVec3::from_array(poses.reference[k]);
        let buf = [(r(0), r(0)), (r(2), r(2)), (centre, centre)];
        fit_pairs(&buf, spread).map(|_| ())
    }

    #[test]
    fn a_fill_whose_centre_is_in_line_with_its_two_markers_is_refused() {
        let (poses, fit) = sphere_and_centre();
        let spread = fill_spread(&poses, &fit, &Params::default());
        // The snowman's right shoulder, 9 mm off the line through the two markers left:
        // their scatter turns the fill tens of degrees about that line.
        let in_line = DVec3::new(200.4, -137.3, -47.9);
        assert!(fill_with(&poses, spread, in_line).is_none());
        // Without the bound the same three points are fitted (the old behaviour).
        let fixed = Spread::fixed(Params::default().min_spread_mm);
        assert!(fill_with(&poses, fixed, in_line).is_some());
        // A centre well off that line fixes the spin: filled.
        assert!(fill_with(&poses, spread, DVec3::new(0.0, 0.0, 150.0)).is_some());
    }

    #[test]
    fn fills_are_bounded_only_where_the_segment_has_a_spread_to_lose() {
        let (mut poses, fit) = sphere_and_centre();
        // Markers nearly in one line even when all are seen: the bound is at most half
        // their own lever, so the fill is kept as their own poses are.
        poses.reference = vec![[0.0, 0.0, 0.0], [150.0, 1.0, 0.0], [300.0, 0.0, 1.0]];
        let spread = fill_spread(&poses, &fit, &Params::default());
        let full = crate::poses::lever_mm(crate::poses::reference_points(&poses).into_iter());
        assert!(
            spread.min_lever_mm <= 0.5 * full + 1e-12,
            "{} {full}",
            spread.min_lever_mm
        );
        // No bound at all with max_spin_deg 0.
        let off = Params {
            max_spin_deg: 0.0,
            ..Params::default()
        };
        assert_eq!(fill_spread(&poses, &fit, &off).min_lever_mm, 0.0);
    }
}
