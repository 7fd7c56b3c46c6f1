//! The joint test: a cluster splits in two where its parts move as two rigid bodies
//! articulated about a point, not as one body with skin on it.
//!
//! Why not the fit scatter: skin artefact (5–15 mm, smooth) leaves a true segment's rigid-fit
//! σ as large as that of two segments joined at a low-motion joint (short segments, markers
//! near the joint), so no scatter threshold tells them apart. What tells them apart is how
//! the parts move relative to each other. Each part is posed per frame (Horn's method on
//! its own reference shape); the relative rotation A→B is
//! - on one body: the parts' rotation errors only, which the fits' own residuals predict
//!   (a part's rotation variance is its residual variance × trace of the inverse inertia
//!   tensor of its markers, linearised least squares);
//! - across a joint: the joint's sweep, tens of degrees, and coherent: B turns as a whole
//!   about a point fixed in A (SCoRE: R_A c_A + t_A = R_B c_B + t_B in every frame).
//!
//! A cluster splits when the relative rotation's deviation from its mean, weighed by the
//! covariance the parts' rotation errors would have on one body (σ² J⁻¹ per part, σ the
//! capture's typical segment fit σ, J the inertia tensor of the part's markers the frame
//! saw: a near-collinear part's spin about its own line counts for little, and a part
//! missing a marker for a while poses worse there), has a robust Mahalanobis length above
//! `joint_split_z` while the worse posed part's centroid travels in the other's frame
//! beyond one body's (`joint_rotation_travel_z`: a part's pose error turns it about its
//! own centroid, which then stays put, where a joint swings the centroid about the joint;
//! a rotation above `joint_rotation_alone_z` needs no travel, as no pose error turns a part
//! that far), and a centre of rotation fixed in both parts explains the parts' relative
//! translation (its residual is at most `joint_centre_fraction` of it). A part of three
//! markers nearly in line with a hinge's axis poses the hinge's rotation badly (its J⁻¹ is
//! large about that line), so the test also weighs where a part goes: the worse
//! posed part's centroid in the better posed part's frame, against the covariance both
//! centroids' errors and the frame's rotation error give it on one body (`joint_travel_z`).
//! The bipartition tried is the one two free rigid bodies fit best
//! (smallest pooled σ): every bipartition into parts of ≥ 3 markers up to
//! [`MAX_ENUMERATED`] markers; above that, the cuts of the spectral bisection of the
//! cluster's ρ affinity, refined by single-marker moves. Each part is split again. Where no
//! such cut passes, a sparse marker set's cluster may still lose a pair of markers by the
//! pair route (`pairsplit`).

use std::collections::{BTreeMap, BTreeSet};

use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::eigen::symmetric_eigen;
use crate::eigen4::largest_eigenpair4;
use crate::fitsplit::{QUANTILE, median_distances, quantile, reference_shape};
use crate::pairsplit::{self, PairTest};
use crate::pairstats::PairStats;
use crate::reassign::{Pose, horn, inertia_det, inertia_tensor, invert3, rotation_matrix};
use crate::rigidity::merge_best_pairs;
use crate::segmentation::NearJoint;

/// Fewest markers in a part: three pose a body's rotation fully.
pub(crate) const MIN_PART: usize = 3;

/// Largest cluster whose bipartitions are all tried.
const MAX_ENUMERATED: usize = 8;

/// Most rounds of single-marker moves refining a bipartition of a larger cluster (each
/// round tries every marker; a few keep the time bounded on dense marker sets).
const MAX_MOVES: usize = 4;

/// At most this many frames, evenly strided, are posed (motion is smooth at capture rates).
const MAX_FRAMES: usize = 1000;

/// How two parts of a cluster move relative to each other (the joint test's evidence).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointEvidence {
    /// Robust spread of the relative rotation about its mean, degrees.
    pub rotation_deg: f64,
    /// The spread the parts' own fit errors predict on one rigid body, degrees.
    pub noise_deg: f64,
    /// Robust residual of the best centre of rotation fixed in both parts, mm.
    pub centre_mm: f64,
    /// Robust spread of part B's centroid about its median in part A's frame, mm.
    pub translation_mm: f64,
    /// Pooled robust rigid-fit σ of the two parts as free bodies, mm per coordinate.
    pub pooled_sigma_mm: f64,
    /// The larger of the two parts' own robust rigid-fit σ, mm per coordinate.
    pub part_sigma_mm: f64,
    /// Rotation noise per mm of marker σ on both parts, degrees per mm: √(tr J_A⁻¹ + tr J_B⁻¹).
    pub gain_deg_per_mm: f64,
    /// Robust Mahalanobis length of the relative rotation's deviation from its mean under the
    /// parts' rotation covariances (σ² J⁻¹ each, σ the typical segment's), dimensionless:
    /// about 2 on one rigid body (√ of χ²₃'s 75th percentile), more across a joint.
    pub rotation_z: f64,
    /// Robust Mahalanobis length of the travel of one part's centroid in the frame of the
    /// other (the better posed: smaller trace of J⁻¹), under the covariance the parts' fit
    /// errors give it on one rigid body, dimensionless: about 2 on one body. It sees a joint
    /// whose rotation one part cannot pose (three markers in a line along the axis) by
    /// where that part goes.
    pub translation_z: f64,
}

impl JointEvidence {
    /// Whether the evidence says articulation: two rigid parts (each fit σ within
    /// `max_part_sigma_mm`) whose relative rotation has a Mahalanobis length above `min_z`
    /// (with a centroid travel above `rotation.0` unless the length is above `rotation.1`)
    /// or one's centroid travels in the other's frame by one above `min_travel_z`,
    /// about a point fixed in both (residual within `centre_fraction` of the relative
    /// translation).
    /// A `min_travel_z` of 0 leaves the centroid's travel out, a `rotation.0` of 0 lets a
    /// rotation count with any travel, a `rotation.1` of 0 never without one.
    pub fn is_joint(
        &self,
        min_z: f64,
        min_travel_z: f64,
        rotation: (f64, f64),
        centre_fraction: f64,
        max_part_sigma_mm: f64,
    ) -> bool {
        let (rotation_travel_z, rotation_alone_z) = rotation;
        let carried = self.translation_z > rotation_travel_z
            || (rotation_alone_z > 0.0 && self.rotation_z > rotation_alone_z);
        ((self.rotation_z > min_z && carried)
            || (min_travel_z > 0.0 && self.translation_z > min_travel_z))
            && self.centre_mm <= centre_fraction * self.translation_mm
            && self.part_sigma_mm <= max_part_sigma_mm
    }
}

