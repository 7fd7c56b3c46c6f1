//! Pieces of one marker's trajectory that the reader left apart, joined by a body that
//! holds one of them.
//!
//! The reader's stitch (`mocap_io::stitch`) follows a piece across a gap of up to a second,
//! carried by neighbours that keep their distances around both ends; past that it cannot
//! tell a neighbour on the same segment from one across a joint. Once segmented, a body of
//! ≥ 3 markers is posed wherever three of its markers are seen, on both sides of any gap:
//! a piece that ends continues as the piece that starts later where its mean position in
//! the body's frame over its last [`WINDOW_SECONDS`] is, to within [`MATCH_SHARE`] of the
//! way to the body's nearest marker seen with it (capped at the marker spacing), the mean
//! position of the later piece over its first, and no rival starts within
//! [`RIVAL_FACTOR`] times that distance (as the stitch decides). The body holds either
//! piece, so a piece that went to a neighbour's cluster is found from its other piece's
//! body. Where no pose carries a piece across (the body's other markers hidden or in
//! pieces over the same stretch), a track never seen with a member joins it when it keeps
//! the distances the body's shape puts that member from ≥ 2 of the others, rigidly
//! ([`kept_distances`]). A cluster of two markers' tracks (one or both in pieces, never
//! more than two seen at once) joins a later piece to an earlier one by the distances it
//! keeps to the partners seen rigidly with both ([`partner_distances`]). A piece with two
//! candidate continuations, or continuing two pieces, joins none. Only where none of these
//! joins anything, a body hidden whole for a while (every member's track ends before any
//! of another body's starts) is that body again where its shape is, marker by marker
//! ([`reappeared_bodies`]); so are tracks of a body's own cluster that it could not be
//! posed with, where they pose a body of its shape (a segment hidden whole whose later
//! tracks clustered with its earlier ones, or most of it hidden, one marker seen, which
//! poses them where fewer than three come back; [`come_back`]).
//! Skin moves a marker in its body's frame slowly: on the hard preset's unlabeled captures
//! (seeds 20001..20020, a throwaway print of every body's best candidate) the true
//! continuation started 0.18 (median) of the way to the nearest marker from where its piece
//! ended, a wrong best candidate 4.7; over seeds 20001..20050 and 30001..30050 one of the
//! 1885 groups the poses join is wrong, and with the distances 6 of 2500, each a marker's
//! piece taken for another marker's of the same segment (at 2–3 markers per segment, 22
//! of 1799, some across a joint: a cluster of two segments' few markers passes for a
//! body there).
//!
//! It does not join pieces that share a frame, or pieces of a marker whose body of ≥ 3
//! neither poses at both ends nor is seen with two of its markers along the other piece,
//! or pieces of a two-marker body never seen with a common partner, or of a cluster that
//! sees three tracks at once but no three pose, or a body of two markers hidden whole.

use std::collections::{BTreeMap, BTreeSet};

use mocap_io::Trajectories;

use crate::glitch::{distance, runs};
use crate::pairstats::PairStats;
use crate::reassign::{Pose, PosedGroup, horn, posed_group, stride_of};
use crate::segmentation::{
    Glitch, LabelSwap, Segmentation, UnassignedMarker, join_pieces, with_positions,
};

/// Seconds at each piece's end over which its position in a body's frame is averaged.
const WINDOW_SECONDS: f64 = 0.5;
/// A continuation starts within this share of the distance from the ended piece to the
/// body's nearest marker seen with it (capped at the marker spacing) of where it ended.
const MATCH_SHARE: f64 = 0.5;
/// No rival continuation starts within this many times the chosen one's distance.
const RIVAL_FACTOR: f64 = 2.0;

/// First and last frame a track is seen in.
pub(crate) fn span(traj: &Trajectories, m: usize) -> Option<(usize, usize)> {
    let first = (0..traj.frames()).find(|&f| traj.get(f, m).is_some())?;
    let last = (0..traj.frames())
        .rev()
        .find(|&f| traj.get(f, m).is_some())?;
    Some((first, last))
}

/// Marker `m`'s mean position in a body's frame over the posed strided frames of `frames`
/// in which it is seen; `None` when there are none.
fn local_mean(
    traj: &Trajectories,
    poses: &[Option<Pose>],
    stride: usize,
    m: usize,
    frames: std::ops::RangeInclusive<usize>,
) -> Option<[f64; 3]> {
    let mut sum = [0.0; 3];
    let mut count = 0usize;
    for f in frames.filter(|f| f % stride == 0) {
        let (Some(pose), Some(x)) = (poses.get(f / stride).copied().flatten(), traj.get(f, m))
        else {
            continue;
        };
        let local = pose.local(x);
        for (s, l) in sum.iter_mut().zip(local) {
            *s += l;
        }
        count += 1;
    }
    (count > 0).then(|| sum.map(|s| s / count as f64))
}

