//! The joint test for a part of two markers: a cluster of a segment with three or more
//! markers and a neighbour with two (sparse marker sets) cannot be cut by the joint test,
//! whose parts must each be posed (`MIN_PART`). Two markers have no spin about their own
//! line, but they still say where they go: in the frame of the rest of the cluster (the
//! body), the pair's midpoint travels and its direction turns, and both markers keep
//! constant distances to one centre fixed in the body (the joint), where on one rigid body
//! the pair stays put up to the body's pose errors at its lever and its own noise. Those
//! pose errors are weighed frame by frame from the body markers each frame saw: a body
//! that loses its fourth marker to a gap may be posed from three nearly in a line, and
//! then spins the pair about that line.

use crate::fitsplit::{QUANTILE, median, quantile};
use crate::jointsplit::{PartCache, SeenGeometry, lever_covariance, median_point};
use crate::swing::solve;

/// Fewest strided frames with the body posed and both markers seen.
const MIN_FRAMES: usize = 10;

/// Ridge on the common centre, relative to the normal equations' trace: pins only the
/// directions the motion leaves open (a hinge's axis) near the pair's midpoint.
const CENTRE_RIDGE: f64 = 1e-6;

/// How a part of two markers moves in the frame of the rest of its cluster (the body).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairEvidence {
    /// Robust spread of the pair's midpoint about its median in the body's frame, mm.
    pub travel_mm: f64,
    /// Robust Mahalanobis length of that travel under the covariance one rigid body gives
    /// it (the body's rotation error σ² J⁻¹ at the midpoint's lever, the body's and the
    /// midpoint's position errors), dimensionless: about 2 on one body.
    pub travel_z: f64,
    /// Robust residual of the pair's distances to one centre fixed in the body (both
    /// markers on spheres about it), mm.
    pub centre_mm: f64,
    /// The two markers' mean distance to that centre, mm: how far from the joint the pair
    /// sits, so the arc's curvature against its travel (a long radius over a short travel
    /// is a straight shuffle, not a turn).
    pub radius_mm: f64,
    /// Robust spread of the pair's direction in the body's frame, degrees.
    pub swing_deg: f64,
    /// Robust Mahalanobis length of the direction's deviation from its mean under the
    /// covariance one rigid body gives it (the body's rotation error turning it, the
    /// pair's own σ across its length), dimensionless: the two of the relative rotation's
    /// three degrees of freedom a pair shows, as the joint test's `rotation_z` weighs all
    /// three.
    pub swing_z: f64,
    /// Pooled robust σ of the body's rigid fit and the pair's distance, mm per coordinate.
    pub pooled_sigma_mm: f64,
    /// The body's own robust fit σ, mm per coordinate.
    pub body_sigma_mm: f64,
    /// The pair's robust distance spread as a σ per coordinate, mm.
    pub pair_sigma_mm: f64,
    /// The body's median rotation noise about its worst posed axis over the frames read,
    /// degrees: √(σ² λ_max(J⁻¹)) of the markers each frame saw, σ the body's fit σ (at
    /// least the typical); large where they nearly line up. Frames above the route's bound
    /// (`joint_pair_max_spin_deg`) are not read.
    pub body_spin_deg: f64,
}

/// A pair swings about the centre only if its distance to it is at most this many times
/// its midpoint's travel: the arc visibly turns (as `swing`'s lone markers must), where
/// skin shuffles a pair on one body along a nearly straight path that a sphere far away
/// fits as well.
const MAX_RADIUS_TRAVELS: f64 = 8.0;

/// A pair that travels must also turn by more than one rigid body turns it (swing z ≈ 1.7
/// at the 75th-percentile frame, √ of χ²₂'s): a three-marker body that skin tilts with
/// the joint angles swings a pair on its own segment along with it without turning it
/// (human-hard-s30030: travel z 5.13, swing z 1.29). It gives up the pair whose joint
/// axis runs along its own line, which only travels.
const MIN_TRAVEL_SWING_Z: f64 = 2.0;

/// Most markers in a cluster whose pairs are all tried (120 pairs at 16).
pub(crate) const MAX_MARKERS: usize = 16;

