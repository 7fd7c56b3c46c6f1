//! Marker reassignment by rigid fit: each marker goes to the body whose motion explains its
//! trajectory clearly best.
//!
//! Why: ρ compares two markers at a time, and a joint with little motion changes a
//! cross-joint distance by no more than skin artefact changes a same-segment one, so a
//! single marker near a joint (a paw marker, a hand marker) can sit on the wrong side of it
//! after clustering; the fit split cannot move it (its parts have ≥ 2 markers). Here every
//! cluster of ≥ 3 markers is posed in every frame (Horn's quaternion method against its
//! reference shape), and a marker's trajectory is expressed in each body's frame: on its
//! own body it stays put up to skin and noise; on a neighbour it swings about the joint by
//! lever arm × angle, first order in the angle. A marker moves when another body holds it
//! still `ratio` times better than its own body does without it (leave-one-out).

use mocap_io::Trajectories;
use rayon::prelude::*;

pub(crate) use crate::eigen4::rotation_matrix;
use crate::eigen4::{det3, horn_matrix, largest_eigenpair4};
use crate::fitsplit::{QUANTILE, core_shape, median, median_distances, quantile, reference_shape};
use crate::pairstats::PairStats;
use crate::rigidity::{DONOR_KEEPS, rms_rho};

/// Most reassignment sweeps (pose every body, then move); moves only ever follow a clear
/// improvement, so a few do.
const MAX_SWEEPS: usize = 4;

/// At most this many frames, evenly strided, are used to pose bodies: motion is smooth at
/// capture rates, so a stride keeps the statistics and bounds the time on long captures.
const MAX_FRAMES: usize = 1500;

/// A body's pose in one frame: position ≈ r · (shape point) + t, mm.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pose {
    /// Rotation, row-major.
    pub r: [[f64; 3]; 3],
    /// Translation, mm.
    pub t: [f64; 3],
}

impl Pose {
    /// `x` (global, mm) in the body's frame: Rᵀ (x − t).
    pub(crate) fn local(&self, x: [f64; 3]) -> [f64; 3] {
        let d = [x[0] - self.t[0], x[1] - self.t[1], x[2] - self.t[2]];
        std::array::from_fn(|i| (0..3).map(|j| self.r[j][i] * d[j]).sum())
    }
}

/// A cluster posed as one rigid body: its reference shape (segment-local, mm; the
/// handedness that fits) and its pose per strided frame (`None` with < 3 visible markers).
struct Body {
    shape: Vec<[f64; 3]>,
    poses: Vec<Option<Pose>>,
    /// Residual variance of the fit per coordinate (sum of squares over dof), mm².
    var: f64,
}

/// Centroid and inertia tensor `Σ (|d|² I − d dᵀ)` (d = point − centroid) of `shape`, mm².
pub(crate) fn inertia_tensor(shape: &[[f64; 3]]) -> ([f64; 3], [[f64; 3]; 3]) {
    let k = shape.len().max(1) as f64;
    let mut c = [0.0; 3];
    shape
        .iter()
        .for_each(|p| (0..3).for_each(|i| c[i] += p[i] / k));
    let mut j = [[0.0; 3]; 3];
    for p in shape {
        let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        let n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        for (a, row) in j.iter_mut().enumerate() {
            for (b, v) in row.iter_mut().enumerate() {
                *v += if a == b { n2 } else { 0.0 } - d[a] * d[b];
            }
        }
    }
    (c, j)
}

/// Inverse of a 3 × 3 matrix by cofactors; `None` when (nearly) singular.
pub(crate) fn invert3(j: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = det3(j);
    let scale = j
        .iter()
        .flatten()
        .map(|x| x.abs())
        .fold(0.0, f64::max)
        .max(1e-300);
    if det.abs() <= 1e-12 * scale * scale * scale {
        return None;
    }
    Some([
        [
            (j[1][1] * j[2][2] - j[1][2] * j[2][1]) / det,
            (j[0][2] * j[2][1] - j[0][1] * j[2][2]) / det,
            (j[0][1] * j[1][2] - j[0][2] * j[1][1]) / det,
        ],
        [
            (j[1][2] * j[2][0] - j[1][0] * j[2][2]) / det,
            (j[0][0] * j[2][2] - j[0][2] * j[2][0]) / det,
            (j[0][2] * j[1][0] - j[0][0] * j[1][2]) / det,
        ],
        [
            (j[1][0] * j[2][1] - j[1][1] * j[2][0]) / det,
            (j[0][1] * j[2][0] - j[0][0] * j[2][1]) / det,
            (j[0][0] * j[1][1] - j[0][1] * j[1][0]) / det,
        ],
    ])
}

/// Determinant of an inertia tensor, or `None` when its points are (nearly) collinear:
/// |det| within 1e-9 × trace³.
pub(crate) fn inertia_det(j: &[[f64; 3]; 3]) -> Option<f64> {
    let det = det3(j);
    let scale = (j[0][0] + j[1][1] + j[2][2]).max(1e-300);
    (det.abs() > 1e-9 * scale * scale * scale).then_some(det)
}

/// How much a pose fitted to `shape` (≥ 3 points, mm) misplaces a point at `x` (same frame),
/// per unit of the markers' residual variance: the leverage 1/k + mean over axes of
/// [r]× J⁻¹ [r]×ᵀ (r = x − centroid, J the points' inertia tensor), the variance of the
/// predicted position over the marker noise (linearised least squares). Infinite when the
/// points are collinear (the rotation about their line is not determined).
fn leverage(shape: &[[f64; 3]], x: [f64; 3]) -> f64 {
    let k = shape.len() as f64;
    let (c, j) = inertia_tensor(shape);
    // `invert3`'s own singularity margin is looser than `inertia_det`'s.
    let Some(inv) = inertia_det(&j).and_then(|_| invert3(&j)) else {
        return f64::INFINITY;
    };
    let r = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
    let cross = [[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]];
    // trace(C J⁻¹ Cᵀ) = Σ_a Σ_b Σ_c C[a][b] J⁻¹[b][c] C[a][c].
    let mut tr = 0.0;
    for row in &cross {
        for b in 0..3 {
            for c2 in 0..3 {
                tr += row[b] * inv[b][c2] * row[c2];
            }
        }
    }
    1.0 / k + tr / 3.0
}

