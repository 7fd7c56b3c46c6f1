//! Symmetrical centre of rotation (SCoRE, Ehrig et al. 2006).
//!
//! Unknowns: the joint centre `c_a` in a's local frame and `c_b` in b's. Every frame where
//! both poses are known gives three equations `R_a c_a + t_a = R_b c_b + t_b`, i.e.
//! `[R_a  −R_b] [c_a; c_b] = t_b − t_a`. The 6×6 normal equations are accumulated
//! (allocation-free) and solved by eigen-decomposition. Hinges leave one direction
//! (the axis, in both frames at once: SARA) and rigid pairs three directions undetermined;
//! those components are not taken from noise but chosen to put the centre nearest the
//! midpoint of the two segments' origins (see [`crate::fit`]). [`solve_weighted`] weighs
//! each frame's three equations by the precision of the two poses' disagreement at the
//! centre (`Params::weighted_centres`).

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::{DMat3, DVec3};

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
    /// The normal matrix's eigenvectors (rows, in `eigenvalues`' order) and right-hand
    /// side, divided by the frame count: [`Self::with_prior`] solves again from them.
    vectors: [[f64; 6]; 6],
    rhs: [f64; 6],
}

impl ScoreSolution {
    /// The same system solved with a prior pulling the centres toward `target` in every
    /// direction the data keep (the `drop` least-determined ones go to `target` as in
    /// [`solve`]): `prior` is added to each kept eigenvalue (per frame), so a direction
    /// the motion fixes firmly (eigenvalue ≫ `prior`) hardly moves, and one it barely
    /// fixes goes most of the way to the target. No pass over the frames.
    pub(crate) fn with_prior(&self, drop: usize, target: (DVec3, DVec3), prior: f64) -> Self {
        solve_normal(
            self.eigenvalues,
            self.vectors,
            self.rhs,
            drop,
            target,
            prior,
        )
    }
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
    solve_with(pa, pb, frames, drop, target, None, 0.0)
}

/// Where one segment's pose puts a point fixed in it, per frame, for [`solve_weighted`].
#[derive(Clone, Copy)]
pub(crate) struct PointCovariance<'a> {
    /// Covariance (mm², segment frame) in a typical frame.
    pub typical: DMat3,
    /// Per frame, the variance's ratio to the typical frame's (`poses::PoseScatter::scales`).
    pub scales: &'a [f64],
}

impl PointCovariance<'_> {
    /// The covariance at frame `f` in the global frame, the segment's rotation `rot`.
    fn at(&self, f: usize, rot: DMat3) -> DMat3 {
        rot * self.typical * rot.transpose() * self.scales.get(f).copied().unwrap_or(1.0)
    }
}

/// [`solve`] with each frame's three equations weighted by the precision of the centres'
/// disagreement there, `(R_a Σ_a R_aᵀ + R_b Σ_b R_bᵀ)⁻¹`, Σ_a and Σ_b (`covariances`)
/// where each pose puts its centre that frame; a frame where that is singular counts for
/// nothing. The eigenvalues are the weighted normal matrix's.
pub(crate) fn solve_weighted(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
    drop: usize,
    target: (DVec3, DVec3),
    covariances: (PointCovariance, PointCovariance),
    prior: f64,
) -> ScoreSolution {
    solve_with(pa, pb, frames, drop, target, Some(covariances), prior)
}

