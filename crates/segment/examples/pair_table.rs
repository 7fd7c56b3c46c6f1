//! The joint test's pair route (a part of two markers against a body of ≥ 3) measured on
//! synthetic trials: across each true joint between a 2-marker segment and one of ≥ 3
//! (the true cut, and the cut the route would choose in their union), and on every
//! pipeline segment of ≥ 5 markers (pure: one true segment, where a cut is a false split;
//! mixed: markers of two or more).
//!
//! `MARKERS=2:3 cargo run --release -p segment --example pair_table SUBJECT PRESET SEEDS [frames]`
//!
//! One line per case: `joint` (the true cut), `joint-best` (the route's cut of the two true
//! segments' markers, `right` when it is the true one), `pure`/`mixed` (the route's cut of
//! a final segment of ≥ 5 markers), `cut-off` (a final two-marker segment cut from a true
//! segment of more, against the rest of it); then the travel (mm and z), the centre's
//! residual and the markers' distance to it over the travel, the direction's swing (° and
//! z), pair, body and pooled σ over the typical σ, the body's spin (°). A `sizes` line per
//! trial gives the share of final segments of two markers (the route's gate reads the
//! same share when the joint test starts). `PAIR=SHARE` sets `joint_pair_share` (0: the
//! route always on, 2: never).
#![allow(clippy::print_stdout)]

mod common;

/// One case's evidence on one line (σs over the typical segment σ `sigma`).
fn line(kind: &str, name: &str, e: &segment::PairEvidence, sigma: f64, extra: &str) {
    println!(
        "{kind:<10} {name:<34} travel {:7.2} tz {:6.2} frac {:5.3} rad/tr {:7.2} swing {:6.2} sz {:6.2} pair {:5.2} body {:5.2} pooled {:5.2} spin {:6.2} {extra}",
        e.travel_mm,
        e.travel_z,
        e.centre_mm / e.travel_mm.max(1e-9),
        e.radius_mm / e.travel_mm.max(1e-9),
        e.swing_deg,
        e.swing_z,
        e.pair_sigma_mm / sigma,
        e.body_sigma_mm / sigma,
        e.pooled_sigma_mm / sigma,
        e.body_spin_deg,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (subject, preset) = common::subject_and_preset(&args);
    let seeds = args
        .get(2)
        .and_then(|a| common::seeds(a))
        .unwrap_or(vec![1]);
    let frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(480);
    let mut params = segment::Params::default();
    // `PAIR=SHARE` sets the pair route's gate (0: always on); its false splits are listed.
    if let Some(share) = std::env::var("PAIR").ok().and_then(|v| v.parse().ok()) {
        params.joint_pair_share = share;
    }
    for &seed in &seeds {
        let trial = common::generate(subject, preset, frames, seed);
        let traj = &trial.trajectories;
        let sets = trial.true_segment_markers();
        let truth = common::true_segment_of(&trial);
        let posable: Vec<Vec<usize>> = sets.iter().filter(|s| s.len() >= 3).cloned().collect();
        let sigma = segment::typical_fit_sigma(traj, &posable);
        for j in &trial.truth.joints {
            let (a, b) = (&sets[j.parent_segment], &sets[j.child_segment]);
            let (body, pair) = match (a.len(), b.len()) {
                (2, k) if k >= 3 => (b, a),
                (k, 2) if k >= 3 => (a, b),
                _ => continue,
            };
            let name = format!("{}/{}", trial.name, j.name);
            if let Some(e) = segment::pair_evidence(traj, body, [pair[0], pair[1]], sigma, &params)
            {
                line("joint", &name, &e, sigma, "");
            }
            let union = [body.as_slice(), pair.as_slice()].concat();
            if let Some((cut, e)) = segment::pair_split_candidate(traj, &union, sigma, &params) {
                let right = cut.iter().all(|m| pair.contains(m));
                line(
                    "joint-best",
                    &name,
                    &e,
                    sigma,
                    if right { "right" } else { "wrong" },
                );
            }
        }
        let Ok(seg) = segment::run(traj, &params) else {
            continue;
        };
        let sized = |k: usize| seg.segments.iter().filter(|s| s.markers.len() == k).count();
        let posed = seg.segments.iter().filter(|s| s.markers.len() >= 2).count();
        println!(
            "sizes      {:<34} pairs {} of {posed} ({:.2}), singles {}",
            trial.name,
            sized(2),
            sized(2) as f64 / posed.max(1) as f64,
            sized(1)
        );
        for (k, s) in seg.segments.iter().enumerate() {
            // A pair cut off a true segment of more: the evidence against the rest of it.
            if s.markers.len() == 2 && truth[s.markers[0]] == truth[s.markers[1]] {
                let owner = &sets[truth[s.markers[0]]];
                if owner.len() > 2 {
                    let rest: Vec<usize> = owner
                        .iter()
                        .copied()
                        .filter(|m| !s.markers.contains(m))
                        .collect();
                    if let Some(e) = segment::pair_evidence(
                        traj,
                        &rest,
                        [s.markers[0], s.markers[1]],
                        sigma,
                        &params,
                    ) {
                        line(
                            "cut-off",
                            &format!("{}/seg{k}", trial.name),
                            &e,
                            sigma,
                            &format!(
                                "of {} {} {}",
                                owner.len(),
                                traj.labels()[s.markers[0]],
                                traj.labels()[s.markers[1]]
                            ),
                        );
                    }
                }
            }
            if s.markers.len() < 5 {
                continue;
            }
            let mut owners: Vec<usize> = s.markers.iter().map(|&m| truth[m]).collect();
            owners.sort_unstable();
            owners.dedup();
            let kind = if owners.len() == 1 { "pure" } else { "mixed" };
            if let Some((cut, e)) = segment::pair_split_candidate(traj, &s.markers, sigma, &params)
            {
                let same = truth[cut[0]] == truth[cut[1]];
                let labels = traj.labels();
                let extra = format!(
                    "{} markers, owners {owners:?}, cut {} {}+{} of {:?}",
                    s.markers.len(),
                    if same { "one-seg" } else { "across" },
                    labels[cut[0]],
                    labels[cut[1]],
                    s.markers
                        .iter()
                        .map(|&m| labels[m].as_str())
                        .collect::<Vec<_>>()
                );
                line(kind, &format!("{}/seg{k}", trial.name), &e, sigma, &extra);
            }
        }
    }
}