/// The pair route's settings (see `Params::joint_pair_share`).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PairTest {
    /// Whether the route is tried at all.
    pub on: bool,
    /// Travel z above which the pair is articulated (0: never by travel alone).
    pub min_travel_z: f64,
    /// Swing z above which it is (0: travel only) ...
    pub min_swing_z: f64,
    /// ... with a travel z above this.
    pub swing_travel_z: f64,
    /// Largest shared-centre residual as a fraction of the midpoint's travel.
    pub centre_fraction: f64,
    /// Largest rotation noise of the body about its worst axis in a frame read, degrees.
    pub max_spin_deg: f64,
}

impl PairEvidence {
    /// Whether the evidence says the pair hangs from the body by a joint under `test`,
    /// both fitting within `max_part_sigma_mm` like ordinary segments.
    pub(crate) fn is_joint(&self, test: &PairTest, max_part_sigma_mm: f64) -> bool {
        let moved = (test.min_travel_z > 0.0
            && self.travel_z > test.min_travel_z
            && self.swing_z > MIN_TRAVEL_SWING_Z)
            || (test.min_swing_z > 0.0
                && self.swing_z > test.min_swing_z
                && self.travel_z > test.swing_travel_z);
        test.on
            && moved
            && self.centre_mm <= test.centre_fraction * self.travel_mm
            && self.radius_mm <= MAX_RADIUS_TRAVELS * self.travel_mm
            && self.body_sigma_mm <= max_part_sigma_mm
            && self.pair_sigma_mm <= max_part_sigma_mm
    }
}

/// One frame the pair route reads: both markers in the body's frame, the body's residual
/// (sum of squares, dof) and where its seen markers put its pose errors.
struct PairFrame {
    local: [[f64; 3]; 2],
    residual: (f64, f64),
    geometry: SeenGeometry,
}

/// A pair read in the frames of the rest of its cluster (the body): what ranks the cut and
/// what its evidence is read from.
struct PairReading {
    frames: Vec<PairFrame>,
    /// The pair's length per frame, mm.
    lengths: Vec<f64>,
    /// Their median, mm.
    typical_length: f64,
    /// The pair's robust distance spread as a variance per coordinate, mm².
    pair_var: f64,
    /// Pooled robust σ of the body's rigid fit and the pair's distance, mm.
    pooled_sigma_mm: f64,
    /// The body's own robust fit variance, mm², and the larger of it and the typical one.
    body_var: (f64, f64),
    /// The capture's typical segment fit variance, mm².
    typical_var: f64,
}