/// Frames used: every `stride`-th.
pub(crate) fn stride_of(traj: &Trajectories) -> usize {
    traj.frames().div_ceil(MAX_FRAMES).max(1)
}

/// Least-squares rigid pose mapping `p` (shape points) onto `q` (positions), Horn's
/// quaternion method, and its residual sum of squares (mm²). Needs `p.len() == q.len() ≥ 1`.
pub(crate) fn horn(p: &[[f64; 3]], q: &[[f64; 3]]) -> (Pose, f64) {
    let k = p.len().min(q.len()).max(1) as f64;
    let centroid = |v: &[[f64; 3]]| {
        let mut c = [0.0; 3];
        v.iter().for_each(|x| (0..3).for_each(|i| c[i] += x[i] / k));
        c
    };
    let (cp, cq) = (centroid(p), centroid(q));
    let mut s = [[0.0; 3]; 3];
    let mut norms = 0.0;
    for (a, b) in p.iter().zip(q) {
        let pa = [a[0] - cp[0], a[1] - cp[1], a[2] - cp[2]];
        let qb = [b[0] - cq[0], b[1] - cq[1], b[2] - cq[2]];
        for r in 0..3 {
            norms += pa[r] * pa[r] + qb[r] * qb[r];
            for c in 0..3 {
                s[r][c] += pa[r] * qb[c];
            }
        }
    }
    let n = horn_matrix(s);
    let (lambda, q) = largest_eigenpair4(n);
    let r = rotation_matrix(q);
    let rc: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| r[i][j] * cp[j]).sum());
    let t = [cq[0] - rc[0], cq[1] - rc[1], cq[2] - rc[2]];
    (Pose { r, t }, (norms - 2.0 * lambda).max(0.0))
}

/// Poses of the shape points at `positions` of `group` (marker indices) in every strided
/// frame, and the total residual sum of squares.
fn poses(
    traj: &Trajectories,
    group: &[usize],
    shape: &[[f64; 3]],
    positions: &[usize],
    stride: usize,
) -> (Vec<Option<Pose>>, f64, f64) {
    let markers = traj.markers().max(1);
    let mut p = Vec::with_capacity(positions.len());
    let mut q = Vec::with_capacity(positions.len());
    let mut total = 0.0;
    let mut dof = 0.0;
    let out = traj
        .positions()
        .chunks_exact(markers)
        .step_by(stride)
        .map(|frame| {
            p.clear();
            q.clear();
            for &a in positions {
                if let Some(&x) = frame.get(group[a])
                    && mocap_io::is_present(x)
                {
                    p.push(shape[a]);
                    q.push(x);
                }
            }
            (p.len() >= 3).then(|| {
                let (pose, ss) = horn(&p, &q);
                total += ss;
                dof += (3 * p.len() - 6) as f64;
                pose
            })
        })
        .collect();
    (out, total, dof)
}

impl Body {
    /// Poses `group` (≥ 3 markers with a reference shape) in every strided frame, with the
    /// shape's handedness that fits better (MDS cannot tell a shape from its mirror image), or
    /// on [`core_shape`] when it holds tracks never seen together.
    fn new(traj: &Trajectories, group: &[usize], stride: usize) -> Option<Self> {
        if group.len() < 3 {
            return None;
        }
        let dist = median_distances(traj, group);
        let all: Vec<usize> = (0..group.len()).collect();
        if let Some(shape) = core_shape(traj, group, &dist, &all) {
            let (poses, sum_sq, dof) = poses(traj, group, &shape, &all, stride);
            return Some(Self {
                shape,
                poses,
                var: sum_sq / dof.max(1.0),
            });
        }
        let shape = reference_shape(&dist, group.len(), &all)?;
        let mirrored: Vec<[f64; 3]> = shape.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let (a, sa, da) = poses(traj, group, &shape, &all, stride);
        let (b, sb, db) = poses(traj, group, &mirrored, &all, stride);
        Some(if sa <= sb {
            Self {
                shape,
                poses: a,
                var: sa / da.max(1.0),
            }
        } else {
            Self {
                shape: mirrored,
                poses: b,
                var: sb / db.max(1.0),
            }
        })
    }
}

/// Robust scatter of marker `m`'s trajectory in a body's frame, mm per coordinate: its local
/// position in every frame with a pose, the distance from the per-coordinate median, and
/// the [`QUANTILE`] of the squared distances over 3 (as the fit split judges a fit). `None`
/// with fewer than `min_frames` posed frames where `m` is seen.
pub(crate) fn marker_sigma(
    traj: &Trajectories,
    poses: &[Option<Pose>],
    noise: (&[[f64; 3]], f64),
    m: usize,
    stride: usize,
    min_frames: usize,
) -> Option<f64> {
    let locals = locals_in(traj, poses, m, stride);
    if locals.len() < min_frames.max(3) {
        return None;
    }
    let mut column = Vec::with_capacity(locals.len());
    let centre: [f64; 3] = std::array::from_fn(|i| {
        column.clear();
        column.extend(locals.iter().map(|l| l[i]));
        median(&mut column)
    });
    let mut dev2: Vec<f64> = locals
        .iter()
        .map(|l| (0..3).map(|i| (l[i] - centre[i]).powi(2)).sum())
        .collect();
    // Less what the pose's own error puts there (leverage × the body's residual variance):
    // a body posed by few or near-collinear markers scatters any marker.
    let (shape, var) = noise;
    let pose_var = if var > 0.0 {
        leverage(shape, centre) * var
    } else {
        0.0
    };
    if !pose_var.is_finite() {
        return None;
    }
    Some(
        (quantile(&mut dev2, QUANTILE) / 3.0 - pose_var)
            .max(0.0)
            .sqrt(),
    )
}

