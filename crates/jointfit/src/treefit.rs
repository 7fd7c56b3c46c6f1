//! The tree's joints read together, once the tree is known: their positions per frame
//! ([`tree_positions`]) and their centres ([`tree_centres`]).
//!
//! A pair's positions weigh its two segments' views of the centre by each pose's precision
//! there, and its weighted SCoRE weighs its gaps so, one joint at a time
//! (`fit::joint_positions`, `fit::weighted_centres`). But a segment's pose error in a frame
//! is one rigid error that shows at every joint the segment carries: the gaps of two joints
//! on one segment err together (a thigh posed off at the hip is posed off at the knee too),
//! so each gap says something about the segments' other joints.
//!
//! The model is the one the pairs' weighing uses, taken over the tree: in frame f, segment
//! s's pose is off by a translation at its reference markers' centroid and a small turn,
//! Gaussian with covariance k_s(f) σ_s² diag(I/n, J⁻¹) (its fit scatter σ, its frame's
//! misfit scale k, its n reference markers' inertia tensor J; `poses::PoseScatter`), the
//! segments independently; its view of a point d from the centroid is then off by the
//! translation plus the turn × d. Every tree joint is one point both its segments see.
//! With g_j = v_aj − v_bj the gap of joint j (a, b its segments; v a segment's view of the
//! centre) and C_s(j, k) = Cov(s's view error at j, at k) (`PoseScatter::covariance_between`,
//! turned into the world by s's pose), the gaps of a frame have the covariance
//! M_jk = Σ_s ε_sj ε_sk C_s(j, k) (ε = +1 on a joint's `a` side, −1 on its `b` side).
//! - Positions: the posterior mean given every joint's two views in the frame: solve
//!   Σ_k M_jk λ_k = g_j, then x_j = v_aj − Σ_k ε_ak C_a(j, k) λ_k. A joint alone (no tree
//!   neighbour sharing a posed segment) gets exactly the pair's weighted mean.
//! - Centres: generalised least squares of all the tree's centres at once, each frame's
//!   gaps weighted by M⁻¹; with M block-diagonal it is the pairs' weighted SCoRE.
//!
//! A joint with a segment that has no precision (two markers, posed through a joint), or
//! not posed in a frame, keeps its pair fit there and tells the others nothing.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::pairfits::PairFits;
use crate::poses::{Pose, PoseScatter, pose_track};

/// The share one segment's pose error has in two of its tree joints' views.
struct Coupling {
    /// The segment.
    segment: usize,
    /// The two joints (indices into the solve's joints; equal on the diagonal).
    joints: [usize; 2],
    /// ε_sj ε_sk: the product of the segment's sides in the two joints' gaps.
    sign: f64,
    /// The segment is the first joint's `a` side, whose view that joint's position
    /// starts from.
    from_a_side: bool,
    /// Covariance between the segment's views of the two centres, its local frame, in a
    /// typical frame (mm²).
    local: DMat3,
}

/// A tree joint the solve reads.
struct SolveJoint {
    /// Index into `PairFits::pairs`.
    pair: usize,
    /// The pair's segments `a`, `b` and the centre in each one's frame.
    sides: [(usize, DVec3); 2],
}

/// Per-thread work space of one frame's solve (reused: no allocation per frame).
struct Workspace {
    /// Position of each joint in this frame's system (`usize::MAX`: not in it).
    slot: Vec<usize>,
    /// Row-major system matrix, then its Cholesky factor.
    matrix: Vec<f64>,
    /// The gaps, then the multipliers λ.
    rhs: Vec<f64>,
    /// Each row's first column that is not zero.
    first: Vec<usize>,
    /// Each coupling's block in this frame (world frame, signed and scaled), where both
    /// its joints are in the system.
    blocks: Vec<Option<DMat3>>,
    /// The joints in this frame's system: index, first row, and the poses of its `a` and
    /// `b` segments ([`tree_centres`]).
    active: Vec<(usize, usize, Pose, Pose)>,
}

