//! Per-frame rigid poses of every segment against a reference shape.
//!
//! Reference shape: the marker positions in the first frame where most of the segment's
//! markers are visible (of those, the one whose markers are seen longest: a marker in
//! pieces never seen together), then replaced by the mean shape in the local frame
//! (every frame aligned to that first reference by Horn's method, each marker averaged
//! over the frames where it is visible), so markers hidden in the reference frame still
//! get a reference position and one frame's noise does not define the body. Local frame:
//! origin at the reference centroid, axes = global axes at the reference frame.

use glam::{DMat3, DQuat, DVec3};
use mocap_io::Trajectories;
use rayon::prelude::*;

use crate::horn::{RigidFit, absolute_orientation};
use crate::pairfits::SegmentPoses;
use crate::score::MarkerLine;
use crate::small::sym_eigen;

/// A segment's pose at one frame as the pair fits use it: local → global.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pose {
    /// Rotation matrix, local → global.
    pub rot: DMat3,
    /// Translation (mm), global.
    pub trans: DVec3,
}

impl Pose {
    /// Global position of a local point.
    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.rot * p + self.trans
    }
    /// Local position of a global point.
    #[inline]
    pub fn inverse_apply(&self, p: DVec3) -> DVec3 {
        self.rot.transpose() * (p - self.trans)
    }
}

/// What a per-frame rigid fit needs and refuses (from [`crate::Params`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FitRules {
    /// Least spread of the points across their second principal direction, mm.
    pub min_spread_mm: f64,
    /// Outlier bound as a multiple of the median per-frame fit RMS; 0 = no rejection.
    pub outlier_factor: f64,
    /// Least outlier bound, mm.
    pub outlier_floor_mm: f64,
    /// Largest spin uncertainty a pose may have (degrees), the spin's standard error
    /// predicted from the segment's own fit scatter, where the visible points' lever is
    /// under half the whole set's; 0 = no limit.
    pub max_spin_deg: f64,
}

impl FitRules {
    /// The rules `params` set.
    pub fn of(params: &crate::Params) -> Self {
        Self {
            min_spread_mm: params.min_spread_mm,
            outlier_factor: params.pose_outlier_factor,
            outlier_floor_mm: params.pose_outlier_floor_mm,
            max_spin_deg: params.max_spin_deg,
        }
    }
}

/// How well spread the points of one frame's fit must be.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Spread {
    /// Least RMS extent across the points' second principal direction, mm.
    pub min_spread_mm: f64,
    /// Least √λ_min of the points' inertia tensor (mm): the lever that turns their scatter
    /// into rotation uncertainty (σ / lever radians); 0 = no limit.
    pub min_lever_mm: f64,
}

impl Spread {
    /// Only the fixed `min_spread_mm`.
    pub fn fixed(min_spread_mm: f64) -> Self {
        Self {
            min_spread_mm,
            min_lever_mm: 0.0,
        }
    }
}

/// Poses of every segment, in parallel over segments (each segment is computed serially,
/// so results do not depend on the thread count).
pub(crate) fn all_segment_poses(
    traj: &Trajectories,
    segments: &[Vec<usize>],
    rules: FitRules,
) -> Vec<SegmentPoses> {
    segments
        .par_iter()
        .enumerate()
        .map(|(id, markers)| segment_poses(traj, id, markers, rules))
        .collect()
}

/// Poses of one segment (`markers` are indices into the capture, already range-checked).
pub(crate) fn segment_poses(
    traj: &Trajectories,
    id: usize,
    markers: &[usize],
    rules: FitRules,
) -> SegmentPoses {
    let shape = fit_shape(
        traj.frames(),
        markers.len(),
        markers.len(),
        |f, k| traj.get(f, markers[k]).map(DVec3::from_array),
        rules,
    );
    shape.into_poses(id, markers.len())
}

/// A reference shape and the rigid fit of every frame against it.
pub(crate) struct Shape {
    /// Reference positions in the local frame (mm); NaN for a point never seen.
    pub reference: Vec<DVec3>,
    /// Fit per frame; `None` where fewer than 3 points are visible or they are collinear.
    pub fits: Vec<Option<RigidFit>>,
}

impl Shape {
    /// Stored poses of segment `id`, whose markers are the first `markers` points.
    pub fn into_poses(self, id: usize, markers: usize) -> SegmentPoses {
        let nan3 = [f64::NAN; 3];
        SegmentPoses {
            segment: id,
            reference: self.reference[..markers]
                .iter()
                .map(|r| if r.is_finite() { r.to_array() } else { nan3 })
                .collect(),
            rotations: self
                .fits
                .iter()
                .map(|f| f.map_or([f64::NAN; 4], |f| f.rotation.to_array()))
                .collect(),
            translations: self
                .fits
                .iter()
                .map(|f| f.map_or(nan3, |f| f.translation.to_array()))
                .collect(),
            rms_mm: self
                .fits
                .iter()
                .map(|f| f.map_or(f64::NAN, |f| f.rms_mm))
                .collect(),
        }
    }
}

