//! Joining the pieces of one marker's trajectory across its gaps.
//!
//! An unlabeled capture starts a new track at every occlusion (Motive's `Unlabeled 1036`,
//! a Vicon reconstruction's `*12`), so one marker comes as pieces that later steps would
//! read as different markers, and pieces of one segment that never share a frame could
//! never be grouped. A piece that ends at frame t₁ continues as the piece that starts at t₂
//! (up to [`MAX_GAP_SECONDS`] later) where the marker would be if it had moved with the
//! markers around it: the rigid motion that carries its steady neighbours from t₁ to t₂
//! (at least [`MIN_PARTNERS`], each visible at both frames and keeping its distance to the
//! ending piece and to the starting one within [`STEADY_SHARE`] of the marker spacing over
//! [`WINDOW_SECONDS`]) carries its last position to within [`MATCH_SHARE`] of the way to
//! the nearest other marker (at either end, and at most of the capture's marker spacing)
//! of the new piece's first; no rival lands within twice that error (a rival being any
//! other piece but one that starts after the chosen one ends, which may be the same marker
//! again), and neither piece has a better partner. Joining repeats on the joined tracks (longer tracks have more steady
//! neighbours) until nothing joins. Skin turns a segment's markers together over a gap far
//! less than the spacing between two markers: in a probe on quadruped-hard cut at every
//! gap, the true continuation landed 5 mm away (median), the nearest wrong one 39 mm, at
//! 46 mm marker spacing.
//!
//! Where the carry leaves a piece apart (fewer than three steady neighbours at either end,
//! a segment of two or three markers with one hidden; or neighbours steady over the window
//! that turn apart across the gap, at two or three markers per segment often across a
//! joint: snowman-hard-s20032 at `--markers 2:3`, carried 69 mm off, its own motion
//! 1.5 mm), a gap of up to [`BRIDGE_SECONDS`] is bridged by the pieces' own motion: a
//! straight line in time over each one's [`MOTION_SECONDS`] at the gap, relative to the
//! neighbour steadiest with both (absolute when none is), must meet the other's at the
//! gap's middle within the same [`MATCH_SHARE`] of the way to the nearest other marker, no
//! rival meeting within twice that, each the other's best. Where two markers sit close that
//! bound is tighter than the lines' own miss, so where some rival met them the lines may
//! also join within [`RIVAL_SHARE`] of the nearest rival's miss, up to [`MATCH_SHARE`] of
//! the marker spacing (human-hard-s20020 at `--markers 2:3`: M035's lines meet 28.9 mm
//! apart, its nearest marker 11.6 mm away, the rivals' lines 554 and 461 mm; a pair with
//! no rival at all keeps the nearest-marker bound, as quadruped-hard-s30023's M025~1 and
//! M048~1, two markers' pieces meeting 22.6 mm apart alone). Either way the lines meet
//! within [`CARRIED_FACTOR`] times the way they were carried to meet, plus
//! [`LINE_NOISE_MM`]: a line bends off its marker's path by no more than it travels. Lines
//! from both sides meeting in the middle miss by the motion's change of acceleration only,
//! not by the acceleration itself; relative to a neighbour on the segment, by its turning
//! alone (the hard preset unlabeled at 2–3 markers per segment, seeds 20001..20010, pairs
//! the carry could not judge, each the other's best: relative lines joined 46 of one
//! marker and refused 1, absolute lines joined 34 and refused 31; both refused the 6 pairs
//! of two markers).
//!
//! It does not guess where the neighbours are not steady or not seen at both ends and the
//! gap is longer than the bridge, or join tracks that share a frame.

use crate::eigen4::{horn_matrix, largest_eigenpair4, rotation_matrix};
use crate::trajectories::distance;
use crate::{Capture, MISSING, Trajectories, is_present};