/// One part of a cluster posed per strided frame.
pub(crate) struct PartFit {
    /// Pose per strided frame (`None` with fewer than 3 visible markers).
    pub(crate) poses: Vec<Option<Pose>>,
    /// Residual sum of squares and degrees of freedom per strided frame.
    pub(crate) residuals: Vec<(f64, f64)>,
    /// Robust residual variance per coordinate, mm².
    pub(crate) var: f64,
    /// Trace of the inverse inertia tensor of the part's shape, 1/mm²: rotation variance
    /// (rad²) per unit of residual variance.
    rot_gain: f64,
    /// Which of the shape's markers each strided frame's pose saw (bit k: `shape[k]`).
    pub(crate) seen: Vec<u64>,
    /// The geometry of each set of markers some frame was posed from (by its bit mask,
    /// ascending; `None` when collinear): a frame that misses a marker poses the part from
    /// the others alone.
    geometries: Vec<(u64, Option<SeenGeometry>)>,
}

impl PartFit {
    /// The geometry of the markers a frame was posed from (its `seen` mask).
    pub(crate) fn geometry(&self, seen: u64) -> Option<SeenGeometry> {
        let k = self
            .geometries
            .binary_search_by_key(&seen, |&(m, _)| m)
            .ok()?;
        self.geometries[k].1
    }
}

/// Where a part's markers seen in a frame put its pose errors (shape coordinates).
#[derive(Clone, Copy)]
pub(crate) struct SeenGeometry {
    /// Their centroid, mm: the pose's translation error is theirs.
    pub(crate) centroid: [f64; 3],
    /// The inverse of their inertia tensor about it, 1/mm².
    pub(crate) inv_inertia: [[f64; 3]; 3],
    /// How many.
    pub(crate) count: usize,
    /// The largest eigenvalue of `inv_inertia`, 1/mm²: rotation variance about the worst
    /// posed axis per unit of marker variance.
    pub(crate) worst_axis_gain: f64,
}

/// The geometry of the shape's markers set in `seen`; `None` when they are fewer than three
/// or collinear.
fn seen_geometry(shape: &[[f64; 3]], seen: u64) -> Option<SeenGeometry> {
    let points: Vec<[f64; 3]> = shape
        .iter()
        .enumerate()
        .filter(|(k, _)| (seen >> k) & 1 == 1)
        .map(|(_, p)| *p)
        .collect();
    let count = points.len();
    if count < 3 {
        return None;
    }
    let mut centroid = [0.0; 3];
    points
        .iter()
        .for_each(|p| (0..3).for_each(|i| centroid[i] += p[i] / count as f64));
    let inv_inertia = inverse_inertia(&points)?;
    Some(SeenGeometry {
        centroid,
        inv_inertia,
        count,
        worst_axis_gain: largest_eigenvalue(&inv_inertia),
    })
}

/// The largest eigenvalue of a symmetric 3 × 3 matrix (infinite when it is not finite).
fn largest_eigenvalue(m: &[[f64; 3]; 3]) -> f64 {
    if !m.iter().flatten().all(|x| x.is_finite()) {
        return f64::INFINITY;
    }
    let flat: Vec<f64> = m.iter().flatten().copied().collect();
    symmetric_eigen(&flat, 3)
        .ok()
        .and_then(|s| s.values.first().copied())
        .unwrap_or(f64::INFINITY)
}

/// Trace of the inverse of the inertia tensor of `shape` about its centroid, 1/mm²;
/// infinite when the points are collinear.
fn inverse_inertia_trace(shape: &[[f64; 3]]) -> f64 {
    let (_, j) = inertia_tensor(shape);
    let Some(det) = inertia_det(&j) else {
        return f64::INFINITY;
    };
    // trace(J⁻¹) = sum of the principal 2×2 minors over det.
    let minors = (j[1][1] * j[2][2] - j[1][2] * j[2][1])
        + (j[0][0] * j[2][2] - j[0][2] * j[2][0])
        + (j[0][0] * j[1][1] - j[0][1] * j[1][0]);
    minors / det
}

/// Inverse of the inertia tensor of `shape` about its centroid, 1/mm²; `None` when the
/// points are collinear.
pub(crate) fn inverse_inertia(shape: &[[f64; 3]]) -> Option<[[f64; 3]; 3]> {
    invert3(&inertia_tensor(shape).1)
}

/// Poses per strided frame, each frame's residual (sum of squares mm², dof) and the
/// markers it saw (bit mask over the part's markers).
type PosedFrames = (Vec<Option<Pose>>, Vec<(f64, f64)>, Vec<u64>);

/// Poses the markers at `positions` of `cluster` (pair distances `dist`) in every strided
/// frame, with the shape's handedness that fits better; `None` without a reference shape.
fn part_fit(
    traj: &Trajectories,
    cluster: &[usize],
    dist: &[f64],
    positions: &[usize],
    stride: usize,
) -> Option<PartFit> {
    let shape = reference_shape(dist, cluster.len(), positions)?;
    let mirrored: Vec<[f64; 3]> = shape.iter().map(|p| [-p[0], p[1], p[2]]).collect();
    let markers = traj.markers().max(1);
    let mut best: Option<(f64, usize, PosedFrames)> = None;
    for (handedness, candidate) in [&shape, &mirrored].into_iter().enumerate() {
        let mut p = Vec::with_capacity(positions.len());
        let mut q = Vec::with_capacity(positions.len());
        let mut total = 0.0;
        let mut poses = Vec::new();
        let mut residuals = Vec::new();
        let mut seen_frames = Vec::new();
        for frame in traj.positions().chunks_exact(markers).step_by(stride) {
            p.clear();
            q.clear();
            let mut seen = 0u64;
            for (a, &pos) in positions.iter().enumerate() {
                if let Some(&x) = cluster.get(pos).and_then(|&m| frame.get(m))
                    && mocap_io::is_present(x)
                {
                    p.push(candidate[a]);
                    q.push(x);
                    seen |= 1 << a;
                }
            }
            seen_frames.push(seen);
            if p.len() >= 3 {
                let (pose, ss) = horn(&p, &q);
                total += ss;
                poses.push(Some(pose));
                residuals.push((ss, (3 * p.len() - 6) as f64));
            } else {
                poses.push(None);
                residuals.push((0.0, 0.0));
            }
        }
        if best.as_ref().is_none_or(|b| total < b.0) {
            best = Some((total, handedness, (poses, residuals, seen_frames)));
        }
    }
    let (_, handedness, (poses, residuals, seen)) = best?;
    let mut v: Vec<f64> = residuals
        .iter()
        .filter(|r| r.1 > 0.0)
        .map(|r| r.0 / r.1)
        .collect();
    let shape = if handedness == 0 { shape } else { mirrored };
    let mut masks: Vec<u64> = seen
        .iter()
        .copied()
        .filter(|m| m.count_ones() >= 3)
        .collect();
    masks.sort_unstable();
    masks.dedup();
    let geometries = masks
        .into_iter()
        .map(|mask| (mask, seen_geometry(&shape, mask)))
        .collect();
    Some(PartFit {
        poses,
        residuals,
        var: quantile(&mut v, QUANTILE),
        rot_gain: inverse_inertia_trace(&shape),
        seen,
        geometries,
    })
}

/// Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method).
fn quaternion(r: &[[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > r[0][0].max(r[1][1]).max(r[2][2]) {
        let s = 2.0 * (1.0 + tr).sqrt();
        [
            0.25 * s,
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
        ]
    } else if r[0][0] >= r[1][1] && r[0][0] >= r[2][2] {
        let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
        [
            (r[2][1] - r[1][2]) / s,
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
        ]
    } else if r[1][1] >= r[2][2] {
        let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
        [
            (r[0][2] - r[2][0]) / s,
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
        ]
    } else {
        let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
        [
            (r[1][0] - r[0][1]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
        ]
    };
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
    q.map(|x| x / n)
}

/// Rotation vector (radians, axis × angle) of `q` relative to `mean`, i.e. of q ⊗ mean⁻¹,
/// expressed in the frame both act in.
fn deviation_vector(mean: [f64; 4], q: [f64; 4]) -> [f64; 3] {
    // d = q * conj(mean).
    let [w1, x1, y1, z1] = q;
    let [w2, x2, y2, z2] = [mean[0], -mean[1], -mean[2], -mean[3]];
    let mut d = [
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ];
    if d[0] < 0.0 {
        d = d.map(|x| -x);
    }
    let s = (d[1] * d[1] + d[2] * d[2] + d[3] * d[3]).sqrt();
    if s < 1e-15 {
        return [0.0; 3];
    }
    let angle = 2.0 * s.atan2(d[0]);
    [d[1] / s * angle, d[2] / s * angle, d[3] / s * angle]
}

/// `aᵀ b` for row-major 3 × 3 matrices.
fn transpose_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[k][i] * b[k][j]).sum()))
}

/// `m v`, or `mᵀ v` with `transpose`.
fn apply(m: &[[f64; 3]; 3], v: [f64; 3], transpose: bool) -> [f64; 3] {
    std::array::from_fn(|i| {
        (0..3)
            .map(|k| if transpose { m[k][i] } else { m[i][k] } * v[k])
            .sum()
    })
}

