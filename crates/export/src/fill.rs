//! markers.trc and markers.c3d: the capture's markers as the pipeline read them, each gap
//! filled from its segment's pose.
//!
//! The pipeline reads a capture with its label swaps undone, a glitch's samples as gaps
//! and an unlabeled capture's pieces of one marker joined in the first piece's track
//! ([`segment::Segmentation::repaired`]); these files hold that reading, so a marker tool
//! (or the next capture session's labelling) starts from what the skeleton was fitted to.
//! Where a segment's marker is missing but the segment is posed, the marker goes to its
//! reference place in the segment posed at that frame: a rigid-body fill, as capture
//! software makes one. The pose is the segment's own (jointfit's
//! [`jointfit::SegmentPoses`]: three of its markers, or two and a joint) or, where it has
//! none, its other markers seen there and its tree joints' centres (each known from the
//! neighbour's pose) fitted as one rigid body, where they spread off a line
//! ([`MIN_SPREAD_MM`]): a two-marker thigh that lost one marker is posed by the other and
//! its hip and knee. Skin moves a marker a few millimetres about that place, so the posed
//! place misses the marker's own samples at the gap's ends; the fill carries that miss,
//! measured at the nearest sample on each side that the pose reaches, linearly across the
//! gap (one side's miss where only one side has a pose), so a filled stretch meets its
//! samples on both sides. In each gap the pose reaching most of its frames leads and the
//! other fills in only where it has none: each switch jumps by how far the two disagree.
//! A marker in no segment, a marker never seen with the rest of its segment and a frame
//! without a pose stay missing.

use glam::{DQuat, DVec3};

use crate::{Error, Inputs, Params};

/// The capture's markers as read and filled, and how many samples each gained.
pub(crate) struct FilledMarkers {
    /// One track per capture marker but the later pieces of one marker (their samples are
    /// in the first piece's track), in capture order; rounded and turned as joints.trc.
    pub trajectories: mocap_io::Trajectories,
    /// Per capture marker (capture order): samples filled from its segment's pose.
    pub filled: Vec<usize>,
}

/// Reads the capture as the pipeline did and fills every segment marker's gaps where its
/// segment is posed (see the module docs).
pub(crate) fn filled_markers(input: &Inputs<'_>, params: &Params) -> Result<FilledMarkers, Error> {
    let seg = input.segmentation;
    let read = seg.repaired(input.trajectories);
    let (frames, markers) = (read.frames(), read.markers());
    let mut tracks: Vec<Vec<[f64; 3]>> = (0..markers)
        .map(|m| {
            (0..frames)
                .map(|f| read.get(f, m).unwrap_or(mocap_io::MISSING))
                .collect()
        })
        .collect();
    // Later pieces of one marker: their samples are in the first piece's track.
    let later_piece: Vec<bool> = (0..markers)
        .map(|m| {
            seg.pieces
                .iter()
                .any(|g| g.len() > 1 && g[1..].contains(&m))
        })
        .collect();
    // The tree joints' positions, which jointfit's artifact leaves to be derived.
    let joint_positions: Vec<Vec<[f64; 3]>> = input
        .topology
        .joints
        .iter()
        .map(|j| input.fits.joint_positions(j.pair))
        .collect();
    let mut filled = vec![0; markers];
    for segment in &seg.segments {
        let Some(poses) = input.fits.poses.get(segment.id) else {
            continue;
        };
        if poses.segment != segment.id {
            return Err(Error::Mismatch(format!(
                "segment {} has the poses of segment {}",
                segment.id, poses.segment
            )));
        }
        if let Some(&m) = segment.markers.iter().find(|&&m| m >= markers) {
            return Err(Error::Mismatch(format!(
                "segment {} holds marker {m}; the capture has {markers}",
                segment.id
            )));
        }
        let own_pose = |f: usize| -> Option<(DQuat, DVec3)> {
            let q = DQuat::from_array(*poses.rotations.get(f)?);
            let t = DVec3::from_array(*poses.translations.get(f)?);
            (q.is_finite() && t.is_finite()).then_some((q, t))
        };
        // The tree's joints on this segment: their centres in its frame and per frame.
        let centres: Vec<(DVec3, &[[f64; 3]])> = input
            .topology
            .joints
            .iter()
            .zip(&joint_positions)
            .filter_map(|(j, positions)| {
                let pair = input.fits.pairs.get(j.pair)?;
                let local = if pair.a == segment.id {
                    pair.centre_in_a
                } else if pair.b == segment.id {
                    pair.centre_in_b
                } else {
                    return None;
                };
                let local = DVec3::from_array(local);
                local.is_finite().then_some((local, &positions[..]))
            })
            .collect();
        for (k, &m) in segment.markers.iter().enumerate() {
            let Some(reference) = poses.reference.get(k).map(|&r| DVec3::from_array(r)) else {
                continue;
            };
            if !reference.is_finite() || later_piece[m] {
                continue;
            }
            let posed = |f: usize| own_pose(f).map(|(q, t)| q * reference + t);
            // Where the segment has no pose of its own: its other markers seen and its
            // joints' centres known there, fitted as one rigid body.
            let through_joints = |f: usize| {
                let mut points: Vec<(DVec3, DVec3)> = segment
                    .markers
                    .iter()
                    .zip(&poses.reference)
                    .filter(|&(&other, r)| other != m && DVec3::from_array(*r).is_finite())
                    .filter_map(|(&other, r)| {
                        let p = read.get(f, other)?;
                        Some((DVec3::from_array(*r), DVec3::from_array(p)))
                    })
                    .collect();
                points.extend(centres.iter().filter_map(|&(local, positions)| {
                    let p = DVec3::from_array(*positions.get(f)?);
                    p.is_finite().then_some((local, p))
                }));
                if line_spread_mm(points.iter().map(|p| p.0)) < MIN_SPREAD_MM {
                    return None;
                }
                let fit = jointfit::absolute_orientation(&points)?;
                Some(fit.rotation * reference + fit.translation)
            };
            filled[m] = fill_gaps(&mut tracks[m], &[&posed, &through_joints]);
        }
    }
    let kept: Vec<usize> = (0..markers).filter(|&m| !later_piece[m]).collect();
    let (tracks, kept) = (&tracks, &kept);
    let positions: Vec<[f64; 3]> = (0..frames)
        .flat_map(|f| {
            kept.iter()
                .map(move |&m| crate::trc::sample(tracks[m][f], params.y_up))
        })
        .collect();
    let labels = kept.iter().map(|&m| read.labels()[m].clone()).collect();
    let trajectories = mocap_io::Trajectories::new(
        labels,
        read.frame_rate(),
        read.first_frame(),
        frames,
        positions,
    )
    .map_err(|e| Error::Mismatch(format!("filled markers: {e}")))?;
    Ok(FilledMarkers {
        trajectories,
        filled,
    })
}