/// [`solve`], weighted as [`solve_weighted`] with `covariances`, with the prior of
/// [`ScoreSolution::with_prior`] (0: none).
fn solve_with(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
    drop: usize,
    target: (DVec3, DVec3),
    covariances: Option<(PointCovariance, PointCovariance)>,
    prior: f64,
) -> ScoreSolution {
    let n = frames.len().max(1) as f64;
    let mut normal = [[0.0f64; 6]; 6];
    let mut rhs = [0.0f64; 6];
    for &f in frames {
        let (Some(a), Some(b)) = (&pa[f], &pb[f]) else {
            continue;
        };
        let d = b.trans - a.trans;
        if let Some((sa, sb)) = covariances {
            let w = (sa.at(f, a.rot) + sb.at(f, b.rot)).inverse();
            if !w.is_finite() {
                continue;
            }
            // A = [R_a, −R_b]; AᵀWA and AᵀW d.
            let blocks = [a.rot, -b.rot];
            for (p, bp) in blocks.iter().enumerate() {
                let left = bp.transpose() * w;
                let g = left * d;
                for i in 0..3 {
                    rhs[3 * p + i] += g[i];
                }
                for (q, bq) in blocks.iter().enumerate() {
                    let m = left * *bq;
                    for i in 0..3 {
                        for j in 0..3 {
                            // Lower triangle is read.
                            if 3 * p + i >= 3 * q + j {
                                normal[3 * p + i][3 * q + j] += m.col(j)[i];
                            }
                        }
                    }
                }
            }
            continue;
        }
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
    solve_normal(values, vectors, rhs, drop, target, prior)
}

/// The centres from the normal matrix's eigen-decomposition (`values` descending, `vectors`
/// as rows) and right-hand side: the kept directions by least squares with `prior` added to
/// their eigenvalues, the `drop` least-determined (and the null ones) set to `target`.
fn solve_normal(
    values: [f64; 6],
    vectors: [[f64; 6]; 6],
    rhs: [f64; 6],
    drop: usize,
    target: (DVec3, DVec3),
    prior: f64,
) -> ScoreSolution {
    let lmax = values[0].max(f64::MIN_POSITIVE);
    let t = [
        target.0.x, target.0.y, target.0.z, target.1.x, target.1.y, target.1.z,
    ];
    let prior = if prior.is_finite() {
        prior.max(0.0)
    } else {
        0.0
    };
    let mut x = [0.0f64; 6];
    let keep = 6usize.saturating_sub(drop);
    for k in 0..6 {
        let v = &vectors[k];
        if k < keep && values[k] > 1e-12 * lmax {
            let coef = (dot6(v, &rhs) + prior * dot6(v, &t)) / (values[k] + prior);
            for i in 0..6 {
                x[i] += coef * v[i];
            }
        }
    }
    // Undetermined directions: move to the target along them (orthogonal projection onto
    // the solution set, which is x + span of those eigenvectors).
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
        vectors,
        rhs,
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

impl MarkerLine {
    /// `pose` with its segment turned by `angle` (radians) about this line first.
    pub fn spin(&self, pose: &Pose, angle: f64) -> Pose {
        let turn = glam::DMat3::from_axis_angle(self.dir, angle);
        Pose {
            rot: pose.rot * turn,
            trans: pose.trans + pose.rot * (self.origin - turn * self.origin),
        }
    }
}

/// SCoRE with one segment's spin about its marker line treated as noise of known size,
/// and the pair's RMS residual (mm) on the same footing as an ordinary pair's.
///
/// The loose segment's own poses spin about its marker line by an error of standard
/// deviation σ_φ per frame. Each frame gets the spin correction φ that minimises
/// `|d(φ)|² + (σ²/σ_φ²) φ²`, exactly on the circle the spin sweeps (d the centres'
/// disagreement; σ² its variance along the line on the uncorrected poses, which no spin
/// moves, fixed: re-estimated as the corrections shrink the residual, the prior would
/// weaken with it until a real turn about the line, a clavicle's axial rotation, cost
/// nothing); the centres are refitted on the corrected poses, alternately until the cost
/// settles. The cost is the RMS of that objective: for a true joint its mean square is
/// 3σ², like any pair's disagreement.
/// `line_a` says the loose segment is `a`; `drop` and `target` are [`solve`]'s. `None`
/// without a common frame.
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve_spin_corrected(
    pa: &[Option<Pose>],
    pb: &[Option<Pose>],
    frames: &[usize],
    start: (DVec3, DVec3),
    drop: usize,
    target: (DVec3, DVec3),
    line: MarkerLine,
    line_a: bool,
) -> Option<(ScoreSolution, f64)> {
    let (own_loose, partner) = if line_a { (pa, pb) } else { (pb, pa) };
    let mut loose: Vec<Option<Pose>> = own_loose.to_vec();
    let mut centres = start;
    let mut solution = None;
    let mut cost = f64::NAN;
    // σ², the prior's scale: set once, in the first round (see above).
    let mut sigma2 = f64::NAN;
    for _ in 0..SPIN_ROUNDS {
        let (c_loose, c_partner) = if line_a {
            centres
        } else {
            (centres.1, centres.0)
        };
        let along = line.dir.dot(c_loose - line.origin);
        let out = c_loose - line.origin - along * line.dir;
        let rho = out.length();
        // The basis (u, ê, u × ê) about the line at the centre.
        let (e, v) = if rho > 1e-9 {
            let e = out / rho;
            (e, line.dir.cross(e))
        } else {
            (DVec3::ZERO, DVec3::ZERO)
        };
        let lambda = if line.spin_sd_rad > 0.0 {
            sigma2 / (line.spin_sd_rad * line.spin_sd_rad)
        } else {
            f64::INFINITY
        };
        let (mut n, mut objective, mut along_sq) = (0.0, 0.0, 0.0);
        for &f in frames {
            let (Some(own), Some(other)) = (&own_loose[f], &partner[f]) else {
                continue;
            };
            // The partner's image of the centre in the loose segment's own frame, in that
            // basis, relative to the loose segment's own image of it at (along, ρ, 0).
            let q = own.inverse_apply(other.apply(c_partner)) - line.origin;
            let (x_u, x_e, x_v) = (line.dir.dot(q) - along, e.dot(q), v.dot(q));
            n += 1.0;
            if sigma2.is_nan() {
                // First round: σ² from the component along the line, which no spin moves.
                along_sq += x_u * x_u;
                continue;
            }
            let phi = spin_correction(rho, x_e, x_v, lambda);
            let (sin, cos) = phi.sin_cos();
            let residual = x_u * x_u + (x_e - rho * cos).powi(2) + (x_v - rho * sin).powi(2);
            objective += residual
                + if lambda.is_finite() {
                    lambda * phi * phi
                } else {
                    0.0
                };
            loose[f] = Some(line.spin(own, phi));
        }
        if n == 0.0 {
            return None;
        }
        if sigma2.is_nan() {
            sigma2 = along_sq / n;
            continue;
        }
        let previous = cost;
        cost = (objective / n).sqrt();
        let sol = if line_a {
            solve(&loose, partner, frames, drop, target)
        } else {
            solve(partner, &loose, frames, drop, target)
        };
        centres = (sol.c_a, sol.c_b);
        solution = Some(sol);
        if (previous - cost).abs() <= SPIN_SETTLED * cost {
            break;
        }
    }
    Some((solution?, cost))
}

/// Most rounds of [`solve_spin_corrected`], the first only estimating σ. Alternating
/// between corrections and centres converges slowly where the prior is weak (a spin error
/// of 26° at 100 mm swamps a residual of 9 mm): ten rounds and more.
const SPIN_ROUNDS: usize = 30;

/// [`solve_spin_corrected`] stops when a round changes the cost by at most this fraction.
const SPIN_SETTLED: f64 = 1e-3;

/// The spin φ minimising `(x_e − ρ cos φ)² + (x_v − ρ sin φ)² + λ φ²`: the point of the
/// circle of radius ρ nearest the partner's image (x_e, x_v), pulled towards φ = 0 by the
/// prior λ (Newton from φ = 0, a gradient step where the curvature is not positive).
fn spin_correction(rho: f64, x_e: f64, x_v: f64, lambda: f64) -> f64 {
    if rho <= 1e-9 || !lambda.is_finite() {
        return 0.0;
    }
    let mut phi = 0.0f64;
    for _ in 0..20 {
        let (sin, cos) = phi.sin_cos();
        let slope = rho * (x_e * sin - x_v * cos) + lambda * phi;
        let curvature = rho * (x_e * cos + x_v * sin) + lambda;
        let step = if curvature > 1e-12 {
            slope / curvature
        } else {
            slope / (rho * rho + lambda)
        };
        phi = (phi - step).clamp(-std::f64::consts::PI, std::f64::consts::PI);
        if step.abs() < 1e-10 {
            break;
        }
    }
    phi
}

#[cfg(test)]
mod tests {
    use glam::{DMat3, DQuat};

    use super::*;
    use crate::horn::tests::TestRng;

    /// A ball joint between `a` and a loose `b` whose own poses spin about b's marker line
    /// by `spin_sd_deg` of noise per frame and carry it by up to 1 mm of noise; `drift_mm`
    /// of random translation per frame between them makes the pair no joint at all.
    /// Returns both pose tracks and the line.
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
            let own = line.spin(&Pose { rot: rb, trans: tb }, rng.gauss() * line.spin_sd_rad);
            pa.push(Some(Pose { rot: ra, trans: ta }));
            pb.push(Some(Pose {
                rot: own.rot,
                trans: own.trans + rng.vec3(1.0),
            }));
        }
        (pa, pb, line)
    }

    /// A ball joint whose `b` side is posed from markers 300 mm from the centre with 3° of
    /// rotation noise per frame about their centroid, `a` exactly: `b`'s noise at the
    /// centre lies across the lever, in a direction that turns with `b`. Weighted by where
    /// each pose puts the centre (as `Params::weighted_centres` does), the frames whose
    /// noise falls along the disagreement count less, and the centre comes out closer to
    /// the truth than plain SCoRE's, which weighs every direction of every frame alike.
    #[test]
    fn weighted_centres_discount_the_noise_each_pose_puts_on_the_centre() {
        let (c_a, c_b) = (DVec3::new(0.0, 0.0, -200.0), DVec3::ZERO);
        let markers = DVec3::new(300.0, 0.0, 0.0);
        let noise = 3f64.to_radians();
        // Σ_b = noise² [d]× [d]×ᵀ + (0.1 mm)², d the centre from the markers; Σ_a tiny.
        let d = c_b - markers;
        let cross = DMat3::from_cols(
            DVec3::new(0.0, d.z, -d.y),
            DVec3::new(-d.z, 0.0, d.x),
            DVec3::new(d.y, -d.x, 0.0),
        );
        let sigma_b = cross * cross.transpose() * (noise * noise) + DMat3::IDENTITY * 0.01;
        let sigma_a = DMat3::IDENTITY * 0.01;
        let (mut plain_error, mut weighted_error) = (0.0, 0.0);
        for seed in 1..=5 {
            let mut rng = TestRng(seed);
            let (mut pa, mut pb) = (Vec::new(), Vec::new());
            for _ in 0..200 {
                let ra = DMat3::from_quat(rng.rotation());
                let ta = rng.vec3(500.0);
                let rb = ra * DMat3::from_quat(DQuat::from_scaled_axis(rng.vec3(0.8)));
                let tb = ra * c_a + ta - rb * c_b;
                // b's pose turned by the noise about its markers.
                let turn = DMat3::from_quat(DQuat::from_scaled_axis(rng.vec3(1.0) * noise));
                let own = Pose {
                    rot: rb * turn,
                    trans: tb + rb * (markers - turn * markers),
                };
                pa.push(Some(Pose { rot: ra, trans: ta }));
                pb.push(Some(own));
            }
            let frames: Vec<usize> = (0..pa.len()).collect();
            let target = (DVec3::ZERO, DVec3::ZERO);
            let plain = solve(&pa, &pb, &frames, 0, target);
            let ones = vec![1.0; frames.len()];
            let covariance = |typical| PointCovariance {
                typical,
                scales: &ones,
            };
            let weighted = solve_weighted(
                &pa,
                &pb,
                &frames,
                0,
                target,
                (covariance(sigma_a), covariance(sigma_b)),
                0.0,
            );
            plain_error += plain.c_b.distance(c_b) + plain.c_a.distance(c_a);
            weighted_error += weighted.c_b.distance(c_b) + weighted.c_a.distance(c_a);
        }
        assert!(
            weighted_error < 0.5 * plain_error,
            "weighted {weighted_error:.2} against plain {plain_error:.2} mm"
        );
    }

    /// A pair that is no joint: `b` turns about its own marker line by up to ±40° relative
    /// to a middle segment, which turns about a ball joint in `a`; b's own poses carry
    /// 10° of spin noise on top. Returns both pose tracks and b's line.
    fn spun_composite(seed: u64) -> (Vec<Option<Pose>>, Vec<Option<Pose>>, MarkerLine) {
        let mut rng = TestRng(seed);
        let c_a = DVec3::new(0.0, 0.0, -200.0);
        let line = MarkerLine {
            origin: DVec3::new(0.0, 90.0, 150.0),
            dir: DVec3::X,
            spin_sd_rad: 10f64.to_radians(),
        };
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        for f in 0..300 {
            let ra = DMat3::from_quat(rng.rotation());
            let ta = rng.vec3(500.0);
            // The middle segment: a ball joint at c_a (its origin there).
            let rm = ra * DMat3::from_quat(DQuat::from_scaled_axis(rng.vec3(0.5)));
            let tm = ra * c_a + ta - rm * c_a;
            // b: the middle segment turned about the line, smoothly over ±40°.
            let real = 40f64.to_radians() * (f as f64 * 0.05).sin();
            let b = line.spin(
                &Pose { rot: rm, trans: tm },
                real + rng.gauss() * line.spin_sd_rad,
            );
            pa.push(Some(Pose { rot: ra, trans: ta }));
            pb.push(Some(Pose {
                rot: b.rot,
                trans: b.trans + rng.vec3(1.0),
            }));
        }
        (pa, pb, line)
    }

    /// Plain SCoRE over every frame (b the loose segment) and its RMS residual, then the
    /// spin-corrected solution and cost from it.
    fn plain_and_corrected(
        pa: &[Option<Pose>],
        pb: &[Option<Pose>],
        line: MarkerLine,
    ) -> (f64, ScoreSolution, f64) {
        let frames: Vec<usize> = (0..pa.len()).collect();
        let target = (DVec3::ZERO, DVec3::ZERO);
        let plain = solve(pa, pb, &frames, 0, target);
        let sq: f64 = frames
            .iter()
            .map(|&f| {
                let (x, y) = (pa[f].unwrap(), pb[f].unwrap());
                (x.apply(plain.c_a) - y.apply(plain.c_b)).length_squared()
            })
            .sum();
        let plain_cost = (sq / frames.len() as f64).sqrt();
        let start = (plain.c_a, plain.c_b);
        let (sol, cost) =
            solve_spin_corrected(pa, pb, &frames, start, 0, target, line, false).unwrap();
        (plain_cost, sol, cost)
    }

    /// An exact joint whose relative rotation is mostly about one axis (±0.8 rad about z,
    /// ±0.02 rad about x and y): the motion barely fixes the centre along z. A prior added
    /// to the normal matrix's eigenvalues leaves the well-fixed directions at the truth and
    /// moves the centre along the weak one toward the target; at 0 it is plain SCoRE.
    #[test]
    fn the_centre_prior_holds_only_the_direction_the_motion_barely_fixes() {
        let mut rng = TestRng(11);
        let (c_a, c_b) = (DVec3::new(10.0, 20.0, 0.0), DVec3::new(-30.0, 5.0, 0.0));
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        for _ in 0..200 {
            let ra = DMat3::from_quat(rng.rotation());
            let ta = rng.vec3(500.0);
            let small = rng.vec3(0.02);
            let turn = DQuat::from_scaled_axis(DVec3::new(small.x, small.y, rng.gauss() * 0.8));
            let rb = ra * DMat3::from_quat(turn);
            let tb = ra * c_a + ta - rb * c_b;
            pa.push(Some(Pose { rot: ra, trans: ta }));
            pb.push(Some(Pose { rot: rb, trans: tb }));
        }
        let frames: Vec<usize> = (0..pa.len()).collect();
        // The target 100 mm off the truth along z in both frames, 50 mm across it.
        let shift = DVec3::new(50.0, 0.0, 100.0);
        let target = (c_a + shift, c_b + shift);
        let plain = solve(&pa, &pb, &frames, 0, target);
        let none = plain.with_prior(0, target, 0.0);
        assert_eq!((plain.c_a, plain.c_b), (none.c_a, none.c_b));
        assert!(plain.c_a.distance(c_a) < 1e-6, "{}", plain.c_a);
        let held = plain.with_prior(0, target, 1e-3);
        let moved = held.c_a - c_a;
        // Along z most of the way to the target; across it, hardly at all.
        assert!(moved.z > 50.0 && moved.z < 100.0, "{moved}");
        assert!(moved.x.abs() < 2.0 && moved.y.abs() < 2.0, "{moved}");
    }

    #[test]
    fn spin_noise_about_the_marker_line_is_corrected_out_of_a_joints_cost() {
        let (pa, pb, line) = loose_pair(20.0, 0.0, 7);
        let (plain_cost, sol, cost) = plain_and_corrected(&pa, &pb, line);
        // 90 mm lever × 20° of spin: ~30 mm along one direction, ~1 mm of noise elsewhere.
        assert!(plain_cost > 15.0, "plain SCoRE {plain_cost:.2} mm");
        // The prior's scale comes from the plain fit's residual along the line, which the
        // noisy spin's pull on the centres inflates: the correction is cautious (7.7 mm
        // of 26 here, against the 1 mm noise's ideal).
        assert!(
            cost < 0.4 * plain_cost,
            "corrected {cost:.2} mm, plain {plain_cost:.2} mm"
        );
        let (c_a, c_b) = (DVec3::new(0.0, 0.0, -200.0), DVec3::new(0.0, 0.0, 150.0));
        assert!(sol.c_a.distance(c_a) < 3.0, "{:?}", sol.c_a);
        // In b the spin leaves the centre's turn about the line to the weak prior: its
        // coordinate along the line and its distance from it are what the data fix.
        let about = |c: DVec3| {
            let d = c - line.origin;
            (d.dot(line.dir), d.reject_from(line.dir).length())
        };
        let ((along, rho), (true_along, true_rho)) = (about(sol.c_b), about(c_b));
        assert!((along - true_along).abs() < 3.0, "{:?}", sol.c_b);
        assert!((rho - true_rho).abs() < 3.0, "{:?}", sol.c_b);
    }

    #[test]
    fn real_turns_about_the_marker_line_are_not_taken_for_spin_noise() {
        let (pa, pb, line) = spun_composite(9);
        let (plain_cost, _, cost) = plain_and_corrected(&pa, &pb, line);
        // Freed, the spin would absorb the ±40° and leave the ball joint at c_a: ~1 mm.
        assert!(
            cost > 10.0,
            "corrected {cost:.2} mm, plain {plain_cost:.2} mm"
        );
    }

    #[test]
    fn a_pair_that_is_no_joint_stays_dear_with_the_spin_corrected() {
        let (pa, pb, line) = loose_pair(20.0, 25.0, 8);
        let (plain_cost, _, cost) = plain_and_corrected(&pa, &pb, line);
        // 25 mm of uniform drift per axis is ~14 mm RMS per axis: two of three dimensions
        // keep it whatever the spin.
        assert!(
            cost > 15.0,
            "corrected {cost:.2} mm, plain {plain_cost:.2} mm"
        );
    }
}