/// Solves the symmetric positive (semi)definite 6 × 6 system `a x = b` by Gaussian
/// elimination with partial pivoting; `None` when singular.
fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    for col in 0..6 {
        let pivot = (col..6).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        if a[pivot][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..6 {
            let f = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (x, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 6];
    for row in (0..6).rev() {
        let s: f64 = (row + 1..6).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    Some(x)
}

/// Ridge weight of the SCoRE system per frame: pins only the directions the motion leaves
/// undetermined (a hinge's axis; everything, on one rigid body) to the parts' midpoint.
const CENTRE_RIDGE: f64 = 1e-4;

/// The joint evidence of parts `a` and `b` (posed per strided frame).
fn evidence(a: &PartFit, b: &PartFit, typical_var: f64) -> Option<JointEvidence> {
    // The frames both parts were posed in, and which markers each was posed from there.
    let mut both: Vec<(&Pose, &Pose)> = Vec::with_capacity(a.poses.len());
    let mut seen: Vec<(u64, u64)> = Vec::with_capacity(a.poses.len());
    for ((x, y), (&sa, &sb)) in a.poses.iter().zip(&b.poses).zip(a.seen.iter().zip(&b.seen)) {
        if let (Some(x), Some(y)) = (x, y) {
            both.push((x, y));
            seen.push((sa, sb));
        }
    }
    if both.len() < 3 {
        return None;
    }
    // Relative rotation per frame and its mean (the top eigenvector of Σ q qᵀ; Markley).
    let rel: Vec<[f64; 4]> = both
        .iter()
        .map(|(pa, pb)| quaternion(&transpose_mul(&pa.r, &pb.r)))
        .collect();
    let mut m = [[0.0; 4]; 4];
    for q in &rel {
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += q[i] * q[j];
            }
        }
    }
    let (_, mean) = largest_eigenpair4(m);
    let mut phi2: Vec<f64> = rel
        .iter()
        .map(|q| {
            let dot = (0..4).map(|i| q[i] * mean[i]).sum::<f64>().abs().min(1.0);
            (2.0 * dot.acos()).powi(2)
        })
        .collect();
    let rotation = quantile(&mut phi2, QUANTILE).sqrt();
    // The parts' rotation noise from the capture's typical segment σ, not their own: a
    // part's own residual has few degrees of freedom (3k − 6 per skin pattern, and skin is
    // one pattern swept by the joint angle), and the bipartition chosen for its small
    // residual would have its noise underestimated.
    // Never below a part's own residual either: a part with a sliding marker is posed worse.
    let (var_a, var_b) = (a.var.max(typical_var), b.var.max(typical_var));
    let noise = (var_a * a.rot_gain + var_b * b.rot_gain).sqrt();
    // Covariance of the deviation's rotation vector (in A's frame): A's σ² J_A⁻¹, and B's
    // σ² J_B⁻¹ carried into A's frame by the mean relative rotation; each J of the markers
    // the frame was posed from, so a part that misses a marker for a while is not taken
    // for as steady as all of it (a frame whose seen markers are collinear adds nothing).
    let qm = rotation_matrix(mean);
    let covariance = |ja: &[[f64; 3]; 3], jb: &[[f64; 3]; 3]| -> [[f64; 3]; 3] {
        let rb = carried(&qm, jb);
        std::array::from_fn(|i| std::array::from_fn(|j| var_a * ja[i][j] + var_b * rb[i][j]))
    };
    let mut weights = Vec::new();
    let mut d2: Vec<f64> = Vec::with_capacity(rel.len());
    for (q, &(sa, sb)) in rel.iter().zip(&seen) {
        let w = memo(&mut weights, (sa, sb), || {
            let (ga, gb) = (a.geometry(sa)?, b.geometry(sb)?);
            let c = covariance(&ga.inv_inertia, &gb.inv_inertia);
            c.iter()
                .flatten()
                .all(|x| x.is_finite())
                .then(|| invert3(&c))?
        });
        d2.push(w.map_or(0.0, |w| quadratic_form(&w, deviation_vector(mean, *q))));
    }
    let rotation_z = quantile(&mut d2, QUANTILE).max(0.0).sqrt();

    // SCoRE: R_A c_A + t_A = R_B c_B + t_B; normal equations Σ [I −Q; −Qᵀ I] x = Σ [R_Aᵀ d; −R_Bᵀ d],
    // d = t_B − t_A, with a small ridge toward the midpoint of the parts' centroids.
    let mut lhs = [[0.0; 6]; 6];
    let mut rhs = [0.0; 6];
    let mut prior = [0.0; 6];
    let mut local_b = Vec::with_capacity(both.len());
    for (pa, pb) in &both {
        let q = transpose_mul(&pa.r, &pb.r);
        let d: [f64; 3] = std::array::from_fn(|i| pb.t[i] - pa.t[i]);
        let da = apply(&pa.r, d, true);
        let db = apply(&pb.r, d, true);
        local_b.push(da);
        for i in 0..3 {
            lhs[i][i] += 1.0;
            lhs[i + 3][i + 3] += 1.0;
            for j in 0..3 {
                lhs[i][j + 3] -= q[i][j];
                lhs[j + 3][i] -= q[i][j];
            }
            rhs[i] += da[i];
            rhs[i + 3] -= db[i];
            // Midpoint t_A + d/2, in A's frame: R_Aᵀ d / 2; in B's: −R_Bᵀ d / 2.
            prior[i] += 0.5 * da[i];
            prior[i + 3] -= 0.5 * db[i];
        }
    }
    let count = both.len() as f64;
    let ridge = CENTRE_RIDGE * count;
    for i in 0..6 {
        lhs[i][i] += ridge;
        rhs[i] += ridge * prior[i] / count;
    }
    let x = solve6(lhs, rhs)?;
    let mut r2: Vec<f64> = both
        .iter()
        .map(|(pa, pb)| {
            let ca = apply(&pa.r, [x[0], x[1], x[2]], false);
            let cb = apply(&pb.r, [x[3], x[4], x[5]], false);
            (0..3)
                .map(|i| (ca[i] + pa.t[i] - cb[i] - pb.t[i]).powi(2))
                .sum()
        })
        .collect();
    let centre = quantile(&mut r2, QUANTILE).sqrt();
    // Part B's centroid in A's frame: how far it travels relative to A.
    let mid = median_point(&local_b);
    let mut t2: Vec<f64> = local_b
        .iter()
        .map(|l| (0..3).map(|i| (l[i] - mid[i]).powi(2)).sum())
        .collect();
    let translation = quantile(&mut t2, QUANTILE).sqrt();
    // In the frame of the better posed part: a near-collinear part spins about its own line
    // by more than the linearised covariance allows, and would swing the other's centroid.
    let translation_z = if a.rot_gain <= b.rot_gain {
        centroid_travel_z(
            &local_b,
            mid,
            seen.iter().copied(),
            (a, var_a),
            (b, var_b),
            &qm,
        )
    } else {
        let local_a: Vec<[f64; 3]> = both
            .iter()
            .map(|(pa, pb)| {
                let d: [f64; 3] = std::array::from_fn(|i| pa.t[i] - pb.t[i]);
                apply(&pb.r, d, true)
            })
            .collect();
        let into_b = std::array::from_fn(|i| std::array::from_fn(|j| qm[j][i]));
        let mid = median_point(&local_a);
        let seen_from_b = seen.iter().map(|&(sa, sb)| (sb, sa));
        centroid_travel_z(&local_a, mid, seen_from_b, (b, var_b), (a, var_a), &into_b)
    };
    let mut pooled: Vec<f64> = a
        .residuals
        .iter()
        .zip(&b.residuals)
        .filter(|(x, y)| x.1 + y.1 > 0.0)
        .map(|(x, y)| (x.0 + y.0) / (x.1 + y.1))
        .collect();
    Some(JointEvidence {
        rotation_deg: rotation.to_degrees(),
        noise_deg: noise.to_degrees(),
        centre_mm: centre,
        translation_mm: translation,
        pooled_sigma_mm: quantile(&mut pooled, QUANTILE).sqrt(),
        part_sigma_mm: a.var.max(b.var).sqrt(),
        gain_deg_per_mm: (a.rot_gain + b.rot_gain).sqrt().to_degrees(),
        rotation_z,
        translation_z,
    })
}

/// Per-coordinate median of `points`.
pub(crate) fn median_point(points: &[[f64; 3]]) -> [f64; 3] {
    let mut column = Vec::with_capacity(points.len());
    std::array::from_fn(|i| {
        column.clear();
        column.extend(points.iter().map(|p| p[i]));
        crate::fitsplit::median(&mut column)
    })
}

/// Robust Mahalanobis length of the travel of one part's centroid in the other's frame
/// (`local`, per frame) about its median `mid` ([`median_point`] of `local`), under the
/// covariance of one rigid body in each frame, from the markers each part was posed from
/// (`seen`: the frame part's mask, the other's): both poses' translation errors at those
/// markers' centroid (σ² / k each), the frame part's rotation error (σ² J⁻¹) swinging the
/// lever from there to `mid`, and the other's swinging its full centroid about its seen
/// one (carried into the frame part's frame by `carry`). With every marker seen, both seen
/// centroids are the full ones. A frame whose covariance is singular adds 0.
fn centroid_travel_z(
    local: &[[f64; 3]],
    mid: [f64; 3],
    seen: impl Iterator<Item = (u64, u64)>,
    (frame_part, frame_var): (&PartFit, f64),
    (other, other_var): (&PartFit, f64),
    carry: &[[f64; 3]; 3],
) -> f64 {
    let weight = |gf: SeenGeometry, go: SeenGeometry| {
        let lever: [f64; 3] = std::array::from_fn(|i| mid[i] - gf.centroid[i]);
        let position_var = frame_var / gf.count as f64 + other_var / go.count as f64;
        let own = lever_covariance(lever, frame_var, &gf.inv_inertia, position_var);
        let swing = lever_covariance(go.centroid.map(|x| -x), other_var, &go.inv_inertia, 0.0);
        let swing = carried(carry, &swing);
        let cov: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| own[i][j] + swing[i][j]));
        cov.iter()
            .flatten()
            .all(|x| x.is_finite())
            .then(|| invert3(&cov))?
    };
    let mut weights = Vec::new();
    let mut d2: Vec<f64> = local
        .iter()
        .zip(seen)
        .map(|(l, (sf, so))| {
            let w = memo(&mut weights, (sf, so), || {
                weight(frame_part.geometry(sf)?, other.geometry(so)?)
            });
            w.map_or(0.0, |w| {
                quadratic_form(&w, std::array::from_fn(|i| l[i] - mid[i]))
            })
        })
        .collect();
    quantile(&mut d2, QUANTILE).max(0.0).sqrt()
}

/// `r m rᵀ`: a covariance `m` in one frame carried into another by the rotation `r`.
fn carried(r: &[[f64; 3]; 3], m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let mut s = 0.0;
            for k in 0..3 {
                for l in 0..3 {
                    s += r[i][k] * m[k][l] * r[j][l];
                }
            }
            s
        })
    })
}

