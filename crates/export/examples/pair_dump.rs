//! Dumps every pair fit of synthetic trials as JSON lines, one trial per line, so topo's
//! rules can be tried offline against the truth without rerunning the fits.
//!
//! `cargo run --release -p export --example pair_dump -- SUBJECT PRESET SEED...`
//! (`MARKERS=MIN:MAX` in the environment sets markers per segment).
//!
//! Per trial: `trial`, `n` (segments), `exact_seg` (every found segment is a different
//! true one, as many as the truth has), `pairs`: `[a, b, cost, kind, true edge, chosen,
//! rotation RMS °, residual RMS mm, per-frame residual median, 90th percentile, RMS]`
//! (−1 for what is not finite; the per-frame residuals from the segments' poses).
#![allow(clippy::print_stdout)]

mod common;

use glam::{DQuat, DVec3};
use synth::{Preset, Subject, SynthConfig};

fn finite_or(v: f64) -> f64 {
    if v.is_finite() { v } else { -1.0 }
}

/// Median, 90th percentile and RMS over frames of the distance between the centre as
/// each segment carries it.
fn residual_stats(fits: &jointfit::PairFits, p: &jointfit::PairFit) -> [f64; 3] {
    let (pa, pb) = (&fits.poses[p.a], &fits.poses[p.b]);
    let (ca, cb) = (
        DVec3::from_array(p.centre_in_a),
        DVec3::from_array(p.centre_in_b),
    );
    let mut r: Vec<f64> = (0..pa.rotations.len().min(pb.rotations.len()))
        .filter_map(|f| {
            let a = DQuat::from_array(pa.rotations[f]) * ca + DVec3::from_array(pa.translations[f]);
            let b = DQuat::from_array(pb.rotations[f]) * cb + DVec3::from_array(pb.translations[f]);
            let d = a.distance(b);
            d.is_finite().then_some(d)
        })
        .collect();
    if r.is_empty() {
        return [-1.0; 3];
    }
    r.sort_by(f64::total_cmp);
    let q = |x: f64| r[((r.len() - 1) as f64 * x).round() as usize];
    let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
    [q(0.5), q(0.9), rms]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        println!("usage: pair_dump SUBJECT PRESET SEED...");
        return Ok(());
    }
    let subject: Subject = args[1].parse()?;
    let preset: Preset = args[2].parse()?;
    let markers_per_segment = std::env::var("MARKERS")
        .ok()
        .and_then(|m| {
            let (lo, hi) = m.split_once(':')?;
            Some((lo.parse().ok()?, hi.parse().ok()?))
        })
        .unwrap_or(SynthConfig::default().markers_per_segment);
    for seed in args[3..].iter().filter_map(|a| a.parse::<u64>().ok()) {
        let trial = common::trial(subject, preset, seed, 480, markers_per_segment)?;
        let (seg, fits, topology) = common::up_to_tree(&trial)?;
        let truth_of = common::truth_of(&trial, &seg);
        let mut distinct = truth_of.clone();
        distinct.sort();
        distinct.dedup();
        let exact_seg = seg.segments.len() == trial.truth.segments.len()
            && distinct.len() == seg.segments.len()
            && distinct.iter().all(Option::is_some);
        let true_edge = |a: usize, b: usize| common::true_edge(&trial, &truth_of, a, b);
        let chosen = |a: usize, b: usize| common::chosen(&topology, a, b);
        let pairs: Vec<String> = fits
            .pairs
            .iter()
            .map(|p| {
                let [median, p90, rms] = residual_stats(&fits, p);
                format!(
                    "[{},{},{:.4},\"{:?}\",{},{},{:.3},{:.3},{:.3},{:.3},{:.3}]",
                    p.a,
                    p.b,
                    finite_or(p.cost),
                    p.kind,
                    true_edge(p.a, p.b),
                    chosen(p.a, p.b),
                    finite_or(p.rotation_rms_deg),
                    finite_or(p.residual_rms_mm),
                    median,
                    p90,
                    rms
                )
            })
            .collect();
        println!(
            "{{\"trial\":\"{}\",\"n\":{},\"exact_seg\":{},\"pairs\":[{}]}}",
            trial.name,
            seg.segments.len(),
            exact_seg,
            pairs.join(",")
        );
    }
    Ok(())
}
