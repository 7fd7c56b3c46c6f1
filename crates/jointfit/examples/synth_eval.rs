//! Joint-centre accuracy of every method on synthetic trials, from the TRUE segmentation.
//!
//! `cargo run --release -p jointfit --example synth_eval -- [SEED|FIRST..LAST] [FRAMES] [SUBJECT|all] [LO,HI]`
//! (LO,HI: markers per segment, default the generator's).
//! Per subject and preset (clean, skin, hard) and method: mean and worst joint error over
//! the true joints (mm and % of height), fraction of frames with a position, whether a
//! minimum spanning tree on the pair costs equals the true tree, hinge-vs-not right, time;
//! `floor`: the error left by the best centre constant in each segment's marker frame
//! (from the truth), the limit skin puts on every method here; and `score-floor`: plain
//! SCoRE on the same poses with every hinge's place along its axis taken from the truth,
//! what plain SCoRE allows with nothing but the poses (the default fit, which weighs each
//! frame by the poses' precision at the centre, goes under it on some subjects; given a
//! SUBJECT, also per joint). `along`: how far
//! the bone placement (`place_hinges_across_bones` over the true tree, as bonefit runs
//! it) leaves the true hinges fitted as hinges from the truth along their true axes, and
//! the same with the truth's axes given to the placement (which still allows them the
//! tilt bound it would allow the fitted ones), with how far the fitted axes are off and
//! that over the tilt bound the placement assumes (RMS per tilt component: 1 when the
//! bound is right on average).
//! Over a seed range, a last table gives each line's mean % of height over the seeds
//! (`tilt/bound`: the mean ratio).
#![allow(clippy::print_stdout)]

use std::collections::BTreeSet;
use std::time::Instant;

use glam::{DQuat, DVec3};
use jointfit::{JointKind, Method, Params, run_on_segments};
use synth::{Preset, Subject, SynthConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seeds: Vec<u64> = match args.get(1) {
        None => vec![101],
        Some(s) => match s.split_once("..") {
            Some((first, last)) => (first.parse()?..=last.parse()?).collect(),
            None => vec![s.parse()?],
        },
    };
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
        "{:<28} {:<11} {:>8} {:>7} {:>8} {:>7} {:>6} {:>5} {:>6} {:>7}",
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
    let mut summary = Summary::new();
    for seed in seeds.iter().copied() {
        for subject in Subject::ALL {
            if only.is_some_and(|o| !subject.name().contains(o.as_str())) {
                continue;
            }
            for preset in [Preset::Clean, Preset::Skin, Preset::Hard] {
                let config = SynthConfig {
                    subject,
                    preset,
                    frames,
                    seed,
                    markers_per_segment,
                    ..SynthConfig::default()
                };
                evaluate(&config, verbose, &mut summary)?;
            }
        }
    }
    if seeds.len() > 1 {
        println!("\nmean % of height over seeds {:?}", seeds);
        for ((subject, preset, line), sum, n) in &summary {
            println!(
                "{subject:<10} {preset:<6} {line:<12} {:>7.3}  ({n} trials)",
                sum / *n as f64
            );
        }
    }
    Ok(())
}

