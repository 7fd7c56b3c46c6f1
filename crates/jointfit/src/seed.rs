//! A first pose where no segment has one of its own: two segments of two markers each,
//! joined by a joint, keep each of their four markers at a constant distance from its
//! centre, so in every frame four spheres of unknown but constant radii meet in one point.
//! Per frame that is four equations for the centre's three coordinates: over the trial the
//! redundancy fixes the four radii, and with them the centre at every frame. One of the
//! two segments is then posed from its two markers plus that centre, and anchoring
//! (`anchor.rs`) carries on from it as from any posed segment.
//!
//! A marker set with two markers on every segment (a sparse set, a robot's links, an
//! animal's limbs) had no pose to start from, and so no joint at all.
//!
//! The fit is Levenberg–Marquardt on the centre of every frame and the four radii at once
//! (the per-frame centres eliminated by their 3 × 3 blocks, leaving a 4 × 4 system in the
//! radii), started from the midpoint of each pair of markers one from either segment, the
//! best start kept. A hinge leaves the centre free along its axis: any point there is
//! fixed in both segments, so the pose built from it is the same wherever the fit stops.
//! But with one degree of freedom between them, two marker pairs also nearly meet at
//! points off the axis that are fixed in neither (on a noise-free hinge, 0.16 mm RMS some
//! 36–42 mm from the axis), and a pose built from such a point turns with the hinge angle. So the
//! pair whose spheres meet best starts, not the one whose radii are best conditioned
//! (that choice, measured, lost 41 of 96 noise-free trees with two markers per segment).

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use std::collections::BTreeMap;

use glam::{DMat3, DMat4, DVec3, DVec4};
use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::params::Params;
use crate::poses::trace;

/// Most frames the radii are fitted on (evenly spaced); the centre is then solved at every
/// frame with the radii fixed.
const FIT_FRAMES: usize = 160;

/// Levenberg–Marquardt iterations of the joint fit from each start, and then of the best.
const START_ITERATIONS: usize = 15;
const MAX_ITERATIONS: usize = 200;

/// Gauss–Newton iterations of one frame's centre with the radii fixed.
const FRAME_ITERATIONS: usize = 30;

/// The common centre of two two-marker segments' markers.
#[derive(Clone, Debug)]
pub(crate) struct CommonCentre {
    /// Per frame, the centre (global, mm); `None` where not all four markers are seen.
    pub centre: Vec<Option<DVec3>>,
    /// RMS over the samples (marker × frame) of the distance residual, mm.
    pub rms_mm: f64,
    /// RMS change of the angle between the two marker lines, degrees: how much the
    /// segments turn relative to each other (a still pair fixes no centre).
    pub excursion_deg: f64,
    /// Mean distance of the centre from each segment's marker line, mm (`a`, then `b`):
    /// the lever a pose built from two markers and the centre has about that line.
    pub lever_mm: [f64; 2],
}

/// Common centre of segments `a` and `b` (two markers each); `None` with fewer than
/// `min_frames` frames where all four are seen, or a relative turn under
/// `min_excursion_deg`.
pub(crate) fn common_centre(
    traj: &Trajectories,
    a: [usize; 2],
    b: [usize; 2],
    min_frames: usize,
    min_excursion_deg: f64,
) -> Option<CommonCentre> {
    let markers = [a[0], a[1], b[0], b[1]];
    let seen: Vec<(usize, [DVec3; 4])> = (0..traj.frames())
        .filter_map(|f| {
            let mut p = [DVec3::ZERO; 4];
            for (k, &m) in markers.iter().enumerate() {
                p[k] = DVec3::from_array(traj.get(f, m)?);
            }
            Some((f, p))
        })
        .collect();
    if seen.len() < min_frames.max(5) {
        return None;
    }
    let excursion_deg = line_angle_rms_deg(&seen);
    if excursion_deg.is_nan() || excursion_deg < min_excursion_deg {
        return None;
    }
    let stride = seen.len().div_ceil(FIT_FRAMES);
    let sample: Vec<[DVec3; 4]> = seen.iter().step_by(stride).map(|(_, p)| *p).collect();
    // Each start a few iterations, the best of them to convergence.
    let mut best: Option<(f64, [f64; 4], Vec<DVec3>)> = None;
    for i in 0..2 {
        for j in 2..4 {
            let start: Vec<DVec3> = sample.iter().map(|p| 0.5 * (p[i] + p[j])).collect();
            let (cost, radii, centres) = fit_radii(&sample, start, START_ITERATIONS);
            if best.as_ref().is_none_or(|(c, _, _)| cost < *c) {
                best = Some((cost, radii, centres));
            }
        }
    }
    let (_, _, started) = best?;
    let (_, radii, fitted) = fit_radii(&sample, started, MAX_ITERATIONS);
    // Every frame's centre with the radii fixed, started from the previous frame's (the
    // four spheres also meet near the mirror image of the centre when the markers are
    // nearly coplanar; continuity keeps the same one).
    let mut centre = vec![None; traj.frames()];
    let (mut sum_sq, mut samples) = (0.0, 0usize);
    let mut lever = [0.0; 2];
    let mut previous: Option<(usize, DVec3)> = None;
    for (k, (f, p)) in seen.iter().enumerate() {
        let start = match previous {
            Some((g, c)) if g + 1 == *f => c,
            _ => fitted[(k / stride).min(fitted.len() - 1)],
        };
        let c = frame_centre(p, &radii, start);
        for m in 0..4 {
            sum_sq += ((c - p[m]).length() - radii[m]).powi(2);
        }
        samples += 4;
        lever[0] += line_distance(c, p[0], p[1]);
        lever[1] += line_distance(c, p[2], p[3]);
        centre[*f] = Some(c);
        previous = Some((*f, c));
    }
    let n = seen.len() as f64;
    Some(CommonCentre {
        centre,
        rms_mm: (sum_sq / samples as f64).sqrt(),
        excursion_deg,
        lever_mm: [lever[0] / n, lever[1] / n],
    })
}