/// `vᵀ w v`.
fn quadratic_form(w: &[[f64; 3]; 3], v: [f64; 3]) -> f64 {
    (0..3)
        .map(|i| (0..3).map(|j| v[i] * w[i][j] * v[j]).sum::<f64>())
        .sum()
}

/// The value `cache` holds for `key`, computed by `make` the first time (a few keys: the
/// sets of markers frames were posed from).
fn memo<K: PartialEq + Copy, V: Copy>(
    cache: &mut Vec<(K, V)>,
    key: K,
    make: impl FnOnce() -> V,
) -> V {
    if let Some(&(_, v)) = cache.iter().find(|(k, _)| *k == key) {
        return v;
    }
    let v = make();
    cache.push((key, v));
    v
}

/// Covariance of a point at `lever` from a body's centroid under the body's rotation error
/// (`var` J⁻¹: δ = ε × lever, so [l]× Σ [l]×ᵀ) plus an isotropic `position_var` (mm²).
pub(crate) fn lever_covariance(
    lever: [f64; 3],
    var: f64,
    inv_inertia: &[[f64; 3]; 3],
    position_var: f64,
) -> [[f64; 3]; 3] {
    let cross = [
        [0.0, -lever[2], lever[1]],
        [lever[2], 0.0, -lever[0]],
        [-lever[1], lever[0], 0.0],
    ];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let mut s = if i == j { position_var } else { 0.0 };
            for k in 0..3 {
                for l in 0..3 {
                    s += cross[i][k] * var * inv_inertia[k][l] * cross[j][l];
                }
            }
            s
        })
    })
}

/// Frames used: every `stride`-th.
fn stride_of(traj: &Trajectories) -> usize {
    traj.frames().div_ceil(MAX_FRAMES).max(1)
}

/// A cluster's parts posed on demand, each subset (bit mask of cluster positions) once.
pub(crate) struct PartCache<'a> {
    pub(crate) traj: &'a Trajectories,
    pub(crate) cluster: &'a [usize],
    dist: Vec<f64>,
    pub(crate) stride: usize,
    /// The capture's typical segment fit variance, mm² (0: each part's own only).
    pub(crate) typical_var: f64,
    fits: BTreeMap<u64, Option<PartFit>>,
}

impl<'a> PartCache<'a> {
    pub(crate) fn new(traj: &'a Trajectories, cluster: &'a [usize], typical_sigma_mm: f64) -> Self {
        Self {
            traj,
            cluster,
            typical_var: typical_sigma_mm * typical_sigma_mm,
            dist: median_distances(traj, cluster),
            stride: stride_of(traj),
            fits: BTreeMap::new(),
        }
    }

    pub(crate) fn fit(&mut self, mask: u64) -> Option<&PartFit> {
        let (traj, cluster, stride) = (self.traj, self.cluster, self.stride);
        let dist = &self.dist;
        self.fits
            .entry(mask)
            .or_insert_with(|| {
                let positions: Vec<usize> = (0..cluster.len())
                    .filter(|&i| (mask >> i) & 1 == 1)
                    .collect();
                part_fit(traj, cluster, dist, &positions, stride)
            })
            .as_ref()
    }

    /// Evidence of the bipartition (`mask`, its complement).
    fn evidence(&mut self, mask: u64) -> Option<JointEvidence> {
        let full = (1u64 << self.cluster.len()) - 1;
        self.fit(mask)?;
        self.fit(full & !mask)?;
        let a = self.fits.get(&mask)?.as_ref()?;
        let b = self.fits.get(&(full & !mask))?.as_ref()?;
        evidence(a, b, self.typical_var)
    }
}

/// Pooled σ of a bipartition, for ranking (infinite when it cannot be posed).
fn pooled_of(cache: &mut PartCache<'_>, mask: u64) -> f64 {
    cache
        .evidence(mask)
        .map_or(f64::INFINITY, |e| e.pooled_sigma_mm)
}

/// Candidate masks of a cluster of more than [`MAX_ENUMERATED`] markers: the cuts of its
/// markers ordered along the Fiedler vector of their ρ affinity (local scaling).
fn spectral_cuts(stats: &PairStats, cluster: &[usize], min_overlap: usize) -> Vec<u64> {
    let n = cluster.len();
    let rho = |a: usize, b: usize| stats.rho(cluster[a], cluster[b], min_overlap);
    // Scale: ρ to the second nearest marker of the cluster (a marker's own skin level).
    let scales: Vec<f64> = (0..n)
        .map(|a| {
            let mut r: Vec<f64> = (0..n)
                .filter(|&b| b != a)
                .filter_map(|b| rho(a, b))
                .collect();
            r.sort_by(f64::total_cmp);
            r.get(1).or(r.first()).copied().unwrap_or(1.0).max(1e-3)
        })
        .collect();
    let mut w = vec![0.0; n * n];
    for a in 0..n {
        for b in 0..n {
            if a != b {
                w[a * n + b] = rho(a, b).map_or(0.0, |r| (-r * r / (scales[a] * scales[b])).exp());
            }
        }
    }
    let degree: Vec<f64> = (0..n)
        .map(|a| w[a * n..(a + 1) * n].iter().sum::<f64>().max(1e-12))
        .collect();
    let norm: Vec<f64> = (0..n * n)
        .map(|i| w[i] / (degree[i / n] * degree[i % n]).sqrt())
        .collect();
    let Ok(spectrum) = symmetric_eigen(&norm, n) else {
        return Vec::new();
    };
    // Second largest eigenvector of D^-½ W D^-½, back to D^-½ scaling.
    let mut order: Vec<usize> = (0..n).collect();
    let fiedler = |a: usize| spectrum.vectors[a * n + 1] / degree[a].sqrt();
    order.sort_by(|&x, &y| fiedler(x).total_cmp(&fiedler(y)).then(x.cmp(&y)));
    (MIN_PART..=n - MIN_PART)
        .map(|cut| order[..cut].iter().fold(0u64, |m, &i| m | (1 << i)))
        .collect()
}