/// Reference shape of `count` points and their per-frame rigid fits. `point(f, k)` is
/// point k's global position at frame f (mm) or `None`. The local origin is the centroid
/// of the first `origin_points` points (a segment's own markers, not the virtual joint
/// centre an anchored segment adds).
///
/// With outlier rejection on, a point farther from its fitted place than the bound
/// (`outlier_factor` × the median per-frame RMS, at least `outlier_floor_mm`) in some
/// frame is left out of the reference average there, and of that frame's fit while ≥ 3
/// points remain (farthest first); a frame left with 3 points and an outlier among them
/// has no pose. Least squares lets one swapped or glitching marker drag the whole pose.
pub(crate) fn fit_shape(
    frames: usize,
    count: usize,
    origin_points: usize,
    point: impl Fn(usize, usize) -> Option<DVec3>,
    rules: FitRules,
) -> Shape {
    let mut spread = Spread::fixed(rules.min_spread_mm);
    let visible = |f: usize| (0..count).filter(|&k| point(f, k).is_some()).count();
    // The first frame seeing every point; else, of the frames seeing most, the first whose
    // points are seen longest: a point missing there gets a place only from frames posed
    // without it, and a segment of an unlabeled capture's pieces (a marker's later piece is
    // never seen with its earlier one) would otherwise be posed only while its shortest
    // piece lasts.
    let (ref_frame, best) = match (0..frames).find(|&f| count > 0 && visible(f) == count) {
        Some(f) => (Some(f), count),
        None => {
            let seen: Vec<usize> = (0..count)
                .map(|k| (0..frames).filter(|&f| point(f, k).is_some()).count())
                .collect();
            let seen_in = |f: usize| -> usize {
                (0..count)
                    .filter(|&k| point(f, k).is_some())
                    .map(|k| seen[k])
                    .sum()
            };
            let mut ref_frame = None;
            let (mut best, mut best_seen) = (0, 0);
            for f in 0..frames {
                let v = visible(f);
                if v < best || v == 0 {
                    continue;
                }
                let s = seen_in(f);
                if v > best || s > best_seen {
                    (best, best_seen) = (v, s);
                    ref_frame = Some(f);
                }
            }
            (ref_frame, best)
        }
    };
    let mut reference: Vec<DVec3> = match ref_frame {
        Some(f) => (0..count)
            .map(|k| point(f, k).unwrap_or(DVec3::NAN))
            .collect(),
        None => vec![DVec3::NAN; count],
    };
    recentre(&mut reference, origin_points);

    let mut buf = Vec::with_capacity(count);
    let mut fits: Vec<Option<RigidFit>> = vec![None; frames];
    if best >= 3 {
        for (f, fit) in fits.iter_mut().enumerate() {
            *fit = fit_frame(f, &point, &reference, &mut buf, spread);
        }
        // A frame whose visible points nearly line up turns freely about that line: its
        // spin is as uncertain as the segment's scatter over the points' lever, and a pose
        // that is tens of degrees off corrupts every joint of the segment. Such frames get
        // no pose here (the anchor's centre can fill them).
        if rules.max_spin_deg > 0.0
            && let Some(sigma_mm) = scatter_mm(&fits, &point, &reference)
        {
            // Only frames that see a clearly worse lever than the whole segment does: a
            // segment whose markers are poorly spread even when all are seen keeps its
            // poses (refusing them all hands it to the greedy anchor search, which picked
            // wrong neighbours: 16 seeds' hard trees 71 → 67 against a mean 1.90 → 1.82 %).
            let full_lever = lever_mm(reference.iter().copied().filter(|r| r.is_finite()));
            spread.min_lever_mm =
                (sigma_mm / rules.max_spin_deg.to_radians()).min(0.5 * full_lever);
            for (f, fit) in fits.iter_mut().enumerate() {
                if fit.is_some() {
                    *fit = fit_frame(f, &point, &reference, &mut buf, spread);
                }
            }
        }
        // One round of align-and-average, then the final alignment against the mean shape.
        reference = mean_shape(&fits, &point, count, None);
        recentre(&mut reference, origin_points);
        for (f, fit) in fits.iter_mut().enumerate() {
            *fit = fit_frame(f, &point, &reference, &mut buf, spread);
        }
        // The outliers inflate the first bound (they bias the mean shape, hence every
        // frame's RMS); a second round takes it from the fits without them.
        for _ in 0..OUTLIER_ROUNDS {
            let Some(limit_mm) = outlier_bound(&fits, rules) else {
                break;
            };
            // A sample's distance from its reference is its residual in that frame's fit:
            // with none beyond the bound, neither shape nor fits would change.
            let beyond = fits.iter().enumerate().any(|(f, fit)| {
                fit.is_some_and(|fit| {
                    (0..count).any(|k| {
                        point(f, k).is_some_and(|p| {
                            (fit.rotation * reference[k] + fit.translation).distance(p) > limit_mm
                        })
                    })
                })
            });
            if !beyond {
                break;
            }
            reference = mean_shape(&fits, &point, count, Some((&reference, limit_mm)));
            recentre(&mut reference, origin_points);
            for (f, fit) in fits.iter_mut().enumerate() {
                *fit = fit_frame_robust(f, &point, &reference, &mut buf, spread, limit_mm);
            }
        }
    }
    Shape { reference, fits }
}

/// Rounds of outlier rejection (bound, reference, fits).
const OUTLIER_ROUNDS: usize = 2;

/// The distance (mm) from its fitted place beyond which a point is an outlier, from the
/// median per-frame RMS of `fits`; `None` when rejection is off or nothing was fitted.
fn outlier_bound(fits: &[Option<RigidFit>], rules: FitRules) -> Option<f64> {
    if rules.outlier_factor <= 0.0 {
        return None;
    }
    let mut rms: Vec<f64> = fits.iter().flatten().map(|f| f.rms_mm).collect();
    if rms.is_empty() {
        return None;
    }
    rms.sort_by(f64::total_cmp);
    Some((rules.outlier_factor * rms[rms.len() / 2]).max(rules.outlier_floor_mm))
}