/// Groups of tracks that are pieces of one marker's trajectory (each ascending, ≥ 2, never
/// seen together), by the rule in the module docs; tracks `fixed` marks are left alone.
pub(crate) fn find_pieces(
    traj: &Trajectories,
    stats: &PairStats,
    clusters: &[Vec<usize>],
    fixed: &[bool],
    rigid: (usize, f64),
) -> Vec<Vec<usize>> {
    let Some(spacing_mm) = traj.marker_spacing_mm() else {
        return Vec::new();
    };
    let frames = traj.frames();
    let window = ((WINDOW_SECONDS * traj.frame_rate()).round() as usize).max(1);
    let stride = stride_of(traj);
    let spans: Vec<Option<(usize, usize)>> = (0..traj.markers())
        .map(|m| span(traj, m).filter(|_| !fixed.get(m).copied().unwrap_or(true)))
        .collect();
    let head = |m: usize| spans[m].map(|(first, _)| first..=(first + window).min(frames - 1));
    let tail = |m: usize| spans[m].map(|(_, last)| last.saturating_sub(window)..=last);
    // (earlier piece, later piece)
    let mut joins: BTreeSet<(usize, usize)> = BTreeSet::new();
    let mut by_distances: BTreeSet<(usize, usize)> = BTreeSet::new();
    // Every posable body, for a body hidden whole for a while (the last resort below).
    let mut bodies: Vec<Body> = Vec::new();
    for c in clusters.iter().filter(|c| c.len() >= 3) {
        let Some((members, PosedGroup { shape, poses })) = posable_body(traj, stats, c) else {
            // Only where the cluster is two markers' tracks: one partner's distance is a
            // sphere of places, and a body of more markers has other tracks on it (c3d.org's
            // Dance cut at gaps of 1.1–2.6 s, tests/it/unlabeled.rs: 3 → 5 wrong of 25).
            let seen_at = |f: usize| c.iter().filter(|&&m| traj.get(f, m).is_some()).count();
            if (0..frames).all(|f| seen_at(f) <= 2) {
                by_distances.extend(partner_distances(stats, c, &spans, spacing_mm, rigid));
            }
            continue;
        };
        // Every track's mean place in this body over its first and its last window.
        let at = |m: usize, frames: Option<std::ops::RangeInclusive<usize>>| {
            local_mean(traj, &poses, stride, m, frames?)
        };
        let starts: Vec<Option<[f64; 3]>> = (0..spans.len()).map(|m| at(m, head(m))).collect();
        let ends: Vec<Option<[f64; 3]>> = (0..spans.len()).map(|m| at(m, tail(m))).collect();
        for &k in c {
            let Some((first_k, last_k)) = spans[k] else {
                continue;
            };
            // How far this marker sits from its body's nearest marker seen with it.
            let nearest = |x: [f64; 3]| {
                members
                    .iter()
                    .zip(&shape)
                    .filter(|&(&m, _)| m != k && !stats.apart(k, m))
                    .map(|(_, s)| distance(*s, x))
                    .fold(spacing_mm, f64::min)
            };
            // k's continuation, then what k continues; a rival is any other candidate but
            // a later (earlier) piece of the chosen one's marker.
            if let Some(end) = ends[k] {
                let candidates: Vec<(usize, f64)> = (0..spans.len())
                    .filter(|&m| spans[m].is_some_and(|(first, _)| first > last_k))
                    .filter_map(|m| Some((m, distance(starts[m]?, end))))
                    .collect();
                let after = |r: usize, p: usize| match (spans[r], spans[p]) {
                    (Some((first, _)), Some((_, last))) => first > last,
                    _ => false,
                };
                if let Some(p) = continuation(&candidates, nearest(end), after) {
                    joins.insert((k, p));
                }
            }
            if let Some(start) = starts[k] {
                let candidates: Vec<(usize, f64)> = (0..spans.len())
                    .filter(|&m| spans[m].is_some_and(|(_, last)| last < first_k))
                    .filter_map(|m| Some((m, distance(ends[m]?, start))))
                    .collect();
                let before = |r: usize, q: usize| match (spans[r], spans[q]) {
                    (Some((_, last)), Some((first, _))) => last < first,
                    _ => false,
                };
                if let Some(q) = continuation(&candidates, nearest(start), before) {
                    joins.insert((q, k));
                }
            }
        }
        let dropped: Vec<usize> = c.iter().copied().filter(|m| !members.contains(m)).collect();
        by_distances.extend(kept_distances(
            stats,
            (&members, &shape),
            &dropped,
            &spans,
            spacing_mm,
            rigid,
        ));
        bodies.push(Body {
            members,
            shape,
            dropped,
        });
    }
    // A pose carries a piece across where it can; distances only join what it left apart.
    for (a, b) in by_distances {
        if !joins.iter().any(|&(x, y)| x == a || y == b) {
            joins.insert((a, b));
        }
    }
    let groups = chains(&joins);
    if !groups.is_empty() {
        return groups;
    }
    // A body's shape only once nothing else joins: matched while other pieces are apart, it
    // sent a real capture's later rounds elsewhere (c3d.org's Dance cut at gaps of
    // 1.1–2.6 s: right joins, but wrong groups 3 → 6 of 27 after them).
    let mut by_shape = reappeared_bodies(stats, &bodies, &spans, spacing_mm, rigid);
    for body in &bodies {
        by_shape.extend(come_back(traj, stats, body, &spans, spacing_mm, rigid));
    }
    chains(&by_shape.into_iter().collect())
}

/// Joins (earlier piece, later piece) of a body's member with a track never seen with it
/// that keeps its distances to the member's place in the body's shape: for a body not
/// posed at one end of a gap (its markers hidden or in pieces together), the track seen
/// with ≥ [`DISTANCE_PARTNERS`] of the other members, rigidly to every member it is seen
/// with (ρ within `rigid.1` over ≥ `rigid.0` frames; fewer frames rule it out) and at the
/// distances the shape puts the member from them (RMS within [`MATCH_SHARE`] × the
/// member's distance to its nearest neighbour in the shape, capped at `spacing_mm`), no
/// other member as near within [`RIVAL_FACTOR`] times, and no track of `others` (the
/// cluster's tracks outside the body) seen with the member and never with the track, on
/// the far side of it in time, as near to its distances to the members; of several such
/// tracks on one side of the member, the nearest in time, unless two of them are seen
/// together (W unlabeled, `--markers 2:3`: wrong joins 28 → 25 of about 1250, across a
/// joint 8 → 5, trees the same; the rival outside the body: wrong groups 8 → 6 of 2500 on
/// W unlabeled, 24 → 22 of 1801 at `--markers 2:3`).
fn kept_distances(
    stats: &PairStats,
    (members, shape): (&[usize], &[[f64; 3]]),
    others: &[usize],
    spans: &[Option<(usize, usize)>],
    spacing_mm: f64,
    (min_overlap, tolerance_mm): (usize, f64),
) -> Vec<(usize, usize)> {
    // RMS misfit of `c`'s distances as the member at `i`, when it qualifies.
    let misfit = |c: usize, i: usize| -> Option<f64> {
        let (mut sum, mut count) = (0.0, 0usize);
        for (j, &x) in members.iter().enumerate() {
            if j == i || stats.apart(c, x) {
                continue;
            }
            let rho = stats.rho(c, x, min_overlap)?;
            if rho > tolerance_mm {
                return None;
            }
            let d = stats.mean[stats.at(c, x)] - distance(shape[i], shape[j]);
            sum += d * d;
            count += 1;
        }
        (count >= DISTANCE_PARTNERS).then(|| (sum / count as f64).sqrt())
    };
    let apart = |a: usize, b: usize| stats.apart(a, b);
    let mut out = Vec::new();
    for (i, &b) in members.iter().enumerate() {
        let Some((first_b, last_b)) = spans[b] else {
            continue;
        };
        let scale = members
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(j, _)| distance(shape[i], shape[j]))
            .fold(spacing_mm, f64::min);
        let mut after: Vec<(usize, usize)> = Vec::new();
        let mut before: Vec<(usize, usize)> = Vec::new();
        for c in (0..spans.len()).filter(|&c| !members.contains(&c) && apart(b, c)) {
            let Some((first_c, last_c)) = spans[c] else {
                continue;
            };
            if first_c <= last_b && last_c >= first_b {
                continue;
            }
            let Some(fit) = misfit(c, i) else {
                continue;
            };
            let rival = members
                .iter()
                .enumerate()
                .filter(|&(j, &o)| j != i && apart(o, c))
                .filter_map(|(j, _)| misfit(c, j))
                .any(|other| other < RIVAL_FACTOR * fit);
            // A track of the cluster seen with the member (so another marker) that could be
            // c's own marker before (after) it, keeping c's distances as well: c may be its
            // piece as much as the member's (human-hard-s30001 unlabeled: r_upperarm's M077
            // ends at 207, M018 at 239, M077's later piece from 271 was taken for M018's).
            let piece_rival = others
                .iter()
                .filter(|&&d| d != c && apart(d, c) && !apart(d, b))
                .filter(|&&d| {
                    spans[d].is_some_and(|(first_d, last_d)| {
                        if first_c > last_b {
                            last_d < first_c
                        } else {
                            first_d > last_c
                        }
                    })
                })
                .filter_map(|&d| {
                    partner_misfit(stats, members, (c, d), (min_overlap, tolerance_mm))
                        .filter(|&(_, count, _)| count >= DISTANCE_PARTNERS)
                        .map(|(misfit, _, _)| misfit)
                })
                .any(|other| other < RIVAL_FACTOR * fit);
            if fit > MATCH_SHARE * scale || rival || piece_rival {
                continue;
            }
            // (frames between the two, track)
            if first_c > last_b {
                after.push((first_c - last_b, c));
            } else {
                before.push((first_b - last_c, c));
            }
        }
        out.extend(nearest_in_time(&after, apart).map(|c| (b, c)));
        out.extend(nearest_in_time(&before, apart).map(|c| (c, b)));
    }
    out
}

