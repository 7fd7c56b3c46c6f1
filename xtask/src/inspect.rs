//! `cargo xtask inspect FILE [--json] [--set mocap-io.PARAM=V]...`: what a capture (read with
//! the capture options `run` takes) or an artifact holds.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use mocap_io::artifact::{self, ArtifactHeader};
use mocap_io::{Capture, ReadOptions};
use serde_json::{Value as Json, json};

use crate::pipeline::{self, StageId};

/// Arguments of `inspect`.
#[derive(clap::Args)]
pub struct Args {
    /// A capture (.c3d, .trc, .csv, .tsv) or an artifact (.cbor, or any file opening with the
    /// CBOR self-describe tag d9 d9 f7).
    pub file: PathBuf,
    /// Print one JSON object on stdout instead of a readable summary.
    #[arg(long)]
    pub json: bool,
    /// Read the capture with a mocap-io option, as `run` would (`mocap-io.frames=[1,100]`,
    /// `mocap-io.exclude_markers=["V*"]`, `mocap-io.units=m`). Repeatable.
    #[arg(long = "set", value_name = "mocap-io.PARAM=VALUE")]
    pub sets: Vec<String>,
}

/// Runs `inspect`.
pub fn main(args: &Args) -> Result<()> {
    if let Some(other) = args
        .sets
        .iter()
        .find(|s| !s.trim_start().starts_with("mocap-io."))
    {
        anyhow::bail!("--set {other}: inspect reads captures, so only mocap-io.* options apply");
    }
    let params = pipeline::Params::from_assignments(&args.sets)?;
    let report = inspect(&args.file, &params.mocap_io)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.json)?);
    } else {
        print!("{}", report.text);
    }
    Ok(())
}

/// A file's summary, as JSON and as text.
pub struct Report {
    /// The `--json` object.
    pub json: Json,
    /// The readable summary.
    pub text: String,
}

/// Inspects a capture, read with `options`, or an artifact.
pub fn inspect(path: &Path, options: &ReadOptions) -> Result<Report> {
    if is_artifact(path)? {
        inspect_artifact(path)
    } else {
        let capture = mocap_io::read_capture(path, options)?;
        Ok(capture_report(&capture))
    }
}

fn is_artifact(path: &Path) -> Result<bool> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("cbor"))
    {
        return Ok(true);
    }
    let mut head = [0u8; 3];
    let mut file =
        std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let n = std::io::Read::read(&mut file, &mut head)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    Ok(n == 3 && head == artifact::MAGIC)
}