/// Partners per two-marker segment whose common centre with it is fitted: the nearest by
/// marker distance (a joint's two segments have markers near each other).
const NEAREST_PARTNERS: usize = 4;

/// What [`best_seed`] computed, kept for its next call (segments and poses of other
/// segments do not change a pair's common centre), by pair `(a, b)`, `a < b`.
#[derive(Default)]
pub(crate) struct SeedMemo {
    /// Smallest median marker distance of the pair, mm.
    distances: BTreeMap<(usize, usize), Option<f64>>,
    /// The pair's common centre, if it has an acceptable one.
    centres: BTreeMap<(usize, usize), Option<CommonCentre>>,
}

/// A seed: the segment to pose from its two markers and the common centre, its partner,
/// and the centre.
pub(crate) type Seed = (usize, usize, CommonCentre);

/// The best seed among pairs of segments of exactly two markers that are not `posed` and
/// not `refused` (symmetric): the common centre with the smallest residual within
/// `params.anchor_max_rms_mm`; the segment posed is the one whose marker line the centre is
/// farther from (the better-fixed spin).
pub(crate) fn best_seed(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    posed: &[bool],
    refused: &[Vec<bool>],
    params: &Params,
    memo: &mut SeedMemo,
) -> Option<Seed> {
    let n = segments.len();
    let free: Vec<usize> = (0..n)
        .filter(|&s| !posed[s] && segments[s].len() == 2)
        .collect();
    if free.len() < 2 {
        return None;
    }
    let mut candidates: Vec<(usize, usize)> = Vec::new();
    for &a in &free {
        let mut near: Vec<(f64, usize)> = free
            .iter()
            .filter(|&&b| b != a && !refused[a][b])
            .filter_map(|&b| {
                let d = *memo
                    .distances
                    .entry((a.min(b), a.max(b)))
                    .or_insert_with(|| nearest_distance(traj, &segments[a], &segments[b]));
                Some((d?, b))
            })
            .collect();
        near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        for &(_, b) in near.iter().take(NEAREST_PARTNERS) {
            candidates.push((a.min(b), a.max(b)));
        }
    }
    candidates.sort_unstable();
    candidates.dedup();
    let missing: Vec<(usize, usize)> = candidates
        .iter()
        .copied()
        .filter(|k| !memo.centres.contains_key(k))
        .collect();
    let fitted: Vec<Option<CommonCentre>> = missing
        .par_iter()
        .map(|&(a, b)| {
            common_centre(
                traj,
                [segments[a][0], segments[a][1]],
                [segments[b][0], segments[b][1]],
                params.min_frames,
                params.anchor_min_excursion_deg,
            )
            .filter(|c| c.rms_mm <= params.anchor_max_rms_mm)
        })
        .collect();
    memo.centres.extend(missing.into_iter().zip(fitted));
    let (a, b, fit) = candidates
        .into_iter()
        .filter_map(|(a, b)| Some((a, b, memo.centres.get(&(a, b))?.as_ref()?)))
        .min_by(|x, y| {
            x.2.rms_mm
                .total_cmp(&y.2.rms_mm)
                .then((x.0, x.1).cmp(&(y.0, y.1)))
        })?;
    let fit = fit.clone();
    Some(if fit.lever_mm[1] > fit.lever_mm[0] {
        (b, a, fit)
    } else {
        (a, b, fit)
    })
}

