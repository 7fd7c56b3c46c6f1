//! The subjects: articulated trees with joint kinds and ranges of motion.
//!
//! Proportions vary with the seed (overall scale and per-segment lengths), the structure
//! does not, except for `random` (everything random) and `hexapod` (2 or 3 leg segments).
//! Every hinge axis is perpendicular, or nearly, to its child's bone, so the markers
//! sweep arcs around the joint and its centre is recoverable up to the hinge's own line.

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::Subject;
use crate::body::{Body, JointKind, RootStyle, SegmentDef};

/// Builds the body of a subject from the body random stream.
pub(crate) fn build(subject: Subject, rng: &mut ChaCha8Rng) -> Body {
    match subject {
        Subject::Human => human(rng),
        Subject::Quadruped => quadruped(rng),
        Subject::Robotarm => robotarm(rng),
        Subject::Snowman => snowman(rng),
        Subject::Hexapod => hexapod(rng),
        Subject::Random => random_tree(rng),
        Subject::Snake => snake(rng),
    }
}

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// A human facing +X, 1750 mm ± 10 %, proportions after Winter's anthropometric table.
fn human(rng: &mut ChaCha8Rng) -> Body {
    let h = 1750.0 * rng.random_range(0.9..1.1);
    // Each long bone varies ±4 % on its own, so no two subjects share proportions.
    let mut len = |fraction: f64| fraction * h * rng.random_range(0.96..1.04);
    let (abdomen, thorax, head) = (len(0.10), len(0.14), len(0.13));
    let (clavicle, upperarm, forearm, hand) = (len(0.10), len(0.186), len(0.146), len(0.108));
    let (thigh, shank, foot) = (len(0.245), len(0.246), len(0.15));
    let ball = JointKind::ball;
    let hinge = JointKind::hinge;
    let seg = SegmentDef::new;
    let style = RootStyle {
        height_mm: shank + thigh + 0.03 * h + 0.045 * h,
        speed_mm_s: 1200.0,
        bob_mm: 25.0,
        bob_hz: 2.0,
        jump_mm: 0.0,
        tilt_deg: 5.0,
    };
    let mut b = Body::new(
        seg(
            "pelvis",
            v(0.0, -0.09 * h, 0.0),
            v(0.0, 0.09 * h, 0.0),
            [30.0, 80.0],
        ),
        style,
    );
    let abd = b.attach(
        0,
        "lumbar",
        v(0.0, 0.0, 0.05 * h),
        ball([-20.0, 20.0], [-15.0, 40.0], [-30.0, 30.0]),
        seg("abdomen", DVec3::ZERO, v(0.0, 0.0, abdomen), [40.0, 80.0]),
    );
    let tho = b.attach(
        abd,
        "thoracic",
        v(0.0, 0.0, abdomen),
        ball([-20.0, 20.0], [-15.0, 35.0], [-35.0, 35.0]),
        seg("thorax", DVec3::ZERO, v(0.0, 0.0, thorax), [50.0, 80.0]),
    );
    b.attach(
        tho,
        "neck",
        v(0.0, 0.0, thorax),
        ball([-35.0, 35.0], [-40.0, 50.0], [-70.0, 70.0]),
        seg(
            "head",
            v(0.0, 0.0, 0.2 * head),
            v(0.1 * head, 0.0, head),
            [30.0, 70.0],
        ),
    );
    b.attach_pair(
        tho,
        vec![
            (
                "sternoclavicular",
                v(0.02 * h, 0.015 * h, 0.85 * thorax),
                ball([-10.0, 35.0], [-25.0, 25.0], [-25.0, 25.0]),
                seg(
                    "clavicle",
                    DVec3::ZERO,
                    v(-0.2 * clavicle, clavicle, 0.1 * clavicle),
                    [30.0, 60.0],
                ),
            ),
            (
                "shoulder",
                v(-0.2 * clavicle, clavicle, 0.1 * clavicle),
                ball([-10.0, 100.0], [-85.0, 40.0], [-60.0, 60.0]),
                seg(
                    "upperarm",
                    DVec3::ZERO,
                    v(0.0, 0.0, -upperarm),
                    [35.0, 80.0],
                ),
            ),
            (
                "elbow",
                v(0.0, 0.0, -upperarm),
                hinge([0.0, -1.0, 0.0], [0.0, 140.0]),
                seg("forearm", DVec3::ZERO, v(0.0, 0.0, -forearm), [30.0, 70.0]),
            ),
            (
                "wrist",
                v(0.0, 0.0, -forearm),
                ball([-20.0, 35.0], [-70.0, 70.0], [-15.0, 15.0]),
                seg("hand", DVec3::ZERO, v(0.0, 0.0, -hand), [30.0, 60.0]),
            ),
        ],
    );
    b.attach_pair(
        0,
        vec![
            (
                "hip",
                v(0.0, 0.05 * h, -0.03 * h),
                ball([-20.0, 40.0], [-85.0, 20.0], [-40.0, 40.0]),
                seg("thigh", DVec3::ZERO, v(0.0, 0.0, -thigh), [40.0, 80.0]),
            ),
            (
                "knee",
                v(0.0, 0.0, -thigh),
                hinge([0.0, 1.0, 0.0], [0.0, 130.0]),
                seg("shank", DVec3::ZERO, v(0.0, 0.0, -shank), [35.0, 80.0]),
            ),
            (
                // The talocrural axis runs slightly oblique to the lateral direction.
                "ankle",
                v(0.0, 0.0, -shank),
                hinge([0.15, 1.0, -0.1], [-40.0, 25.0]),
                seg(
                    "foot",
                    v(-0.2 * foot, 0.0, -0.5 * foot * 0.3),
                    v(0.8 * foot, 0.0, -foot * 0.22),
                    [30.0, 60.0],
                ),
            ),
        ],
    );
    b.height_mm = h;
    b
}