/// The summary of a capture as read (positions in mm).
pub fn capture_report(capture: &Capture) -> Report {
    let t = &capture.trajectories;
    let frames = t.frames();
    let middle = frames / 2;
    let middle_frame: Json = if frames == 0 {
        Json::Null
    } else {
        // One entry per marker, in label order (like `labels`).
        Json::Array(
            (0..t.markers())
                .map(|m| t.get(middle, m).map_or(Json::Null, |p| json!(p)))
                .collect(),
        )
    };
    let spacing = t.marker_spacing_mm();
    // The segment stage's own rule at its defaults; a capture it cannot judge has none.
    let still: Vec<&str> = segment::stationary_markers(t, &segment::Params::default())
        .unwrap_or_default()
        .into_iter()
        .map(|m| t.labels()[m].as_str())
        .collect();
    // Bodies that move independently, as segment tells them apart; none where it sees one.
    let bodies: Vec<Vec<&str>> = segment::independent_bodies(t, &segment::Params::default())
        .unwrap_or_default()
        .into_iter()
        .map(|b| b.into_iter().map(|m| t.labels()[m].as_str()).collect())
        .collect();
    let bodies = if bodies.len() > 1 { bodies } else { Vec::new() };
    let json = json!({
        "kind": "capture",
        "format": capture.format.name(),
        "markers": t.markers(),
        "labels": t.labels(),
        "first_frame": t.first_frame(),
        "frames": frames,
        "frame_rate": t.frame_rate(),
        "duration_seconds": t.duration_seconds(),
        "units": capture.info.declared_units,
        "processor": capture.info.processor,
        "storage": capture.info.storage,
        "point_scale": capture.info.point_scale,
        "missing_samples": t.missing_samples(),
        "marker_spacing_mm": spacing,
        "floor_scale": mocap_io::floor_scale_of(spacing),
        "stationary_markers": still,
        "independent_bodies": bodies,
        "middle_frame": middle_frame,
        "warnings": capture.info.warnings,
        "stitched": capture.info.stitched,
    });

    let mut text = String::new();
    let total = frames * t.markers();
    let _ = writeln!(text, "format        {}", capture.format.name());
    if let (Some(p), Some(s)) = (&capture.info.processor, &capture.info.storage) {
        let _ = writeln!(text, "encoding      {p}, {s}");
    }
    let _ = writeln!(
        text,
        "units         {} (positions below in mm)",
        capture
            .info
            .declared_units
            .as_deref()
            .unwrap_or("not declared")
    );
    let _ = writeln!(text, "markers       {}", t.markers());
    let _ = writeln!(
        text,
        "frames        {frames} (first {}), {} Hz, {:.2} s",
        t.first_frame(),
        t.frame_rate(),
        t.duration_seconds()
    );
    let _ = writeln!(
        text,
        "missing       {} of {total} samples ({:.1} %)",
        t.missing_samples(),
        percent(t.missing_samples(), total)
    );
    if let Some(spacing) = spacing {
        let scale = mocap_io::floor_scale_of(Some(spacing));
        let _ = writeln!(
            text,
            "spacing       {spacing:.1} mm between nearest markers (median){}",
            if scale < 1.0 {
                format!("; mm floors of the parameters × {scale:.3}")
            } else {
                String::new()
            }
        );
    }
    if !still.is_empty() {
        let _ = writeln!(
            text,
            "still         {} {} (the room's; segment groups them apart): {}",
            still.len(),
            if still.len() == 1 {
                "marker that never moves"
            } else {
                "markers that never move"
            },
            still.join(", ")
        );
    }
    if let [biggest, others @ ..] = &bodies[..] {
        let listed: Vec<String> = others
            .iter()
            .map(|b| match &b[..] {
                [a, b, c, d, e, _, ..] => format!("{a} {b} {c} {d} {e} …"),
                few => few.join(" "),
            })
            .collect();
        let _ = writeln!(
            text,
            "bodies        {} that move independently (segment groups each on its own): \
             {} markers, then {}",
            bodies.len(),
            biggest.len(),
            listed.join(" | ")
        );
    }
    if frames > 0 {
        let _ = writeln!(text, "frame index {middle} (middle):");
        for (m, label) in t.labels().iter().enumerate() {
            match t.get(middle, m) {
                Some([x, y, z]) => {
                    let _ = writeln!(text, "  {label:<12} {x:>10.2} {y:>10.2} {z:>10.2}");
                }
                None => {
                    let _ = writeln!(text, "  {label:<12} missing");
                }
            }
        }
    }
    for w in &capture.info.warnings {
        let _ = writeln!(text, "warning: {w}");
    }
    Report { json, text }
}

fn percent(part: usize, whole: usize) -> f64 {
    if whole == 0 {
        0.0
    } else {
        100.0 * part as f64 / whole as f64
    }
}

fn inspect_artifact(path: &Path) -> Result<Report> {
    // Read as it streams, twice (generic, then typed), so an artifact of hundreds of
    // megabytes is never in memory more than once.
    let (header, payload, hash): (ArtifactHeader, ciborium::Value, String) =
        artifact::read_hashed(path)?;
    let keys = payload_keys(&payload);
    drop(payload);
    let size = std::fs::metadata(path)
        .with_context(|| format!("{}: cannot read", path.display()))?
        .len();
    // A known stage's payload is decoded with its own type for a domain summary; a payload
    // that does not decode (older schema, damage) is reported, not fatal.
    let domain = match StageId::from_name(&header.stage) {
        Ok(stage) => match pipeline::read_payload(stage, path) {
            Ok((_, payload, _)) => payload.summary(),
            Err(e) => json!({ "error": format!("{e:#}") }),
        },
        Err(_) => Json::Null,
    };
    let params_json = cbor_to_json(&header.params);
    let json = json!({
        "kind": "artifact",
        "bytes": size,
        "blake3": &hash,
        "header": {
            "stage": header.stage,
            "schema_version": header.schema_version,
            "tool_version": header.tool_version,
            "params": params_json,
            "inputs": header.inputs.iter().map(|i| json!({"role": i.role, "blake3": i.blake3})).collect::<Vec<_>>(),
        },
        "payload": keys,
        "summary": domain,
    });

    let mut text = String::new();
    let _ = writeln!(text, "artifact      {} ({size} bytes)", path.display());
    let _ = writeln!(text, "blake3        {hash}");
    let _ = writeln!(
        text,
        "stage         {} (schema v{})",
        header.stage, header.schema_version
    );
    let _ = writeln!(text, "tool version  {}", header.tool_version);
    let _ = writeln!(text, "params        {}", json["header"]["params"]);
    for input in &header.inputs {
        let _ = writeln!(text, "input         {:<10} {}", input.role, input.blake3);
    }
    let _ = writeln!(text, "payload:");
    if let Json::Array(entries) = &keys {
        for e in entries {
            let _ = writeln!(
                text,
                "  {:<22} {:<6} {:>8} items {:>10} bytes",
                e["key"].as_str().unwrap_or("?"),
                e["type"].as_str().unwrap_or("?"),
                e["items"],
                e["bytes"]
            );
        }
    }
    if let Json::Object(map) = &domain {
        let _ = writeln!(text, "summary:");
        for (k, v) in map {
            let _ = writeln!(text, "  {k:<22} {v}");
        }
    }
    Ok(Report { json, text })
}