/// The bipartition of `cluster` (as a mask of positions) with the smallest pooled σ into
/// parts of ≥ [`MIN_PART`] markers, and its evidence.
fn best_bipartition(
    cache: &mut PartCache<'_>,
    stats: &PairStats,
    min_overlap: usize,
) -> Option<(u64, JointEvidence)> {
    let n = cache.cluster.len();
    if !(2 * MIN_PART..=63).contains(&n) {
        return None;
    }
    let full = (1u64 << n) - 1;
    let valid = |mask: u64| {
        let k = mask.count_ones() as usize;
        k >= MIN_PART && n - k >= MIN_PART
    };
    let mut best: Option<(f64, u64)> = None;
    let consider = |cache: &mut PartCache<'_>, mask: u64, best: &mut Option<(f64, u64)>| {
        // Canonical: the first marker in A, so each bipartition has one mask.
        let mask = if mask & 1 == 1 { mask } else { full & !mask };
        let s = pooled_of(cache, mask);
        if s.is_finite() && best.is_none_or(|(b, m)| s < b || (s == b && mask < m)) {
            *best = Some((s, mask));
        }
        s
    };
    if n <= MAX_ENUMERATED {
        for half in 0u64..(1u64 << (n - 1)) {
            let mask = 1 | (half << 1);
            if valid(mask) {
                consider(cache, mask, &mut best);
            }
        }
    } else {
        for mask in spectral_cuts(stats, cache.cluster, min_overlap) {
            consider(cache, mask, &mut best);
        }
        // Single-marker moves while one lowers the pooled σ.
        for _ in 0..MAX_MOVES {
            let Some((current, mask)) = best else { break };
            let mut improved = false;
            for i in 0..n {
                let moved = mask ^ (1 << i);
                if valid(moved) && consider(cache, moved, &mut best) < current {
                    improved = true;
                }
            }
            if !improved {
                break;
            }
        }
    }
    let (_, mask) = best?;
    Some((mask, cache.evidence(mask)?))
}

/// The joint test's settings.
#[derive(Clone, Copy, Debug)]
pub(crate) struct JointTest {
    /// Mahalanobis length of the relative rotation that means articulation.
    pub min_z: f64,
    /// Mahalanobis length of a part's centroid travel that means articulation (0: unused).
    pub min_travel_z: f64,
    /// Least travel a rotation above `min_z` must come with to mean articulation (0: any).
    pub rotation_travel_z: f64,
    /// Rotation length above which no travel is needed (0: never).
    pub rotation_alone_z: f64,
    /// Largest SCoRE residual as a fraction of the parts' relative translation.
    pub centre_fraction: f64,
    /// The route for a part of two markers, tried where no cut into parts of ≥ 3 passes.
    pub pair: PairTest,
    /// The capture's typical segment fit σ, mm per coordinate (skin and noise).
    pub typical_sigma_mm: f64,
    /// Largest fit σ of a part, mm: a part must fit like an ordinary segment, or a marker
    /// from a third body (which swings with it) would pass for the joint.
    pub max_part_sigma_mm: f64,
}

impl JointTest {
    /// Whether `e` says articulation under this test.
    pub(crate) fn passes(&self, e: &JointEvidence) -> bool {
        e.is_joint(
            self.min_z,
            self.min_travel_z,
            (self.rotation_travel_z, self.rotation_alone_z),
            self.centre_fraction,
            self.max_part_sigma_mm,
        )
    }
}

/// Splits `cluster` (marker indices) while its best bipartition passes the joint test
/// (see the module docs), or where none does, while its best pair passes the pair route
/// (`pairsplit`); recursively.
pub(crate) fn split_by_joint(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    cluster: &[usize],
    test: JointTest,
) -> Vec<Vec<usize>> {
    let pair_route = test.pair.on && cluster.len() >= 5;
    if cluster.len() < 2 * MIN_PART && !pair_route {
        return vec![cluster.to_vec()];
    }
    let mut cache = PartCache::new(traj, cluster, test.typical_sigma_mm);
    let cut = best_bipartition(&mut cache, stats, min_overlap)
        .filter(|(_, e)| test.passes(e))
        .map(|(mask, _)| mask)
        .or_else(|| {
            // No cut into posable parts: a segment of two markers merged with its neighbour.
            if !pair_route {
                return None;
            }
            let (mask, e) =
                pairsplit::best_pair(&mut cache, pairsplit::MAX_MARKERS, test.pair.max_spin_deg)?;
            e.is_joint(&test.pair, test.max_part_sigma_mm)
                .then_some(mask)
        });
    match cut {
        Some(mask) => {
            let a: Vec<usize> = (0..cluster.len())
                .filter(|&i| (mask >> i) & 1 == 1)
                .map(|i| cluster[i])
                .collect();
            let b: Vec<usize> = (0..cluster.len())
                .filter(|&i| (mask >> i) & 1 == 0)
                .map(|i| cluster[i])
                .collect();
            let mut out = split_by_joint(traj, stats, min_overlap, &a, test);
            out.extend(split_by_joint(traj, stats, min_overlap, &b, test));
            out
        }
        _ => vec![cluster.to_vec()],
    }
}

/// Splits every cluster not in `tested` (markers ascending) by [`split_by_joint`], in
/// parallel, keeping the cluster order.
pub(crate) fn split_all(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    clusters: Vec<Vec<usize>>,
    test: JointTest,
    tested: &BTreeSet<Vec<usize>>,
) -> Vec<Vec<usize>> {
    clusters
        .par_iter()
        .map(|c| {
            if tested.contains(c) {
                vec![c.clone()]
            } else {
                split_by_joint(traj, stats, min_overlap, c, test)
            }
        })
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .collect()
}

/// When two clusters move as one rigid body (see [`merge_rigid`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RigidMerge {
    /// Only clusters with some marker pair within this ρ (mm) are compared.
    pub near_mm: f64,
    /// Joint test rotation score below which they are one body.
    pub max_z: f64,
    /// ... and centroid travel score (0: unused).
    pub max_travel_z: f64,
    /// Largest robust spread of the second's centroid in the first's frame, mm.
    pub max_translation_mm: f64,
    /// The capture's typical segment fit σ, mm per coordinate.
    pub typical_sigma_mm: f64,
}

/// Merges neighbouring clusters (≥ 3 markers each, some pair of their markers within
/// `near_mm` of ρ) whose relative motion is that of one rigid body: relative rotation below
/// `max_z` (a rigid body's best cut scores ≈ 2, true joints ≳ 4) and the second's centroid
/// steady in the first's frame within `max_translation_mm`. Clusters split by ρ or by the
/// fit split on skin alone come back together; the most rigid pair first, repeatedly.
pub(crate) fn merge_rigid(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    clusters: &mut Vec<Vec<usize>>,
    merge: RigidMerge,
) -> usize {
    let near = |a: &[usize], b: &[usize]| {
        a.iter().any(|&x| {
            b.iter().any(|&y| {
                stats
                    .rho(x, y, min_overlap)
                    .is_some_and(|r| r <= merge.near_mm)
            })
        })
    };
    merge_best_pairs(
        clusters,
        |a, b| a.len() >= MIN_PART && b.len() >= MIN_PART && a.len() + b.len() <= 63 && near(a, b),
        |a, b| {
            let e = evidence_of(traj, a, b, merge.typical_sigma_mm)?;
            (e.rotation_z < merge.max_z
                && (merge.max_travel_z <= 0.0 || e.translation_z < merge.max_travel_z)
                && e.translation_mm <= merge.max_translation_mm)
                .then_some(e.rotation_z)
        },
    )
}

