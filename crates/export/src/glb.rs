//! skeleton.glb: the skeleton and its motion as one binary glTF 2.0 file, the format
//! Blender, three.js, Unity, Godot and web viewers import directly.
//!
//! The same hierarchy as the BVH: a root node (the root point, moving and turning with
//! the root segment), one node per joint (translation = the constant bone offset,
//! rotation = the joint's rotation per frame) and one node per End Site. A skin over
//! those nodes makes importers build an armature, and a mesh of one thin octahedral
//! bone per offset, each bound rigidly to the node it moves with, makes the skeleton
//! visible in any viewer. glTF's units are metres, so every length is divided by 1000;
//! glTF is Y-up by its specification, so a Z-up capture wants `export.y_up` (the same
//! axis change as the BVH and TRC).

use glam::{DQuat, DVec3};
use serde_json::{Value, json};

use crate::bvh::{Axes, children, end_site, held_root_translations, root_end_site};
use crate::{Error, Inputs, Params};

/// glTF lengths are metres; ours are millimetres.
const METRES_PER_MM: f64 = 0.001;
/// Width of a drawn bone as a share of its length.
const BONE_WIDTH: f64 = 0.08;
/// Where along a drawn bone it is widest, as a share of its length.
const BONE_WAIST: f64 = 0.2;
/// Bones shorter than this (m) are not drawn (coincident joints).
const SHORTEST_DRAWN_BONE: f64 = 0.001;

// glTF enumerations (glTF 2.0 specification, 5.1 and 5.11).
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const TRIANGLES: u32 = 4;

/// One node of the file: its name, parent node and constant translation (m, file axes).
struct Node {
    name: String,
    parent: Option<usize>,
    translation: DVec3,
}

/// Writes the GLB (see the module docs).
pub(crate) fn write(input: &Inputs<'_>, params: &Params) -> Result<Vec<u8>, Error> {
    let skel = input.skeleton;
    let children = children(skel)?;
    let n = skel.joints.len();
    let frames = skel.frame_count;
    let axes = Axes::new(params);
    let metres = |v: DVec3| axes.vector(v) * METRES_PER_MM;

    // Nodes: the root, the joints (node j + 1), then the End Sites.
    let mut nodes = vec![Node {
        name: skel.root_name.clone(),
        parent: None,
        translation: DVec3::ZERO,
    }];
    for joint in &skel.joints {
        nodes.push(Node {
            name: joint.name.clone(),
            parent: Some(joint.parent.map_or(0, |p| p + 1)),
            translation: metres(DVec3::from_array(joint.offset)),
        });
    }
    if children[n].is_empty() {
        nodes.push(Node {
            name: format!("{} end", skel.root_name),
            parent: Some(0),
            translation: metres(root_end_site(skel)),
        });
    }
    for (j, joint) in skel.joints.iter().enumerate() {
        if children[j].is_empty() {
            nodes.push(Node {
                name: format!("{} end", joint.name),
                parent: Some(j + 1),
                translation: metres(end_site(input, j)),
            });
        }
    }
    // Rest pose: every rotation the identity, the root point at the origin (the BVH's
    // rest pose); parents come before children.
    let mut rest = vec![DVec3::ZERO; nodes.len()];
    for i in 1..nodes.len() {
        rest[i] = nodes[i].parent.map_or(DVec3::ZERO, |p| rest[p]) + nodes[i].translation;
    }

    let mut bin = Binary::default();
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("ossify ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
    });
    let mut scene_nodes = vec![0];
    let mut node_json: Vec<Value> = nodes
        .iter()
        .map(|node| {
            let mut v = json!({"name": node.name});
            if node.translation != DVec3::ZERO {
                v["translation"] = json!(node.translation.to_array());
            }
            v
        })
        .collect();
    for (i, node) in nodes.iter().enumerate() {
        if let Some(p) = node.parent {
            push_child(&mut node_json[p], i);
        }
    }

    if let Some(mesh) = bones(&nodes, &rest) {
        // The mesh's node sits at the scene's top with no transform of its own, as the
        // specification asks of skinned meshes; the skin's joints are every other node.
        let skinned = nodes.len();
        let positions = bin.accessor_vec3(&mesh.positions, Some(ARRAY_BUFFER), true);
        let joints = bin.accessor_joints(&mesh.joints);
        let weights = bin.accessor_weights(mesh.positions.len());
        let indices = bin.accessor_indices(&mesh.indices);
        let inverse_bind = bin.accessor_translations_as_mat4(&rest);
        doc["meshes"] = json!([{
            "name": "bones",
            "primitives": [{
                "attributes": {"POSITION": positions, "JOINTS_0": joints, "WEIGHTS_0": weights},
                "indices": indices,
                "mode": TRIANGLES,
            }],
        }]);
        doc["skins"] = json!([{
            "name": skel.root_name,
            "inverseBindMatrices": inverse_bind,
            "skeleton": 0,
            "joints": (0..nodes.len()).collect::<Vec<_>>(),
        }]);
        node_json.push(json!({"name": "bones", "mesh": 0, "skin": 0}));
        scene_nodes.push(skinned);
    }

    if frames > 0 {
        doc["animations"] = json!([animation(
            input,
            axes,
            &held_root_translations(&skel.root_translations),
            &mut bin
        )]);
    }
    doc["nodes"] = Value::Array(node_json);
    doc["scenes"] = json!([{"name": skel.root_name, "nodes": scene_nodes}]);
    if !bin.bytes.is_empty() {
        doc["buffers"] = json!([{"byteLength": bin.bytes.len()}]);
        doc["bufferViews"] = Value::Array(std::mem::take(&mut bin.views));
        doc["accessors"] = Value::Array(std::mem::take(&mut bin.accessors));
    }
    let text = serde_json::to_vec(&doc)?;
    glb(text, bin.bytes)
}

