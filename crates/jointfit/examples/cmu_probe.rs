//! Why are the joint centres of a real walking trial where they are?
//!
//! `cargo run --release -p jointfit --example cmu_probe -- [C3D] [hinge_slide_max_rise] [hinge_ratio]`
//! (default: the shared CMU 02_01 walk). Runs the segment stage and jointfit, then for the
//! limb chains (pelvis–thigh–shank–foot, torso–upper arm–forearm, found by marker label)
//! prints which joint poses each 2-marker segment, each joint's kind, residual, SCoRE
//! conditioning, the distances from the centre to every marker of both segments, and the
//! bone lengths (distance of the two joints of a segment in its local frame, mm).
#![allow(clippy::print_stdout)]

use std::path::PathBuf;

use glam::{DQuat, DVec3};
use jointfit::{PairFit, PairFits, Params};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).map_or_else(
        || PathBuf::from("/work/shared/data/c3d/cmu/02_01.c3d"),
        PathBuf::from,
    );
    let mut params = Params::default();
    if let Some(r) = args.get(2) {
        params.hinge_slide_max_rise = r.parse()?;
    }
    if let Some(r) = args.get(3) {
        params.hinge_ratio = r.parse()?;
    }
    let capture = mocap_io::read_capture(&path, &mocap_io::ReadOptions::default())?;
    let traj = &capture.trajectories;
    let seg = segment::run(traj, &segment::Params::default())?;
    let fits = jointfit::run(traj, &seg, &params)?;
    let short = |m: usize| {
        let l = &traj.labels()[m];
        l.rsplit(':').next().unwrap_or(l).to_string()
    };
    let names: Vec<Vec<String>> = seg
        .segments
        .iter()
        .map(|s| s.markers.iter().map(|&m| short(m)).collect())
        .collect();
    for (i, n) in names.iter().enumerate() {
        println!("segment {i}: {}", n.join(" "));
    }
    let find = |label: &str| names.iter().position(|n| n.iter().any(|m| m == label));
    let chains: [&[&str]; 4] = [
        &["LBWT", "LTHI", "LSHN", "LHEE"],
        &["LBWT", "RTHI", "RSHN", "RHEE"],
        &["C7", "LUPA", "LFRM"],
        &["C7", "RELB"],
    ];
    for chain in chains {
        let ids: Vec<Option<usize>> = chain.iter().map(|l| find(l)).collect();
        println!("\n== chain {}", chain.join(" → "));
        for w in ids.windows(2) {
            let (Some(p), Some(c)) = (w[0], w[1]) else {
                continue;
            };
            let Some(fit) = pair(&fits, p, c) else {
                continue;
            };
            describe(&fits, fit, p, c, &names);
        }
        for w in ids.windows(3) {
            let (Some(p), Some(s), Some(c)) = (w[0], w[1], w[2]) else {
                continue;
            };
            let (Some(up), Some(down)) = (pair(&fits, p, s), pair(&fits, s, c)) else {
                continue;
            };
            let (u, d) = (centre_in(up, s), centre_in(down, s));
            let global = mean_distance(&up.positions, &down.positions);
            println!(
                "bone of segment {s} ({}): {:.1} mm in its frame, {:.1} mm mean over frames",
                names[s].join(" "),
                (u - d).length(),
                global
            );
        }
    }
    Ok(())
}

fn pair(fits: &PairFits, a: usize, b: usize) -> Option<&PairFit> {
    let (a, b) = (a.min(b), a.max(b));
    fits.pairs.iter().find(|p| p.a == a && p.b == b)
}

fn centre_in(fit: &PairFit, s: usize) -> DVec3 {
    DVec3::from_array(if s == fit.a {
        fit.centre_in_a
    } else {
        fit.centre_in_b
    })
}

fn mean_distance(x: &[[f64; 3]], y: &[[f64; 3]]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (p, q) in x.iter().zip(y) {
        let d = (DVec3::from_array(*p) - DVec3::from_array(*q)).length();
        if d.is_finite() {
            sum += d;
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

fn describe(fits: &PairFits, fit: &PairFit, p: usize, c: usize, names: &[Vec<String>]) {
    println!(
        "joint {p}–{c}: {:?}, residual {:.2} mm, rotation {:.1}° RMS, wobble {:.1}/{:.1}/{:.1}°",
        fit.kind,
        fit.residual_rms_mm,
        fit.rotation_rms_deg,
        fit.wobble_deg[0],
        fit.wobble_deg[1],
        fit.wobble_deg[2]
    );
    println!("  evidence: {}", fit.evidence);
    for s in [p, c] {
        let centre = centre_in(fit, s);
        let reference = &fits.poses[s].reference;
        let dist: Vec<String> = names[s]
            .iter()
            .zip(reference)
            .map(|(n, r)| format!("{n} {:.0}", (DVec3::from_array(*r) - centre).length()))
            .collect();
        let axis = if s == fit.a {
            fit.axis_in_a
        } else {
            fit.axis_in_b
        };
        let along = axis.map_or(String::new(), |u| {
            format!(
                ", centre along axis from origin {:.0} mm",
                DVec3::from_array(u).dot(centre)
            )
        });
        println!(
            "  in segment {s}: centre {:.0?} ({:.0} mm from origin{along}); to markers: {}",
            centre.to_array(),
            centre.length(),
            dist.join(", ")
        );
    }
    // The axis in global terms at the first posed frame, to read its anatomical direction.
    if let Some(u) = fit.axis_in_a {
        let r = fits.poses[fit.a]
            .rotations
            .iter()
            .find(|q| q[0].is_finite());
        if let Some(q) = r {
            let g = DQuat::from_array(*q) * DVec3::from_array(u);
            println!("  axis (global, first frame): {:.2?}", g.to_array());
        }
    }
}