/// Least RMS distance (mm) of the points a pose through joints stands on from their best
/// line: below it their spin about that line is left to noise (the markers themselves are
/// ~14 mm wide; 1 mm of noise at 10 mm turns the spin by ~6°).
const MIN_SPREAD_MM: f64 = 10.0;

/// RMS distance of `points` from the line through the two farthest apart (their long
/// axis); 0 for fewer than three.
fn line_spread_mm(points: impl Iterator<Item = DVec3>) -> f64 {
    let points: Vec<DVec3> = points.collect();
    if points.len() < 3 {
        return 0.0;
    }
    let mut ends = (points[0], points[0]);
    for (i, &a) in points.iter().enumerate() {
        for &b in &points[i + 1..] {
            if a.distance_squared(b) > ends.0.distance_squared(ends.1) {
                ends = (a, b);
            }
        }
    }
    let Some(axis) = (ends.1 - ends.0).try_normalize() else {
        return 0.0;
    };
    let sum: f64 = points
        .iter()
        .map(|&p| (p - ends.0).reject_from_normalized(axis).length_squared())
        .sum();
    (sum / points.len() as f64).sqrt()
}

/// Most samples on each side of a gap searched for one a source places, to measure its
/// miss there: farther from the gap than this the skin has moved on.
const EDGE_SEARCH: usize = 32;