/// Longest gap a piece is followed across, in seconds.
const MAX_GAP_SECONDS: f64 = 1.0;
/// Seconds at each piece's end over which a neighbour's distance must be steady: long
/// enough that a neighbour on another segment has turned about their joint.
const WINDOW_SECONDS: f64 = 0.5;
/// Steady neighbours needed to carry a piece across its gap.
const MIN_PARTNERS: usize = 3;
/// Steady neighbours used at most (the steadiest).
const MAX_PARTNERS: usize = 6;
/// A neighbour is steady when its distance's standard deviation over the window is within
/// this share of the capture's marker spacing.
const STEADY_SHARE: f64 = 0.2;
/// A continuation lands within this share of the distance from the piece to its nearest
/// other marker (capped at the marker spacing) of where it was carried.
const MATCH_SHARE: f64 = 0.5;
/// Where a bridge's lines meet farther apart than [`MATCH_SHARE`] of the way to the
/// nearest marker, they may still join within this share of the nearest rival's miss (and
/// [`MATCH_SHARE`] of the marker spacing).
const RIVAL_SHARE: f64 = 1.0 / 3.0;
/// A bridge's two lines meet within this many times the way they were carried to meet,
/// plus [`LINE_NOISE_MM`].
const CARRIED_FACTOR: f64 = 2.0;
/// How far a line's place at the gap may be off by the positions' noise alone (mm; the
/// hard preset's noise is 1 mm per coordinate).
const LINE_NOISE_MM: f64 = 2.0;

/// Where each piece starts and ends: first and last frame seen.
#[derive(Clone, Copy)]
struct Span {
    first: usize,
    last: usize,
}

/// Each track's steady neighbours at one of its ends: (neighbour, spread) for every track
/// seen at that end frame whose distance's standard deviation over the window is within
/// `limit`, ascending by neighbour.
fn steady_neighbours(
    t: &Trajectories,
    k: usize,
    end: usize,
    window: std::ops::RangeInclusive<usize>,
    limit: f64,
) -> Vec<(usize, f64)> {
    let row = t.frame(end);
    (0..t.markers())
        .filter(|&r| r != k && is_present(row[r]))
        .map(|r| (r, distance_spread(t, k, r, window.clone())))
        .filter(|&(_, spread)| spread <= limit)
        .collect()
}

/// For each track, the track that continues it (`None` at its true end), as decided by the
/// rule in the module docs.
fn continuations(t: &Trajectories) -> Vec<Option<usize>> {
    let (m, frames) = (t.markers(), t.frames());
    let mut next = vec![None; m];
    let Some(spacing) = t.marker_spacing_mm() else {
        return next;
    };
    let spans: Vec<Option<Span>> = (0..m)
        .map(|k| {
            let first = (0..frames).find(|&f| t.get(f, k).is_some())?;
            let last = (0..frames).rev().find(|&f| t.get(f, k).is_some())?;
            Some(Span { first, last })
        })
        .collect();
    let max_gap = (MAX_GAP_SECONDS * t.frame_rate()).round().max(1.0) as usize;
    let limit = STEADY_SHARE * spacing;
    // Half the way to the nearest other marker, capped at the capture's spacing: where two
    // markers sit close, a piece landing near one of them is no evidence for the other.
    let nearest = |k: usize, f: usize| {
        let row = t.frame(f);
        (0..m)
            .filter(|&r| r != k && is_present(row[r]))
            .map(|r| distance(row[k], row[r]))
            .fold(spacing, f64::min)
    };
    let window = ((WINDOW_SECONDS * t.frame_rate()).round() as usize).max(3);
    // A track can only be continued if it ends before the last frame, and only continue
    // another if it starts after the first: the neighbours at those ends, once each.
    let ending: Vec<Vec<(usize, f64)>> = (0..m)
        .map(|k| match spans[k] {
            Some(s) if s.last + 1 < frames => steady_neighbours(
                t,
                k,
                s.last,
                s.last.saturating_sub(window - 1)..=s.last,
                limit,
            ),
            _ => Vec::new(),
        })
        .collect();
    let starting: Vec<Vec<(usize, f64)>> = (0..m)
        .map(|k| match spans[k] {
            Some(s) if s.first > 0 => steady_neighbours(
                t,
                k,
                s.first,
                s.first..=(s.first + window - 1).min(frames - 1),
                limit,
            ),
            _ => Vec::new(),
        })
        .collect();
    // Every (ending, starting, error) that could be carried.
    let mut carried: Vec<(usize, usize, f64)> = Vec::new();
    for a in (0..m).filter(|&a| ending[a].len() >= MIN_PARTNERS) {
        let Some(sa) = spans[a] else { continue };
        for b in (0..m).filter(|&b| starting[b].len() >= MIN_PARTNERS) {
            let Some(sb) = spans[b] else { continue };
            if b == a || sb.first <= sa.last || sb.first - sa.last > max_gap {
                continue;
            }
            if let Some(error) = carry(t, (a, sa.last, &ending[a]), (b, sb.first, &starting[b])) {
                carried.push((a, b, error));
            }
        }
    }
    let choices = Choices::of(&carried, &spans);
    for (a, continued_by) in next.iter_mut().enumerate() {
        *continued_by = choices.clear_best(a, &spans, &nearest, None);
    }
    bridge_by_motion(
        t,
        &spans,
        (&ending, &starting),
        (&nearest, spacing),
        &mut next,
    );
    next
}

