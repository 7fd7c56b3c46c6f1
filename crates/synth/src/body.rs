//! Articulated bodies: segments with a bone, joints with a kind and range of motion.
//!
//! Every segment has a local frame. At rest all local frames are parallel to the global
//! frame (Z up, X the subject's forward, Y its left), so bones, joint offsets and hinge
//! axes are written in rest-pose coordinates. A non-root segment's origin is its parent
//! joint's centre; the root's origin is the root position driven by the motion.

use glam::{DQuat, DVec3, EulerRot};

/// How a joint rotates its child segment relative to its parent.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum JointKind {
    /// Three rotations, `Rz(z)·Ry(y)·Rx(x)` about the parent's local axes; `limits` are
    /// degrees `[x, y, z]`, with the y limits inside (−90°, 90°) so the angles are unique.
    Ball { limits: [[f64; 2]; 3] },
    /// One rotation about `axis` (unit, parent's local frame); `limits` in degrees.
    Hinge { axis: DVec3, limits: [f64; 2] },
    /// Two rotations about perpendicular unit axes, `R(axes[0], a)·R(axes[1], b)`: the
    /// first fixed in the parent's frame, the second in the child's (a Hooke or Cardan
    /// joint); `limits` in degrees, one per axis.
    Universal {
        axes: [DVec3; 2],
        limits: [[f64; 2]; 2],
    },
}

impl JointKind {
    /// A ball joint with limits in degrees about x, y, z.
    pub(crate) fn ball(x: [f64; 2], y: [f64; 2], z: [f64; 2]) -> Self {
        JointKind::Ball { limits: [x, y, z] }
    }
    /// A hinge about a (not necessarily unit) axis in the parent's frame, limits in degrees.
    pub(crate) fn hinge(axis: [f64; 3], limits: [f64; 2]) -> Self {
        JointKind::Hinge {
            axis: DVec3::from(axis).normalize(),
            limits,
        }
    }
    /// A universal joint about `first` (parent's frame) then `second` (child's), made
    /// perpendicular to `first`; limits in degrees.
    pub(crate) fn universal(
        first: [f64; 3],
        second: [f64; 3],
        first_limits: [f64; 2],
        second_limits: [f64; 2],
    ) -> Self {
        let a = DVec3::from(first).normalize();
        let b = DVec3::from(second);
        let b = (b - a * a.dot(b)).normalize();
        JointKind::Universal {
            axes: [a, b],
            limits: [first_limits, second_limits],
        }
    }
    /// "ball", "hinge" or "universal", as in the truth file.
    pub(crate) fn name(&self) -> &'static str {
        match self {
            JointKind::Ball { .. } => "ball",
            JointKind::Hinge { .. } => "hinge",
            JointKind::Universal { .. } => "universal",
        }
    }
    /// Range of motion per degree of freedom, degrees.
    pub(crate) fn limits(&self) -> Vec<[f64; 2]> {
        match self {
            JointKind::Ball { limits } => limits.to_vec(),
            JointKind::Hinge { limits, .. } => vec![*limits],
            JointKind::Universal { limits, .. } => limits.to_vec(),
        }
    }
    /// The child's rotation relative to the parent for angles in degrees (one per DOF).
    pub(crate) fn rotation(&self, angles_deg: &[f64]) -> DQuat {
        match self {
            JointKind::Ball { .. } => {
                let [x, y, z] = [0, 1, 2].map(|i| angles_deg.get(i).copied().unwrap_or(0.0));
                DQuat::from_euler(
                    EulerRot::ZYX,
                    z.to_radians(),
                    y.to_radians(),
                    x.to_radians(),
                )
            }
            JointKind::Hinge { axis, .. } => DQuat::from_axis_angle(
                *axis,
                angles_deg.first().copied().unwrap_or(0.0).to_radians(),
            ),
            JointKind::Universal { axes, .. } => {
                let [a, b] = [0, 1].map(|i| angles_deg.get(i).copied().unwrap_or(0.0));
                DQuat::from_axis_angle(axes[0], a.to_radians())
                    * DQuat::from_axis_angle(axes[1], b.to_radians())
            }
        }
    }
    /// The angles (degrees, one per DOF) of a relative rotation; inverse of [`Self::rotation`]
    /// for rotations it produced.
    pub(crate) fn angles(&self, rotation: DQuat) -> Vec<f64> {
        match self {
            JointKind::Ball { .. } => {
                let (z, y, x) = rotation.to_euler(EulerRot::ZYX);
                vec![x.to_degrees(), y.to_degrees(), z.to_degrees()]
            }
            JointKind::Hinge { axis, .. } => vec![angle_about(rotation, *axis).to_degrees()],
            JointKind::Universal { axes: [a, b], .. } => {
                // The second axis, fixed in the child, is turned only by the first rotation.
                let turned = rotation * *b;
                let first = a.dot(b.cross(turned)).atan2(b.dot(turned));
                let second = angle_about(DQuat::from_axis_angle(*a, -first) * rotation, *b);
                vec![first.to_degrees(), second.to_degrees()]
            }
        }
    }
    /// The same joint on the other side of the body (mirror y → −y).
    pub(crate) fn mirrored(&self) -> Self {
        let neg = |[lo, hi]: [f64; 2]| [-hi, -lo];
        match self {
            // M·Rx(a)·M = Rx(−a), M·Ry(a)·M = Ry(a), M·Rz(a)·M = Rz(−a) for M = diag(1, −1, 1).
            JointKind::Ball { limits } => JointKind::Ball {
                limits: [neg(limits[0]), limits[1], neg(limits[2])],
            },
            // A rotation axis is a pseudovector: it mirrors to −M·axis.
            JointKind::Hinge { axis, limits } => JointKind::Hinge {
                axis: DVec3::new(-axis.x, axis.y, -axis.z),
                limits: *limits,
            },
            JointKind::Universal { axes, limits } => JointKind::Universal {
                axes: axes.map(|a| DVec3::new(-a.x, a.y, -a.z)),
                limits: *limits,
            },
        }
    }
}