/// Marker `m`'s position in a body's frame (shape coordinates, mm) at every strided frame
/// where the body has a pose and `m` is seen.
pub(crate) fn locals_in(
    traj: &Trajectories,
    poses: &[Option<Pose>],
    m: usize,
    stride: usize,
) -> Vec<[f64; 3]> {
    let markers = traj.markers().max(1);
    traj.positions()
        .chunks_exact(markers)
        .step_by(stride)
        .zip(poses)
        .filter_map(|(frame, pose)| {
            let pose = pose.as_ref()?;
            let x = *frame.get(m)?;
            if !mocap_io::is_present(x) {
                return None;
            }
            Some(pose.local(x))
        })
        .collect()
}

/// Each group's pose per strided frame (see [`stride_of`]) as one rigid body, for the
/// groups of ≥ 3 markers with a reference shape; `None` for the others.
pub(crate) fn group_poses(
    traj: &Trajectories,
    groups: &[Vec<usize>],
) -> Vec<Option<Vec<Option<Pose>>>> {
    let stride = stride_of(traj);
    groups
        .iter()
        .map(|g| Body::new(traj, g, stride).map(|b| b.poses))
        .collect()
}

/// A group of ≥ 3 markers posed as one rigid body.
pub(crate) struct PosedGroup {
    /// Reference shape, indexed like the group (segment-local, mm).
    pub shape: Vec<[f64; 3]>,
    /// Pose per strided frame (see [`stride_of`]), `None` with < 3 markers seen.
    pub poses: Vec<Option<Pose>>,
}

/// `group` posed as one rigid body; `None` without a reference shape.
pub(crate) fn posed_group(traj: &Trajectories, group: &[usize]) -> Option<PosedGroup> {
    Body::new(traj, group, stride_of(traj)).map(|b| PosedGroup {
        shape: b.shape,
        poses: b.poses,
    })
}

/// Robust fit σ of three markers as one rigid body, mm per coordinate: the [`QUANTILE`] over
/// frames with all three seen of the residual sum of squares over its 3 degrees of freedom.
/// Where a body of two cannot be posed without the marker, this is how well it holds it.
fn triple_sigma(traj: &Trajectories, triple: &[usize], stride: usize) -> Option<f64> {
    let body = Body::new(traj, triple, stride)?;
    let markers = traj.markers().max(1);
    let mut v: Vec<f64> = traj
        .positions()
        .chunks_exact(markers)
        .step_by(stride)
        .filter_map(|frame| {
            let mut p = [[0.0; 3]; 3];
            let mut q = [[0.0; 3]; 3];
            for (a, &m) in triple.iter().enumerate() {
                let x = *frame.get(m)?;
                if !mocap_io::is_present(x) {
                    return None;
                }
                p[a] = body.shape[a];
                q[a] = x;
            }
            Some(horn(&p, &q).1 / 3.0)
        })
        .collect();
    (v.len() >= 3).then(|| quantile(&mut v, QUANTILE).sqrt())
}

/// A proposed move: (how many times better the target holds the marker, marker, from, to).
type Move = (f64, usize, usize, usize);

/// Moves markers between clusters (marker indices) by rigid fit: a marker of a cluster of
/// ≥ 3 whose scatter in its own body (posed without it when ≥ 3 others remain) exceeds
/// `floor_mm` and `ratio` × its scatter in another body of ≥ 3 markers goes to the body
/// that holds it best; a donor keeps ≥ 2 markers. Strongest moves first, sweeps until none.
pub(crate) fn reassign(
    traj: &Trajectories,
    clusters: &mut [Vec<usize>],
    ratio: f64,
    floor_mm: f64,
    min_overlap: usize,
) {
    let stride = stride_of(traj);
    let min_frames = min_overlap.div_ceil(stride);
    for _ in 0..MAX_SWEEPS {
        let bodies: Vec<Option<Body>> = clusters
            .par_iter()
            .map(|c| Body::new(traj, c, stride))
            .collect();
        let members: Vec<(usize, usize)> = clusters
            .iter()
            .enumerate()
            .flat_map(|(c, ms)| (0..ms.len()).map(move |a| (c, a)))
            .collect();
        let mut moves: Vec<Move> = members
            .par_iter()
            .filter_map(|&(c, a)| {
                let own = &clusters[c];
                let m = own[a];
                let own_sigma = if own.len() >= 4 {
                    left_out_sigma(traj, own, bodies[c].as_ref()?, a, stride, min_frames)?
                } else if own.len() == 3 {
                    triple_sigma(traj, own, stride)?
                } else {
                    return None;
                };
                if own_sigma <= floor_mm {
                    return None;
                }
                let (best, target) = clusters
                    .iter()
                    .enumerate()
                    .filter(|&(d, _)| d != c)
                    .filter_map(|(d, g)| {
                        let s = match (g.len(), &bodies[d]) {
                            (_, Some(b)) => {
                                marker_sigma(traj, &b.poses, (&b.shape, 0.0), m, stride, min_frames)
                            }
                            _ => None,
                        };
                        s.map(|s| (s, d))
                    })
                    .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))?;
                (ratio * best < own_sigma).then(|| (own_sigma / best.max(1e-12), m, c, target))
            })
            .collect();
        moves.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let mut any = false;
        for (_, m, from, to) in moves {
            if clusters[from].len() <= 2 {
                continue;
            }
            clusters[from].retain(|&x| x != m);
            clusters[to].push(m);
            any = true;
        }
        if !any {
            break;
        }
    }
}

