//! skeleton.bvh: hierarchy with the skeleton's offsets, motion as ZXY Euler angles.

use std::f64::consts::FRAC_PI_2;
use std::fmt::Write;

use glam::{DQuat, DVec3, EulerRot};

use crate::{Error, Inputs, Params};

/// BVH rotation channel order; `EulerRot::ZXY` is the same intrinsic order (R = Rz·Rx·Ry).
const ROTATION_CHANNELS: &str = "Zrotation Xrotation Yrotation";
const EULER: EulerRot = EulerRot::ZXY;

/// Writes the BVH (see the crate docs).
pub(crate) fn write(input: &Inputs<'_>, params: &Params) -> Result<Vec<u8>, Error> {
    let skel = input.skeleton;
    let children = children(skel)?;
    let n = skel.joints.len();
    let frames = skel.frame_count;
    let axes = Axes::new(params);
    let vector = |v: DVec3| axes.vector(v);
    let rotation = |q: DQuat| axes.rotation(q);

    let mut out = String::new();
    out.push_str("HIERARCHY\n");
    let _ = writeln!(out, "ROOT {}", skel.root_name);
    out.push_str("{\n\tOFFSET 0.000000 0.000000 0.000000\n");
    let _ = writeln!(
        out,
        "\tCHANNELS 6 Xposition Yposition Zposition {ROTATION_CHANNELS}"
    );
    if children[n].is_empty() {
        // Strict readers want every branch to end in a joint or an End Site: a root
        // without joints ends at its own segment's marker centroid (the frame's origin).
        let end = root_end_site(skel);
        let _ = writeln!(
            out,
            "\tEnd Site\n\t{{\n\t\tOFFSET {}\n\t}}",
            triple(vector(end))
        );
    }
    let mut order = Vec::with_capacity(n);
    // Depth-first, children in skeleton order: the MOTION column order.
    let mut stack: Vec<(usize, usize)> = children[n].iter().rev().map(|&c| (c, 1)).collect();
    let mut open: Vec<usize> = Vec::new(); // depths of open JOINT braces
    while let Some((j, depth)) = stack.pop() {
        while open.last().is_some_and(|&d| d >= depth) {
            let d = open.pop().unwrap_or(0);
            let _ = writeln!(out, "{}}}", tabs(d));
        }
        let joint = &skel.joints[j];
        order.push(j);
        let t = tabs(depth);
        let _ = writeln!(out, "{t}JOINT {}\n{t}{{", joint.name);
        let _ = writeln!(
            out,
            "{t}\tOFFSET {}",
            triple(vector(DVec3::from_array(joint.offset)))
        );
        let _ = writeln!(out, "{t}\tCHANNELS 3 {ROTATION_CHANNELS}");
        open.push(depth);
        if children[j].is_empty() {
            let end = end_site(input, j);
            let _ = writeln!(
                out,
                "{t}\tEnd Site\n{t}\t{{\n{t}\t\tOFFSET {}\n{t}\t}}",
                triple(vector(end))
            );
        }
        stack.extend(children[j].iter().rev().map(|&c| (c, depth + 1)));
    }
    while let Some(d) = open.pop() {
        let _ = writeln!(out, "{}}}", tabs(d));
    }
    out.push_str("}\nMOTION\n");
    let _ = writeln!(out, "Frames: {frames}");
    let _ = writeln!(out, "Frame Time: {}", 1.0 / skel.frame_rate);

    let root_translations = held_root_translations(&skel.root_translations);
    for (f, &root_translation) in root_translations.iter().enumerate() {
        let p = vector(root_translation);
        let _ = write!(out, "{}", triple(p));
        let q = rotation(DQuat::from_array(skel.root_rotations[f]));
        let _ = write!(out, " {}", euler_degrees(q));
        for &j in &order {
            let q = rotation(DQuat::from_array(skel.joints[j].local_rotations[f]));
            let _ = write!(out, " {}", euler_degrees(q));
        }
        out.push('\n');
    }
    Ok(out.into_bytes())
}

