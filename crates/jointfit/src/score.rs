//! Symmetrical centre of rotation (SCoRE, Ehrig et al. 2006).
//!
//! Unknowns: the joint centre `c_a` in a's local frame and `c_b` in b's. Every frame where
//! both poses are known gives three equations `R_a c_a + t_a = R_b c_b + t_b`, i.e.
//! `[R_a  −R_b] [c_a; c_b] = t_b − t_a`. The 6×6 normal equations are accumulated
//! (allocation-free) and solved by eigen-decomposition. Hinges leave one direction
//! (the axis, in both frames at once: SARA) and rigid pairs three directions undetermined;
//! those components are not taken from noise but chosen to put the centre nearest the
//! midpoint of the two segments' origins (see [`crate::fit`]).

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;

use crate::poses::Pose;
use crate::small::sym_eigen;

/// Solution of the stacked system.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScoreSolution {
    /// Centre in a's local frame (mm).
    pub c_a: DVec3,
    /// Centre in b's local frame (mm).
    pub c_b: DVec3,
    /// Eigenvalues of the normal matrix divided by the frame count, descending.
    pub eigenvalues: [f64; 6],
}

/// Solves SCoRE over `frames`, leaving the `drop` least-determined directions to `target`
/// (a point `[c_a; c_b]` the solution is pulled to along those directions only).
pub(crate) fn solve(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
    drop: usize,
    target: (DVec3, DVec3),
) -> ScoreSolution {
    let n = frames.len().max(1) as f64;
    let mut normal = [[0.0f64; 6]; 6];
    let mut rhs = [0.0f64; 6];
    for &f in frames {
        let (Some(a), Some(b)) = (&pa[f], &pb[f]) else {
            continue;
        };
        let d = b.trans - a.trans;
        let ra_t = a.rot.transpose();
        let rb_t = b.rot.transpose();
        let cross = ra_t * b.rot;
        let ga = ra_t * d;
        let gb = -(rb_t * d);
        for i in 0..3 {
            normal[i][i] += 1.0;
            normal[i + 3][i + 3] += 1.0;
            for j in 0..3 {
                // Lower triangle is read: block (b, a) = −(R_aᵀ R_b)ᵀ.
                normal[j + 3][i] -= cross.col(j)[i];
            }
            rhs[i] += ga[i];
            rhs[i + 3] += gb[i];
        }
    }
    for row in normal.iter_mut() {
        for x in row.iter_mut() {
            *x /= n;
        }
    }
    for x in rhs.iter_mut() {
        *x /= n;
    }
    let (values, vectors) = sym_eigen(normal);
    let lmax = values[0].max(f64::MIN_POSITIVE);
    let mut x = [0.0f64; 6];
    let keep = 6usize.saturating_sub(drop);
    for k in 0..6 {
        let v = &vectors[k];
        if k < keep && values[k] > 1e-12 * lmax {
            let coef = dot6(v, &rhs) / values[k];
            for i in 0..6 {
                x[i] += coef * v[i];
            }
        }
    }
    // Undetermined directions: move to the target along them (orthogonal projection onto
    // the solution set, which is x + span of those eigenvectors).
    let t = [
        target.0.x, target.0.y, target.0.z, target.1.x, target.1.y, target.1.z,
    ];
    let mut diff = [0.0f64; 6];
    for i in 0..6 {
        diff[i] = t[i] - x[i];
    }
    let mut adjust = [0.0f64; 6];
    for k in 0..6 {
        if !(k < keep && values[k] > 1e-12 * lmax) {
            let v = &vectors[k];
            let coef = dot6(v, &diff);
            for i in 0..6 {
                adjust[i] += coef * v[i];
            }
        }
    }
    for i in 0..6 {
        x[i] += adjust[i];
    }
    ScoreSolution {
        c_a: DVec3::new(x[0], x[1], x[2]),
        c_b: DVec3::new(x[3], x[4], x[5]),
        eigenvalues: values,
    }
}

fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
