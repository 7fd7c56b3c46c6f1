//! A segment's pose track with its gaps filled: rotations everywhere, translations where
//! measured or inside a short gap.

use glam::{DQuat, DVec3};
use jointfit::SegmentPoses;

/// One segment's poses over all frames, local frame → global frame.
pub(crate) struct FilledPoses {
    /// Unit rotation per frame; slerped in gaps, held at the ends, identity if never measured.
    pub rotations: Vec<DQuat>,
    /// Translation per frame (mm); NaN where `known` is false.
    pub translations: Vec<DVec3>,
    /// The pose at this frame came from jointfit (not interpolated).
    pub measured: Vec<bool>,
    /// The pose at this frame is measured or inside a filled short gap.
    pub known: Vec<bool>,
}

/// Fills the gaps of a pose track; gaps of at most `max_gap` frames between two measured
/// poses count as known. Quaternion signs are made continuous so slerp takes the short way.
pub(crate) fn fill(poses: &SegmentPoses, max_gap: usize) -> FilledPoses {
    let n = poses.rotations.len().min(poses.translations.len());
    let mut rotations = vec![DQuat::IDENTITY; n];
    let mut translations = vec![DVec3::NAN; n];
    let mut measured = vec![false; n];
    let mut previous: Option<DQuat> = None;
    for f in 0..n {
        let q = DQuat::from_array(poses.rotations[f]);
        let t = DVec3::from_array(poses.translations[f]);
        let len = q.length();
        if !(q.is_finite() && t.is_finite() && len > 1e-6) {
            continue;
        }
        let mut q = q / len;
        if previous.is_some_and(|p| p.dot(q) < 0.0) {
            q = -q;
        }
        previous = Some(q);
        rotations[f] = q;
        translations[f] = t;
        measured[f] = true;
    }

    let mut known = measured.clone();
    let mut last: Option<usize> = None;
    let mut f = 0;
    while f < n {
        if measured[f] {
            last = Some(f);
            f += 1;
            continue;
        }
        let start = f;
        while f < n && !measured[f] {
            f += 1;
        }
        let next = (f < n).then_some(f);
        match (last, next) {
            (Some(a), Some(b)) => {
                let short = b - a - 1 <= max_gap;
                let span = (b - a) as f64;
                for g in start..b {
                    let s = (g - a) as f64 / span;
                    rotations[g] = rotations[a].slerp(rotations[b], s).normalize();
                    if short {
                        translations[g] = translations[a].lerp(translations[b], s);
                        known[g] = true;
                    }
                }
            }
            (Some(a), None) => {
                let q = rotations[a];
                rotations[start..].fill(q);
            }
            (None, Some(b)) => {
                let q = rotations[b];
                rotations[..b].fill(q);
            }
            (None, None) => {}
        }
    }
    FilledPoses {
        rotations,
        translations,
        measured,
        known,
    }
}

/// Rotations where given, slerped between the nearest given ones, held at the ends;
/// identity when none is given.
pub(crate) fn fill_rotations(given: &[Option<DQuat>]) -> Vec<DQuat> {
    let mut out = vec![DQuat::IDENTITY; given.len()];
    let mut last: Option<(usize, DQuat)> = None;
    for (f, q) in given.iter().enumerate() {
        let Some(q) = q.filter(|q| q.is_finite() && q.length() > 1e-6) else {
            continue;
        };
        let mut q = q.normalize();
        // Continuous signs so slerp takes the short way.
        if last.is_some_and(|(_, p)| p.dot(q) < 0.0) {
            q = -q;
        }
        match last {
            Some((a, p)) => {
                let span = (f - a) as f64;
                for (g, r) in out.iter_mut().enumerate().take(f).skip(a + 1) {
                    *r = p.slerp(q, (g - a) as f64 / span).normalize();
                }
            }
            None => out[..f].fill(q),
        }
        out[f] = q;
        last = Some((f, q));
    }
    if let Some((a, q)) = last {
        out[a + 1..].fill(q);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(rotations: Vec<[f64; 4]>, translations: Vec<[f64; 3]>) -> SegmentPoses {
        SegmentPoses {
            segment: 0,
            reference: Vec::new(),
            rms_mm: vec![0.0; rotations.len()],
            rotations,
            translations,
        }
    }

    #[test]
    fn short_gaps_are_interpolated_long_ones_only_rotated() {
        let nan4 = [f64::NAN; 4];
        let nan3 = [f64::NAN; 3];
        let q0 = DQuat::IDENTITY.to_array();
        let q1 = DQuat::from_rotation_z(1.0).to_array();
        // Sign flip in the data: -q1 is the same rotation.
        let q1n = (-DQuat::from_rotation_z(1.0)).to_array();
        let p = track(
            vec![nan4, q0, nan4, q1, nan4, nan4, nan4, q1n, nan4],
            vec![
                nan3,
                [0.0; 3],
                nan3,
                [10.0, 0.0, 0.0],
                nan3,
                nan3,
                nan3,
                [10.0, 0.0, 0.0],
                nan3,
            ],
        );
        let filled = fill(&p, 2);
        assert_eq!(
            filled.known,
            [false, true, true, true, false, false, false, true, false]
        );
        assert_eq!(filled.measured.iter().filter(|m| **m).count(), 3);
        // Ends held, middle of the short gap half way.
        assert!(filled.rotations[0].angle_between(DQuat::IDENTITY) < 1e-12);
        let mid = filled.rotations[2];
        assert!((mid.angle_between(DQuat::IDENTITY) - 0.5).abs() < 1e-9);
        assert!((filled.translations[2] - DVec3::new(5.0, 0.0, 0.0)).length() < 1e-12);
        // The long gap keeps the rotation (same rotation at both ends, sign made continuous).
        for f in 4..9 {
            assert!(filled.rotations[f].angle_between(DQuat::from_rotation_z(1.0)) < 1e-9);
        }
        assert!(filled.translations[5].is_nan());
        // Never measured: identity, unknown.
        let none = fill(&track(vec![nan4; 3], vec![nan3; 3]), 5);
        assert!(none.known.iter().all(|k| !k));
        assert!(none.rotations.iter().all(|q| *q == DQuat::IDENTITY));
    }

    #[test]
    fn fill_rotations_holds_the_ends_and_slerps_between() {
        let q = DQuat::from_rotation_z(1.0);
        let r = fill_rotations(&[None, None, Some(DQuat::IDENTITY), None, Some(-q), None]);
        assert!(r[0].angle_between(DQuat::IDENTITY) < 1e-12);
        assert!(r[1].angle_between(DQuat::IDENTITY) < 1e-12);
        assert!((r[3].angle_between(DQuat::IDENTITY) - 0.5).abs() < 1e-9);
        assert!(r[5].angle_between(q) < 1e-12);
        assert!(
            fill_rotations(&[None, None])
                .iter()
                .all(|q| *q == DQuat::IDENTITY)
        );
    }
}