/// Checks that the skeleton can be written (a frame rate, parents before children, one
/// rotation and position per frame everywhere) and gives each joint's children; index
/// `joints.len()` stands for the root.
pub(crate) fn children(skel: &bonefit::Skeleton) -> Result<Vec<Vec<usize>>, Error> {
    if !(skel.frame_rate.is_finite() && skel.frame_rate > 0.0) {
        return Err(Error::BadFrameRate {
            rate: skel.frame_rate,
        });
    }
    let n = skel.joints.len();
    let frames = skel.frame_count;
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n + 1];
    for (j, joint) in skel.joints.iter().enumerate() {
        let parent = match joint.parent {
            Some(p) if p < j => p,
            None => n,
            Some(p) => {
                return Err(Error::Mismatch(format!(
                    "joint {} has parent index {p}, not an earlier joint",
                    joint.name
                )));
            }
        };
        children[parent].push(j);
        if joint.local_rotations.len() != frames || joint.positions.len() != frames {
            return Err(Error::Mismatch(format!(
                "joint {} has {} rotations for {frames} frames",
                joint.name,
                joint.local_rotations.len()
            )));
        }
    }
    if skel.root_positions.len() != frames
        || skel.root_translations.len() != frames
        || skel.root_rotations.len() != frames
    {
        return Err(Error::Mismatch(format!(
            "the root has {} positions, {} translations and {} rotations for {frames} frames",
            skel.root_positions.len(),
            skel.root_translations.len(),
            skel.root_rotations.len()
        )));
    }
    Ok(children)
}

/// The axis change of the animation files: none, or Z-up → Y-up with `export.y_up`
/// (a rotation of −90° about X: (x, y, z) → (x, z, −y)).
#[derive(Clone, Copy)]
pub(crate) struct Axes(Option<DQuat>);

impl Axes {
    pub(crate) fn new(params: &Params) -> Self {
        Self(params.y_up.then(|| DQuat::from_rotation_x(-FRAC_PI_2)))
    }

    /// A point or direction in the file's axes.
    pub(crate) fn vector(self, v: DVec3) -> DVec3 {
        self.0.map_or(v, |a| a * v)
    }

    /// A rotation in the file's axes (the same turn, seen in the new frame).
    pub(crate) fn rotation(self, q: DQuat) -> DQuat {
        self.0.map_or(q, |a| a * q * a.inverse())
    }
}

fn tabs(depth: usize) -> String {
    "\t".repeat(depth)
}

/// Three numbers with 6 decimals, no negative zero.
fn triple(v: DVec3) -> String {
    let c = |x: f64| if x.abs() < 5e-7 { 0.0 } else { x };
    format!("{:.6} {:.6} {:.6}", c(v.x), c(v.y), c(v.z))
}

/// A rotation as the ZXY channel values in degrees.
pub(crate) fn euler_degrees(q: DQuat) -> String {
    let (z, x, y) = q.normalize().to_euler(EULER);
    triple(DVec3::new(z.to_degrees(), x.to_degrees(), y.to_degrees()))
}

/// The leaf's End Site: from the joint toward the child segment's marker centroid (the
/// origin of its local frame), in the child's rest frame; if that is under 1 mm, a
/// quarter of the bone, continuing its direction.
pub(crate) fn end_site(input: &Inputs<'_>, j: usize) -> DVec3 {
    let joint = &input.skeleton.joints[j];
    let centre_in_child = input
        .fits
        .pairs
        .get(joint.pair)
        .map(|p| DVec3::from_array(p.centre_in(joint.child_segment)));
    match centre_in_child
        .map(|c| -c)
        .filter(|e| e.is_finite() && e.length() >= 1.0)
    {
        Some(e) => e,
        None => DVec3::from_array(joint.offset) * 0.25,
    }
}

/// The End Site of a root without joints: its own segment's marker centroid (the
/// origin of the root segment's frame), from the root point.
pub(crate) fn root_end_site(skel: &bonefit::Skeleton) -> DVec3 {
    let end = -DVec3::from_array(skel.root_point_in_segment);
    if end.is_finite() { end } else { DVec3::ZERO }
}

/// Root translations (`Skeleton::root_translations`) with NaN frames holding the last
/// finite one (the first finite one before it; the origin if never finite).
pub(crate) fn held_root_translations(translations: &[[f64; 3]]) -> Vec<DVec3> {
    let finite = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
    let mut last = translations
        .iter()
        .find(|p| finite(p))
        .map_or(DVec3::ZERO, |p| DVec3::from_array(*p));
    translations
        .iter()
        .map(|p| {
            if finite(p) {
                last = DVec3::from_array(*p);
            }
            last
        })
        .collect()
}
