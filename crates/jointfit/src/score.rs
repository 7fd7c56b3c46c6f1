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
    solve_normal(normal, rhs, n, drop, target)
}

/// Solves the accumulated normal equations (sums over `n` frames), leaving the `drop`
/// least-determined directions to `target` (see [`solve`]).
fn solve_normal(
    mut normal: [[f64; 6]; 6],
    mut rhs: [f64; 6],
    n: f64,
    drop: usize,
    target: (DVec3, DVec3),
) -> ScoreSolution {
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

/// A line through a segment's markers in its local frame (mm): markers nearly on it fix
/// the segment's spin about it poorly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MarkerLine {
    /// A point of the line (the markers' centroid).
    pub origin: DVec3,
    /// Unit direction.
    pub dir: DVec3,
    /// Standard error of the segment's spin about it per frame (radians).
    pub spin_sd_rad: f64,
}

/// SCoRE with one segment's spin about its marker line weighed as noise, and the pair's
/// RMS residual (mm) on the same footing as an ordinary pair's.
///
/// A spin error δφ about the loose segment's marker line moves its image of the centre by
/// δφ·ρ along `v = u × (c − o)` (ρ the centre's distance from the line), so that component
/// of the disagreement has variance σ² + ρ²σ_φ² where the other two have σ² (estimated from
/// them). Weighing it by σ² / (σ² + ρ²σ_φ²) (the spin error marginalised under its standard
/// error σ_φ) leaves a residual whose mean square is 3σ² like any pair's. The centres are
/// refitted under those weights from `start` a few times, since the weights depend on them:
/// on the segment's own noisy spin the least-squares centre is pulled towards its line. The
/// spin is not set free: its real motion (about a line along a hinge axis) still counts,
/// against its standard error. `line_a` says the loose segment is `a`; `drop` and `target`
/// are [`solve`]'s. `None` without a common frame.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve_spin_weighted(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
    start: (DVec3, DVec3),
    drop: usize,
    target: (DVec3, DVec3),
    line: MarkerLine,
    line_a: bool,
) -> Option<(ScoreSolution, f64)> {
    let mut centres = start;
    let mut solution = None;
    for _ in 0..SPIN_WEIGHT_ROUNDS {
        let spin = SpinWeight::at(pa, pb, frames, centres, line, line_a)?;
        let mut normal = [[0.0f64; 6]; 6];
        let mut rhs = [0.0f64; 6];
        for &f in frames {
            let (Some(x), Some(y)) = (&pa[f], &pb[f]) else {
                continue;
            };
            // Least squares under W = I − (1 − weight) v̂ v̂ᵀ, A = [R_a  −R_b].
            let v = spin.direction(x, y);
            let w = glam::DMat3::IDENTITY
                - (1.0 - spin.weight) * glam::DMat3::from_cols(v * v.x, v * v.y, v * v.z);
            let blocks = [x.rot, -y.rot];
            let d = w * (y.trans - x.trans);
            for (bi, ri) in blocks.iter().enumerate() {
                let g = ri.transpose() * d;
                for (bj, rj) in blocks.iter().enumerate() {
                    let m = ri.transpose() * w * *rj;
                    for i in 0..3 {
                        for j in 0..3 {
                            normal[3 * bi + i][3 * bj + j] += m.col(j)[i];
                        }
                    }
                }
                for i in 0..3 {
                    rhs[3 * bi + i] += g[i];
                }
            }
        }
        let sol = solve_normal(normal, rhs, spin.frames, drop, target);
        centres = (sol.c_a, sol.c_b);
        solution = Some(sol);
    }
    let sol = solution?;
    let spin = SpinWeight::at(pa, pb, frames, centres, line, line_a)?;
    Some((sol, spin.rms))
}

/// Rounds of [`solve_spin_weighted`]: the weights settle in two or three.
const SPIN_WEIGHT_ROUNDS: usize = 3;

/// The weight of the loose segment's spin direction at given centres (see
/// [`solve_spin_weighted`]) and the weighted RMS residual there.
struct SpinWeight {
    /// The centre's lever about the marker line, in the loose segment's frame (mm).
    lever: DVec3,
    /// Which segment is the loose one.
    line_a: bool,
    /// σ² / (σ² + ρ²σ_φ²).
    weight: f64,
    /// Weighted RMS residual (mm).
    rms: f64,
    /// Frames where both are posed.
    frames: f64,
}

impl SpinWeight {
    fn at(
        pa: &[Option<Pose>],
        pb: &[Option<Pose>],
        frames: &[usize],
        (c_a, c_b): (DVec3, DVec3),
        line: MarkerLine,
        line_a: bool,
    ) -> Option<Self> {
        let lever = line.dir.cross(if line_a { c_a } else { c_b } - line.origin);
        let mut spin = Self {
            lever,
            line_a,
            weight: 1.0,
            rms: f64::NAN,
            frames: 0.0,
        };
        let (mut across, mut along) = (0.0, 0.0);
        for &f in frames {
            let (Some(x), Some(y)) = (&pa[f], &pb[f]) else {
                continue;
            };
            let d = x.apply(c_a) - y.apply(c_b);
            let on = d.dot(spin.direction(x, y));
            spin.frames += 1.0;
            across += d.length_squared() - on * on;
            along += on * on;
        }
        if spin.frames == 0.0 {
            return None;
        }
        let sigma2 = across / (2.0 * spin.frames);
        let rho_sd = lever.length() * line.spin_sd_rad;
        if sigma2 > 0.0 {
            spin.weight = sigma2 / (sigma2 + rho_sd * rho_sd);
        }
        spin.rms = ((across + spin.weight * along) / spin.frames).sqrt();
        Some(spin)
    }