/// Diagnostic: the joint evidence of parts `a` and `b` (marker indices, ≥ 3 each), rotation
/// noise from `typical_sigma_mm` (0: from each part's own fit).
pub(crate) fn evidence_of(
    traj: &Trajectories,
    a: &[usize],
    b: &[usize],
    typical_sigma_mm: f64,
) -> Option<JointEvidence> {
    let mut union = a.to_vec();
    union.extend(b);
    if union.len() > 63 {
        return None;
    }
    let mut cache = PartCache::new(traj, &union, typical_sigma_mm);
    cache.evidence((1u64 << a.len()) - 1)
}

/// The segments among `segments` (marker indices; ids are their indices) whose best cut
/// scores at least `fraction` of the test's rotation bound, or of its travel bound when it
/// has one, without being cut: possibly two segments that turn little about a joint.
/// Parts of ≥ [`MIN_PART`] markers, so segments of ≥ 6; in parallel, in segment order.
pub(crate) fn near_joints(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    segments: &[Vec<usize>],
    test: JointTest,
    fraction: f64,
) -> Vec<NearJoint> {
    segments
        .par_iter()
        .enumerate()
        .filter(|(_, markers)| markers.len() >= 2 * MIN_PART && markers.len() <= 63)
        .filter_map(|(segment, markers)| {
            let (mut a, mut b, e) =
                best_of(traj, stats, min_overlap, markers, test.typical_sigma_mm)?;
            let near = e.rotation_z >= fraction * test.min_z
                || (test.min_travel_z > 0.0 && e.translation_z >= fraction * test.min_travel_z);
            near.then(|| {
                a.sort_unstable();
                b.sort_unstable();
                if b.first() < a.first() {
                    std::mem::swap(&mut a, &mut b);
                }
                NearJoint {
                    segment,
                    parts: [a, b],
                    rotation_z: e.rotation_z,
                    travel_z: e.translation_z,
                }
            })
        })
        .collect()
}

/// Diagnostic: the bipartition the joint test weighs for `cluster` and its evidence.
pub(crate) fn best_of(
    traj: &Trajectories,
    stats: &PairStats,
    min_overlap: usize,
    cluster: &[usize],
    typical_sigma_mm: f64,
) -> Option<(Vec<usize>, Vec<usize>, JointEvidence)> {
    let mut cache = PartCache::new(traj, cluster, typical_sigma_mm);
    let (mask, e) = best_bipartition(&mut cache, stats, min_overlap)?;
    let a: Vec<usize> = (0..cluster.len())
        .filter(|&i| (mask >> i) & 1 == 1)
        .map(|i| cluster[i])
        .collect();
    let b: Vec<usize> = cluster.iter().copied().filter(|m| !a.contains(m)).collect();
    Some((a, b, e))
}

#[cfg(test)]
mod tests {
    use mocap_io::Trajectories;

    use super::{JointEvidence, JointTest, RigidMerge, merge_rigid, near_joints, split_by_joint};
    use crate::fitsplit::typical_sigma;
    use crate::pairstats::pair_stats;
    use crate::testscene::cut_at_gap;

    /// Eight markers: four on a parent, four on a child hinged at the origin (about x) that
    /// swings ±`swing_deg`, all translating; every marker carries smooth skin artefact of
    /// up to `skin_mm` (half its body's direction, half its own, swept by the joint angle as
    /// the generator's skin is).
    fn capture(swing_deg: f64, skin_mm: f64, seed: u64) -> Trajectories {
        let child = [
            [30.0, 35.0, -150.0],
            [-40.0, 5.0, -220.0],
            [25.0, -35.0, -290.0],
            [-15.0, 40.0, -360.0],
        ];
        capture_with_child(&child, swing_deg, skin_mm, seed)
    }

    /// As [`capture`], with the child's markers at `child` (hinge-local, mm).
    fn capture_with_child(
        child: &[[f64; 3]],
        swing_deg: f64,
        skin_mm: f64,
        seed: u64,
    ) -> Trajectories {
        let parent = [
            [40.0, 0.0, 150.0],
            [-35.0, 30.0, 220.0],
            [10.0, -40.0, 290.0],
            [-30.0, -25.0, 360.0],
        ];
        crate::testscene::skin_hinged_capture(&parent, child, swing_deg, skin_mm, seed)
    }

    /// A relative rotation well above the parts' pose noise that leaves the worse posed
    /// part's centroid where one body would keep it is that part spinning about its own
    /// centroid, not a joint; the same rotation with the centroid swinging is one.
    #[test]
    fn a_turn_that_carries_no_centroid_is_no_joint() {
        let spin = JointEvidence {
            rotation_z: 5.0,
            translation_z: 2.0,
            centre_mm: 2.5,
            translation_mm: 8.0,
            part_sigma_mm: 3.0,
            ..JointEvidence::default()
        };
        // The test's defaults but for the two rotation bounds.
        let joint =
            |e: &JointEvidence, rotation: (f64, f64)| e.is_joint(4.0, 5.0, rotation, 1.0, 6.0);
        assert!(joint(&spin, (0.0, 0.0)), "any travel");
        assert!(!joint(&spin, (2.5, 8.0)), "travel z 2 < 2.5");
        let swing = JointEvidence {
            translation_z: 3.0,
            ..spin
        };
        assert!(joint(&swing, (2.5, 8.0)), "travel z 3 > 2.5");
        let travel_alone = JointEvidence {
            rotation_z: 1.0,
            translation_z: 5.5,
            ..spin
        };
        assert!(
            joint(&travel_alone, (2.5, 8.0)),
            "joint_travel_z's own route"
        );
        // Far beyond what pose error turns a part (a long bone posed from markers near its
        // line swings the other's centroid through a wide covariance).
        let strong = JointEvidence {
            rotation_z: 9.0,
            ..spin
        };
        assert!(joint(&strong, (2.5, 8.0)), "z 9 > 8 needs no travel");
        assert!(!joint(&strong, (2.5, 0.0)), "0: always needs one");
    }

    fn split(traj: &Trajectories) -> Vec<Vec<usize>> {
        split_as(traj, &[vec![0, 1, 2, 3], vec![4, 5, 6, 7]])
    }

    /// [`split_by_joint`] on all of `traj`'s markers, the typical σ from the `truth` groups.
    fn split_as(traj: &Trajectories, truth: &[Vec<usize>]) -> Vec<Vec<usize>> {
        let stats = pair_stats(traj);
        let test = JointTest {
            min_z: 4.5,
            min_travel_z: 0.0,
            rotation_travel_z: 2.5,
            rotation_alone_z: 8.0,
            centre_fraction: 1.0,
            pair: crate::pairsplit::PairTest::default(),
            typical_sigma_mm: typical_sigma(traj, truth),
            max_part_sigma_mm: 2.0 * typical_sigma(traj, truth),
        };
        let all: Vec<usize> = (0..traj.markers()).collect();
        let mut parts = split_by_joint(traj, &stats, 10, &all, test);
        parts.iter_mut().for_each(|p| p.sort_unstable());
        parts.sort();
        parts
    }