/// Recomputes the positions of every tree joint in `edges` (`(pair, parent, child)`, the
/// parent and child unused) from all tree joints' views at once (module docs); pairs not
/// in `edges`, and frames or joints the solve cannot read, keep their positions. `poses`
/// are [`TreePoses::of`] these fits (or of any with the same poses). Returns how many
/// joint-frames changed.
pub fn tree_positions(
    fits: &mut PairFits,
    edges: &[(usize, usize, usize)],
    poses: &TreePoses,
) -> usize {
    let Some(tree) = TreeModel::of(fits, edges, poses) else {
        return 0;
    };
    let count = tree.joints.len();
    let mut solved = vec![[f64::NAN; 3]; fits.frames * count];
    solved.par_chunks_mut(count).enumerate().for_each_init(
        || tree.workspace(),
        |work, (f, out)| tree.positions_in_frame(f, work, out),
    );
    let mut changed = 0;
    for (j, joint) in tree.joints.iter().enumerate() {
        let positions = &mut fits.pairs[joint.pair].positions;
        for (f, p) in positions.iter_mut().enumerate() {
            let x = solved[f * count + j];
            if x.iter().all(|v| v.is_finite()) {
                *p = x;
                changed += 1;
            }
        }
    }
    changed
}

/// Every segment's pose precision and pose per frame, read once from a [`PairFits`]'
/// poses for both tree readings: they change the pairs' centres and positions, never the
/// poses.
pub struct TreePoses {
    scatters: Vec<PoseScatter>,
    tracks: Vec<Vec<Option<Pose>>>,
    frames: usize,
}

impl TreePoses {
    /// The precision and poses of every segment of `fits`.
    pub fn of(fits: &PairFits) -> Self {
        Self {
            scatters: fits.poses.par_iter().map(PoseScatter::of).collect(),
            tracks: fits.poses.par_iter().map(pose_track).collect(),
            frames: fits.frames,
        }
    }
}

/// What both tree readings share: the joints they read, their segments' couplings,
/// precision and poses.
struct TreeModel<'a> {
    joints: Vec<SolveJoint>,
    couplings: Vec<Coupling>,
    scatters: &'a [PoseScatter],
    tracks: &'a [Vec<Option<Pose>>],
}

impl<'a> TreeModel<'a> {
    /// The tree joints of `edges` both of whose segments have a precision (module docs);
    /// `None` when there is none, or when `poses` were not read from poses like `fits'`.
    fn of(fits: &PairFits, edges: &[(usize, usize, usize)], poses: &'a TreePoses) -> Option<Self> {
        let (scatters, tracks) = (&poses.scatters[..], &poses.tracks[..]);
        if scatters.len() != fits.poses.len() || poses.frames != fits.frames {
            return None;
        }
        let mut joints: Vec<SolveJoint> = Vec::new();
        for &(pair, _, _) in edges {
            let Some(fit) = fits.pairs.get(pair) else {
                continue;
            };
            let (c_a, c_b) = (
                DVec3::from_array(fit.centre_in_a),
                DVec3::from_array(fit.centre_in_b),
            );
            let readable = c_a.is_finite()
                && c_b.is_finite()
                && fit.positions.len() == fits.frames
                && [fit.a, fit.b].iter().all(|&s| s < scatters.len())
                && scatters[fit.a].precision_at(c_a).is_some()
                && scatters[fit.b].precision_at(c_b).is_some()
                && !joints.iter().any(|j| j.pair == pair);
            if readable {
                joints.push(SolveJoint {
                    pair,
                    sides: [(fit.a, c_a), (fit.b, c_b)],
                });
            }
        }
        if joints.is_empty() {
            return None;
        }
        let couplings = couplings(&joints, scatters);
        Some(Self {
            joints,
            couplings,
            scatters,
            tracks,
        })
    }

    /// A frame's work space.
    fn workspace(&self) -> Workspace {
        let count = self.joints.len();
        Workspace {
            slot: vec![usize::MAX; count],
            matrix: vec![0.0; 9 * count * count],
            rhs: vec![0.0; 3 * count],
            first: vec![0; 3 * count],
            blocks: vec![None; self.couplings.len()],
            active: Vec::with_capacity(count),
        }
    }

