//! A marker on a segment of its own swings about the joint it hangs from: in the frame of
//! the neighbour on the other side, its distance to the joint centre is constant, so its
//! trajectory lies on a sphere (about a hinge, on a circle). That distance's spread is what
//! ρ is for a pair of markers, with the joint centre as the partner (see
//! `singleton_swing_factor`).

use mocap_io::Trajectories;

use crate::eigen::symmetric_eigen;
use crate::reassign::{Pose, locals_in, stride_of};

/// A marker hangs from a body only if it moves in the body's frame by at least this many
/// rigidity tolerances: less, and it is as good as rigid with the body.
const MIN_SPREAD_TOLERANCES: f64 = 2.0;

/// ... and its sphere's radius is at most this many times its spread: the arc turns
/// through ≳ 25° (spread ≈ radius × angle / √12), so its curvature is seen, not fitted to
/// a flat patch of a trajectory that has none.
const MAX_RADIUS_SPREADS: f64 = 8.0;

/// How a marker's trajectory in a body's frame fits a sphere (or a circle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Swing {
    /// RMS of the distance to the sphere's centre about its radius, mm: the spread of that
    /// distance, as ρ is of a pair's.
    pub residual_mm: f64,
    /// RMS distance of the trajectory from its mean, mm: how far the marker moves.
    pub spread_mm: f64,
    /// The sphere's radius, mm: the marker's distance to the centre it swings about.
    pub radius_mm: f64,
    /// The sphere's centre in the body's frame, mm.
    pub centre: [f64; 3],
}

impl Swing {
    /// Whether this swing shows a marker hanging from the body by a joint: its distance to
    /// the centre spreads by at most `bound_mm` (as ρ must, for a pair), while it moves by
    /// several tolerances (`tolerance_mm`) along an arc that visibly turns.
    pub(crate) fn hangs(&self, bound_mm: f64, tolerance_mm: f64) -> bool {
        self.residual_mm <= bound_mm
            && self.spread_mm >= MIN_SPREAD_TOLERANCES * tolerance_mm
            && self.radius_mm <= MAX_RADIUS_SPREADS * self.spread_mm
    }
}

/// The spheres and circles marker `m` fits in the frames of the posed bodies (`poses`, per
/// strided frame as [`crate::reassign::group_poses`] gives them): a ball joint's swing
/// covers a patch of a sphere, a hinge's a circle.
pub(crate) fn swings(
    traj: &Trajectories,
    poses: &[Option<Vec<Option<Pose>>>],
    m: usize,
) -> Vec<Swing> {
    let stride = stride_of(traj);
    poses
        .iter()
        .flatten()
        .flat_map(|p| {
            let local = locals_in(traj, p, m, stride);
            [sphere_fit(&local), circle_fit(&local)]
        })
        .flatten()
        .collect()
}

/// The least-squares sphere through `points` (algebraic fit: |x − c|² = r² is linear in c
/// and r² − |c|², Kasa 1976), with the spread of the distances to its centre; `None`
/// with fewer than 4 points or when they do not fix a sphere (all on one line or plane
/// patch too flat to curve).
pub(crate) fn sphere_fit(points: &[[f64; 3]]) -> Option<Swing> {
    if points.len() < 4 {
        return None;
    }
    let (mean, spread) = mean_and_spread(points);
    // Centred, so the normal equations are conditioned by the spread, not the position.
    let mut a = [[0.0; 4]; 4];
    let mut b = [0.0; 4];
    for p in points {
        let y = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
        let y2 = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
        let row = [2.0 * y[0], 2.0 * y[1], 2.0 * y[2], 1.0];
        for r in 0..4 {
            b[r] += row[r] * y2;
            for c in 0..4 {
                a[r][c] += row[r] * row[c];
            }
        }
    }
    let x = solve(a, b)?;
    let centre = [x[0] + mean[0], x[1] + mean[1], x[2] + mean[2]];
    let r2 = x[3] + x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
    swing_about(points, centre, r2, spread)
}

/// The least-squares circle through `points` in their best-fitting plane (algebraic fit in
/// the plane of the two largest principal directions): a marker turning about a hinge
/// draws a circle, which fixes no sphere (every centre on the axis fits). The residual is
/// still the spread of the 3-D distance to the centre. `None` with fewer than 3 points or
/// when they do not fix a circle.
pub(crate) fn circle_fit(points: &[[f64; 3]]) -> Option<Swing> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mean, spread) = mean_and_spread(points);
    let mut cov = [0.0; 9];
    for p in points {
        let y = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
        for r in 0..3 {
            for c in 0..3 {
                cov[r * 3 + c] += y[r] * y[c] / n;
            }
        }
    }
    let spectrum = symmetric_eigen(&cov, 3).ok()?;
    let axis = |k: usize| [0, 1, 2].map(|r| spectrum.vectors[r * 3 + k]);
    let (e1, e2) = (axis(0), axis(1));
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut a = [[0.0; 3]; 3];
    let mut b = [0.0; 3];
    for p in points {
        let y = [p[0] - mean[0], p[1] - mean[1], p[2] - mean[2]];
        let (u, v) = (dot(y, e1), dot(y, e2));
        let row = [2.0 * u, 2.0 * v, 1.0];
        for r in 0..3 {
            b[r] += row[r] * (u * u + v * v);
            for c in 0..3 {
                a[r][c] += row[r] * row[c];
            }
        }
    }
    let x = solve(a, b)?;
    let centre = [0, 1, 2].map(|i| mean[i] + x[0] * e1[i] + x[1] * e2[i]);
    swing_about(points, centre, x[2] + x[0] * x[0] + x[1] * x[1], spread)
}