/// Dissolves two-marker clusters whose markers each belong to a body of ≥ 3: when both are
/// held within `hold_mm` (scatter as [`marker_sigma`]) by two different other clusters'
/// bodies, each joins the body that holds it best. Two markers near one joint axis, one on each side,
/// keep a steady distance and pair up although each moves with its own segment; a true
/// two-marker segment has a marker no other body holds (CMU's THI, SHN). A one-marker
/// cluster a body holds within `hold_mm` joins it: the robust scatter ignores the minority
/// of frames where a swapped or glitching trajectory was elsewhere, which ρ (over every
/// frame) does not. With `rejoin`, a pair one body holds both of rejoins that body when the
/// rigidity check cut it from it (see [`PairRejoin`]); with `repair`, a pair only one of
/// whose markers a body holds re-pairs (see [`LoosePairs`]). Returns how many clusters were
/// dissolved or re-paired.
pub(crate) fn dissolve_small_clusters(
    traj: &Trajectories,
    clusters: &mut Vec<Vec<usize>>,
    hold_mm: f64,
    min_overlap: usize,
    rejoin: Option<PairRejoin>,
    repair: Option<LoosePairs>,
) -> usize {
    let stride = stride_of(traj);
    let min_frames = min_overlap.div_ceil(stride);
    // Both markers and some marker of the holder came out of one spectral cluster.
    let cut_from = |r: &PairRejoin, a: usize, b: usize, holder: &[usize]| {
        let origin = |m: usize| r.spectral_of.get(m).copied().flatten();
        origin(a)
            .is_some_and(|o| origin(b) == Some(o) && holder.iter().any(|&x| origin(x) == Some(o)))
    };
    // A body costs a pose per frame: pose only those that could hold a lone or paired marker,
    // the clusters nearest it in space (a marker's own segment is among its neighbours).
    let mut candidates = std::collections::BTreeSet::new();
    for (c, ms) in clusters.iter().enumerate() {
        if ms.len() <= 2 {
            for &m in ms {
                candidates.extend(nearest_clusters(
                    traj,
                    clusters,
                    m,
                    c,
                    stride,
                    HOLDER_CANDIDATES,
                    3,
                ));
            }
        }
    }
    if candidates.is_empty() {
        return 0;
    }
    let bodies: Vec<Option<Body>> = clusters
        .par_iter()
        .enumerate()
        .map(|(d, c)| {
            if c.len() >= 3 && candidates.contains(&d) {
                Body::new(traj, c, stride)
            } else {
                None
            }
        })
        .collect();
    let best_home = |m: usize, own: usize| {
        bodies
            .iter()
            .enumerate()
            .filter(|&(d, _)| d != own)
            .filter_map(|(d, b)| {
                let b = b.as_ref()?;
                marker_sigma(traj, &b.poses, (&b.shape, 0.0), m, stride, min_frames).map(|s| (s, d))
            })
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))
    };
    let outcomes: Vec<SmallClusterFate> = clusters
        .par_iter()
        .enumerate()
        .map(|(c, ms)| {
            let moves = |mv: Vec<(usize, usize)>| (mv, None);
            // A lone marker a body holds is that body's, its outlying frames a swap or a
            // glitch (a real one-marker segment moves against every body).
            if let &[a] = &ms[..] {
                return match best_home(a, c) {
                    Some((sa, da)) if sa <= hold_mm => moves(vec![(a, da)]),
                    _ => moves(Vec::new()),
                };
            }
            let &[a, b] = &ms[..] else {
                return moves(Vec::new());
            };
            match (best_home(a, c), best_home(b, c)) {
                // Held by one body, the pair may be a segment of its own that moved little
                // against it (a foot on its shank, a pelvis on the trunk in a walk):
                // merging would lose a segment. Only a pair split across two bodies is a
                // cross-joint artefact.
                (Some((sa, da)), Some((sb, db))) if sa <= hold_mm && sb <= hold_mm && da != db => {
                    moves(vec![(a, da), (b, db)])
                }
                (Some((sa, da)), Some((sb, db)))
                    if sa <= hold_mm
                        && sb <= hold_mm
                        && da == db
                        && rejoin.as_ref().is_some_and(|r| {
                            let body_sigma = bodies[da].as_ref().map_or(0.0, |x| x.var.sqrt());
                            cut_from(r, a, b, &clusters[da]) && sa.max(sb) <= r.ratio * body_sigma
                        }) =>
                {
                    // Spectral clustering saw the three move as one and skin cut them
                    // apart: as still in the body as its own markers are, the pair is
                    // part of it. Exact data (a body's σ near zero) keeps a pair whose
                    // millimetres of motion are real.
                    moves(vec![(a, da), (b, da)])
                }
                // One marker held, the other by no body: a candidate for a steadier
                // partner (below).
                (ha, hb) => {
                    let held = |h: Option<(f64, usize)>| h.filter(|&(s, _)| s <= hold_mm);
                    match (held(ha), held(hb)) {
                        (Some((_, da)), None) => (Vec::new(), Some([a, da, b])),
                        (None, Some((_, db))) => (Vec::new(), Some([b, db, a])),
                        _ => moves(Vec::new()),
                    }
                }
            }
        })
        .collect();
    let mut dissolved = 0;
    for (c, (mv, _)) in outcomes.iter().enumerate() {
        if mv.is_empty() {
            continue;
        }
        for &(m, d) in mv {
            clusters[d].push(m);
        }
        clusters[c].clear();
        dissolved += 1;
    }
    if let Some(repair) = repair {
        let loose = outcomes
            .iter()
            .enumerate()
            .filter_map(|(c, (_, l))| l.map(|l| (c, l)));
        for (c, [held, holder, free]) in loose {
            // The held marker keeps its distances to the holder's markers better than to
            // its partner (an elbow marker the forearm holds loosely stays with the arm).
            // An earlier re-pairing may have taken one of the two already.
            if clusters[c] != [held, free] && clusters[c] != [free, held] {
                continue;
            }
            let Some(bond) = repair.stats.rho(held, free, min_overlap) else {
                continue;
            };
            let to_holder = rms_rho(repair.stats, held, &clusters[holder], min_overlap);
            let rehomed = (to_holder.is_some_and(|h| h < bond)
                && repair.take_partner(clusters, c, free, bond, min_overlap))
                || repair.join_pair(traj, clusters, c, free, bond, min_overlap);
            if rehomed {
                clusters[holder].push(held);
                dissolved += 1;
            }
        }
    }
    clusters.retain(|c| !c.is_empty());
    dissolved
}