    /// Segment `s`'s pose in frame `f`.
    fn pose(&self, s: usize, f: usize) -> Option<Pose> {
        self.tracks[s].get(f).copied().flatten()
    }

    /// The view of joint j from its side `side` in frame `f`.
    fn view(&self, j: usize, side: usize, f: usize) -> Option<DVec3> {
        let (s, c) = self.joints[j].sides[side];
        self.pose(s, f).map(|p| p.apply(c))
    }

    /// Frame `f`'s system (module docs): which joints are in it (`work.slot`), the gaps
    /// (`work.rhs`), each coupling's block and the Cholesky factor of M (`work.matrix`, in
    /// the profile `work.first`); its size 3 × joints, or `None` when no joint is posed or
    /// M is not positive definite.
    fn factor_frame(&self, f: usize, work: &mut Workspace) -> Option<usize> {
        let mut size = 0;
        for (j, joint) in self.joints.iter().enumerate() {
            let posed = joint.sides.iter().all(|&(s, _)| self.pose(s, f).is_some());
            work.slot[j] = if posed {
                size += 1;
                size - 1
            } else {
                usize::MAX
            };
        }
        if size == 0 {
            return None;
        }
        let n = 3 * size;
        let matrix = &mut work.matrix[..n * n];
        matrix.fill(0.0);
        let rhs = &mut work.rhs[..n];
        for j in 0..self.joints.len() {
            let row = work.slot[j];
            if row == usize::MAX {
                continue;
            }
            let gap = self.view(j, 0, f)? - self.view(j, 1, f)?;
            rhs[3 * row..3 * row + 3].copy_from_slice(&gap.to_array());
        }
        // Each row's first nonzero column: the factor keeps that profile (no fill left of
        // it), and a tree's joints in the order topo lists them couple mostly with near
        // neighbours.
        let first = &mut work.first[..n];
        for (r, f) in first.iter_mut().enumerate() {
            *f = r - r % 3;
        }
        for (c, block) in self.couplings.iter().zip(work.blocks.iter_mut()) {
            *block = None;
            let (row, col) = (work.slot[c.joints[0]], work.slot[c.joints[1]]);
            if row == usize::MAX || col == usize::MAX {
                continue;
            }
            let Some(p) = self.pose(c.segment, f) else {
                continue;
            };
            let scale = c.sign * self.scatters[c.segment].scale(f);
            let global = p.rot * c.local * p.rot.transpose() * scale;
            for r in 0..3 {
                for k in 0..3 {
                    matrix[(3 * row + r) * n + 3 * col + k] += global.col(k)[r];
                }
                first[3 * row + r] = first[3 * row + r].min(3 * col);
            }
            *block = Some(global);
        }
        cholesky_factor(matrix, n, first).then_some(n)
    }

    /// One frame's positions (module docs): each joint's into `out` (NaN where the joint
    /// keeps its pair positions).
    fn positions_in_frame(&self, f: usize, work: &mut Workspace, out: &mut [[f64; 3]]) {
        out.fill([f64::NAN; 3]);
        let Some(n) = self.factor_frame(f, work) else {
            return;
        };
        let (matrix, first, rhs) = (&work.matrix[..n * n], &work.first[..n], &mut work.rhs[..n]);
        forward_substitute(matrix, n, first, rhs, 0);
        back_substitute(matrix, n, first, rhs);
        if !rhs.iter().all(|v| v.is_finite()) {
            return;
        }
        // x_j = v_aj − Σ_k ε_ak C_a(j, k) λ_k: the couplings of j's `a` segment from j.
        for (j, x) in out.iter_mut().enumerate() {
            if work.slot[j] != usize::MAX
                && let Some(v) = self.view(j, 0, f)
            {
                *x = v.to_array();
            }
        }
        for (c, block) in self.couplings.iter().zip(&work.blocks) {
            if let Some(block) = block
                && c.from_a_side
            {
                let col = work.slot[c.joints[1]];
                let lambda = DVec3::from_slice(&rhs[3 * col..3 * col + 3]);
                let x = &mut out[c.joints[0]];
                *x = (DVec3::from_array(*x) - *block * lambda).to_array();
            }
        }
        for x in out.iter_mut() {
            if !x.iter().all(|v| v.is_finite()) {
                *x = [f64::NAN; 3];
            }
        }
    }
}

