//! Joint-centre accuracy of every method on synthetic trials, from the TRUE segmentation.
//!
//! `cargo run --release -p jointfit --example synth_eval -- [SEED] [FRAMES] [SUBJECT|all] [LO,HI]`
//! (LO,HI: markers per segment, default the generator's).
//! Per subject and preset (clean, hard) and method: mean and worst joint error over the
//! true joints (mm and % of height), fraction of frames with a position, whether a
//! minimum spanning tree on the pair costs equals the true tree, hinge-vs-not right, time;
//! and `floor`: the error left by the best centre constant in each segment's marker frame
//! (from the truth), the limit skin puts on every method here.
#![allow(clippy::print_stdout)]

use std::collections::BTreeSet;
use std::time::Instant;

use glam::{DQuat, DVec3};
use jointfit::{JointKind, Method, Params, run_on_segments};
use synth::{Preset, Subject, SynthConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seed: u64 = args.get(1).map_or(Ok(101), |s| s.parse())?;
    let frames: usize = args.get(2).map_or(Ok(1200), |s| s.parse())?;
    // Optional third argument: only subjects whose name contains it, with per-joint detail.
    let only = args.get(3).filter(|s| s.as_str() != "all");
    let verbose = only.is_some();
    let markers_per_segment = match args.get(4) {
        Some(s) => {
            let (lo, hi) = s.split_once(',').ok_or("markers: LO,HI")?;
            (lo.parse()?, hi.parse()?)
        }
        None => SynthConfig::default().markers_per_segment,
    };
    println!(
        "{:<28} {:<7} {:>8} {:>7} {:>8} {:>7} {:>6} {:>5} {:>6} {:>7}",
        "trial",
        "method",
        "mean_mm",
        "mean_%",
        "worst_mm",
        "worst_%",
        "known",
        "tree",
        "hinge",
        "secs"
    );
    for subject in Subject::ALL {
        if only.is_some_and(|o| !subject.name().contains(o.as_str())) {
            continue;
        }
        for preset in [Preset::Clean, Preset::Skin, Preset::Hard] {
            let trial = synth::generate(&SynthConfig {
                subject,
                preset,
                frames,
                seed,
                markers_per_segment,
                ..SynthConfig::default()
            })?;
            let truth = &trial.truth;
            let traj = &trial.trajectories;
            let segments: Vec<Vec<usize>> = trial.true_segment_markers();
            let true_edges: BTreeSet<(usize, usize)> = truth
                .joints
                .iter()
                .map(|j| {
                    (
                        j.parent_segment.min(j.child_segment),
                        j.parent_segment.max(j.child_segment),
                    )
                })
                .collect();
            for (name, method, anchor) in [
                ("score", Method::Score, true),
                ("no-anch", Method::Score, false),
                ("no-dist", Method::Score, true),
                ("aguiar", Method::Aguiar, true),
                ("score+h", Method::Score, true),
                ("local", Method::Local, true),
                ("local+h", Method::Local, true),
            ] {
                let params = Params {
                    method,
                    anchor,
                    anchor_centres_by_distance: name != "no-dist",
                    ..Params::default()
                };
                let start = Instant::now();
                let mut fits = run_on_segments(traj, &segments, &params)?;
                if name.ends_with("+h") {
                    // Hinge centres placed from the TRUE tree.
                    let edges: Vec<(usize, usize, usize)> = truth
                        .joints
                        .iter()
                        .filter_map(|j| {
                            let (a, b) = (
                                j.parent_segment.min(j.child_segment),
                                j.parent_segment.max(j.child_segment),
                            );
                            let idx = fits.pairs.iter().position(|p| p.a == a && p.b == b)?;
                            Some((idx, j.parent_segment, j.child_segment))
                        })
                        .collect();
                    jointfit::place_hinge_centres(&mut fits, &edges);
                }
                let secs = start.elapsed().as_secs_f64();
                let (mut sum, mut worst, mut known, mut total, mut hinge_ok) =
                    (0.0, 0.0f64, 0, 0, 0);
                for j in &truth.joints {
                    let (a, b) = (
                        j.parent_segment.min(j.child_segment),
                        j.parent_segment.max(j.child_segment),
                    );
                    let Some(fit) = fits.pairs.iter().find(|p| p.a == a && p.b == b) else {
                        continue;
                    };
                    let (mut e, mut n) = (0.0, 0);
                    for (p, t) in fit.positions.iter().zip(&j.positions) {
                        total += 1;
                        if p[0].is_finite() {
                            known += 1;
                            e += ((p[0] - t[0]).powi(2)
                                + (p[1] - t[1]).powi(2)
                                + (p[2] - t[2]).powi(2))
                            .sqrt();
                            n += 1;
                        }
                    }
                    let e = if n > 0 { e / n as f64 } else { f64::NAN };
                    if verbose {
                        println!(
                            "    {:<14} truth {:<5} fit {:<6} err {:>7.2} mm  wobble {:>6.2} {:>6.2} {:>6.2}  resid {:>6.2}  cost {:>8.2}",
                            j.name,
                            j.kind,
                            format!("{:?}", fit.kind),
                            e,
                            fit.wobble_deg[0],
                            fit.wobble_deg[1],
                            fit.wobble_deg[2],
                            fit.residual_rms_mm,
                            fit.cost
                        );
                    }
                    sum += e;
                    worst = worst.max(e);
                    if (fit.kind == JointKind::Hinge) == (j.kind == "hinge") {
                        hinge_ok += 1;
                    }
                }
                let mean = sum / truth.joints.len() as f64;
                let found = mst(segments.len(), &fits);
                let tree = found == true_edges;
                if verbose && !tree {
                    for e in found.difference(&true_edges) {
                        let p = fits.pairs.iter().find(|p| (p.a, p.b) == *e);
                        println!(
                            "    extra edge {e:?}: cost {:.3} kind {:?}; {}",
                            p.map_or(f64::NAN, |p| p.cost),
                            p.map(|p| p.kind),
                            p.map_or("", |p| p.evidence.as_str())
                        );
                    }
                    for e in true_edges.difference(&found) {
                        let p = fits.pairs.iter().find(|p| (p.a, p.b) == *e);
                        println!(
                            "    missed edge {e:?}: cost {:.3}",
                            p.map_or(f64::NAN, |p| p.cost)
                        );
                    }
                }
                let h = truth.height_mm / 100.0;
                println!(
                    "{:<28} {:<7} {:>8.2} {:>7.3} {:>8.2} {:>7.3} {:>6.3} {:>5} {:>3}/{:<2} {:>7.3}",
                    trial.name,
                    name,
                    mean,
                    mean / h,
                    worst,
                    worst / h,
                    known as f64 / total.max(1) as f64,
                    if tree { "ok" } else { "WRONG" },
                    hinge_ok,
                    truth.joints.len(),
                    secs
                );
            }
            // The floor of any method that keeps a joint at one place in each segment's
            // marker frame: the best such place, known from the truth.
            let fits = run_on_segments(traj, &segments, &Params::default())?;
            let (floor, fit_fits_better) = constant_centre_floor(&fits, truth);
            let h = truth.height_mm / 100.0;
            // On clean data both residuals are rounding error: nothing to compare.
            let versus = if floor > 0.5 {
                format!(
                    "   (SCoRE's centres leave a smaller residual than these at {fit_fits_better}/{} joints)",
                    truth.joints.len()
                )
            } else {
                String::new()
            };
            println!(
                "{:<28} {:<7} {:>8.2} {:>7.3}{versus}",
                trial.name,
                "floor",
                floor,
                floor / h
            );
        }
    }
    Ok(())
}