/// What [`dissolve_small_clusters`] does with one cluster: its markers' moves (marker,
/// cluster), or, for a pair only one of whose markers a body holds, that marker, its holder
/// and the other marker.
type SmallClusterFate = (Vec<(usize, usize)>, Option<[usize; 3]>);

/// When a pair only one of whose markers a body holds re-pairs ([`dissolve_small_clusters`]).
///
/// Two markers of different segments can keep a steady distance for a whole capture (a
/// forehead and an upper-arm marker in a walk, 4.9 mm robust ρ in CMU 02_01); when the
/// fit split cuts an intruder from a body it takes a partner with it (its parts have ≥ 2
/// markers), and the true partner of the intruder is left in the body next door. The free
/// marker takes the partner [`crate::rigidity::pair_orphans`] would give it were it alone
/// (ρ within the tolerance, no looser than the partner's RMS ρ to its own group, which
/// keeps [`DONOR_KEEPS`]) if that partner is steadier with it than the marker it is paired
/// with, and the held marker joins its holder if its RMS ρ to the holder's markers is
/// below the pair's ρ too. A true two-marker segment with one marker near a joint keeps
/// it: a knee marker the shank holds, whose thigh marker has no steadier partner; an elbow
/// marker the forearm holds more loosely than the upper-arm marker does. Failing a
/// partner, the free marker joins a two-marker cluster it is steadier with than with the
/// marker it is paired with, when the three fit as one ordinary segment, and the held
/// marker, alone then, joins its holder as a lone held marker does: a three-marker
/// segment cut into a pair and a marker paired across a joint (snake-hard-s20040, whose
/// link4 and link5 markers near their joint kept ρ 3.1 mm, the link5 marker 1.5 and 3.6
/// mm to its own pair).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LoosePairs<'a> {
    /// Every pair's distance statistics.
    pub stats: &'a PairStats,
    /// Largest ρ of a new pair, mm (the rigidity tolerance).
    pub tol_mm: f64,
    /// Largest rigid-fit σ of a pair and the free marker joined into one segment, mm (the
    /// fit split's floor: what an ordinary segment fits within).
    pub segment_sigma_mm: f64,
}

impl LoosePairs<'_> {
    /// Gives `free` (paired in cluster `c` with a marker it keeps ρ `bond` to) its
    /// steadiest partner from a cluster that keeps [`DONOR_KEEPS`] markers without it, when
    /// steadier than `bond`; the other marker leaves cluster `c`. Whether it did.
    fn take_partner(
        &self,
        clusters: &mut [Vec<usize>],
        c: usize,
        free: usize,
        bond: f64,
        min_overlap: usize,
    ) -> bool {
        let mut best: Option<(f64, usize, usize)> = None;
        for (d, donor) in clusters.iter().enumerate() {
            if d == c || donor.len() <= DONOR_KEEPS {
                continue;
            }
            for &x in donor {
                let Some(r) = self.stats.rho(free, x, min_overlap) else {
                    continue;
                };
                if r > self.tol_mm || r >= bond || best.is_some_and(|(b, _, _)| r >= b) {
                    continue;
                }
                let mates: Vec<usize> = donor.iter().copied().filter(|&y| y != x).collect();
                if rms_rho(self.stats, x, &mates, min_overlap).is_some_and(|own| r <= own) {
                    best = Some((r, d, x));
                }
            }
        }
        let Some((_, d, x)) = best else {
            return false;
        };
        clusters[d].retain(|&y| y != x);
        clusters[c] = vec![free, x];
        true
    }

    /// Moves `free` (paired in cluster `c` with a marker it keeps ρ `bond` to) into a
    /// two-marker cluster it keeps its distances to better than that (RMS ρ) and fits with
    /// as one segment (rigid σ within `segment_sigma_mm`), the best-fitting such; cluster
    /// `c` is emptied. Where a three-marker segment lost one marker to a cross-joint pair
    /// its remaining pair has no marker to spare for [`Self::take_partner`]. Whether it did.
    fn join_pair(
        &self,
        traj: &Trajectories,
        clusters: &mut [Vec<usize>],
        c: usize,
        free: usize,
        bond: f64,
        min_overlap: usize,
    ) -> bool {
        let best = clusters
            .iter()
            .enumerate()
            .filter(|&(q, pair)| {
                q != c
                    && pair.len() == 2
                    && rms_rho(self.stats, free, pair, min_overlap).is_some_and(|r| r < bond)
            })
            .filter_map(|(q, pair)| {
                crate::fitsplit::union_sigma(traj, &[free], pair)
                    .filter(|&sigma| sigma <= self.segment_sigma_mm)
                    .map(|sigma| (sigma, q))
            })
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let Some((_, q)) = best else {
            return false;
        };
        clusters[q].push(free);
        clusters[c].clear();
        true
    }
}

/// When a held pair rejoins the body it was cut from ([`dissolve_small_clusters`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PairRejoin<'a> {
    /// Each marker's spectral cluster before the rigidity check (`None`: not clustered).
    pub spectral_of: &'a [Option<usize>],
    /// The pair's larger scatter in the body may be at most this × the body's own fit σ.
    pub ratio: f64,
}

/// Clusters [`dissolve_small_clusters`] poses as possible holders of each lone or paired marker.
const HOLDER_CANDIDATES: usize = 3;