/// Every segment's couplings between the tree joints it carries (both orders, and each
/// joint with itself).
fn couplings(joints: &[SolveJoint], scatters: &[PoseScatter]) -> Vec<Coupling> {
    let mut out = Vec::new();
    for (j, joint_j) in joints.iter().enumerate() {
        for (side_j, &(s, c_j)) in joint_j.sides.iter().enumerate() {
            for (k, joint_k) in joints.iter().enumerate() {
                for (side_k, &(t, c_k)) in joint_k.sides.iter().enumerate() {
                    if t != s {
                        continue;
                    }
                    let Some(local) = scatters[s].covariance_between(c_j, c_k) else {
                        continue;
                    };
                    let sign = if side_j == side_k { 1.0 } else { -1.0 };
                    out.push(Coupling {
                        segment: s,
                        joints: [j, k],
                        sign,
                        from_a_side: side_j == 0,
                        local,
                    });
                }
            }
        }
    }
    out
}

/// Cholesky factor of the symmetric positive definite `a` (row-major n × n, row i zero
/// left of column `first[i]`) in its lower triangle; false when `a` is not positive
/// definite.
fn cholesky_factor(a: &mut [f64], n: usize, first: &[usize]) -> bool {
    for i in 0..n {
        for j in first[i]..=i {
            let mut sum = a[i * n + j];
            for k in first[i].max(first[j])..j {
                sum -= a[i * n + k] * a[j * n + k];
            }
            if i == j {
                if !(sum > 0.0 && sum.is_finite()) {
                    return false;
                }
                a[i * n + i] = sum.sqrt();
            } else {
                a[i * n + j] = sum / a[j * n + j];
            }
        }
    }
    true
}

/// Solves L y = b in place for the factor `l` of [`cholesky_factor`], `b` zero above row
/// `start`.
fn forward_substitute(l: &[f64], n: usize, first: &[usize], b: &mut [f64], start: usize) {
    for i in start..n {
        let mut sum = b[i];
        for k in first[i].max(start)..i {
            sum -= l[i * n + k] * b[k];
        }
        b[i] = sum / l[i * n + i];
    }
}

/// Solves Lᵀ x = y in place for the factor `l` of [`cholesky_factor`].
fn back_substitute(l: &[f64], n: usize, first: &[usize], y: &mut [f64]) {
    for i in (0..n).rev() {
        let mut sum = y[i];
        for k in i + 1..n {
            if first[k] <= i {
                sum -= l[k * n + i] * y[k];
            }
        }
        y[i] = sum / l[i * n + i];
    }
}

/// Most frames [`tree_centres`] reads, evenly strided (motion is smooth at capture rates).
const CENTRE_FRAMES: usize = 1000;

/// Frames per block of [`tree_centres`]' sums, added up in order (the same sums whatever
/// the threads).
const CENTRE_BLOCK_FRAMES: usize = 64;

/// Ridge toward the pair fits' centres, as a share of each joint's own mean eigenvalue: it
/// keeps a joint the motion barely fixes near where its pair fit put it. At 0.1 % the
/// neighbours' gaps carried such a centre far (snowman-hard-s30038's waist 49 → 133 mm off,
/// a real capture's joint 79 mm); the hard means of seeds 20001..20050,30001..30050 and
/// 40001..40100 were 1.464 and 1.456 % at 0.1 %, 1.466 and 1.456 at 1 %, 1.483 (the first)
/// at 3 %.
const CENTRE_RIDGE: f64 = 1e-2;

/// Weight of a hinge's place along its axis in [`tree_centres`], per unit of its joint's
/// mean eigenvalue: held to well under a millimetre.
const HINGE_PIN: f64 = 1e3;