/// Two tracks' mean distances to the `partners` seen rigidly with both (ρ within
/// `rigid.1` over ≥ `rigid.0` frames): the RMS difference, how many partners, and the
/// least of `a`'s distances to them; `None` without such a partner.
fn partner_misfit(
    stats: &PairStats,
    partners: &[usize],
    (a, b): (usize, usize),
    (min_overlap, tolerance_mm): (usize, f64),
) -> Option<(f64, usize, f64)> {
    let rigid = |p: usize, x: usize| {
        stats
            .rho(p, x, min_overlap)
            .is_some_and(|rho| rho <= tolerance_mm)
    };
    let (mut sum, mut count, mut nearest) = (0.0, 0usize, f64::INFINITY);
    for &x in partners.iter().filter(|&&x| rigid(a, x) && rigid(b, x)) {
        let (da, db) = (stats.mean[stats.at(a, x)], stats.mean[stats.at(b, x)]);
        sum += (db - da) * (db - da);
        count += 1;
        nearest = nearest.min(da);
    }
    (count > 0).then(|| ((sum / count as f64).sqrt(), count, nearest))
}

/// Of the tracks `found` to fit one piece (frames between them and it, track), the nearest
/// in time; but two of them seen together (not `apart`) cannot both be it, so then none.
fn nearest_in_time(
    found: &[(usize, usize)],
    apart: impl Fn(usize, usize) -> bool,
) -> Option<usize> {
    let clash = found
        .iter()
        .any(|&(_, c)| found.iter().any(|&(_, d)| c != d && !apart(c, d)));
    let first = found.iter().min().map(|&(_, c)| c);
    first.filter(|_| !clash)
}

/// Joins (earlier piece, later piece) of tracks of a cluster of two markers' tracks (one or
/// both in pieces, never more than two seen at once): the later piece, never seen with the
/// earlier one, keeps to every partner seen rigidly with both (ρ within `rigid.1` over ≥
/// `rigid.0` frames; ≥ 1 partner) the earlier one's mean distance, RMS within
/// [`MATCH_SHARE`] × the nearest such distance (capped at `spacing_mm`) and within
/// `rigid.1`; of several such later pieces, the nearest in time, unless two of them are
/// seen together.
fn partner_distances(
    stats: &PairStats,
    cluster: &[usize],
    spans: &[Option<(usize, usize)>],
    spacing_mm: f64,
    (min_overlap, tolerance_mm): (usize, f64),
) -> Vec<(usize, usize)> {
    let apart = |a: usize, b: usize| stats.apart(a, b);
    let mut out = Vec::new();
    for &b in cluster {
        let Some((_, last_b)) = spans[b] else {
            continue;
        };
        let mut after: Vec<(usize, usize)> = Vec::new();
        for &c in cluster.iter().filter(|&&c| c != b && apart(b, c)) {
            let Some((first_c, _)) = spans[c] else {
                continue;
            };
            if first_c <= last_b {
                continue;
            }
            let Some((misfit, _, nearest)) =
                partner_misfit(stats, cluster, (b, c), (min_overlap, tolerance_mm))
            else {
                continue;
            };
            if misfit <= (MATCH_SHARE * nearest.min(spacing_mm)).min(tolerance_mm) {
                after.push((first_c - last_b, c));
            }
        }
        out.extend(nearest_in_time(&after, apart).map(|c| (b, c)));
    }
    out
}

/// A posable cluster: the members it is posed from, their shape, and the cluster's other
/// tracks (never seen with some member).
struct Body {
    /// Tracks posed as one rigid body.
    members: Vec<usize>,
    /// Their reference shape, indexed like `members` (body-local, mm).
    shape: Vec<[f64; 3]>,
    /// The cluster's tracks the body could not be posed with.
    dropped: Vec<usize>,
}

/// Joins (earlier piece, later piece) of a body's members with the cluster's tracks it
/// could not be posed with, where those pose a body of its shape (by [`shape_match`]'s
/// bounds), each never seen with the member it maps to: its markers come back (CMU
/// 02_01's right foot hidden whole 1.2 s: its later tracks clustered with its earlier
/// ones; tests/it/unlabeled.rs). Fewer than three such tracks pose that body with the
/// members seen with each of them, each of those in its own place: a body of three with
/// one marker in sight while the other two came back as new tracks (snowman-hard-s70037
/// unlabeled, whose right upper arm comes back so for its last 136 frames: its two
/// returning markers sit 16 mm apart at like distances from the third, and only the shapes'
/// own scatter tells the swapped map from the right one, see [`shape_match`]).
fn come_back(
    traj: &Trajectories,
    stats: &PairStats,
    body: &Body,
    spans: &[Option<(usize, usize)>],
    spacing_mm: f64,
    (min_overlap, tolerance_mm): (usize, f64),
) -> Vec<(usize, usize)> {
    let (members, dropped) = (&body.members, &body.dropped);
    if dropped.is_empty() {
        return Vec::new();
    }
    // With three or more, the tracks that came back pose alone; else with those members.
    let staying: Vec<usize> = if dropped.len() >= 3 {
        Vec::new()
    } else {
        members
            .iter()
            .copied()
            .filter(|&m| dropped.iter().all(|&d| !stats.apart(m, d)))
            .collect()
    };
    let tracks: Vec<usize> = dropped.iter().chain(&staying).copied().collect();
    if tracks.len() < 3 {
        return Vec::new();
    }
    let Some(again) = posed_group(traj, &tracks) else {
        return Vec::new();
    };
    let allowed = |i: usize, j: usize| match dropped.get(j) {
        Some(&d) => stats.apart(members[i], d),
        None => members[i] == tracks[j],
    };
    let scatter = shape_scatter(stats, [members, &tracks], min_overlap);
    let pairs = shape_match(
        &body.shape,
        &again.shape,
        spacing_mm,
        (tolerance_mm, scatter),
        allowed,
    );
    let mut out = Vec::new();
    for (i, j) in pairs.into_iter().flatten() {
        let Some(&d) = dropped.get(j) else {
            continue;
        };
        match (spans[members[i]], spans[d]) {
            (Some((_, last)), Some((first, _))) if last < first => out.push((members[i], d)),
            (Some((first, _)), Some((_, last))) if last < first => out.push((d, members[i])),
            _ => {}
        }
    }
    out
}

