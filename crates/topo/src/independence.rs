//! How independently two segments turn on a third: the evidence that picks the hub of
//! three segments meeting close together.
//!
//! Two joints on one hub turn independently of each other; the pair across them
//! composes both motions. Seen from a wrong hub (one of the two children), its two
//! pairs share that child's joint motion: the pair to the true hub is that motion, the
//! pair to the other child is it composed with the other joint, so their rotations are
//! correlated. Seen from the true hub, they are not. Smooth motions of a few cycles
//! correlate by chance too, so the correlation is read in units of what shifting one
//! series against the other gives.

use std::collections::HashMap;

use glam::{DQuat, DVec3};
use jointfit::{PairFits, chordal_mean};

/// Fewest frames with all three poses known for a correlation to be read.
const MIN_FRAMES: usize = 20;

/// Shifts, as shares of the frames, at which the two series' correlation measures what
/// chance gives signals this slow.
const LAG_FRACTIONS: [f64; 4] = [0.1, 0.2, 0.3, 0.4];

/// Most frames a correlation reads (at a stride beyond).
const MAX_SAMPLES: usize = 600;

/// Floor of the chance correlation, so that series which hardly correlate at any shift
/// do not make a small correlation read as a large one.
const MIN_CHANCE: f64 = 0.05;

/// Correlations of pairs' rotations seen from a hub, computed once per (hub, x, y).
pub(crate) struct HubCorrelations<'a> {
    fits: &'a PairFits,
    known: HashMap<(usize, usize, usize), f64>,
}

impl<'a> HubCorrelations<'a> {
    /// Nothing read yet.
    pub(crate) fn new(fits: &'a PairFits) -> Self {
        Self {
            fits,
            known: HashMap::new(),
        }
    }

    /// How much x's and y's rotations relative to the hub (in its frame, about their
    /// means) correlate beyond chance: their correlation (trace form) over the RMS of
    /// their correlations with one shifted against the other by 10–40 % of the frames
    /// (signals with a few slow cycles correlate by chance that much). Frames where all
    /// three poses are known, at most about [`MAX_SAMPLES`] of them evenly spread; NaN
    /// with fewer than [`MIN_FRAMES`].
    pub(crate) fn get(&mut self, hub: usize, x: usize, y: usize) -> f64 {
        let key = (hub, x.min(y), x.max(y));
        if let Some(&r) = self.known.get(&key) {
            return r;
        }
        let r = correlation_beyond_chance(self.fits, hub, key.1, key.2);
        self.known.insert(key, r);
        r
    }

    /// Whether a's two pairs (with b and with c) correlate at least `margin` less than
    /// b's two pairs and c's; the readings stop at the first that misses.
    pub(crate) fn clearly_the_hub(&mut self, a: usize, b: usize, c: usize, margin: f64) -> bool {
        let bound = self.get(a, b, c) + margin;
        bound <= self.get(b, a, c) && bound <= self.get(c, a, b)
    }
}

fn quat(q: [f64; 4]) -> Option<DQuat> {
    let q = DQuat::from_array(q);
    q.is_finite().then_some(q)
}

/// The rotation from q to r as a rotation vector (radians), the short way round.
fn turn(q: DQuat, r: DQuat) -> DVec3 {
    let d = (r * q.inverse()).normalize();
    if d.w < 0.0 { -d } else { d }.to_scaled_axis()
}

fn correlation_beyond_chance(fits: &PairFits, hub: usize, x: usize, y: usize) -> f64 {
    let (h, px, py) = (&fits.poses[hub], &fits.poses[x], &fits.poses[y]);
    let frames = h
        .rotations
        .len()
        .min(px.rotations.len())
        .min(py.rotations.len());
    // Slow motions need no more samples than this; long captures are read at a stride,
    // which keeps the stage's time flat in the capture's length.
    let stride = frames.div_ceil(MAX_SAMPLES).max(1);
    let mut relative_x = Vec::with_capacity(frames / stride + 1);
    let mut relative_y = Vec::with_capacity(frames / stride + 1);
    for f in (0..frames).step_by(stride) {
        let (Some(qh), Some(qx), Some(qy)) = (
            quat(h.rotations[f]),
            quat(px.rotations[f]),
            quat(py.rotations[f]),
        ) else {
            continue;
        };
        let to_hub = qh.inverse();
        relative_x.push((to_hub * qx).normalize());
        relative_y.push((to_hub * qy).normalize());
    }
    if relative_x.len() < MIN_FRAMES {
        return f64::NAN;
    }
    let (Some(mean_x), Some(mean_y)) = (chordal_mean(&relative_x), chordal_mean(&relative_y))
    else {
        return f64::NAN;
    };
    let tx: Vec<DVec3> = relative_x.iter().map(|&q| turn(mean_x, q)).collect();
    let ty: Vec<DVec3> = relative_y.iter().map(|&q| turn(mean_y, q)).collect();
    // Shifts count the frames kept (all three poses known): a gap only blurs the
    // chance estimate, while the zero-shift correlation pairs the same instants.
    let at_lag = |lag: isize| {
        let skip_x = lag.max(0).unsigned_abs();
        let skip_y = (-lag).max(0).unsigned_abs();
        correlation_of(&tx[skip_x.min(tx.len())..], &ty[skip_y.min(ty.len())..])
    };
    let frames = tx.len() as f64;
    let chance: Vec<f64> = LAG_FRACTIONS
        .iter()
        .flat_map(|&f| {
            let lag = (f * frames).round() as isize;
            [at_lag(lag), at_lag(-lag)]
        })
        .filter(|c| c.is_finite())
        .collect();
    if chance.is_empty() {
        return f64::NAN;
    }
    let chance_rms = (chance.iter().map(|c| c * c).sum::<f64>() / chance.len() as f64).sqrt();
    at_lag(0) / chance_rms.max(MIN_CHANCE)
}