/// A dog-like quadruped facing +X, shoulder height about 550 mm ± 15 %.
fn quadruped(rng: &mut ChaCha8Rng) -> Body {
    let k = rng.random_range(0.85..1.15);
    let mut j = |x: f64| x * k * rng.random_range(0.95..1.05);
    let (chest, neck, head, tail1, tail2) = (j(400.0), j(190.0), j(180.0), j(200.0), j(200.0));
    let (fore_up, fore_lo, fore_paw) = (j(230.0), j(220.0), j(80.0));
    let (hind_up, hind_lo, hind_paw) = (j(225.0), j(215.0), j(100.0));
    let ball = JointKind::ball;
    let hinge = JointKind::hinge;
    let seg = SegmentDef::new;
    let style = RootStyle {
        height_mm: hind_up + hind_lo + hind_paw + 30.0 * k,
        speed_mm_s: 1000.0,
        bob_mm: 20.0,
        bob_hz: 2.5,
        jump_mm: 0.0,
        tilt_deg: 5.0,
    };
    let mut b = Body::new(
        seg(
            "hindquarters",
            v(-120.0 * k, 0.0, 0.0),
            v(50.0 * k, 0.0, 0.0),
            [40.0, 90.0],
        ),
        style,
    );
    let ch = b.attach(
        0,
        "spine",
        v(50.0 * k, 0.0, 0.0),
        ball([-20.0, 20.0], [-25.0, 25.0], [-30.0, 30.0]),
        seg("chest", DVec3::ZERO, v(chest, 0.0, 0.0), [50.0, 100.0]),
    );
    let nk = b.attach(
        ch,
        "neck_base",
        v(chest + 20.0 * k, 0.0, 50.0 * k),
        ball([-25.0, 25.0], [-40.0, 30.0], [-40.0, 40.0]),
        seg(
            "neck",
            DVec3::ZERO,
            v(0.6 * neck, 0.0, 0.8 * neck),
            [30.0, 70.0],
        ),
    );
    b.attach(
        nk,
        "atlas",
        v(0.6 * neck, 0.0, 0.8 * neck),
        ball([-25.0, 25.0], [-35.0, 35.0], [-45.0, 45.0]),
        seg("head", DVec3::ZERO, v(head, 0.0, -0.2 * head), [30.0, 70.0]),
    );
    let t1 = b.attach(
        0,
        "tail_base",
        v(-130.0 * k, 0.0, 30.0 * k),
        ball([-40.0, 40.0], [-45.0, 35.0], [-45.0, 45.0]),
        seg(
            "tail_base",
            DVec3::ZERO,
            v(-tail1, 0.0, 0.1 * tail1),
            [20.0, 40.0],
        ),
    );
    b.attach(
        t1,
        "tail_mid",
        v(-tail1, 0.0, 0.1 * tail1),
        ball([-45.0, 45.0], [-45.0, 45.0], [-45.0, 45.0]),
        seg(
            "tail_tip",
            DVec3::ZERO,
            v(-tail2, 0.0, -0.1 * tail2),
            [20.0, 40.0],
        ),
    );
    b.attach_pair(
        ch,
        vec![
            (
                "shoulder",
                v(0.85 * chest, 100.0 * k, -40.0 * k),
                ball([-20.0, 25.0], [-45.0, 45.0], [-20.0, 20.0]),
                seg(
                    "fore_upper",
                    DVec3::ZERO,
                    v(0.0, 0.0, -fore_up),
                    [30.0, 60.0],
                ),
            ),
            (
                "elbow",
                v(0.0, 0.0, -fore_up),
                hinge([0.0, -1.0, 0.0], [0.0, 110.0]),
                seg(
                    "fore_lower",
                    DVec3::ZERO,
                    v(0.0, 0.0, -fore_lo),
                    [25.0, 50.0],
                ),
            ),
            (
                "carpus",
                v(0.0, 0.0, -fore_lo),
                hinge([0.0, 1.0, 0.0], [-20.0, 80.0]),
                seg(
                    "fore_paw",
                    DVec3::ZERO,
                    v(0.6 * fore_paw, 0.0, -0.8 * fore_paw),
                    [20.0, 40.0],
                ),
            ),
        ],
    );
    b.attach_pair(
        0,
        vec![
            (
                "hip",
                v(-60.0 * k, 90.0 * k, -30.0 * k),
                ball([-20.0, 25.0], [-50.0, 40.0], [-20.0, 20.0]),
                seg(
                    "hind_upper",
                    DVec3::ZERO,
                    v(0.18 * hind_up, 0.0, -hind_up),
                    [30.0, 60.0],
                ),
            ),
            (
                "stifle",
                v(0.18 * hind_up, 0.0, -hind_up),
                hinge([0.0, 1.0, 0.0], [0.0, 110.0]),
                seg(
                    "hind_lower",
                    DVec3::ZERO,
                    v(-0.28 * hind_lo, 0.0, -hind_lo),
                    [25.0, 50.0],
                ),
            ),
            (
                "hock",
                v(-0.28 * hind_lo, 0.0, -hind_lo),
                hinge([0.0, -1.0, 0.0], [-20.0, 80.0]),
                seg(
                    "hind_paw",
                    DVec3::ZERO,
                    v(0.3 * hind_paw, 0.0, -0.95 * hind_paw),
                    [20.0, 40.0],
                ),
            ),
        ],
    );
    b.set_height_from_rest_pose();
    b
}

