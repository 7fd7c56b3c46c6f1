//! Label swaps: two markers of different segments whose trajectories a tracker exchanged
//! for a while (it confuses markers that pass close to each other).
//!
//! A swapped marker spends the swap where its partner belongs, so distance statistics (ρ
//! over every frame) can set it apart from its segment, pair it with a stranger, or leave
//! a home too small to pose. Found on a first segmentation, a swap is undone and the
//! capture segmented again (`segment::run`), so every stage sees the markers as they were.
//!
//! A suspect is a marker whose distances to its segment-mates (for a marker in a group of
//! one or two, to a nearby cluster's markers) leave their usual values in a minority of
//! frames. Two suspects of different homes, away in the same frames, are a swap when in
//! those frames each sits where the other belongs, at its partner's usual distances from
//! the partner's home. A steady triangle alone is no proof (a marker near a knee's axis
//! keeps its distances to both the thigh's and the shank's markers); the exchange is.
//! A suspect whose partner never left its own distances (the two were close when the
//! tracker confused them) is paired with the marker of another cluster nearest to where it
//! was recorded while away, judged on whichever distances are seen, and must also jump at
//! a window's end: an exchange is a discontinuity, skin is smooth.
//! Every swap's window ends then move to where exchanging back joins both markers' paths
//! again, and a swap whose undoing would leave a jump is no swap ([`joined_windows`]).
//! Last, two markers that jump in one step each onto the other's path, and again later,
//! are a swap whatever the clusters made of them ([`exchanges_by_jumps`]); so is one that
//! jumps onto the path of a track that has just ended, or leaves its own to a track that
//! starts soon after (an unlabeled capture's tracks end at every gap). Which frames are
//! exchanged follows from where the labels can flip ([`exchanged_frames`]), and undoing
//! them must leave both markers nearer their steadiest partners ([`steadier_undone`]).

use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::fitsplit::median;
use crate::glitch::runs;
use crate::reassign::nearest_clusters;
use crate::segmentation::{LabelSwap, untangle};

/// Rounds of [`exchanges_by_jumps`] at most, each on the capture with the earlier rounds'
/// exchanges undone.
const EXCHANGE_ROUNDS: usize = 3;

/// Most suspect pairs tested, those away together the most first (and as many lone
/// suspects, those away the most first).
const MAX_SWAP_TESTS: usize = 256;

/// Clusters searched as a swapped marker's home, nearest first.
const HOME_CANDIDATES: usize = 3;

/// Share of the frames both markers are seen in that must be explained (at home or swapped).
const MIN_EXPLAINED: f64 = 0.9;

/// Fewest swapped frames that prove a swap (fewer can be two markers passing close).
const MIN_SWAPPED_FRAMES: usize = 3;

/// A swap proven on part of its distances only (a partner that never left its own, a home
/// unseen during the window) must also jump: one of the two markers moves between two
/// frames at a window's end by this many times its median frame-to-frame step. A tracker's
/// exchange is a discontinuity; skin is smooth (snowman-messy-s6005's swap: steps of
/// 49-68 mm against medians of 11-12 mm; hexapod-hard-s10009's skin, which the distances
/// alone took for a swap: 2.4-5.6 mm against 4.5-5.7).
const JUMP_FACTOR: f64 = 4.0;

/// Longest gap (frames) of one marker that [`exchanges_by_jumps`] bridges to pair it with
/// the other's jump: the generator's short holes last up to 20 frames.
const MAX_BRIDGE_FRAMES: usize = 20;

/// Two markers that both step more than their jump bound divided by this, neither
/// jumping, exchange in a step where landing on each other's paths explains the steps
/// this many times better than running on ([`exchanges_by_jumps`]).
const EXCHANGE_GAIN: f64 = 2.0;

/// Frames searched on each side of a window's end for [`JUMP_FACTOR`]'s jump.
const JUMP_SLACK_FRAMES: usize = 2;

/// A marker's own bound: this many times the median change of its distances from their
/// usual values (a marker skin moves a lot is judged by its own scatter).
const OWN_BOUND_FACTOR: f64 = 3.0;

/// Swapped runs apart by this many seen frames that home explains better, or fewer, are
/// one window (a frame or two where the two markers pass close can go either way).
const WINDOW_MERGE_FRAMES: usize = 5;

