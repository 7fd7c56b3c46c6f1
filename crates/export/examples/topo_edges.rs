//! Prints, for one synthetic trial, every pair near the tree: its cost, kind, motion and
//! whether it is a true joint and a chosen edge, so wrong trees can be diagnosed.
//!
//! `cargo run --release -p export --example topo_edges [-- subject preset seed frames markers]`
//! (markers per segment as `MIN:MAX`, default the generator's).
#![allow(clippy::print_stdout)]

use synth::{Preset, Subject, SynthConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let subject: Subject = args.get(1).map_or("random", |s| s.as_str()).parse()?;
    let preset: Preset = args.get(2).map_or("clean", |s| s.as_str()).parse()?;
    let seed = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1001);
    let frames = args.get(4).and_then(|a| a.parse().ok()).unwrap_or(480);
    let markers_per_segment = args
        .get(5)
        .and_then(|a| a.split_once(':'))
        .and_then(|(lo, hi)| Some((lo.parse().ok()?, hi.parse().ok()?)))
        .unwrap_or(SynthConfig::default().markers_per_segment);
    let trial = synth::generate(&SynthConfig {
        subject,
        preset,
        frames,
        seed,
        markers_per_segment,
        ..SynthConfig::default()
    })?;
    let traj = &trial.trajectories;
    let seg = segment::run(traj, &segment::Params::default())?;
    let fits = jointfit::run(traj, &seg, &jointfit::Params::default())?;
    let topology = topo::run(&seg, &fits, &topo::Params::default())?;
    // Estimated segment → truth segment with the most shared markers.
    let labels = traj.labels();
    let truth_of: Vec<Option<usize>> = seg
        .segments
        .iter()
        .map(|s| {
            let mut best = (0usize, None);
            for (t, ts) in trial.truth.segments.iter().enumerate() {
                let shared = s
                    .markers
                    .iter()
                    .filter(|&&m| labels.get(m).is_some_and(|l| ts.markers.contains(l)))
                    .count();
                if shared > best.0 {
                    best = (shared, Some(t));
                }
            }
            best.1
        })
        .collect();
    let true_edge = |a: usize, b: usize| {
        let (Some(ta), Some(tb)) = (truth_of[a], truth_of[b]) else {
            return false;
        };
        trial.truth.joints.iter().any(|j| {
            (j.parent_segment, j.child_segment) == (ta, tb)
                || (j.parent_segment, j.child_segment) == (tb, ta)
        })
    };
    let chosen = |a: usize, b: usize| {
        topology.joints.iter().any(|j| {
            (j.parent_segment, j.child_segment) == (a, b)
                || (j.parent_segment, j.child_segment) == (b, a)
        })
    };
    println!(
        "{} segments {}, truth {}; root {}",
        trial.name,
        seg.segments.len(),
        trial.truth.segments.len(),
        topology.root_segment
    );
    let name = |s: usize| truth_of[s].map_or("?", |t| trial.truth.segments[t].name.as_str());
    let mut pairs: Vec<&jointfit::PairFit> = fits.pairs.iter().collect();
    pairs.sort_by(|x, y| x.cost.total_cmp(&y.cost));
    println!(
        "{:>3} {:>3} {:<25} {:>10} {:>8} {:>5} {:>6} {:>7} {:>7} {:>8}  evidence",
        "a", "b", "true segments", "cost", "kind", "true", "chosen", "rot-rms", "resid", "frames"
    );
    for p in pairs.iter().take(3 * seg.segments.len()) {
        println!(
            "{:>3} {:>3} {:<25} {:>10.4} {:>8} {:>5} {:>6} {:>7.1} {:>7.2} {:>8}  {}",
            p.a,
            p.b,
            format!("{}-{}", name(p.a), name(p.b)),
            p.cost,
            format!("{:?}", p.kind),
            true_edge(p.a, p.b),
            chosen(p.a, p.b),
            p.rotation_rms_deg,
            p.residual_rms_mm,
            p.frames_used,
            p.evidence
        );
    }
    for n in &topology.notes {
        println!("note: {n}");
    }
    Ok(())
}