/// The mean of `points` (non-empty) and their RMS distance from it (mm).
fn mean_and_spread(points: &[[f64; 3]]) -> ([f64; 3], f64) {
    let n = points.len() as f64;
    let mut mean = [0.0; 3];
    for p in points {
        (0..3).for_each(|i| mean[i] += p[i] / n);
    }
    let spread2: f64 = points
        .iter()
        .map(|p| (0..3).map(|i| (p[i] - mean[i]).powi(2)).sum::<f64>() / n)
        .sum();
    (mean, spread2.sqrt())
}

/// The swing of `points` about `centre` at the fitted squared radius `r2`: the RMS of
/// their distances to the centre about the radius.
fn swing_about(points: &[[f64; 3]], centre: [f64; 3], r2: f64, spread_mm: f64) -> Option<Swing> {
    if !(r2.is_finite() && r2 > 0.0) {
        return None;
    }
    let radius = r2.sqrt();
    let n = points.len() as f64;
    let residual2: f64 = points
        .iter()
        .map(|p| {
            let d = ((p[0] - centre[0]).powi(2)
                + (p[1] - centre[1]).powi(2)
                + (p[2] - centre[2]).powi(2))
            .sqrt();
            (d - radius).powi(2) / n
        })
        .sum();
    Some(Swing {
        residual_mm: residual2.sqrt(),
        spread_mm,
        radius_mm: radius,
        centre,
    })
}

/// Solves the `N × N` system `a x = b` by Gaussian elimination with partial pivoting;
/// `None` when a pivot is negligible against the matrix's scale (the points fix no fit).
pub(crate) fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    let scale = a
        .iter()
        .flat_map(|r| r.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    for k in 0..N {
        let p = (k..N).max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))?;
        if a[p][k].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(k, p);
        b.swap(k, p);
        let (pivot_row, pivot_b) = (a[k], b[k]);
        for (row, bi) in a.iter_mut().zip(b.iter_mut()).skip(k + 1) {
            let f = row[k] / pivot_row[k];
            for (x, p) in row.iter_mut().zip(pivot_row).skip(k) {
                *x -= f * p;
            }
            *bi -= f * pivot_b;
        }
    }
    let mut x = [0.0; N];
    for k in (0..N).rev() {
        let s: f64 = (k + 1..N).map(|j| a[k][j] * x[j]).sum();
        x[k] = (b[k] - s) / a[k][k];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::{circle_fit, sphere_fit};

    /// Points on a 30° × 40° patch of a sphere of radius 120 mm about (10, −20, 5): the fit
    /// gives that centre and radius back, with no residual.
    #[test]
    fn a_patch_of_a_sphere_gives_its_centre_and_radius() {
        let centre = [10.0, -20.0, 5.0];
        let mut points = Vec::new();
        for i in 0..12 {
            for j in 0..12 {
                let (lat, lon) = ((i as f64 * 2.5).to_radians(), (j as f64 * 3.3).to_radians());
                points.push([
                    centre[0] + 120.0 * lat.cos() * lon.cos(),
                    centre[1] + 120.0 * lat.cos() * lon.sin(),
                    centre[2] + 120.0 * lat.sin(),
                ]);
            }
        }
        let s = sphere_fit(&points).unwrap();
        assert!((s.radius_mm - 120.0).abs() < 1e-6, "{s:?}");
        assert!(s.residual_mm < 1e-6, "{s:?}");
        for (found, truth) in s.centre.iter().zip(centre) {
            assert!((found - truth).abs() < 1e-6, "{s:?}");
        }
    }

    /// A 50° arc of a circle of radius 90 mm, tilted out of every coordinate plane: no
    /// sphere, but the circle fit gives its centre and radius back.
    #[test]
    fn an_arc_of_a_circle_gives_its_centre_and_radius() {
        let centre = [30.0, 40.0, -10.0];
        let (e1, e2) = ([0.6, 0.8, 0.0], [0.0, 0.0, 1.0]);
        let points: Vec<[f64; 3]> = (0..40)
            .map(|i| {
                let a = (i as f64 * 1.25).to_radians();
                [0, 1, 2].map(|k| centre[k] + 90.0 * (a.cos() * e1[k] + a.sin() * e2[k]))
            })
            .collect();
        let c = circle_fit(&points).unwrap();
        assert!(
            (c.radius_mm - 90.0).abs() < 1e-6 && c.residual_mm < 1e-6,
            "{c:?}"
        );
        for (found, truth) in c.centre.iter().zip(centre) {
            assert!((found - truth).abs() < 1e-6, "{c:?}");
        }
    }

    /// A straight run fixes no sphere worth the name: either none, or one whose radius
    /// dwarfs the run.
    #[test]
    fn a_straight_run_is_no_swing() {
        let points: Vec<[f64; 3]> = (0..50).map(|i| [i as f64, 2.0 * i as f64, 0.5]).collect();
        if let Some(s) = sphere_fit(&points) {
            assert!(s.radius_mm > 100.0 * s.spread_mm, "{s:?}");
        }
    }
}
