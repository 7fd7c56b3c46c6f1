//! A hand-made articulated body with exact poses and joint centres, for tests of this
//! crate and of the stages downstream (feature `testkit`). Not part of the stage.

use glam::{DQuat, DVec3, EulerRot};
use jointfit::{JointKind, PairFit, PairFits, SegmentPoses};
use mocap_io::Trajectories;
use segment::{MarkerDiagnostics, Segment, Segmentation};
use topo::{Topology, TreeJoint};

/// Everything the stages give for the body, with the truth.
pub struct Scene {
    /// Marker trajectories (mm), 3 markers per segment, labels `M000`…
    pub trajectories: Trajectories,
    /// Segments 0..4: 0 torso (root), 1 thigh, 2 shank, 3 head.
    pub segmentation: Segmentation,
    /// Exact poses and joint centres.
    pub fits: PairFits,
    /// Tree 0→1→2, 0→3; joints j1, j3, j2 (breadth-first).
    pub topology: Topology,
    /// True global joint centre per topology joint per frame (mm).
    pub truth: Vec<Vec<[f64; 3]>>,
}

/// Reference marker positions per segment in its local frame (centroid at the origin).
const MARKERS: [[[f64; 3]; 3]; 4] = [
    [[-60.0, -20.0, 0.0], [60.0, -20.0, 0.0], [0.0, 40.0, 0.0]],
    [
        [30.0, -10.0, 40.0],
        [-30.0, -10.0, -20.0],
        [0.0, 20.0, -20.0],
    ],
    [[25.0, 0.0, 30.0], [-25.0, 10.0, -10.0], [0.0, -10.0, -20.0]],
    [[40.0, 0.0, 0.0], [-20.0, 35.0, 0.0], [-20.0, -35.0, 0.0]],
];

/// Tree edges: (parent, child, centre in parent's frame, centre in child's frame).
const EDGES: [(usize, usize, [f64; 3], [f64; 3]); 3] = [
    (0, 1, [0.0, 0.0, -200.0], [0.0, 0.0, 150.0]),
    (0, 3, [0.0, 0.0, 180.0], [0.0, 0.0, -60.0]),
    (1, 2, [0.0, 0.0, -150.0], [0.0, 0.0, 120.0]),
];