/// A robot's mobile base (a 120 mm upright segment gliding level, no bob or tilt), and
/// its height (mm), where the first link attaches.
fn mobile_base() -> (Body, f64) {
    let base = 120.0;
    let style = RootStyle {
        height_mm: 100.0,
        speed_mm_s: 300.0,
        bob_mm: 0.0,
        bob_hz: 1.0,
        jump_mm: 0.0,
        tilt_deg: 0.0,
    };
    let body = Body::new(
        SegmentDef::new("base", DVec3::ZERO, v(0.0, 0.0, base), [50.0, 90.0]),
        style,
    );
    (body, base)
}

/// Link `k` of a robot's chain: a straight upright bone `length` mm long.
fn link(k: usize, length: f64) -> SegmentDef {
    SegmentDef::new(
        format!("link{k}"),
        DVec3::ZERO,
        v(0.0, 0.0, length),
        [30.0, 60.0],
    )
}

/// A six-link arm on a mobile base; every hinge axis is horizontal at rest, perpendicular
/// to the vertical links, and turns 45–135° from the previous one.
fn robotarm(rng: &mut ChaCha8Rng) -> Body {
    let (mut b, base) = mobile_base();
    let mut heading = rng.random_range(0.0..std::f64::consts::TAU);
    let mut at = 0;
    let mut offset = v(0.0, 0.0, base);
    for k in 1..=6 {
        let length = rng.random_range(150.0..400.0);
        let width = rng.random_range(90.0..150.0);
        let centre = rng.random_range(-20.0..20.0);
        let axis = [heading.cos(), heading.sin(), 0.0];
        at = b.attach(
            at,
            format!("joint{k}"),
            offset,
            JointKind::hinge(axis, [centre - width / 2.0, centre + width / 2.0]),
            link(k, length),
        );
        offset = v(0.0, 0.0, length);
        let turn = rng.random_range(45f64..135.0).to_radians();
        heading += if rng.random_bool(0.5) { turn } else { -turn };
    }
    b.set_height_from_rest_pose();
    b
}

