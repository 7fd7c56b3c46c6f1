//! The C3D reader against every C3D file in the shared real-capture reference.

use std::path::Path;

use mocap_io::{Capture, ReadOptions, c3d};
use serde_json::Value;

fn reference() -> Option<(std::path::PathBuf, Vec<Value>)> {
    let dir = mocap_io::testdata::shared_data_dir("c3d_real")?;
    let text = std::fs::read_to_string(dir.join("reference.json")).expect("reference.json");
    let json: Value = serde_json::from_str(&text).expect("reference.json parses");
    let files = json["files"].as_array().expect("files array").clone();
    Some((dir, files))
}

fn is_c3d(entry: &Value) -> bool {
    let path = entry["path"].as_str().unwrap_or("");
    path.to_ascii_lowercase().ends_with(".c3d")
}

/// A shared file read as the reference readers give it: every point, model outputs and
/// computed points included.
fn read(dir: &Path, path: &str) -> Result<Capture, mocap_io::FormatError> {
    let options = ReadOptions {
        keep_model_outputs: true,
        ..ReadOptions::default()
    };
    read_with(dir, path, &options)
}

/// A shared file read with `options`.
fn read_with(
    dir: &Path,
    path: &str,
    options: &ReadOptions,
) -> Result<Capture, mocap_io::FormatError> {
    let bytes = std::fs::read(dir.join(path)).expect("shared file readable");
    c3d::parse(&bytes, options)
}

/// The first of `capture`'s warnings that contains `needle`.
fn warning_with<'a>(capture: &'a Capture, needle: &str) -> Option<&'a String> {
    capture.info.warnings.iter().find(|w| w.contains(needle))
}

/// Millimetres per unit of the reference's own numbers.
fn unit_factor(units: Option<&str>) -> f64 {
    match units {
        Some("mm") | None => 1.0,
        Some("cm") => 10.0,
        Some("m") | Some("mete") => 1000.0,
        Some(other) => panic!("reference unit {other} unknown to the test"),
    }
}

