//! Read speed of the C3D parser: a 6000-frame, 70-marker float file made by our writer
//! (seeded), and the integer AlbertoINT.c3d from the shared data when it is present.
//!
//! Run: `cargo bench -p mocap-io --bench read_c3d`. Prints MB/s (file bytes / parse time,
//! best of N) on stderr.

use std::time::{Duration, Instant};

use mocap_io::{ReadOptions, Trajectories, c3d};

/// SplitMix64, seeded: the same file every run.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// 70 markers circling at their own speeds, with about 2 % of samples missing.
fn capture(frames: usize, markers: usize, seed: u64) -> Trajectories {
    let mut rng = Rng(seed);
    let phases: Vec<(f64, f64, f64)> = (0..markers)
        .map(|_| {
            (
                rng.unit() * 6.3,
                0.5 + rng.unit() * 2.0,
                200.0 + rng.unit() * 1500.0,
            )
        })
        .collect();
    let mut positions = Vec::with_capacity(frames * markers);
    for f in 0..frames {
        let t = f as f64 / 120.0;
        for &(phase, speed, height) in &phases {
            if rng.unit() < 0.02 {
                positions.push(mocap_io::MISSING);
            } else {
                let a = phase + speed * t;
                positions.push([
                    400.0 * a.cos(),
                    400.0 * a.sin(),
                    height + 30.0 * (3.0 * a).sin(),
                ]);
            }
        }
    }
    let labels = (0..markers).map(|m| format!("M{m:02}")).collect();
    Trajectories::new(labels, 120.0, 1, frames, positions).expect("valid synthetic capture")
}

/// Best parse time over `runs` runs (at least 1 s of work), in MB/s of file bytes.
fn measure(name: &str, bytes: &[u8], runs: usize) {
    let options = ReadOptions::default();
    let mut best = Duration::MAX;
    let start = Instant::now();
    let mut n = 0;
    while n < runs || start.elapsed() < Duration::from_secs(1) {
        let t0 = Instant::now();
        let capture = c3d::parse(std::hint::black_box(bytes), &options).expect("bench file parses");
        best = best.min(t0.elapsed());
        std::hint::black_box(capture);
        n += 1;
    }
    let mb = bytes.len() as f64 / 1e6;
    eprintln!(
        "{name}: {mb:.1} MB, best of {n}: {:.2} ms = {:.0} MB/s",
        best.as_secs_f64() * 1e3,
        mb / best.as_secs_f64()
    );
}

fn main() {
    let dir = std::env::temp_dir().join("ossify-bench-read-c3d");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("float_6000x70.c3d");
    let t = capture(6000, 70, 0x0551_f7c3d);
    std::fs::write(&path, c3d::write(&t).expect("writer")).expect("write temp file");
    let bytes = std::fs::read(&path).expect("read temp file");
    measure(
        "float, 6000 frames x 70 markers (Intel, written by ossify)",
        &bytes,
        20,
    );

    if let Some(shared) = mocap_io::testdata::shared_data_dir("read_c3d bench (integer file)") {
        let int_path = shared.join("c3d/c3d.org/sample34/AlbertoINT.c3d");
        if let Ok(bytes) = std::fs::read(int_path) {
            measure(
                "integer, 4921 frames x 40 markers (AlbertoINT.c3d)",
                &bytes,
                20,
            );
        }
        if let Ok(bytes) = std::fs::read(shared.join("c3d/c3d.org/sample00/arthuman-sample.c3d")) {
            measure(
                "float, 4007 frames x 63 markers (arthuman-sample.c3d)",
                &bytes,
                20,
            );
        }
    }
}
