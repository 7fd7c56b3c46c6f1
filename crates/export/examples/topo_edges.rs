//! Prints, for one synthetic trial, every pair near the tree: its cost, kind, motion and
//! whether it is a true joint and a chosen edge, so wrong trees can be diagnosed.
//!
//! `cargo run --release -p export --example topo_edges [-- subject preset seed frames markers]`
//! (`TRUE_SEGMENTS=1` gives the later stages the true segments; `JOINTFIT=JSON` sets jointfit
//! parameters, e.g. `{"tree_poses": false}` for the first pass alone)
//! (markers per segment as `MIN:MAX`, default the generator's).
#![allow(clippy::print_stdout)]

mod common;

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
    let trial = common::trial(subject, preset, seed, frames, markers_per_segment)?;
    let (seg, fits, topology) = common::up_to_tree(&trial)?;
    let truth_of = common::truth_of(&trial, &seg);
    let true_edge = |a: usize, b: usize| common::true_edge(&trial, &truth_of, a, b);
    let chosen = |a: usize, b: usize| common::chosen(&topology, a, b);
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