/// Top-level keys of a payload with their CBOR type, item count and encoded size.
fn payload_keys(payload: &ciborium::Value) -> Json {
    match payload {
        ciborium::Value::Map(entries) => Json::Array(
            entries
                .iter()
                .map(|(k, v)| {
                    let key = match k {
                        ciborium::Value::Text(s) => s.clone(),
                        other => format!("{other:?}"),
                    };
                    let (kind, items) = describe(v);
                    json!({"key": key, "type": kind, "items": items, "bytes": encoded_len(v)})
                })
                .collect(),
        ),
        other => {
            let (kind, items) = describe(other);
            json!([{"key": "", "type": kind, "items": items, "bytes": encoded_len(other)}])
        }
    }
}

fn describe(v: &ciborium::Value) -> (&'static str, usize) {
    use ciborium::Value as V;
    match v {
        V::Map(m) => ("map", m.len()),
        V::Array(a) => ("array", a.len()),
        V::Bytes(b) => ("bytes", b.len()),
        V::Text(t) => ("text", t.len()),
        V::Integer(_) => ("int", 1),
        V::Float(_) => ("float", 1),
        V::Bool(_) => ("bool", 1),
        V::Null => ("null", 0),
        V::Tag(_, inner) => describe(inner),
        _ => ("other", 1),
    }
}

/// The length of `v` encoded, counted rather than kept.
fn encoded_len(v: &ciborium::Value) -> usize {
    struct Count(usize);
    impl std::io::Write for Count {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0 += buf.len();
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let mut count = Count(0);
    match ciborium::into_writer(v, &mut count) {
        Ok(()) => count.0,
        Err(_) => 0,
    }
}

/// A CBOR value as JSON for printing (byte strings as their length).
pub fn cbor_to_json(v: &ciborium::Value) -> Json {
    use ciborium::Value as V;
    match v {
        V::Integer(i) => {
            let i: i128 = (*i).into();
            i64::try_from(i).map_or_else(|_| json!(i.to_string()), |i| json!(i))
        }
        V::Float(f) => json!(f),
        V::Bool(b) => json!(b),
        V::Null => Json::Null,
        V::Text(s) => json!(s),
        V::Bytes(b) => json!(format!("<{} bytes>", b.len())),
        V::Array(a) => Json::Array(a.iter().map(cbor_to_json).collect()),
        V::Map(m) => Json::Object(
            m.iter()
                .map(|(k, v)| {
                    let key = match k {
                        V::Text(s) => s.clone(),
                        other => cbor_to_json(other).to_string(),
                    };
                    (key, cbor_to_json(v))
                })
                .collect(),
        ),
        V::Tag(_, inner) => cbor_to_json(inner),
        _ => Json::Null,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mocap_io::{CaptureInfo, Format, Trajectories};

    #[test]
    fn capture_json_has_the_contract_fields() {
        let t = Trajectories::new(
            vec!["A".into(), "B".into()],
            100.0,
            1,
            3,
            vec![
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
                [2.0, 0.0, 1.0],
                [f64::NAN; 3],
                [4.0, 0.0, 1.0],
                [5.0, 5.0, 5.0],
            ],
        )
        .unwrap();
        let capture = Capture {
            format: Format::Trc,
            trajectories: t,
            info: CaptureInfo {
                declared_units: Some("m".into()),
                warnings: vec!["w".into()],
                ..CaptureInfo::default()
            },
        };
        let r = capture_report(&capture);
        assert_eq!(r.json["format"], "trc");
        assert_eq!(r.json["markers"], 2);
        assert_eq!(r.json["frames"], 3);
        assert_eq!(r.json["first_frame"], 1);
        assert_eq!(r.json["units"], "m");
        assert_eq!(r.json["missing_samples"], 1);
        assert_eq!(r.json["middle_frame"], json!([[2.0, 0.0, 1.0], null]));
        assert_eq!(r.json["warnings"], json!(["w"]));
        assert!(r.text.contains("missing"));
    }
}