/// Refits the centres of every tree joint in `edges` (`(pair, parent, child)`) all at once
/// by generalised least squares: SCoRE's gaps g_j = R_a c_a + t_a − R_b c_b − t_b of all the
/// tree's joints in a frame weighted by the inverse of their joint covariance M (module
/// docs), which the pairs' own weighing (`Params::weighted_centres`) takes one joint at a
/// time, as if the gaps of two joints on one segment were independent. M is taken at the
/// pair fits' centres; a small ridge holds each joint toward them, and a hinge's place
/// along its axis (which no motion fixes) stays theirs. Positions are recomputed from the
/// new centres, pair by pair. `poses` as for [`tree_positions`]. Returns how far the
/// centres moved (mm, mean over the joints and both sides), or `None` when nothing was
/// refitted.
pub fn tree_centres(
    fits: &mut PairFits,
    edges: &[(usize, usize, usize)],
    poses: &TreePoses,
) -> Option<f64> {
    let tree = TreeModel::of(fits, edges, poses)?;
    let count = tree.joints.len();
    let unknowns = 6 * count;
    let stride = fits.frames.div_ceil(CENTRE_FRAMES).max(1);
    let frames: Vec<usize> = (0..fits.frames).step_by(stride).collect();
    let partial: Vec<(Vec<f64>, Vec<f64>)> = frames
        .par_chunks(CENTRE_BLOCK_FRAMES)
        .map_init(
            || (tree.workspace(), vec![0.0; 3 * count * unknowns]),
            |(work, columns), block| {
                let mut normal = vec![0.0; unknowns * unknowns];
                let mut rhs = vec![0.0; unknowns];
                for &f in block {
                    tree.accumulate_centres(f, work, columns, &mut normal, &mut rhs);
                }
                (normal, rhs)
            },
        )
        .collect();
    let mut normal = vec![0.0; unknowns * unknowns];
    let mut rhs = vec![0.0; unknowns];
    for (n, r) in &partial {
        normal.iter_mut().zip(n).for_each(|(x, y)| *x += y);
        rhs.iter_mut().zip(r).for_each(|(x, y)| *x += y);
    }
    for row in 0..unknowns {
        for col in row + 1..unknowns {
            normal[row * unknowns + col] = normal[col * unknowns + row];
        }
    }
    // Ridge toward the pair fits' centres, and a hinge held along its axis.
    for (j, joint) in tree.joints.iter().enumerate() {
        let fit = &fits.pairs[joint.pair];
        let base = 6 * j;
        let trace: f64 = (0..6)
            .map(|i| normal[(base + i) * unknowns + base + i])
            .sum();
        let c0 = [joint.sides[0].1.to_array(), joint.sides[1].1.to_array()].concat();
        if !(trace.is_finite() && trace > 0.0) {
            // Never posed together in the frames read: it keeps its pair fit's centres.
            for i in 0..6 {
                normal[(base + i) * unknowns + base + i] = 1.0;
                rhs[base + i] = c0[i];
            }
            continue;
        }
        let ridge = CENTRE_RIDGE * trace / 6.0;
        for i in 0..6 {
            normal[(base + i) * unknowns + base + i] += ridge;
            rhs[base + i] += ridge * c0[i];
        }
        if fit.free_hinge()
            && let (Some(u_a), Some(u_b)) = (fit.axis_in_a, fit.axis_in_b)
        {
            // HINGE_PIN × trace × (v · (c − c0))², v = (u_a, u_b) / √2: the slide no motion
            // fixes.
            let v: Vec<f64> = [u_a, u_b]
                .concat()
                .iter()
                .map(|x| x / 2f64.sqrt())
                .collect();
            let pinned: f64 = v.iter().zip(&c0).map(|(x, y)| x * y).sum();
            for i in 0..6 {
                for k in 0..6 {
                    normal[(base + i) * unknowns + base + k] += HINGE_PIN * trace * v[i] * v[k];
                }
                rhs[base + i] += HINGE_PIN * trace * v[i] * pinned;
            }
        }
    }
    let first = vec![0; unknowns];
    if !cholesky_factor(&mut normal, unknowns, &first) {
        return None;
    }
    forward_substitute(&normal, unknowns, &first, &mut rhs, 0);
    back_substitute(&normal, unknowns, &first, &mut rhs);
    if !rhs.iter().all(|x| x.is_finite()) {
        return None;
    }
    let mut moved = 0.0;
    for (j, joint) in tree.joints.iter().enumerate() {
        let c_a = DVec3::from_slice(&rhs[6 * j..6 * j + 3]);
        let c_b = DVec3::from_slice(&rhs[6 * j + 3..6 * j + 6]);
        moved += 0.5 * (c_a.distance(joint.sides[0].1) + c_b.distance(joint.sides[1].1));
        let (a, b) = (joint.sides[0].0, joint.sides[1].0);
        let positions = crate::fit::joint_positions(
            c_a,
            c_b,
            crate::fit::PosedSegment::of(tree.scatters, tree.tracks, a),
            crate::fit::PosedSegment::of(tree.scatters, tree.tracks, b),
        );
        let fit = &mut fits.pairs[joint.pair];
        fit.centre_in_a = c_a.to_array();
        fit.centre_in_b = c_b.to_array();
        fit.positions = positions;
    }
    Some(moved / count as f64)
}