/// Fills each run of missing samples of `track` where one of `sources` gives the marker's
/// place, shifted by that source's miss at the run's ends (linear between the nearest
/// sample before and after that the source places, within [`EDGE_SEARCH`] of the gap; the
/// one side's where only one has it, none where neither); returns the samples filled. In
/// each gap the source placing the most frames leads and the others fill in where it has
/// nothing (earlier sources first), since every switch jumps by how far two sources
/// disagree.
pub(crate) fn fill_gaps(
    track: &mut [[f64; 3]],
    sources: &[&dyn Fn(usize) -> Option<DVec3>],
) -> usize {
    let n = track.len();
    let present = |p: [f64; 3]| mocap_io::is_present(p);
    let mut filled = 0;
    let mut f = 0;
    while f < n {
        if present(track[f]) {
            f += 1;
            continue;
        }
        let start = f;
        while f < n && !present(track[f]) {
            f += 1;
        }
        // The gap is start..f, with a run of samples (or the capture's end) on each side.
        let places: Vec<Vec<Option<DVec3>>> = sources
            .iter()
            .map(|source| (start..f).map(source).collect())
            .collect();
        let mut order: Vec<usize> = (0..sources.len()).collect();
        order.sort_by_key(|&i| std::cmp::Reverse(places[i].iter().flatten().count()));
        let track_ref: &[[f64; 3]] = track;
        let miss = |source: &dyn Fn(usize) -> Option<DVec3>,
                    side: &mut dyn Iterator<Item = usize>| {
            side.take(EDGE_SEARCH)
                .take_while(|&e| present(track_ref[e]))
                .find_map(|e| source(e).map(|p| (e, DVec3::from_array(track_ref[e]) - p)))
        };
        let misses: Vec<_> = sources
            .iter()
            .map(|source| {
                let before = miss(*source, &mut (0..start).rev());
                let after = miss(*source, &mut (f..n));
                (before, after)
            })
            .collect();
        for (g, sample) in track.iter_mut().enumerate().take(f).skip(start) {
            let Some((p, (before, after))) = order
                .iter()
                .find_map(|&i| places[i][g - start].map(|p| (p, misses[i])))
            else {
                continue;
            };
            let shift = match (before, after) {
                (Some((e0, a)), Some((e1, b))) => a.lerp(b, (g - e0) as f64 / (e1 - e0) as f64),
                (Some((_, a)), None) => a,
                (None, Some((_, b))) => b,
                (None, None) => DVec3::ZERO,
            };
            let q = p + shift;
            if q.is_finite() {
                *sample = q.to_array();
                filled += 1;
            }
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::fill_gaps;

    const GAP: [f64; 3] = mocap_io::MISSING;

    /// A marker that moves with its body plus a steady skin offset: the fill is the posed
    /// place plus that offset, exactly, and the samples around the gap are untouched.
    #[test]
    fn a_gap_is_filled_at_the_posed_place_shifted_by_the_miss_at_its_ends() {
        let posed = |f: usize| Some(DVec3::new(f as f64 * 10.0, 5.0, 0.0));
        let skin = DVec3::new(0.0, 3.0, -2.0);
        let truth: Vec<[f64; 3]> = (0..10)
            .map(|f| (posed(f).unwrap_or_default() + skin).to_array())
            .collect();
        let mut track = truth.clone();
        for p in &mut track[3..7] {
            *p = GAP;
        }
        assert_eq!(fill_gaps(&mut track, &[&posed]), 4);
        for (f, (got, want)) in track.iter().zip(&truth).enumerate() {
            let d = DVec3::from_array(*got).distance(DVec3::from_array(*want));
            assert!(d < 1e-12, "frame {f}: {got:?} against {want:?}");
        }
    }

    /// A miss that grows across the gap (skin drifting) is carried linearly from one end
    /// to the other, so the filled stretch meets both ends' samples.
    #[test]
    fn the_miss_is_carried_linearly_from_one_end_of_the_gap_to_the_other() {
        let posed = |_: usize| Some(DVec3::ZERO);
        let mut track = vec![[0.0, 0.0, 0.0], GAP, GAP, GAP, [8.0, 0.0, 0.0]];
        assert_eq!(fill_gaps(&mut track, &[&posed]), 3);
        let x: Vec<f64> = track.iter().map(|p| p[0]).collect();
        assert_eq!(x, [0.0, 2.0, 4.0, 6.0, 8.0]);
    }

    /// Two sources: the first places only the gap's first frame, the second every gap
    /// frame but not the samples right beside the gap. The second leads (no switch
    /// inside the gap), and its miss is measured at the nearest samples it places.
    #[test]
    fn the_source_placing_most_of_a_gap_leads_and_its_miss_is_found_beside_the_gap() {
        let first = |f: usize| (f == 3).then_some(DVec3::new(100.0, 0.0, 0.0));
        let second = |f: usize| (f != 2 && f != 7).then_some(DVec3::new(f as f64, 0.0, 0.0));
        // Samples 1 mm above the second source's place; frames 3..7 missing.
        let mut track: Vec<[f64; 3]> = (0..10).map(|f| [f as f64, 1.0, 0.0]).collect();
        for p in &mut track[3..7] {
            *p = GAP;
        }
        assert_eq!(fill_gaps(&mut track, &[&first, &second]), 4);
        for (f, p) in track.iter().enumerate() {
            assert_eq!(*p, [f as f64, 1.0, 0.0], "frame {f}");
        }
    }

    /// Where the body has no pose the marker stays missing; a gap at the capture's start
    /// takes the one miss it has (at its end).
    #[test]
    fn frames_without_a_pose_stay_missing_and_an_open_gap_takes_its_one_miss() {
        let posed = |f: usize| (f != 1).then_some(DVec3::new(f as f64, 0.0, 0.0));
        let mut track = vec![GAP, GAP, GAP, [3.0, 1.0, 0.0], [4.0, 1.0, 0.0]];
        assert_eq!(fill_gaps(&mut track, &[&posed]), 2);
        assert_eq!(track[0], [0.0, 1.0, 0.0]);
        assert!(!mocap_io::is_present(track[1]));
        assert_eq!(track[2], [2.0, 1.0, 0.0]);
        // Nothing posed: nothing filled.
        let mut lost = vec![GAP; 4];
        assert_eq!(fill_gaps(&mut lost, &[&|_| None]), 0);
        assert!(lost.iter().all(|p| !mocap_io::is_present(*p)));
    }
}