/// Mean % of height per (subject, preset, line) over the seeds: sum and count.
type Summary = Vec<((&'static str, &'static str, &'static str), f64, usize)>;

/// Adds one trial's % of height to its (subject, preset, line) entry.
fn tally(summary: &mut Summary, key: (&'static str, &'static str, &'static str), pct: f64) {
    match summary.iter_mut().find(|(k, ..)| *k == key) {
        Some((_, sum, n)) => {
            *sum += pct;
            *n += 1;
        }
        None => summary.push((key, pct, 1)),
    }
}

/// One trial: every method's line, `floor` and `score-floor`, each tallied in `summary`.
fn evaluate(
    config: &SynthConfig,
    verbose: bool,
    summary: &mut Summary,
) -> Result<(), Box<dyn std::error::Error>> {
    let (subject, preset) = (config.subject, config.preset);
    let trial = synth::generate(config)?;
    let truth = &trial.truth;
    let traj = &trial.trajectories;
    let segments: Vec<Vec<usize>> = trial.true_segment_markers();
    let true_edges: BTreeSet<(usize, usize)> = truth.joints.iter().map(segment_pair).collect();
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
            let edges = true_tree_edges(&fits, truth);
            jointfit::place_hinge_centres(&mut fits, &edges);
        }
        let secs = start.elapsed().as_secs_f64();
        let (mut sum, mut worst, mut known, mut total, mut hinge_ok) = (0.0, 0.0f64, 0, 0, 0);
        for j in &truth.joints {
            let (a, b) = segment_pair(j);
            let Some(fit) = fits.pairs.iter().find(|p| p.a == a && p.b == b) else {
                continue;
            };
            let (mut e, mut n) = (0.0, 0);
            for (p, t) in fit.positions.iter().zip(&j.positions) {
                total += 1;
                if p[0].is_finite() {
                    known += 1;
                    e += ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2))
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
        tally(summary, (subject.name(), preset.name(), name), mean / h);
        println!(
            "{:<28} {:<11} {:>8.2} {:>7.3} {:>8.2} {:>7.3} {:>6.3} {:>5} {:>3}/{:<2} {:>7.3}",
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
    if let Some(along) = along_axis(&fits, truth) {
        let n = along.hinges as f64;
        // Per tilt component: an isotropic tilt of σ per component has E[angle²] = 2σ².
        let over_bound = (along.bounded > 0)
            .then(|| (along.tilt_over_bound_sq / (2.0 * along.bounded as f64)).sqrt());
        println!(
            "{:<28} {:<11} {:>8.2} {:>7.3}   (true axes {:.2} mm, {:.3} %; {} hinges, axes {:.1}° off, {} × the placement's tilt bound)",
            trial.name,
            "along",
            along.fitted_mm / n,
            along.fitted_mm / n / h,
            along.true_axes_mm / n,
            along.true_axes_mm / n / h,
            along.hinges,
            along.tilt_deg / n,
            over_bound.map_or("-".to_string(), |r| format!("{r:.2}"))
        );
        let key = |line| (subject.name(), preset.name(), line);
        tally(summary, key("along"), along.fitted_mm / n / h);
        tally(summary, key("along-ta"), along.true_axes_mm / n / h);
        if let Some(r) = over_bound {
            tally(summary, key("tilt/bound"), r);
        }
    }
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
        "{:<28} {:<11} {:>8.2} {:>7.3}{versus}",
        trial.name,
        "floor",
        floor,
        floor / h
    );
    let per_joint = score_floor(&fits, truth);
    if verbose {
        for (j, e) in truth.joints.iter().zip(&per_joint) {
            if let Some(e) = e {
                let part = if j.axis.is_some() {
                    " (across the axis)"
                } else {
                    ""
                };
                println!("    {:<18} score-floor {e:>7.2} mm{part}", j.name);
            }
        }
    }
    // A joint with no frame both its segments are posed in counts as 0, as in `floor`.
    let score_floor = per_joint.iter().flatten().sum::<f64>() / truth.joints.len().max(1) as f64;
    println!(
        "{:<28} {:<11} {:>8.2} {:>7.3}",
        trial.name,
        "score-floor",
        score_floor,
        score_floor / h
    );
    tally(summary, (subject.name(), preset.name(), "floor"), floor / h);
    tally(
        summary,
        (subject.name(), preset.name(), "score-floor"),
        score_floor / h,
    );
    Ok(())
}

/// A segment's pose at one frame: rotation and translation (mm), local to global.
type Pose = (DQuat, DVec3);

/// The pose `fits` gives segment `s` at frame `f`, if known.
fn fitted_pose(fits: &jointfit::PairFits, s: usize, f: usize) -> Option<Pose> {
    let p = fits.poses.iter().find(|p| p.segment == s)?;
    let q = DQuat::from_array(*p.rotations.get(f)?);
    let t = DVec3::from_array(*p.translations.get(f)?);
    (q.is_finite() && t.is_finite()).then_some((q, t))
}

/// Each true joint's mean error (mm) under plain SCoRE on the poses of `fits` (the true
/// segments' own marker fits), with what SCoRE leaves free (a hinge's place along its
/// axis) taken from the truth, and the error along a hinge's true axis not counted: the
/// error a fit reading only these poses cannot avoid; `None` where no frame poses both
/// segments. A ridge of 1e-6 (of the normal matrix's scale, at most 2) pulls only the
/// undetermined directions to the truth.
fn score_floor(fits: &jointfit::PairFits, truth: &synth::Truth) -> Vec<Option<f64>> {
    truth
        .joints
        .iter()
        .map(|j| joint_score_floor(fits, j))
        .collect()
}

/// [`score_floor`] for one true joint.
fn joint_score_floor(fits: &jointfit::PairFits, j: &synth::TruthJoint) -> Option<f64> {
    const RIDGE: f64 = 1e-6;
    let (a, b) = (j.parent_segment, j.child_segment);
    let at = |f: usize| DVec3::from_array(j.positions[f]);
    let frames = j.positions.len();
    let both: Vec<(usize, Pose, Pose)> = (0..frames)
        .filter_map(|f| Some((f, fitted_pose(fits, a, f)?, fitted_pose(fits, b, f)?)))
        .collect();
    if both.is_empty() {
        return None;
    }
    // The truth's centre in each frame, averaged over the frames: the ridge's target.
    let n = both.len() as f64;
    let target_a = both
        .iter()
        .map(|(f, (q, t), _)| q.inverse() * (at(*f) - *t))
        .sum::<DVec3>()
        / n;
    let target_b = both
        .iter()
        .map(|(f, _, (q, t))| q.inverse() * (at(*f) - *t))
        .sum::<DVec3>()
        / n;
    // Normal equations of [R_a  −R_b][c_a; c_b] = t_b − t_a, divided by the frame count.
    let mut normal = [[0.0f64; 6]; 6];
    let mut rhs = [0.0f64; 6];
    for (_, (qa, ta), (qb, tb)) in &both {
        let (ra, rb) = (glam::DMat3::from_quat(*qa), glam::DMat3::from_quat(*qb));
        let d = *tb - *ta;
        let block = [ra, -rb];
        for (i, row) in normal.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                // Column i of [R_a −R_b] dotted with column k.
                let ci = block[i / 3].col(i % 3);
                let ck = block[k / 3].col(k % 3);
                *x += ci.dot(ck) / n;
            }
            rhs[i] += block[i / 3].col(i % 3).dot(d) / n;
        }
    }
    let target = [
        target_a.x, target_a.y, target_a.z, target_b.x, target_b.y, target_b.z,
    ];
    for i in 0..6 {
        normal[i][i] += RIDGE;
        rhs[i] += RIDGE * target[i];
    }
    let x = solve6(normal, rhs)?;
    let (ca, cb) = (DVec3::new(x[0], x[1], x[2]), DVec3::new(x[3], x[4], x[5]));
    // A hinge's true axis in the parent's frame, from frame 0, where the truth gives it
    // (the parent unposed there, the error along the axis counts too).
    let axis_in_parent = j.axis.and_then(|axis| {
        let (q, _) = fitted_pose(fits, a, 0)?;
        Some(q.inverse() * DVec3::from_array(axis))
    });
    let mut sum = 0.0;
    for (f, (qa, ta), (qb, tb)) in &both {
        let mut e = 0.5 * ((*qa * ca + *ta) + (*qb * cb + *tb)) - at(*f);
        if let Some(u) = axis_in_parent {
            let u = *qa * u;
            e -= u * e.dot(u);
        }
        sum += e.length();
    }
    Some(sum / n)
}

/// Solves a 6×6 linear system (faer's LU with partial pivoting); `None` when singular.
fn solve6(m: [[f64; 6]; 6], r: [f64; 6]) -> Option<[f64; 6]> {
    use faer::linalg::solvers::Solve;
    let lu = faer::Mat::from_fn(6, 6, |i, k| m[i][k]).partial_piv_lu();
    let x = lu.solve(faer::Mat::from_fn(6, 1, |i, _| r[i]));
    let x: [f64; 6] = std::array::from_fn(|i| x[(i, 0)]);
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Mean joint error (mm) of the truth's joints placed at their mean position in each
/// adjacent segment's marker frame (the poses of `fits`), the two sides averaged: what
/// skin leaves of any estimate that is constant in the segments' frames. Also how many
/// joints' fitted centres (the pair fit's) have a smaller RMS gap between the two
/// segments' images than these: where they do, no residual-minimising fit finds the floor.
fn constant_centre_floor(fits: &jointfit::PairFits, truth: &synth::Truth) -> (f64, usize) {
    let pose = |s: usize, f: usize| fitted_pose(fits, s, f);
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
        let (a, b) = segment_pair(j);
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

/// The two segments a true joint joins, lower index first (as the pair fits name them).
fn segment_pair(j: &synth::TruthJoint) -> (usize, usize) {
    (
        j.parent_segment.min(j.child_segment),
        j.parent_segment.max(j.child_segment),
    )
}

/// The true tree's joints as `(pair index, parent segment, child segment)` of `fits`
/// (joints whose pair was not fitted left out).
fn true_tree_edges(fits: &jointfit::PairFits, truth: &synth::Truth) -> Vec<(usize, usize, usize)> {
    truth
        .joints
        .iter()
        .filter_map(|j| {
            let (a, b) = segment_pair(j);
            let idx = fits.pairs.iter().position(|p| p.a == a && p.b == b)?;
            Some((idx, j.parent_segment, j.child_segment))
        })
        .collect()
}

/// Sums over the true hinges fitted as hinges of [`along_axis`].
struct AlongAxis {
    /// Mean over frames of the placed centre's error along the true axis, |mm|, summed.
    fitted_mm: f64,
    /// The same with the truth's axes given to the placement.
    true_axes_mm: f64,
    /// Angle between the fitted and the true axis, degrees, summed.
    tilt_deg: f64,
    /// (That angle over the placement's tilt bound)², summed where the bound is not 0
    /// (noise-free poses have none).
    tilt_over_bound_sq: f64,
    /// Hinges with a bound.
    bounded: usize,
    /// Hinges summed.
    hinges: usize,
}

/// Where `jointfit::place_hinges_across_bones` leaves the true hinges along their true
/// axes (the true tree, directed as bonefit directs it), with the fitted axes and with the
/// truth's; `None` without a true hinge fitted as a hinge.
fn along_axis(fits: &jointfit::PairFits, truth: &synth::Truth) -> Option<AlongAxis> {
    let edges = true_tree_edges(fits, truth);
    // As bonefit places them by default (`hinge_sides_from_steadiest`, `hinge_lines`).
    let place = |fits: &mut jointfit::PairFits| {
        let (directed, direction) = jointfit::placement_direction(fits, &edges, true);
        jointfit::place_hinges_across_bones(fits, &directed, direction, true);
    };
    // A true hinge's axis in segment s's frame (from frame 0, where the truth gives it).
    let axis_in = |j: &synth::TruthJoint, s: usize| -> Option<DVec3> {
        let (q, _) = fitted_pose(fits, s, 0)?;
        Some(q.inverse() * DVec3::from_array(j.axis?))
    };
    let hinge = |f: &jointfit::PairFits, j: &synth::TruthJoint| {
        let (a, b) = segment_pair(j);
        f.pairs.iter().position(|p| {
            p.a == a && p.b == b && p.kind == JointKind::Hinge && p.axis_in_a.is_some()
        })
    };
    let mut fitted = fits.clone();
    place(&mut fitted);
    let mut true_axes = fits.clone();
    for j in &truth.joints {
        let Some(k) = hinge(fits, j) else { continue };
        let (a, b) = segment_pair(j);
        if let (Some(ua), Some(ub)) = (axis_in(j, a), axis_in(j, b)) {
            true_axes.pairs[k].axis_in_a = Some(ua.to_array());
            true_axes.pairs[k].axis_in_b = Some(ub.to_array());
        }
    }
    place(&mut true_axes);
    // Mean over frames of the signed error along the true axis, |mm|.
    let along = |f: &jointfit::PairFits, k: usize, j: &synth::TruthJoint, local: DVec3| {
        let fit = &f.pairs[k];
        let (mut sum, mut n) = (0.0, 0usize);
        for (frame, p) in fit.positions.iter().enumerate() {
            let Some((q, _)) = fitted_pose(f, fit.a, frame) else {
                continue;
            };
            if p[0].is_finite() {
                sum +=
                    (q * local).dot(DVec3::from_array(*p) - DVec3::from_array(j.positions[frame]));
                n += 1;
            }
        }
        (n > 0).then(|| (sum / n as f64).abs())
    };
    let mut out = AlongAxis {
        fitted_mm: 0.0,
        true_axes_mm: 0.0,
        tilt_deg: 0.0,
        tilt_over_bound_sq: 0.0,
        bounded: 0,
        hinges: 0,
    };
    for j in &truth.joints {
        let Some(k) = hinge(fits, j) else { continue };
        let fit = &fits.pairs[k];
        let (Some(local), Some(u)) = (axis_in(j, fit.a), fit.axis_in_a) else {
            continue;
        };
        let (Some(x), Some(y)) = (along(&fitted, k, j, local), along(&true_axes, k, j, local))
        else {
            continue;
        };
        // An axis is a line: its sign is free.
        let angle = local.angle_between(DVec3::from_array(u));
        let tilt = angle.min(std::f64::consts::PI - angle);
        let bound = jointfit::axis_tilt_bound(fits, fit, &edges);
        out.fitted_mm += x;
        out.true_axes_mm += y;
        out.tilt_deg += tilt.to_degrees();
        if bound > 0.0 {
            out.tilt_over_bound_sq += (tilt / bound).powi(2);
            out.bounded += 1;
        }
        out.hinges += 1;
    }
    (out.hinges > 0).then_some(out)
}