/// Up to `k` clusters of ≥ `min_size` markers other than `own`, nearest marker `m` in
/// space: by the mean over strided frames of the distance from `m` to the cluster's
/// nearest visible marker.
pub(crate) fn nearest_clusters(
    traj: &Trajectories,
    clusters: &[Vec<usize>],
    m: usize,
    own: usize,
    stride: usize,
    k: usize,
    min_size: usize,
) -> Vec<usize> {
    let mut ranked: Vec<(f64, usize)> = clusters
        .iter()
        .enumerate()
        .filter(|&(d, c)| d != own && c.len() >= min_size)
        .filter_map(|(d, c)| {
            let (mut sum, mut count) = (0.0, 0usize);
            for f in (0..traj.frames()).step_by(stride) {
                let Some(p) = traj.get(f, m) else { continue };
                let nearest = c
                    .iter()
                    .filter_map(|&x| traj.get(f, x))
                    .map(|q| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>())
                    .fold(f64::INFINITY, f64::min);
                if nearest.is_finite() {
                    sum += nearest.sqrt();
                    count += 1;
                }
            }
            (count > 0).then(|| (sum / count as f64, d))
        })
        .collect();
    ranked.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    ranked.into_iter().take(k).map(|(_, d)| d).collect()
}

/// Largest cluster searched for a marker to eject: each candidate costs a pose of the
/// cluster per frame, so the search is quadratic in its size, and clusters this large are
/// not one segment's markers but body-model outputs (bigparlove.c3d: 179 points, 15 s).
const MAX_EJECT_CLUSTER: usize = 24;

/// Takes out of their clusters the markers no body holds: in a cluster of ≥ 5, the marker
/// with the largest scatter in its own body posed without it leaves as a group of its own
/// when that scatter exceeds `ratio` × the median of its cluster-mates' (each measured in
/// the cluster without the suspect, whose swing would otherwise spoil their poses too),
/// that median floored at `floor_mm`. A distance-based clustering keeps a marker whose distances to a
/// cluster barely change — an upper-arm marker swinging across the line to the head
/// markers — although the body turns it by tens of mm; `reassign` only moves markers to a
/// body that holds them, and a one-marker segment (the arm in CMU 02_01) has none.
/// Returns the markers taken out.
pub(crate) fn eject(
    traj: &Trajectories,
    clusters: &mut Vec<Vec<usize>>,
    ratio: f64,
    floor_mm: f64,
) -> Vec<usize> {
    let ejected: Vec<Option<usize>> = clusters
        .par_iter()
        .map(|c| {
            if !(5..=MAX_EJECT_CLUSTER).contains(&c.len()) {
                return None;
            }
            let stride = stride_of(traj);
            let body = Body::new(traj, c, stride)?;
            let (own, suspect) = (0..c.len())
                .filter_map(|a| left_out_sigma(traj, c, &body, a, stride, 3).map(|s| (s, c[a])))
                .max_by(|x, y| x.0.total_cmp(&y.0).then(y.1.cmp(&x.1)))?;
            // The mates' median is at least the floor, so nothing below this can leave.
            if own <= ratio * floor_mm {
                return None;
            }
            let rest: Vec<usize> = c.iter().copied().filter(|&m| m != suspect).collect();
            let mut mates: Vec<f64> = rest
                .iter()
                .filter_map(|&m| sigma_in(traj, &rest, m))
                .collect();
            if mates.len() < 3 {
                return None;
            }
            mates.sort_by(f64::total_cmp);
            // The mates' scatter is net of their poses' own error and can come out near
            // zero; no marker is held better than the floor (skin, noise).
            let median = mates[mates.len() / 2].max(floor_mm);
            (own > ratio * median).then_some(suspect)
        })
        .collect();
    let mut taken = Vec::new();
    for (c, out) in clusters.iter_mut().zip(&ejected) {
        if let Some(m) = *out {
            c.retain(|&x| x != m);
            taken.push(m);
        }
    }
    for &m in &taken {
        clusters.push(vec![m]);
    }
    taken
}

/// Scatter (as [`marker_sigma`]) of `cluster[a]` in `body` (the whole cluster's) posed
/// again without it on its other markers' rows of the same reference shape.
fn left_out_sigma(
    traj: &Trajectories,
    cluster: &[usize],
    body: &Body,
    a: usize,
    stride: usize,
    min_frames: usize,
) -> Option<f64> {
    let others: Vec<usize> = (0..cluster.len()).filter(|&b| b != a).collect();
    let (loo, ss, dof) = poses(traj, cluster, &body.shape, &others, stride);
    let rest: Vec<[f64; 3]> = others.iter().map(|&b| body.shape[b]).collect();
    let var = ss / dof.max(1.0);
    marker_sigma(traj, &loo, (&rest, var), cluster[a], stride, min_frames)
}

/// Scatter of marker `m` in the body of `group` posed without `m` (see [`marker_sigma`]),
/// mm; `None` when fewer than 3 other markers or no reference shape.
pub(crate) fn sigma_in(traj: &Trajectories, group: &[usize], m: usize) -> Option<f64> {
    let others: Vec<usize> = group.iter().copied().filter(|&x| x != m).collect();
    let stride = stride_of(traj);
    let body = Body::new(traj, &others, stride)?;
    marker_sigma(traj, &body.poses, (&body.shape, body.var), m, stride, 3)
}

#[cfg(test)]
mod tests {
    use super::{LoosePairs, PairRejoin, dissolve_small_clusters, eject, reassign};
    use crate::pairstats::pair_stats;
    use crate::testscene::{CHILD, PARENT, hinge_x, hinged_capture, moving_capture};