/// Every point's mean position in the local frame over the frames with a fit, NaN where
/// never seen; with `outliers` (reference, bound), samples farther than the bound from
/// their reference position are left out.
fn mean_shape(
    fits: &[Option<RigidFit>],
    point: &impl Fn(usize, usize) -> Option<DVec3>,
    count: usize,
    outliers: Option<(&[DVec3], f64)>,
) -> Vec<DVec3> {
    let mut sum = vec![DVec3::ZERO; count];
    let mut seen = vec![0usize; count];
    for (f, fit) in fits.iter().enumerate() {
        let Some(fit) = fit else { continue };
        let inv = fit.rotation.inverse();
        for k in 0..count {
            let Some(p) = point(f, k) else { continue };
            let local = inv * (p - fit.translation);
            if outliers.is_some_and(|(reference, bound)| local.distance(reference[k]) > bound) {
                continue;
            }
            sum[k] += local;
            seen[k] += 1;
        }
    }
    sum.iter()
        .zip(&seen)
        .map(|(s, &c)| if c > 0 { *s / c as f64 } else { DVec3::NAN })
        .collect()
}

/// [`fit_frame`], then again without the point farthest from its fitted place while that
/// is beyond `limit_mm` and at least 4 points are in the fit; `None` when 3 points remain
/// and one is still beyond it.
fn fit_frame_robust(
    frame: usize,
    point: &impl Fn(usize, usize) -> Option<DVec3>,
    reference: &[DVec3],
    buf: &mut Vec<(DVec3, DVec3)>,
    spread: Spread,
    limit_mm: f64,
) -> Option<RigidFit> {
    let mut fit = fit_frame(frame, point, reference, buf, spread)?;
    loop {
        let (worst, far) = buf
            .iter()
            .enumerate()
            .map(|(i, (r, o))| (i, (fit.rotation * *r + fit.translation).distance(*o)))
            .fold((0, 0.0), |best, x| if x.1 > best.1 { x } else { best });
        if far <= limit_mm {
            break;
        }
        if buf.len() < 4 {
            // Three points and one of them wrong: which one, no fit can tell.
            return None;
        }
        buf.swap_remove(worst);
        match fit_pairs(buf, spread) {
            Some(f) => fit = f,
            None => break,
        }
    }
    Some(fit)
}

/// Moves the origin to the centroid of the finite ones among the first `origin_points`
/// reference positions.
fn recentre(reference: &mut [DVec3], origin_points: usize) {
    let (sum, n) = reference[..origin_points.min(reference.len())]
        .iter()
        .filter(|r| r.is_finite())
        .fold((DVec3::ZERO, 0usize), |(s, n), r| (s + *r, n + 1));
    if n > 0 {
        let c = sum / n as f64;
        for r in reference.iter_mut().filter(|r| r.is_finite()) {
            *r -= c;
        }
    }
}

/// Horn fit of one frame on the points visible there and present in the reference.
fn fit_frame(
    frame: usize,
    point: &impl Fn(usize, usize) -> Option<DVec3>,
    reference: &[DVec3],
    buf: &mut Vec<(DVec3, DVec3)>,
    spread: Spread,
) -> Option<RigidFit> {
    buf.clear();
    for (k, r) in reference.iter().enumerate() {
        if let Some(p) = point(frame, k)
            && r.is_finite()
        {
            buf.push((*r, p));
        }
    }
    fit_pairs(buf, spread)
}

/// Horn fit of (reference, observed) pairs: `None` with fewer than 3 or a set too close
/// to a line for `spread`.
pub(crate) fn fit_pairs(buf: &[(DVec3, DVec3)], spread: Spread) -> Option<RigidFit> {
    if buf.len() < 3 {
        return None;
    }
    let [_, second, third] = principal_variances(buf.iter().map(|p| p.0));
    let lever_mm = (buf.len() as f64 * (second + third)).sqrt();
    if second.sqrt() < spread.min_spread_mm || lever_mm < spread.min_lever_mm {
        return None;
    }
    absolute_orientation(buf)
}

/// √ of the least eigenvalue of the points' inertia tensor about their centroid (mm):
/// √(n × the sum of the two smaller principal variances).
pub(crate) fn lever_mm(points: impl Iterator<Item = DVec3> + Clone) -> f64 {
    let n = points.clone().count() as f64;
    let [_, second, third] = principal_variances(points);
    (n * (second + third)).sqrt()
}

/// The points' scatter about their fitted places, mm per coordinate: the median over
/// frames of each fit's RMS, corrected for the degrees of freedom the fit takes out
/// ([`scatter_from_rms`]); `None` when no frame has a fit.
fn scatter_mm(
    fits: &[Option<RigidFit>],
    point: &impl Fn(usize, usize) -> Option<DVec3>,
    reference: &[DVec3],
) -> Option<f64> {
    let mut sigma: Vec<f64> = fits
        .iter()
        .enumerate()
        .filter_map(|(f, fit)| {
            let fit = fit.as_ref()?;
            let n = reference
                .iter()
                .enumerate()
                .filter(|(k, r)| r.is_finite() && point(f, *k).is_some())
                .count() as f64;
            Some(scatter_from_rms(fit.rms_mm, n))
        })
        .collect();
    if sigma.is_empty() {
        return None;
    }
    sigma.sort_by(f64::total_cmp);
    Some(sigma[sigma.len() / 2])
}