impl TreeModel<'_> {
    /// Adds frame `f`'s share of [`tree_centres`]' normal equations: with G the gaps'
    /// matrix in the centres and h = t_b − t_a per joint, Yᵀ Y to `normal` (its lower
    /// triangle) and Yᵀ L⁻¹ h to `rhs`, Y = L⁻¹ G (`columns`, column-major, n rows per
    /// column).
    fn accumulate_centres(
        &self,
        f: usize,
        work: &mut Workspace,
        columns: &mut [f64],
        normal: &mut [f64],
        rhs: &mut [f64],
    ) {
        let Some(n) = self.factor_frame(f, work) else {
            return;
        };
        let unknowns = 6 * self.joints.len();
        let (l, first) = (&work.matrix[..n * n], &work.first[..n]);
        // Each joint in the system, the row its columns start at, and its two poses.
        work.active.clear();
        for (j, joint) in self.joints.iter().enumerate() {
            let [(a, _), (b, _)] = joint.sides;
            if let (true, Some(pa), Some(pb)) =
                (work.slot[j] != usize::MAX, self.pose(a, f), self.pose(b, f))
            {
                work.active.push((j, 3 * work.slot[j], pa, pb));
            }
        }
        let active = &work.active;
        // h = t_b − t_a, whitened: z = L⁻¹ h.
        let z = &mut work.rhs[..n];
        for &(_, row, pa, pb) in active {
            z[row..row + 3].copy_from_slice(&(pb.trans - pa.trans).to_array());
        }
        forward_substitute(l, n, first, z, 0);
        // Y's six columns per active joint: [R_a, −R_b] in the joint's rows, whitened.
        for (slot, &(_, row, pa, pb)) in active.iter().enumerate() {
            for k in 0..6 {
                let column = &mut columns[(6 * slot + k) * n..(6 * slot + k + 1) * n];
                column.fill(0.0);
                let g = if k < 3 {
                    pa.rot.col(k)
                } else {
                    -pb.rot.col(k - 3)
                };
                column[row..row + 3].copy_from_slice(&g.to_array());
                forward_substitute(l, n, first, column, row);
            }
        }
        for (s1, &(j1, row1, _, _)) in active.iter().enumerate() {
            for k1 in 0..6 {
                let c1 = &columns[(6 * s1 + k1) * n..(6 * s1 + k1 + 1) * n];
                let u1 = 6 * j1 + k1;
                rhs[u1] += (row1..n).map(|r| c1[r] * z[r]).sum::<f64>();
                for (s2, &(j2, row2, _, _)) in active.iter().enumerate() {
                    // The lower triangle; the upper is its mirror (`tree_centres`).
                    for k2 in (0..6).filter(|&k2| 6 * j2 + k2 <= u1) {
                        let c2 = &columns[(6 * s2 + k2) * n..(6 * s2 + k2 + 1) * n];
                        let from = row1.max(row2);
                        normal[u1 * unknowns + 6 * j2 + k2] +=
                            (from..n).map(|r| c1[r] * c2[r]).sum::<f64>();
                    }
                }
            }
        }
    }
}