    /// Two 4-marker bodies at a hinge swinging ±15°, with 1 mm deterministic jitter: a child
    /// marker clustered with the parent goes back to the child, and the true partition
    /// stays as it is.
    #[test]
    fn misplaced_marker_returns_to_its_body() {
        let traj = hinged_capture(&PARENT, &CHILD, 300, 15.0, 1.0);
        let mut clusters = vec![vec![0, 1, 2, 3, 7], vec![4, 5, 6]];
        reassign(&traj, &mut clusters, 2.0, 1.0, 10);
        clusters.iter_mut().for_each(|c| c.sort_unstable());
        assert_eq!(clusters, vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
        let mut right = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]];
        reassign(&traj, &mut right, 2.0, 1.0, 10);
        assert_eq!(right, vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
    }

    /// A 5-marker rigid body with 1 mm jitter plus one marker on an arm swinging ±20°
    /// 250 mm from the body's hinge: the clustering kept it with the body, the ejection
    /// takes it out; the body alone loses nothing.
    #[test]
    fn swinging_marker_is_ejected_and_a_rigid_body_keeps_its_markers() {
        let body: Vec<[f64; 3]> = PARENT
            .iter()
            .copied()
            .chain([[25.0, 25.0, 250.0]])
            .collect();
        let arm = [0.0, 0.0, -250.0];
        let traj = hinged_capture(&body, &[arm], 300, 20.0, 1.0);
        let mut clusters = vec![vec![0, 1, 2, 3, 4, 5]];
        assert_eq!(eject(&traj, &mut clusters, 4.0, 1.0), vec![5]);
        assert_eq!(clusters, vec![vec![0, 1, 2, 3, 4], vec![5]]);
        let mut rigid = vec![vec![0, 1, 2, 3, 4]];
        assert!(eject(&traj, &mut rigid, 4.0, 1.0).is_empty());
        assert_eq!(rigid, vec![vec![0, 1, 2, 3, 4]]);
    }