/// Mean joint error (mm) of the truth's joints placed at their mean position in each
/// adjacent segment's marker frame (the poses of `fits`), the two sides averaged: what
/// skin leaves of any estimate that is constant in the segments' frames. Also how many
/// joints' fitted centres (the pair fit's) have a smaller RMS gap between the two
/// segments' images than these: where they do, no residual-minimising fit finds the floor.
fn constant_centre_floor(fits: &jointfit::PairFits, truth: &synth::Truth) -> (f64, usize) {
    let pose = |s: usize, f: usize| -> Option<(DQuat, DVec3)> {
        let p = fits.poses.iter().find(|p| p.segment == s)?;
        let q = DQuat::from_array(p.rotations[f]);
        let t = DVec3::from_array(p.translations[f]);
        (q.is_finite() && t.is_finite()).then_some((q, t))
    };
    // RMS over frames of the distance between the two sides' images of a centre.
    let gap = |a: usize, b: usize, ca: DVec3, cb: DVec3, frames: usize| {
        let (mut sum, mut n) = (0.0, 0usize);
        for f in 0..frames {
            if let (Some((qa, ta)), Some((qb, tb))) = (pose(a, f), pose(b, f)) {
                sum += (qa * ca + ta).distance_squared(qb * cb + tb);
                n += 1;
            }
        }
        (sum / n.max(1) as f64).sqrt()
    };
    let (mut total, mut fit_fits_better) = (0.0, 0);
    for j in &truth.joints {
        let at = |f: usize| DVec3::from_array(j.positions[f]);
        let frames = j.positions.len();
        let (a, b) = (
            j.parent_segment.min(j.child_segment),
            j.parent_segment.max(j.child_segment),
        );
        let means: Vec<DVec3> = [a, b]
            .into_iter()
            .map(|s| {
                let locals: Vec<DVec3> = (0..frames)
                    .filter_map(|f| pose(s, f).map(|(q, t)| q.inverse() * (at(f) - t)))
                    .collect();
                locals.iter().copied().sum::<DVec3>() / locals.len().max(1) as f64
            })
            .collect();
        let sides: Vec<Vec<Option<DVec3>>> = [a, b]
            .into_iter()
            .zip(&means)
            .map(|(s, &mean)| {
                (0..frames)
                    .map(|f| pose(s, f).map(|(q, t)| q * mean + t))
                    .collect()
            })
            .collect();
        if let Some(fit) = fits.pairs.iter().find(|p| p.a == a && p.b == b) {
            let (ca, cb) = (
                DVec3::from_array(fit.centre_in_a),
                DVec3::from_array(fit.centre_in_b),
            );
            if gap(a, b, ca, cb, frames) < gap(a, b, means[0], means[1], frames) {
                fit_fits_better += 1;
            }
        }
        let (mut sum, mut n) = (0.0, 0usize);
        for f in 0..frames {
            let known: Vec<DVec3> = sides.iter().filter_map(|s| s[f]).collect();
            if !known.is_empty() {
                let est = known.iter().copied().sum::<DVec3>() / known.len() as f64;
                sum += est.distance(at(f));
                n += 1;
            }
        }
        total += sum / n.max(1) as f64;
    }
    (total / truth.joints.len().max(1) as f64, fit_fits_better)
}

/// Kruskal's minimum spanning tree on the pair costs (ties by pair order).
fn mst(n: usize, fits: &jointfit::PairFits) -> BTreeSet<(usize, usize)> {
    let mut order: Vec<_> = fits.pairs.iter().filter(|p| p.cost.is_finite()).collect();
    order.sort_by(|x, y| x.cost.total_cmp(&y.cost));
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let mut edges = BTreeSet::new();
    for p in order {
        let (ra, rb) = (find(&mut parent, p.a), find(&mut parent, p.b));
        if ra != rb {
            parent[ra] = rb;
            edges.insert((p.a, p.b));
        }
    }
    edges
}