/// A serpentine manipulator on a mobile base: 5–7 links in a chain, each joined to the
/// last by a universal joint whose two axes lie across the link (the first fixed in the
/// lower link, the second in the upper), as in modular snake robots.
fn snake(rng: &mut ChaCha8Rng) -> Body {
    let (mut b, base) = mobile_base();
    let links = rng.random_range(5..=7);
    let mut at = 0;
    let mut offset = v(0.0, 0.0, base);
    for k in 1..=links {
        let length = rng.random_range(150.0..300.0);
        let heading = rng.random_range(0.0..std::f64::consts::PI);
        let mut range = || {
            let width = rng.random_range(70.0..110.0);
            let centre = rng.random_range(-15.0..15.0);
            [centre - width / 2.0, centre + width / 2.0]
        };
        let (first, second) = (range(), range());
        at = b.attach(
            at,
            format!("joint{k}"),
            offset,
            JointKind::universal(
                [heading.cos(), heading.sin(), 0.0],
                [-heading.sin(), heading.cos(), 0.0],
                first,
                second,
            ),
            link(k, length),
        );
        offset = v(0.0, 0.0, length);
    }
    b.set_height_from_rest_pose();
    b
}

/// The paper's jumping snowman: three stacked balls and stick arms; 1340 mm ± 10 %.
fn snowman(rng: &mut ChaCha8Rng) -> Body {
    let k = rng.random_range(0.9..1.1);
    let (rb, rm, rh) = (300.0 * k, 220.0 * k, 150.0 * k);
    let (arm, forearm) = (250.0 * k, 200.0 * k);
    let ball = JointKind::ball;
    let seg = SegmentDef::new;
    // Markers sit near the ball surfaces: a short vertical bone through the centre and
    // a radius close to the ball's.
    let ball_seg = |name: &str, centre: f64, r: f64| {
        SegmentDef::new(
            name.to_string(),
            v(0.0, 0.0, centre - 0.4 * r),
            v(0.0, 0.0, centre + 0.4 * r),
            [0.8 * r, 0.92 * r],
        )
    };
    let style = RootStyle {
        height_mm: rb,
        speed_mm_s: 600.0,
        bob_mm: 0.0,
        bob_hz: 1.0,
        jump_mm: 250.0,
        tilt_deg: 8.0,
    };
    let mut b = Body::new(ball_seg("bottom", 0.0, rb), style);
    let mid = b.attach(
        0,
        "waist",
        v(0.0, 0.0, rb),
        ball([-25.0, 25.0], [-25.0, 25.0], [-60.0, 60.0]),
        ball_seg("middle", rm, rm),
    );
    b.attach(
        mid,
        "neck",
        v(0.0, 0.0, 2.0 * rm),
        ball([-25.0, 25.0], [-30.0, 30.0], [-70.0, 70.0]),
        ball_seg("head", rh, rh),
    );
    b.attach_pair(
        mid,
        vec![
            (
                "shoulder",
                v(0.0, 0.9 * rm, rm),
                ball([-30.0, 60.0], [-40.0, 40.0], [-45.0, 45.0]),
                seg("arm", DVec3::ZERO, v(0.0, arm, 0.0), [20.0, 40.0]),
            ),
            (
                "elbow",
                v(0.0, arm, 0.0),
                JointKind::hinge([0.0, 0.0, 1.0], [0.0, 110.0]),
                seg("forearm", DVec3::ZERO, v(0.0, forearm, 0.0), [20.0, 40.0]),
            ),
        ],
    );
    b.height_mm = 2.0 * (rb + rm + rh);
    b
}

