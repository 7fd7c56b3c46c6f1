//! Props beside a subject: rigid objects that move on their own (a ball, a box pushed
//! about, a second tracked object), which no joint joins to the subject and which the
//! pipeline must leave the subject's segments as they are for.

use glam::{DQuat, DVec3};
use mocap_io::Trajectories;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::Error;

/// Markers on each prop.
pub const PROP_MARKERS: usize = 4;

/// `t` with `count` props appended after its markers, labelled `PROP<p>_<k>`: each a rigid
/// body of [`PROP_MARKERS`] markers 40–100 mm from its centre, the centre swinging
/// 300–1200 mm along each horizontal axis and 100–400 mm up and down (at 0.1–0.5 Hz) about
/// a point within 1.5 m across of the subject's mean position and 0.5–1.5 m up, turning
/// about a fixed axis at 0.3–1.5 rad/s, each coordinate with 0.5 mm of bell-shaped noise,
/// seen in every frame. Same `t` and `seed` → the same props. Fails only where `t` already
/// has such a label.
pub fn with_props(t: &Trajectories, count: usize, seed: u64) -> Result<Trajectories, Error> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut sum, mut seen) = (DVec3::ZERO, 0usize);
    for f in 0..t.frames() {
        for p in t
            .frame(f)
            .iter()
            .filter(|p| p.iter().all(|c| c.is_finite()))
        {
            sum += DVec3::from_array(*p);
            seen += 1;
        }
    }
    let middle = if seen > 0 {
        sum / seen as f64
    } else {
        DVec3::ZERO
    };
    let rate = if t.frame_rate() > 0.0 {
        t.frame_rate()
    } else {
        120.0
    };
    let mut range = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let props: Vec<Prop> = (0..count)
        .map(|_| {
            let offsets = std::array::from_fn(|_| {
                let dir = DVec3::new(range(-1.0, 1.0), range(-1.0, 1.0), range(-1.0, 1.0));
                dir.normalize_or(DVec3::X) * range(40.0, 100.0)
            });
            let mut home = middle + DVec3::new(range(-1500.0, 1500.0), range(-1500.0, 1500.0), 0.0);
            home.z = range(500.0, 1500.0);
            let axis = DVec3::new(range(-1.0, 1.0), range(-1.0, 1.0), range(-1.0, 1.0));
            Prop {
                offsets,
                home,
                amplitude: DVec3::new(
                    range(300.0, 1200.0),
                    range(300.0, 1200.0),
                    range(100.0, 400.0),
                ),
                hz: DVec3::new(range(0.1, 0.5), range(0.1, 0.5), range(0.1, 0.5)),
                phase: DVec3::new(range(0.0, 6.3), range(0.0, 6.3), range(0.0, 6.3)),
                axis: axis.normalize_or(DVec3::Z),
                spin: range(0.3, 1.5),
            }
        })
        .collect();
    let mut labels = t.labels().to_vec();
    for p in 0..count {
        labels.extend((0..PROP_MARKERS).map(|k| format!("PROP{p}_{k}")));
    }
    let mut positions = Vec::with_capacity(t.frames() * labels.len());
    for f in 0..t.frames() {
        positions.extend_from_slice(t.frame(f));
        let time = f as f64 / rate;
        for prop in &props {
            let centre = prop.centre(time);
            let turn = DQuat::from_axis_angle(prop.axis, prop.spin * time);
            for offset in prop.offsets {
                // A sum of uniforms: bell-shaped, σ 0.5 mm.
                let mut noise = || (0..3).map(|_| range(-0.5, 0.5)).sum::<f64>();
                let p = centre + turn * offset + DVec3::new(noise(), noise(), noise());
                positions.push(p.to_array());
            }
        }
    }
    Ok(Trajectories::new(
        labels,
        t.frame_rate(),
        t.first_frame(),
        t.frames(),
        positions,
    )?)
}

/// One prop's shape and path.
struct Prop {
    /// Its markers in its own frame, mm.
    offsets: [DVec3; PROP_MARKERS],
    /// The point its centre drifts about, mm.
    home: DVec3,
    /// How far its centre drifts per axis, mm.
    amplitude: DVec3,
    /// How fast per axis, Hz.
    hz: DVec3,
    /// Phase per axis, radians.
    phase: DVec3,
    /// The axis it turns about.
    axis: DVec3,
    /// How fast it turns, rad/s.
    spin: f64,
}

impl Prop {
    /// Its centre at `time` seconds, mm.
    fn centre(&self, time: f64) -> DVec3 {
        let tau = std::f64::consts::TAU;
        let wave = |a: f64, hz: f64, phase: f64| a * (tau * hz * time + phase).sin();
        self.home
            + DVec3::new(
                wave(self.amplitude.x, self.hz.x, self.phase.x),
                wave(self.amplitude.y, self.hz.y, self.phase.y),
                wave(self.amplitude.z, self.hz.z, self.phase.z),
            )
    }
}