fn push_child(node: &mut Value, child: usize) {
    match node.get_mut("children").and_then(Value::as_array_mut) {
        Some(list) => list.push(json!(child)),
        None => node["children"] = json!([child]),
    }
}

/// The animation: root translation and rotation, every joint's rotation, one key per
/// frame at `frame / rate` seconds, linear.
fn animation(
    input: &Inputs<'_>,
    axes: Axes,
    root_translations: &[DVec3],
    bin: &mut Binary,
) -> Value {
    let skel = input.skeleton;
    let times: Vec<f32> = (0..skel.frame_count)
        .map(|f| (f as f64 / skel.frame_rate) as f32)
        .collect();
    let time = bin.accessor_times(&times);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let mut add = |output: usize, node: usize, path: &str| {
        channels.push(json!({"sampler": samplers.len(), "target": {"node": node, "path": path}}));
        samplers.push(json!({"input": time, "output": output, "interpolation": "LINEAR"}));
    };
    let translations: Vec<DVec3> = root_translations
        .iter()
        .map(|&p| axes.vector(p) * METRES_PER_MM)
        .collect();
    add(
        bin.accessor_vec3(&translations, None, false),
        0,
        "translation",
    );
    add(
        bin.accessor_rotations(&skel.root_rotations, axes),
        0,
        "rotation",
    );
    for (j, joint) in skel.joints.iter().enumerate() {
        add(
            bin.accessor_rotations(&joint.local_rotations, axes),
            j + 1,
            "rotation",
        );
    }
    json!({"name": "capture", "samplers": samplers, "channels": channels})
}

/// The drawn bones: vertices at rest (m), the node each vertex moves with, triangles.
struct Bones {
    positions: Vec<DVec3>,
    joints: Vec<u16>,
    indices: Vec<u32>,
}

/// One octahedron from each node's parent to the node, bound to the parent (the bone
/// lies in the parent's child segment, so it turns with the parent's rotation); `None`
/// when there is nothing to draw.
fn bones(nodes: &[Node], rest: &[DVec3]) -> Option<Bones> {
    let mut mesh = Bones {
        positions: Vec::new(),
        joints: Vec::new(),
        indices: Vec::new(),
    };
    for (i, node) in nodes.iter().enumerate() {
        let Some(parent) = node.parent else { continue };
        let (head, tail) = (rest[parent], rest[i]);
        let length = head.distance(tail);
        let Ok(bound) = u16::try_from(parent) else {
            continue;
        };
        if length.is_nan() || length < SHORTEST_DRAWN_BONE {
            continue;
        }
        let along = (tail - head) / length;
        // (u, v, along) right-handed, so the waist runs counter-clockwise about the bone.
        let u = along.any_orthonormal_vector();
        let v = along.cross(u);
        let waist = head + along * (BONE_WAIST * length);
        let r = BONE_WIDTH * length;
        let first = mesh.positions.len() as u32;
        mesh.positions.extend([
            head,
            tail,
            waist + u * r,
            waist + v * r,
            waist - u * r,
            waist - v * r,
        ]);
        mesh.joints.extend([bound; 6]);
        for k in 0..4 {
            let (a, b) = (first + 2 + k, first + 2 + (k + 1) % 4);
            // Counter-clockwise seen from outside: the front faces.
            mesh.indices.extend([first, b, a, first + 1, a, b]);
        }
    }
    (!mesh.positions.is_empty()).then_some(mesh)
}

