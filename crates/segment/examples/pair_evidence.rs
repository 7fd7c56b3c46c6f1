//! The joint test's evidence between every two final segments of ≥ 3 markers of a capture
//! that the rigid merge weighs (z below 8), as the merge sees them.
//!
//! `cargo run --release -p segment --example pair_evidence PATH [key=value ...]`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((_, traj)) = common::capture_from_args(&args, "pair_evidence PATH [key=value ...]")
    else {
        return;
    };
    let params = common::params_from_overrides(args.iter().skip(1));
    let traj = &traj;
    let seg = segment::run(traj, &params).expect("segmentation");
    let clusters: Vec<Vec<usize>> = seg.segments.iter().map(|s| s.markers.clone()).collect();
    let sigma = segment::typical_fit_sigma(traj, &clusters);
    for (i, a) in clusters.iter().enumerate() {
        for (j, b) in clusters.iter().enumerate().skip(i + 1) {
            if a.len() < 3 || b.len() < 3 {
                continue;
            }
            if let Some(e) = segment::joint_evidence(traj, a, b, sigma)
                && e.rotation_z < 8.0
            {
                println!("{i:>2} + {j:>2}: {}", common::evidence_line(&e, sigma));
            }
        }
    }
}
