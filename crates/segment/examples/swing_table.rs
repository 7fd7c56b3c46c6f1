//! The swing test's evidence in synthetic trials: every marker the segmentation leaves
//! alone or unassigned, fitted to a sphere in the frame of each found segment of ≥ 3
//! markers, with whether its true segment has it alone and whether that segment is a
//! true neighbour of the one fitted against.
//!
//! `MARKERS=1:3 cargo run --release -p segment --example swing_table SUBJECTS PRESET FRAMES SEEDS...`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let set = common::trial_set_from_args(&args);
    let params = segment::Params::default();
    for trial in set.trials() {
        let traj = &trial.trajectories;
        let truth = common::true_segment_of(&trial);
        let Ok(seg) = segment::run(traj, &params) else {
            continue;
        };
        let tolerance = seg.tolerance_mm;
        let true_size = |s: usize| truth.iter().filter(|&&t| t == s).count();
        let adjacent = |a: usize, b: usize| {
            trial.truth.joints.iter().any(|j| {
                (j.parent_segment == a && j.child_segment == b)
                    || (j.parent_segment == b && j.child_segment == a)
            })
        };
        let lone: Vec<usize> = seg
            .unassigned
            .iter()
            .map(|u| u.marker)
            .chain(
                seg.segments
                    .iter()
                    .filter(|s| s.markers.len() == 1)
                    .map(|s| s.markers[0]),
            )
            .collect();
        for &m in &lone {
            let t = truth[m];
            for s in seg.segments.iter().filter(|s| s.markers.len() >= 3) {
                // The body's true segment: its markers' majority.
                let mut votes = std::collections::BTreeMap::new();
                for &x in &s.markers {
                    *votes.entry(truth[x]).or_insert(0) += 1;
                }
                let body = votes
                    .iter()
                    .max_by_key(|(_, v)| **v)
                    .map(|(k, _)| *k)
                    .unwrap_or(0);
                if let Some(w) = segment::marker_swing(traj, &s.markers, m) {
                    println!(
                        "{:24} m{m:3} alone {} adjacent {} res {:6.2} spread {:7.2} radius {:8.1} tol {:5.2} r/tol {:6.2} spread/res {:7.1}",
                        trial.truth.name,
                        (true_size(t) == 1) as u8,
                        adjacent(t, body) as u8,
                        w.residual_mm,
                        w.spread_mm,
                        w.radius_mm,
                        tolerance,
                        w.residual_mm / tolerance,
                        w.spread_mm / w.residual_mm
                    );
                }
            }
        }
    }
}