/// The binary chunk being built, with its buffer views and accessors.
#[derive(Default)]
struct Binary {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Binary {
    /// Appends one buffer view (4-byte aligned) holding `data`; gives its index.
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        while self.bytes.len() % 4 != 0 {
            self.bytes.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bytes.extend_from_slice(data);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, view: usize, component: u32, count: usize, kind: &str) -> usize {
        self.accessors.push(json!({
            "bufferView": view, "componentType": component, "count": count, "type": kind,
        }));
        self.accessors.len() - 1
    }

    fn floats(values: impl Iterator<Item = f32>) -> Vec<u8> {
        values.flat_map(f32::to_le_bytes).collect()
    }

    /// Keyframe times (s), with the bounds the specification requires of animation input.
    fn accessor_times(&mut self, times: &[f32]) -> usize {
        let view = self.view(&Self::floats(times.iter().copied()), None);
        let a = self.accessor(view, FLOAT, times.len(), "SCALAR");
        let (lo, hi) = (times.first().copied(), times.last().copied());
        self.accessors[a]["min"] = json!([lo.unwrap_or(0.0)]);
        self.accessors[a]["max"] = json!([hi.unwrap_or(0.0)]);
        a
    }

    /// Points as f32 VEC3; with `bounds`, their min and max (required of POSITION).
    fn accessor_vec3(&mut self, points: &[DVec3], target: Option<u32>, bounds: bool) -> usize {
        let f32s: Vec<f32> = points
            .iter()
            .flat_map(|p| p.to_array().map(|c| c as f32))
            .collect();
        let view = self.view(&Self::floats(f32s.iter().copied()), target);
        let a = self.accessor(view, FLOAT, points.len(), "VEC3");
        if bounds {
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for p in f32s.chunks_exact(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            self.accessors[a]["min"] = json!(lo);
            self.accessors[a]["max"] = json!(hi);
        }
        a
    }

    /// Unit quaternions `[x, y, z, w]` in the file's axes, each on the side of the one
    /// before it so that importers interpolating components (Blender) turn the short way.
    fn accessor_rotations(&mut self, rotations: &[[f64; 4]], axes: Axes) -> usize {
        let mut previous = DQuat::IDENTITY;
        let mut f32s = Vec::with_capacity(rotations.len() * 4);
        for r in rotations {
            let mut q = axes.rotation(DQuat::from_array(*r)).normalize();
            if q.dot(previous) < 0.0 {
                q = -q;
            }
            previous = q;
            f32s.extend(q.to_array().map(|c| c as f32));
        }
        let view = self.view(&Self::floats(f32s.into_iter()), None);
        self.accessor(view, FLOAT, rotations.len(), "VEC4")
    }

    fn accessor_joints(&mut self, joints: &[u16]) -> usize {
        let bytes: Vec<u8> = joints
            .iter()
            .flat_map(|&j| [j, 0, 0, 0])
            .flat_map(u16::to_le_bytes)
            .collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        self.accessor(view, UNSIGNED_SHORT, joints.len(), "VEC4")
    }

    /// Every vertex wholly bound to its first joint.
    fn accessor_weights(&mut self, count: usize) -> usize {
        let one = [1.0f32, 0.0, 0.0, 0.0];
        let view = self.view(
            &Self::floats((0..count).flat_map(|_| one)),
            Some(ARRAY_BUFFER),
        );
        self.accessor(view, FLOAT, count, "VEC4")
    }

    fn accessor_indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.accessor(view, UNSIGNED_INT, indices.len(), "SCALAR")
    }

    /// Inverse bind matrices of nodes whose rest transforms are pure translations:
    /// translations by minus each, column-major.
    fn accessor_translations_as_mat4(&mut self, rest: &[DVec3]) -> usize {
        let f32s = rest.iter().flat_map(|p| {
            let mut m = [0.0f32; 16];
            m[0] = 1.0;
            m[5] = 1.0;
            m[10] = 1.0;
            m[15] = 1.0;
            m[12] = -p.x as f32;
            m[13] = -p.y as f32;
            m[14] = -p.z as f32;
            m
        });
        let view = self.view(&Self::floats(f32s), None);
        self.accessor(view, FLOAT, rest.len(), "MAT4")
    }
}

/// The GLB container: a 12-byte header, the JSON chunk padded with spaces, the binary
/// chunk padded with zeros (glTF 2.0 specification, 4.4).
fn glb(mut text: Vec<u8>, mut bin: Vec<u8>) -> Result<Vec<u8>, Error> {
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let chunks = 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + chunks;
    // GLB lengths are 32-bit.
    let too_large = || Error::TooLarge {
        file: "skeleton.glb",
        bytes: total,
    };
    let total32 = u32::try_from(total).map_err(|_| too_large())?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    Ok(out)
}
