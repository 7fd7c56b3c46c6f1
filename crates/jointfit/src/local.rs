//! Local fitting (Kalra, Boulic, Thalmann et al., "local fitting tool"; see
//! `papers/local-fitting-marker-positioning.md`, Sect. 3.3).
//!
//! For a pair (a, b), every marker of b is seen in a's local frame (and every marker of a
//! in b's frame). Its trajectory there lies on a sphere about the joint (Eq. 3:
//! `d = |p − c| − r`); the sphere is fitted by Levenberg–Marquardt, started from the
//! closed-form algebraic fit, each sample weighted by the inverse density of the
//! trajectory's samples (voxel grid of `local_voxels` divisions per axis over its bounding
//! box: weight = 1 / samples in the sample's voxel), so poses the subject dwells in do
//! not dominate. A trajectory whose smallest principal extent is below `local_planar_ratio`
//! of the middle one is a circle (hinge): it is projected onto its best plane and fitted
//! there (centre in the plane, on the axis).
//!
//! The joint is the mean of the per-marker centres weighted by `attachment / radius`
//! (Eq. 4–6). Attachment weight (the paper's "normalised rigidity of the marker's
//! attachment to its segment", default 1 there): ours is `1 / (1 + ρ / 1 mm)` with ρ the
//! RMS distance of the marker from its reference position in its own segment's pose, so
//! sliding skin markers count less. Centres found in b's frame are carried into a's by
//! least squares through the poses. Cost: mean over markers of the radial RMS (mm).

// Index loops read like the matrix formulas they implement.
#![allow(clippy::needless_range_loop)]

use glam::DVec3;
use mocap_io::Trajectories;

use crate::fit::SegmentView;
use crate::poses::Pose;
use crate::small::sym_eigen;

/// Fewest samples of a marker in the other segment's frame for a sphere fit.
const MIN_SAMPLES: usize = 10;

/// Sphere (or circle) fitted to one marker's trajectory in a segment's local frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MarkerSphere {
    /// Centre in the observing segment's local frame (mm).
    pub centre: DVec3,
    /// Radius (mm).
    pub radius: f64,
    /// Unweighted RMS of `|p − c| − r` over the samples (mm).
    pub rms: f64,
    /// Whether the trajectory was planar (circle fit).
    pub planar: bool,
}

/// How the pair's markers were fitted, for the evidence string.
pub(crate) struct LocalFit {
    /// Joint centre in a's local frame (mm), before any placement along a hinge axis.
    pub centre_in_a: DVec3,
    /// Mean radial RMS over the fitted markers (mm); +∞ when none could be fitted.
    pub cost: f64,
    /// Summary.
    pub note: String,
}

/// Settings of the local fit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LocalSettings {
    /// Voxel divisions per axis for the density weights.
    pub voxels: usize,
    /// Planar when the smallest RMS principal extent is below this fraction of the middle one.
    pub planar_ratio: f64,
}

/// Fits every marker of each segment in the other's frame and combines the centres into
/// a's frame. `co`: frames where both poses exist (non-empty). `fallback`: a-local point
/// used when no marker can be fitted.
pub(crate) fn fit_local(
    traj: &Trajectories,
    sa: &SegmentView<'_>,
    sb: &SegmentView<'_>,
    co: &[usize],
    settings: LocalSettings,
    fallback: DVec3,
) -> LocalFit {
    let mut points = Vec::new();
    let mut weights = Vec::new();
    let (mut sum_c, mut sum_w, mut sum_rms, mut fitted, mut planar) =
        (DVec3::ZERO, 0.0, 0.0, 0usize, 0usize);
    // (observer, observed, observer is a)
    for (observer, observed, in_a) in [(sa, sb, true), (sb, sa, false)] {
        for (k, &m) in observed.markers.iter().enumerate() {
            points.clear();
            for (f, pose) in observer.track.iter().enumerate() {
                if let (Some(pose), Some(p)) = (pose, traj.get(f, m)) {
                    points.push(pose.inverse_apply(DVec3::from_array(p)));
                }
            }
            if points.len() < MIN_SAMPLES {
                continue;
            }
            density_weights(&points, settings.voxels, &mut weights);
            let Some(fit) = fit_marker(&points, &weights, settings.planar_ratio) else {
                continue;
            };
            if !(fit.radius > 0.0 && fit.centre.is_finite()) {
                continue;
            }
            let attach = 1.0 / (1.0 + rigidity_rms(traj, observed, k, m));
            let w = attach / fit.radius;
            let centre = if in_a {
                fit.centre
            } else {
                b_to_a(sa.track, sb.track, co, fit.centre)
            };
            sum_c += w * centre;
            sum_w += w;
            sum_rms += fit.rms;
            fitted += 1;
            planar += usize::from(fit.planar);
        }
    }
    if fitted == 0 || sum_w <= 0.0 {
        return LocalFit {
            centre_in_a: fallback,
            cost: f64::INFINITY,
            note: "local: no marker trajectory could be fitted".to_string(),
        };
    }
    LocalFit {
        centre_in_a: sum_c / sum_w,
        cost: sum_rms / fitted as f64,
        note: format!(
            "local: {fitted} marker trajectories fitted ({planar} planar → circle), \
             mean radial RMS {:.2} mm",
            sum_rms / fitted as f64
        ),
    }
}