/// Smallest median distance over the frames between a marker of `a` and one of `b`, mm.
fn nearest_distance(traj: &Trajectories, a: &[usize], b: &[usize]) -> Option<f64> {
    let mut best: Option<f64> = None;
    let mut d = Vec::with_capacity(traj.frames());
    for &i in a {
        for &j in b {
            d.clear();
            d.extend((0..traj.frames()).filter_map(|f| {
                let (p, q) = (traj.get(f, i)?, traj.get(f, j)?);
                Some(DVec3::from_array(p).distance(DVec3::from_array(q)))
            }));
            if d.is_empty() {
                continue;
            }
            let mid = d.len() / 2;
            let median = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
            best = Some(best.map_or(median, |b| b.min(median)));
        }
    }
    best
}

/// RMS deviation from its mean of the angle between the lines 0–1 and 2–3, degrees.
fn line_angle_rms_deg(seen: &[(usize, [DVec3; 4])]) -> f64 {
    let angles: Vec<f64> = seen
        .iter()
        .filter_map(|(_, p)| {
            let u = (p[1] - p[0]).try_normalize()?;
            let v = (p[3] - p[2]).try_normalize()?;
            Some(u.dot(v).clamp(-1.0, 1.0).acos().to_degrees())
        })
        .collect();
    if angles.is_empty() {
        return f64::NAN;
    }
    let mean = angles.iter().sum::<f64>() / angles.len() as f64;
    (angles.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / angles.len() as f64).sqrt()
}

/// Distance of `c` from the line through `p` and `q`, mm.
fn line_distance(c: DVec3, p: DVec3, q: DVec3) -> f64 {
    let Some(u) = (q - p).try_normalize() else {
        return (c - p).length();
    };
    let d = c - p;
    (d - u * d.dot(u)).length()
}

/// Sum of squared distance residuals of centres `c` (one per frame of `points`) and `radii`.
fn cost(points: &[[DVec3; 4]], centres: &[DVec3], radii: &[f64; 4]) -> f64 {
    points
        .iter()
        .zip(centres)
        .map(|(p, c)| {
            (0..4)
                .map(|k| ((*c - p[k]).length() - radii[k]).powi(2))
                .sum::<f64>()
        })
        .sum()
}

/// Levenberg–Marquardt on every frame's centre and the four radii, from centres `start`;
/// returns (sum of squares, radii, centres).
fn fit_radii(
    points: &[[DVec3; 4]],
    start: Vec<DVec3>,
    iterations: usize,
) -> (f64, [f64; 4], Vec<DVec3>) {
    let frames = points.len();
    let mut centres = start;
    let mut radii = [0.0; 4];
    for k in 0..4 {
        radii[k] = points
            .iter()
            .zip(&centres)
            .map(|(p, c)| (*c - p[k]).length())
            .sum::<f64>()
            / frames as f64;
    }
    let mut current = cost(points, &centres, &radii);
    let mut damping = Damping::new();
    let mut blocks: Vec<FrameBlock> = Vec::with_capacity(frames);
    let mut trial = centres.clone();
    for _ in 0..iterations {
        let (schur, rhs) = reduced_system(points, &centres, &radii, damping.lambda, &mut blocks);
        let s = DMat4::from_cols_array_2d(&schur);
        if s.determinant().abs() < 1e-300 {
            break;
        }
        let dr = s.inverse() * DVec4::from_array(rhs);
        let dr = dr.to_array();
        let mut trial_radii = radii;
        for k in 0..4 {
            trial_radii[k] += dr[k];
        }
        for (t, (inv, n, e)) in blocks.iter().enumerate() {
            // Hcc Δc = −g_c − Hcr Δr = −Σ n e + Σ n Δr.
            let mut rhs_c = DVec3::ZERO;
            for k in 0..4 {
                rhs_c += n[k] * (dr[k] - e[k]);
            }
            trial[t] = centres[t] + *inv * rhs_c;
        }
        let next = cost(points, &trial, &trial_radii);
        let (accepted, stop) = damping.judge(current, next, 1e-12);
        if accepted {
            std::mem::swap(&mut centres, &mut trial);
            radii = trial_radii;
            current = next;
        }
        if stop {
            break;
        }
    }
    (current, radii, centres)
}