/// Longest gap a piece's own motion bridges, in seconds.
const BRIDGE_SECONDS: f64 = 0.2;
/// Seconds at each piece's end its motion (a straight line in time) is fitted over.
const MOTION_SECONDS: f64 = 0.1;

/// A piece's motion at one end: a straight line in time fitted over its end frames.
#[derive(Clone, Copy)]
struct EndMotion {
    /// Mean frame of the fitted samples.
    frame: f64,
    /// Mean position there (mm).
    at: [f64; 3],
    /// Velocity (mm per frame).
    velocity: [f64; 3],
}

impl EndMotion {
    /// The line fitted to `sample`'s positions over `frames` (≥ 3 seen), `None` otherwise.
    fn fit(
        frames: std::ops::RangeInclusive<usize>,
        sample: impl Fn(usize) -> Option<[f64; 3]>,
    ) -> Option<Self> {
        let (mut n, mut sf, mut sx) = (0.0, 0.0, [0.0; 3]);
        for f in frames.clone() {
            if let Some(p) = sample(f) {
                n += 1.0;
                sf += f as f64;
                for i in 0..3 {
                    sx[i] += p[i];
                }
            }
        }
        if n < 3.0 {
            return None;
        }
        let (frame, at) = (sf / n, sx.map(|x| x / n));
        let (mut sff, mut sfx) = (0.0, [0.0; 3]);
        for f in frames {
            if let Some(p) = sample(f) {
                let df = f as f64 - frame;
                sff += df * df;
                for i in 0..3 {
                    sfx[i] += df * (p[i] - at[i]);
                }
            }
        }
        (sff > 0.0).then(|| EndMotion {
            frame,
            at,
            velocity: sfx.map(|x| x / sff),
        })
    }

    /// Where the line puts the marker at `frame`.
    fn at_frame(&self, frame: f64) -> [f64; 3] {
        std::array::from_fn(|i| self.at[i] + self.velocity[i] * (frame - self.frame))
    }
}

/// Each track's steady neighbours at one of its ends, (neighbour, spread) ascending by
/// neighbour (see [`steady_neighbours`]).
type SteadyNeighbours = [Vec<(usize, f64)>];