/// RMS distance (mm) of marker `m` (index `k` in its segment) from its posed reference
/// position; 0 when it cannot be measured (so the marker keeps full weight).
fn rigidity_rms(traj: &Trajectories, seg: &SegmentView<'_>, k: usize, m: usize) -> f64 {
    let Some(reference) = seg.poses.reference.get(k).map(|r| DVec3::from_array(*r)) else {
        return 0.0;
    };
    if !reference.is_finite() {
        return 0.0;
    }
    let (mut sq, mut n) = (0.0, 0usize);
    for (f, pose) in seg.track.iter().enumerate() {
        if let (Some(pose), Some(p)) = (pose, traj.get(f, m)) {
            sq += (pose.apply(reference) - DVec3::from_array(p)).length_squared();
            n += 1;
        }
    }
    if n == 0 { 0.0 } else { (sq / n as f64).sqrt() }
}

/// The a-local point that b-local `c` is on average (least squares over `co`).
fn b_to_a(pa: &[Option<Pose>], pb: &[Option<Pose>], co: &[usize], c: DVec3) -> DVec3 {
    let (mut sum, mut n) = (DVec3::ZERO, 0.0);
    for &f in co {
        if let (Some(x), Some(y)) = (&pa[f], &pb[f]) {
            sum += x.inverse_apply(y.apply(c));
            n += 1.0;
        }
    }
    sum / n
}

/// Inverse sample density: `weights[i]` = 1 / (samples in sample i's voxel), the voxel
/// grid having `divisions` cells per axis over the samples' bounding box.
pub(crate) fn density_weights(points: &[DVec3], divisions: usize, weights: &mut Vec<f64>) {
    let divisions = divisions.max(1);
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let extent = hi - lo;
    let cell = |p: DVec3| -> usize {
        let mut index = 0;
        for axis in 0..3 {
            let i = if extent[axis] > 0.0 {
                let t = (p[axis] - lo[axis]) / extent[axis] * divisions as f64;
                (t as usize).min(divisions - 1)
            } else {
                0
            };
            index = index * divisions + i;
        }
        index
    };
    let mut counts = vec![0u32; divisions * divisions * divisions];
    for p in points {
        if let Some(c) = counts.get_mut(cell(*p)) {
            *c += 1;
        }
    }
    weights.clear();
    weights.extend(
        points
            .iter()
            .map(|p| 1.0 / f64::from(counts.get(cell(*p)).copied().unwrap_or(1).max(1))),
    );
}

/// Sphere (or, for a planar trajectory, circle) through weighted samples.
pub(crate) fn fit_marker(
    points: &[DVec3],
    weights: &[f64],
    planar_ratio: f64,
) -> Option<MarkerSphere> {
    let total: f64 = weights.iter().sum();
    if points.len() < 4 || total <= 0.0 {
        return None;
    }
    let mean = points
        .iter()
        .zip(weights)
        .map(|(p, w)| *p * *w)
        .sum::<DVec3>()
        / total;
    let mut cov = [[0.0f64; 3]; 3];
    for (p, w) in points.iter().zip(weights) {
        let d = (*p - mean).to_array();
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += w * d[i] * d[j];
            }
        }
    }
    let (values, vectors) = sym_eigen(cov);
    let planar = values[2].max(0.0).sqrt() < planar_ratio * values[1].max(0.0).sqrt();
    let normal = DVec3::from_array(vectors[2]);
    // Centred (and, if planar, flattened) samples: the centre then comes out relative to
    // the mean, in the plane when planar (its normal component has zero gradient).
    let local = |p: DVec3| {
        let d = p - mean;
        if planar {
            d - normal * d.dot(normal)
        } else {
            d
        }
    };
    let start = algebraic_sphere(points.iter().map(|p| local(*p)), weights)?;
    let (centre, radius) = levenberg_marquardt(points, weights, &local, start);
    let mut sq = 0.0;
    for p in points {
        let r = (local(*p) - centre).length() - radius;
        sq += r * r;
    }
    Some(MarkerSphere {
        centre: centre + mean,
        radius,
        rms: (sq / points.len() as f64).sqrt(),
        planar,
    })
}