/// A hexapod: an oval body and six legs splayed 60°, 90° and 120° from forward; the
/// legs swing ±22° about the vertical so neighbours do not cross.
fn hexapod(rng: &mut ChaCha8Rng) -> Body {
    let k = rng.random_range(0.85..1.15);
    let three = rng.random_bool(0.5);
    let style = RootStyle {
        height_mm: 120.0 * k,
        speed_mm_s: 250.0,
        bob_mm: 10.0,
        bob_hz: 2.0,
        jump_mm: 0.0,
        tilt_deg: 4.0,
    };
    let mut b = Body::new(
        SegmentDef::new(
            "body",
            v(-150.0 * k, 0.0, 0.0),
            v(150.0 * k, 0.0, 0.0),
            [40.0, 80.0],
        ),
        style,
    );
    for (i, (x, splay)) in [(120.0, 60.0f64), (0.0, 90.0), (-120.0, 120.0)]
        .into_iter()
        .enumerate()
    {
        for (side, sign) in [("l", 1.0), ("r", -1.0)] {
            let a = (sign * splay).to_radians();
            let out = v(a.cos(), a.sin(), 0.0);
            // Horizontal, perpendicular to the leg: the axis of the femur and tibia hinges.
            let lift = DVec3::Z.cross(out);
            let femur = out * 110.0 * k + v(0.0, 0.0, 70.0 * k);
            let tibia = out * 60.0 * k + v(0.0, 0.0, -170.0 * k);
            let leg = format!("{side}{}", i + 1);
            let mount = v(x * k, sign * 75.0 * k, 0.0);
            let seg = |part: &str, bone: DVec3| {
                SegmentDef::new(format!("{leg}_{part}"), DVec3::ZERO, bone, [20.0, 40.0])
            };
            let f = if three {
                let coxa = out * 70.0 * k;
                let c = b.attach(
                    0,
                    format!("{leg}_coxa_joint"),
                    mount,
                    JointKind::hinge([0.0, 0.0, 1.0], [-22.0, 22.0]),
                    seg("coxa", coxa),
                );
                b.attach(
                    c,
                    format!("{leg}_femur_joint"),
                    coxa,
                    JointKind::hinge(lift.to_array(), [-40.0, 45.0]),
                    seg("femur", femur),
                )
            } else {
                b.attach(
                    0,
                    format!("{leg}_hip"),
                    mount,
                    JointKind::ball([-30.0, 30.0], [-30.0, 30.0], [-22.0, 22.0]),
                    seg("femur", femur),
                )
            };
            b.attach(
                f,
                format!("{leg}_tibia_joint"),
                femur,
                JointKind::hinge(lift.to_array(), [-25.0, 55.0]),
                seg("tibia", tibia),
            );
        }
    }
    b.set_height_from_rest_pose();
    b
}

