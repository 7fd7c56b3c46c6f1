//! Shows one synthetic trial's segmentation against the truth, with the distance standard
//! deviation ρ (mm) inside and between the groups, to see why a partition differs.
//!
//! `cargo run --release -p segment --example inspect_segment SUBJECT PRESET SEED [frames] [key=value ...]`
#![allow(clippy::print_stdout)]

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let trial = common::trial_from_args(&args, 600);
    let params = common::params_from_overrides(args.iter().skip(4));
    let traj = &trial.trajectories;
    let labels = traj.labels();
    let n = traj.markers();
    let truth = common::true_segment_of(&trial);
    let rho = |i: usize, j: usize| common::rho_mm(traj, i, j);
    let seg = segment::run(traj, &params).expect("segmentation");
    println!(
        "{}: noise {:.2} mm, tolerance {:.2} mm, eigen-gap k {}, {} segments (truth {})",
        trial.name,
        seg.noise_mm,
        seg.tolerance_mm,
        seg.eigengap_segments,
        seg.segments.len(),
        trial.truth.segments.len()
    );
    let ev: Vec<String> = seg
        .eigenvalues
        .iter()
        .take(trial.truth.segments.len() + 3)
        .map(|v| format!("{v:.3}"))
        .collect();
    println!("eigenvalues {}", ev.join(" "));
    for swap in &seg.swaps {
        println!("swap {swap:?}");
    }
    let found: Vec<Vec<usize>> = seg.segments.iter().map(|s| s.markers.clone()).collect();
    let typical = segment::typical_fit_sigma(traj, &found);
    for (i, c) in found.iter().enumerate() {
        if let Some((a, b, e)) = segment::joint_split_candidate(traj, c, typical, &params) {
            println!(
                "found {i} best cut {a:?} | {b:?}: {}",
                common::evidence_line(&e, typical)
            );
        }
        if c.len() <= 2 {
            // Which bodies hold a small cluster's markers, and how tightly (mm).
            for &m in c {
                let mut holds: Vec<(f64, usize)> = found
                    .iter()
                    .enumerate()
                    .filter(|(_, o)| o.len() >= 3)
                    .filter_map(|(j, o)| Some((segment::marker_fit_sigma(traj, o, m)?, j)))
                    .collect();
                holds.sort_by(|x, y| x.0.total_cmp(&y.0));
                let best: Vec<String> = holds
                    .iter()
                    .take(2)
                    .map(|(s, j)| format!("{j}{:?}:{s:.2}", found[*j]))
                    .collect();
                println!(
                    "found {i} marker {m} held by {} (typical {typical:.2})",
                    best.join(" ")
                );
            }
            // How rigid the cluster is with each body, and with each other small cluster.
            let mut unions: Vec<(f64, f64, usize)> = found
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .filter_map(|(j, o)| {
                    let union = common::union_ratio(traj, o, c, typical);
                    let own = segment::fit_split_sigmas(traj, o).map_or(f64::NAN, |x| x.0);
                    (!union.is_nan()).then_some((union, own / typical, j))
                })
                .collect();
            unions.sort_by(|x, y| x.0.total_cmp(&y.0));
            let u: Vec<String> = unions
                .iter()
                .take(3)
                .map(|(union, own, j)| {
                    format!("{j}(n{}): {union:.2} (own {own:.2})", found[*j].len())
                })
                .collect();
            println!("found {i} union σ/typ with {}", u.join(", "));
        }
    }
    for (s, tseg) in trial.truth.segments.iter().enumerate() {
        let ms: Vec<usize> = (0..n).filter(|&m| truth[m] == s).collect();
        let found: Vec<String> = ms
            .iter()
            .map(|&m| seg.markers[m].segment.map_or("-".into(), |x| x.to_string()))
            .collect();
        let mut within = Vec::new();
        for (a, &i) in ms.iter().enumerate() {
            for &j in &ms[a + 1..] {
                within.push(rho(i, j));
            }
        }
        let wmax = within.iter().copied().fold(0.0, f64::max);
        // A true segment split in two: what the rigid merge saw of its halves.
        let mut halves: Vec<Vec<usize>> = Vec::new();
        for &m in &ms {
            let f = seg.markers[m].segment;
            match halves.iter_mut().find(|h| seg.markers[h[0]].segment == f) {
                Some(h) => h.push(m),
                None => halves.push(vec![m]),
            }
        }
        if halves.len() == 2 && halves.iter().all(|h| h.len() >= 3) {
            if let Some(e) = segment::joint_evidence(traj, &halves[0], &halves[1], typical) {
                println!(
                    "  truth {s} halves {:?} | {:?}: {} union σ/typ {:.2}",
                    halves[0],
                    halves[1],
                    common::evidence_line(&e, typical),
                    common::union_ratio(traj, &halves[0], &halves[1], typical)
                );
            }
        }
        let consistent = found.iter().all(|f| *f == found[0]);
        println!(
            "{} truth {:>2} {:<12} max within ρ {:6.2} found {:?}",
            if consistent { " " } else { "!" },
            s,
            tseg.name,
            wmax,
            found
        );
    }
    for u in &seg.unassigned {
        println!(
            "unassigned {} ({}): {}",
            u.marker, labels[u.marker], u.reason
        );
    }
    // Found segments mixing truths: show the cross ρ between the truth parts.
    for s in &seg.segments {
        let parts: Vec<usize> = {
            let mut p: Vec<usize> = s.markers.iter().map(|&m| truth[m]).collect();
            p.sort_unstable();
            p.dedup();
            p
        };
        if parts.len() > 1 {
            let a: Vec<usize> = s
                .markers
                .iter()
                .copied()
                .filter(|&m| truth[m] == parts[0])
                .collect();
            let b: Vec<usize> = s
                .markers
                .iter()
                .copied()
                .filter(|&m| truth[m] != parts[0])
                .collect();
            let cross: Vec<f64> = a
                .iter()
                .flat_map(|&i| b.iter().map(move |&j| (i, j)))
                .map(|(i, j)| rho(i, j))
                .collect();
            let mean = cross.iter().sum::<f64>() / cross.len() as f64;
            let min = cross.iter().copied().fold(f64::INFINITY, f64::min);
            println!(
                "found {} mixes truth {:?}: cross ρ mean {:.2} min {:.2}",
                s.id, parts, mean, min
            );
        }
    }
    // Each marker whose found segment mixes truths: its fit scatter in its found segment and
    // in its true segment's markers (both posed without it).
    for s in &seg.segments {
        let mut parts: Vec<usize> = s.markers.iter().map(|&m| truth[m]).collect();
        parts.sort_unstable();
        parts.dedup();
        if parts.len() < 2 {
            continue;
        }
        for &m in &s.markers {
            let own: Vec<usize> = (0..n).filter(|&x| truth[x] == truth[m]).collect();
            let fmt = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.2}"));
            println!(
                "  marker {m} ({}) truth {} in found {}: σ found {} σ truth {}",
                labels[m],
                truth[m],
                s.id,
                fmt(segment::marker_fit_sigma(traj, &s.markers, m)),
                fmt(segment::marker_fit_sigma(traj, &own, m)),
            );
        }
    }
    let slides: Vec<usize> = (0..n).filter(|&m| seg.markers[m].slides).collect();
    println!("sliding markers: {slides:?}");
}