/// The line a segment's reference points lie nearest (through their centroid, along their
/// principal direction), with the given spin error; `None` for fewer than 2 points.
pub(crate) fn marker_line(poses: &SegmentPoses, spin_sd_rad: f64) -> Option<MarkerLine> {
    let points = reference_points(poses);
    if points.len() < 2 {
        return None;
    }
    let (origin, cov) = centroid_covariance(points.iter().copied());
    let (_, vectors) = sym_eigen(cov);
    let dir = DVec3::from_array(vectors[0]).normalize_or_zero();
    (dir != DVec3::ZERO).then_some(MarkerLine {
        origin,
        dir,
        spin_sd_rad,
    })
}

/// The points' centroid and covariance matrix (mm, mm²); `points` must not be empty.
fn centroid_covariance(points: impl Iterator<Item = DVec3> + Clone) -> (DVec3, [[f64; 3]; 3]) {
    let n = points.clone().count() as f64;
    let c = points.clone().sum::<DVec3>() / n;
    let mut cov = [[0.0; 3]; 3];
    for r in points {
        let d = (r - c).to_array();
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += d[i] * d[j] / n;
            }
        }
    }
    (c, cov)
}

/// Variances of the points along their principal directions, largest first (mm²); zeros
/// for no points.
fn principal_variances(points: impl Iterator<Item = DVec3> + Clone) -> [f64; 3] {
    if points.clone().next().is_none() {
        return [0.0; 3];
    }
    let (_, cov) = centroid_covariance(points);
    let (vals, _) = sym_eigen(cov);
    vals.map(|v| v.max(0.0))
}

impl SegmentPoses {
    /// The median over frames of the segment's RMS marker misfit (mm); `None` without a fit.
    pub fn median_rms_mm(&self) -> Option<f64> {
        let mut rms: Vec<f64> = self
            .rms_mm
            .iter()
            .copied()
            .filter(|r| r.is_finite())
            .collect();
        if rms.is_empty() {
            return None;
        }
        rms.sort_by(f64::total_cmp);
        Some(rms[rms.len() / 2])
    }

    /// Drops every frame's pose (the reference shape stays).
    pub(crate) fn forget(&mut self) {
        self.rotations.fill([f64::NAN; 4]);
        self.translations.fill([f64::NAN; 3]);
        self.rms_mm.fill(f64::NAN);
    }
}

/// A segment's predicted spin error (degrees, the linearised standard error) with all its
/// markers seen: its median per-frame fit scatter over its reference shape's lever; `None`
/// for fewer than 3 reference points or no fit, +∞ for collinear ones.
pub(crate) fn spin_error_deg(poses: &SegmentPoses) -> Option<f64> {
    let (sigma, reference) = fit_scatter(poses)?;
    let lever = lever_mm(reference.iter().copied());
    Some(if lever > 0.0 {
        (sigma / lever).to_degrees()
    } else {
        f64::INFINITY
    })
}

/// A segment's per-coordinate fit scatter (mm: its median frame's RMS, all markers seen
/// in a segment without many gaps) and its reference points; `None` for fewer than 3
/// points or no fit.
pub(crate) fn fit_scatter(poses: &SegmentPoses) -> Option<(f64, Vec<DVec3>)> {
    let reference = reference_points(poses);
    let n = reference.len() as f64;
    if n < 3.0 {
        return None;
    }
    Some((scatter_from_rms(poses.median_rms_mm()?, n), reference))
}

/// A segment's reference points that were ever seen together with the others (mm, local).
pub(crate) fn reference_points(poses: &SegmentPoses) -> Vec<DVec3> {
    poses
        .reference
        .iter()
        .map(|r| DVec3::from_array(*r))
        .filter(|r| r.is_finite())
        .collect()
}

/// The inverse of the inertia tensor of `points` about their centroid (mm⁻²): how far a
/// marker scatter turns a rigid fit of them (linearised least squares). `None` for
/// collinear points (the least principal moment vanishes against the largest: no bound
/// on their spin).
pub(crate) fn inverse_inertia(points: &[DVec3]) -> Option<DMat3> {
    let centroid = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    inverse_inertia_about(points, centroid)
}

/// The inverse of the inertia tensor of `points` about `pivot` (mm⁻²): how far their
/// scatter turns a body that pivots there; `None` when they line up with the pivot.
fn inverse_inertia_about(points: &[DVec3], pivot: DVec3) -> Option<DMat3> {
    let inertia = points.iter().fold(DMat3::ZERO, |j, &r| {
        let d = r - pivot;
        j + DMat3::from_diagonal(DVec3::splat(d.length_squared()))
            - DMat3::from_cols(d * d.x, d * d.y, d * d.z)
    });
    let scale = trace(inertia);
    let determinant = inertia.determinant();
    if determinant.is_nan() || determinant <= 1e-9 * scale.powi(3) {
        return None;
    }
    Some(inertia.inverse())
}

/// [`tilt_variance`] of a segment of two markers posed through a joint at `pivot`
/// (segment-local, mm), its markers scattering `sigma_mm` per coordinate: its markers turn
/// it about the pivot, which its neighbour carries, so their moments about the pivot bound
/// the turn.
pub(crate) fn pivot_tilt_variance(
    poses: &SegmentPoses,
    pivot: DVec3,
    sigma_mm: f64,
    axis: DVec3,
) -> Option<f64> {
    let reference = reference_points(poses);
    if reference.len() < 2 || !sigma_mm.is_finite() {
        return None;
    }
    let inverse = inverse_inertia_about(&reference, pivot)?;
    Some(sigma_mm * sigma_mm * (trace(inverse) - axis.dot(inverse * axis)).max(0.0))
}

