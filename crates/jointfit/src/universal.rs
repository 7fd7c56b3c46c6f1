//! Universal (Hooke, Cardan) joints: two rotation axes, the first fixed in one segment and
//! the second in the other.
//!
//! With `R(t) = R_aᵀ R_b` (b-local → a-local), a universal joint about `u_a` (fixed in a)
//! and `u_b` (fixed in b) is `R = Rot(u_a, α) R₀ Rot(u_b, β)`, so `u_a · R(t) u_b` never
//! changes: the angle between the two axes is constant. A ball joint has no such pair of
//! directions, and a hinge has many (its axis with any other). Writing `r(t) = vec R(t)` and
//! `C` its 9×9 covariance over the frames, the variance of `u_a · R u_b` is the quadratic
//! form `(u_a ⊗ u_b)ᵀ C (u_a ⊗ u_b)`; for a fixed `u_b` the best `u_a` is the least
//! eigenvector of a 3×3 matrix and vice versa. A grid over `u_b` and alternating refinement
//! find the pair whose angle wobbles least. What of that wobble neither the joint's two
//! angles explain linearly (skin tilts the posed segments smoothly with them) nor
//! frame-to-frame noise does is what a third rotation would leave; against the joint's
//! whole motion (`Params::universal_ratio`) it says whether the pair turns about two axes
//! or three.

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;
use rayon::prelude::*;

use crate::pairfits::{JointKind, PairFits};
use crate::params::Params;
use crate::poses::{Pose, pose_track};
use crate::small::sym_eigen;

/// A pair is tested when its cost is at most this many times the larger of its two
/// segments' cheapest pair costs (plus [`CANDIDATE_COST_SLACK_MM`]): only a pair a tree
/// could use has its kind written, and topo's rules read a universal joint as a ball
/// joint (its composite rules take a pair at up to 3 times the cost of the pairs it is
/// weighed against).
const CANDIDATE_COST_RATIO: f64 = 3.0;

/// ... plus this (mm): noiseless joints all cost next to nothing, in any ratio.
const CANDIDATE_COST_SLACK_MM: f64 = 1.0;

/// Calls universal every ball pair a tree could use (see [`CANDIDATE_COST_RATIO`]) whose
/// best pair of axes keeps its angle, beyond a linear function of the joint's two angles
/// and frame-to-frame noise, within `Params::universal_ratio` of the pair's RMS relative
/// rotation; sets its kind and axes and adds the evidence either way.
pub(crate) fn read_universal_joints(fits: &mut PairFits, params: &Params) {
    if params.universal_ratio <= 0.0 {
        return;
    }
    let mut cheapest = vec![f64::INFINITY; fits.poses.len()];
    for p in fits.pairs.iter().filter(|p| p.cost.is_finite()) {
        for s in [p.a, p.b] {
            if let Some(c) = cheapest.get_mut(s) {
                *c = c.min(p.cost);
            }
        }
    }
    let tracks: Vec<Vec<Option<Pose>>> = fits.poses.par_iter().map(pose_track).collect();
    fits.pairs.par_iter_mut().for_each(|fit| {
        let (Some(&ca), Some(&cb)) = (cheapest.get(fit.a), cheapest.get(fit.b)) else {
            return;
        };
        if fit.kind != JointKind::Ball
            || !fit.cost.is_finite()
            || fit.cost > CANDIDATE_COST_RATIO * ca.max(cb) + CANDIDATE_COST_SLACK_MM
        {
            return;
        }
        let (pa, pb) = (&tracks[fit.a], &tracks[fit.b]);
        let frames: Vec<usize> = (0..pa.len().min(pb.len()))
            .filter(|&f| pa[f].is_some() && pb[f].is_some())
            .collect();
        let Some(axes) = universal_axes(pa, pb, &frames) else {
            return;
        };
        let ratio = axes.third_deg / fit.rotation_rms_deg.max(f64::MIN_POSITIVE);
        let verdict = if ratio < params.universal_ratio {
            fit.kind = JointKind::Universal;
            fit.universal_axes = Some([axes.axis_in_a.to_array(), axes.axis_in_b.to_array()]);
            format!(
                "universal: ratio < universal_ratio {}",
                params.universal_ratio
            )
        } else {
            format!(
                "not universal: ratio ≥ universal_ratio {}",
                params.universal_ratio
            )
        };
        fit.evidence.push_str(&format!(
            "; {verdict}: the pair of axes (one fixed in each segment) whose angle changes \
             least keeps its {:.1}° within {:.2}° RMS, {:.2}° beyond what the joint's two \
             angles explain linearly and frame-to-frame noise ({ratio:.3} of the relative \
             rotation)",
            axes.angle_deg, axes.wobble_deg, axes.third_deg
        ));
    });
}

