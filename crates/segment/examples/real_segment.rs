//! Segments a real capture and prints the groups by label.
//!
//! `cargo run --release -p segment --example real_segment PATH [key=value ...]`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((path, traj)) = common::capture_from_args(&args, "real_segment PATH [key=value ...]")
    else {
        return;
    };
    let params = common::params_from_overrides(args.iter().skip(1));
    let traj = &traj;
    let start = std::time::Instant::now();
    let seg = segment::run(traj, &params).expect("segmentation");
    let labels = traj.labels();
    println!(
        "{path}: {} frames, {} markers, {} missing samples; {:.1} ms",
        traj.frames(),
        traj.markers(),
        traj.missing_samples(),
        start.elapsed().as_secs_f64() * 1e3
    );
    println!(
        "noise {:.2} mm, tolerance {:.2} mm, eigen-gap k {}",
        seg.noise_mm, seg.tolerance_mm, seg.eigengap_segments
    );
    let ev: Vec<String> = seg
        .eigenvalues
        .iter()
        .take(25)
        .map(|v| format!("{v:.3}"))
        .collect();
    println!("eigenvalues {}", ev.join(" "));
    let bodies = segment::independent_bodies(traj, &params).expect("bodies");
    if bodies.len() > 1 {
        let sizes: Vec<String> = bodies.iter().map(|b| b.len().to_string()).collect();
        println!(
            "{} bodies segmented apart, of {} markers",
            bodies.len(),
            sizes.join(", ")
        );
    }
    for s in &seg.segments {
        let names: Vec<String> = s
            .markers
            .iter()
            .map(|&m| {
                let d = &seg.markers[m];
                format!(
                    "{}({:.1}{})",
                    labels[m],
                    d.rigidity_residual_mm,
                    if d.slides { ",slides" } else { "" }
                )
            })
            .collect();
        println!("segment {:>2}: {}", s.id, names.join(" "));
    }
    // The joint test's weighed cut of every segment of >= 6 markers: on a real capture
    // these are the scores one rigid body (or one the test failed to cut) reaches.
    let clusters: Vec<Vec<usize>> = seg.segments.iter().map(|s| s.markers.clone()).collect();
    let sigma = segment::typical_fit_sigma(traj, &clusters);
    for s in &seg.segments {
        if let Some((a, b, e)) = segment::joint_split_candidate(traj, &s.markers, sigma, &params) {
            let names = |p: &[usize]| {
                p.iter()
                    .map(|&m| labels[m].as_str())
                    .collect::<Vec<_>>()
                    .join(",")
            };
            println!(
                "cut {:>2}: {} [{}] | [{}]",
                s.id,
                common::evidence_line(&e, sigma),
                names(&a),
                names(&b)
            );
        }
    }
    for u in &seg.unassigned {
        println!("unassigned {}: {}", labels[u.marker], u.reason);
    }
}