/// Closed-form sphere: `|p|² = 2 c·p + k` with `k = r² − |c|²`, weighted linear least
/// squares in (c, k), pseudo-inverse so a flat sample set leaves the normal component 0.
fn algebraic_sphere(points: impl Iterator<Item = DVec3>, weights: &[f64]) -> Option<(DVec3, f64)> {
    let mut normal = [[0.0f64; 4]; 4];
    let mut rhs = [0.0f64; 4];
    for (p, w) in points.zip(weights) {
        let row = [2.0 * p.x, 2.0 * p.y, 2.0 * p.z, 1.0];
        let y = p.length_squared();
        for i in 0..4 {
            for j in 0..4 {
                normal[i][j] += w * row[i] * row[j];
            }
            rhs[i] += w * row[i] * y;
        }
    }
    let x = pseudo_solve(normal, rhs);
    let c = DVec3::new(x[0], x[1], x[2]);
    let r2 = x[3] + c.length_squared();
    (r2 > 0.0 && c.is_finite()).then(|| (c, r2.sqrt()))
}

/// Solves a symmetric 4×4 system, ignoring directions with eigenvalue below 1e-12 of the largest.
fn pseudo_solve(m: [[f64; 4]; 4], rhs: [f64; 4]) -> [f64; 4] {
    let (values, vectors) = sym_eigen(m);
    let lmax = values[0].max(f64::MIN_POSITIVE);
    let mut x = [0.0f64; 4];
    for k in 0..4 {
        if values[k] > 1e-12 * lmax {
            let v = &vectors[k];
            let coef = (0..4).map(|i| v[i] * rhs[i]).sum::<f64>() / values[k];
            for i in 0..4 {
                x[i] += coef * v[i];
            }
        }
    }
    x
}

/// Weighted cost Σ w (|map(p) − c| − r)².
fn sphere_cost(
    points: &[DVec3],
    weights: &[f64],
    map: &impl Fn(DVec3) -> DVec3,
    c: DVec3,
    r: f64,
) -> f64 {
    points
        .iter()
        .zip(weights)
        .map(|(p, w)| {
            let d = (map(*p) - c).length() - r;
            w * d * d
        })
        .sum()
}

