//! Times the segment stage on a generated 6000-frame × 70-marker capture (14 rigid bodies
//! of 5 markers in a chain, 0.5 mm noise, 10 % gaps).
//!
//! `cargo run --release -p segment --example bench_segment [frames] [bodies]`
#![allow(clippy::print_stdout)]

use std::time::Instant;

use mocap_io::{MISSING, Trajectories};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn rotate(axis: [f64; 3], angle: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let cross = [
        axis[1] * v[2] - axis[2] * v[1],
        axis[2] * v[0] - axis[0] * v[2],
        axis[0] * v[1] - axis[1] * v[0],
    ];
    let dot = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
    std::array::from_fn(|k| v[k] * c + cross[k] * s + axis[k] * dot * (1.0 - c))
}

fn capture(frames: usize, bodies: usize, per_body: usize) -> Trajectories {
    let mut rng = ChaCha8Rng::seed_from_u64(2006);
    let unit = |rng: &mut ChaCha8Rng| loop {
        let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 0.2 && n < 1.0 {
            return v.map(|x| x / n);
        }
    };
    let offsets: Vec<Vec<[f64; 3]>> = (0..bodies)
        .map(|_| {
            (0..per_body)
                .map(|_| {
                    let side = unit(&mut rng).map(|x| x * 50.0);
                    [side[0], side[1], side[2] - rng.random_range(50.0..250.0)]
                })
                .collect()
        })
        .collect();
    let axes: Vec<[f64; 3]> = (0..bodies).map(|_| unit(&mut rng)).collect();
    let rates: Vec<f64> = (0..bodies).map(|_| rng.random_range(0.01..0.05)).collect();
    let markers = bodies * per_body;
    let mut positions = Vec::with_capacity(frames * markers);
    for f in 0..frames {
        let mut origin = [0.0, 0.0, 1500.0];
        let mut rots: Vec<([f64; 3], f64)> = Vec::new();
        for b in 0..bodies {
            rots.push((axes[b], 0.8 * (rates[b] * f as f64).sin()));
            let apply = |v| {
                rots.iter()
                    .rev()
                    .fold(v, |acc, &(ax, an)| rotate(ax, an, acc))
            };
            for o in &offsets[b] {
                let p = apply(*o);
                if rng.random::<f64>() < 0.1 {
                    positions.push(MISSING);
                } else {
                    positions.push(std::array::from_fn(|k| {
                        origin[k] + p[k] + rng.random_range(-0.87..0.87)
                    }));
                }
            }
            let tip = apply([0.0, 0.0, -300.0]);
            origin = std::array::from_fn(|k| origin[k] + tip[k]);
        }
    }
    let labels = (0..markers).map(|m| format!("M{m:02}")).collect();
    Trajectories::new(labels, 120.0, 1, frames, positions).expect("generated capture is valid")
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let frames = args.first().copied().unwrap_or(6000);
    let bodies = args.get(1).copied().unwrap_or(14);
    let traj = capture(frames, bodies, 5);
    // SEG_JOINT_Z overrides joint_split_z (0 = the joint test off), to time it.
    let params = segment::Params {
        joint_split_z: std::env::var("SEG_JOINT_Z")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(segment::Params::default().joint_split_z),
        ..segment::Params::default()
    };
    let mut times = Vec::new();
    let mut result = None;
    for _ in 0..5 {
        let start = Instant::now();
        result = Some(segment::run(&traj, &params).expect("segmentation"));
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let seg = result.expect("ran");
    println!(
        "segment: {} frames × {} markers: median {:.1} ms (min {:.1}, max {:.1}) over 5 runs; {} segments, {} unassigned, rayon threads {}",
        frames,
        traj.markers(),
        times[2],
        times[0],
        times[4],
        seg.segments.len(),
        seg.unassigned.len(),
        rayon::current_num_threads()
    );
}