/// Every label swap among the markers of `clusters` (a segmentation before small groups
/// are dropped), within `hold_mm` (RMS change of a marker's distances to its home's markers
/// from their medians); each marker in at most one.
pub(crate) fn find_swaps(
    traj: &Trajectories,
    clusters: &[Vec<usize>],
    hold_mm: f64,
    stride: usize,
) -> Vec<LabelSwap> {
    // Every marker is judged on its own: in parallel, collected in marker order.
    let markers: Vec<(usize, usize)> = clusters
        .iter()
        .enumerate()
        .flat_map(|(c, cluster)| cluster.iter().map(move |&m| (c, m)))
        .collect();
    let suspects: Vec<Suspect> = markers
        .par_iter()
        .map(|&(c, m)| {
            let cluster = &clusters[c];
            if cluster.len() >= 3 {
                let mates: Vec<usize> = cluster.iter().copied().filter(|&x| x != m).collect();
                Suspect::new(traj, m, c, mates, hold_mm, stride)
                    .into_iter()
                    .collect::<Vec<_>>()
            } else {
                nearest_clusters(traj, clusters, m, c, stride, HOME_CANDIDATES, 2)
                    .into_iter()
                    .filter_map(|h| Suspect::new(traj, m, h, clusters[h].clone(), hold_mm, stride))
                    .collect()
            }
        })
        .flatten()
        .collect();
    // Pairs of suspects away from different homes in the same frames, most shared first.
    let mut pairs: Vec<(usize, usize, usize)> = Vec::new();
    for (i, x) in suspects.iter().enumerate() {
        for (j, y) in suspects.iter().enumerate().skip(i + 1) {
            if x.marker == y.marker || x.home_cluster == y.home_cluster {
                continue;
            }
            let shared = sorted_overlap(&x.away, &y.away);
            if 2 * shared >= x.away.len().min(y.away.len()) {
                pairs.push((shared, i, j));
            }
        }
    }
    pairs.sort_by(|x, y| y.0.cmp(&x.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    // Each test reads every frame: on a long capture where skin sends many markers away
    // in the same frames, only the pairs sharing the most are tried.
    pairs.truncate(MAX_SWAP_TESTS);
    let mut found: Vec<LabelSwap> = Vec::new();
    for (_, i, j) in pairs {
        let (x, y) = (&suspects[i], &suspects[j]);
        if found
            .iter()
            .any(|s| s.markers.contains(&x.marker) || s.markers.contains(&y.marker))
        {
            continue;
        }
        let test = swap_test(
            traj,
            (x.marker, &x.home),
            (y.marker, &y.home),
            hold_mm,
            stride,
            false,
        );
        let test =
            test.and_then(|w| joined_windows(traj, [x.marker, y.marker], &w, hold_mm, stride));
        if let Some(windows) = test {
            found.push(LabelSwap {
                markers: [x.marker, y.marker],
                frames: windows,
            });
        }
    }
    // A suspect with no suspect partner: the two were close when the tracker confused
    // them, so the partner, sitting where the suspect was, can stay within its own bound
    // (and its home can be unseen in the window). Its partner is the marker of another
    // posable cluster nearest to where the suspect was recorded while away; the swap is
    // proven on the distances that are seen, and by a jump at a window's end. Tested as
    // the pairs are, the longest away first and at most MAX_SWAP_TESTS of them.
    let mut lone: Vec<&Suspect> = suspects.iter().collect();
    lone.sort_by(|x, y| {
        y.away
            .len()
            .cmp(&x.away.len())
            .then(x.marker.cmp(&y.marker))
    });
    for x in lone.into_iter().take(MAX_SWAP_TESTS) {
        let taken = |m: usize| found.iter().any(|s| s.markers.contains(&m));
        if taken(x.marker) {
            continue;
        }
        let nearest = markers
            .iter()
            .filter(|&&(c, m)| c != x.home_cluster && clusters[c].len() >= 3 && !taken(m))
            .filter_map(|&(c, m)| {
                let d: Vec<f64> = x
                    .away
                    .iter()
                    .filter_map(|&f| distance(traj, f, x.marker, m))
                    .collect();
                (!d.is_empty()).then(|| (d.iter().sum::<f64>() / d.len() as f64, c, m))
            })
            .min_by(|p, q| p.0.total_cmp(&q.0).then(p.2.cmp(&q.2)));
        let Some((_, c, y)) = nearest else {
            continue;
        };
        let home_y: Vec<usize> = clusters[c].iter().copied().filter(|&m| m != y).collect();
        let test = swap_test(
            traj,
            (x.marker, &x.home),
            (y, &home_y),
            hold_mm,
            stride,
            true,
        );
        let test = test
            .filter(|w| jumps_at_an_end(traj, [x.marker, y], w, hold_mm))
            .and_then(|w| joined_windows(traj, [x.marker, y], &w, hold_mm, stride));
        if let Some(windows) = test {
            found.push(LabelSwap {
                markers: [x.marker, y],
                frames: windows,
            });
        }
    }
    // Last, exchanges the trajectories show by themselves, whatever the clusters made of
    // them (a swap can pull a marker into its partner's cluster, and then neither is a
    // suspect: robotarm-messy-s9001), where undoing them brings both markers nearer their
    // steadiest partners. They are looked for with the swaps found so far undone, and in
    // rounds again with those undone too: a marker exchanged with a partner seen in two
    // tracks pairs with one track a round (snowman-messy-s20015's M024, exchanged with
    // M029 over 326-397, whose track ends at 348 and goes on in another from 352; the
    // distances found the second track's part). The swaps are undone in the order found.
    let mut undone = if found.is_empty() {
        std::borrow::Cow::Borrowed(traj)
    } else {
        std::borrow::Cow::Owned(untangle(traj, &found))
    };
    for _ in 0..EXCHANGE_ROUNDS {
        let more = exchanges_by_jumps(&undone, hold_mm, |swap| {
            !exchanged_again(&found, swap) && steadier_undone(&undone, swap, hold_mm, stride)
        });
        if more.is_empty() {
            break;
        }
        for swap in more {
            add_in_order(&mut found, swap, traj.frames());
        }
        undone = std::borrow::Cow::Owned(untangle(traj, &found));
    }
    found
}

/// Whether `swap` exchanges again frames an earlier swap of the same two markers
/// exchanged: that puts them back as recorded (random-messy-s10026, exchanged over 14-85,
/// passing close at its middle: the distances found 14-48, and a lone jump at 85 in what
/// that left made 0-85 the exchange, its frames near the close pass no farther off their
/// partners either way).
fn exchanged_again(swaps: &[LabelSwap], swap: &LabelSwap) -> bool {
    swaps.iter().filter(|s| same_pair(s, swap)).any(|s| {
        s.frames
            .iter()
            .any(|a| swap.frames.iter().any(|b| a[0] <= b[1] && b[0] <= a[1]))
    })
}

/// Whether two swaps exchange the same two markers.
fn same_pair(x: &LabelSwap, y: &LabelSwap) -> bool {
    x.markers == y.markers || x.markers == [y.markers[1], y.markers[0]]
}

/// Appends `swap` to `swaps` (undone in order), or adds its frames to the last swap that
/// touches either of its markers when that is the same pair (in other frames: see
/// [`exchanged_again`]): the rest of an exchange a round found in part
/// (snowman-messy-s10006: 220-240 by the distances, 169-219 by the jump at its entry).
/// Frames of one pair exchanged in most of the capture's `frames` are the others
/// exchanged, the two labels read the other way round, and are kept so (labels are as
/// recorded in most frames); all of them is no swap (hexapod-hard-s30045 at 2-3 markers
/// per segment: the distances took 17-341 for an exchange, a round the rest).
fn add_in_order(swaps: &mut Vec<LabelSwap>, swap: LabelSwap, frames: usize) {
    let Some(at) = swaps
        .iter()
        .rposition(|s| s.markers.iter().any(|m| swap.markers.contains(m)))
        .filter(|&at| same_pair(&swaps[at], &swap))
    else {
        swaps.push(swap);
        return;
    };
    let mut exchanged = vec![false; frames];
    for &[first, last] in swaps[at].frames.iter().chain(&swap.frames) {
        exchanged[first.min(frames)..(last + 1).min(frames)].fill(true);
    }
    let most = 2 * exchanged.iter().filter(|&&x| x).count() > frames;
    let kept: Vec<usize> = (0..frames).filter(|&f| exchanged[f] != most).collect();
    if kept.is_empty() {
        swaps.remove(at);
    } else {
        swaps[at].frames = runs(&kept);
    }
}

/// Label exchanges the trajectories show by themselves: two markers that jump in the same
/// step, each landing where the other's path goes on, and (unless the capture ends first)
/// again in a later step, which ends the exchange; undone, both paths run on without a
/// jump. A jump is a step beyond [`jump_bound`]. A tracker that confused
/// two markers far apart does this (the generator's swaps: steps of 95-98 mm against
/// medians near 10); skin and noise move markers smoothly, and a glitch moves one marker,
/// not two onto each other's paths. Two markers that both move fast (over their bound
/// divided by [`EXCHANGE_GAIN`]) exchange too where each lands within its bound on the
/// other's path and that explains the steps that many times better than running on. An
/// exchange where the two passed close shows no jump and is left to the distances
/// ([`swap_test`]). An exchange step may also show on one side only, where the other
/// marker's track ends or starts (an unlabeled capture cuts tracks at every gap): one
/// marker jumps onto the path of a track that has just ended, or leaves its path to a
/// track that starts soon after (robotarm-messy-s20006's M028 carries link 1's marker
/// while link 1's own track ends a frame before and the base marker's path goes on in a
/// track starting 15 frames later). Which frames are exchanged is [`exchanged_frames`]'s
/// choice, and an exchange is kept where `accept` takes it. Each marker is in at most one
/// of them: the pairs with more steps seen on both sides first.
fn exchanges_by_jumps(
    traj: &Trajectories,
    floor_mm: f64,
    accept: impl Fn(&LabelSwap) -> bool,
) -> Vec<LabelSwap> {
    let (frames, markers) = (traj.frames(), traj.markers());
    if frames < 2 {
        return Vec::new();
    }
    let step = |m: usize, f: usize| Some(apart(traj.get(f, m)?, traj.get(f + 1, m)?));
    let bounds: Vec<f64> = (0..markers)
        .map(|m| jump_bound(traj, m, floor_mm))
        .collect();
    // Each pair's exchange steps, in step order, and how many were seen on both sides.
    let mut exchanges: std::collections::BTreeMap<[usize; 2], (Vec<usize>, usize)> =
        std::collections::BTreeMap::new();
    let mut record = |pair: [usize; 2], f: usize, both_sides: bool| {
        let (steps, seen_both) = exchanges.entry(pair).or_default();
        steps.push(f);
        *seen_both += usize::from(both_sides);
    };
    let (mut moved, mut jumping, mut fast) = (Vec::new(), Vec::new(), Vec::new());
    for f in 0..frames - 1 {
        // Each marker's step f → f + 1, once: both kinds of exchange read it.
        moved.clear();
        moved.extend((0..markers).map(|m| step(m, f)));
        jumping.clear();
        jumping.extend((0..markers).filter(|&m| moved[m].is_some_and(|d| d > bounds[m])));
        // Neither need jump where both move fast and the exchange explains the steps
        // EXCHANGE_GAIN times better than none, each landing within its bound of the other's
        // path (snowman-messy-s20020's entry: steps of 49.5 and 36.5 mm against bounds of 50
        // and 49, crossed 10.0 and 10.5 mm).
        fast.clear();
        fast.extend((0..markers).filter(|&m| {
            moved[m].is_some_and(|d| d <= bounds[m] && EXCHANGE_GAIN * d > bounds[m])
        }));
        for (i, &a) in fast.iter().enumerate() {
            for &b in &fast[i + 1..] {
                let (Some(pa), Some(qa), Some(pb), Some(qb)) = (
                    traj.get(f, a),
                    traj.get(f + 1, a),
                    traj.get(f, b),
                    traj.get(f + 1, b),
                ) else {
                    continue;
                };
                let (cross_a, cross_b) = (apart(pa, qb), apart(pb, qa));
                if cross_a <= bounds[a]
                    && cross_b <= bounds[b]
                    && EXCHANGE_GAIN * (cross_a + cross_b) <= apart(pa, qa) + apart(pb, qb)
                {
                    record([a, b], f, true);
                }
            }
        }
        // One of the two must jump; the other may land within its bound when the two were
        // close (snowman-messy-s10005's exit: 54 and 35 mm steps, 44 mm apart, bounds 36
        // and 38 mm), but then the exchange must explain the steps better than no exchange.
        for &a in &jumping {
            for b in (0..markers).filter(|&b| b != a) {
                if jumping.contains(&b) && b < a {
                    continue;
                }
                if let Some(both_sides) = exchange_step(traj, &bounds, f, a, b) {
                    record([a.min(b), a.max(b)], f, both_sides);
                }
            }
        }
    }
    let mut pairs: Vec<([usize; 2], Vec<usize>, usize)> = exchanges
        .into_iter()
        .map(|(pair, (steps, seen_both))| (pair, steps, seen_both))
        .collect();
    pairs.sort_by(|x, y| {
        y.2.cmp(&x.2)
            .then(y.1.len().cmp(&x.1.len()))
            .then(x.0.cmp(&y.0))
    });
    let mut found: Vec<LabelSwap> = Vec::new();
    for (pair, steps, _) in pairs {
        if found
            .iter()
            .any(|s| s.markers.iter().any(|m| pair.contains(m)))
        {
            continue;
        }
        if let Some(windows) = exchanged_frames(traj, &bounds, pair, &steps) {
            let swap = LabelSwap {
                markers: pair,
                frames: windows,
            };
            if accept(&swap) {
                found.push(swap);
            }
        }
    }
    found.sort_by_key(|s| s.markers);
    found
}

/// Whether `a`, seen at frames `f` and `f + 1` and jumping between them, exchanges with
/// `b` in that step: `Some(true)` when `b` is seen on both sides (taken at its last sample
/// up to `f` and its first from `f + 1`, across a gap of up to [`MAX_BRIDGE_FRAMES`]: an
/// exchange can hide in one marker's gap, and a's jump places it) and each lands where the
/// other's path goes on; `Some(false)` when `b` is seen on one side only (its track ends
/// or starts there) and that side's path goes on in `a`'s; each frame bridged allows a
/// typical step more, and the exchange must explain the steps better than none.
fn exchange_step(
    traj: &Trajectories,
    bounds: &[f64],
    f: usize,
    a: usize,
    b: usize,
) -> Option<bool> {
    let (pa, qa) = (traj.get(f, a)?, traj.get(f + 1, a)?);
    let (before, after) = (last_seen(traj, b, f), first_seen(traj, b, f + 1));
    let reach = |m: usize, bridged: usize| bridged_bound(bounds[m], bridged);
    let own = apart(pa, qa);
    match (before, after) {
        (Some((before, pb)), Some((after, qb))) => {
            let (cross_a, cross_b) = (apart(pa, qb), apart(pb, qa));
            (cross_a <= reach(a, after - f - 1)
                && cross_b <= reach(b, f - before)
                && cross_a + cross_b < own + apart(pb, qb))
            .then_some(true)
        }
        // b's track ends: a lands on its path.
        (Some((before, pb)), None) => {
            let cross = apart(pb, qa);
            (cross <= reach(b, f - before) && cross < own).then_some(false)
        }
        // b's track starts: a's path goes on in it.
        (None, Some((after, qb))) => {
            let cross = apart(pa, qb);
            (cross <= reach(a, after - f - 1) && cross < own).then_some(false)
        }
        (None, None) => None,
    }
}

/// Marker `m`'s last sample (frame, position) at or before frame `at`, at most
/// [`MAX_BRIDGE_FRAMES`] before it.
fn last_seen(traj: &Trajectories, m: usize, at: usize) -> Option<(usize, [f64; 3])> {
    (at.saturating_sub(MAX_BRIDGE_FRAMES)..=at)
        .rev()
        .find_map(|g| Some((g, traj.get(g, m)?)))
}

/// Marker `m`'s first sample (frame, position) at or after frame `from`, at most
/// [`MAX_BRIDGE_FRAMES`] after it.
fn first_seen(traj: &Trajectories, m: usize, from: usize) -> Option<(usize, [f64; 3])> {
    let last = (from + MAX_BRIDGE_FRAMES).min(traj.frames().saturating_sub(1));
    (from..=last).find_map(|g| Some((g, traj.get(g, m)?)))
}

/// A marker's jump bound `bound` over a step that bridges `bridged` unseen frames: a
/// typical step more for each (the bound is [`JUMP_FACTOR`] typical steps).
fn bridged_bound(bound: f64, bridged: usize) -> f64 {
    bound * (1.0 + bridged as f64 / JUMP_FACTOR)
}

/// How the labels of a pair may change between frames f and f + 1.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Step {
    /// An exchange step: the labels flip.
    Flips,
    /// A marker runs on without a jump: the labels stay.
    Holds,
    /// Neither marker runs on unbroken (gaps, a track's end or start): a flip may hide
    /// here; `jump` when one marker is seen on both sides and jumps (its partner unseen
    /// on one side, so no exchange could be checked): labels that stay keep the jump.
    Open { jump: bool },
}

/// The frames where `pair`'s labels hold each other's marker, given their exchange
/// `steps`: each exchange step flips the labels, a step where either marker runs on
/// without a jump keeps them, and across a stretch where neither does (both in gaps, or
/// tracks ending and starting) they flip when the markers' last samples before it run on in
/// each other's first after it and not in their own (within [`MAX_BRIDGE_FRAMES`], a
/// typical step more a frame), stay when the reverse, and are free otherwise. Of the
/// labellings that obey these, the one with the fewest frames exchanged where either
/// marker is seen (the labels are as recorded in most frames: with both seen throughout,
/// the minority's runs). `None` when that is half of those frames or more, or no window is
/// [`MIN_SWAPPED_FRAMES`] long.
fn exchanged_frames(
    traj: &Trajectories,
    bounds: &[f64],
    [a, b]: [usize; 2],
    steps: &[usize],
) -> Option<Vec<[usize; 2]>> {
    let frames = traj.frames();
    let runs_on = |m: usize, f: usize| match (traj.get(f, m), traj.get(f + 1, m)) {
        (Some(p), Some(q)) => apart(p, q) <= bounds[m],
        _ => false,
    };
    let mut kinds: Vec<Step> = (0..frames - 1)
        .map(|f| {
            if steps.binary_search(&f).is_ok() {
                Step::Flips
            } else if runs_on(a, f) || runs_on(b, f) {
                Step::Holds
            } else {
                let seen_across =
                    |m: usize| traj.get(f, m).is_some() && traj.get(f + 1, m).is_some();
                Step::Open {
                    jump: seen_across(a) || seen_across(b),
                }
            }
        })
        .collect();
    let reach = |m: usize, bridged: usize| bridged_bound(bounds[m], bridged);
    let mut f = 0;
    while f < kinds.len() {
        if !matches!(kinds[f], Step::Open { .. }) {
            f += 1;
            continue;
        }
        let first = f;
        while f < kinds.len() && matches!(kinds[f], Step::Open { .. }) {
            f += 1;
        }
        // Open steps first..f: each marker's last sample up to `first` and first from `f`.
        let (last, next) = (|m| last_seen(traj, m, first), |m| first_seen(traj, m, f));
        if let (Some(la), Some(lb), Some(na), Some(nb)) = (last(a), last(b), next(a), next(b)) {
            let goes_on = |m: usize, (g, p): (usize, [f64; 3]), (h, q): (usize, [f64; 3])| {
                apart(p, q) <= reach(m, h - g - 1)
            };
            let straight = goes_on(a, la, na) && goes_on(b, lb, nb);
            let crossed = goes_on(a, la, nb) && goes_on(b, lb, na);
            if straight != crossed {
                kinds[first] = if crossed { Step::Flips } else { Step::Holds };
                kinds[first + 1..f].fill(Step::Holds);
            }
        }
    }
    // Fewest frames exchanged with a marker seen, frame by frame over the two labellings;
    // a jump kept costs more than any number of frames.
    let seen = |f: usize| traj.get(f, a).is_some() || traj.get(f, b).is_some();
    let jump_kept = frames;
    let mut cost = [0usize, usize::from(seen(0))];
    // For each frame after the first and each state there, the state the frame before.
    let mut came_from: Vec<[u8; 2]> = Vec::with_capacity(frames - 1);
    for f in 1..frames {
        let mut from = [0u8; 2];
        let mut next = [0usize; 2];
        for s in 0..2 {
            let (prev, extra) = match kinds[f - 1] {
                Step::Flips => (1 - s, 0),
                Step::Holds => (s, 0),
                Step::Open { jump } => {
                    let stay = cost[s] + if jump { jump_kept } else { 0 };
                    if cost[1 - s] < stay {
                        (1 - s, 0)
                    } else {
                        (s, stay - cost[s])
                    }
                }
            };
            from[s] = prev as u8;
            next[s] = cost[prev] + extra + usize::from(s == 1 && seen(f));
        }
        came_from.push(from);
        cost = next;
    }
    let mut state = usize::from(cost[1] < cost[0]);
    let mut exchanged = vec![false; frames];
    for f in (0..frames).rev() {
        exchanged[f] = state == 1;
        if f > 0 {
            state = usize::from(came_from[f - 1][state]);
        }
    }
    let mut windows = runs(&(0..frames).filter(|&f| exchanged[f]).collect::<Vec<_>>());
    let swapped = (0..frames).filter(|&f| exchanged[f] && seen(f)).count();
    windows.retain(|w| w[1] + 1 - w[0] >= MIN_SWAPPED_FRAMES);
    let seen_frames = (0..frames).filter(|&f| seen(f)).count();
    (!windows.is_empty() && 2 * swapped < seen_frames).then_some(windows)
}

/// Whether undoing `swap` leaves its two markers off their usual distances to their
/// steadiest partners in fewer frames than the capture as recorded ([`frames_off`], each
/// judged in the trajectories it is in). Where only one end of an exchange jumps (the
/// other where the two passed close, which no jump shows), the labellings on either side
/// of the jump both join the paths; undoing the wrong side moves a marker off its segment
/// for longer (quadruped-messy-s20007: exchanged over 325-396, entered 13-16 mm apart,
/// left with a 37 mm jump; the frames after the jump, 397-479, are no swap).
fn steadier_undone(traj: &Trajectories, swap: &LabelSwap, hold_mm: f64, stride: usize) -> bool {
    let off = |t: &Trajectories| -> usize {
        swap.markers
            .iter()
            .map(|&m| frames_off(t, m, &swap.markers, hold_mm, stride))
            .sum()
    };
    off(&untangle(traj, std::slice::from_ref(swap))) < off(traj)
}

/// Partners a marker's distances are judged on in [`frames_off`].
const STEADY_PARTNERS: usize = 3;

/// Strided frames where marker `m` is more than `hold_mm` (RMS) off its usual distances to
/// its [`STEADY_PARTNERS`] steadiest partners: the markers (none of `exclude`) seen with it
/// in at least half of its frames whose distance to it deviates least from its median
/// (median absolute deviation: the partners of what `m` carries in most frames).
fn frames_off(
    traj: &Trajectories,
    m: usize,
    exclude: &[usize],
    hold_mm: f64,
    stride: usize,
) -> usize {
    let frames = || (0..traj.frames()).step_by(stride);
    let seen = frames().filter(|&f| traj.get(f, m).is_some()).count();
    let mut steadiness: Vec<(f64, usize)> = (0..traj.markers())
        .filter(|h| !exclude.contains(h))
        .filter_map(|h| {
            let mut d: Vec<f64> = frames().filter_map(|f| distance(traj, f, m, h)).collect();
            if d.is_empty() || 2 * d.len() < seen {
                return None;
            }
            let usual = median(&mut d);
            let mut deviation: Vec<f64> = d.iter().map(|x| (x - usual).abs()).collect();
            Some((median(&mut deviation), h))
        })
        .collect();
    steadiness.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let partners: Vec<usize> = steadiness
        .iter()
        .take(STEADY_PARTNERS)
        .map(|&(_, h)| h)
        .collect();
    let usual = Distances::new(traj, m, &partners, stride);
    frames()
        .filter(|&f| usual.change(traj, f, m).is_some_and(|c| c > hold_mm))
        .count()
}

/// Whether one of `markers` jumps ([`JUMP_FACTOR`] × its median step, and more than
/// `floor_mm`, what skin moves a marker: a still marker's median step is its noise) between
/// two frames within [`JUMP_SLACK_FRAMES`] of the start or the end of one of `windows`.
fn jumps_at_an_end(
    traj: &Trajectories,
    markers: [usize; 2],
    windows: &[[usize; 2]],
    floor_mm: f64,
) -> bool {
    let frames = traj.frames();
    let step = |m: usize, f: usize| Some(apart(traj.get(f, m)?, traj.get(f + 1, m)?));
    markers.iter().any(|&m| {
        let bound = jump_bound(traj, m, floor_mm);
        windows.iter().any(|&[start, end]| {
            // The step into the window (start − 1 → start) and out of it (end → end + 1).
            [start.checked_sub(1), Some(end)]
                .into_iter()
                .flatten()
                .any(|edge| {
                    let lo = edge.saturating_sub(JUMP_SLACK_FRAMES);
                    let hi = (edge + JUMP_SLACK_FRAMES).min(frames.saturating_sub(2));
                    (lo..=hi).filter_map(|f| step(m, f)).any(|d| d > bound)
                })
        })
    })
}

/// `windows` with each end moved to where exchanging `markers` back joins both
/// trajectories again, or `None` when some end cannot be joined: the distances place an
/// end only roughly (skin, gaps; quadruped-messy-s4006: found 270-334, the exchange ends
/// at 341), continuity places it to the frame. Each end is searched within
/// [`JUMP_SLACK_FRAMES`] plus the search stride plus a quarter of its window's length:
/// there each marker's corrected step across it must be within [`JUMP_FACTOR`] × its
/// median step (and `floor_mm`); of those, the one where the corrected steps are shortest
/// against the recorded ones. A real swap's undoing joins each marker's own path again,
/// whether the tracker's exchange jumped (the generator's) or happened where the two
/// passed close; undoing an exchange that never happened puts a jump of the markers'
/// separation into both (hexapod-skin-s5001: a femur and a tibia
/// marker 32-42 mm apart, steps of 4.5 mm, taken for a swap by their distances alone).
/// An end where no step joins stays where it was if some step of its search is unseen
/// (the exchange may hide in a gap).
fn joined_windows(
    traj: &Trajectories,
    [a, b]: [usize; 2],
    windows: &[[usize; 2]],
    floor_mm: f64,
    stride: usize,
) -> Option<Vec<[usize; 2]>> {
    let frames = traj.frames();
    if frames < 2 {
        return Some(windows.to_vec());
    }
    let (bound_a, bound_b) = (jump_bound(traj, a, floor_mm), jump_bound(traj, b, floor_mm));
    // The end placed between frames f and f + 1, `inside_first` when f is in the window (an
    // exit), else f + 1 is (an entry): whether the corrected steps join both paths, and how
    // many mm shorter they are than the recorded ones (what the exchange explains there).
    let placement = |f: usize, inside_first: bool| -> Option<(bool, f64)> {
        let (pa, pb) = (traj.get(f, a)?, traj.get(f, b)?);
        let (qa, qb) = (traj.get(f + 1, a)?, traj.get(f + 1, b)?);
        // Inside the window each label holds the other marker.
        let (step_a, step_b) = if inside_first {
            (apart(pb, qa), apart(pa, qb))
        } else {
            (apart(pa, qb), apart(pb, qa))
        };
        let joined = step_a <= bound_a && step_b <= bound_b;
        let gain = apart(pa, qa) + apart(pb, qb) - step_a - step_b;
        Some((joined, gain))
    };
    let mut joined: Vec<[usize; 2]> = Vec::with_capacity(windows.len());
    for &[start, end] in windows {
        let reach = JUMP_SLACK_FRAMES + stride.max(1) + (end - start + 1) / 4;
        // The best step f → f + 1 for one end within [lo, hi]; the nominal one when none
        // joins but some step is unseen (the exchange may hide in a gap: robotarm-messy-
        // s10019's begins in one); None when every step is seen and none joins. Of the
        // steps that join, the one the exchange explains best: at the true end the
        // recorded steps are the markers' separation and the corrected ones ordinary, on
        // either side of it the other way round (where the two pass close several join).
        let settle = |nominal: usize, lo: usize, hi: usize, inside_first: bool| {
            let mut hidden = false;
            let mut best: Option<(f64, usize, usize)> = None;
            for f in lo..=hi {
                let Some((ok, gain)) = placement(f, inside_first) else {
                    hidden = true;
                    continue;
                };
                let better = |(g, d, _): (f64, usize, usize)| {
                    gain > g || (gain == g && f.abs_diff(nominal) < d)
                };
                if ok && best.is_none_or(better) {
                    best = Some((gain, f.abs_diff(nominal), f));
                }
            }
            match best {
                Some((_, _, f)) => Some(f),
                None if hidden => Some(nominal),
                None => None,
            }
        };
        let start = match start.checked_sub(1) {
            // The entry step f → f + 1 puts the window's first frame at f + 1, before its end.
            Some(edge) => {
                let lo = edge.saturating_sub(reach);
                let hi = (edge + reach).min(end.saturating_sub(1)).min(frames - 2);
                settle(edge, lo, hi.max(lo), false)? + 1
            }
            None => start,
        };
        let end = if end + 1 < frames {
            let lo = end.saturating_sub(reach).max(start);
            let hi = (end + reach).min(frames - 2);
            settle(end, lo, hi.max(lo), true)?
        } else {
            end
        };
        let window = [start, end.max(start)];
        // Moved ends may meet the previous window: one exchange, not two that cancel.
        match joined.last_mut() {
            Some(last) if window[0] <= last[1] + 1 => last[1] = last[1].max(window[1]),
            _ => joined.push(window),
        }
    }
    Some(joined)
}

/// The largest step (mm) between two frames that is no jump for marker `m`:
/// [`JUMP_FACTOR`] × its median frame-to-frame step, and at least `floor_mm` (what skin
/// moves a marker: a still marker's median step is its noise); infinite for a marker never
/// seen in two frames running.
fn jump_bound(traj: &Trajectories, m: usize, floor_mm: f64) -> f64 {
    let mut steps: Vec<f64> = (0..traj.frames().saturating_sub(1))
        .filter_map(|f| Some(apart(traj.get(f, m)?, traj.get(f + 1, m)?)))
        .collect();
    if steps.is_empty() {
        f64::INFINITY
    } else {
        (JUMP_FACTOR * median(&mut steps)).max(floor_mm)
    }
}

/// A marker that leaves its usual distances to a home's markers in a minority of frames.
struct Suspect {
    marker: usize,
    /// Index of the home's cluster.
    home_cluster: usize,
    /// The home's markers (without `marker`).
    home: Vec<usize>,
    /// Frames (ascending, strided) where it is farther than the bound from its usual
    /// distances.
    away: Vec<usize>,
}

impl Suspect {
    fn new(
        traj: &Trajectories,
        marker: usize,
        home_cluster: usize,
        home: Vec<usize>,
        hold_mm: f64,
        stride: usize,
    ) -> Option<Self> {
        let distances = Distances::new(traj, marker, &home, stride);
        let (mut seen, mut away) = (0usize, Vec::new());
        for f in (0..traj.frames()).step_by(stride) {
            let Some(change) = distances.change(traj, f, marker) else {
                continue;
            };
            seen += 1;
            if change > hold_mm {
                away.push(f);
            }
        }
        (away.len() >= MIN_SWAPPED_FRAMES && 2 * away.len() < seen).then_some(Self {
            marker,
            home_cluster,
            home,
            away,
        })
    }
}

/// How many values two ascending lists share.
fn sorted_overlap(x: &[usize], y: &[usize]) -> usize {
    let (mut i, mut j, mut n) = (0, 0, 0);
    while i < x.len() && j < y.len() {
        match x[i].cmp(&y[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                n += 1;
                i += 1;
                j += 1;
            }
        }
    }
    n
}

/// A marker's usual distances to a set of markers (medians over the strided frames both
/// are seen in: a swap is a minority of frames).
struct Distances<'a> {
    home: &'a [usize],
    usual: Vec<Option<f64>>,
}