    /// The unit direction a spin error moves the loose segment's image of the centre in.
    fn direction(&self, x: &Pose, y: &Pose) -> DVec3 {
        ((if self.line_a { x } else { y }).rot * self.lever).normalize_or_zero()
    }
}

#[cfg(test)]
mod tests {
    use glam::{DMat3, DQuat};

    use super::*;
    use crate::horn::tests::TestRng;

    /// A ball joint between `a` and a loose `b` whose own poses spin about b's marker line
    /// by `spin_sd_deg` of noise per frame; `drift_mm` of random translation per frame
    /// between them makes the pair no joint at all. Returns both pose tracks and the line.
    fn loose_pair(
        spin_sd_deg: f64,
        drift_mm: f64,
        seed: u64,
    ) -> (Vec<Option<Pose>>, Vec<Option<Pose>>, MarkerLine) {
        let mut rng = TestRng(seed);
        let (c_a, c_b) = (DVec3::new(0.0, 0.0, -200.0), DVec3::new(0.0, 0.0, 150.0));
        // b's markers lie along x, 90 mm from the joint.
        let line = MarkerLine {
            origin: DVec3::new(0.0, 90.0, 150.0),
            dir: DVec3::X,
            spin_sd_rad: spin_sd_deg.to_radians(),
        };
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        for _ in 0..300 {
            let ra = DMat3::from_quat(rng.rotation());
            let ta = rng.vec3(500.0) + rng.vec3(1.0);
            let turn = DQuat::from_scaled_axis(rng.vec3(0.8));
            let rb = ra * DMat3::from_quat(turn);
            // b's true pose puts c_b on a's centre (plus any drift).
            let joint = ra * c_a + ta + rng.vec3(drift_mm);
            let tb = joint - rb * c_b;
            // Its own pose: spun about its marker line by noise.
            let spin = DMat3::from_axis_angle(line.dir, rng.gauss() * line.spin_sd_rad);
            let rb_own = rb * spin;
            let tb_own = tb + rb * (line.origin - spin * line.origin);
            pa.push(Some(Pose { rot: ra, trans: ta }));
            pb.push(Some(Pose {
                rot: rb_own,
                trans: tb_own,
            }));
        }
        (pa, pb, line)
    }

    fn plain_rms(pa: &[Option<Pose>], pb: &[Option<Pose>], sol: &ScoreSolution) -> f64 {
        let sq: f64 = pa
            .iter()
            .zip(pb)
            .map(|(x, y)| {
                let (x, y) = (x.as_ref().unwrap(), y.as_ref().unwrap());
                (x.apply(sol.c_a) - y.apply(sol.c_b)).length_squared()
            })
            .sum();
        (sq / pa.len() as f64).sqrt()
    }

    #[test]
    fn spin_noise_about_the_marker_line_is_weighed_out_of_a_joints_cost() {
        let (pa, pb, line) = loose_pair(10.0, 0.0, 7);
        let frames: Vec<usize> = (0..pa.len()).collect();
        let target = (DVec3::ZERO, DVec3::ZERO);
        let plain = solve(&pa, &pb, &frames, 0, target);
        let plain_cost = plain_rms(&pa, &pb, &plain);
        let (sol, cost) = solve_spin_weighted(
            &pa,
            &pb,
            &frames,
            (plain.c_a, plain.c_b),
            0,
            target,
            line,
            false,
        )
        .unwrap();
        // 90 mm lever × 10° of spin: ~16 mm along one direction, ~1 mm of noise elsewhere
        // and ~2 mm of the spin's curvature (ρ(1 − cos φ), second order) towards the line.
        assert!(plain_cost > 8.0, "plain SCoRE {plain_cost:.2} mm");
        assert!(
            cost < 3.0,
            "weighted {cost:.2} mm, plain {plain_cost:.2} mm"
        );
        let (c_a, c_b) = (DVec3::new(0.0, 0.0, -200.0), DVec3::new(0.0, 0.0, 150.0));
        assert!(sol.c_a.distance(c_a) < 5.0, "{:?}", sol.c_a);
        assert!(sol.c_b.distance(c_b) < 5.0, "{:?}", sol.c_b);
    }

    #[test]
    fn a_pair_that_is_no_joint_stays_dear_with_the_spin_weighed_out() {
        let (pa, pb, line) = loose_pair(10.0, 25.0, 8);
        let frames: Vec<usize> = (0..pa.len()).collect();
        let target = (DVec3::ZERO, DVec3::ZERO);
        let plain = solve(&pa, &pb, &frames, 0, target);
        let (_, cost) = solve_spin_weighted(
            &pa,
            &pb,
            &frames,
            (plain.c_a, plain.c_b),
            0,
            target,
            line,
            false,
        )
        .unwrap();
        // 25 mm of uniform drift per axis is ~14 mm RMS per axis: two of three dimensions
        // keep it whatever the spin.
        assert!(cost > 15.0, "weighted {cost:.2} mm");
    }
}