/// Most members of a body whose shape is matched against another's (the maps tried grow as
/// the factorial of the count).
const MAX_SHAPE_MEMBERS: usize = 10;

/// Two bodies whose shapes are one, the later seen only after the earlier.
struct BodyMatch {
    /// Frames between the earlier's last and the later's first.
    gap: usize,
    /// Index of the earlier body.
    earlier: usize,
    /// Index of the later body.
    later: usize,
    /// Matched members, (index in the earlier, index in the later).
    pairs: Vec<(usize, usize)>,
}

/// Joins (earlier piece, later piece) between two posable bodies never seen together, the
/// later starting after the earlier ends, whose shapes are one body's: all of one body's
/// members hidden at once (an unlabeled capture starts a new track for each when they come
/// back, and no pose or seen partner carries a piece across). The smaller body's members
/// map one-to-one onto the other's so that a rotation and translation put its shape on the
/// other's within [`MATCH_SHARE`] × the larger shape's closest two markers (capped at
/// `spacing_mm`) and within twice `tolerance_mm` (a distance scattering within the
/// tolerance has means over two stretches up to twice it apart), RMS, and no other map fits
/// within the rival bar (`tolerance_mm`, or twice the shapes' own distance scatter where
/// that is less: [`shape_scatter`]) or within [`RIVAL_FACTOR`] times the best; ≥ 3 members
/// each. A proper rotation tells a body of four or more from its mirror image (a left
/// limb's cluster from a right one's). Of several such bodies on one side, the nearest in
/// time, and only where each is the other's.
fn reappeared_bodies(
    stats: &PairStats,
    bodies: &[Body],
    spans: &[Option<(usize, usize)>],
    spacing_mm: f64,
    (min_overlap, tolerance_mm): (usize, f64),
) -> Vec<(usize, usize)> {
    // Each body's first and last frame; None where a member has no span (a user's track).
    let extent = |members: &[usize]| -> Option<(usize, usize)> {
        let spans: Option<Vec<(usize, usize)>> = members.iter().map(|&m| spans[m]).collect();
        let spans = spans?;
        Some((
            spans.iter().map(|s| s.0).min()?,
            spans.iter().map(|s| s.1).max()?,
        ))
    };
    let extents: Vec<Option<(usize, usize)>> = bodies.iter().map(|b| extent(&b.members)).collect();
    // Every fitting (earlier body, later body) with the frames between them.
    let mut found: Vec<BodyMatch> = Vec::new();
    for (a, body_a) in bodies.iter().enumerate() {
        for (b, body_b) in bodies.iter().enumerate() {
            let (Some((_, last_a)), Some((first_b, _))) = (extents[a], extents[b]) else {
                continue;
            };
            if a == b || last_a >= first_b {
                continue;
            }
            let scatter = shape_scatter(stats, [&body_a.members, &body_b.members], min_overlap);
            if let Some(pairs) = shape_match(
                &body_a.shape,
                &body_b.shape,
                spacing_mm,
                (tolerance_mm, scatter),
                |_, _| true,
            ) {
                found.push(BodyMatch {
                    gap: first_b - last_a,
                    earlier: a,
                    later: b,
                    pairs,
                });
            }
        }
    }
    let mut out = Vec::new();
    for m in &found {
        // Nearest in time on both sides; a tie is no answer.
        let nearer = found.iter().any(|o| {
            (o.earlier, o.later) != (m.earlier, m.later)
                && (o.later == m.later || o.earlier == m.earlier)
                && o.gap <= m.gap
        });
        if nearer {
            continue;
        }
        out.extend(
            m.pairs
                .iter()
                .map(|&(i, j)| (bodies[m.earlier].members[i], bodies[m.later].members[j])),
        );
    }
    out
}

/// RMS of the distance scatter ρ over the pairs of each of `shapes` seen together in at
/// least `min_overlap` frames; `None` without such a pair.
fn shape_scatter(stats: &PairStats, shapes: [&[usize]; 2], min_overlap: usize) -> Option<f64> {
    let (mut sum_sq, mut count) = (0.0, 0usize);
    for tracks in shapes {
        for (k, &i) in tracks.iter().enumerate() {
            for &j in &tracks[k + 1..] {
                if let Some(rho) = stats.rho(i, j, min_overlap) {
                    sum_sq += rho * rho;
                    count += 1;
                }
            }
        }
    }
    (count > 0).then(|| (sum_sq / count as f64).sqrt())
}

/// The one-to-one map of the smaller shape's points onto the larger's (pairs of indices
/// into `a` and `b`) under which one rigid motion fits them best, by [`reappeared_bodies`]'s
/// rule, pairing only points `allowed(i in a, j in b)` lets be one marker; `None` when none
/// fits, or another map fits too nearly as well. `scatter_mm`: the shapes' own distance
/// scatter ([`shape_scatter`]), where known.
fn shape_match(
    a: &[[f64; 3]],
    b: &[[f64; 3]],
    spacing_mm: f64,
    (tolerance_mm, scatter_mm): (f64, Option<f64>),
    allowed: impl Fn(usize, usize) -> bool,
) -> Option<Vec<(usize, usize)>> {
    let (small, large, flipped) = if a.len() <= b.len() {
        (a, b, false)
    } else {
        (b, a, true)
    };
    if small.len() < 3 || large.len() > MAX_SHAPE_MEMBERS {
        return None;
    }
    let mut closest = spacing_mm;
    for (i, p) in large.iter().enumerate() {
        for q in &large[i + 1..] {
            closest = closest.min(distance(*p, *q));
        }
    }
    // A distance that scatters within the tolerance has means over two stretches of the
    // capture up to twice it apart (skin swept by the joints, a snowman's bottom 2.05 mm
    // RMS over a 2 mm tolerance).
    let bound = (MATCH_SHARE * closest).min(2.0 * tolerance_mm);
    // A rival that matters fits within the tolerance or RIVAL_FACTOR × the bound, RMS; a
    // map with a pair of distances twice that apart cannot, and is not tried.
    let prune = 2.0 * tolerance_mm.max(RIVAL_FACTOR * bound);
    let mut best: Option<(f64, Vec<usize>)> = None;
    let mut runner_up = f64::INFINITY;
    let mut map: Vec<usize> = Vec::with_capacity(small.len());
    let mut q: Vec<[f64; 3]> = Vec::with_capacity(small.len());
    let mut visit = |map: &[usize]| {
        q.clear();
        q.extend(map.iter().map(|&j| large[j]));
        let rms = (horn(small, &q).1 / small.len() as f64).sqrt();
        match &best {
            Some((b, _)) if rms >= *b => runner_up = runner_up.min(rms),
            _ => {
                if let Some((b, _)) = &best {
                    runner_up = runner_up.min(*b);
                }
                best = Some((rms, map.to_vec()));
            }
        }
    };
    let may_be = |i: usize, j: usize| {
        if flipped {
            allowed(j, i)
        } else {
            allowed(i, j)
        }
    };
    extend_map(small, large, prune, &may_be, &mut map, &mut visit);
    let (rms, map) = best?;
    // A second map within twice the shapes' own distance scatter (the bound above's reason)
    // cannot be told from the best: c3d.org's Dance cut at gaps of 1.1–2.6 s has a
    // near-isosceles triangle of three markers that fit 1.02 mm RMS with two of them
    // exchanged, 2.83 the right way, its distances scattering 6.1 mm (ρ, RMS), so the
    // capture-wide tolerance, which caps the bar, decides. Where the shapes' own distances
    // scatter less the bar is lower: unlabeled snowman-hard-s70037's upper arm, back as two
    // new tracks beside the third, fits 0.97 mm the right way and 6.88 swapped, its
    // distances scattering 2.24 mm, under a tolerance of 11.2 mm.
    let rival_bar = scatter_mm.map_or(tolerance_mm, |s| tolerance_mm.min(2.0 * s));
    (rms <= bound && runner_up > rival_bar.max(RIVAL_FACTOR * rms)).then(|| {
        map.into_iter()
            .enumerate()
            .map(|(i, j)| if flipped { (j, i) } else { (i, j) })
            .collect()
    })
}