impl<'a> Distances<'a> {
    fn new(traj: &Trajectories, m: usize, home: &'a [usize], stride: usize) -> Self {
        let usual = home
            .iter()
            .map(|&h| {
                let mut d: Vec<f64> = (0..traj.frames())
                    .step_by(stride)
                    .filter_map(|f| distance(traj, f, m, h))
                    .collect();
                (!d.is_empty()).then(|| median(&mut d))
            })
            .collect();
        Self { home, usual }
    }

    /// RMS change (mm) of `m`'s distances to the home's markers from these usual ones in
    /// frame `f`, over ≥ 2 visible home markers.
    fn change(&self, traj: &Trajectories, f: usize, m: usize) -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0usize);
        for (&h, r) in self.home.iter().zip(&self.usual) {
            if let (Some(d), Some(r)) = (distance(traj, f, m, h), r) {
                sum += (d - r).powi(2);
                n += 1;
            }
        }
        (n >= 2).then(|| (sum / n as f64).sqrt())
    }
}

/// Distance (mm) between markers `m` and `h` in frame `f`, when both are seen.
pub(crate) fn distance(traj: &Trajectories, f: usize, m: usize, h: usize) -> Option<f64> {
    Some(apart(traj.get(f, m)?, traj.get(f, h)?))
}

