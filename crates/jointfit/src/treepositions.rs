//! Joint positions per frame read over the whole tree at once ([`tree_positions`]).
//!
//! A pair's positions weigh its two segments' views of the centre by each pose's precision
//! there, one joint at a time (`fit::joint_positions`). Once the tree is known, more is
//! seen: a segment's pose error in a frame is one rigid error that shows at every joint the
//! segment carries, so the gap between the two views of one joint says something about
//! both poses, and through them about the segments' other joints (a thigh posed off at the
//! hip is posed off at the knee too).
//!
//! The model is the one the pair's weighing uses, taken over the tree: in frame f, segment
//! s's pose is off by a translation at its reference markers' centroid and a small turn,
//! Gaussian with covariance k_s(f) σ_s² diag(I/n, J⁻¹) (its fit scatter σ, its frame's
//! misfit scale k, its n reference markers' inertia tensor J; `poses::PoseScatter`), the
//! segments independently; its view of a point d from the centroid is then off by the
//! translation plus the turn × d. Every tree joint is one point both its segments see.
//! The positions are that model's posterior mean given every joint's two views in the
//! frame: with g_j = v_aj − v_bj the gap of joint j (a, b its segments) and
//! C_s(j, k) = Cov(s's view error at j, at k) (`PoseScatter::covariance_between`, turned
//! into the world by s's pose), solve Σ_k M_jk λ_k = g_j with M_jk = Σ_s ε_sj ε_sk C_s(j, k)
//! (ε = +1 on a joint's `a` side, −1 on its `b` side), then x_j = v_aj − Σ_k ε_ak C_a(j, k) λ_k.
//! A joint alone (no tree neighbour sharing a posed segment) gets exactly the pair's
//! weighted mean. A joint with a segment that has no precision (two markers, posed through
//! a joint) or not posed in the frame keeps its pair positions there, and tells the others
//! nothing.

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
}

/// Recomputes the positions of every tree joint in `edges` (`(pair, parent, child)`, the
/// parent and child unused) from all tree joints' views at once (module docs); pairs not
/// in `edges`, and frames or joints the solve cannot read, keep their positions. Returns
/// how many joint-frames changed.
pub fn tree_positions(fits: &mut PairFits, edges: &[(usize, usize, usize)]) -> usize {
    let scatters: Vec<PoseScatter> = fits.poses.par_iter().map(PoseScatter::of).collect();
    let tracks: Vec<Vec<Option<Pose>>> = fits.poses.par_iter().map(pose_track).collect();
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
        return 0;
    }
    let couplings = couplings(&joints, &scatters);
    let count = joints.len();
    let frames = fits.frames;
    let mut solved = vec![[f64::NAN; 3]; frames * count];
    solved.par_chunks_mut(count).enumerate().for_each_init(
        || Workspace {
            slot: vec![usize::MAX; count],
            matrix: vec![0.0; 9 * count * count],
            rhs: vec![0.0; 3 * count],
            first: vec![0; 3 * count],
            blocks: vec![None; couplings.len()],
        },
        |work, (f, out)| solve_frame(f, &joints, &couplings, &scatters, &tracks, work, out),
    );
    let mut changed = 0;
    for (j, joint) in joints.iter().enumerate() {
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

/// One frame's solve (module docs): writes each joint's position into `out` (NaN where
/// the joint keeps its pair positions).
fn solve_frame(
    f: usize,
    joints: &[SolveJoint],
    couplings: &[Coupling],
    scatters: &[PoseScatter],
    tracks: &[Vec<Option<Pose>>],
    work: &mut Workspace,
    out: &mut [[f64; 3]],
) {
    let pose = |s: usize| tracks[s].get(f).copied().flatten();
    // The joints both of whose segments are posed, in system order.
    let mut size = 0;
    for (j, joint) in joints.iter().enumerate() {
        let posed = joint.sides.iter().all(|&(s, _)| pose(s).is_some());
        work.slot[j] = if posed {
            size += 1;
            size - 1
        } else {
            usize::MAX
        };
    }
    out.fill([f64::NAN; 3]);
    if size == 0 {
        return;
    }
    let n = 3 * size;
    let matrix = &mut work.matrix[..n * n];
    matrix.fill(0.0);
    let rhs = &mut work.rhs[..n];
    // The view of joint j from its side `side`.
    let view = |j: usize, side: usize| {
        let (s, c) = joints[j].sides[side];
        pose(s).map(|p| p.apply(c))
    };
    for j in 0..joints.len() {
        let row = work.slot[j];
        if row == usize::MAX {
            continue;
        }
        let (Some(v_a), Some(v_b)) = (view(j, 0), view(j, 1)) else {
            return;
        };
        rhs[3 * row..3 * row + 3].copy_from_slice(&(v_a - v_b).to_array());
    }
    // Each row's first nonzero column: the factor keeps that profile (no fill left of it),
    // and a tree's joints in the order topo lists them couple mostly with near neighbours.
    let first = &mut work.first[..n];
    for (r, f) in first.iter_mut().enumerate() {
        *f = r - r % 3;
    }
    for (c, block) in couplings.iter().zip(work.blocks.iter_mut()) {
        *block = None;
        let (row, col) = (work.slot[c.joints[0]], work.slot[c.joints[1]]);
        if row == usize::MAX || col == usize::MAX {
            continue;
        }
        let Some(p) = pose(c.segment) else {
            continue;
        };
        let global = p.rot * c.local * p.rot.transpose() * (c.sign * scatters[c.segment].scale(f));
        for r in 0..3 {
            for k in 0..3 {
                matrix[(3 * row + r) * n + 3 * col + k] += global.col(k)[r];
            }
            first[3 * row + r] = first[3 * row + r].min(3 * col);
        }
        *block = Some(global);
    }
    if !cholesky_solve(matrix, n, first, rhs) {
        return;
    }
    // x_j = v_aj − Σ_k ε_ak C_a(j, k) λ_k: the couplings of j's `a` segment from j.
    for (j, x) in out.iter_mut().enumerate() {
        if work.slot[j] != usize::MAX
            && let Some(v) = view(j, 0)
        {
            *x = v.to_array();
        }
    }
    for (c, block) in couplings.iter().zip(&work.blocks) {
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

/// Solves `a x = b` in place (`b` becomes x) for a symmetric positive definite `a`
/// (row-major n × n, its lower triangle overwritten by its Cholesky factor) whose row i
/// is zero left of column `first[i]`; false when `a` is not positive definite.
fn cholesky_solve(a: &mut [f64], n: usize, first: &[usize], b: &mut [f64]) -> bool {
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
    for i in 0..n {
        let mut sum = b[i];
        for k in first[i]..i {
            sum -= a[i * n + k] * b[k];
        }
        b[i] = sum / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut sum = b[i];
        for k in i + 1..n {
            if first[k] <= i {
                sum -= a[k * n + i] * b[k];
            }
        }
        b[i] = sum / a[i * n + i];
    }
    b.iter().all(|v| v.is_finite())
}