/// The best pair of axes of a segment pair read as a universal joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct UniversalAxes {
    /// The axis fixed in a's frame (unit).
    pub axis_in_a: DVec3,
    /// The axis fixed in b's frame (unit).
    pub axis_in_b: DVec3,
    /// RMS deviation of the angle between the two axes from its mean over the frames
    /// (degrees): zero for a perfect universal joint.
    pub wobble_deg: f64,
    /// Mean angle between the two axes (degrees).
    pub angle_deg: f64,
    /// `wobble_deg` less what the two joint angles explain linearly (skin moves the
    /// markers, and so the fitted poses, smoothly with the joint's own angles: the
    /// artefact's rigid component) and less the frame-to-frame white noise (half the mean
    /// square step between consecutive frames, less what a motion as rough as the joint's
    /// own angles steps by): the part a third rotation would leave.
    pub third_deg: f64,
}

/// Directions of the grid over `u_b` (a hemisphere: `u_b` and `−u_b` are one axis).
const GRID: usize = 256;

/// Alternating refinement rounds after the grid.
const ROUNDS: usize = 50;

/// The pair of axes (one fixed in each segment) whose angle changes least over `frames`;
/// `None` without a frame where both poses are known.
pub(crate) fn universal_axes(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
) -> Option<UniversalAxes> {
    let mut n = 0.0;
    let mut mean = [0.0f64; 9];
    let mut second = [[0.0f64; 9]; 9];
    for &f in frames {
        let (Some(a), Some(b)) = (&pa[f], &pb[f]) else {
            continue;
        };
        let r = relative_entries(a, b);
        n += 1.0;
        for i in 0..9 {
            mean[i] += r[i];
            for j in 0..=i {
                second[i][j] += r[i] * r[j];
            }
        }
    }
    if n == 0.0 {
        return None;
    }
    let mut cov = [[0.0f64; 9]; 9];
    for i in 0..9 {
        for j in 0..=i {
            let c = second[i][j] / n - (mean[i] / n) * (mean[j] / n);
            cov[i][j] = c;
            cov[j][i] = c;
        }
    }
    // Variance of u·R v as a quadratic form in u (R's row index) for fixed v, and in v
    // (its column index) for fixed u. Entry (i, j) of R sits at 3i + j.
    let form = |fixed: DVec3, free_is_row: bool| -> [[f64; 3]; 3] {
        let at = |free: usize, other: usize| {
            if free_is_row {
                3 * free + other
            } else {
                3 * other + free
            }
        };
        let mut m = [[0.0; 3]; 3];
        for p in 0..3 {
            for q in 0..3 {
                let mut s = 0.0;
                for x in 0..3 {
                    for y in 0..3 {
                        s += cov[at(p, x)][at(q, y)] * fixed[x] * fixed[y];
                    }
                }
                m[p][q] = s;
            }
        }
        m
    };
    let form_in_a = |v: DVec3| form(v, true);
    let form_in_b = |u: DVec3| form(u, false);
    let mean_rotation = glam::DMat3::from_cols_array(&std::array::from_fn(|k| {
        // Column-major: element k is (row k % 3, column k / 3), stored at 3·row + column.
        mean[3 * (k % 3) + k / 3] / n
    }));
    // The variance of u·R v is that of cos α (α the axes' angle), which shrinks by sin²α
    // near parallel axes; divide by 1 − E[u·R v]², which is sin²ᾱ to first order, to weigh
    // every pair by the wobble of α itself. For a fixed other axis with mean image m that
    // is the generalised eigenproblem M x = λ (I − m mᵀ) x, solved by whitening.
    let least = |form: [[f64; 3]; 3], m: DVec3| -> (f64, DVec3) {
        let length_sq = m.length_squared();
        let stretch = 1.0 / (1.0 - length_sq).max(1e-9).sqrt() - 1.0;
        let unit = m.try_normalize().unwrap_or(DVec3::ZERO);
        let w = glam::DMat3::IDENTITY
            + glam::DMat3::from_cols(unit * unit.x, unit * unit.y, unit * unit.z) * stretch;
        let f = glam::DMat3::from_cols_array_2d(&form);
        let (values, vectors) = sym_eigen((w * f * w).to_cols_array_2d());
        let x = (w * DVec3::from_array(vectors[2])).normalize();
        (values[2].max(0.0), x)
    };
    // Grid: a Fibonacci spiral over the upper hemisphere.
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut best = (f64::INFINITY, DVec3::X, DVec3::Z);
    for k in 0..GRID {
        let z = 1.0 - (k as f64 + 0.5) / GRID as f64;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * k as f64;
        let v = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        let (value, u) = least(form_in_a(v), mean_rotation * v);
        if value < best.0 {
            best = (value, u, v);
        }
    }
    let (mut value, mut u, mut v) = best;
    for _ in 0..ROUNDS {
        let (_, v_next) = least(form_in_b(u), mean_rotation.transpose() * u);
        let (value_next, u_next) = least(form_in_a(v_next), mean_rotation * v_next);
        let settled = value - value_next <= 1e-12 * value.max(f64::MIN_POSITIVE);
        if value_next <= value {
            (value, u, v) = (value_next, u_next, v_next);
        }
        if settled {
            break;
        }
    }
    // Per frame: the angle between the axes, and the joint's two angles, each measured
    // as the turn of the other axis's image about it from its first frame's direction.
    let mut samples: Vec<(usize, f64, f64, f64)> = Vec::with_capacity(frames.len());
    let (mut ref_a, mut ref_b) = (None, None);
    for &f in frames {
        let (Some(a), Some(b)) = (&pa[f], &pb[f]) else {
            continue;
        };
        let r = a.rot.transpose() * b.rot;
        let (v_in_a, u_in_b) = (r * v, r.transpose() * u);
        let between = u.dot(v_in_a).clamp(-1.0, 1.0).acos();
        let across = |axis: DVec3, w: DVec3| (w - axis * axis.dot(w)).try_normalize();
        let (Some(wa), Some(wb)) = (across(u, v_in_a), across(v, u_in_b)) else {
            continue;
        };
        let wa0 = *ref_a.get_or_insert(wa);
        let wb0 = *ref_b.get_or_insert(wb);
        let turn = |axis: DVec3, w0: DVec3, w: DVec3| axis.dot(w0.cross(w)).atan2(w0.dot(w));
        samples.push((f, between, turn(u, wa0, wa), turn(v, wb0, wb)));
    }
    if samples.is_empty() {
        return None;
    }
    let count = samples.len() as f64;
    let mean = samples.iter().map(|s| s.1).sum::<f64>() / count;
    let wobble = (samples.iter().map(|s| (s.1 - mean).powi(2)).sum::<f64>() / count).sqrt();
    let residuals = linear_residuals(&samples);
    let third_var = residuals.iter().map(|r| r * r).sum::<f64>() / count;
    // White noise: half the mean square step of the residual between consecutive frames,
    // less what a third rotation as rough as the joint's own two angles would step by
    // (its variance × their roughness: the share of their variance their steps make). At
    // capture rates a joint's angles barely step (roughness ~1e-3) and this is the noise;
    // a motion that jumps from frame to frame leaves nothing to tell noise by.
    let (mut steps, mut step_sq, mut angle_step_sq) = (0.0, 0.0, 0.0);
    for (w, pair) in samples.windows(2).zip(residuals.windows(2)) {
        if w[1].0 == w[0].0 + 1 {
            steps += 1.0;
            step_sq += (pair[1] - pair[0]).powi(2);
            angle_step_sq += (w[1].2 - w[0].2).powi(2) + (w[1].3 - w[0].3).powi(2);
        }
    }
    let angle_var = {
        let m1 = samples.iter().map(|s| s.2).sum::<f64>() / count;
        let m2 = samples.iter().map(|s| s.3).sum::<f64>() / count;
        samples
            .iter()
            .map(|s| (s.2 - m1).powi(2) + (s.3 - m2).powi(2))
            .sum::<f64>()
            / count
    };
    let white = if steps > 0.0 && angle_var > 0.0 {
        let roughness = (angle_step_sq / steps / 2.0 / angle_var).min(1.0);
        (step_sq / steps / 2.0 - roughness * third_var).max(0.0)
    } else {
        0.0
    };
    Some(UniversalAxes {
        axis_in_a: u,
        axis_in_b: v,
        wobble_deg: wobble.to_degrees(),
        angle_deg: mean.to_degrees(),
        third_deg: (third_var - white).max(0.0).sqrt().to_degrees(),
    })
}