    /// A merged pair at a ±15° hinge under 8 mm of skin artefact (markers 150–360 mm from
    /// the joint) splits at the joint; a rigid body with the same artefact stays whole
    /// (several skin draws).
    #[test]
    fn joint_splits_and_skin_does_not() {
        for seed in 1..=3 {
            let jointed = capture(15.0, 8.0, seed);
            assert_eq!(
                split(&jointed),
                vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]],
                "seed {seed}"
            );
            let rigid = capture(0.0, 8.0, seed);
            assert_eq!(
                split(&rigid),
                vec![(0..8).collect::<Vec<_>>()],
                "seed {seed}"
            );
        }
    }

    /// A marker an unlabeled capture cut at an occlusion into two pieces never seen together
    /// leaves a rigid body whole and a jointed one cut at its joint, the pieces together:
    /// a part with both is posed (their distance filled in by the rest of the shape), and a
    /// part posed without a marker for a while is not taken for as steady as all of it.
    #[test]
    fn pieces_of_one_marker_stay_together() {
        for seed in 1..=3 {
            for m in [1, 6] {
                let rigid = cut_at_gap(&capture(0.0, 8.0, seed), m, 150..170);
                let truth = [(0..9).collect::<Vec<_>>()];
                assert_eq!(split_as(&rigid, &truth), truth, "seed {seed}, marker {m}");
                let jointed = cut_at_gap(&capture(15.0, 8.0, seed), m, 150..170);
                let mut truth = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
                truth[usize::from(m >= 4)].push(8);
                assert_eq!(split_as(&jointed, &truth), truth, "seed {seed}, marker {m}");
            }
        }
    }

    /// The same two halves as separate clusters: merged when they are one rigid body under
    /// 8 mm of skin, kept apart across a ±15° hinge (several skin draws).
    #[test]
    fn rigid_halves_merge_and_jointed_ones_do_not() {
        for seed in 1..=3 {
            for (swing, merged) in [(0.0, true), (15.0, false)] {
                let traj = capture(swing, 8.0, seed);
                let stats = pair_stats(&traj);
                let mut clusters = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
                let typical = typical_sigma(&traj, &clusters);
                let merge = RigidMerge {
                    near_mm: 1e9,
                    max_z: 3.0,
                    max_travel_z: 0.0,
                    max_translation_mm: 4.0 * typical.max(1.0),
                    typical_sigma_mm: typical,
                };
                let n = merge_rigid(&traj, &stats, 10, &mut clusters, merge);
                assert_eq!(n == 1, merged, "seed {seed}, swing {swing}: {clusters:?}");
            }
        }
    }

    /// A three-marker child nearly in line with the hinge's axis (x), 40 mm off it, swinging
    /// ±20°: it poses that rotation badly, so the rotation score alone leaves parent + child
    /// whole, while its centroid swinging in the parent's frame splits them; the same markers
    /// on one rigid body stay whole with the travel score too (several noise draws).
    #[test]
    fn a_child_in_line_with_its_axis_splits_by_where_it_goes() {
        let child = [[-30.0, 40.0, -2.0], [0.0, 41.5, 1.0], [30.0, 39.0, 0.5]];
        for seed in 1..=3 {
            let parts = |swing: f64, min_travel_z: f64| {
                let traj = capture_with_child(&child, swing, 0.0, seed);
                let stats = pair_stats(&traj);
                let truth = vec![vec![0, 1, 2, 3], vec![4, 5, 6]];
                let typical = typical_sigma(&traj, &truth);
                let test = JointTest {
                    min_z: 4.0,
                    min_travel_z,
                    rotation_travel_z: 0.0,
                    rotation_alone_z: 0.0,
                    centre_fraction: 1.0,
                    pair: crate::pairsplit::PairTest::default(),
                    typical_sigma_mm: typical,
                    max_part_sigma_mm: 2.0 * typical.max(0.5),
                };
                let mut parts =
                    split_by_joint(&traj, &stats, 10, &(0..7).collect::<Vec<_>>(), test);
                parts.iter_mut().for_each(|p| p.sort_unstable());
                parts.sort();
                parts
            };
            let whole = vec![(0..7).collect::<Vec<_>>()];
            assert_eq!(parts(20.0, 0.0), whole, "seed {seed}: rotation alone");
            assert_eq!(
                parts(20.0, 5.0),
                vec![vec![0, 1, 2, 3], vec![4, 5, 6]],
                "seed {seed}: with the travel"
            );
            assert_eq!(parts(0.0, 5.0), whole, "seed {seed}: rigid");
        }
    }

    /// A hinge turning ±5° or ±6° under 8 mm of skin scores just under the joint test
    /// (rotation z 3.0 and 3.7 against 4 in this draw): the segment is listed as maybe two,
    /// cut at the hinge; the same markers on one rigid body are not. (In other draws skin
    /// puts the best cut of so small a turn elsewhere: the parts are the test's best cut.)
    #[test]
    fn a_joint_just_under_the_test_is_listed_and_a_rigid_body_is_not() {
        let seed = 6;
        for (swing, listed) in [(5.0, true), (6.0, true), (0.0, false)] {
            let traj = capture(swing, 8.0, seed);
            let stats = pair_stats(&traj);
            let truth = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
            // Rotation only: this draw's rigid body has its centroid travel at z 4.6.
            let test = JointTest {
                min_z: 4.0,
                min_travel_z: 0.0,
                rotation_travel_z: 0.0,
                rotation_alone_z: 0.0,
                centre_fraction: 1.0,
                pair: crate::pairsplit::PairTest::default(),
                typical_sigma_mm: typical_sigma(&traj, &truth),
                max_part_sigma_mm: 2.0 * typical_sigma(&traj, &truth),
            };
            let whole = vec![(0..8).collect::<Vec<usize>>()];
            assert_eq!(
                split_by_joint(&traj, &stats, 10, &whole[0], test),
                whole,
                "seed {seed}, swing {swing}: the test cuts it"
            );
            let near = near_joints(&traj, &stats, 10, &whole, test, 0.75);
            if listed {
                assert_eq!(near.len(), 1, "seed {seed}");
                assert_eq!(near[0].segment, 0);
                assert_eq!(near[0].parts, [vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
                assert!((3.0..4.0).contains(&near[0].rotation_z), "{:?}", near[0]);
            } else {
                assert!(near.is_empty(), "seed {seed}: {near:?}");
            }
        }
    }
}
