//! Hand-made articulated bodies with known joints, for the tests.

use glam::{DQuat, DVec3};
use mocap_io::Trajectories;

use crate::PairFit;
use crate::horn::tests::TestRng;

/// How a body moves relative to its parent.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Articulation {
    /// Random axis, angle up to the given degrees.
    Ball(f64),
    /// Fixed axis (parent-local), angle in ±degrees.
    Hinge(DVec3, f64),
    /// No relative motion.
    Rigid,
}

/// A body: parent, joint in parent-local and own-local coordinates, marker positions.
pub(crate) struct Body {
    pub parent: Option<usize>,
    pub joint_in_parent: DVec3,
    pub joint_in_self: DVec3,
    pub articulation: Articulation,
    pub markers: Vec<DVec3>,
}

/// A generated trial: trajectories, segmentation, true joint positions per body (global, mm).
pub(crate) struct Trial {
    pub traj: Trajectories,
    /// Marker indices per body (the true segmentation).
    pub segments: Vec<Vec<usize>>,
    /// `joints[i][f]`: global centre of the joint between body i and its parent.
    pub joints: Vec<Vec<DVec3>>,
    /// `axes[i][f]`: global hinge axis of body i's joint.
    pub axes: Vec<Vec<DVec3>>,
}

/// A chain of bodies, each marker set placed around a point 250 mm from the joint.
pub(crate) fn chain(
    rng: &mut TestRng,
    articulations: &[Articulation],
    markers: usize,
) -> Vec<Body> {
    let mut bodies = Vec::new();
    for i in 0..=articulations.len() {
        let centre = DVec3::new(0.0, 0.0, -250.0);
        let pts = (0..markers).map(|_| centre + rng.vec3(60.0)).collect();
        bodies.push(Body {
            parent: i.checked_sub(1),
            joint_in_parent: DVec3::new(0.0, 0.0, -500.0),
            joint_in_self: DVec3::ZERO,
            articulation: if i == 0 {
                Articulation::Rigid
            } else {
                articulations[i - 1]
            },
            markers: pts,
        });
    }
    bodies
}

/// Poses every body for `frames` random frames; `noise_mm` Gaussian per coordinate;
/// `missing(frame, body, marker)` removes samples.
pub(crate) fn generate(
    rng: &mut TestRng,
    bodies: &[Body],
    frames: usize,
    noise_mm: f64,
    missing: impl Fn(usize, usize, usize) -> bool,
) -> Trial {
    let total: usize = bodies.iter().map(|b| b.markers.len()).sum();
    let mut positions = Vec::with_capacity(frames * total);
    let mut joints = vec![Vec::new(); bodies.len()];
    let mut axes = vec![Vec::new(); bodies.len()];
    for f in 0..frames {
        let mut pose: Vec<(DQuat, DVec3)> = Vec::new();
        for (i, body) in bodies.iter().enumerate() {
            let (q, t) = match body.parent {
                None => (rng.rotation(), rng.vec3(1000.0)),
                Some(p) => {
                    let (qp, tp) = pose[p];
                    let (rel, axis) = match body.articulation {
                        Articulation::Ball(deg) => {
                            let axis = rng.vec3(1.0).try_normalize().unwrap_or(DVec3::X);
                            (
                                DQuat::from_axis_angle(axis, rng.next_f64() * deg.to_radians()),
                                DVec3::X,
                            )
                        }
                        Articulation::Hinge(axis, deg) => (
                            DQuat::from_axis_angle(axis, rng.sym() * deg.to_radians()),
                            axis,
                        ),
                        Articulation::Rigid => (DQuat::IDENTITY, DVec3::X),
                    };
                    let j = qp * body.joint_in_parent + tp;
                    joints[i].push(j);
                    axes[i].push(qp * axis);
                    let q = qp * rel;
                    (q, j - q * body.joint_in_self)
                }
            };
            pose.push((q, t));
        }
        for (i, body) in bodies.iter().enumerate() {
            let (q, t) = pose[i];
            for (k, m) in body.markers.iter().enumerate() {
                let noise = DVec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * noise_mm;
                positions.push(if missing(f, i, k) {
                    mocap_io::MISSING
                } else {
                    (q * *m + t + noise).to_array()
                });
            }
        }
    }
    let labels = (0..total).map(|i| format!("M{i}")).collect();
    let traj = Trajectories::new(labels, 100.0, 1, frames, positions).expect("valid trajectories");
    let mut next = 0;
    let segments = bodies
        .iter()
        .map(|b| {
            let markers = (next..next + b.markers.len()).collect();
            next += b.markers.len();
            markers
        })
        .collect();
    Trial {
        traj,
        segments,
        joints,
        axes,
    }
}

/// A pair fit between segments a < b, centres and residual given, nothing else.
pub(crate) fn point_fit(a: usize, b: usize, centres: [[f64; 3]; 2], residual: f64) -> PairFit {
    PairFit {
        a,
        b,
        method: "test".into(),
        cost: residual,
        centre_in_a: centres[0],
        centre_in_b: centres[1],
        positions: Vec::new(),
        kind: crate::JointKind::Ball,
        axis_in_a: None,
        axis_in_b: None,
        universal_axes: None,
        residual_rms_mm: residual,
        frames_used: 100,
        rotation_rms_deg: 30.0,
        rotation_max_deg: 60.0,
        wobble_deg: [10.0; 3],
        evidence: String::new(),
        centre_from_distances: false,
        seeded: false,
        posed_through: None,
        next_best_anchor: None,
        first_pass_kind: None,
        misfit_over_noise: f64::NAN,
    }
}