/// Per frame: the damped 3 × 3 block's inverse, the unit directions (the centre's
/// Jacobian rows) and the residuals.
type FrameBlock = (DMat3, [DVec3; 4], [f64; 4]);

/// The Gauss–Newton system of every frame's centre and the four radii, damped by
/// `lambda`, reduced to the radii (the centres eliminated by their 3 × 3 blocks, kept in
/// `blocks`): (Schur complement, right-hand side).
fn reduced_system(
    points: &[[DVec3; 4]],
    centres: &[DVec3],
    radii: &[f64; 4],
    lambda: f64,
    blocks: &mut Vec<FrameBlock>,
) -> ([[f64; 4]; 4], [f64; 4]) {
    blocks.clear();
    let mut schur = [[0.0; 4]; 4];
    let mut rhs = [0.0; 4];
    for (p, c) in points.iter().zip(centres) {
        let mut n = [DVec3::ZERO; 4];
        let mut e = [0.0; 4];
        let mut h = DMat3::ZERO;
        let mut g = DVec3::ZERO;
        for k in 0..4 {
            let d = *c - p[k];
            let len = d.length();
            n[k] = if len > 1e-12 { d / len } else { DVec3::ZERO };
            e[k] = len - radii[k];
            h += outer(n[k], n[k]);
            g += n[k] * e[k];
            // The radii's own gradient: each residual is −1 in its radius.
            rhs[k] += e[k];
        }
        let inv = damped(h, lambda).inverse();
        // Schur complement: S −= Hrc Hcc⁻¹ Hcr, with Hcr's column k = −n_k.
        for i in 0..4 {
            let m_ni = inv * n[i];
            for j in 0..4 {
                schur[i][j] -= n[j].dot(m_ni);
            }
            // rhs = −g_r + Hrc Hcc⁻¹ g_c, with g_r = −Σ e and Hrc row i = −n_iᵀ.
            rhs[i] -= n[i].dot(inv * g);
        }
        blocks.push((inv, n, e));
    }
    for k in 0..4 {
        schur[k][k] += points.len() as f64 * (1.0 + lambda);
    }
    (schur, rhs)
}

/// Centre of one frame's four spheres (`points`, `radii`) by damped Gauss–Newton from `start`.
fn frame_centre(points: &[DVec3; 4], radii: &[f64; 4], start: DVec3) -> DVec3 {
    let residual = |c: DVec3| -> f64 {
        (0..4)
            .map(|k| ((c - points[k]).length() - radii[k]).powi(2))
            .sum()
    };
    let mut c = start;
    let mut current = residual(c);
    let mut damping = Damping::new();
    for _ in 0..FRAME_ITERATIONS {
        let mut h = DMat3::ZERO;
        let mut g = DVec3::ZERO;
        for k in 0..4 {
            let d = c - points[k];
            let len = d.length();
            if len <= 1e-12 {
                continue;
            }
            let n = d / len;
            h += outer(n, n);
            g += n * (len - radii[k]);
        }
        let step = -(damped(h, damping.lambda).inverse() * g);
        let next = residual(c + step);
        let (accepted, stop) = damping.judge(current, next, 1e-14);
        if accepted {
            c += step;
            current = next;
        }
        if stop {
            break;
        }
    }
    c
}

/// Levenberg–Marquardt's damping factor: smaller after a step that lowers the cost, larger
/// after one that does not.
struct Damping {
    lambda: f64,
}

impl Damping {
    fn new() -> Self {
        Self { lambda: 1e-3 }
    }

    /// Judges a step from cost `current` to `next`: (accept it, stop iterating). A step is
    /// accepted when it lowers the cost; the iteration stops when the gain falls to
    /// `tolerance` of the cost, or when damping no step helps.
    fn judge(&mut self, current: f64, next: f64, tolerance: f64) -> (bool, bool) {
        if next < current {
            self.lambda = (self.lambda / 3.0).max(1e-12);
            (true, current - next <= tolerance * next.max(1e-12))
        } else {
            self.lambda *= 4.0;
            (false, self.lambda > 1e8)
        }
    }
}

/// A 3 × 3 normal-equations block `h` damped by `lambda` (scaled to its mean diagonal).
fn damped(h: DMat3, lambda: f64) -> DMat3 {
    h + DMat3::from_diagonal(DVec3::splat(lambda * (1.0 + trace(h) / 3.0)))
}