/// Joins, into `next`, pieces the carry left apart across a gap of up to
/// [`BRIDGE_SECONDS`] where each one's own motion meets the other's (module docs); the
/// tracks' steady neighbours at their ends and starts are `ending` and `starting`.
fn bridge_by_motion(
    t: &Trajectories,
    spans: &[Option<Span>],
    (ending, starting): (&SteadyNeighbours, &SteadyNeighbours),
    (nearest, spacing): (&impl Fn(usize, usize) -> f64, f64),
    next: &mut [Option<usize>],
) {
    let (m, frames) = (t.markers(), t.frames());
    let bridge = (BRIDGE_SECONDS * t.frame_rate()).round() as usize;
    let k = ((MOTION_SECONDS * t.frame_rate()).round() as usize).max(3);
    // `track`'s line over its end (or start) window, relative to track `r` when given.
    let line = |track: usize, window: std::ops::RangeInclusive<usize>, r: Option<usize>| {
        EndMotion::fit(window, |f| {
            let p = t.get(f, track)?;
            match r {
                None => Some(p),
                Some(r) => t.get(f, r).map(|q| std::array::from_fn(|i| p[i] - q[i])),
            }
        })
    };
    // Every (ending, starting, error) a short gap leaves: where the two lines meet apart,
    // relative to the neighbour steadiest with both ends when there is one (a segment's
    // markers turn about each other far slower than they travel).
    let mut met: Vec<(usize, usize, f64)> = Vec::new();
    // How far the two lines were carried to meet, indexed like `met`.
    let mut reach: Vec<f64> = Vec::new();
    for a in 0..m {
        let Some(sa) = spans[a].filter(|s| s.last + 1 < frames) else {
            continue;
        };
        for b in 0..m {
            let Some(sb) = spans[b].filter(|s| s.first > 0) else {
                continue;
            };
            if b == a || sb.first <= sa.last || sb.first - sa.last > bridge {
                continue;
            }
            let partner = ending[a]
                .iter()
                .filter_map(|&(r, e)| {
                    let (_, s) = starting[b].iter().find(|&&(q, _)| q == r)?;
                    (r != b).then_some((e.max(*s), r))
                })
                .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))
                .map(|(_, r)| r);
            let (Some(ea), Some(eb)) = (
                line(a, sa.last.saturating_sub(k - 1)..=sa.last, partner),
                line(b, sb.first..=(sb.first + k - 1).min(frames - 1), partner),
            ) else {
                continue;
            };
            let meet = 0.5 * (sa.last + sb.first) as f64;
            met.push((a, b, distance(ea.at_frame(meet), eb.at_frame(meet))));
            reach.push(
                distance(ea.at_frame(meet), ea.at_frame(sa.last as f64))
                    + distance(eb.at_frame(meet), eb.at_frame(sb.first as f64)),
            );
        }
    }
    let mut continued = vec![false; m];
    for b in next.iter().flatten() {
        continued[*b] = true;
    }
    let choices = Choices::of(&met, spans);
    // A line bends away from its marker's path by no more than it was carried, so two
    // lines that miss by more than that met by chance (a real capture, c3d.org's Dance cut
    // at gaps: two markers' pieces a frame apart, the lines 54 mm apart, carried 0.4 mm in
    // all; hexapod-hard-s20001 unlabeled: M081~1 and M033~1, 16.7 mm apart, carried 3.5
    // mm, where the same marker's pieces missed by at most 2.95 × the way: the hard preset
    // unlabeled, seeds 20001..20025, 1,381 joins at 3–6 and 2–3 markers per segment).
    // `met` is in (ending, starting) order, as the loops made it.
    let most = |a: usize, b: usize| {
        met.binary_search_by(|&(x, y, _)| (x, y).cmp(&(a, b)))
            .map_or(0.0, |i| {
                (CARRIED_FACTOR * reach[i] + LINE_NOISE_MM).min(MATCH_SHARE * spacing)
            })
    };
    for (a, continued_by) in next.iter_mut().enumerate() {
        // Only pieces the carry left apart; any piece is a rival.
        if let Some(b) = choices.clear_best(a, spans, nearest, Some(&most))
            && continued_by.is_none()
            && !continued[b]
        {
            *continued_by = Some(b);
            continued[b] = true;
        }
    }
}

/// Each track's best partner on either side among (ending, starting, error) pairs, and
/// the least error of any rival: another partner, but for a piece that starts after the
/// chosen one ends (or ends before it starts), which may be the same marker again.
struct Choices {
    best_next: Vec<Option<(usize, f64)>>,
    best_previous: Vec<Option<(usize, f64)>>,
    rival_next: Vec<f64>,
    rival_previous: Vec<f64>,
}

impl Choices {
    /// The best partners and their rivals among `pairs`, for tracks spanning `spans`.
    fn of(pairs: &[(usize, usize, f64)], spans: &[Option<Span>]) -> Self {
        let m = spans.len();
        let after = |x: usize, y: usize| match (spans[x], spans[y]) {
            (Some(p), Some(q)) => p.first > q.last,
            _ => false,
        };
        let mut best_next: Vec<Option<(usize, f64)>> = vec![None; m];
        let mut best_previous: Vec<Option<(usize, f64)>> = vec![None; m];
        for &(a, b, error) in pairs {
            if best_next[a].is_none_or(|(_, e)| error < e) {
                best_next[a] = Some((b, error));
            }
            if best_previous[b].is_none_or(|(_, e)| error < e) {
                best_previous[b] = Some((a, error));
            }
        }
        let mut rival_next = vec![f64::INFINITY; m];
        let mut rival_previous = vec![f64::INFINITY; m];
        for &(a, b, error) in pairs {
            if let Some((chosen, _)) = best_next[a]
                && chosen != b
                && !after(b, chosen)
            {
                rival_next[a] = rival_next[a].min(error);
            }
            if let Some((chosen, _)) = best_previous[b]
                && chosen != a
                && !after(chosen, a)
            {
                rival_previous[b] = rival_previous[b].min(error);
            }
        }
        Choices {
            best_next,
            best_previous,
            rival_next,
            rival_previous,
        }
    }