/// Trace correlation of two vector series about their means, over their common length.
fn correlation_of(x: &[DVec3], y: &[DVec3]) -> f64 {
    let len = x.len().min(y.len());
    if len < MIN_FRAMES {
        return f64::NAN;
    }
    let (x, y) = (&x[..len], &y[..len]);
    let n = len as f64;
    let (cx, cy) = (x.iter().sum::<DVec3>() / n, y.iter().sum::<DVec3>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0f64, 0.0f64, 0.0f64);
    for (a, b) in x.iter().zip(y) {
        let (a, b) = (*a - cx, *b - cy);
        sxy += a.dot(b);
        sxx += a.dot(a);
        syy += b.dot(b);
    }
    let norm = (sxx * syy).sqrt();
    if norm > 0.0 { sxy / norm } else { f64::NAN }
}

/// Poses of a hub (segment 0) turning on its own and two children (1, 2) each turning on
/// it with three independent smooth angles, as a test scene.
#[cfg(test)]
pub(crate) fn hub_and_two_children(frames: usize) -> Vec<jointfit::SegmentPoses> {
    // Per axis: cycles per trial of two sinusoids (apart, so no two tracks share one),
    // a phase and an amplitude (radians).
    type Axes = [([f64; 2], f64, f64); 3];
    let hub: Axes = [
        ([1.0, 2.3], 0.3, 0.3),
        ([1.4, 3.1], 1.1, 0.2),
        ([0.9, 2.7], 2.0, 0.2),
    ];
    let first: Axes = [
        ([1.7, 4.1], 0.7, 0.5),
        ([2.2, 3.6], 2.5, 0.4),
        ([1.2, 4.6], 1.9, 0.4),
    ];
    let second: Axes = [
        ([2.6, 5.2], 1.3, 0.5),
        ([1.9, 3.3], 0.2, 0.4),
        ([3.4, 4.4], 2.9, 0.4),
    ];
    let rotation = |axes: &Axes, f: usize| {
        let t = f as f64 / frames as f64 * std::f64::consts::TAU;
        let angle = |(cycles, phase, amplitude): ([f64; 2], f64, f64)| {
            amplitude * (0.6 * (cycles[0] * t + phase).sin() + 0.4 * (cycles[1] * t).cos())
        };
        DQuat::from_scaled_axis(DVec3::new(angle(axes[0]), angle(axes[1]), angle(axes[2])))
    };
    let poses = |segment: usize, of: &dyn Fn(usize) -> DQuat| jointfit::SegmentPoses {
        segment,
        reference: Vec::new(),
        rotations: (0..frames).map(|f| of(f).to_array()).collect(),
        translations: vec![[0.0; 3]; frames],
        rms_mm: vec![1.0; frames],
    };
    vec![
        poses(0, &|f| rotation(&hub, f)),
        poses(1, &|f| rotation(&hub, f) * rotation(&first, f)),
        poses(2, &|f| rotation(&hub, f) * rotation(&second, f)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_hub_sees_its_two_joints_turn_independently() {
        // The same motion sampled 480 times, and 4800 times (read at a stride of 8).
        for frames in [480, 4800] {
            let fits = PairFits {
                frames,
                poses: hub_and_two_children(frames),
                pairs: Vec::new(),
            };
            let mut seen = HubCorrelations::new(&fits);
            let at_hub = seen.get(0, 1, 2);
            let (at_first, at_second) = (seen.get(1, 0, 2), seen.get(2, 0, 1));
            // Measured at 480: hub -0.34, children 2.59 and 2.44 (chance about 0.3).
            assert!(at_hub.abs() < 1.0, "{frames} frames: hub {at_hub}");
            assert!(
                at_first.min(at_second) > at_hub + 2.0,
                "{frames} frames: hub {at_hub}, children {at_first} {at_second}"
            );
            assert!(seen.clearly_the_hub(0, 1, 2, 2.0));
            assert!(!seen.clearly_the_hub(1, 0, 2, 0.0));
            // Cached per (hub, pair), either order.
            assert_eq!(seen.get(0, 2, 1), at_hub);
        }
    }
}