/// How precisely a segment's poses put a point fixed in it, read once per segment: what
/// [`PoseScatter::precision_at`] needs of its fit, and its frames' [`misfit_scales`].
#[derive(Clone, Debug, Default)]
pub(crate) struct PoseScatter {
    /// Fit scatter σ (mm per coordinate), the reference markers' centroid, the inverse of
    /// their inertia tensor and their count; `None` for fewer than 3 points, no fit or
    /// collinear points.
    fit: Option<(f64, DVec3, DMat3, f64)>,
    /// Per frame, the pose's variance over its typical frame's ([`misfit_scales`]).
    pub scales: Vec<f64>,
    /// The unseen shift of the whole set, per coordinate, in units of σ²:
    /// [`SKIN_SHIFT_SHARE`] × [`misfit_smoothness`].
    shift_share: f64,
}

impl PoseScatter {
    /// The scatter of `poses`.
    pub fn of(poses: &SegmentPoses) -> Self {
        let fit = fit_scatter(poses).and_then(|(sigma, reference)| {
            let inverse = inverse_inertia(&reference)?;
            let n = reference.len() as f64;
            Some((
                sigma,
                reference.iter().copied().sum::<DVec3>() / n,
                inverse,
                n,
            ))
        });
        Self {
            fit,
            scales: misfit_scales(poses),
            shift_share: SKIN_SHIFT_SHARE * misfit_smoothness(poses),
        }
    }

    /// Inverse covariance (mm⁻², segment frame) of where the segment's pose puts its local
    /// point `p` in a typical frame: its fit scatter σ through the Horn fit of its reference
    /// markers, σ² (I/n + [d]× J⁻¹ [d]×ᵀ) with d = p less their centroid and J their
    /// inertia tensor (linearised least squares: the translation's error, and the turn's
    /// at p's lever), plus the shift of the whole set no fit sees where skin moves it
    /// ([`SKIN_SHIFT_SHARE`]).
    /// `None` without a fit (see `fit`) or for a scatter of 0.
    pub fn precision_at(&self, p: DVec3) -> Option<DMat3> {
        let covariance = self.covariance_between(p, p)?;
        let determinant = covariance.determinant();
        (determinant.is_finite() && determinant > 0.0)
            .then(|| covariance.inverse())
            .filter(|m| m.is_finite())
    }

    /// Covariance (mm², segment frame) between where the segment's pose puts its local
    /// points `p` and `q` in a typical frame: the same pose error moves both, through the
    /// translation alike and through the turn by each one's lever, σ² (I/n + [d_p]× J⁻¹
    /// [d_q]×ᵀ), and the unseen shift of the set alike ([`SKIN_SHIFT_SHARE`]) (at p = q the
    /// inverse of [`Self::precision_at`]). `None` without a fit.
    pub fn covariance_between(&self, p: DVec3, q: DVec3) -> Option<DMat3> {
        let (sigma, centroid, inverse, n) = self.fit?;
        let (cross_p, cross_q) = (cross_matrix(p - centroid), cross_matrix(q - centroid));
        let covariance =
            (DMat3::IDENTITY / n + cross_p * inverse * cross_q.transpose()) * (sigma * sigma);
        let covariance = covariance + DMat3::IDENTITY * (self.shift_share * sigma * sigma);
        covariance.is_finite().then_some(covariance)
    }

    /// Frame `f`'s variance ratio (1 beyond the frames read).
    pub fn scale(&self, f: usize) -> f64 {
        self.scales.get(f).copied().unwrap_or(1.0)
    }
}

/// The lag-1 autocorrelation of a segment's per-frame misfit RMS, clamped to [0, 1]: near
/// 1 where the misfit drifts smoothly with the motion (skin), 0 for white noise; 0 with
/// fewer than three frames fitted.
pub(crate) fn misfit_smoothness(poses: &SegmentPoses) -> f64 {
    let finite: Vec<f64> = poses
        .rms_mm
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    if finite.len() < 3 {
        return 0.0;
    }
    let mean = finite.iter().sum::<f64>() / finite.len() as f64;
    let (mut lagged, mut spread) = (0.0, 0.0);
    for w in poses.rms_mm.windows(2) {
        if w[0].is_finite() && w[1].is_finite() {
            lagged += (w[0] - mean) * (w[1] - mean);
            spread += 0.5 * ((w[0] - mean).powi(2) + (w[1] - mean).powi(2));
        }
    }
    if spread > 0.0 {
        (lagged / spread).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Variance of a segment's whole marker set shifting together, per coordinate, in units of
/// its markers' fit scatter σ², where the misfit is smooth ([`misfit_smoothness`] scales
/// it): skin that moves markers with the joint angles moves the set as a whole too, which
/// no rigid fit's misfit shows, by about as much as it moves them apart; white noise moves
/// each marker on its own. `cargo xtask eval --presets hard`, seeds
/// 20001..20050,30001..30050 / 40001..40100: 1.466 / 1.456 % of height without it, 1.455 /
/// 1.450 with it unscaled, 1.455 / 1.448 scaled (as here); `--presets noise` on
/// 20001..20030 0.206 % without it and scaled, 0.215 unscaled (white noise has no such
/// shift); in the tree readings alone at 3 σ²: 1.475 (the first set).
pub(crate) const SKIN_SHIFT_SHARE: f64 = 1.0;

/// [d]×, the cross product with `d` as a matrix.
fn cross_matrix(d: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, d.z, -d.y),
        DVec3::new(-d.z, 0.0, d.x),
        DVec3::new(d.y, -d.x, 0.0),
    )
}

