//! Whether props that move on their own (`synth::with_props`) leave a subject's
//! segmentation as it is alone: per subject, the trials whose subject alone the
//! segmentation takes for more than one body (which it would segment apart), those whose
//! bodies are exactly the subject and each prop, those whose subject segments change when
//! the props are added (and which) and those in which every prop is one segment of its
//! own, with a `body_gap_ratio` and with 0.
//!
//! `cargo run --release -p segment --example props_segment [SUBJECTS PRESET SEEDS PROPS RATIO]`
//!
//! SUBJECTS: `all` or comma-separated names (default all); PRESET default hard; SEEDS a
//! seed or `FIRST..LAST` (default 20001..20010); PROPS default 3; RATIO the
//! `body_gap_ratio` set against 0 (default its default). 480 frames, as eval.
#![allow(clippy::print_stdout)]

mod common;

use std::collections::BTreeSet;

use synth::Subject;

/// The groups of markers below `n` (the subject's) in `seg`'s segments, and its
/// unassigned markers below `n`.
fn subject_part(seg: &segment::Segmentation, n: usize) -> (BTreeSet<Vec<usize>>, Vec<usize>) {
    let groups = seg
        .segments
        .iter()
        .map(|s| {
            s.markers
                .iter()
                .copied()
                .filter(|&m| m < n)
                .collect::<Vec<usize>>()
        })
        .filter(|g| !g.is_empty())
        .collect();
    let unassigned = seg
        .unassigned
        .iter()
        .map(|u| u.marker)
        .filter(|&m| m < n)
        .collect();
    (groups, unassigned)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let subjects: Vec<Subject> = match args.first().map(String::as_str) {
        None | Some("all") => Subject::ALL.to_vec(),
        Some(list) => list
            .split(',')
            .map(|s| s.parse().expect("a subject name"))
            .collect(),
    };
    let preset = args
        .get(1)
        .map_or(synth::Preset::Hard, |p| p.parse().expect("a preset name"));
    let seeds = args.get(2).map_or_else(
        || (20001..=20010).collect(),
        |s| common::seeds(s).expect("SEEDS"),
    );
    let props: usize = args
        .get(3)
        .map_or(3, |p| p.parse().expect("PROPS: a count"));
    let ratio: f64 = args
        .get(4)
        .map_or(segment::Params::default().body_gap_ratio, |r| {
            r.parse().expect("RATIO: a number")
        });
    let variants = [ratio, 0.0].map(|body_gap_ratio| {
        (
            format!("body_gap_ratio={body_gap_ratio}"),
            segment::Params {
                body_gap_ratio,
                ..segment::Params::default()
            },
        )
    });
    // `BODIES_ONLY=1`: the bodies alone, no segmentation (fast, for the ratio).
    let bodies_only = std::env::var_os("BODIES_ONLY").is_some();
    println!("{props} props, preset {preset:?}, {} seeds", seeds.len());
    for subject in subjects {
        for (name, params) in &variants {
            let (mut changed, mut props_whole, mut told_apart, mut split_alone) =
                (Vec::new(), 0, 0, 0);
            for &seed in &seeds {
                let trial = common::generate(subject, preset, 480, seed);
                let alone = &trial.trajectories;
                let n = alone.markers();
                let with = synth::with_props(alone, props, seed).expect("props");
                let prop = |p: usize| -> Vec<usize> {
                    (0..synth::PROP_MARKERS)
                        .map(|k| n + p * synth::PROP_MARKERS + k)
                        .collect()
                };
                let bodies = |t| segment::independent_bodies(t, params).expect("bodies");
                split_alone += usize::from(bodies(alone).len() > 1);
                let mut expected: Vec<Vec<usize>> = (0..props).map(prop).collect();
                expected.push((0..n).collect());
                expected.sort();
                let mut found = bodies(&with);
                found.sort();
                told_apart += usize::from(found == expected);
                if found != expected && std::env::var_os("SHOW").is_some() {
                    let sizes: Vec<usize> = found.iter().map(Vec::len).collect();
                    eprintln!("{subject} seed {seed}: bodies of {sizes:?} markers");
                }
                if bodies_only {
                    continue;
                }
                let seg_alone = segment::run(alone, params).expect("segmentation");
                let seg_with = segment::run(&with, params).expect("segmentation");
                if subject_part(&seg_alone, n) != subject_part(&seg_with, n) {
                    changed.push(seed);
                }
                props_whole += usize::from(
                    (0..props).all(|p| seg_with.segments.iter().any(|s| s.markers == prop(p))),
                );
            }
            let segmented = if bodies_only {
                String::new()
            } else {
                format!(
                    "; subject changed {:>3}{}; props whole {props_whole:>3}",
                    changed.len(),
                    if changed.is_empty() {
                        String::new()
                    } else {
                        format!(" (seeds {changed:?})")
                    }
                )
            };
            println!(
                "{:<10} {name:<18} of {}: subject alone split {split_alone:>3}; \
                 props told apart {told_apart:>3}{segmented}",
                subject.to_string(),
                seeds.len(),
            );
        }
    }
}