#[test]
fn every_read_file_matches_the_reference() {
    let Some((dir, files)) = reference() else {
        return;
    };
    let mut checked = 0;
    let mut failures = Vec::new();
    for entry in files.iter().filter(|e| is_c3d(e) && e["expect"] == "read") {
        let path = entry["path"].as_str().unwrap();
        let r = &entry["reference"];
        let capture = match read(&dir, path) {
            Ok(c) => c,
            Err(e) => {
                failures.push(format!("{path}: read failed: {e}"));
                continue;
            }
        };
        let t = &capture.trajectories;
        let mut check = |what: &str, ok: bool, detail: String| {
            if !ok {
                failures.push(format!("{path}: {what}: {detail}"));
            }
        };
        check(
            "markers",
            t.markers() as u64 == r["markers"].as_u64().unwrap(),
            format!("{} vs {}", t.markers(), r["markers"]),
        );
        let labels: Vec<&str> = r["labels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_str().unwrap())
            .collect();
        // A label the file repeats is read as `LABEL#k` from its second marker on, so each
        // marker has a name of its own; every name is still the file's.
        let as_read = |i: usize, ours: &str| {
            let theirs = labels[i];
            ours == theirs
                || (labels[..i].contains(&theirs)
                    && ours
                        .strip_prefix(theirs)
                        .and_then(|rest| rest.strip_prefix('#'))
                        .is_some_and(|k| k.parse::<usize>().is_ok_and(|k| k >= 2)))
        };
        let distinct: std::collections::BTreeSet<&String> = t.labels().iter().collect();
        check(
            "labels",
            t.markers() == labels.len()
                && distinct.len() == labels.len()
                && t.labels().iter().enumerate().all(|(i, l)| as_read(i, l)),
            format!(
                "{:?}.. vs {:?}..",
                &t.labels()[..3.min(t.markers())],
                &labels[..3.min(labels.len())]
            ),
        );
        check(
            "first frame",
            t.first_frame() == r["first_frame"].as_i64().unwrap(),
            format!("{} vs {}", t.first_frame(), r["first_frame"]),
        );
        check(
            "frames",
            t.frames() as u64 == r["frames"].as_u64().unwrap(),
            format!("{} vs {}", t.frames(), r["frames"]),
        );
        let rate = r["frame_rate"].as_f64().unwrap();
        check(
            "frame rate",
            t.frame_rate() as f32 == rate as f32,
            format!("{} vs {rate}", t.frame_rate()),
        );
        let units = r["units"].as_str();
        check(
            "units",
            capture.info.declared_units.as_deref() == units,
            format!("{:?} vs {units:?}", capture.info.declared_units),
        );
        check(
            "storage",
            capture.info.storage.as_deref() == r["storage"].as_str(),
            format!("{:?} vs {}", capture.info.storage, r["storage"]),
        );
        if let Some(p) = r["processor"].as_str() {
            check(
                "processor",
                capture.info.processor.as_deref() == Some(p),
                format!("{:?} vs {p}", capture.info.processor),
            );
        }
        let scale = r["point_scale"].as_f64().unwrap();
        check(
            "point scale",
            capture.info.point_scale == Some(scale),
            format!("{:?} vs {scale}", capture.info.point_scale),
        );
        check(
            "missing samples",
            t.missing_samples() as u64 == r["missing_samples"].as_u64().unwrap(),
            format!("{} vs {}", t.missing_samples(), r["missing_samples"]),
        );
        // Reference positions are in the file's units rounded to 3 decimals; giant.c3d has
        // no units, is in metres, and its reference samples are all missing (null).
        let factor = unit_factor(units);
        for s in r["samples"].as_array().unwrap() {
            let frame = s["frame"].as_u64().unwrap() as usize;
            let marker = s["marker"].as_u64().unwrap() as usize;
            check(
                "sample frame is the middle frame",
                frame == t.frames() / 2,
                format!("{frame} vs {}", t.frames() / 2),
            );
            let ours = t.get(frame, marker);
            match (s["xyz"].as_array(), ours) {
                (None, None) => {}
                (Some(xyz), Some(p)) => {
                    for (axis, (want, got)) in xyz.iter().zip(p).enumerate() {
                        let want = want.as_f64().unwrap() * factor;
                        // Half a unit in the third decimal, plus f32 rounding of the stored value.
                        let tol = 0.0005 * factor + 1e-6 * want.abs();
                        check(
                            "sample position",
                            (got - want).abs() <= tol,
                            format!(
                                "frame {frame} marker {marker} axis {axis}: {got} vs {want} mm"
                            ),
                        );
                    }
                }
                (want, got) => check(
                    "sample presence",
                    false,
                    format!("frame {frame} marker {marker}: ours {got:?}, reference {want:?}"),
                ),
            }
        }
        checked += 1;
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(checked >= 20, "only {checked} C3D files checked");
}

#[test]
fn files_flagged_read_or_error_never_panic_and_errors_say_where() {
    let Some((dir, files)) = reference() else {
        return;
    };
    for entry in files.iter().filter(|e| is_c3d(e) && e["expect"] != "read") {
        let path = entry["path"].as_str().unwrap();
        match (entry["expect"].as_str().unwrap(), read(&dir, path)) {
            ("error", Ok(_)) => panic!("{path}: read, but it must fail"),
            (_, Err(e)) => {
                assert!(
                    !e.location.is_empty() && !e.problem.is_empty(),
                    "{path}: {e}"
                );
            }
            (_, Ok(c)) => {
                let t = &c.trajectories;
                assert_eq!(t.positions().len(), t.frames() * t.markers(), "{path}");
            }
        }
    }
}

#[test]
fn empty_file_error_names_the_problem() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let e = read(&dir, "bad/Empty.c3d").unwrap_err();
    assert!(e.to_string().contains("0 bytes"), "{e}");
}

/// The same trial in six (sample01) and three × two (sample02) encodings reads the same.
#[test]
fn encodings_of_one_trial_agree() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let groups: [(&[&str], f64); 2] = [
        (
            &["pi", "pr", "vi", "vr", "si", "sr"].map(|s| s),
            0.083_333_336,
        ),
        (
            &[
                "pc_int", "pc_real", "dec_int", "dec_real", "sgi_int", "sgi_real",
            ],
            0.281_181_87,
        ),
    ];
    for (gi, (names, scale)) in groups.iter().enumerate() {
        let paths: Vec<String> = names
            .iter()
            .map(|n| {
                if gi == 0 {
                    format!("c3d/c3d.org/sample01/Eb015{n}.c3d")
                } else {
                    format!("c3d/c3d.org/sample02/{n}.c3d")
                }
            })
            .collect();
        let captures: Vec<Capture> = paths.iter().map(|p| read(&dir, p).unwrap()).collect();
        let base = &captures[0].trajectories;
        for (path, c) in paths.iter().zip(&captures).skip(1) {
            let t = &c.trajectories;
            assert_eq!(t.labels(), base.labels(), "{path}");
            assert_eq!(t.frames(), base.frames(), "{path}");
            let mut worst = 0.0f64;
            for (a, b) in t.positions().iter().zip(base.positions()) {
                assert_eq!(mocap_io::is_present(*a), mocap_io::is_present(*b), "{path}");
                if mocap_io::is_present(*a) {
                    for k in 0..3 {
                        worst = worst.max((a[k] - b[k]).abs());
                    }
                }
            }
            // Float encodings round differently from integer ones: allow one integer step.
            assert!(worst <= scale * 1.0 + 1e-3, "{path}: differs by {worst} mm");
        }
    }
}