/// Per frame, how a segment's pose error there compares with its typical frame's
/// (variance ratio): the mean squared misfit RMS over the frames within
/// [`MISFIT_WINDOW_FRAMES`] of it, over the squared median misfit RMS, at least
/// [`MIN_MISFIT_SCALE`]; 1 where no frame near it has a fit, and everywhere without a
/// median. Skin that deforms a segment's marker set in a frame has moved the set as a
/// whole there too, which no misfit shows; the frames it deforms most are the ones whose
/// pose to trust least. The window, because one frame's misfit has only 3n − 6 degrees
/// of freedom (three with three markers): white noise alone would make it scatter.
fn misfit_scales(poses: &SegmentPoses) -> Vec<f64> {
    let n = poses.rms_mm.len();
    let Some(median) = poses.median_rms_mm().filter(|m| *m > 0.0) else {
        return vec![1.0; n];
    };
    // Prefix sums of the finite squares and their count.
    let mut squares = vec![0.0; n + 1];
    let mut counts = vec![0usize; n + 1];
    for (f, r) in poses.rms_mm.iter().enumerate() {
        let finite = r.is_finite();
        squares[f + 1] = squares[f] + if finite { r * r } else { 0.0 };
        counts[f + 1] = counts[f] + usize::from(finite);
    }
    (0..n)
        .map(|f| {
            let (lo, hi) = (
                f.saturating_sub(MISFIT_WINDOW_FRAMES),
                (f + MISFIT_WINDOW_FRAMES + 1).min(n),
            );
            let count = counts[hi] - counts[lo];
            if count == 0 {
                return 1.0;
            }
            let mean = (squares[hi] - squares[lo]) / count as f64;
            (mean / (median * median)).max(MIN_MISFIT_SCALE)
        })
        .collect()
}

/// Half-width (frames) of the window [`misfit_scales`] averages a frame's misfit over:
/// 13 frames of three markers give 39 degrees of freedom.
const MISFIT_WINDOW_FRAMES: usize = 6;

/// Least variance ratio [`misfit_scales`] gives a frame: no frame counts more than a
/// hundred typical ones.
const MIN_MISFIT_SCALE: f64 = 0.01;