/// The angle (radians) of a rotation about a unit axis, for a rotation about that axis.
fn angle_about(rotation: DQuat, axis: DVec3) -> f64 {
    let q = if rotation.w < 0.0 {
        -rotation
    } else {
        rotation
    };
    let s = DVec3::new(q.x, q.y, q.z).dot(axis);
    2.0 * s.atan2(q.w)
}

/// A rigid segment: its bone (where markers go) and how far from it markers sit.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SegmentDef {
    /// Segment name, e.g. "l_thigh".
    pub name: String,
    /// Bone start and end in the segment's local frame, mm; markers are spread along it.
    pub bone: [DVec3; 2],
    /// Marker distance from the bone's line, mm, [min, max].
    pub radius: [f64; 2],
}

impl SegmentDef {
    /// A segment from a bone's two ends (mm, local frame) and a marker radius range (mm).
    pub(crate) fn new(name: impl Into<String>, start: DVec3, end: DVec3, radius: [f64; 2]) -> Self {
        Self {
            name: name.into(),
            bone: [start, end],
            radius,
        }
    }
    /// The same segment on the other side of the body.
    fn mirrored(&self, name: String) -> Self {
        Self {
            name,
            bone: self.bone.map(mirror),
            radius: self.radius,
        }
    }
}

/// A joint: where it sits on its parent and how it moves its child.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct JointDef {
    /// Joint name, e.g. "l_knee".
    pub name: String,
    /// Parent segment index.
    pub parent: usize,
    /// Child segment index (always greater than `parent`).
    pub child: usize,
    /// Joint centre in the parent's local frame, mm.
    pub offset: DVec3,
    /// Kind and range of motion.
    pub kind: JointKind,
}

/// How the whole body travels: forward speed, vertical bob or jumps, tilt.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RootStyle {
    /// Height of the root origin above the floor at rest, mm.
    pub height_mm: f64,
    /// Forward speed along the path, mm/s (path length is clamped to 0.5–4 m).
    pub speed_mm_s: f64,
    /// Vertical bob amplitude, mm, at `bob_hz`.
    pub bob_mm: f64,
    /// Bob frequency, Hz.
    pub bob_hz: f64,
    /// Jump height, mm (snowman), at `bob_hz`; 0 for no jumps.
    pub jump_mm: f64,
    /// Amplitude of the slow pitch and roll of the root, degrees.
    pub tilt_deg: f64,
}