/// The pair at the cluster positions set in `pair` (two bits) against the rest of
/// `cache`'s cluster (≥ 3 markers), in the frames whose body rotation noise is at most
/// `max_spin_deg` about every axis; `None` when the body cannot be posed or too few frames
/// are read.
fn read_pair(cache: &mut PartCache<'_>, pair: u64, max_spin_deg: f64) -> Option<PairReading> {
    let n = cache.cluster.len();
    if pair.count_ones() != 2 || !(5..=63).contains(&n) {
        return None;
    }
    let full = (1u64 << n) - 1;
    let positions: Vec<usize> = (0..n).filter(|&i| (pair >> i) & 1 == 1).collect();
    let (p, q) = (cache.cluster[positions[0]], cache.cluster[positions[1]]);
    let (traj, stride, typical_var) = (cache.traj, cache.stride, cache.typical_var);
    let body = cache.fit(full & !pair)?;
    let body_var = body.var.max(typical_var);
    // A frame whose seen markers nearly line up spins them about that line far beyond the
    // linearised covariance (a body losing its one marker off the line to a gap).
    let max_gain = max_spin_deg.to_radians().powi(2) / body_var.max(1e-12);
    let markers = traj.markers().max(1);
    let mut frames: Vec<PairFrame> = Vec::new();
    for (((frame, pose), &residual), &seen) in traj
        .positions()
        .chunks_exact(markers)
        .step_by(stride)
        .zip(&body.poses)
        .zip(&body.residuals)
        .zip(&body.seen)
    {
        let (Some(pose), Some(&x), Some(&y)) = (pose.as_ref(), frame.get(p), frame.get(q)) else {
            continue;
        };
        if !(mocap_io::is_present(x) && mocap_io::is_present(y)) {
            continue;
        }
        let Some(g) = body.geometry(seen) else {
            continue;
        };
        if g.worst_axis_gain > max_gain {
            continue;
        }
        let into = |x: [f64; 3]| -> [f64; 3] {
            let d = [x[0] - pose.t[0], x[1] - pose.t[1], x[2] - pose.t[2]];
            std::array::from_fn(|i| (0..3).map(|j| pose.r[j][i] * d[j]).sum())
        };
        frames.push(PairFrame {
            local: [into(x), into(y)],
            residual,
            geometry: g,
        });
    }
    if frames.len() < MIN_FRAMES {
        return None;
    }
    let lengths: Vec<f64> = frames
        .iter()
        .map(|f| {
            (0..3)
                .map(|i| (f.local[1][i] - f.local[0][i]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let typical_length = median(&mut lengths.clone());
    // A pair's distance scatters by √2 σ along its line under σ per coordinate per marker.
    let half_dev2: Vec<f64> = lengths
        .iter()
        .map(|l| 0.5 * (l - typical_length).powi(2))
        .collect();
    let pair_var = quantile(&mut half_dev2.clone(), QUANTILE);
    let mut pooled: Vec<f64> = frames
        .iter()
        .zip(&half_dev2)
        .map(|(f, h)| (f.residual.0 + h) / (f.residual.1 + 1.0))
        .collect();
    Some(PairReading {
        frames,
        lengths,
        typical_length,
        pair_var,
        pooled_sigma_mm: quantile(&mut pooled, QUANTILE).sqrt(),
        body_var: (body.var, body_var),
        typical_var,
    })
}

/// The evidence of the pair at the cluster positions set in `pair` (two bits) against the
/// rest of `cache`'s cluster (≥ 3 markers), read in the frames whose body rotation noise
/// is at most `max_spin_deg` about every axis; `None` when the body cannot be posed or too
/// few frames are read.
pub(crate) fn pair_evidence(
    cache: &mut PartCache<'_>,
    pair: u64,
    max_spin_deg: f64,
) -> Option<PairEvidence> {
    evidence(&read_pair(cache, pair, max_spin_deg)?)
}

/// What a pair's reading shows (see [`PairEvidence`]); `None` when no centre fits.
fn evidence(reading: &PairReading) -> Option<PairEvidence> {
    let PairReading {
        frames,
        lengths,
        typical_length,
        pair_var,
        ..
    } = reading;
    let (own_body_var, body_var) = reading.body_var;
    let var_b = pair_var.max(reading.typical_var);

    let mids: Vec<[f64; 3]> = frames
        .iter()
        .map(|f| std::array::from_fn(|i| 0.5 * (f.local[0][i] + f.local[1][i])))
        .collect();
    let mid = median_point(&mids);
    let mut travel2: Vec<f64> = mids
        .iter()
        .map(|m| (0..3).map(|i| (m[i] - mid[i]).powi(2)).sum())
        .collect();
    let travel = quantile(&mut travel2, QUANTILE).sqrt();
    let mut travel_z2: Vec<f64> = frames
        .iter()
        .zip(&mids)
        .map(|(f, m)| {
            let g = &f.geometry;
            let lever: [f64; 3] = std::array::from_fn(|i| mid[i] - g.centroid[i]);
            let position_var = body_var / g.count as f64 + var_b / 2.0;
            let cov = lever_covariance(lever, body_var, &g.inv_inertia, position_var);
            let v: [f64; 3] = std::array::from_fn(|i| m[i] - mid[i]);
            mahalanobis2(&cov, v)
        })
        .collect();
    let travel_z = quantile(&mut travel_z2, QUANTILE).max(0.0).sqrt();

    // The pair's direction in the body's frame about its mean.
    let units: Vec<[f64; 3]> = frames
        .iter()
        .zip(lengths)
        .map(|(f, len)| {
            let len = len.max(1e-9);
            std::array::from_fn(|i| (f.local[1][i] - f.local[0][i]) / len)
        })
        .collect();
    let mut mean = [0.0; 3];
    units
        .iter()
        .for_each(|u| (0..3).for_each(|i| mean[i] += u[i]));
    let norm = mean.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-12);
    let mean = mean.map(|x| x / norm);
    let mut angle2: Vec<f64> = units
        .iter()
        .map(|u| {
            let dot: f64 = (0..3).map(|i| u[i] * mean[i]).sum();
            dot.clamp(-1.0, 1.0).acos().powi(2)
        })
        .collect();
    let swing = quantile(&mut angle2, QUANTILE).sqrt();
    let across_var = 2.0 * var_b / (typical_length * typical_length).max(1e-12);
    let mut swing_z2: Vec<f64> = frames
        .iter()
        .zip(&units)
        .map(|(f, u)| direction_z2(*u, mean, body_var, &f.geometry.inv_inertia, across_var))
        .collect();
    let swing_z = quantile(&mut swing_z2, QUANTILE).max(0.0).sqrt();
    let mut spin: Vec<f64> = frames
        .iter()
        .map(|f| (body_var * f.geometry.worst_axis_gain).sqrt())
        .collect();
    let locals: Vec<[[f64; 3]; 2]> = frames.iter().map(|f| f.local).collect();
    let (centre_mm, radius_mm) = common_centre(&locals, mid)?;
    Some(PairEvidence {
        travel_mm: travel,
        travel_z,
        centre_mm,
        radius_mm,
        swing_deg: swing.to_degrees(),
        swing_z,
        pooled_sigma_mm: reading.pooled_sigma_mm,
        body_sigma_mm: own_body_var.sqrt(),
        pair_sigma_mm: pair_var.sqrt(),
        body_spin_deg: median(&mut spin).to_degrees(),
    })
}

/// `vᵀ cov⁻¹ v`; 0 when `cov` is singular: a frame with no error budget to weigh by is no
/// evidence (as the joint test's travel takes it).
fn mahalanobis2(cov: &[[f64; 3]; 3], v: [f64; 3]) -> f64 {
    match crate::reassign::invert3(cov) {
        Some(w) => (0..3)
            .map(|i| (0..3).map(|j| v[i] * w[i][j] * v[j]).sum::<f64>())
            .sum(),
        None => 0.0,
    }
}

/// Squared Mahalanobis length of the unit direction `u`'s deviation from `mean` in the
/// plane square to it, under one rigid body's covariance: a body rotation error ε
/// (covariance `body_var` J⁻¹) moves the direction by ε × u, and each marker's σ moves it
/// across by `across_var` (2 σ² / length²) per axis.
fn direction_z2(
    u: [f64; 3],
    mean: [f64; 3],
    body_var: f64,
    inv_inertia: &[[f64; 3]; 3],
    across_var: f64,
) -> f64 {
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    // A basis (e1, e2) of the plane square to the mean direction.
    let helper = if mean[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let e1 = cross(mean, helper);
    let n1 = e1.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-12);
    let e1 = e1.map(|x| x / n1);
    let e2 = cross(mean, e1);
    // (ε × u)·e = ε·(u × e).
    let g = [cross(mean, e1), cross(mean, e2)];
    let mut cov = [[0.0; 2]; 2];
    for a in 0..2 {
        for b in 0..2 {
            let mut s = if a == b { across_var } else { 0.0 };
            for i in 0..3 {
                for j in 0..3 {
                    s += g[a][i] * body_var * inv_inertia[i][j] * g[b][j];
                }
            }
            cov[a][b] = s;
        }
    }
    let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
    if !(det.is_finite() && det > 0.0) {
        return 0.0;
    }
    let v = [e1, e2].map(|e| (0..3).map(|i| u[i] * e[i]).sum::<f64>());
    (cov[1][1] * v[0] * v[0] - 2.0 * cov[0][1] * v[0] * v[1] + cov[0][0] * v[1] * v[1]) / det
}

/// Robust residual (mm) of both markers' distances (`local`, per frame, in the body's
/// frame) to one centre that keeps each at its own constant distance: the linear
/// least-squares sphere pair |y_k − c|² = r_k², in c and r_k² − |c|² (Kasa's fit with a
/// shared centre), centred on `origin`, and the markers' mean distance to that centre;
/// `None` when it has no solution.
fn common_centre(local: &[[[f64; 3]; 2]], origin: [f64; 3]) -> Option<(f64, f64)> {
    let mut a = [[0.0; 5]; 5];
    let mut b = [0.0; 5];
    for l in local {
        for (k, y) in l.iter().enumerate() {
            let z: [f64; 3] = std::array::from_fn(|i| y[i] - origin[i]);
            let z2 = z[0] * z[0] + z[1] * z[1] + z[2] * z[2];
            let mut row = [2.0 * z[0], 2.0 * z[1], 2.0 * z[2], 0.0, 0.0];
            row[3 + k] = 1.0;
            for r in 0..5 {
                b[r] += row[r] * z2;
                for c in 0..5 {
                    a[r][c] += row[r] * row[c];
                }
            }
        }
    }
    let ridge = CENTRE_RIDGE * (a[0][0] + a[1][1] + a[2][2]);
    (0..3).for_each(|i| a[i][i] += ridge);
    let x = solve(a, b)?;
    let c = [x[0], x[1], x[2]];
    let c2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    let radius = [(x[3] + c2).max(0.0).sqrt(), (x[4] + c2).max(0.0).sqrt()];
    let mut e2: Vec<f64> = local
        .iter()
        .map(|l| {
            let dev = |k: usize| {
                let d = (0..3)
                    .map(|i| (l[k][i] - origin[i] - c[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                d - radius[k]
            };
            0.5 * (dev(0).powi(2) + dev(1).powi(2))
        })
        .collect();
    Some((
        quantile(&mut e2, QUANTILE).sqrt(),
        0.5 * (radius[0] + radius[1]),
    ))
}

/// The two-marker part of `cache`'s cluster (≥ 5 markers, at most `max_markers`) with the
/// smallest pooled σ against the rest, as a mask of cluster positions, and its evidence.
/// Frames are read as [`pair_evidence`] reads them (`max_spin_deg`). Only the pooled σ ranks
/// the cuts, so only the best is weighed (the next where no centre fits it).
pub(crate) fn best_pair(
    cache: &mut PartCache<'_>,
    max_markers: usize,
    max_spin_deg: f64,
) -> Option<(u64, PairEvidence)> {
    let n = cache.cluster.len();
    if n < 5 || n > max_markers.min(63) {
        return None;
    }
    let mut ranked: Vec<(f64, u64)> = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let mask = (1u64 << i) | (1u64 << j);
            if let Some(r) = read_pair(cache, mask, max_spin_deg) {
                ranked.push((r.pooled_sigma_mm, mask));
            }
        }
    }
    // Stable: among equal σ the first in enumeration order.
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    ranked.into_iter().find_map(|(_, mask)| {
        let e = pair_evidence(cache, mask, max_spin_deg)?;
        Some((mask, e))
    })
}

#[cfg(test)]
mod tests {
    use mocap_io::Trajectories;

    use super::{PairEvidence, PairTest};
    use crate::fitsplit::typical_sigma;
    use crate::jointsplit::{JointTest, split_by_joint};
    use crate::pairstats::pair_stats;

    /// A parent of three markers (`parent`) and a child of two hinged to it at the origin
    /// about x, swinging ±`swing_deg`, all translating; each marker carries smooth skin of
    /// up to `skin_mm` swept with the joint angle (half its body's direction, half its own,
    /// as the generator's) and ±0.5 mm of noise.
    fn capture(parent: &[[f64; 3]; 3], swing_deg: f64, skin_mm: f64, seed: u64) -> Trajectories {
        let child = [[30.0, 35.0, -150.0], [-40.0, 5.0, -240.0]];
        crate::testscene::skin_hinged_capture(parent, &child, swing_deg, skin_mm, seed)
    }

    const SPREAD: [[f64; 3]; 3] = [
        [40.0, 0.0, 150.0],
        [-35.0, 30.0, 220.0],
        [10.0, -40.0, 290.0],
    ];

    /// The clusters `split_by_joint` leaves of all five markers, sorted, with the
    /// parameters' joint test and the pair route on or off.
    fn split(traj: &Trajectories, pair_route: bool) -> Vec<Vec<usize>> {
        let p = crate::Params::default();
        let typical = typical_sigma(traj, &[vec![0, 1, 2], vec![3, 4]]);
        let test = JointTest {
            min_z: p.joint_split_z,
            min_travel_z: p.joint_travel_z,
            rotation_travel_z: p.joint_rotation_travel_z,
            rotation_alone_z: p.joint_rotation_alone_z,
            centre_fraction: p.joint_centre_fraction,
            pair: PairTest {
                on: pair_route,
                min_travel_z: p.joint_travel_z,
                min_swing_z: p.joint_split_z,
                swing_travel_z: p.joint_rotation_travel_z,
                centre_fraction: p.joint_pair_centre_fraction,
                max_spin_deg: p.joint_pair_max_spin_deg,
            },
            typical_sigma_mm: typical,
            max_part_sigma_mm: p.segment_sigma_mm(typical),
        };
        let stats = pair_stats(traj);
        let mut parts = split_by_joint(traj, &stats, 10, &[0, 1, 2, 3, 4], test);
        parts.iter_mut().for_each(|p| p.sort_unstable());
        parts.sort();
        parts
    }

    /// Three markers and a two-marker child at a ±20° hinge under 5 mm of skin: the joint
    /// test alone cannot cut 3 + 2, the pair route cuts at the joint; the same five markers
    /// on one rigid body stay whole (several skin draws).
    #[test]
    fn a_pair_hinged_to_a_body_splits_off_and_a_rigid_one_does_not() {
        let whole = vec![vec![0, 1, 2, 3, 4]];
        for seed in 1..=3 {
            let hinged = capture(&SPREAD, 20.0, 5.0, seed);
            assert_eq!(split(&hinged, false), whole, "seed {seed}: no route");
            assert_eq!(
                split(&hinged, true),
                vec![vec![0, 1, 2], vec![3, 4]],
                "seed {seed}"
            );
            let rigid = capture(&SPREAD, 0.0, 5.0, seed);
            assert_eq!(split(&rigid, true), whole, "seed {seed}: rigid");
        }
    }

    /// A body of three markers within a millimetre of one line spins about it by far
    /// more than its linearised covariance says, swinging a pair on one rigid body with it
    /// about that line: the route refuses to read such a body's frame.
    #[test]
    fn a_body_in_a_line_is_not_read() {
        let line = [[0.0, 0.0, 150.0], [0.8, 0.5, 220.0], [-0.5, 0.8, 290.0]];
        for seed in 1..=3 {
            let rigid = capture(&line, 0.0, 5.0, seed);
            assert_eq!(
                split(&rigid, true),
                vec![vec![0, 1, 2, 3, 4]],
                "seed {seed}"
            );
        }
    }

    /// The route's bounds one at a time on evidence that passes: a pair far from the
    /// centre it "turns" about for its travel (a straight shuffle), one the centre does not
    /// explain, and one that neither travels nor turns enough.
    #[test]
    fn each_bound_of_the_route_can_refuse() {
        let test = PairTest {
            on: true,
            min_travel_z: 5.0,
            min_swing_z: 4.0,
            swing_travel_z: 2.5,
            centre_fraction: 0.3,
            max_spin_deg: 20.0,
        };
        let joint = PairEvidence {
            travel_mm: 40.0,
            travel_z: 6.0,
            centre_mm: 4.0,
            radius_mm: 120.0,
            swing_deg: 15.0,
            swing_z: 3.0,
            pooled_sigma_mm: 2.0,
            body_sigma_mm: 2.0,
            pair_sigma_mm: 2.0,
            body_spin_deg: 5.0,
        };
        assert!(joint.is_joint(&test, 4.0));
        assert!(!joint.is_joint(&PairTest { on: false, ..test }, 4.0), "off");
        assert!(
            !PairEvidence {
                swing_z: 1.5,
                ..joint
            }
            .is_joint(&test, 4.0),
            "travels unturned"
        );
        let turns = PairEvidence {
            travel_z: 3.0,
            swing_z: 4.5,
            ..joint
        };
        assert!(turns.is_joint(&test, 4.0), "turns with some travel");
        assert!(
            !PairEvidence {
                travel_z: 2.0,
                ..turns
            }
            .is_joint(&test, 4.0),
            "turns in place"
        );
        assert!(
            !PairEvidence {
                travel_z: 4.5,
                ..joint
            }
            .is_joint(&test, 4.0),
            "too little travel"
        );
        assert!(
            !PairEvidence {
                radius_mm: 330.0,
                ..joint
            }
            .is_joint(&test, 4.0),
            "straight"
        );
        assert!(
            !PairEvidence {
                centre_mm: 13.0,
                ..joint
            }
            .is_joint(&test, 4.0),
            "no centre"
        );
        assert!(!joint.is_joint(&test, 1.5), "fits like no segment");
    }
}