#[test]
fn giant_keeps_flagged_samples_only_when_asked() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let giant = "c3d/c3d.org/sample16/giant.c3d";
    let default = read_with(&dir, giant, &ReadOptions::default()).unwrap();
    let t = &default.trajectories;
    assert_eq!(t.missing_samples(), t.frames() * t.markers());
    assert!(
        warning_with(&default, "keep_invalid_residuals").is_some(),
        "{:?}",
        default.info.warnings
    );
    let keep = ReadOptions {
        keep_invalid_residuals: true,
        ..ReadOptions::default()
    };
    let kept = read_with(&dir, giant, &keep).unwrap();
    let t = &kept.trajectories;
    // 1806 of its samples are SIMI's (-1e9, -1e9, -1e9) gap fill: missing even when kept.
    assert_eq!(t.missing_samples(), 1806);
    // No POINT:UNITS: values under 10 are metres, so a giant is metres tall, in mm.
    let tallest = t
        .positions()
        .iter()
        .filter(|p| mocap_io::is_present(**p))
        .map(|p| p[2])
        .fold(f64::MIN, f64::max);
    assert!((1000.0..10_000.0).contains(&tallest), "{tallest}");
    assert!(kept.info.warnings.iter().any(|w| w.contains("metres")));
}

/// Dance.c3d: DATA_START 0 and POINT:FRAMES one more than the data holds.
#[test]
fn dance_falls_back_to_the_header_with_warnings() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let c = read(&dir, "c3d/c3d.org/sample13/Dance.c3d").unwrap();
    let w = c.info.warnings.join("\n");
    assert!(w.contains("DATA_START"), "{w}");
    assert!(w.contains("500"), "{w}");
}

/// MACsample.c3d: header scale 0.0551 against POINT:SCALE 0.0215 (MIPS, integer).
#[test]
fn mac_sample_prefers_the_parameter_scale_and_says_so() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let c = read(&dir, "c3d/c3d.org/sample06/MACsample.c3d").unwrap();
    assert_eq!(c.info.processor.as_deref(), Some("mips"));
    assert_eq!(c.info.point_scale, Some(f64::from(0.021_541_154_f32)));
    assert!(c.info.warnings.iter().any(|w| w.contains("POINT:SCALE")));
}

