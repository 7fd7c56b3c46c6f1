//! Prints, for one capture file, every segment (by its markers' labels) and the pairs
//! nearest the tree: cost, kind, motion, whether the tree chose it, so a real capture's
//! tree can be read against its marker names.
//!
//! `cargo run --release -p export --example real_pairs -- FILE [pairs per segment]`
#![allow(clippy::print_stdout)]

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        println!("usage: real_pairs FILE [pairs per segment]");
        return Ok(());
    };
    let per_segment: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(3);
    let capture = mocap_io::read_capture(path.as_ref(), &mocap_io::ReadOptions::default())?;
    let traj = &capture.trajectories;
    let seg = segment::run(traj, &segment::Params::default())?;
    let fits = jointfit::run(traj, &seg, &jointfit::Params::default())?;
    let topology = topo::run(&seg, &fits, &topo::Params::default())?;
    let labels = traj.labels();
    for s in &seg.segments {
        let names: Vec<&str> = s.markers.iter().map(|&m| labels[m].as_str()).collect();
        println!("seg{:<3} {}", s.id, names.join(" "));
    }
    println!("root {}", topology.root_segment);
    let chosen = |a: usize, b: usize| {
        topology.joints.iter().any(|j| {
            (j.parent_segment, j.child_segment) == (a, b)
                || (j.parent_segment, j.child_segment) == (b, a)
        })
    };
    let mut pairs: Vec<&jointfit::PairFit> = fits.pairs.iter().collect();
    pairs.sort_by(|x, y| x.cost.total_cmp(&y.cost));
    println!(
        "{:>3} {:>3} {:>10} {:>8} {:>6} {:>7} {:>7} {:>8} {:>7} {:>7}  evidence",
        "a", "b", "cost", "kind", "chosen", "rot-rms", "resid", "frames", "near-a", "near-b"
    );
    // Distance (mm) from a centre in a segment's frame to that segment's nearest marker.
    let nearest = |s: usize, c: [f64; 3]| {
        fits.poses[s]
            .reference
            .iter()
            .map(|r| ((r[0] - c[0]).powi(2) + (r[1] - c[1]).powi(2) + (r[2] - c[2]).powi(2)).sqrt())
            .filter(|d| d.is_finite())
            .fold(f64::INFINITY, f64::min)
    };
    for p in pairs.iter().take(per_segment * seg.segments.len()) {
        println!(
            "{:>3} {:>3} {:>10.4} {:>8} {:>6} {:>7.1} {:>7.2} {:>8} {:>7.0} {:>7.0}  {}",
            p.a,
            p.b,
            p.cost,
            format!("{:?}", p.kind),
            chosen(p.a, p.b),
            p.rotation_rms_deg,
            p.residual_rms_mm,
            p.frames_used,
            nearest(p.a, p.centre_in_a),
            nearest(p.b, p.centre_in_b),
            p.evidence.chars().take(60).collect::<String>()
        );
    }
    for n in &topology.notes {
        println!("note: {n}");
    }
    Ok(())
}