/// Every one-to-one map of `small`'s points onto `large`'s, extending `map`, pairing only
/// points `may_be(i in small, j in large)` allows, whose pair distances agree within
/// `prune`, each complete one given to `visit`.
fn extend_map(
    small: &[[f64; 3]],
    large: &[[f64; 3]],
    prune: f64,
    may_be: &impl Fn(usize, usize) -> bool,
    map: &mut Vec<usize>,
    visit: &mut impl FnMut(&[usize]),
) {
    let i = map.len();
    if i == small.len() {
        visit(map);
        return;
    }
    for j in 0..large.len() {
        if map.contains(&j) || !may_be(i, j) {
            continue;
        }
        let agrees = map.iter().enumerate().all(|(k, &l)| {
            (distance(small[i], small[k]) - distance(large[j], large[l])).abs() <= prune
        });
        if agrees {
            map.push(j);
            extend_map(small, large, prune, may_be, map, visit);
            map.pop();
        }
    }
}

/// Fewest of a body's members a track must be seen with to join a member by its distances:
/// two fix it on a circle about their line, the member's place one point of it.
const DISTANCE_PARTNERS: usize = 2;

/// The cluster posed as one rigid body (its members, their reference shape and the poses
/// per strided frame), without the fewest seen of the tracks never seen with some other
/// member, one at a time, while that leaves no shape (two pieces of one marker with fewer
/// than three partners seen with both) and ≥ 3 members.
fn posable_body(
    traj: &Trajectories,
    stats: &PairStats,
    cluster: &[usize],
) -> Option<(Vec<usize>, PosedGroup)> {
    let mut members = cluster.to_vec();
    while members.len() >= 3 {
        if let Some(posed) = posed_group(traj, &members) {
            return Some((members, posed));
        }
        let apart = |m: usize| members.iter().any(|&o| o != m && stats.apart(m, o));
        let drop = members
            .iter()
            .copied()
            .filter(|&m| apart(m))
            .min_by_key(|&m| (stats.visible[m], m))?;
        members.retain(|&m| m != drop);
    }
    None
}

/// The nearest of `candidates` (track, distance in mm), when within [`MATCH_SHARE`] ×
/// `scale_mm` and no rival is within [`RIVAL_FACTOR`] times as far; `same_marker(r, c)`:
/// whether `r` may be another piece of the chosen `c`'s marker, and so no rival.
fn continuation(
    candidates: &[(usize, f64)],
    scale_mm: f64,
    same_marker: impl Fn(usize, usize) -> bool,
) -> Option<usize> {
    let &(chosen, d) = candidates.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    let rival = candidates
        .iter()
        .filter(|&&(r, _)| r != chosen && !same_marker(r, chosen))
        .map(|&(_, e)| e)
        .fold(f64::INFINITY, f64::min);
    (d <= MATCH_SHARE * scale_mm && rival >= RIVAL_FACTOR * d).then_some(chosen)
}

/// Joins in chains: a piece with two continuations, or continuing two, is in none.
fn chains(joins: &BTreeSet<(usize, usize)>) -> Vec<Vec<usize>> {
    let mut next: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    let mut prev: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &(a, b) in joins {
        next.entry(a).or_default().push(b);
        prev.entry(b).or_default().push(a);
    }
    let sure = |a: usize, b: usize| next[&a].len() == 1 && prev[&b].len() == 1;
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for &(a, _) in joins {
        // Chains start at a piece nothing surely continues.
        if prev.get(&a).is_some_and(|p| p.len() == 1 && sure(p[0], a)) {
            continue;
        }
        let mut group = vec![a];
        let mut at = a;
        while let Some(&[b]) = next.get(&at).map(Vec::as_slice) {
            if !sure(at, b) {
                break;
            }
            group.push(b);
            at = b;
        }
        if group.len() >= 2 {
            group.sort_unstable();
            groups.push(group);
        }
    }
    groups.sort_unstable();
    groups.dedup();
    groups
}

/// Adds the frames of `ranges` (`[first, last]`, inclusive) to `into` under the key `key`
/// gives each frame, as ranges again.
fn by_owner<K: Ord>(
    into: &mut BTreeMap<K, Vec<[usize; 2]>>,
    ranges: &[[usize; 2]],
    key: impl Fn(usize) -> K,
) {
    let mut frames: BTreeMap<K, Vec<usize>> = BTreeMap::new();
    for &[first, last] in ranges {
        for f in first..=last {
            frames.entry(key(f)).or_default().push(f);
        }
    }
    for (k, frames) in frames {
        let held = into.entry(k).or_default();
        held.extend(runs(&frames));
        held.sort_unstable();
    }
}

/// `traj` with each group's pieces in its first track (the smallest index) and the others
/// empty: what segmentation reads once the pieces are joined.
pub(crate) fn joined(traj: &Trajectories, groups: &[Vec<usize>]) -> Trajectories {
    let mut positions = traj.positions().to_vec();
    join_pieces(&mut positions, traj.markers(), groups);
    with_positions(traj, positions)
}