/// phasespace_sample.c3d declares no parameter blocks: the header alone is read.
#[test]
fn phasespace_without_parameters_reads_from_the_header() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let c = read(&dir, "bad/phasespace_sample.c3d").unwrap();
    assert_eq!(
        (c.trajectories.markers(), c.trajectories.frames()),
        (40, 701)
    );
    assert!(c.info.warnings.iter().any(|w| w.contains("no parameters")));
}

/// bigparlove lists 64 of its 205 points in POINT:ANGLES, FORCES, MOMENTS and POWERS
/// (Plug-in Gait outputs): not markers, so not read unless asked, and said so.
#[test]
fn model_outputs_are_not_read_as_markers() {
    let Some((dir, _)) = reference() else {
        return;
    };
    let bigparlove = "c3d/c3d.org/sample33/bigparlove.c3d";
    let default = read_with(&dir, bigparlove, &ReadOptions::default()).unwrap();
    let t = &default.trajectories;
    assert_eq!(t.markers(), 205 - 64);
    for output in ["RHipAngles", "RKneeForce", "RKneeMoment", "RHipPower"] {
        assert!(!t.labels().iter().any(|l| l == output), "{output} read");
    }
    assert!(t.labels().iter().any(|l| l == "Sacr"));
    let warning =
        warning_with(&default, "model outputs").expect("a warning about the dropped points");
    assert!(
        warning.contains("64 points") && warning.contains("POINT:ANGLES"),
        "{warning}"
    );
    let keep = ReadOptions {
        keep_model_outputs: true,
        ..ReadOptions::default()
    };
    let all = read_with(&dir, bigparlove, &keep).unwrap();
    assert_eq!(all.trajectories.markers(), 205);
    // The markers kept are the same samples either way.
    let sacr = |t: &mocap_io::Trajectories| {
        let m = t.labels().iter().position(|l| l == "Sacr").unwrap();
        t.get(100, m)
    };
    assert_eq!(sacr(&default.trajectories), sacr(&all.trajectories));
}

/// CMU 49_04 holds 41 tracked markers and 289 bone-model points (PEL0, LFEM1, ...) that no
/// camera saw (every residual word 0): those are not read as markers unless asked, and
/// the warning says how many and which. Every other readable shared C3D, read with the
/// default options, keeps all its points.
#[test]
fn computed_points_are_not_read_as_markers() {
    let Some((dir, files)) = reference() else {
        return;
    };
    let default = read_with(&dir, "c3d/cmu/49_04.c3d", &ReadOptions::default()).unwrap();
    let t = &default.trajectories;
    assert_eq!(t.markers(), 41);
    for marker in ["Cristine1:LBWT", "Cristine1:RTOE", "Cristine1:LKNE"] {
        assert!(t.labels().iter().any(|l| l == marker), "{marker} dropped");
    }
    for computed in ["Cristine1:PEL0", "Cristine1:LFEM1", "Cristine1:RTB8"] {
        assert!(!t.labels().iter().any(|l| l == computed), "{computed} read");
    }
    let warning = warning_with(&default, "never seen by a camera")
        .expect("a warning about the computed points");
    assert!(
        warning.starts_with("289 points") && warning.contains("while 41 were"),
        "{warning}"
    );
    // No other readable file has points that are both present and unseen beside seen ones.
    for entry in files.iter().filter(|e| is_c3d(e) && e["expect"] == "read") {
        let path = entry["path"].as_str().unwrap();
        if path.ends_with("49_04.c3d") {
            continue;
        }
        let capture = read_with(&dir, path, &ReadOptions::default()).unwrap();
        assert!(
            warning_with(&capture, "never seen by a camera").is_none(),
            "{path}: {:?}",
            capture.info.warnings
        );
    }
}
