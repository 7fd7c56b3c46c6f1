//! Captures as Motive, Nexus and QTM export them give the skeleton the same capture gives
//! as C3D: the bundled fixture written in each vendor's layout (full precision, so the
//! trajectories read back bit for bit) runs to a byte-identical skeleton.json.

use std::fmt::Write as _;

use crate::support::{Scratch, root};

/// A sample's three fields with `sep` before each, empty where it is missing.
fn sample(out: &mut String, p: Option<[f64; 3]>, sep: char) {
    match p {
        Some([x, y, z]) => write!(out, "{sep}{x}{sep}{y}{sep}{z}").unwrap(),
        None => write!(out, "{sep}{sep}{sep}").unwrap(),
    }
}

/// Motive 1.23's layout: a rigid body before the markers, which the reader leaves out.
fn motive(t: &mocap_io::Trajectories) -> String {
    let mut out = format!(
        "Format Version,1.23,Take Name,fixture,Take Notes,,Capture Frame Rate,{r},Export Frame \
         Rate,{r},Total Exported Frames,{},Rotation Type,Quaternion,Length Units,Millimeters,\
         Coordinate Space,Global\n\n",
        t.frames(),
        r = t.frame_rate()
    );
    let mut rows = [",Type", ",Name", ",ID", ",", "Frame,Time (Seconds)"].map(String::from);
    for holds in ["Rotation", "Rotation", "Rotation", "Rotation", "Position"] {
        rows[0].push_str(",Rigid Body");
        rows[1].push_str(",prop");
        rows[2].push_str(",\"1\"");
        rows[3].push_str(&format!(",{holds}"));
    }
    rows[4].push_str(",X,Y,Z,W,X");
    for (m, label) in t.labels().iter().enumerate() {
        for axis in ["X", "Y", "Z"] {
            rows[0].push_str(",Marker");
            rows[1].push_str(&format!(",{label}"));
            rows[2].push_str(&format!(",\"{m:X}\""));
            rows[3].push_str(",Position");
            rows[4].push_str(&format!(",{axis}"));
        }
    }
    for row in rows {
        out.push_str(&row);
        out.push('\n');
    }
    for f in 0..t.frames() {
        let seconds = f as f64 / t.frame_rate();
        write!(out, "{},{seconds:.6},0,0,0,1,9", t.first_frame() + f as i64).unwrap();
        for m in 0..t.markers() {
            sample(&mut out, t.get(f, m), ',');
        }
        out.push('\n');
    }
    out
}

/// Nexus's layout: a Devices section first, rows padded with commas, a blank row after.
fn nexus(t: &mocap_io::Trajectories) -> String {
    let width = 2 + 3 * t.markers();
    let pad = |cells: usize| ",".repeat(width.saturating_sub(cells));
    let mut out = format!("Devices{}\n1000{}\n", pad(1), pad(1));
    out.push_str(&format!(
        ",,Plate - Force{}\nFrame,Sub Frame,Fx{}\n,,N{}\n1,0,5{}\n{}\n",
        pad(3),
        pad(3),
        pad(3),
        pad(3),
        pad(1)
    ));
    out.push_str(&format!(
        "Trajectories{}\n{}{}\n,",
        pad(1),
        t.frame_rate(),
        pad(1)
    ));
    for label in t.labels() {
        write!(out, ",{label},,").unwrap();
    }
    out.push_str("\nFrame,Sub Frame");
    out.push_str(&",X,Y,Z".repeat(t.markers()));
    out.push_str("\n,");
    out.push_str(&",mm,mm,mm".repeat(t.markers()));
    out.push('\n');
    for f in 0..t.frames() {
        write!(out, "{},0", t.first_frame() + f as i64).unwrap();
        for m in 0..t.markers() {
            sample(&mut out, t.get(f, m), ',');
        }
        out.push('\n');
    }
    out + &pad(1) + "\n"
}

/// QTM's layout: the header, the column header, gaps as zeros.
fn qtm(t: &mocap_io::Trajectories) -> String {
    let mut out = format!(
        "NO_OF_FRAMES\t{}\nNO_OF_CAMERAS\t8\nNO_OF_MARKERS\t{}\nFREQUENCY\t{}\nNO_OF_ANALOG\t0\n\
         DATA_INCLUDED\t3D\nMARKER_NAMES",
        t.frames(),
        t.markers(),
        t.frame_rate()
    );
    for label in t.labels() {
        write!(out, "\t{label}").unwrap();
    }
    out.push_str("\nFrame\tTime");
    for label in t.labels() {
        write!(out, "\t{label} X\t{label} Y\t{label} Z").unwrap();
    }
    out.push('\n');
    for f in 0..t.frames() {
        write!(
            out,
            "{}\t{:.5}",
            t.first_frame() + f as i64,
            f as f64 / t.frame_rate()
        )
        .unwrap();
        for m in 0..t.markers() {
            sample(&mut out, Some(t.get(f, m).unwrap_or([0.0; 3])), '\t');
        }
        out.push('\n');
    }
    out
}

#[test]
fn motive_nexus_and_qtm_exports_give_the_skeleton_their_c3d_gives() {
    let fixture = root().join("fixtures/human-clean.c3d");
    let t = mocap_io::read_capture(&fixture, &mocap_io::ReadOptions::default())
        .unwrap()
        .trajectories;
    let tmp = Scratch::new("vendor");
    // Every field alike but what each reader said about its file: a layout's own notes
    // (what it left out), a word of which `said` names ("" for none).
    let skeleton = |path: &std::path::Path, said: &str| {
        let mut json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
        let warnings = json["reader_warnings"].take();
        let warnings = warnings.as_array().expect("reader_warnings");
        if said.is_empty() {
            assert!(warnings.is_empty(), "{}: {warnings:?}", path.display());
        } else {
            assert!(
                warnings
                    .iter()
                    .any(|w| w.as_str().is_some_and(|w| w.contains(said))),
                "{}: {warnings:?}",
                path.display()
            );
        }
        json
    };
    let expected = skeleton(&tmp.run(&fixture).join("skeleton.json"), "");
    for (name, text, said) in [
        ("take.csv", motive(&t), "left out 1 Rigid Body"),
        ("trial.csv", nexus(&t), "left out Devices"),
        ("measurement.tsv", qtm(&t), ""),
    ] {
        let dir = Scratch::new(&format!("vendor-{name}"));
        let input = dir.path(name);
        std::fs::write(&input, text).unwrap();
        let got = skeleton(&dir.run(&input).join("skeleton.json"), said);
        assert!(
            got == expected,
            "{name}: skeleton.json differs from the C3D's"
        );
    }
}