/// Puts the segmentation of [`joined`]`(traj, groups)` back on `traj`'s tracks: each piece
/// goes where its group's first track went (segment, near-joint part, or unassigned with
/// that track's reason), and the glitches and swaps found on the joined track go to the
/// piece seen in their frames. The per-marker diagnostics are the caller's to redo.
pub(crate) fn spread_back(seg: &mut Segmentation, traj: &Trajectories, groups: &[Vec<usize>]) {
    // Which track holds each joined track's sample in a frame.
    let owner = |m: usize, f: usize| -> usize {
        groups
            .iter()
            .find(|g| g[0] == m)
            .and_then(|g| g.iter().copied().find(|&p| traj.get(f, p).is_some()))
            .unwrap_or(m)
    };
    let mut placed: BTreeMap<usize, usize> = BTreeMap::new();
    for group in groups {
        for &p in &group[1..] {
            placed.insert(p, group[0]);
        }
    }
    // A list of markers takes the pieces of the marker tracks it holds.
    let with_pieces = |markers: &mut Vec<usize>| {
        let pieces: Vec<usize> = placed
            .iter()
            .filter(|&(_, kept)| markers.contains(kept))
            .map(|(&p, _)| p)
            .collect();
        markers.extend(pieces);
        markers.sort_unstable();
    };
    seg.segments
        .iter_mut()
        .for_each(|s| with_pieces(&mut s.markers));
    seg.near_joints
        .iter_mut()
        .flat_map(|near| near.parts.iter_mut())
        .for_each(with_pieces);
    let label = |m: usize| seg.labels.get(m).cloned().unwrap_or_else(|| m.to_string());
    let mut unassigned: Vec<UnassignedMarker> = seg
        .unassigned
        .iter()
        .filter(|u| !placed.contains_key(&u.marker))
        .cloned()
        .collect();
    for (&p, &kept) in &placed {
        if let Some(u) = seg.unassigned.iter().find(|u| u.marker == kept) {
            unassigned.push(UnassignedMarker {
                marker: p,
                reason: format!("a piece of {}'s trajectory: {}", label(kept), u.reason),
            });
        }
    }
    unassigned.sort_by_key(|u| u.marker);
    seg.unassigned = unassigned;
    let mut glitches = BTreeMap::new();
    for g in &seg.glitches {
        by_owner(&mut glitches, &g.frames, |f| owner(g.marker, f));
    }
    seg.glitches = glitches
        .into_iter()
        .map(|(marker, frames)| Glitch { marker, frames })
        .collect();
    // Swaps are undone in order (a marker can be in several): each maps to its pieces on
    // its own, in its place.
    let mut swaps = Vec::with_capacity(seg.swaps.len());
    for s in &seg.swaps {
        let [a, b] = s.markers;
        let mut held = BTreeMap::new();
        by_owner(&mut held, &s.frames, |f| [owner(a, f), owner(b, f)]);
        swaps.extend(
            held.into_iter()
                .map(|(markers, frames)| LabelSwap { markers, frames }),
        );
    }
    seg.swaps = swaps;
    // Pieces an inner round joined, by their tracks here.
    let mut all: Vec<Vec<usize>> = groups.to_vec();
    for inner in std::mem::take(&mut seg.pieces) {
        match all.iter_mut().find(|g| inner.iter().any(|m| g.contains(m))) {
            Some(g) => {
                g.extend(inner);
                g.sort_unstable();
                g.dedup();
            }
            None => all.push(inner),
        }
    }
    all.sort_unstable();
    seg.pieces = all;
}

#[cfg(test)]
mod tests {
    use super::{find_pieces, joined, kept_distances, posable_body, span, spread_back};
    use crate::pairstats::pair_stats;
    use crate::segmentation::{Glitch, LabelSwap, with_positions};
    use crate::testscene::{CHILD, PARENT, cut_at_gap, skin_hinged_capture};
    use crate::{Params, run};
    use mocap_io::Trajectories;