/// Euclidean distance between two points (mm).
fn apart(p: [f64; 3], q: [f64; 3]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// Whether markers `a` (home `home_a`) and `b` (home `home_b`) are a swap: each at its
/// home's distances in most frames, each at the other's home's distances for the other
/// in the rest. Returns the swap windows. With `partial`, a frame where only some of the
/// four distances are seen counts too, judged on those (a home unseen in the window).
fn swap_test(
    traj: &Trajectories,
    (a, home_a): (usize, &[usize]),
    (b, home_b): (usize, &[usize]),
    hold_mm: f64,
    stride: usize,
    partial: bool,
) -> Option<Vec<[usize; 2]>> {
    let (usual_a, usual_b) = (
        Distances::new(traj, a, home_a, stride),
        Distances::new(traj, b, home_b, stride),
    );
    // Per seen frame: how far each marker is from its home's usual distances, and from
    // its partner's home's usual distances for the partner (at its partner's place, a
    // marker is at the partner's usual distances).
    let changes: Vec<(usize, [Option<f64>; 4])> = (0..traj.frames())
        .map(|f| {
            (
                f,
                [
                    usual_a.change(traj, f, a),
                    usual_b.change(traj, f, b),
                    usual_b.change(traj, f, a),
                    usual_a.change(traj, f, b),
                ],
            )
        })
        .collect();
    // Frames where both markers are judged, for the proof.
    let both: Vec<[f64; 4]> = changes
        .iter()
        .filter_map(|(_, c)| Some([c[0]?, c[1]?, c[2]?, c[3]?]))
        .collect();
    // Skin moves some markers more than others: each marker is held within its own usual
    // change, if that is looser than the common bound.
    let own_bound = |i: usize| {
        let mut v: Vec<f64> = both.iter().map(|c| c[i]).collect();
        if v.is_empty() {
            hold_mm
        } else {
            (OWN_BOUND_FACTOR * median(&mut v)).max(hold_mm)
        }
    };
    let (hold_a, hold_b) = (own_bound(0), own_bound(1));
    // One pass: the proof counts frames where both markers are judged (at home, or each
    // at the other's place and not at home); the windows are runs of frames the exchange
    // explains better than home does (skin moves both alike), judged on whichever marker
    // is seen. Unseen frames inside a run belong to it, and so do frames that do not
    // clearly belong home; runs apart by a few frames that only home explains are one
    // window. A window must hold frames of proof (two markers passing close can look
    // exchanged briefly).
    let (mut at_home, mut swapped, mut partly) = (0usize, 0usize, 0usize);
    let mut windows: Vec<([usize; 2], usize)> = Vec::new();
    let mut home_since_last = usize::MAX;
    for &(f, [ha, hb, xa, xb]) in &changes {
        let ratio = |x: Option<f64>, bound: f64| x.map(|x| x / bound);
        let home = [ratio(ha, hold_a), ratio(hb, hold_b)];
        let away = [ratio(xa, hold_b), ratio(xb, hold_a)];
        let within =
            |ratios: [Option<f64>; 2], bound: f64| ratios.iter().flatten().all(|&x| x <= bound);
        let judged = home.iter().chain(&away).all(Option::is_some);
        // Seen in part: away from home on what is seen, and some exchange to weigh.
        let part = partial
            && !judged
            && home.iter().flatten().any(|&x| x > 1.0)
            && away.iter().any(Option::is_some);
        partly += usize::from(part);
        let proof = (judged || part) && !within(home, 1.0) && within(away, 1.0);
        if judged && within(home, 1.0) {
            at_home += 1;
        }
        swapped += usize::from(proof);
        let (home_cost, away_cost) = match (home[0].zip(away[0]), home[1].zip(away[1])) {
            (Some((h1, x1)), Some((h2, x2))) => (h1 + h2, x1 + x2),
            (Some((h, x)), None) | (None, Some((h, x))) => (h, x),
            (None, None) if part => (
                home.iter().flatten().sum::<f64>(),
                away.iter().flatten().sum::<f64>(),
            ),
            (None, None) => continue,
        };
        if away_cost >= home_cost {
            // Only a frame home explains and the exchange clearly does not (beyond twice
            // the bounds) ends a window: where the two pass close both fit, and skin can
            // leave either just outside its bound.
            if within(home, 1.0) && !within(away, 2.0) {
                home_since_last = home_since_last.saturating_add(1);
            }
            continue;
        }
        match windows.last_mut() {
            Some((w, n)) if home_since_last <= WINDOW_MERGE_FRAMES => {
                w[1] = f;
                *n += usize::from(proof);
            }
            _ => windows.push(([f, f], usize::from(proof))),
        }
        home_since_last = 0;
    }
    let explained = (at_home + swapped) as f64 / (both.len() + partly).max(1) as f64;
    let proven = swapped >= MIN_SWAPPED_FRAMES && at_home > swapped && explained >= MIN_EXPLAINED;
    let windows: Vec<[usize; 2]> = windows
        .into_iter()
        .filter(|&(_, n)| n >= MIN_SWAPPED_FRAMES)
        .map(|(w, _)| w)
        .collect();
    // Proven in scattered frames only, the swap has no window to undo: not reported.
    if !proven || windows.is_empty() {
        return None;
    }
    Some(windows)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two markers moving smoothly (4 mm a frame); with `jump`, the first leaves by 60 mm
    /// for frames 40-59 (a tracker's exchange), else it swerves by as much smoothly.
    fn pair(jump: bool) -> Trajectories {
        let frames = 100;
        let mut positions = Vec::with_capacity(2 * frames);
        for f in 0..frames {
            let x = 4.0 * f as f64;
            let offset = if jump {
                if (40..60).contains(&f) { 60.0 } else { 0.0 }
            } else {
                60.0 * (std::f64::consts::PI * f as f64 / frames as f64).sin()
            };
            positions.push([x, offset, 0.0]);
            positions.push([x, 100.0, 0.0]);
        }
        Trajectories::new(vec!["A".into(), "B".into()], 100.0, 1, frames, positions).expect("valid")
    }

    /// Two markers 4 mm a frame along x, one at y = `y(f)`, the other at −y(f), their
    /// labels exchanged in `exchanged` and both unseen in `unseen`.
    fn exchange(
        y: impl Fn(usize) -> f64,
        exchanged: std::ops::Range<usize>,
        unseen: std::ops::Range<usize>,
    ) -> Trajectories {
        exchange_with_gap(y, exchanged, unseen, 0..0)
    }

    /// As [`exchange`], the second label also unseen in `second_unseen`.
    fn exchange_with_gap(
        y: impl Fn(usize) -> f64,
        exchanged: std::ops::Range<usize>,
        unseen: std::ops::Range<usize>,
        second_unseen: std::ops::Range<usize>,
    ) -> Trajectories {
        let frames = 100;
        let mut positions = Vec::with_capacity(2 * frames);
        for f in 0..frames {
            let x = 4.0 * f as f64;
            let (a, b) = ([x, y(f), 0.0], [x, -y(f), 0.0]);
            let (a, b) = if exchanged.contains(&f) {
                (b, a)
            } else {
                (a, b)
            };
            let hide = |p| {
                if unseen.contains(&f) {
                    mocap_io::MISSING
                } else {
                    p
                }
            };
            positions.push(hide(a));
            positions.push(if second_unseen.contains(&f) {
                mocap_io::MISSING
            } else {
                hide(b)
            });
        }
        Trajectories::new(vec!["A".into(), "B".into()], 100.0, 1, frames, positions).expect("valid")
    }

    /// [`exchanges_by_jumps`] with every exchange accepted (the tests' captures have no
    /// partners to judge them on).
    fn exchanges_by_jumps_all(traj: &Trajectories, floor_mm: f64) -> Vec<LabelSwap> {
        exchanges_by_jumps(traj, floor_mm, |_| true)
    }

    #[test]
    fn undoing_a_swap_must_join_both_paths_again() {
        let far = |_| 30.0;
        // A tracker's exchange 60 mm across: the ends found roughly settle on the jumps.
        let swapped = exchange(far, 40..60, 0..0);
        assert_eq!(
            joined_windows(&swapped, [0, 1], &[[42, 57]], 10.0, 1),
            Some(vec![[40, 59]])
        );
        // No exchange: undoing one would put a 60 mm jump into both paths.
        assert_eq!(
            joined_windows(&exchange(far, 0..0, 0..0), [0, 1], &[[40, 59]], 10.0, 1),
            None
        );
        // An exchange where the two pass close (they cross at frames 40 and 60) joins too.
        let crossing = |f: usize| 20.0 * (std::f64::consts::TAU * f as f64 / 40.0).sin();
        let passed = exchange(crossing, 40..60, 0..0);
        assert!(joined_windows(&passed, [0, 1], &[[40, 59]], 10.0, 1).is_some());
        // An exchange that begins in a gap keeps the end found; its other end still settles.
        let hidden = exchange(far, 40..60, 30..46);
        assert_eq!(
            joined_windows(&hidden, [0, 1], &[[46, 57]], 10.0, 1),
            Some(vec![[46, 59]])
        );
    }

    #[test]
    fn two_markers_jumping_onto_each_others_paths_are_an_exchange() {
        let far = |_| 30.0;
        let found = exchanges_by_jumps_all(&exchange(far, 40..60, 0..0), 10.0);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].markers, [0, 1]);
        assert_eq!(found[0].frames, vec![[40, 59]]);
        // 12 mm apart, neither jumps (steps of 12.6 mm, bounds of 16) but each lands 4 mm
        // from the other's path: an exchange; running side by side, none.
        let close = exchanges_by_jumps_all(&exchange(|_| 6.0, 40..60, 0..0), 10.0);
        assert_eq!(close[0].frames, vec![[40, 59]]);
        assert!(exchanges_by_jumps_all(&exchange(|_| 6.0, 0..0, 0..0), 10.0).is_empty());
        // Smooth paths, and one marker jumping by itself (a glitch), are no exchange.
        assert!(exchanges_by_jumps_all(&exchange(far, 0..0, 0..0), 10.0).is_empty());
        assert!(exchanges_by_jumps_all(&pair(true), 10.0).is_empty());
        // Exchanged for most of the capture: the minority, before and after, is the swap.
        let found = exchanges_by_jumps_all(&exchange(far, 10..90, 0..0), 10.0);
        assert_eq!(found[0].frames, vec![[0, 9], [90, 99]]);
        // An exchange lasting to the end has one exchange step ...
        let found = exchanges_by_jumps_all(&exchange(far, 70..100, 0..0), 10.0);
        assert_eq!(found[0].frames, vec![[70, 99]]);
        // The second label unseen across the exchange's first step: the first's jump
        // places it.
        let bridged = exchange_with_gap(far, 40..60, 0..0, 35..45);
        assert_eq!(
            exchanges_by_jumps_all(&bridged, 10.0)[0].frames,
            vec![[40, 59]]
        );
        // An exit hidden in a gap of both: it is there when exchanging back joins both
        // paths across the gap, and not when they run on as recorded.
        let hidden_exit = exchanges_by_jumps_all(&exchange(far, 70..85, 85..90), 10.0);
        assert_eq!(hidden_exit[0].frames, vec![[70, 84]]);
        let no_exit = exchanges_by_jumps_all(&exchange(far, 70..100, 85..90), 10.0);
        assert_eq!(no_exit[0].frames, vec![[70, 99]]);
        // ... and half the capture or more is not a minority.
        assert!(exchanges_by_jumps_all(&exchange(far, 50..100, 0..0), 10.0).is_empty());
    }

    #[test]
    fn an_exchange_shows_where_a_track_ends_or_starts() {
        let far = |_| 30.0;
        // The second label unseen from before the exchange to after it, longer than a
        // bridge: the first jumps onto its path as its track ends, and back onto its own
        // as the second's track starts again.
        let long_gap = exchange_with_gap(far, 40..60, 0..0, 38..65);
        let found = exchanges_by_jumps_all(&long_gap, 10.0);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].frames, vec![[40, 59]]);
        // An exchange to the end with a track that starts late: the first label runs on
        // unbroken before, so the exchange is the frames after the step, not before.
        let late = exchange_with_gap(far, 70..100, 0..0, 0..50);
        assert_eq!(
            exchanges_by_jumps_all(&late, 10.0)[0].frames,
            vec![[70, 99]]
        );
        // The exit where the second label is in a gap to the end: the first's jump back
        // ends the exchange, though the frames before the entry are fewer.
        let exit_unseen = exchange_with_gap(far, 30..75, 0..0, 50..100);
        assert_eq!(
            exchanges_by_jumps_all(&exit_unseen, 10.0)[0].frames,
            vec![[30, 74]]
        );
        // Both markers jump away and back while the second's track ends, the first landing
        // off the second's path: no exchange.
        let moved = |f: usize| if (40..60).contains(&f) { 90.0 } else { 30.0 };
        let glitch = exchange_with_gap(moved, 0..0, 0..0, 40..100);
        assert!(exchanges_by_jumps_all(&glitch, 10.0).is_empty());
    }

    #[test]
    fn the_rest_of_an_exchange_joins_its_swap_in_order() {
        let swap = |markers: [usize; 2], frames: [usize; 2]| LabelSwap {
            markers,
            frames: vec![frames],
        };
        let mut swaps = vec![swap([3, 5], [220, 240])];
        add_in_order(&mut swaps, swap([5, 3], [169, 219]), 480);
        assert_eq!(swaps, vec![swap([3, 5], [169, 240])]);
        // Frames already exchanged are no rest of it: exchanging them again undoes them.
        assert!(exchanged_again(&swaps, &swap([5, 3], [200, 260])));
        assert!(!exchanged_again(&swaps, &swap([5, 3], [241, 260])));
        assert!(!exchanged_again(&swaps, &swap([5, 7], [200, 260])));
        // After another swap of one of its markers, it keeps its place in the order.
        let mut swaps = vec![swap([3, 5], [220, 240]), swap([5, 7], [300, 320])];
        add_in_order(&mut swaps, swap([3, 5], [100, 150]), 480);
        assert_eq!(swaps.len(), 3);
        // The rest of the capture: the two labels read the other way round, no swap.
        let mut swaps = vec![swap([3, 5], [17, 341])];
        let rest = LabelSwap {
            markers: [3, 5],
            frames: vec![[0, 16], [342, 479]],
        };
        add_in_order(&mut swaps, rest, 480);
        assert!(swaps.is_empty());
        // Most of it: the frames left out are the swap.
        let mut swaps = vec![swap([3, 5], [17, 341])];
        add_in_order(&mut swaps, swap([3, 5], [342, 400]), 480);
        assert_eq!(
            swaps,
            vec![LabelSwap {
                markers: [3, 5],
                frames: vec![[0, 16], [401, 479]]
            }]
        );
    }

    /// Two bodies of four markers, 4 mm a frame along x, the second (markers 4-7) swinging
    /// 40 mm in y against the first; markers 0 and 4 exchanged in `exchanged`.
    fn two_bodies(exchanged: std::ops::Range<usize>) -> Trajectories {
        let shape = [
            [0.0, 0.0, 0.0],
            [20.0, 0.0, 10.0],
            [10.0, 15.0, -10.0],
            [-5.0, 10.0, 20.0],
        ];
        let frames = 100;
        let mut positions = Vec::with_capacity(8 * frames);
        for f in 0..frames {
            let x = 4.0 * f as f64;
            let swing = 40.0 * (std::f64::consts::TAU * f as f64 / 50.0).sin();
            let mut row: Vec<[f64; 3]> = [(50.0, 0.0), (-50.0, swing)]
                .iter()
                .flat_map(|&(y, s)| shape.iter().map(move |p| [x + p[0], y + s + p[1], p[2]]))
                .collect();
            if exchanged.contains(&f) {
                row.swap(0, 4);
            }
            positions.extend(row);
        }
        let labels = (0..8).map(|m| format!("M{m}")).collect();
        Trajectories::new(labels, 100.0, 1, frames, positions).expect("valid")
    }

    #[test]
    fn undoing_the_wrong_side_of_an_exchange_is_refused() {
        let swapped = two_bodies(40..60);
        let swap = |frames: [usize; 2]| LabelSwap {
            markers: [0, 4],
            frames: vec![frames],
        };
        assert!(steadier_undone(&swapped, &swap([40, 59]), 5.0, 1));
        // The frames after the exchange (as if its entry had shown no jump): undoing them
        // moves both markers off their bodies for longer.
        assert!(!steadier_undone(&swapped, &swap([60, 99]), 5.0, 1));
        // Nothing exchanged: undoing anything moves markers off their bodies.
        assert!(!steadier_undone(&two_bodies(0..0), &swap([40, 59]), 5.0, 1));
    }

    #[test]
    fn an_exchange_jumps_at_its_window_and_skin_does_not() {
        assert!(jumps_at_an_end(&pair(true), [0, 1], &[[40, 59]], 10.0));
        // Off by the slack: still found.
        assert!(jumps_at_an_end(&pair(true), [0, 1], &[[42, 57]], 10.0));
        assert!(!jumps_at_an_end(&pair(true), [0, 1], &[[20, 30]], 10.0));
        assert!(!jumps_at_an_end(&pair(false), [0, 1], &[[40, 59]], 10.0));
        // A jump no larger than skin moves a marker is none.
        assert!(!jumps_at_an_end(&pair(true), [0, 1], &[[40, 59]], 80.0));
    }
}