/// The sum of a 3×3 matrix's diagonal.
pub(crate) fn trace(m: DMat3) -> f64 {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

/// Variance (rad²) of a segment's pose turn about the two directions across `axis` (unit,
/// segment-local) that its fit scatter σ gives: σ² (tr J⁻¹ − axisᵀ J⁻¹ axis), J the
/// inertia tensor of its reference points about their centroid (linearised least
/// squares). It is how far fit noise alone tilts a line fixed in the segment. `None`
/// without a fit or for collinear points (no bound on their spin).
pub(crate) fn tilt_variance(poses: &SegmentPoses, axis: DVec3) -> Option<f64> {
    let (sigma, reference) = fit_scatter(poses)?;
    let inverse = inverse_inertia(&reference)?;
    Some(sigma * sigma * (trace(inverse) - axis.dot(inverse * axis)).max(0.0))
}

/// Per-coordinate scatter (mm) from a rigid fit's RMS over `points` points: the fit takes
/// 6 degrees of freedom out of 3n, so E[RMS²] = σ²(3n − 6)/n.
pub(crate) fn scatter_from_rms(rms_mm: f64, points: f64) -> f64 {
    rms_mm * (points / (3.0 * points - 6.0)).sqrt()
}

/// The stored poses as the pair fits use them; `None` where the pose is unknown.
pub(crate) fn pose_track(poses: &SegmentPoses) -> Vec<Option<Pose>> {
    poses
        .rotations
        .iter()
        .zip(&poses.translations)
        .map(|(q, t)| {
            let q = DQuat::from_array(*q);
            let t = DVec3::from_array(*t);
            (q.is_finite() && t.is_finite()).then(|| Pose {
                rot: DMat3::from_quat(q),
                trans: t,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::horn::tests::TestRng;

    /// The default rules.
    fn rules() -> FitRules {
        FitRules::of(&crate::Params::default())
    }

    /// A frame's variance ratio reads the misfit of the frames round it over the median's:
    /// 1 where the fit is typical, the burst's ratio squared inside a long burst, partly at
    /// its edges (the window straddles them), never below the floor, and 1 where nothing
    /// near has a fit.
    #[test]
    fn misfit_scales_read_each_frame_against_the_typical_one() {
        let mut rms = vec![2.0; 100];
        for r in &mut rms[40..70] {
            *r = 6.0;
        }
        for r in &mut rms[0..3] {
            *r = 0.0;
        }
        rms.extend([f64::NAN; 20]);
        let poses = SegmentPoses {
            segment: 0,
            reference: vec![[0.0; 3]; 3],
            rotations: vec![[0.0, 0.0, 0.0, 1.0]; rms.len()],
            translations: vec![[0.0; 3]; rms.len()],
            rms_mm: rms,
        };
        let scales = misfit_scales(&poses);
        assert_eq!(scales.len(), 120);
        assert!((scales[20] - 1.0).abs() < 1e-12, "{}", scales[20]);
        assert!((scales[55] - 9.0).abs() < 1e-12, "{}", scales[55]);
        // Seven of the thirteen frames round frame 40 are the burst's (6 mm), six not (2 mm).
        let edge = (7.0 * 36.0 + 6.0 * 4.0) / 13.0 / 4.0;
        assert!((scales[40] - edge).abs() < 1e-12, "{} {edge}", scales[40]);
        assert!(
            scales[0] >= MIN_MISFIT_SCALE && scales[0] < 1.0,
            "{}",
            scales[0]
        );
        assert!(scales[110] == 1.0);
    }

    /// A 5-marker body whose last marker's trajectory is another body's for 50 of 300
    /// frames (a swap): with rejection the poses there stay exact and the marker's
    /// reference is its true place; least squares alone lets it drag every one of them.
    #[test]
    fn a_swapped_marker_does_not_drag_the_pose() {
        let mut rng = TestRng(12);
        let local = [
            DVec3::new(40.0, 0.0, 100.0),
            DVec3::new(-35.0, 25.0, 180.0),
            DVec3::new(10.0, -40.0, 260.0),
            DVec3::new(-20.0, -15.0, 140.0),
            DVec3::new(30.0, 30.0, 220.0),
        ];
        let frames = 300;
        let mut truth = Vec::new();
        let mut positions = Vec::new();
        for f in 0..frames {
            let t = f as f64 / 100.0;
            let q = DQuat::from_rotation_y(0.8 * (1.3 * t).sin()) * DQuat::from_rotation_x(0.4 * t);
            let trans = DVec3::new(300.0 * t, 50.0 * t.sin(), 900.0);
            truth.push((q, trans));
            for (k, l) in local.iter().enumerate() {
                let p = if k == 4 && (100..150).contains(&f) {
                    // Elsewhere: where a marker of a swinging neighbour was.
                    DVec3::new(300.0 * t - 150.0, 400.0 + 80.0 * (3.0 * t).sin(), 600.0)
                } else {
                    q * *l + trans
                };
                positions.push((p + rng.vec3(0.1)).to_array());
            }
        }
        let labels = (0..5).map(|i| format!("M{i}")).collect();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        let worst_error = |sp: &SegmentPoses| {
            let track = pose_track(sp);
            let mut worst: f64 = 0.0;
            for (f, pose) in track.iter().enumerate() {
                let pose = pose.as_ref().unwrap();
                let (q, t) = truth[f];
                // Markers 0..4 never leave: the pose must carry their references onto them.
                for (r, l) in sp.reference.iter().zip(&local).take(4) {
                    let g = pose.apply(DVec3::from_array(*r));
                    worst = worst.max((g - (q * *l + t)).length());
                }
            }
            worst
        };
        let robust = segment_poses(&traj, 0, &[0, 1, 2, 3, 4], rules());
        let plain = segment_poses(
            &traj,
            0,
            &[0, 1, 2, 3, 4],
            FitRules {
                outlier_factor: 0.0,
                ..rules()
            },
        );
        assert!(worst_error(&robust) < 1.0, "{} mm", worst_error(&robust));
        assert!(worst_error(&plain) > 20.0, "{} mm", worst_error(&plain));
        // The swapped marker's reference keeps its true distance to the others.
        let r = |k: usize| DVec3::from_array(robust.reference[k]);
        assert!((r(4).distance(r(0)) - local[4].distance(local[0])).abs() < 1.0);

        // Three markers, one of them swapped: no fit can say which, so no pose there.
        let three = segment_poses(&traj, 0, &[0, 1, 4], rules());
        for (f, q) in three.rotations.iter().enumerate() {
            assert_eq!(q[0].is_nan(), (100..150).contains(&f), "frame {f}");
        }
    }

    /// A body of 4 markers under 2 mm scatter whose only marker off the line of the other
    /// three is hidden for a third of the trial: the three left (a 4.4 mm lever) fix the
    /// spin about their line to ~26°, so those frames get no pose of their own; with the
    /// limit off they are posed and turned far off.
    #[test]
    fn nearly_collinear_markers_left_alone_pose_no_frame() {
        let mut rng = TestRng(21);
        let local = [
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(-2.0, 3.0, 120.0),
            DVec3::new(0.0, -3.0, 240.0),
            DVec3::new(70.0, 0.0, 120.0),
        ];
        let frames = 300;
        let hidden = 100..200;
        let mut truth = Vec::new();
        let mut positions = Vec::new();
        for f in 0..frames {
            let q = rng.rotation();
            let t = rng.vec3(500.0);
            truth.push(q);
            for (k, l) in local.iter().enumerate() {
                let scatter = DVec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * 2.0;
                positions.push(if k == 3 && hidden.contains(&f) {
                    mocap_io::MISSING
                } else {
                    (q * *l + t + scatter).to_array()
                });
            }
        }
        let labels = (0..4).map(|i| format!("M{i}")).collect();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        // Worst rotation error (degrees) over frames with a pose: the local frame is the
        // body's up to a constant rotation, so truth⁻¹ × pose is constant; against frame 0.
        let worst_deg = |sp: &SegmentPoses, frames: std::ops::Range<usize>| {
            let track = pose_track(sp);
            let offset = |f: usize| truth[f].inverse() * DQuat::from_mat3(&track[f].unwrap().rot);
            frames
                .filter(|&f| track[f].is_some())
                .map(|f| {
                    (offset(f) * offset(0).inverse())
                        .to_axis_angle()
                        .1
                        .to_degrees()
                })
                .map(|a| if a > 180.0 { 360.0 - a } else { a })
                .fold(0.0f64, f64::max)
        };
        let limited = segment_poses(&traj, 0, &[0, 1, 2, 3], rules());
        let posed = |sp: &SegmentPoses, f: usize| sp.rotations[f][0].is_finite();
        for f in 0..frames {
            assert_eq!(posed(&limited, f), !hidden.contains(&f), "frame {f}");
        }
        assert!(
            worst_deg(&limited, 0..frames) < 12.0,
            "{}°",
            worst_deg(&limited, 0..frames)
        );
        let unlimited = segment_poses(
            &traj,
            0,
            &[0, 1, 2, 3],
            FitRules {
                max_spin_deg: 0.0,
                ..rules()
            },
        );
        assert!(hidden.clone().all(|f| posed(&unlimited, f)));
        let off = worst_deg(&unlimited, hidden);
        assert!(off > 45.0, "{off}°");
    }

    /// One rigid body of 4 markers, random poses, a gap pattern; poses must reproduce it.
    #[test]
    fn poses_reproduce_markers_with_gaps() {
        let mut rng = TestRng(11);
        let local = [
            DVec3::new(60.0, 0.0, 0.0),
            DVec3::new(-30.0, 50.0, 0.0),
            DVec3::new(-30.0, -50.0, 10.0),
            DVec3::new(0.0, 0.0, 80.0),
        ];
        let frames = 200;
        let mut positions = Vec::new();
        let mut truth = Vec::new();
        for f in 0..frames {
            let q = rng.rotation();
            let t = rng.vec3(500.0);
            truth.push((q, t));
            for (k, l) in local.iter().enumerate() {
                // Marker 0 missing in the first 50 frames; marker 3 every 3rd frame;
                // frames 100..110 keep only 2 markers.
                let gone = (k == 0 && f < 50)
                    || (k == 3 && f % 3 == 0)
                    || ((100..110).contains(&f) && k >= 2);
                positions.push(if gone {
                    mocap_io::MISSING
                } else {
                    (q * *l + t + rng.vec3(0.1)).to_array()
                });
            }
        }
        let labels = (0..4).map(|i| format!("M{i}")).collect();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        let sp = segment_poses(&traj, 0, &[0, 1, 2, 3], rules());
        let track = pose_track(&sp);
        assert!(sp.reference.iter().all(|r| r[0].is_finite()));
        let mut known = 0;
        for (f, pose) in track.iter().enumerate() {
            if (100..110).contains(&f) || (f < 50 && f % 3 == 0) {
                assert!(pose.is_none(), "frame {f} has only 2 markers");
                continue;
            }
            let pose = pose.as_ref().unwrap();
            known += 1;
            // Local frame differs from `local` by a fixed rigid motion: compare shapes
            // through distances of the mapped reference to the true markers.
            let (q, t) = truth[f];
            for (k, r) in sp.reference.iter().enumerate() {
                let g = pose.apply(DVec3::from_array(*r));
                let e = (g - (q * local[k] + t)).length();
                assert!(e < 0.5, "frame {f} marker {k}: {e} mm");
            }
            assert!(sp.rms_mm[f] < 0.3);
        }
        assert_eq!(known, frames - 10 - 17);
    }

    /// A segment of three markers, one of them in two pieces never seen together (an
    /// unlabeled capture's: 30 frames, then 150): posed in the longer piece's frames, not
    /// only the first piece's (the reference frame holds the longer piece; the shorter one
    /// is never seen with three placed markers).
    #[test]
    fn a_marker_in_pieces_poses_its_segment_while_the_longer_piece_lasts() {
        let mut rng = TestRng(17);
        let local = [
            DVec3::new(60.0, 0.0, 0.0),
            DVec3::new(-30.0, 50.0, 0.0),
            DVec3::new(-30.0, -50.0, 10.0),
        ];
        let frames = 200;
        let mut positions = Vec::new();
        for f in 0..frames {
            let (q, t) = (rng.rotation(), rng.vec3(500.0));
            let at = |k: usize| (q * local[k] + t).to_array();
            // Tracks: markers 1 and 2, then marker 0's first piece (frames 0..30) and its
            // second (50..200).
            positions.extend([
                at(1),
                at(2),
                if f < 30 { at(0) } else { mocap_io::MISSING },
                if f >= 50 { at(0) } else { mocap_io::MISSING },
            ]);
        }
        let labels = ["B", "C", "A", "A~1"].map(String::from).to_vec();
        let traj = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
        let sp = segment_poses(&traj, 0, &[0, 1, 2, 3], rules());
        let posed = pose_track(&sp).iter().filter(|p| p.is_some()).count();
        assert_eq!(posed, 150, "{:?}", sp.reference);
    }

    #[test]
    fn collinear_markers_give_no_pose() {
        let positions = (0..40)
            .flat_map(|f| {
                let x = f as f64;
                [[x, 0.0, 0.0], [x + 50.0, 0.0, 0.0], [x + 100.0, 0.0, 0.5]]
            })
            .collect();
        let labels = (0..3).map(|i| format!("M{i}")).collect();
        let traj = Trajectories::new(labels, 100.0, 1, 40, positions).unwrap();
        let sp = segment_poses(&traj, 0, &[0, 1, 2], rules());
        assert!(sp.rotations.iter().all(|q| q[0].is_nan()));
    }
}