    /// Parent markers 0–3 and child markers 4–7 hinged ±30° under 6 mm of skin, marker `a`
    /// cut over frames 120..300 (1.8 s at 100 Hz, past the reader's stitch) and marker `b`
    /// over `b_gap`: the later pieces are markers 8 and 9.
    fn two_cuts(a: usize, b: usize, b_gap: std::ops::Range<usize>, seed: u64) -> Trajectories {
        let traj = skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, seed);
        cut_at_gap(&cut_at_gap(&traj, a, 120..300), b, b_gap)
    }

    fn found(traj: &Trajectories, clusters: &[Vec<usize>]) -> Vec<Vec<usize>> {
        find_pieces(
            traj,
            &pair_stats(traj),
            clusters,
            &vec![false; traj.markers()],
            (crate::Params::default().min_overlap_frames, 10.0),
        )
    }

    /// Two of a body's four markers hidden together (frames 120..260, past the reader's
    /// stitch) come back as new tracks, so no three of its tracks are seen on both sides of
    /// the gap and no pose carries a piece across: each later piece keeps the distances its
    /// marker had to the two markers seen throughout, and joins it; the other pairing does
    /// not fit.
    #[test]
    fn pieces_hidden_together_join_by_their_distances() {
        for seed in 1..=3 {
            for (a, b) in [(1, 2), (4, 6), (0, 3)] {
                let traj = cut_at_gap(
                    &cut_at_gap(
                        &skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, seed),
                        a,
                        120..260,
                    ),
                    b,
                    120..260,
                );
                let side = usize::from(a >= 4);
                let mut clusters = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
                clusters[side].extend([8, 9]);
                assert_eq!(
                    found(&traj, &clusters),
                    vec![vec![a, 8], vec![b, 9]],
                    "seed {seed}, {a} {b}"
                );
            }
        }
    }

    /// A body of two markers, one of them in pieces, has no three tracks to pose it: the
    /// later piece joins its marker by the distance it keeps to the other marker. A track
    /// at another place on the body, never seen with the first, keeps another distance to
    /// it and does not join.
    #[test]
    fn a_two_marker_body_joins_its_pieces_by_the_distance_they_keep() {
        for seed in 1..=3 {
            // Parent markers 0 and 1, child 2–5; marker 1's later piece is 6.
            let cut = cut_at_gap(
                &skin_hinged_capture(&PARENT[..2], &CHILD, 30.0, 6.0, seed),
                1,
                120..300,
            );
            let clusters = [vec![0, 1, 6], vec![2, 3, 4, 5]];
            assert_eq!(found(&cut, &clusters), vec![vec![1, 6]], "seed {seed}");
            // Parent markers 0–2, marker 1 seen only before frame 120, marker 2 only from 300.
            let three = skin_hinged_capture(&PARENT[..3], &CHILD, 30.0, 6.0, seed);
            let n = three.markers();
            let mut positions = three.positions().to_vec();
            for (i, p) in positions.iter_mut().enumerate() {
                let (f, m) = (i / n, i % n);
                if (m == 1 && f >= 120) || (m == 2 && f < 300) {
                    *p = [f64::NAN; 3];
                }
            }
            let apart =
                Trajectories::new(three.labels().to_vec(), 100.0, 1, three.frames(), positions)
                    .expect("same shape");
            let clusters = [vec![0, 1, 2], vec![3, 4, 5, 6]];
            assert_eq!(
                found(&apart, &clusters),
                Vec::<Vec<usize>>::new(),
                "seed {seed}"
            );
        }
    }

    /// A body hidden whole (every child marker over frames 120..300) comes back as four new
    /// tracks, a cluster never seen with the first: no pose and no seen partner carries a
    /// piece across, but its shape is the first cluster's, and each track joins its marker.
    #[test]
    fn a_body_hidden_whole_joins_its_pieces_by_its_shape() {
        for seed in 1..=3 {
            let mut traj = skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, seed);
            for m in 4..8 {
                traj = cut_at_gap(&traj, m, 120..300);
            }
            let clusters = [vec![0, 1, 2, 3], vec![4, 5, 6, 7], vec![8, 9, 10, 11]];
            assert_eq!(
                found(&traj, &clusters),
                vec![vec![4, 8], vec![5, 9], vec![6, 10], vec![7, 11]],
                "seed {seed}"
            );
        }
    }

    /// Four of a body's five markers hidden together (frames 120..300) come back as new
    /// tracks in the body's own cluster, the fifth seen throughout: no pose carries them
    /// across and each later track is seen with one member only, but the four pose a body
    /// of the first one's shape, and each joins its marker.
    #[test]
    fn markers_come_back_in_their_cluster_join_by_its_shape() {
        let child = child_plus_one();
        for seed in 1..=3 {
            assert_eq!(
                come_back_found(&child, &[5, 6, 7, 8], seed),
                vec![vec![5, 9], vec![6, 10], vec![7, 11], vec![8, 12]],
                "seed {seed}"
            );
        }
    }

    /// `CHILD` with a fifth marker below the rest, along the bone.
    fn child_plus_one() -> Vec<[f64; 3]> {
        CHILD
            .iter()
            .copied()
            .chain([[40.0, 10.0, -340.0]])
            .collect()
    }

    /// What `find_pieces` joins in the skin-hinged scene (`PARENT` and `child`, 6 mm of
    /// skin) with markers `hidden` cut at frames 120..300 into new tracks, each body's
    /// tracks one cluster, at a 4 mm tolerance, about what 6 mm of skin leaves a capture
    /// (at the default test tolerance, 10 mm, a body's end-to-end flip fits within it:
    /// 5.7 mm RMS for the four-marker child plus one, the markers along the bone).
    fn come_back_found(child: &[[f64; 3]], hidden: &[usize], seed: u64) -> Vec<Vec<usize>> {
        come_back_found_at(child, hidden, seed, 4.0)
    }

    /// [`come_back_found`] at a rigidity tolerance of `tolerance_mm`.
    fn come_back_found_at(
        child: &[[f64; 3]],
        hidden: &[usize],
        seed: u64,
        tolerance_mm: f64,
    ) -> Vec<Vec<usize>> {
        let mut traj = skin_hinged_capture(&PARENT, child, 30.0, 6.0, seed);
        for &m in hidden {
            traj = cut_at_gap(&traj, m, 120..300);
        }
        let clusters = [vec![0, 1, 2, 3], (4..traj.markers()).collect()];
        let tight = (crate::Params::default().min_overlap_frames, tolerance_mm);
        let stats = pair_stats(&traj);
        find_pieces(
            &traj,
            &stats,
            &clusters,
            &vec![false; traj.markers()],
            tight,
        )
    }

    /// Two of a three-marker body's markers hidden together (frames 120..300) come back as
    /// new tracks, the third seen throughout: two tracks pose nothing and each is seen with
    /// one member only, but with the member seen with both they pose a body of the first
    /// one's shape, that member in its own place, and each joins its marker.
    #[test]
    fn a_body_of_three_with_one_marker_in_sight_joins_by_its_shape() {
        for seed in 1..=3 {
            assert_eq!(
                come_back_found(&CHILD[..3], &[5, 6], seed),
                vec![vec![5, 7], vec![6, 8]],
                "seed {seed}"
            );
        }
    }

    /// At a loose tolerance (10 mm) the wrong map of two scenes fits within it: the
    /// four-marker child plus one flipped end to end (5.7 mm RMS), and a body of three whose
    /// two returning markers sit 18 mm apart at distances 7 mm unlike from the third, as
    /// snowman-hard-s70037's upper arm, exchanged. The rival bar is then twice the shapes'
    /// own distance scatter, well under the tolerance, and each joins as at 4 mm.
    #[test]
    fn a_loose_tolerance_leaves_the_rival_bar_to_the_shapes_own_scatter() {
        let child = child_plus_one();
        let arm = [[0.0, 30.0, -100.0], [8.0, 0.0, -160.0], [-8.0, 0.0, -168.0]];
        for seed in 1..=3 {
            assert_eq!(
                come_back_found_at(&child, &[5, 6, 7, 8], seed, 10.0),
                vec![vec![5, 9], vec![6, 10], vec![7, 11], vec![8, 12]],
                "seed {seed}"
            );
            assert_eq!(
                come_back_found_at(&arm, &[5, 6], seed, 10.0),
                vec![vec![5, 7], vec![6, 8]],
                "seed {seed}"
            );
        }
    }

    /// Two bodies on one hinge never seen together, the second seen only after the first:
    /// a copy of the first's shape is it again and joins it marker by marker; its mirror
    /// image keeps every distance but no rotation puts it on the first, and joins nothing.
    #[test]
    fn a_mirror_image_body_is_not_the_hidden_one() {
        let mirror = CHILD.map(|[x, y, z]| [-x, y, z]);
        for (later, joins) in [(CHILD, true), (mirror, false)] {
            let both: Vec<[f64; 3]> = CHILD.iter().chain(&later).copied().collect();
            let traj = skin_hinged_capture(&PARENT, &both, 30.0, 6.0, 1);
            let n = traj.markers();
            let mut positions = traj.positions().to_vec();
            for (i, p) in positions.iter_mut().enumerate() {
                let (f, m) = (i / n, i % n);
                if ((4..8).contains(&m) && f >= 120) || ((8..12).contains(&m) && f < 300) {
                    *p = [f64::NAN; 3];
                }
            }
            let apart = with_positions(&traj, positions);
            let clusters = [vec![0, 1, 2, 3], vec![4, 5, 6, 7], vec![8, 9, 10, 11]];
            let expected = if joins {
                vec![vec![4, 8], vec![5, 9], vec![6, 10], vec![7, 11]]
            } else {
                Vec::new()
            };
            assert_eq!(found(&apart, &clusters), expected, "joins {joins}");
        }
    }

    /// The skin-hinged scene with marker 1 hidden over frames 120..260, its later piece
    /// track 8.
    fn marker_1_cut(seed: u64) -> Trajectories {
        cut_at_gap(
            &skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, seed),
            1,
            120..260,
        )
    }

    /// `cut` with one more track, `label`, placed in each frame by `at` from that frame's
    /// markers (`None`: hidden).
    fn with_track(
        cut: &Trajectories,
        label: &str,
        at: impl Fn(usize, &[[f64; 3]]) -> Option<[f64; 3]>,
    ) -> Trajectories {
        let n = cut.markers();
        let mut labels = cut.labels().to_vec();
        labels.push(label.to_owned());
        let mut positions = Vec::with_capacity(cut.frames() * (n + 1));
        for f in 0..cut.frames() {
            let frame = cut.frame(f);
            positions.extend_from_slice(frame);
            positions.push(at(f, frame).unwrap_or([f64::NAN; 3]));
        }
        Trajectories::new(labels, cut.frame_rate(), 1, cut.frames(), positions)
            .expect("capture with one more track")
    }

    /// What `kept_distances` joins to the body of markers 0–3, with `others` the cluster's
    /// tracks outside it.
    fn kept_joins(traj: &Trajectories, others: &[usize]) -> Vec<(usize, usize)> {
        let stats = pair_stats(traj);
        let (members, posed) = posable_body(traj, &stats, &[0, 1, 2, 3]).expect("a posable body");
        let spans: Vec<_> = (0..traj.markers()).map(|m| span(traj, m)).collect();
        let spacing = traj.marker_spacing_mm().expect("a spacing");
        kept_distances(
            &stats,
            (&members, &posed.shape),
            others,
            &spans,
            spacing,
            (24, 10.0),
        )
    }

    /// Two tracks seen together that both keep a hidden marker's distances (its later
    /// piece and a ghost 1 mm beside it) cannot both be it: neither joins.
    #[test]
    fn two_tracks_seen_together_do_not_join_one_marker() {
        for seed in 1..=3 {
            let cut = marker_1_cut(seed);
            let traj = with_track(&cut, "ghost", |_, frame| {
                Some([frame[8][0] + 1.0, frame[8][1], frame[8][2]])
            });
            // By distances to the body the later piece alone keeps marker 1's place.
            assert_eq!(kept_joins(&cut, &[]), vec![(1, 8)], "seed {seed}");
            assert_eq!(kept_joins(&traj, &[]), Vec::new(), "seed {seed}");
        }
    }

    /// Another marker of the cluster, seen with marker 1 and gone before 1's later piece
    /// starts, that sits where the piece keeps its distances could be the piece's own
    /// marker: then the piece joins neither; sitting elsewhere on the body, it is no rival.
    #[test]
    fn a_piece_another_marker_could_have_left_does_not_join() {
        for seed in 1..=3 {
            let cut = marker_1_cut(seed);
            for (share, joined) in [(0.02, false), (0.6, true)] {
                // On the body, `share` of the way from marker 1 away from marker 3; seen
                // until frame 100.
                let traj = with_track(&cut, "other", |f, frame| {
                    let (one, three) = (frame[1], frame[3]);
                    (f < 100).then(|| std::array::from_fn(|i| one[i] + share * (one[i] - three[i])))
                });
                let expected = if joined { vec![(1, 8)] } else { Vec::new() };
                assert_eq!(
                    kept_joins(&traj, &[9]),
                    expected,
                    "seed {seed}, share {share}"
                );
            }
        }
    }

    /// Each later piece joins its marker's earlier one, in its own body's cluster or,
    /// found from the earlier piece's body, in the neighbour's.
    #[test]
    fn pieces_join_the_marker_their_body_carries_them_to() {
        let side = |m: usize| usize::from(m >= 4);
        for seed in 1..=3 {
            for (a, b, b_gap) in [(1, 6, 200..330), (5, 2, 200..330), (0, 3, 310..360)] {
                let traj = two_cuts(a, b, b_gap, seed);
                let mut clusters = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
                clusters[side(a)].push(8);
                clusters[side(b)].push(9);
                let mut expected = vec![vec![a, 8], vec![b, 9]];
                expected.sort_unstable();
                assert_eq!(found(&traj, &clusters), expected, "seed {seed}, {a} {b}");
            }
            for a in [1, 5] {
                let traj = cut_at_gap(
                    &skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, seed),
                    a,
                    120..300,
                );
                let mut astray = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
                astray[1 - side(a)].push(8);
                assert_eq!(
                    found(&traj, &astray),
                    vec![vec![a, 8]],
                    "seed {seed}, {a} astray"
                );
            }
        }
    }

    /// A later piece of another marker is no continuation: with marker 5's later piece gone,
    /// marker 6's (cut over the same frames) joins 6, not 5 (a child of five markers, so
    /// the body holding the piece is posed: 5 and the piece have three partners seen with
    /// both).
    #[test]
    fn a_piece_of_another_marker_does_not_join() {
        let mut child = CHILD.to_vec();
        child.push([0.0, -20.0, -150.0]);
        for seed in 1..=3 {
            let traj = skin_hinged_capture(&PARENT, &child, 30.0, 6.0, seed);
            let mut cut = cut_at_gap(&cut_at_gap(&traj, 5, 120..300), 6, 120..300);
            // Marker 5's later piece (9) never seen.
            let n = cut.markers();
            let mut positions = cut.positions().to_vec();
            positions
                .iter_mut()
                .skip(9)
                .step_by(n)
                .for_each(|p| *p = [f64::NAN; 3]);
            cut = Trajectories::new(cut.labels().to_vec(), 100.0, 1, cut.frames(), positions)
                .expect("same shape");
            let clusters = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7, 8, 10]];
            assert_eq!(found(&cut, &clusters), vec![vec![6, 10]], "seed {seed}");
        }
    }

    /// The segmentation of the joined capture, put back: the piece goes to its marker's
    /// segment, and a glitch or swap on the joined track to the piece seen in its frames.
    #[test]
    fn a_joined_segmentation_goes_back_to_the_pieces() {
        let traj = cut_at_gap(
            &skin_hinged_capture(&PARENT, &CHILD, 30.0, 6.0, 1),
            1,
            120..300,
        );
        let groups = vec![vec![1, 8]];
        let plain = Params {
            join_pieces: false,
            ..Params::default()
        };
        let mut seg = run(&joined(&traj, &groups), &plain).expect("segments");
        assert!(
            seg.unassigned.iter().any(|u| u.marker == 8),
            "{:?}",
            seg.unassigned
        );
        seg.glitches = vec![Glitch {
            marker: 1,
            frames: vec![[110, 119], [310, 312]],
        }];
        seg.swaps = vec![LabelSwap {
            markers: [1, 5],
            frames: vec![[100, 119], [300, 304]],
        }];
        spread_back(&mut seg, &traj, &groups);
        let groups_found: Vec<Vec<usize>> =
            seg.segments.iter().map(|s| s.markers.clone()).collect();
        assert_eq!(groups_found, vec![vec![0, 1, 2, 3, 8], vec![4, 5, 6, 7]]);
        assert!(seg.unassigned.is_empty(), "{:?}", seg.unassigned);
        assert_eq!(
            seg.glitches,
            vec![
                Glitch {
                    marker: 1,
                    frames: vec![[110, 119]]
                },
                Glitch {
                    marker: 8,
                    frames: vec![[310, 312]]
                },
            ]
        );
        assert_eq!(
            seg.swaps,
            vec![
                LabelSwap {
                    markers: [1, 5],
                    frames: vec![[100, 119]]
                },
                LabelSwap {
                    markers: [8, 5],
                    frames: vec![[300, 304]]
                },
            ]
        );
        assert_eq!(seg.pieces, groups);
    }

    /// Joining moves each piece's samples into the group's first track and leaves the rest
    /// empty.
    #[test]
    fn joined_pieces_are_one_track() {
        let traj = two_cuts(1, 6, 200..330, 1);
        let one = joined(&traj, &[vec![1, 8]]);
        for f in 0..traj.frames() {
            let piece = traj.get(f, 1).or(traj.get(f, 8));
            assert_eq!(one.get(f, 1), piece, "frame {f}");
            assert_eq!(one.get(f, 8), None, "frame {f}");
            assert_eq!(one.get(f, 6), traj.get(f, 6), "frame {f}");
        }
    }
}