    /// A child marker whose trajectory was the parent's for a sixth of the trial (a swap),
    /// split off alone, rejoins the child; a marker on a third body swinging against both
    /// stays alone.
    #[test]
    fn lone_marker_a_body_holds_rejoins_it() {
        let swing = |t: f64| 20f64.to_radians() * (0.7 * t).sin();
        let swapped = [25.0, -20.0, -150.0];
        let third = [0.0, 30.0, -450.0];
        let traj = moving_capture(10, 300, 0.5, |t, k| match k {
            0..=3 => PARENT[k],
            4..=7 => hinge_x(swing(t), CHILD[k - 4], 0.0),
            // Frames 100..150 (t 5.0..7.5) on a parent marker's track instead.
            8 if (5.0..7.5).contains(&t) => PARENT[2],
            8 => hinge_x(swing(t), swapped, 0.0),
            _ => hinge_x(swing(t), hinge_x(1.2 * swing(t + 1.0), third, -400.0), 0.0),
        });
        let mut clusters = vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7], vec![8], vec![9]];
        assert_eq!(
            dissolve_small_clusters(&traj, &mut clusters, 3.0, 10, None, None),
            1
        );
        clusters.iter_mut().for_each(|c| c.sort_unstable());
        assert_eq!(
            clusters,
            vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7, 8], vec![9]]
        );
    }

    /// Two 4-marker bodies at a hinge about x swinging ±20°, each with a fifth marker 15 mm
    /// from the axis; a third body hinged to the child carries two markers; two more
    /// markers ride on the parent. The two near-axis markers paired up dissolve back into
    /// their bodies; the third body's pair, which no other body holds, stays; so does the
    /// pair the parent alone holds (a segment that moved little against it, for all the
    /// data can tell).
    #[test]
    fn near_axis_pair_dissolves_and_a_true_pair_stays() {
        let parent = PARENT.iter().copied().chain([[40.0, 0.0, 15.0]]);
        let child = CHILD.iter().copied().chain([[-40.0, 0.0, -15.0]]);
        let third = [[10.0, 20.0, -450.0], [-15.0, -10.0, -550.0]];
        let riders = [[50.0, 40.0, 250.0], [-45.0, 35.0, 120.0]];
        let points: Vec<[f64; 3]> = parent.chain(child).chain(third).chain(riders).collect();
        let traj = moving_capture(points.len(), 300, 0.5, |t, k| {
            let a1 = 20f64.to_radians() * (0.7 * t).sin();
            let a2 = 25f64.to_radians() * (0.45 * t).cos();
            match k {
                5..=9 => hinge_x(a1, points[k], 0.0),
                10..=11 => hinge_x(a1, hinge_x(a2, points[k], -400.0), 0.0),
                _ => points[k],
            }
        });
        let mut clusters = vec![
            vec![0, 1, 2, 3],
            vec![5, 6, 7, 8],
            vec![4, 9],
            vec![10, 11],
            vec![12, 13],
        ];
        assert_eq!(
            dissolve_small_clusters(&traj, &mut clusters, 3.0, 10, None, None),
            1
        );
        clusters.iter_mut().for_each(|c| c.sort_unstable());
        assert_eq!(
            clusters,
            vec![
                vec![0, 1, 2, 3, 4],
                vec![5, 6, 7, 8, 9],
                vec![10, 11],
                vec![12, 13]
            ]
        );
    }

    /// Two markers riding on a 4-marker body, next to a hinged child: cut from the body
    /// after spectral clustering had them together, the pair rejoins it; had spectral
    /// clustering kept them apart, or did they drift 2 mm on an exactly rigid body (real
    /// motion, however small, where the body's own σ is rounding error), they stay a pair.
    #[test]
    fn pair_cut_from_the_body_that_holds_it_rejoins_it() {
        let riders = [[50.0, 40.0, 250.0], [-45.0, 35.0, 120.0]];
        let points: Vec<[f64; 3]> = PARENT
            .iter()
            .copied()
            .chain(riders)
            .chain(CHILD.iter().copied())
            .collect();
        let capture = |jitter_mm: f64, drift_mm: f64| {
            moving_capture(points.len(), 300, jitter_mm, |t, k| match k {
                4..=5 => {
                    let mut p = points[k];
                    p[0] += drift_mm * (0.3 * t).sin();
                    p
                }
                6..=9 => hinge_x(20f64.to_radians() * (0.7 * t).sin(), points[k], 0.0),
                _ => points[k],
            })
        };
        let as_cut = || vec![vec![0, 1, 2, 3], vec![4, 5], vec![6, 7, 8, 9]];
        let together = [0, 0, 0, 0, 0, 0, 1, 1, 1, 1].map(Some);
        let apart = [0, 0, 0, 0, 2, 2, 1, 1, 1, 1].map(Some);
        let dissolve = |traj, spectral_of: &[Option<usize>]| {
            let mut clusters = as_cut();
            let rejoin = PairRejoin {
                spectral_of,
                ratio: 8.0,
            };
            let n = dissolve_small_clusters(traj, &mut clusters, 3.0, 10, Some(rejoin), None);
            clusters.iter_mut().for_each(|c| c.sort_unstable());
            (n, clusters)
        };
        let jittered = capture(0.5, 0.0);
        assert_eq!(
            dissolve(&jittered, &together),
            (1, vec![vec![0, 1, 2, 3, 4, 5], vec![6, 7, 8, 9]])
        );
        assert_eq!(dissolve(&jittered, &apart), (0, as_cut()));
        assert_eq!(dissolve(&capture(0.0, 2.0), &together), (0, as_cut()));
    }

    /// `clusters` after [`dissolve_small_clusters`] with only the loose-pair repair (ρ
    /// tolerance 5 mm, segment floor 1 mm, hold bound 3 mm), each sorted, and how many
    /// clusters it dissolved.
    fn repair_loose_pairs(
        traj: &mocap_io::Trajectories,
        mut clusters: Vec<Vec<usize>>,
    ) -> (usize, Vec<Vec<usize>>) {
        let stats = pair_stats(traj);
        let repair = LoosePairs {
            stats: &stats,
            tol_mm: 5.0,
            segment_sigma_mm: 1.0,
        };
        let n = dissolve_small_clusters(traj, &mut clusters, 3.0, 10, None, Some(repair));
        clusters.iter_mut().for_each(|c| c.sort_unstable());
        (n, clusters)
    }

    /// An arm swinging ±20° about x against a fixed 4-marker body carries marker 6 and,
    /// 15 mm off the axis, marker 4, which the clustering left with the body (its distances
    /// to the body's markers change by a few mm). Marker 6 is paired with a body marker 5
    /// that keeps a fairly steady distance to it (20 mm off the axis). The pair re-pairs:
    /// 6 takes 4 (steadier with it than 5 is, and 4 no steadier with the body), 5 rejoins
    /// the body. Where the arm has no steadier partner for 6 (marker 4 on the body), the
    /// pair stays: a true two-marker segment whose one marker its neighbour holds.
    #[test]
    fn loose_pair_re_pairs_with_a_steadier_partner() {
        let scene = |x_on_arm: bool| {
            let points: Vec<[f64; 3]> = PARENT
                .iter()
                .copied()
                .chain([[60.0, 0.0, -15.0], [-60.0, 20.0, 0.0], [0.0, 30.0, -150.0]])
                .collect();
            moving_capture(points.len(), 300, 0.3, |t, k| {
                let swing = 20f64.to_radians() * (0.7 * t).sin();
                match k {
                    4 if x_on_arm => hinge_x(swing, points[k], 0.0),
                    6 => hinge_x(swing, points[k], 0.0),
                    _ => points[k],
                }
            })
        };
        let run = |traj: &mocap_io::Trajectories| {
            repair_loose_pairs(traj, vec![vec![0, 1, 2, 3, 4], vec![5, 6]])
        };
        assert_eq!(
            run(&scene(true)),
            (1, vec![vec![0, 1, 2, 3, 5], vec![4, 6]])
        );
        assert_eq!(
            run(&scene(false)),
            (0, vec![vec![0, 1, 2, 3, 4], vec![5, 6]])
        );
    }

    /// An arm of three markers swinging ±20° about x against a fixed 4-marker body: its two
    /// far markers 4 and 5 are a pair, and marker 6, 45 mm from the axis, is paired with
    /// body marker 7, 18 mm from it (ρ a few mm). The body holds 7; no cluster has a marker
    /// to spare for 6, but the arm's pair is steadier with it than 7 is and the three fit as
    /// one body: 6 joins the pair, 7 the body. Where 4 and 5 turn on a body of their own
    /// (another phase), 6 fits with neither and the pair stays.
    #[test]
    fn loose_pair_marker_joins_a_pair_it_fits_with_as_one_segment() {
        let scene = |pair_on_arm: bool| {
            let points: Vec<[f64; 3]> = PARENT
                .iter()
                .copied()
                .chain([
                    [20.0, 25.0, -200.0],
                    [-30.0, -20.0, -280.0],
                    [0.0, 20.0, -40.0],
                    [40.0, 15.0, 10.0],
                ])
                .collect();
            moving_capture(points.len(), 300, 0.3, |t, k| {
                let swing = 20f64.to_radians() * (0.7 * t).sin();
                let other = 30f64.to_radians() * (1.3 * t).sin();
                match k {
                    4 | 5 if !pair_on_arm => hinge_x(other, points[k], 0.0),
                    4..=6 => hinge_x(swing, points[k], 0.0),
                    _ => points[k],
                }
            })
        };
        let run = |traj: &mocap_io::Trajectories| {
            repair_loose_pairs(traj, vec![vec![0, 1, 2, 3], vec![4, 5], vec![6, 7]])
        };
        assert_eq!(
            run(&scene(true)),
            (1, vec![vec![0, 1, 2, 3, 7], vec![4, 5, 6]])
        );
        assert_eq!(
            run(&scene(false)),
            (0, vec![vec![0, 1, 2, 3], vec![4, 5], vec![6, 7]])
        );
    }
}