/// An articulated tree; joint `j` is listed after the joint of its parent segment.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Body {
    /// Segments; index 0 is the root.
    pub segments: Vec<SegmentDef>,
    /// Joints, parents before children.
    pub joints: Vec<JointDef>,
    /// Height used to express errors as a percentage (see `Truth::height_mm`), mm.
    pub height_mm: f64,
    /// How the root travels.
    pub root: RootStyle,
}

/// Mirrors a rest-pose point or direction to the other side (y → −y).
pub(crate) fn mirror(v: DVec3) -> DVec3 {
    DVec3::new(v.x, -v.y, v.z)
}

impl Body {
    /// A body of one root segment.
    pub(crate) fn new(root: SegmentDef, style: RootStyle) -> Self {
        Self {
            segments: vec![root],
            joints: Vec::new(),
            height_mm: 0.0,
            root: style,
        }
    }

    /// Attaches a new segment to `parent` at `offset` (parent frame, mm); returns its index.
    pub(crate) fn attach(
        &mut self,
        parent: usize,
        joint: impl Into<String>,
        offset: DVec3,
        kind: JointKind,
        segment: SegmentDef,
    ) -> usize {
        let child = self.segments.len();
        self.segments.push(segment);
        self.joints.push(JointDef {
            name: joint.into(),
            parent,
            child,
            offset,
            kind,
        });
        child
    }

    /// Attaches a left-side chain and its mirror image; names start with "l_" / "r_".
    ///
    /// `chain` lists (joint name, offset in parent frame, kind, segment), each attached to
    /// the previous one, the first to `parent`. Returns the (left, right) segment indices.
    pub(crate) fn attach_pair(
        &mut self,
        parent: usize,
        chain: Vec<(&str, DVec3, JointKind, SegmentDef)>,
    ) -> (Vec<usize>, Vec<usize>) {
        let mut out = (Vec::new(), Vec::new());
        for (side, mirrored) in [("l_", false), ("r_", true)] {
            let mut at = parent;
            for (joint, offset, kind, seg) in &chain {
                let name = format!("{side}{}", seg.name);
                let (offset, kind, seg) = if mirrored {
                    (mirror(*offset), kind.mirrored(), seg.mirrored(name))
                } else {
                    let mut s = seg.clone();
                    s.name = name;
                    (*offset, kind.clone(), s)
                };
                at = self.attach(at, format!("{side}{joint}"), offset, kind, seg);
                if mirrored {
                    out.1.push(at);
                } else {
                    out.0.push(at);
                }
            }
        }
        out
    }

    /// Sets `height_mm` to the largest side of the rest pose's bounding box (bones and joints).
    pub(crate) fn set_height_from_rest_pose(&mut self) {
        let pose = self.pose(
            DQuat::IDENTITY,
            DVec3::ZERO,
            &vec![Vec::new(); self.joints.len()],
        );
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for (s, seg) in self.segments.iter().enumerate() {
            for p in seg.bone {
                let g = pose.origin[s] + pose.rot[s] * p;
                lo = lo.min(g);
                hi = hi.max(g);
            }
            lo = lo.min(pose.origin[s]);
            hi = hi.max(pose.origin[s]);
        }
        self.height_mm = (hi - lo).max_element();
    }

    /// Forward kinematics: every segment's global rotation and origin (mm).
    ///
    /// `angles[j]` holds joint `j`'s angles in degrees (empty = rest).
    pub(crate) fn pose(&self, root_rot: DQuat, root_pos: DVec3, angles: &[Vec<f64>]) -> Pose {
        let n = self.segments.len();
        let mut pose = Pose {
            rot: vec![DQuat::IDENTITY; n],
            origin: vec![DVec3::ZERO; n],
        };
        pose.rot[0] = root_rot;
        pose.origin[0] = root_pos;
        for (j, joint) in self.joints.iter().enumerate() {
            let parent_rot = pose.rot[joint.parent];
            let a = angles.get(j).map(Vec::as_slice).unwrap_or(&[]);
            pose.origin[joint.child] = pose.origin[joint.parent] + parent_rot * joint.offset;
            pose.rot[joint.child] = (parent_rot * joint.kind.rotation(a)).normalize();
        }
        pose
    }