/// A uniformly random unit vector.
fn unit(rng: &mut ChaCha8Rng) -> DVec3 {
    loop {
        let p = v(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = p.length();
        if (0.1..=1.0).contains(&l) {
            return p / l;
        }
    }
}

/// A random tree of 5–15 segments: branches anywhere on a parent bone, bones 50–600 mm.
fn random_tree(rng: &mut ChaCha8Rng) -> Body {
    let n = rng.random_range(5..=15usize);
    let style = RootStyle {
        height_mm: 800.0,
        speed_mm_s: 500.0,
        bob_mm: 20.0,
        bob_hz: 1.5,
        jump_mm: 0.0,
        tilt_deg: 10.0,
    };
    let root_dir = unit(rng);
    let root_len = rng.random_range(50.0..600.0);
    let mut b = Body::new(
        SegmentDef::new("seg00", DVec3::ZERO, root_dir * root_len, [30.0, 80.0]),
        style,
    );
    for i in 1..n {
        let parent = rng.random_range(0..i);
        let [start, end] = b.segments[parent].bone;
        let t = if rng.random_bool(0.6) {
            1.0
        } else {
            rng.random_range(0.3..1.0)
        };
        let offset = start + (end - start) * t;
        let parent_dir = (end - start).normalize_or_zero();
        // Bones do not fold straight back onto their parent.
        let dir = loop {
            let d = unit(rng);
            if d.dot(parent_dir) > -0.5 {
                break d;
            }
        };
        let length = rng.random_range(50.0..600.0);
        let kind = if rng.random_bool(0.5) {
            let mut w = || rng.random_range(30.0..60.0);
            let (x, y, z) = (w(), w(), w());
            JointKind::ball([-x, x], [-y, y], [-z, z])
        } else {
            // An axis perpendicular to the child's bone.
            let axis = loop {
                let a = unit(rng);
                let p = a - dir * a.dot(dir);
                if p.length() > 0.3 {
                    break p.normalize();
                }
            };
            let width = rng.random_range(90.0..150.0);
            let centre = rng.random_range(-30.0..30.0);
            JointKind::hinge(
                axis.to_array(),
                [centre - width / 2.0, centre + width / 2.0],
            )
        };
        b.attach(
            parent,
            format!("joint{i:02}"),
            offset,
            kind,
            SegmentDef::new(
                format!("seg{i:02}"),
                DVec3::ZERO,
                dir * length,
                [30.0, 80.0],
            ),
        );
    }
    b.set_height_from_rest_pose();
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn subjects_have_their_documented_structure() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let human = build(Subject::Human, &mut rng);
        assert_eq!(human.segments.len(), 18);
        assert!((1575.0..=1925.0).contains(&human.height_mm));
        let kinds = |b: &Body, name: &str| {
            b.joints
                .iter()
                .find(|j| j.name == name)
                .map(|j| j.kind.name())
        };
        assert_eq!(kinds(&human, "l_knee"), Some("hinge"));
        assert_eq!(kinds(&human, "r_elbow"), Some("hinge"));
        assert_eq!(kinds(&human, "l_hip"), Some("ball"));
        assert_eq!(kinds(&human, "r_shoulder"), Some("ball"));
        assert_eq!(kinds(&human, "neck"), Some("ball"));
        let quad = build(Subject::Quadruped, &mut rng);
        assert!(quad.segments.iter().any(|s| s.name.starts_with("tail")));
        for seed in 0..20 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let r = build(Subject::Random, &mut rng);
            assert!((5..=15).contains(&r.segments.len()));
            for s in &r.segments {
                let l = (s.bone[1] - s.bone[0]).length();
                assert!((50.0..=600.0).contains(&l), "{l}");
            }
            let h = build(Subject::Hexapod, &mut rng);
            assert!(h.segments.len() == 13 || h.segments.len() == 19);
        }
    }

    #[test]
    fn robot_and_snake_joint_axes_lie_across_their_links() {
        for seed in 0..10 {
            let arm = build(Subject::Robotarm, &mut ChaCha8Rng::seed_from_u64(seed));
            assert_eq!(arm.joints.len(), 6);
            for j in &arm.joints {
                let JointKind::Hinge { axis, .. } = j.kind else {
                    panic!("{} is not a hinge", j.name);
                };
                let [s, e] = arm.segments[j.child].bone;
                assert!(axis.dot((e - s).normalize()).abs() < 1e-12);
            }
            // The snake: a chain of 5-7 links, each on a universal joint whose two square
            // axes lie across its link.
            let snake = build(Subject::Snake, &mut ChaCha8Rng::seed_from_u64(seed));
            assert!((5..=7).contains(&snake.joints.len()));
            for (k, j) in snake.joints.iter().enumerate() {
                assert_eq!((j.parent, j.child), (k, k + 1));
                let JointKind::Universal { axes: [a, b], .. } = j.kind else {
                    panic!("{} is not universal", j.name);
                };
                let [s, e] = snake.segments[j.child].bone;
                let bone = (e - s).normalize();
                assert!(a.dot(b).abs() < 1e-12 && a.dot(bone).abs() < 1e-12);
                assert!(b.dot(bone).abs() < 1e-12);
            }
        }
    }
}
