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
//! are a swap whatever the clusters made of them ([`exchanges_by_jumps`]).

use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::fitsplit::median;
use crate::reassign::nearest_clusters;
use crate::segmentation::LabelSwap;

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
    // suspect: robotarm-messy-s9001).
    let taken: Vec<usize> = found.iter().flat_map(|s| s.markers).collect();
    found.extend(exchanges_by_jumps(traj, hold_mm, &taken));
    found
}

/// Label exchanges the trajectories show by themselves: two markers that jump in the same
/// step, each landing where the other's path goes on, and (unless the capture ends first)
/// again in a later step, which ends the exchange; undone, both paths run on without a
/// jump. A jump is a step beyond [`jump_bound`]. A tracker that confused
/// two markers far apart does this (the generator's swaps: steps of 95-98 mm against
/// medians near 10); skin and noise move markers smoothly, and a glitch moves one marker,
/// not two onto each other's paths. An exchange where the two passed close shows no jump
/// and is left to the distances ([`swap_test`]). Each exchange step flips the labels, and
/// the labels are as recorded in most frames: with both markers seen throughout, the
/// windows are the runs in the minority state; with gaps, where a step may hide, the
/// steps pair up from the start. Windows hold under half of the capture, each at least
/// [`MIN_SWAPPED_FRAMES`] long; markers in `taken` are left alone, and each marker is in
/// at most one swap.
fn exchanges_by_jumps(traj: &Trajectories, floor_mm: f64, taken: &[usize]) -> Vec<LabelSwap> {
    let (frames, markers) = (traj.frames(), traj.markers());
    if frames < 2 {
        return Vec::new();
    }
    let step = |m: usize, f: usize| Some(apart(traj.get(f, m)?, traj.get(f + 1, m)?));
    let bounds: Vec<f64> = (0..markers)
        .map(|m| jump_bound(traj, m, floor_mm))
        .collect();
    // Each pair's exchange steps, in step order: both jump, each onto the other's path.
    let mut exchanges: std::collections::BTreeMap<[usize; 2], Vec<usize>> =
        std::collections::BTreeMap::new();
    let mut jumping = Vec::new();
    for f in 0..frames - 1 {
        jumping.clear();
        jumping.extend(
            (0..markers)
                .filter(|m| !taken.contains(m))
                .filter(|&m| step(m, f).is_some_and(|d| d > bounds[m])),
        );
        // One of the two must jump; the other may land within its bound when the two were
        // close (snowman-messy-s10005's exit: 54 and 35 mm steps, 44 mm apart, bounds 36
        // and 38 mm), but then the exchange must explain the steps better than no exchange.
        for &a in &jumping {
            for b in (0..markers).filter(|&b| b != a && !taken.contains(&b)) {
                if jumping.contains(&b) && b < a {
                    continue;
                }
                // a is seen across the step (it jumped); b is taken at its last sample up to
                // f and its first from f + 1, across a gap of up to MAX_BRIDGE_FRAMES (an
                // exchange can hide in one marker's gap, and a's jump places it), each
                // frame bridged allowing a typical step more.
                let crossed = || -> Option<bool> {
                    let (pa, qa) = (traj.get(f, a)?, traj.get(f + 1, a)?);
                    let (before, pb) = (f.saturating_sub(MAX_BRIDGE_FRAMES)..=f)
                        .rev()
                        .find_map(|g| Some((g, traj.get(g, b)?)))?;
                    let (after, qb) = (f + 1..=(f + 1 + MAX_BRIDGE_FRAMES).min(frames - 1))
                        .find_map(|g| Some((g, traj.get(g, b)?)))?;
                    let per_frame = |m: usize| bounds[m] / JUMP_FACTOR;
                    let (cross_a, cross_b) = (apart(pa, qb), apart(pb, qa));
                    Some(
                        cross_a <= bounds[a] + per_frame(a) * (after - f - 1) as f64
                            && cross_b <= bounds[b] + per_frame(b) * (f - before) as f64
                            && cross_a + cross_b < apart(pa, qa) + apart(pb, qb),
                    )
                };
                if crossed() == Some(true) {
                    exchanges.entry([a.min(b), a.max(b)]).or_default().push(f);
                }
            }
        }
    }
    let mut found: Vec<LabelSwap> = Vec::new();
    for (pair, steps) in exchanges {
        if found
            .iter()
            .any(|s| s.markers.iter().any(|m| pair.contains(m)))
        {
            continue;
        }
        // Each exchange step flips the labels, and the labels are as recorded in most
        // frames. Where both markers are seen in every frame no exchange step can hide, so
        // the runs between steps alternate and the minority's runs are the windows (a swap
        // lasting to the capture's end has one step: robotarm-messy-s25). Otherwise steps
        // pair up from the start, each pair a window, and a step left over says nothing
        // (its partner may be in a gap: quadruped-messy-s52's exit is).
        let length = |w: &[usize; 2]| w[1] + 1 - w[0];
        let always_seen =
            (0..frames).all(|f| traj.get(f, pair[0]).is_some() && traj.get(f, pair[1]).is_some());
        let candidates: Vec<[usize; 2]> = if always_seen {
            let mut runs: [Vec<[usize; 2]>; 2] = [Vec::new(), Vec::new()];
            let mut first = 0;
            for (k, &f) in steps.iter().chain([&(frames - 1)]).enumerate() {
                runs[k % 2].push([first, f]);
                first = f + 1;
            }
            let total = |r: &[[usize; 2]]| r.iter().map(length).sum::<usize>();
            let minority = usize::from(total(&runs[1]) <= total(&runs[0]));
            runs[minority].clone()
        } else {
            steps.chunks_exact(2).map(|w| [w[0] + 1, w[1]]).collect()
        };
        let swapped: usize = candidates.iter().map(length).sum();
        let windows: Vec<[usize; 2]> = candidates
            .into_iter()
            .filter(|w| length(w) >= MIN_SWAPPED_FRAMES)
            .collect();
        if !windows.is_empty() && 2 * swapped < frames {
            found.push(LabelSwap {
                markers: pair,
                frames: windows,
            });
        }
    }
    found
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
        let found = exchanges_by_jumps(&exchange(far, 40..60, 0..0), 10.0, &[]);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].markers, [0, 1]);
        assert_eq!(found[0].frames, vec![[40, 59]]);
        // A marker already in a swap is left alone.
        assert!(exchanges_by_jumps(&exchange(far, 40..60, 0..0), 10.0, &[1]).is_empty());
        // Smooth paths, and one marker jumping by itself (a glitch), are no exchange.
        assert!(exchanges_by_jumps(&exchange(far, 0..0, 0..0), 10.0, &[]).is_empty());
        assert!(exchanges_by_jumps(&pair(true), 10.0, &[]).is_empty());
        // Exchanged for most of the capture: the minority, before and after, is the swap.
        let found = exchanges_by_jumps(&exchange(far, 10..90, 0..0), 10.0, &[]);
        assert_eq!(found[0].frames, vec![[0, 9], [90, 99]]);
        // An exchange lasting to the end has one exchange step ...
        let found = exchanges_by_jumps(&exchange(far, 70..100, 0..0), 10.0, &[]);
        assert_eq!(found[0].frames, vec![[70, 99]]);
        // The second label unseen across the exchange's first step: the first's jump
        // places it.
        let bridged = exchange_with_gap(far, 40..60, 0..0, 35..45);
        assert_eq!(
            exchanges_by_jumps(&bridged, 10.0, &[])[0].frames,
            vec![[40, 59]]
        );
        // ... which says nothing when the exchange's other end may hide in a gap.
        assert!(exchanges_by_jumps(&exchange(far, 70..85, 85..90), 10.0, &[]).is_empty());
        // ... and half the capture or more is not a minority.
        assert!(exchanges_by_jumps(&exchange(far, 50..100, 0..0), 10.0, &[]).is_empty());
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
