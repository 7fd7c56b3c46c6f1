//! Small deterministic captures for the unit tests: rigid bodies hinged about the x axis,
//! wandering through space, with a smooth jitter standing in for noise.

use mocap_io::Trajectories;

/// Markers of a parent body above the hinge (mm; the axis is x through the origin).
pub(crate) const PARENT: [[f64; 3]; 4] = [
    [30.0, 0.0, 100.0],
    [-25.0, 20.0, 200.0],
    [10.0, -30.0, 300.0],
    [-20.0, -15.0, 150.0],
];

/// Markers of a child body below the hinge (mm).
pub(crate) const CHILD: [[f64; 3]; 4] = [
    [20.0, 25.0, -100.0],
    [-30.0, 5.0, -200.0],
    [15.0, -25.0, -300.0],
    [-10.0, 30.0, -250.0],
];

/// Seconds per frame of every scene (the shapes only care about the phase).
const STEP: f64 = 0.05;

/// `p` turned by `angle` (rad) about the x axis through (0, 0, `pivot_z`).
pub(crate) fn hinge_x(angle: f64, p: [f64; 3], pivot_z: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let z = p[2] - pivot_z;
    [p[0], c * p[1] - s * z, s * p[1] + c * z + pivot_z]
}

/// A capture of `markers` markers over `frames` frames at 100 Hz, labels `M0`…: marker `k`
/// at frame `f` is `place(t, k)` (t = 0.05 f, seconds of the scene's own clock) carried by
/// a translation that wanders with t, plus a jitter of amplitude `jitter_mm` per coordinate
/// that is smooth in no way the fits could mistake for motion.
pub(crate) fn moving_capture(
    markers: usize,
    frames: usize,
    jitter_mm: f64,
    place: impl Fn(f64, usize) -> [f64; 3],
) -> Trajectories {
    let mut positions = Vec::with_capacity(markers * frames);
    for f in 0..frames {
        let t = f as f64 * STEP;
        let shift = [100.0 * t.sin(), 50.0 * t.cos(), 1000.0];
        for k in 0..markers {
            let q = place(t, k);
            let jitter = |axis: usize| jitter_mm * ((f * 7 + k * 13 + axis * 5) as f64).sin();
            positions.push(std::array::from_fn(|i| q[i] + shift[i] + jitter(i)));
        }
    }
    let labels: Vec<String> = (0..markers).map(|m| format!("M{m}")).collect();
    match Trajectories::new(labels, 100.0, 1, frames, positions) {
        Ok(traj) => traj,
        Err(e) => panic!("test scene: {e}"),
    }
}

/// `parent` fixed and `child` hinged about the x axis through the origin, swinging
/// ±`swing_deg` as sin(0.7 t): parent markers first, then child markers.
pub(crate) fn hinged_capture(
    parent: &[[f64; 3]],
    child: &[[f64; 3]],
    frames: usize,
    swing_deg: f64,
    jitter_mm: f64,
) -> Trajectories {
    let n = parent.len();
    moving_capture(n + child.len(), frames, jitter_mm, |t, k| {
        if k < n {
            parent[k]
        } else {
            hinge_x(swing_deg.to_radians() * (0.7 * t).sin(), child[k - n], 0.0)
        }
    })
}

/// `parent` fixed and `child` hinged about the x axis through the origin, swinging
/// ±`swing_deg` as sin(0.7 t) over 400 frames at t = 0.04 f, all translating (parent
/// markers first, labels `M0`…); each marker carries smooth skin of up to `skin_mm` swept
/// with the joint angle, half its body's direction and half its own (as the generator's
/// skin), and uniform ±0.5 mm noise, drawn from `seed`.
pub(crate) fn skin_hinged_capture(
    parent: &[[f64; 3]],
    child: &[[f64; 3]],
    swing_deg: f64,
    skin_mm: f64,
    seed: u64,
) -> Trajectories {
    use rand::{Rng, SeedableRng};
    let split = parent.len();
    let n = split + child.len();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut unit = || {
        let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
        v.map(|x| x / n)
    };
    let shared = [unit(), unit()];
    let dirs: Vec<[f64; 3]> = (0..n)
        .map(|k| {
            let own = unit();
            std::array::from_fn(|i| 0.5 * shared[usize::from(k >= split)][i] + 0.5 * own[i])
        })
        .collect();
    let frames = 400;
    let mut positions = Vec::new();
    for f in 0..frames {
        let t = f as f64 * 0.04;
        let drive = (0.7 * t).sin();
        let (s, c) = (swing_deg.to_radians() * drive).sin_cos();
        let shift = [150.0 * (0.3 * t).sin(), 80.0 * (0.2 * t).cos(), 900.0];
        for (k, p) in parent.iter().chain(child.iter()).enumerate() {
            let q = if k >= split {
                [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]]
            } else {
                *p
            };
            let noise: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.5..0.5));
            positions.push(std::array::from_fn(|i| {
                q[i] + shift[i] + skin_mm * drive * dirs[k][i] + noise[i]
            }));
        }
    }
    let labels: Vec<String> = (0..n).map(|m| format!("M{m}")).collect();
    match Trajectories::new(labels, 100.0, 1, frames, positions) {
        Ok(traj) => traj,
        Err(e) => panic!("test scene: {e}"),
    }
}

/// `traj` with marker `m` hidden over frames `gap` and seen after it only as a new marker
/// (appended, labelled `M…~1`), as an unlabeled reconstruction cuts a marker at an occlusion.
pub(crate) fn cut_at_gap(
    traj: &Trajectories,
    m: usize,
    gap: std::ops::Range<usize>,
) -> Trajectories {
    let n = traj.markers();
    let mut labels = traj.labels().to_vec();
    labels.push(format!("{}~1", labels[m]));
    let missing = [f64::NAN; 3];
    let mut positions = Vec::with_capacity(traj.frames() * (n + 1));
    for f in 0..traj.frames() {
        let frame = traj.frame(f);
        let (before, after) = (f < gap.start, f >= gap.end);
        for (k, &p) in frame.iter().enumerate() {
            positions.push(if k != m || before { p } else { missing });
        }
        positions.push(if after { frame[m] } else { missing });
    }
    match Trajectories::new(labels, traj.frame_rate(), 1, traj.frames(), positions) {
        Ok(cut) => cut,
        Err(e) => panic!("cut capture: {e}"),
    }
}
