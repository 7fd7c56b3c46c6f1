//! Marker placement on segments, shuffled labels, and global marker positions.

use glam::{DQuat, DVec3};
use rand::Rng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use crate::body::Body;
use crate::motion::Motion;

/// Markers closer than this to another marker in the rest pose are re-drawn (a real
/// marker is ~14 mm wide), mm.
const MIN_SEPARATION_MM: f64 = 15.0;

/// Every marker, in label order (`M000`, `M001`, …).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MarkerSet {
    /// Labels, sorted; the numbering is a random permutation of the physical markers.
    pub labels: Vec<String>,
    /// The segment each marker rides on.
    pub segment: Vec<usize>,
    /// Position in the segment's local frame, mm.
    pub local: Vec<DVec3>,
}

/// Places `count.0..=count.1` markers on every segment from the marker random stream.
///
/// A marker sits at a random point of the middle 80 % of its segment's bone, pushed
/// out perpendicular to the bone by a random distance in the segment's radius range, in
/// a direction within `arc_deg` degrees centred on a side drawn per segment (all round at
/// 360, which draws no side, so the stream is the same as before the arc existed).
pub(crate) fn place(
    body: &Body,
    count: (usize, usize),
    arc_deg: f64,
    rng: &mut ChaCha8Rng,
) -> MarkerSet {
    let mut segment = Vec::new();
    let mut local: Vec<DVec3> = Vec::new();
    // Rest-pose positions of the markers placed so far (rest rotations are identity).
    let rest = body.pose(DQuat::IDENTITY, DVec3::ZERO, &[]);
    let mut placed: Vec<DVec3> = Vec::new();
    for (s, seg) in body.segments.iter().enumerate() {
        let n = rng.random_range(count.0..=count.1);
        let [start, end] = seg.bone;
        let axis = (end - start).try_normalize().unwrap_or(DVec3::Z);
        let e1 = axis.any_orthonormal_vector();
        let e2 = axis.cross(e1);
        let all_round = arc_deg >= 360.0;
        let side = if all_round {
            0.0
        } else {
            rng.random_range(0.0..std::f64::consts::TAU)
        };
        let half = 0.5 * arc_deg.to_radians();
        for _ in 0..n {
            let mut p = start;
            // Re-draw a few times when too close to a marker already placed.
            for _ in 0..50 {
                let along = rng.random_range(0.1..0.9);
                let angle = if all_round {
                    rng.random_range(0.0..std::f64::consts::TAU)
                } else {
                    side + rng.random_range(-half..=half)
                };
                let r = rng.random_range(seg.radius[0]..=seg.radius[1]);
                p = start + (end - start) * along + (e1 * angle.cos() + e2 * angle.sin()) * r;
                let at_rest = rest.origin[s] + p;
                if placed
                    .iter()
                    .all(|q| q.distance(at_rest) >= MIN_SEPARATION_MM)
                {
                    break;
                }
            }
            segment.push(s);
            local.push(p);
            placed.push(rest.origin[s] + p);
        }
    }
    // Label numbers are a random permutation, so a label says nothing about its segment.
    let mut number: Vec<usize> = (0..segment.len()).collect();
    number.shuffle(rng);
    let mut order = vec![0; number.len()];
    for (physical, &n) in number.iter().enumerate() {
        order[n] = physical;
    }
    MarkerSet {
        labels: (0..order.len()).map(|n| format!("M{n:03}")).collect(),
        segment: order.iter().map(|&p| segment[p]).collect(),
        local: order.iter().map(|&p| local[p]).collect(),
    }
}

/// Global marker positions, frame-major in label order, mm; `skin` adds a per-sample
/// displacement in the segment's local frame (`skin[f * markers + m]`).
pub(crate) fn positions(
    motion: &Motion,
    markers: &MarkerSet,
    skin: Option<&[DVec3]>,
) -> Vec<[f64; 3]> {
    let m = markers.labels.len();
    let mut out = Vec::with_capacity(motion.frames * m);
    for f in 0..motion.frames {
        for (i, (&s, &p)) in markers.segment.iter().zip(&markers.local).enumerate() {
            let d = skin.map_or(DVec3::ZERO, |k| k[f * m + i]);
            out.push((motion.origin(f, s) + motion.rot(f, s) * (p + d)).to_array());
        }
    }
    out
}
