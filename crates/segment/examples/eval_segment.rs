//! Segmentation against the synthetic generator's truth: adjusted Rand index (ARI) and
//! exact-partition count per subject and preset, for several parameter variants.
//!
//! `cargo run --release -p segment --example eval_segment [frames] [seeds...]`
//! Variants: default, paper (Eq. 1, no rigidity check), local without rigidity check,
//! cliques. Unassigned markers count as singletons.
#![allow(clippy::print_stdout)]

use std::collections::BTreeMap;
use std::time::Instant;

use segment::{Affinity, Method, Params};
use synth::{Preset, Subject};

mod common;

/// Adjusted Rand index of two labelings of the same items (Hubert & Arabie 1985).
fn ari(a: &[usize], b: &[usize]) -> f64 {
    let n = a.len() as f64;
    let mut table: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    let mut ra: BTreeMap<usize, f64> = BTreeMap::new();
    let mut rb: BTreeMap<usize, f64> = BTreeMap::new();
    for (&x, &y) in a.iter().zip(b) {
        *table.entry((x, y)).or_default() += 1.0;
        *ra.entry(x).or_default() += 1.0;
        *rb.entry(y).or_default() += 1.0;
    }
    let c2 = |v: f64| v * (v - 1.0) / 2.0;
    let index: f64 = table.values().map(|&v| c2(v)).sum();
    let sa: f64 = ra.values().map(|&v| c2(v)).sum();
    let sb: f64 = rb.values().map(|&v| c2(v)).sum();
    let expected = sa * sb / c2(n);
    let max = 0.5 * (sa + sb);
    if (max - expected).abs() < 1e-12 {
        1.0
    } else {
        (index - expected) / (max - expected)
    }
}

fn main() {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let frames = args.first().copied().unwrap_or(600) as usize;
    let seeds: Vec<u64> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        vec![101, 202]
    };
    // SEG_VARIANTS='name={"method":"linkage"};other={...}' runs those parameter sets.
    let custom = std::env::var("SEG_VARIANTS").unwrap_or_default();
    let custom: Vec<(String, Params)> = custom
        .split(';')
        .filter_map(|v| v.split_once('='))
        .map(|(name, json)| {
            let params: Params = serde_json::from_str(json).expect("variant params as JSON");
            (name.to_string(), params)
        })
        .collect();
    let leaked: Vec<(&str, Params)> = custom
        .into_iter()
        .map(|(n, p)| (&*Box::leak(n.into_boxed_str()), p))
        .collect();
    let variants: Vec<(&str, Params)> = match std::env::var("SEG_VARIANTS").as_deref() {
        _ if !leaked.is_empty() => leaked,
        Ok("tune") => vec![
            ("default", Params::default()),
            (
                "tf3",
                Params {
                    tolerance_factor: 3.0,
                    ..Params::default()
                },
            ),
            (
                "tf4",
                Params {
                    tolerance_factor: 4.0,
                    ..Params::default()
                },
            ),
            (
                "tf7",
                Params {
                    tolerance_factor: 7.0,
                    ..Params::default()
                },
            ),
            (
                "k1",
                Params {
                    local_k: 1,
                    ..Params::default()
                },
            ),
            (
                "k3",
                Params {
                    local_k: 3,
                    ..Params::default()
                },
            ),
        ],
        _ => vec![
            ("default", Params::default()),
            (
                "paper",
                Params {
                    affinity: Affinity::Paper,
                    rigidity_check: false,
                    ..Params::default()
                },
            ),
            (
                "local-norigid",
                Params {
                    rigidity_check: false,
                    ..Params::default()
                },
            ),
            (
                "absolute",
                Params {
                    affinity: Affinity::Absolute,
                    ..Params::default()
                },
            ),
            (
                "cliques",
                Params {
                    method: Method::Cliques,
                    ..Params::default()
                },
            ),
        ],
    };
    let subjects = [
        Subject::Human,
        Subject::Quadruped,
        Subject::Robotarm,
        Subject::Snowman,
        Subject::Hexapod,
        Subject::Random,
    ];
    // SEG_PRESETS=clean,hard limits the presets.
    let presets: Vec<Preset> = match std::env::var("SEG_PRESETS") {
        Ok(list) => list.split(',').filter_map(|p| p.parse().ok()).collect(),
        Err(_) => vec![
            Preset::Clean,
            Preset::Noise,
            Preset::Skin,
            Preset::Gaps,
            Preset::Swap,
            Preset::Hard,
        ],
    };
    let mut summary: BTreeMap<(&str, &str), (f64, usize, usize)> = BTreeMap::new();
    for &preset in &presets {
        for &subject in &subjects {
            for &seed in &seeds {
                let trial = common::generate(subject, preset, frames, seed);
                let traj = &trial.trajectories;
                let truth = common::true_segment_of(&trial);
                let mut line = format!(
                    "{:<22} {:>3} segs {:>3} markers |",
                    trial.name,
                    trial.truth.segments.len(),
                    traj.markers()
                );
                for (name, params) in &variants {
                    let start = Instant::now();
                    let seg = segment::run(traj, params).expect("segmentation");
                    let ms = start.elapsed().as_secs_f64() * 1e3;
                    let mut found: Vec<usize> = (0..traj.markers()).map(|m| 1000 + m).collect();
                    for s in &seg.segments {
                        for &m in &s.markers {
                            found[m] = s.id;
                        }
                    }
                    let score = ari(&truth, &found);
                    let exact = score > 1.0 - 1e-12;
                    let e = summary.entry((preset.name(), name)).or_default();
                    e.0 += score;
                    e.1 += usize::from(exact);
                    e.2 += 1;
                    line += &format!(
                        " {name} {score:.3} ({}s,{}u,{ms:.0}ms)",
                        seg.segments.len(),
                        seg.unassigned.len()
                    );
                }
                if std::env::var_os("SEG_QUIET").is_none() {
                    println!("{line}");
                }
            }
        }
    }
    println!(
        "\nmean ARI / exact partitions per preset and variant ({frames} frames, seeds {seeds:?}):"
    );
    for ((preset, name), (sum, exact, count)) in &summary {
        println!(
            "{preset:<6} {name:<14} ARI {:.3}  exact {exact}/{count}",
            sum / *count as f64
        );
    }
}