    /// What continues track `a`: its best partner when `a` is that one's best too, within
    /// [`MATCH_SHARE`] of the way to the nearest other marker at either end, clearly
    /// better than any rival on either side, and not within a quarter of that tolerance
    /// either (two pieces in one place are a guess); with `most`, never beyond `most` of
    /// the pair, and with a rival, up to it within [`RIVAL_SHARE`] of the nearest rival's
    /// error.
    fn clear_best(
        &self,
        a: usize,
        spans: &[Option<Span>],
        nearest: &impl Fn(usize, usize) -> f64,
        most: Option<&dyn Fn(usize, usize) -> f64>,
    ) -> Option<usize> {
        let (b, error) = self.best_next[a]?;
        let (sa, sb) = (spans[a]?, spans[b]?);
        let mut tolerance = MATCH_SHARE * nearest(a, sa.last).min(nearest(b, sb.first));
        if let Some(most) = most.map(|most| most(a, b)) {
            let rival = self.rival_next[a].min(self.rival_previous[b]);
            if rival.is_finite() {
                tolerance = tolerance.max(RIVAL_SHARE * rival);
            }
            tolerance = tolerance.min(most);
        }
        let clear = |rival: f64| rival >= (2.0 * error).max(0.25 * tolerance);
        (error < tolerance
            && self.best_previous[b].is_some_and(|(p, _)| p == a)
            && clear(self.rival_next[a])
            && clear(self.rival_previous[b]))
        .then_some(b)
    }
}

/// How far from piece b's first position (frame t₂) piece a's last one (frame t₁) lands
/// when carried by the rigid motion of the neighbours steady at both ends (each end given
/// as track, frame and steady neighbours); `None` with fewer than [`MIN_PARTNERS`].
fn carry(
    t: &Trajectories,
    (a, t1, at_end): (usize, usize, &[(usize, f64)]),
    (b, t2, at_start): (usize, usize, &[(usize, f64)]),
) -> Option<f64> {
    // The steadiest common neighbours by (spread, id), kept in place: this runs for every
    // candidate pair, so it does not allocate.
    let mut steady = [(f64::INFINITY, usize::MAX); MAX_PARTNERS];
    let mut count = 0;
    let (mut i, mut j) = (0, 0);
    while i < at_end.len() && j < at_start.len() {
        match at_end[i].0.cmp(&at_start[j].0) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                let r = at_end[i].0;
                let item = (at_end[i].1.max(at_start[j].1), r);
                let before = |x: (f64, usize), y: (f64, usize)| {
                    x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).is_lt()
                };
                if r != a && r != b && (count < MAX_PARTNERS || before(item, steady[count - 1])) {
                    let mut at = count.min(MAX_PARTNERS - 1);
                    steady[at] = item;
                    while at > 0 && before(steady[at], steady[at - 1]) {
                        steady.swap(at, at - 1);
                        at -= 1;
                    }
                    count = (count + 1).min(MAX_PARTNERS);
                }
                i += 1;
                j += 1;
            }
        }
    }
    if count < MIN_PARTNERS {
        return None;
    }
    let (row1, row2) = (t.frame(t1), t.frame(t2));
    let from: [[f64; 3]; MAX_PARTNERS] = std::array::from_fn(|k| row1[steady[k.min(count - 1)].1]);
    let to: [[f64; 3]; MAX_PARTNERS] = std::array::from_fn(|k| row2[steady[k.min(count - 1)].1]);
    let (rotation, translation) = rigid_motion(&from[..count], &to[..count])?;
    let p = row1[a];
    let moved: [f64; 3] = std::array::from_fn(|i| {
        rotation[i][0] * p[0] + rotation[i][1] * p[1] + rotation[i][2] * p[2] + translation[i]
    });
    Some(distance(moved, row2[b]))
}

/// The standard deviation of the distance between markers `a` and `r` over the frames of
/// `window` where both are seen; infinite (not steady) with fewer than three such frames.
fn distance_spread(
    t: &Trajectories,
    a: usize,
    r: usize,
    window: std::ops::RangeInclusive<usize>,
) -> f64 {
    let (mut n, mut sum, mut sum_sq) = (0.0, 0.0, 0.0);
    for f in window {
        if let (Some(p), Some(q)) = (t.get(f, a), t.get(f, r)) {
            let d = distance(p, q);
            n += 1.0;
            sum += d;
            sum_sq += d * d;
        }
    }
    if n < 3.0 {
        return f64::INFINITY;
    }
    (sum_sq / n - (sum / n).powi(2)).max(0.0).sqrt()
}