/// `u vᵀ`.
fn outer(u: DVec3, v: DVec3) -> DMat3 {
    DMat3::from_cols(u * v.x, u * v.y, u * v.z)
}

#[cfg(test)]
mod tests {
    use super::common_centre;
    use glam::{DQuat, DVec3};
    use mocap_io::Trajectories;

    /// A pelvis-like and a thigh-like segment of two markers each, the thigh swinging on a
    /// ball joint about all three axes while the pelvis moves: the four distances meet at
    /// the joint in every frame, and nowhere else.
    #[test]
    fn two_pairs_meet_at_their_ball_joint() {
        let frames = 240;
        let joint_in_parent = DVec3::new(80.0, -60.0, -90.0);
        let parent = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(40.0, 120.0, 30.0)];
        let child = [
            DVec3::new(50.0, 20.0, -150.0),
            DVec3::new(35.0, -25.0, -360.0),
        ];
        let parent_rot =
            |t: f64| DQuat::from_rotation_z(0.3 * t.sin()) * DQuat::from_rotation_x(0.1 * t.cos());
        let mut positions = Vec::new();
        let mut joints = Vec::new();
        for f in 0..frames {
            let t = f as f64 / frames as f64 * std::f64::consts::TAU;
            let origin = DVec3::new(300.0 * t.cos(), 100.0 * t, 900.0);
            let swing = DQuat::from_rotation_y(0.5 * (2.0 * t).sin())
                * DQuat::from_rotation_x(0.4 * (3.0 * t).cos())
                * DQuat::from_rotation_z(0.3 * t.sin());
            let joint = origin + parent_rot(t) * joint_in_parent;
            for p in parent {
                positions.push((origin + parent_rot(t) * p).to_array());
            }
            for p in child {
                positions.push((joint + parent_rot(t) * swing * p).to_array());
            }
            joints.push(joint);
        }
        let labels = ["P1", "P2", "C1", "C2"].map(String::from).to_vec();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        let fit = common_centre(&traj, [0, 1], [2, 3], 30, 5.0).unwrap();
        assert!(fit.rms_mm < 1e-3, "rms {}", fit.rms_mm);
        assert!(fit.excursion_deg > 10.0);
        for (f, c) in fit.centre.iter().enumerate() {
            let miss = c.unwrap().distance(joints[f]);
            assert!(miss < 0.01, "frame {f}: {miss} mm off");
        }
    }

    /// A degenerate pair (two markers a micrometre apart, the other two in line with the
    /// joint, one of them missing in most frames) gives a finite fit, never a panic or NaN.
    #[test]
    fn a_degenerate_pair_gives_a_finite_fit() {
        let frames = 120;
        let mut positions = Vec::new();
        for f in 0..frames {
            let t = f as f64 * 0.05;
            let swing = DQuat::from_rotation_y(0.6 * t.sin());
            let gap = f % 3 != 0;
            let points = [
                DVec3::ZERO,
                DVec3::new(1e-6, 0.0, 0.0),
                swing * DVec3::new(0.0, 0.0, -100.0),
                swing * DVec3::new(0.0, 0.0, -200.0),
            ];
            for (k, p) in points.iter().enumerate() {
                positions.push(if gap && k == 3 {
                    [f64::NAN; 3]
                } else {
                    p.to_array()
                });
            }
        }
        let labels = ["A", "B", "C", "D"].map(String::from).to_vec();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        // The pair turns, so the fit runs, and it must come out finite.
        let fit = common_centre(&traj, [0, 1], [2, 3], 30, 0.0).expect("a fit");
        assert!(fit.rms_mm.is_finite());
        assert!(fit.centre.iter().flatten().all(|c| c.is_finite()));
    }

    /// Two pairs that never turn relative to each other fix no centre.
    #[test]
    fn still_pairs_give_no_centre() {
        let frames = 100;
        let mut positions = Vec::new();
        for f in 0..frames {
            let rot = DQuat::from_rotation_z(f as f64 * 0.02);
            let shift = DVec3::new(f as f64, 0.0, 0.0);
            for p in [
                [0.0, 0.0, 0.0],
                [100.0, 0.0, 0.0],
                [0.0, 80.0, 0.0],
                [50.0, 80.0, 40.0],
            ] {
                positions.push((shift + rot * DVec3::from_array(p)).to_array());
            }
        }
        let labels = ["A", "B", "C", "D"].map(String::from).to_vec();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        assert!(common_centre(&traj, [0, 1], [2, 3], 30, 5.0).is_none());
    }
}