/// Residuals of the least-squares fit `between ≈ c₀ + c₁ first + c₂ second` over
/// `(frame, between, first, second)` samples (all of `between` minus its mean where the
/// fit is singular).
fn linear_residuals(samples: &[(usize, f64, f64, f64)]) -> Vec<f64> {
    let mut normal = [[0.0f64; 3]; 3];
    let mut rhs = [0.0f64; 3];
    for &(_, y, x1, x2) in samples {
        let x = [1.0, x1, x2];
        for i in 0..3 {
            for j in 0..3 {
                normal[i][j] += x[i] * x[j];
            }
            rhs[i] += x[i] * y;
        }
    }
    let (values, vectors) = sym_eigen(normal);
    let mut c = [0.0f64; 3];
    for k in 0..3 {
        if values[k] > 1e-12 * values[0].max(f64::MIN_POSITIVE) {
            let coef = (0..3).map(|i| vectors[k][i] * rhs[i]).sum::<f64>() / values[k];
            for i in 0..3 {
                c[i] += coef * vectors[k][i];
            }
        }
    }
    samples
        .iter()
        .map(|&(_, y, x1, x2)| y - c[0] - c[1] * x1 - c[2] * x2)
        .collect()
}

/// The entries of `R_aᵀ R_b`, row-major.
fn relative_entries(a: &Pose, b: &Pose) -> [f64; 9] {
    let r = a.rot.transpose() * b.rot;
    let mut out = [0.0; 9];
    for i in 0..3 {
        for j in 0..3 {
            out[3 * i + j] = r.col(j)[i];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    fn pose(rot: DMat3) -> Option<Pose> {
        Some(Pose {
            rot,
            trans: DVec3::ZERO,
        })
    }

    /// Poses of a pair whose relative rotation is `rel(t)` at 400 frames, with a tumbling
    /// parent so nothing lines up with the world axes.
    fn pair(rel: impl Fn(f64) -> DMat3) -> (Vec<Option<Pose>>, Vec<Option<Pose>>, Vec<usize>) {
        let frames = 400;
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        for f in 0..frames {
            let t = f as f64 / frames as f64;
            let parent = DMat3::from_axis_angle(DVec3::new(0.3, 0.5, 0.8).normalize(), 2.0 * t)
                * DMat3::from_rotation_x(0.7 * (5.0 * t).sin());
            pa.push(pose(parent));
            pb.push(pose(parent * rel(t)));
        }
        (pa, pb, (0..frames).collect())
    }

    #[test]
    fn finds_the_two_axes_of_a_universal_joint() {
        let ua = DVec3::new(1.0, 0.4, -0.2).normalize();
        let ub = ua.any_orthonormal_vector();
        let (pa, pb, frames) = pair(|t| {
            DMat3::from_axis_angle(ua, 0.8 * (7.0 * t).sin())
                * DMat3::from_axis_angle(ub, 0.6 * (11.0 * t).cos())
        });
        let fit = universal_axes(&pa, &pb, &frames).expect("frames");
        assert!(fit.wobble_deg < 1e-4, "{fit:?}");
        assert!(fit.axis_in_a.dot(ua).abs() > 1.0 - 1e-6, "{fit:?}");
        assert!(fit.axis_in_b.dot(ub).abs() > 1.0 - 1e-6, "{fit:?}");
        assert!((fit.angle_deg - 90.0).abs() < 1e-3);
    }

    #[test]
    fn a_ball_joint_leaves_a_wobble_of_its_third_rotation() {
        let (pa, pb, frames) = pair(|t| {
            DMat3::from_rotation_z(0.7 * (7.0 * t).sin())
                * DMat3::from_rotation_y(0.5 * (11.0 * t).cos())
                * DMat3::from_rotation_x(0.4 * (13.0 * t).sin())
        });
        let fit = universal_axes(&pa, &pb, &frames).expect("frames");
        // Three rotations of 0.4–0.7 rad amplitude: what no pair of axes keeps is well above
        // the default universal_ratio of the relative rotation (0.10 measured).
        let rotation = crate::motion::relative_motion(&pa, &pb, &frames).rms_deg;
        let ratio = fit.third_deg / rotation;
        let threshold = crate::Params::default().universal_ratio;
        assert!(ratio > 2.0 * threshold, "{ratio} {fit:?}");
    }

    #[test]
    fn skin_linear_in_the_angles_and_white_noise_are_not_a_third_rotation() {
        let ua = DVec3::new(0.2, 1.0, 0.1).normalize();
        let ub = ua.any_orthonormal_vector();
        // A tilt about the common normal linear in both angles (as skin gives a posed
        // segment), plus frame-to-frame jitter from a fixed pseudo-random sequence (±0.05
        // rad: σ 1.7°).
        let normal = ua.cross(ub);
        let jitter = |t: f64| {
            // splitmix64 of the frame number, to [−1, 1).
            let mut z = (t * 400.0).round() as u64 + 0x9E37_79B9_7F4A_7C15;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            0.05 * ((z >> 11) as f64 / (1u64 << 52) as f64 - 1.0)
        };
        let (pa, pb, frames) = pair(|t| {
            let (a, b) = (0.8 * (7.0 * t).sin(), 0.6 * (11.0 * t).cos());
            DMat3::from_axis_angle(ua, a)
                * DMat3::from_axis_angle(normal, 0.05 * a - 0.04 * b + jitter(t))
                * DMat3::from_axis_angle(ub, b)
        });
        let fit = universal_axes(&pa, &pb, &frames).expect("frames");
        assert!(fit.wobble_deg > 1.0, "the raw angle wobbles: {fit:?}");
        let rotation = crate::motion::relative_motion(&pa, &pb, &frames).rms_deg;
        assert!(
            fit.third_deg / rotation < 0.25 * crate::Params::default().universal_ratio,
            "{fit:?}"
        );
    }
}