/// Levenberg–Marquardt on (centre, radius), analytic Jacobian `[−u, −1]` with
/// `u = (p − c)/|p − c|`; no allocation per iteration (4×4 normal equations).
fn levenberg_marquardt(
    points: &[DVec3],
    weights: &[f64],
    map: &impl Fn(DVec3) -> DVec3,
    start: (DVec3, f64),
) -> (DVec3, f64) {
    let (mut c, mut r) = start;
    let mut cost = sphere_cost(points, weights, map, c, r);
    let mut lambda = 1e-3;
    for _ in 0..100 {
        let mut jtj = [[0.0f64; 4]; 4];
        let mut jtr = [0.0f64; 4];
        for (p, w) in points.iter().zip(weights) {
            let v = map(*p) - c;
            let d = v.length();
            if d <= 0.0 {
                continue;
            }
            let u = v / d;
            let row = [-u.x, -u.y, -u.z, -1.0];
            let res = d - r;
            for i in 0..4 {
                for j in 0..4 {
                    jtj[i][j] += w * row[i] * row[j];
                }
                jtr[i] += w * row[i] * res;
            }
        }
        let mut improved = false;
        while lambda < 1e12 {
            let mut damped = jtj;
            for i in 0..4 {
                damped[i][i] += lambda * jtj[i][i];
            }
            let step = pseudo_solve(damped, jtr.map(|x| -x));
            let (nc, nr) = (c + DVec3::new(step[0], step[1], step[2]), r + step[3]);
            let new_cost = sphere_cost(points, weights, map, nc, nr);
            if new_cost.is_finite() && new_cost < cost {
                let converged = cost - new_cost <= 1e-12 * cost
                    || step.iter().map(|s| s * s).sum::<f64>() < 1e-18;
                (c, r, cost) = (nc, nr, new_cost);
                lambda = (lambda * 0.1).max(1e-12);
                improved = !converged;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (c, r.abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::horn::tests::TestRng;

    fn on_sphere(
        rng: &mut TestRng,
        centre: DVec3,
        radius: f64,
        n: usize,
        noise: f64,
    ) -> Vec<DVec3> {
        (0..n)
            .map(|_| {
                let d = rng.vec3(1.0).try_normalize().unwrap_or(DVec3::X);
                centre + d * radius + rng.vec3(noise)
            })
            .collect()
    }

    #[test]
    fn sphere_on_a_cap_with_noise() {
        let mut rng = TestRng(31);
        let centre = DVec3::new(10.0, -40.0, 300.0);
        // A 60° cap: directions near +z only.
        let pts: Vec<DVec3> = (0..400)
            .map(|_| {
                let d = (rng.vec3(0.5) + DVec3::Z).normalize();
                centre + d * 250.0 + rng.vec3(0.5)
            })
            .collect();
        let mut w = Vec::new();
        density_weights(&pts, 8, &mut w);
        let fit = fit_marker(&pts, &w, 0.1).unwrap();
        assert!(!fit.planar);
        assert!((fit.centre - centre).length() < 3.0, "{}", fit.centre);
        assert!((fit.radius - 250.0).abs() < 3.0, "{}", fit.radius);
        let exact = on_sphere(&mut rng, centre, 120.0, 100, 0.0);
        density_weights(&exact, 8, &mut w);
        let fit = fit_marker(&exact, &w, 0.1).unwrap();
        assert!((fit.centre - centre).length() < 1e-6 && fit.rms < 1e-6);
    }

    #[test]
    fn circle_gives_centre_in_its_plane() {
        let centre = DVec3::new(5.0, 7.0, -9.0);
        let (u, v) = (DVec3::new(1.0, 1.0, 0.0).normalize(), DVec3::Z);
        let pts: Vec<DVec3> = (0..90)
            .map(|i| {
                let t = (i as f64 * 1.5).to_radians();
                centre + 200.0 * (u * t.cos() + v * t.sin())
            })
            .collect();
        let mut w = Vec::new();
        density_weights(&pts, 8, &mut w);
        let fit = fit_marker(&pts, &w, 0.1).unwrap();
        assert!(fit.planar);
        assert!((fit.centre - centre).length() < 1e-6, "{}", fit.centre);
        assert!((fit.radius - 200.0).abs() < 1e-6);
    }

    #[test]
    fn dwelling_pose_does_not_dominate() {
        let mut rng = TestRng(32);
        let centre = DVec3::new(-20.0, 15.0, 80.0);
        // 150 samples over a 45° cap, then 3000 samples dwelling in one pose where soft
        // tissue holds the marker 3 mm off the sphere; 1 mm noise.
        let mut pts: Vec<DVec3> = (0..150)
            .map(|_| {
                let d = (rng.vec3(0.4) + DVec3::Z).normalize();
                centre + d * 250.0 + rng.vec3(1.0)
            })
            .collect();
        let dwell = centre + DVec3::new(0.3, 0.1, 1.0).normalize() * 253.0;
        pts.extend((0..3000).map(|_| dwell + rng.vec3(1.0)));
        let mut w = Vec::new();
        density_weights(&pts, 8, &mut w);
        let weighted = fit_marker(&pts, &w, 0.1).unwrap();
        let uniform = fit_marker(&pts, &vec![1.0; pts.len()], 0.1).unwrap();
        let (ew, eu) = (
            (weighted.centre - centre).length(),
            (uniform.centre - centre).length(),
        );
        // Measured: weighted 0.52 mm, uniform 8.9 mm.
        assert!(ew < 3.0, "weighted centre off by {ew} mm");
        assert!(ew < eu, "weighting did not help: {ew} vs {eu} mm");
    }

    #[test]
    fn density_weights_count_voxel_mates() {
        let mut pts = vec![DVec3::ZERO; 5];
        pts.push(DVec3::splat(10.0));
        let mut w = Vec::new();
        density_weights(&pts, 5, &mut w);
        assert_eq!(w, vec![0.2, 0.2, 0.2, 0.2, 0.2, 1.0]);
    }
}