/// The rotation (row-major) and translation carrying points `from` onto `to` best in least
/// squares (Horn's quaternion method); `None` for fewer than three points.
fn rigid_motion(from: &[[f64; 3]], to: &[[f64; 3]]) -> Option<([[f64; 3]; 3], [f64; 3])> {
    if from.len() < 3 || from.len() != to.len() {
        return None;
    }
    let centroid = |pts: &[[f64; 3]]| -> [f64; 3] {
        let n = pts.len() as f64;
        std::array::from_fn(|i| pts.iter().map(|p| p[i]).sum::<f64>() / n)
    };
    let (cf, ct) = (centroid(from), centroid(to));
    let mut s = [[0.0; 3]; 3];
    for (p, q) in from.iter().zip(to) {
        for (i, row) in s.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += (p[i] - cf[i]) * (q[j] - ct[j]);
            }
        }
    }
    let (_, q) = largest_eigenpair4(horn_matrix(s));
    let r = rotation_matrix(q);
    let moved: [f64; 3] =
        std::array::from_fn(|i| r[i][0] * cf[0] + r[i][1] * cf[1] + r[i][2] * cf[2]);
    Some((r, std::array::from_fn(|i| ct[i] - moved[i])))
}

/// Rounds of joining at most: a joined track is longer, so pieces next to it find steady
/// neighbours the round before could not; a few rounds settle.
const MAX_ROUNDS: usize = 8;

/// The tracks with each chain of `next` (a track and what continues it) joined into one,
/// in the order of the chains' heads; and each joined track's pieces (indices into `t`).
fn join_chains(
    t: &Trajectories,
    next: &[Option<usize>],
) -> Option<(Trajectories, Vec<Vec<usize>>)> {
    let mut continued = vec![false; next.len()];
    for b in next.iter().flatten() {
        continued[*b] = true;
    }
    let chains: Vec<Vec<usize>> = (0..next.len())
        .filter(|&k| !continued[k])
        .map(|head| {
            let mut chain = vec![head];
            let mut at = head;
            while let Some(b) = next[at] {
                chain.push(b);
                at = b;
            }
            chain
        })
        .collect();
    let (frames, count) = (t.frames(), chains.len());
    let mut positions = vec![MISSING; frames * count];
    for f in 0..frames {
        let row = t.frame(f);
        for (c, chain) in chains.iter().enumerate() {
            if let Some(&k) = chain.iter().find(|&&k| is_present(row[k])) {
                positions[f * count + c] = row[k];
            }
        }
    }
    let labels = chains.iter().map(|c| t.labels()[c[0]].clone()).collect();
    // The samples are the capture's own, so this fails only on a broken invariant; the
    // capture is then better read unjoined than not at all.
    let joined =
        Trajectories::new(labels, t.frame_rate(), t.first_frame(), frames, positions).ok()?;
    Some((joined, chains))
}