    /// Index of the joint whose child is `segment` (None for the root).
    pub(crate) fn parent_joint(&self, segment: usize) -> Option<usize> {
        self.joints.iter().position(|j| j.child == segment)
    }
}

/// Global pose of every segment at one frame.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Pose {
    /// Local → global rotation per segment.
    pub rot: Vec<DQuat>,
    /// Local origin in global coordinates per segment, mm.
    pub origin: Vec<DVec3>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ball_angles_round_trip_through_rotation() {
        let k = JointKind::ball([-40.0, 40.0], [-80.0, 80.0], [-120.0, 120.0]);
        let a = vec![30.0, -70.0, 110.0];
        let back = k.angles(k.rotation(&a));
        for (x, y) in a.iter().zip(&back) {
            assert!((x - y).abs() < 1e-9, "{a:?} vs {back:?}");
        }
        // Rz·Ry·Rx order: a pure x rotation moves +Y toward +Z.
        let r = k.rotation(&[90.0, 0.0, 0.0]) * DVec3::Y;
        assert!((r - DVec3::Z).length() < 1e-12);
    }

    #[test]
    fn hinge_angle_round_trips_and_mirroring_reflects_motion() {
        let k = JointKind::hinge([0.3, 1.0, -0.2], [0.0, 150.0]);
        assert!((k.angles(k.rotation(&[137.0]))[0] - 137.0).abs() < 1e-9);
        let p = DVec3::new(10.0, 20.0, -30.0);
        // The mirrored hinge with the same angle moves the mirrored point to the mirror image.
        let left = k.rotation(&[25.0]) * p;
        let m = k.mirrored();
        assert!((mirror(left) - m.rotation(&[25.0]) * mirror(p)).length() < 1e-9);
        // A ball's x and z angles change sign in the mirror, and so do their limits.
        let b = JointKind::ball([-10.0, 30.0], [0.0, 1.0], [5.0, 20.0]);
        let left = b.rotation(&[25.0, -15.0, 40.0]) * p;
        let right = b.rotation(&[-25.0, -15.0, -40.0]) * mirror(p);
        assert!((mirror(left) - right).length() < 1e-9);
        assert_eq!(
            b.mirrored().limits(),
            vec![[-30.0, 10.0], [0.0, 1.0], [-20.0, -5.0]]
        );
        assert!(matches!(m, JointKind::Hinge { .. }));
    }

    #[test]
    fn universal_angles_round_trip_and_its_axes_keep_their_angle() {
        let k = JointKind::universal(
            [1.0, 0.2, 0.0],
            [0.0, 1.0, 0.3],
            [-60.0, 60.0],
            [-50.0, 50.0],
        );
        let JointKind::Universal { axes: [a, b], .. } = k else {
            unreachable!("built as universal")
        };
        assert!(a.dot(b).abs() < 1e-12, "axes made perpendicular");
        for angles in [[35.0, -20.0], [-55.0, 48.0], [0.0, 0.0], [10.0, 0.0]] {
            let r = k.rotation(&angles);
            let back = k.angles(r);
            for (x, y) in angles.iter().zip(&back) {
                assert!((x - y).abs() < 1e-9, "{angles:?} vs {back:?}");
            }
            // The child's axis stays square to the parent's: the joint's invariant.
            assert!(a.dot(r * b).abs() < 1e-12);
        }
        let p = DVec3::new(10.0, 20.0, -30.0);
        let left = k.rotation(&[25.0, -40.0]) * p;
        let right = k.mirrored().rotation(&[25.0, -40.0]) * mirror(p);
        assert!((mirror(left) - right).length() < 1e-9);
    }
}