/// Index of pair (a, b), a < b, among the 4 segments' pairs in lexicographic order.
fn pair_index(a: usize, b: usize) -> usize {
    [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
        .iter()
        .position(|&p| p == (a.min(b), a.max(b)))
        .unwrap_or(0)
}

/// The body moving for `frames` frames at `rate` Hz: a turning, travelling torso, a thigh
/// swinging as a ball joint, a knee hinge, a nodding head.
pub fn scene(frames: usize, rate: f64) -> Scene {
    let mut rotations = vec![vec![DQuat::IDENTITY; frames]; 4];
    let mut translations = vec![vec![DVec3::ZERO; frames]; 4];
    let mut truth = vec![vec![[0.0; 3]; frames]; 3];
    for f in 0..frames {
        let t = f as f64 / rate.max(1.0);
        let r0 = DQuat::from_euler(EulerRot::ZXY, 2.0 * t, 0.3 * (1.3 * t).sin(), 0.2 * t.cos());
        rotations[0][f] = r0;
        translations[0][f] = DVec3::new(400.0 * t, 50.0 * (2.0 * t).sin(), 1000.0);
        let relative = [
            DQuat::from_rotation_x(0.8 * (3.0 * t).sin())
                * DQuat::from_rotation_y(0.3 * (2.0 * t).cos()),
            DQuat::from_rotation_x(0.4 * (2.5 * t).sin()),
            DQuat::from_rotation_x(-(0.5 + 0.5 * (3.0 * t).sin())),
        ];
        for (e, &(p, c, in_p, in_c)) in EDGES.iter().enumerate() {
            let rc = rotations[p][f] * relative[e];
            let centre = rotations[p][f] * DVec3::from_array(in_p) + translations[p][f];
            rotations[c][f] = rc;
            translations[c][f] = centre - rc * DVec3::from_array(in_c);
            truth[e][f] = centre.to_array();
        }
    }

    let labels: Vec<String> = (0..12).map(|m| format!("M{m:03}")).collect();
    let mut positions = Vec::with_capacity(frames * 12);
    for f in 0..frames {
        for (s, markers) in MARKERS.iter().enumerate() {
            for m in markers {
                let p = rotations[s][f] * DVec3::from_array(*m) + translations[s][f];
                positions.push(p.to_array());
            }
        }
    }
    let trajectories = match Trajectories::new(labels, rate, 1, frames, positions) {
        Ok(t) => t,
        Err(e) => panic!("testkit trajectories: {e}"),
    };

    let poses = (0..4)
        .map(|s| SegmentPoses {
            segment: s,
            reference: MARKERS[s].to_vec(),
            rotations: rotations[s].iter().map(|q| q.to_array()).collect(),
            translations: translations[s].iter().map(|t| t.to_array()).collect(),
            rms_mm: vec![0.0; frames],
        })
        .collect();
    let mut pairs = Vec::new();
    for a in 0..4 {
        for b in a + 1..4 {
            let edge = EDGES.iter().position(|e| (e.0, e.1) == (a, b));
            let (in_a, in_b, positions, cost) = match edge {
                Some(e) => (EDGES[e].2, EDGES[e].3, truth[e].clone(), 1.0 + e as f64),
                None => ([0.0; 3], [0.0; 3], vec![[f64::NAN; 3]; frames], 50.0),
            };
            pairs.push(PairFit {
                a,
                b,
                method: "truth".into(),
                cost,
                centre_in_a: in_a,
                centre_in_b: in_b,
                positions,
                kind: if (a, b) == (1, 2) {
                    JointKind::Hinge
                } else {
                    JointKind::Ball
                },
                axis_in_a: ((a, b) == (1, 2)).then_some([1.0, 0.0, 0.0]),
                axis_in_b: ((a, b) == (1, 2)).then_some([1.0, 0.0, 0.0]),
                universal_axes: None,
                residual_rms_mm: 0.0,
                frames_used: frames,
                rotation_rms_deg: 20.0,
                rotation_max_deg: 40.0,
                wobble_deg: [0.0, 5.0, 5.0],
                evidence: "exact".into(),
                centre_from_distances: false,
                seeded: false,
                posed_through: None,
                next_best_anchor: None,
                first_pass_kind: None,
                misfit_over_noise: f64::NAN,
            });
        }
    }
    let fits = PairFits {
        frames,
        poses,
        pairs,
    };

    let segmentation = Segmentation {
        segments: (0..4)
            .map(|id| Segment {
                id,
                markers: (3 * id..3 * id + 3).collect(),
            })
            .collect(),
        unassigned: Vec::new(),
        markers: (0..12)
            .map(|m| MarkerDiagnostics {
                segment: Some(m / 3),
                visible_frames: frames,
                glitch_frames: 0,
                rigidity_residual_mm: 0.0,
                slides: false,
            })
            .collect(),
        noise_mm: 0.0,
        tolerance_mm: 1.0,
        eigenvalues: Vec::new(),
        scatter_smoothness: None,
        eigengap_segments: 4,
        swaps: Vec::new(),
        glitches: Vec::new(),
        near_joints: Vec::new(),
        labels: Vec::new(),
        named_segments: Vec::new(),
        pieces: Vec::new(),
        stationary_segment: None,
        bodies: Vec::new(),
    };

    let topology = Topology {
        root_segment: 0,
        joints: EDGES
            .iter()
            .enumerate()
            .map(|(e, &(p, c, _, _))| TreeJoint {
                name: format!("j{c}"),
                parent_segment: p,
                child_segment: c,
                pair: pair_index(p, c),
                parent_joint: (p != 0).then_some(0),
                cost: 1.0 + e as f64,
                runner_up: None,
                named: false,
            })
            .collect(),
        detached_segments: Vec::new(),
        notes: Vec::new(),
        bodies: Vec::new(),
        body: None,
    };
    Scene {
        trajectories,
        segmentation,
        fits,
        topology,
        truth,
    }
}