/// The capture with each marker's pieces joined into one track (see the module docs),
/// saying so in a warning and in `info.stitched`; unchanged when nothing joins.
pub(crate) fn join_pieces(mut capture: Capture) -> Capture {
    let labels = capture.trajectories.labels().to_vec();
    // The capture's pieces each current track is made of, in time order.
    let mut pieces: Vec<Vec<usize>> = (0..labels.len()).map(|k| vec![k]).collect();
    let mut current = capture.trajectories.clone();
    for _ in 0..MAX_ROUNDS {
        let next = continuations(&current);
        if next.iter().all(Option::is_none) {
            break;
        }
        let Some((joined, chains)) = join_chains(&current, &next) else {
            break;
        };
        pieces = chains
            .iter()
            .map(|c| c.iter().flat_map(|&k| pieces[k].iter().copied()).collect())
            .collect();
        current = joined;
    }
    if pieces.len() == labels.len() {
        return capture;
    }
    let stitched: Vec<Vec<String>> = pieces
        .iter()
        .filter(|p| p.len() > 1)
        .map(|p| p.iter().map(|&k| labels[k].clone()).collect())
        .collect();
    let joined: usize = stitched.iter().map(Vec::len).sum();
    let shown: Vec<String> = stitched.iter().take(3).map(|s| s.join(" + ")).collect();
    capture.info.warnings.push(format!(
        "{joined} tracks are {} markers seen in pieces across gaps (each piece lands where \
         its steady neighbours carry the one before, or across a short gap where its own \
         motion leads), each joined into one track \
         (mocap-io.stitch=false keeps them apart): {}{}",
        stitched.len(),
        shown.join("; "),
        if stitched.len() > shown.len() {
            "; ..."
        } else {
            ""
        }
    ));
    capture.trajectories = current;
    capture.info.stitched = stitched;
    capture
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CaptureInfo, Format};

    /// A rigid body of six markers turning and travelling for `frames` frames at 100 Hz.
    fn body(frames: usize) -> Vec<Vec<[f64; 3]>> {
        let shape = [
            [0.0, 0.0, 0.0],
            [60.0, 0.0, 10.0],
            [0.0, 70.0, -5.0],
            [10.0, 10.0, 80.0],
            [55.0, 60.0, 30.0],
            [-40.0, 35.0, 45.0],
        ];
        (0..frames)
            .map(|f| {
                let a = 0.03 * f as f64;
                let (c, s) = (a.cos(), a.sin());
                shape
                    .iter()
                    .map(|p| {
                        [
                            c * p[0] - s * p[1] + 4.0 * f as f64,
                            s * p[0] + c * p[1],
                            p[2] + 100.0 * (0.02 * f as f64).sin(),
                        ]
                    })
                    .collect()
            })
            .collect()
    }

    /// A capture of tracks, each a marker of `body` seen in the frame range given.
    fn capture(tracks: &[(usize, std::ops::Range<usize>)], frames: usize) -> Capture {
        let motion = body(frames);
        let mut positions = vec![MISSING; frames * tracks.len()];
        for (k, (marker, seen)) in tracks.iter().enumerate() {
            for f in seen.clone() {
                positions[f * tracks.len() + k] = motion[f][*marker];
            }
        }
        let labels = (0..tracks.len()).map(|k| format!("*{k}")).collect();
        Capture {
            format: Format::C3d,
            trajectories: Trajectories::new(labels, 100.0, 1, frames, positions).unwrap(),
            info: CaptureInfo::default(),
        }
    }

    #[test]
    fn rigid_motion_recovers_a_turn_and_a_shift() {
        let from = [
            [0.0, 0.0, 0.0],
            [100.0, 0.0, 0.0],
            [0.0, 50.0, 0.0],
            [0.0, 0.0, 30.0],
        ];
        // A quarter turn about z, then a shift.
        let to: Vec<[f64; 3]> = from
            .iter()
            .map(|p| [-p[1] + 5.0, p[0] - 2.0, p[2] + 7.0])
            .collect();
        let (r, t) = rigid_motion(&from, &to).unwrap();
        let expected = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        for i in 0..3 {
            for j in 0..3 {
                assert!((r[i][j] - expected[i][j]).abs() < 1e-9, "{r:?}");
            }
        }
        assert!(
            (t[0] - 5.0).abs() < 1e-9 && (t[1] + 2.0).abs() < 1e-9 && (t[2] - 7.0).abs() < 1e-9
        );
        assert_eq!(rigid_motion(&from[..2], &to[..2]), None);
    }

    #[test]
    fn a_marker_seen_in_pieces_is_joined_and_others_are_not() {
        // Marker 0 in three pieces (gaps of 12 and 30 frames); marker 1 lost at frame 100 and
        // marker 2's second piece starting where marker 1 is not: neither joins marker 1.
        let tracks = [
            (0, 0..80),
            (0, 92..150),
            (0, 180..300),
            (1, 0..100),
            (2, 0..90),
            (2, 110..300),
            (3, 0..300),
            (4, 0..300),
            (5, 0..300),
        ];
        let c = join_pieces(capture(&tracks, 300));
        let t = &c.trajectories;
        assert_eq!(
            c.info.stitched,
            [vec!["*0", "*1", "*2"], vec!["*4", "*5"]]
                .map(|g| g.into_iter().map(String::from).collect::<Vec<_>>())
        );
        assert_eq!(t.labels(), ["*0", "*3", "*4", "*6", "*7", "*8"]);
        let motion = body(300);
        for f in [0, 79, 92, 299] {
            assert_eq!(t.get(f, 0), Some(motion[f][0]));
        }
        assert_eq!(t.get(85, 0), None);
        assert_eq!(t.get(150, 1), None);
        assert!(
            c.info.warnings[0].starts_with("5 tracks are 2 markers seen in pieces"),
            "{:?}",
            c.info.warnings
        );
    }

    #[test]
    fn a_capture_without_pieces_reads_unchanged() {
        // Marker 3 is lost at 150 and nothing starts after it; marker 2 starts late.
        let c = capture(
            &[
                (0, 0..200),
                (1, 0..200),
                (2, 10..200),
                (3, 0..150),
                (4, 0..200),
            ],
            200,
        );
        let read = join_pieces(c.clone());
        assert!(read.info.stitched.is_empty() && read.info.warnings.is_empty());
        assert_eq!(read.trajectories.labels(), c.trajectories.labels());
        let bits = |t: &Trajectories| -> Vec<u64> {
            t.positions()
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect()
        };
        assert!(bits(&read.trajectories) == bits(&c.trajectories));
    }

    #[test]
    fn a_short_gap_is_bridged_by_the_pieces_own_motion() {
        // Two of the body's markers (too few neighbours for a carry). Marker 0 hidden for 8
        // frames beside marker 1: its motion about marker 1 on each side meets across the
        // gap.
        let two_markers = |pieces: &[(usize, std::ops::Range<usize>)]| capture(pieces, 300);
        let c = join_pieces(two_markers(&[(0, 0..120), (0, 128..300), (1, 0..300)]));
        assert_eq!(c.info.stitched, [vec!["*0".to_owned(), "*1".to_owned()]]);
        // Both hidden together (a two-marker body hidden whole): each line meets its own
        // marker's, each a rival of the other, 60 mm apart.
        let c = join_pieces(two_markers(&[
            (0, 0..120),
            (1, 0..118),
            (0, 128..300),
            (1, 130..300),
        ]));
        assert_eq!(
            c.info.stitched,
            [vec!["*0", "*2"], vec!["*1", "*3"]]
                .map(|g| g.into_iter().map(String::from).collect::<Vec<_>>())
        );
        // Past the bridge (0.2 s at 100 Hz) a piece's motion is no guide.
        let c = join_pieces(two_markers(&[(0, 0..120), (0, 150..300), (1, 0..300)]));
        assert!(c.info.stitched.is_empty(), "{:?}", c.info.stitched);
        // Another marker's piece where this one's motion does not lead joins nothing.
        let c = join_pieces(two_markers(&[(0, 0..120), (2, 126..300), (1, 0..300)]));
        assert!(c.info.stitched.is_empty(), "{:?}", c.info.stitched);
    }

    #[test]
    fn a_bridge_widens_its_bound_against_a_rival_up_to_the_way_its_lines_came() {
        // Piece 0 ends at 99, piece 1 starts at 110 and their lines meet 12 mm apart,
        // beyond half the way to a marker 10 mm off; piece 2, seen until 90, meets piece 1
        // 60 mm apart.
        let spans = [(0, 99), (110, 200), (0, 90)].map(|(first, last)| Some(Span { first, last }));
        let nearest = |_: usize, _: usize| 10.0;
        let alone = Choices::of(&[(0, 1, 12.0)], &spans);
        let beside = Choices::of(&[(0, 1, 12.0), (2, 1, 60.0)], &spans);
        let far = |_: usize, _: usize| 25.0;
        // A third of the rival's 60 mm, within what the lines' way allows.
        assert_eq!(beside.clear_best(0, &spans, &nearest, Some(&far)), Some(1));
        // The nearest-marker bound alone, and with nothing else to measure the miss
        // against.
        assert_eq!(beside.clear_best(0, &spans, &nearest, None), None);
        assert_eq!(alone.clear_best(0, &spans, &nearest, Some(&far)), None);
        // Lines carried too short a way to miss by 12 mm, and by 4 mm, which the
        // nearest-marker bound alone would take.
        let near = |_: usize, _: usize| 3.0;
        assert_eq!(beside.clear_best(0, &spans, &nearest, Some(&near)), None);
        let close = Choices::of(&[(0, 1, 4.0)], &spans);
        assert_eq!(close.clear_best(0, &spans, &nearest, None), Some(1));
        assert_eq!(close.clear_best(0, &spans, &nearest, Some(&near)), None);
    }

    #[test]
    fn two_pieces_that_could_each_continue_one_are_left_apart() {
        // Marker 0 ends; two pieces of the same place (a duplicate reconstruction) start
        // after it: which one continues it is a guess, so neither does.
        let c = join_pieces(capture(
            &[
                (0, 0..100),
                (0, 105..200),
                (0, 106..200),
                (1, 0..200),
                (2, 0..200),
                (3, 0..200),
            ],
            200,
        ));
        assert!(c.info.stitched.is_empty(), "{:?}", c.info.stitched);
    }
}
