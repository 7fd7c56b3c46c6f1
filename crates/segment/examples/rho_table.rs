//! Prints each marker's nearest neighbours in ρ (the standard deviation of the pair's
//! distance over the frames both are seen, mm), with ρ relative to the mean distance, to
//! see the scale of skin motion (within a segment) against joint motion (across one).
//!
//! `cargo run --release -p segment --example rho_table PATH [markers] [neighbours]`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((_, traj)) = common::capture_from_args(&args, "rho_table PATH [markers] [neighbours]")
    else {
        return;
    };
    let traj = &traj;
    let n = args
        .get(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(traj.markers())
        .min(traj.markers());
    let show: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(6);
    let (frames, stride) = (traj.frames(), traj.markers());
    let pos = traj.positions();
    let short = |l: &str| l.rsplit(':').next().unwrap_or(l).to_string();
    let labels: Vec<String> = traj.labels().iter().map(|l| short(l)).collect();
    for i in 0..n {
        let mut row: Vec<(f64, f64, usize)> = Vec::new();
        for j in 0..n {
            if i == j {
                continue;
            }
            let d: Vec<f64> = (0..frames)
                .filter_map(|f| {
                    let (a, b) = (pos[f * stride + i], pos[f * stride + j]);
                    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2))
                        .sqrt();
                    (!d.is_nan()).then_some(d)
                })
                .collect();
            if d.len() < 10 {
                continue;
            }
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64;
            row.push((var.sqrt(), mean, j));
        }
        row.sort_by(|a, b| a.0.total_cmp(&b.0));
        let cells: Vec<String> = row
            .iter()
            .take(show)
            .map(|(r, m, j)| format!("{}:{r:.1}/{:.0}", labels[*j], m))
            .collect();
        println!("{:<5} {}", labels[i], cells.join("  "));
    }
}
